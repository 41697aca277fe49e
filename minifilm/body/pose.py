"""Pose transfer between two humanoid rigs: rest-pose alignment and world bone directions.

Two rigs do not share a zero pose: 100STYLE's is a T-pose, CMU's a T-pose with the arms a little
raised, and the Bandai rig's zero pose is not a human pose at all (every bone along its joint's
local x). So each rig is first brought into one **canonical pose** (:func:`canonical_pose`): facing
+z with y up, spine, neck and head straight up, arms straight out to the sides (left is +x), legs
straight down, feet and toes pointing forward. Top down, each role joint's world rotation is the
smallest rotation (a swing) that turns its bone from where its parent has put it onto the
canonical direction; the hips get the rotation that takes their up (hips -> chest) and left
(right hip -> left hip) onto +y and +x. This is the per-bone rotation between the two rest poses:
a T-pose and an A-pose rig end up in the same canonical pose.

Then every frame (:func:`transfer_rotations`), with ``C`` a rig's canonical world rotations and
``R(f)`` its world rotations at frame f, the source's change from canonical
``D_s(f) = R_s(f) C_s^T`` is given to the matching target joint: ``R_t(f) = D(f) C_t``. A mapped
target bone then points exactly where the source's bone points (both bones point the same way in
the canonical pose, and both turn by the same D): world bone directions are copied. Where the
chains differ:

* spine and neck chains of different lengths: the target joints between hips and chest (and
  between chest and head) take the source bones' D averaged over the part of the chain they
  cover, by normalised arc length (:func:`chain_overlaps`);
* the feet are not flattened: each rig's canonical foot points down by the pitch its foot has
  when flat on the floor (its rest pose's, or measured from its motion when the rest pose is not
  a standing pose), and the toes keep their rest bend;
* a target collar the source lacks follows the chest; a target toe the source lacks follows the
  ankle; any other joint without a role (CMU's ``LHipJoint``, fingers) follows its parent.

Last, the chains' chords (hips -> chest, chest -> head) are turned onto the source's
(:func:`match_chords`). Bone lengths are the target's own: FK of the target gives its joint positions.
"""
from __future__ import annotations

from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from minifilm.body.roles import SIDES, RigError, Roles
from minifilm.motion.kinematics import forward_kinematics, matrix_to_quat, quat_to_matrix
from minifilm.motion.motion import Motion
from minifilm.motion.skeleton_fit import rotation_between

__all__ = ["canonical_pose", "place_feet", "match_chords", "rest_positions", "bone_directions", "transfer_rotations",
           "pitch_below_horizontal", "foot_and_toe_directions", "UP", "LEFT", "FORWARD"]

UP, LEFT, FORWARD = np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])


def rest_positions(motion: Motion) -> np.ndarray:
    """(J, 3) world joint positions of ``motion``'s zero pose (identity rotations, rest offsets)."""
    J = motion.n_joints
    P, _ = forward_kinematics(np.broadcast_to(np.eye(3), (1, J, 3, 3)), motion.offsets[None], motion.parents)
    return P[0]


def bone_directions(roles: Roles) -> List[Tuple[str, str, np.ndarray]]:
    """(joint, child end, canonical world direction) of every role bone, from the body outwards.

    A bone runs from a role joint to the next role joint of its chain (which may be several
    hierarchy levels below, e.g. CMU's hand -> index finger)."""
    bones: List[Tuple[str, str, np.ndarray]] = []
    spine = (roles.hips,) + roles.spine
    neck = (roles.chest,) + roles.neck + ((roles.head_end,) if roles.head_end else ())
    for a, b in zip(spine[1:-1], spine[2:]):        # the hips' own bone is set by the hips' frame
        bones.append((a, b, UP))
    for a, b in zip(neck[:-1], neck[1:]):
        bones.append((a, b, UP))
    for side, sign in zip(SIDES, (1.0, -1.0)):
        limb = roles.limb(side)
        arm = limb.arm()
        for a, b in zip(arm[:-1], arm[1:]):
            bones.append((a, b, sign * LEFT))
        foot_end = limb.toe or limb.toe_end
        bones += [(limb.upleg, limb.knee, -UP), (limb.knee, limb.ankle, -UP)]
        if foot_end:
            bones.append((limb.ankle, foot_end, FORWARD))     # tilted by the foot's pitch (canonical_pose)
    return bones


