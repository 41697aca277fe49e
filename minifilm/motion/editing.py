"""Whole-motion edits that build a new ``Motion``: left/right mirroring and resampling.

Mirroring follows docs/original-code.md §1.3 (joint names decide the partners); resampling uses
slerp for rotations and linear interpolation for translations, so data at 30, 60 and 120 fps can
be brought to one rate.
"""
from __future__ import annotations

import itertools
import re
from typing import Sequence

import numpy as np

from minifilm.motion.kinematics import forward_kinematics, matrix_to_quat, quat_to_matrix, slerp
from minifilm.motion.motion import Motion

# ----------------------------------------------------------------------------------------------
# Mirroring (docs/original-code.md §1.3)
# ----------------------------------------------------------------------------------------------

_SUFFIX_LR = re.compile(r"_([LR])(?=$|_|Site$)")


def mirror_name(name: str) -> str:
    """The name of the joint on the other side, or ``name`` itself when it has no side.

    Rules, tried in turn: the substrings ``Left`` <-> ``Right`` (also lower case ``left``/``right``),
    as the original does (MD l.196-234); a leading ``L``/``R`` followed by a capital (``LHipJoint``);
    and, beyond the original, a leading ``l``/``r`` followed by a capital (CMU ``rCollar``) and a
    ``_L``/``_R`` suffix as in the Bandai files (``Hand_L``, ``Hand_LSite``).
    """
    for a, b in (("Left", "Right"), ("left", "right")):
        if a in name or b in name:
            return b.join(part.replace(b, a) for part in name.split(a))
    if len(name) >= 2 and name[0] in "LRlr" and name[1].isupper():
        return {"L": "R", "R": "L", "l": "r", "r": "l"}[name[0]] + name[1:]
    m = _SUFFIX_LR.search(name)
    if m:
        side = "R" if m.group(1) == "L" else "L"
        return name[:m.start(1)] + side + name[m.end(1):]
    return name


def mirror_pairs(names: Sequence[str]) -> np.ndarray:
    """(J,) index of each joint's mirror partner; joints without a partner map to themselves."""
    index = {n: i for i, n in enumerate(names)}
    return np.array([index.get(mirror_name(n), i) for i, n in enumerate(names)], dtype=np.int64)


def _signed_permutations() -> np.ndarray:
    """(24, 3, 3) every signed permutation matrix of determinant -1: the reflections that keep
    axis-aligned joint axes axis-aligned."""
    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            m = np.zeros((3, 3))
            m[np.arange(3), perm] = signs
            if np.linalg.det(m) < 0:
                out.append(m)
    return np.array(out)


_REFLECTIONS = _signed_permutations()


def _nearest_reflection(a: np.ndarray) -> np.ndarray:
    """The orthogonal matrix of determinant -1 nearest to ``a`` (3, 3)."""
    u, _, vt = np.linalg.svd(a)
    if np.linalg.det(u @ vt) > 0:
        u[:, -1] *= -1.0
    return u @ vt


def side_axes(motion, sym: np.ndarray) -> np.ndarray:
    """(F, 3) the character's left/right direction in each frame, a horizontal unit vector (its
    sign is arbitrary), from the partner joints that hang off the trunk (hips, collars): their
    offsets point sideways, while hands and feet swing forwards and back. Partners that sit on
    the same spot (CMU's zero-length ``LHipJoint``) pass the role to their children. (1, 0, 0) when
    the skeleton has no such pair."""
    P = motion.world()[0]
    gap = np.linalg.norm(P - P[:, sym], axis=2).mean(axis=0)          # (J,) partners' mean distance
    apart = gap > 1e-3 * max(float(gap.max()), 1e-12)

    def hangs_off_trunk(j: int) -> bool:
        p = motion.parents[j]
        while p >= 0 and sym[p] != p:
            if apart[p]:
                return False
            p = motion.parents[p]
        return True

    trunk = np.array([j for j in range(len(sym)) if sym[j] != j and apart[j] and hangs_off_trunk(j)], dtype=np.int64)
    if len(trunk) == 0:
        return np.tile([1.0, 0.0, 0.0], (motion.n_frames, 1))
    d = (P[:, trunk] - P[:, sym[trunk]])[:, :, [0, 2]]
    scatter = np.einsum("fji,fjk->fik", d, d)
    main = np.linalg.eigh(scatter)[1][:, :, -1]
    return np.stack([main[:, 0], np.zeros(len(main)), main[:, 1]], axis=1)