def foot_and_toe_directions(motion: Motion, limb) -> Tuple[np.ndarray, np.ndarray]:
    """World directions (F, 3) of a limb's foot bone (ankle -> toe) and toe bone (toe -> tip; for a
    tip of zero length, the foot's direction carried by the toe joint's rotation)."""
    P, R = motion.world()
    i = {n: j for j, n in enumerate(motion.names)}
    end = limb.toe or limb.toe_end
    fs = P[:, i[end]] - P[:, i[limb.ankle]]
    if limb.toe and limb.toe_end and np.linalg.norm(motion.offsets[i[limb.toe_end]]) > 1e-9:
        ts = P[:, i[limb.toe_end]] - P[:, i[limb.toe]]
    elif limb.toe:
        ts = (R[:, i[limb.toe]] @ np.swapaxes(R[:, i[limb.ankle]], -1, -2) @ fs[..., None])[..., 0]
    else:
        ts = fs
    return fs, ts


def canonical_pose(motion: Motion, roles: Roles, foot_pitch: float = 0.0) -> np.ndarray:
    """(J, 3, 3) world rotations that put ``motion``'s rig in the canonical pose (module doc).

    The feet point forward and ``foot_pitch`` radians down: a rig's foot is flat on the floor at
    its own pitch (100STYLE's ankle -> toe bone points 27 degrees down when standing, CMU's 10),
    so a flat foot stays flat. The toes keep their rest bend relative to the foot.

    Joints without a role turn with their parent (their local rotation stays the identity);
    a zero-length bone has no direction and is left as its parent puts it."""
    names = motion.names
    idx = {n: i for i, n in enumerate(names)}
    J = motion.n_joints
    P0 = rest_positions(motion)
    bones: Dict[int, Tuple[int, np.ndarray]] = {idx[a]: (idx[b], d) for a, b, d in bone_directions(roles)}
    hips = idx[roles.hips]
    up = P0[idx[roles.chest]] - P0[hips]
    left = P0[idx[roles.left.upleg]] - P0[idx[roles.right.upleg]]
    up_n, left_n = np.linalg.norm(up), np.linalg.norm(left)
    if up_n < 1e-9 or left_n < 1e-9 or abs(np.dot(up, left)) > 0.95 * up_n * left_n:
        raise RigError(f"{motion.source}: cannot tell up from left at rest (hips -> chest {np.round(up, 3)}, "
                       f"right -> left upper leg {np.round(left, 3)}): is this a humanoid with two legs?")
    # Q[j]: the world rotation applied to joint j's zero-pose frame (identity in the zero pose)
    Q = np.empty((J, 3, 3))
    for j in range(J):
        p = int(motion.parents[j])
        Q[j] = Q[p] if p >= 0 else np.eye(3)
        if j == hips:
            Q[j] = _two_vector(up, left, UP, LEFT)
        elif j in bones:
            child, want = bones[j]
            if want is FORWARD:
                want = np.array([0.0, -np.sin(foot_pitch), np.cos(foot_pitch)])
            v = Q[j] @ (P0[child] - P0[j])
            if np.linalg.norm(v) > 1e-9:
                Q[j] = rotation_between(v, want) @ Q[j]
    # the zero pose's world rotations are the identity, so the canonical ones are Q itself
    return Q


def _two_vector(a: np.ndarray, b: np.ndarray, a_to: np.ndarray, b_to: np.ndarray) -> np.ndarray:
    """The rotation taking direction a onto a_to exactly and b as near b_to as it can."""
    def frame(x, y):
        x = x / np.linalg.norm(x)
        y = y - np.dot(y, x) * x
        y = y / np.linalg.norm(y)
        return np.stack([x, y, np.cross(x, y)], axis=1)
    return frame(a_to, b_to) @ frame(a, b).T


def _chain_lengths(P0: np.ndarray, idx: Dict[str, int], chain) -> np.ndarray:
    return np.array([np.linalg.norm(P0[idx[b]] - P0[idx[a]]) for a, b in zip(chain[:-1], chain[1:])])


def _average_rotations(R: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Weighted average of rotations R (K, F, 3, 3) with weights w (K,): the normalised weighted sum
    of their quaternions, signs aligned to the heaviest (fine for the nearby rotations of one chain)."""
    keep = w > 1e-12
    R, w = R[keep], w[keep]
    if len(w) == 1:
        return R[0]
    q = matrix_to_quat(R)                                  # (K, F, 4)
    ref = q[int(np.argmax(w))]
    sign = np.where(np.sum(q * ref, axis=-1, keepdims=True) < 0, -1.0, 1.0)
    return quat_to_matrix(np.einsum("k,kfi->fi", w, q * sign))


def transfer_rotations(source_world: np.ndarray, source: Motion, source_roles: Roles, source_canonical: np.ndarray,
                       target: Motion, target_roles: Roles, target_canonical: np.ndarray) -> np.ndarray:
    """Target world rotations (F, Jt, 3, 3) from the source's world rotations (F, Js, 3, 3).

    ``*_canonical``: (J, 3, 3) from :func:`canonical_pose`. See the module doc for the rule."""
    F = source_world.shape[0]
    sidx = {n: i for i, n in enumerate(source.names)}
    tidx = {n: i for i, n in enumerate(target.names)}
    # D_s(f) = R_s(f) C_s^T for every source joint
    D_src = source_world @ np.swapaxes(source_canonical, -1, -2)[None]
    D: Dict[int, np.ndarray] = {}

    def give(t_name: Optional[str], s_name: Optional[str]) -> None:
        if t_name is not None and s_name is not None:
            D[tidx[t_name]] = D_src[:, sidx[s_name]]

    give(target_roles.hips, source_roles.hips)
    give(target_roles.chest, source_roles.chest)
    give(target_roles.head, source_roles.head)
    for side in SIDES:
        s, t = source_roles.limb(side), target_roles.limb(side)
        for part in ("shoulder", "elbow", "wrist", "upleg", "knee", "ankle"):
            give(getattr(t, part), getattr(s, part))
        give(t.collar, s.collar or source_roles.chest)
        give(t.toe, s.toe or s.ankle)
    # chains between the mapped ends: each inner target joint's bone averages the source bones it covers
    sP0, tP0 = rest_positions(source), rest_positions(target)
    for s_chain, t_chain in (((source_roles.hips,) + source_roles.spine, (target_roles.hips,) + target_roles.spine),
                             ((source_roles.chest,) + source_roles.neck, (target_roles.chest,) + target_roles.neck)):
        W = chain_overlaps(_chain_lengths(sP0, sidx, s_chain), _chain_lengths(tP0, tidx, t_chain))
        s_bone_D = np.stack([D_src[:, sidx[n]] for n in s_chain[:-1]])        # bone k turns with joint k
        for k in range(1, len(t_chain) - 1):                                   # inner joints only
            D[tidx[t_chain[k]]] = _average_rotations(s_bone_D, W[k])
    # everything else follows its parent; joints above the hips stay at rest
    world = np.empty((F, target.n_joints, 3, 3))
    above = _ancestors(target, tidx[target_roles.hips])
    for j in range(target.n_joints):
        p = int(target.parents[j])
        if j in above:
            world[:, j] = np.eye(3) if p < 0 else world[:, p]
            continue
        if j not in D:
            D[j] = D[p] if p >= 0 else np.broadcast_to(np.eye(3), (F, 3, 3))
        world[:, j] = D[j] @ target_canonical[j]
    return world


def _ancestors(motion: Motion, j: int) -> set:
    out, a = set(), int(motion.parents[j])
    while a >= 0:
        out.add(a)
        a = int(motion.parents[a])
    return out


def _world_positions(motion: Motion, world: np.ndarray) -> np.ndarray:
    """(F, J, 3) joint positions from world rotations and rest offsets, the root at the origin."""
    F, J = world.shape[:2]
    P = np.zeros((F, J, 3))
    for j in range(J):
        p = int(motion.parents[j])
        if p >= 0:
            P[:, j] = P[:, p] + (world[:, p] @ motion.offsets[j][:, None])[..., 0]
    return P


def match_chords(world: np.ndarray, target: Motion, chains, directions) -> np.ndarray:
    """Turn each chain's inner joints so its end lies in the wanted direction from its start.

    A spine of 2 joints spread over 4 bends a little differently from its source, so the chest
    (and the head over the neck) would drift from where the source's hips -> chest direction puts
    it. Per chain ``[c0, c1, ..., cn]`` (joint indices, n >= 2) and frame, the part from c1 to cn
    is turned rigidly about c1 by the smallest rotation that puts cn on the ray from c0 along the
    wanted direction (F, 3): the world bone direction of the mapped bone c0 -> cn is copied. The
    end joint and everything beyond it keep their world rotations. Returns the new world rotations.
    """
    world = world.copy()
    for chain, d in zip(chains, directions):
        if len(chain) < 3:
            continue
        P = _world_positions(target, world)
        c0, c1, cn = chain[0], chain[1], chain[-1]
        d = d / np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-12)
        v = P[:, cn] - P[:, c1]
        a = P[:, c0] - P[:, c1]
        b = np.sum(d * a, axis=-1)
        c = np.sum(a * a, axis=-1) - np.sum(v * v, axis=-1)
        disc = b * b - c
        ok = disc >= 0
        t = -b + np.sqrt(np.maximum(disc, 0.0))
        goal = P[:, c0] + t[:, None] * d - P[:, c1]
        S = rotation_between(v, np.where(ok[:, None], goal, v))
        j = int(target.parents[cn])            # every joint from c1 up to cn's parent, roles or not
        while j >= 0 and j != c0:
            world[:, j] = S @ world[:, j]
            j = int(target.parents[j])
    return world


# ----------------------------------------------------------------------------------------------
# Feet: pitch and toe bend in world space
# ----------------------------------------------------------------------------------------------

def pitch_below_horizontal(d: np.ndarray) -> np.ndarray:
    """Angle (radians) by which directions (..., 3) point below the horizontal."""
    return np.arctan2(-d[..., 1], np.hypot(d[..., 0], d[..., 2]))


def _with_pitch(d: np.ndarray, pitch: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    """Unit directions with the heading of ``d`` (or of ``fallback`` where d is nearly vertical)
    and the given pitch below the horizontal."""
    h = d * np.array([1.0, 0.0, 1.0])
    n = np.linalg.norm(h, axis=-1, keepdims=True)
    hf = fallback * np.array([1.0, 0.0, 1.0])
    h = np.where(n > 1e-3, h, hf)
    h = h / np.maximum(np.linalg.norm(h, axis=-1, keepdims=True), 1e-12)
    return np.cos(pitch)[..., None] * h - np.sin(pitch)[..., None] * UP


#: how far (degrees) a placed foot may point below (or above) the horizontal
MAX_FOOT_PITCH = 85.0


def place_feet(world: np.ndarray, target: Motion, t_roles: Roles, t_shape: Tuple[float, float],
               source: Motion, s_roles: Roles, s_shape: Tuple[float, float]) -> np.ndarray:
    """Aim each target foot and toe from the source's, in world space (returns new world rotations).

    A rig's zero pose fixes a bone's direction but not its twist, and the Bandai rig's legs are
    turned half way round to stand in the canonical pose, so an offset in pitch carried through
    the canonical frames can come out sideways or upside down. The feet are therefore aimed here:
    the foot (ankle -> toe) keeps the source foot's heading and its pitch shifted by the rigs'
    flat-foot difference (``*_shape`` = (flat-foot pitch, toe bend),
    :func:`minifilm.body.proportions.foot_shape_of`: a flat foot stays flat), and the toe (toe -> tip) is bent relative to the foot as much more than its
    flat-foot bend as the source's toe is. Each is turned by the smallest rotation, so its twist
    stays as the transfer set it."""
    world = world.copy()
    ti = {n: i for i, n in enumerate(target.names)}
    (t_pitch, t_bend0), (s_pitch, s_bend0) = t_shape, s_shape
    for side in SIDES:
        s, t = s_roles.limb(side), t_roles.limb(side)
        t_end = t.toe or t.toe_end
        if (s.toe or s.toe_end) is None or t_end is None:
            continue
        fs, ts = foot_and_toe_directions(source, s)
        a = ti[t.ankle]
        local_foot = _local_offset(target, ti[t_end], a)
        if np.linalg.norm(local_foot) < 1e-9:
            continue
        ft_now = (world[:, a] @ local_foot[:, None])[..., 0]
        # short of vertical: a foot shifted past it would point backwards, and read back (a round
        # trip) as a foot pitched less than vertical the other way
        limit = np.radians(MAX_FOOT_PITCH)
        ft = _with_pitch(fs, np.clip(pitch_below_horizontal(fs) + (t_pitch - s_pitch), -limit, limit), ft_now)
        world[:, a] = rotation_between(ft_now, ft) @ world[:, a]
        if not (t.toe and t.toe_end):
            continue
        toe = ti[t.toe]
        local_toe = _local_offset(target, ti[t.toe_end], toe)
        if np.linalg.norm(local_toe) < 1e-9:       # a toe tip of zero length (Bandai): nothing to aim
            continue
        bend = (pitch_below_horizontal(fs) - pitch_below_horizontal(ts)) - s_bend0
        tt_now = (world[:, toe] @ local_toe[:, None])[..., 0]
        tt = _with_pitch(ts, pitch_below_horizontal(ft) - t_bend0 - bend, ft)
        world[:, toe] = rotation_between(tt_now, tt) @ world[:, toe]
    return world


def _local_offset(motion: Motion, end: int, joint: int) -> np.ndarray:
    """The rest vector from ``joint`` to its descendant ``end`` in ``joint``'s frame (the joints
    between at rest)."""
    v = np.zeros(3)
    j = end
    while j != joint:
        v = motion.offsets[j] + v
        j = int(motion.parents[j])
    return v


def chain_overlaps(source_lengths: Sequence[float], target_lengths: Sequence[float]) -> np.ndarray:
    """How much of each target bone each source bone covers, along normalised arc length.

    Both chains run from 0 to 1 (bone lengths divided by the chain's length). Entry [t, s] is the
    fraction of target bone t's span covered by source bone s; each row sums to 1. A zero-length
    target bone takes the source bone at its position; a chain of zero length is spread evenly.

    Args:
        source_lengths: (S,) bone lengths of the source chain.
        target_lengths: (T,) bone lengths of the target chain.
    Returns:
        (T, S) weights.
    """
    def edges(lengths):
        L = np.maximum(np.asarray(lengths, dtype=np.float64), 0.0)
        total = L.sum()
        L = L / total if total > 1e-12 else np.full(len(L), 1.0 / len(L))
        return np.concatenate([[0.0], np.cumsum(L)])

    es, et = edges(source_lengths), edges(target_lengths)
    es[-1] = et[-1] = 1.0
    W = np.zeros((len(et) - 1, len(es) - 1))
    for t in range(len(et) - 1):
        a, b = et[t], et[t + 1]
        if b - a <= 1e-12:             # a point: the source bone containing it
            s = int(np.clip(np.searchsorted(es, a, side="right") - 1, 0, len(es) - 2))
            W[t, s] = 1.0
            continue
        for s in range(len(es) - 1):
            W[t, s] = max(0.0, min(b, es[s + 1]) - max(a, es[s])) / (b - a)
        W[t] /= W[t].sum()
    return W