def rest_reflection(motion, sym: np.ndarray) -> np.ndarray | None:
    """(3, 3) the reflection that maps the skeleton's rest pose (every rotation the identity) onto
    itself with left and right swapped, or None when the rest pose is not left/right symmetric
    (within 5 % of its size)."""
    P = forward_kinematics(np.tile(np.eye(3), (1, motion.n_joints, 1, 1)), motion.offsets[None],
                           motion.parents)[0][0]
    P = P - P.mean(axis=0)
    d = P - P[sym]
    if not np.any(np.linalg.norm(d, axis=1) > 1e-9):
        return None
    n = np.linalg.eigh(d.T @ d)[1][:, -1]
    K = np.eye(3) - 2.0 * np.outer(n, n)
    axis_aligned = _REFLECTIONS[np.argmin(np.abs(_REFLECTIONS - K).max(axis=(1, 2)))]
    if np.abs(axis_aligned - K).max() < 0.1:      # a slightly uneven capture skeleton
        K = axis_aligned
    size = np.linalg.norm(P, axis=1).max()
    return K if np.linalg.norm(P @ K.T - P[sym], axis=1).max() <= 0.05 * size else None


def _symmetry_fits(motion, sym: np.ndarray, max_shift_seconds: float = 1.0) -> np.ndarray:
    """(n_shifts, J, 3, 3) ``A_j(s)``: the mean over frames f of ``World_sym(j)(f + s)^T K_f World_j(f)``
    for time shifts s up to a second either way (a stride of 1/30 s), ``K_f`` the mirror across
    the character's left/right direction (:func:`side_axes`). In a gait the left limb mirrors the
    right one half a cycle later, not at the same instant, so the best shift is what makes a
    swinging arm's fit as clear as the spine's."""
    d = side_axes(motion, sym)
    K = np.eye(3) - 2.0 * np.einsum("fi,fk->fik", d, d)
    W = motion.world()[1]
    F = motion.n_frames
    step = max(1, int(round(motion.fps / 30.0)))
    reach = min(int(round(max_shift_seconds * motion.fps)), F // 2)
    fits = []
    for shift in range(-reach, reach + 1, step):
        f = np.arange(max(0, -shift), F - max(0, shift))
        fits.append(np.einsum("fjki,fkl,fjlm->jim", W[f + shift][:, sym], K[f], W[f]) / len(f))
    return np.array(fits)


def joint_reflections(motion, sym: np.ndarray | None = None) -> np.ndarray:
    """(J, 3, 3) for each joint the reflection ``S_j`` between its own axes and its partner's: in
    a left/right symmetric pose, ``World_j = K World_sym(j) S_j``, where ``K = I - 2 d d^T``
    mirrors across the character's own left/right direction ``d`` (:func:`side_axes`).

    Skeletons differ here. When the rest pose (every rotation the identity) is itself left/right
    symmetric, as in CMU, Xia and 100STYLE's T-poses, it is a symmetric pose with ``World_j = I``,
    so every ``S_j`` is the rest pose's own reflection (``diag(-1, 1, 1)`` for a T-pose facing z).
    Skeletons exported from Maya-like tools (the Bandai Namco files) have no such rest pose: each
    joint's axes run along its bone, the right side's turned against the left's, and ``S_j``
    changes from joint to joint (``-I`` in the limbs, ``diag(1, 1, -1)`` in the spine).

    Then ``S_j`` is measured: it must carry the joint's child offsets onto its partner's; among the reflections that do
    (a signed permutation when the skeleton's axes are aligned, as in every common BVH), the one
    that fits the motion best is taken: the largest ``trace(S^T A_j)`` with ``A_j`` the mean over
    frames of ``World_sym(j)^T K World_j`` (locomotion is left/right symmetric on average, and the
    choice is between axes 90 degrees or more apart). Partners share it (``S_sym(j) = S_j^T``),
    so mirroring twice gives the motion back; End Sites take their parent's.
    """
    sym = mirror_pairs(motion.names) if sym is None else sym
    rest = rest_reflection(motion, sym)
    if rest is not None:        # a symmetric rest pose is a symmetric pose: S_j = its reflection
        return np.tile(rest, (motion.n_joints, 1, 1))
    fits = _symmetry_fits(motion, sym)
    children = [[] for _ in range(motion.n_joints)]
    for c, p in enumerate(motion.parents):
        if p >= 0 and np.linalg.norm(motion.offsets[c]) > 1e-9:
            children[p].append(c)
    out = np.empty((motion.n_joints, 3, 3))
    for j in range(motion.n_joints):
        k = sym[j]
        if k < j:
            out[j] = out[k].T
            continue
        if not motion.channels[j] and motion.parents[j] >= 0:
            out[j] = out[motion.parents[j]]
            continue
        fit = fits[:, j]
        mine, theirs = motion.offsets[children[j]], motion.offsets[sym[children[j]]]
        allowed = 0.1 * np.linalg.norm(mine, axis=1) + 1e-6
        fits_offsets = [S for S in _REFLECTIONS
                        if np.all(np.linalg.norm(mine @ S.T - theirs, axis=1) <= allowed)]
        if fits_offsets:
            def score(S):       # mean cosine between the axes of S and of the motion's best fit
                return float(np.max(np.sum(S * fit, axis=(1, 2)))) / 3.0
            best = max(fits_offsets, key=score)
            parent = motion.parents[j]
            # a chain keeps its parent's axes unless the motion clearly says otherwise: a wrong
            # choice scores about -1/3, a right one near 1, an unclear one in between
            if parent >= 0 and any(np.array_equal(out[parent], S) for S in fits_offsets) \
                    and score(out[parent]) >= score(best) - 0.5:
                best = out[parent]
            out[j] = best
        else:       # axes not aligned with each other: the best reflection of any kind
            best = int(np.argmax(np.linalg.svd(fit, compute_uv=False).sum(axis=1)))
            out[j] = _nearest_reflection(fit[best])
    return out


def mirror(motion):
    """Mirror a motion across the character's left/right (§1.3), on the same skeleton.

    The world is mirrored about x, ``M = diag(-1, 1, 1)``, and each joint takes its partner's
    motion: ``World'_j = M World_sym(j) S_j`` with ``S_j`` from :func:`joint_reflections`. Then
    world positions become ``(-x, y, z)`` of the partner's, and a joint's axes mean in mirrored
    data what they mean in real data, so rotation features of both can be mixed. In local terms
    ``R'_j = S_parent^T R_sym(j) S_j`` (the root: ``M R_sym S_j``) and ``t'_j = S_parent^T t_sym(j)``
    (the root: ``M t``), which keeps the positions an exact mirror.

    The original mirrors with ``M R M`` for every joint (``S_j = M``): the same for skeletons whose
    joints have the world's axes at rest, and wrong for the others (on the Bandai Namco skeleton
    the mirrored hips' axes point where no real pose's do, some thousand standard deviations off).
    Raises ValueError when the hierarchy is not left/right symmetric.
    """
    sym = mirror_pairs(motion.names)
    parents = motion.parents
    for j in range(motion.n_joints):
        p, ps = parents[j], parents[sym[j]]
        if (p < 0) != (ps < 0) or (p >= 0 and sym[p] != ps):
            raise ValueError(f"mirror({motion.source}): hierarchy is not left/right symmetric at joint "
                             f"{motion.names[j]!r} (partner {motion.names[sym[j]]!r})")
    S = joint_reflections(motion, sym)
    M = np.diag([-1.0, 1.0, 1.0])
    outer = np.where(parents[:, None, None] >= 0, S[np.maximum(parents, 0)], M)      # S_parent, or M at a root
    rotations = np.swapaxes(outer, -1, -2) @ motion.rotations[:, sym] @ S
    roots = parents < 0
    rotations[:, roots] = M @ motion.rotations[:, sym][:, roots] @ S[roots]
    translations = np.einsum("jkl,fjk->fjl", outer, motion.translations[:, sym])      # S_parent^T t
    offsets = np.einsum("jkl,jk->jl", outer, motion.offsets[sym])
    return Motion(list(motion.names), parents.copy(), offsets, list(motion.channels), rotations,
                  translations, motion.frame_time, f"mirror({motion.source})")


# ----------------------------------------------------------------------------------------------
# Resampling
# ----------------------------------------------------------------------------------------------

def resample(motion, fps: float):
    """The same motion at another frame rate: slerp for rotations, linear for translations.

    New frame ``k`` sits at time ``k / fps``; frames run while that time is within the original
    duration ``(F - 1) * frame_time`` (plus a 1e-6 frame tolerance), so the first frame is kept and
    the last new frame is at or before the last old one. Returns a new ``Motion``.

    BVH files store rounded frame times (1/60 s as 0.016667), so a source rate within 0.01 % of a
    whole number of frames per second is taken to be that number, as the original importer does
    (``round(1 / FrameTime)``, BVH l.300). That makes 60 -> 30 fps keep exactly every second frame.
    """
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"resample: fps must be positive, got {fps}")
    F = motion.n_frames
    source_fps = motion.fps
    if abs(source_fps - round(source_fps)) < 1e-4 * source_fps:
        source_fps = float(round(source_fps))
    step = source_fps / fps                            # old frames per new frame
    n_new = int(np.floor((F - 1) / step + 1e-6)) + 1
    u = np.arange(n_new) * step                        # fractional old-frame index per new frame
    i0 = np.clip(np.floor(u + 1e-9).astype(np.int64), 0, F - 1)
    i1 = np.minimum(i0 + 1, F - 1)
    a = np.clip(u - i0, 0.0, 1.0)
    q = matrix_to_quat(motion.rotations)               # (F, J, 4)
    q_new = slerp(q[i0], q[i1], np.broadcast_to(a[:, None], (n_new, motion.n_joints)))
    rotations = quat_to_matrix(q_new)
    t0, t1 = motion.translations[i0], motion.translations[i1]
    translations = t0 + a[:, None, None] * (t1 - t0)
    return Motion(list(motion.names), motion.parents.copy(), motion.offsets.copy(), list(motion.channels),
                  rotations, translations, 1.0 / fps, f"resample({motion.source}, {fps:g} fps)")
