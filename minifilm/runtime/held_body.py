"""The geometry of a held body: legs that keep their feet where they are, a root that keeps its place.

Used by :class:`~minifilm.runtime.standing.StandStill` once a character is idle (the runtime's
settling, not part of the paper's loop). Everything works on world joint positions (metres, y up)
of B characters; the legs are found by name and hierarchy (:func:`leg_chains`) and bent with the
foot locker's two-bone IK (:func:`minifilm.motion.foot_ik.two_bone_ik`).
"""
from __future__ import annotations

from typing import List, Optional, Sequence, Tuple

import numpy as np

from minifilm.motion.foot_ik import FootLocker, two_bone_ik
from minifilm.motion.skeletons import BUILTIN_SKELETONS
from minifilm.runtime.root_frames import to_local2, to_local3, to_world2, to_world3, unit2

#: the toe joints' names tried, [right, left] (the contact columns' order): each built-in
#: skeleton's feet phase joints, then the commonest other name
TOE_NAMES = tuple((s.phase_bones[3], s.phase_bones[2]) for s in BUILTIN_SKELETONS) + (("RightFoot", "LeftFoot"),)
#: metres: a held ankle is reached this much short of the straight leg (the knee keeps a bend)
REACH_MARGIN = 0.0005


def toe_joints(joint_names: Sequence[str]) -> Optional[List[int]]:
    """[right, left] indices of the first pair of ``TOE_NAMES`` among ``joint_names``; None if none."""
    names = list(joint_names)
    for pair in TOE_NAMES:
        if all(n in names for n in pair):
            return [names.index(n) for n in pair]
    return None


def foot_locker(layout, threshold: float = 0.2) -> Optional[FootLocker]:
    """A :class:`~minifilm.motion.foot_ik.FootLocker` on the legs of ``layout`` (a FeatureLayout:
    found from its toes, :func:`leg_chains`); None when no pair of toes is found."""
    chains = leg_chains(layout.joint_names, layout.parents)
    return None if chains is None else FootLocker(chains, threshold)


def leg_chains(joint_names: Sequence[str], parents: Sequence[int]) -> Optional[np.ndarray]:
    """(2, 4) exported-joint indices (hip, knee, ankle, toe) of the [right, left] legs: the toes by
    name (:func:`toe_joints`), the rest their parents; None when no pair of toes is found."""
    toes = toe_joints(joint_names)
    if toes is None:
        return None
    chains = []
    for toe in toes:
        ankle = parents[toe]
        knee = parents[ankle] if ankle >= 0 else -1
        hip = parents[knee] if knee >= 0 else -1
        if hip < 0:
            return None
        chains.append([hip, knee, ankle, toe])
    return np.array(chains, dtype=np.int64)


def plant_feet(positions: np.ndarray, held: Optional[np.ndarray], weight: np.ndarray,
               chains: np.ndarray, lower: Optional[np.ndarray] = None, floor: float = 0.08,
               lowering: Optional[np.ndarray] = None,
               fresh: Optional[np.ndarray] = None) -> Tuple[np.ndarray, np.ndarray, Optional[np.ndarray]]:
    """Hold the feet where they come to rest: the lower body of a settled character.

    positions (B, J, 3) world joints; held (B, 2, 2, 3) the [right, left] feet's held ankle and toe
    positions (None: start from these positions); weight (B,) in [0, 1] (:meth:`~minifilm.runtime.standing.StandStill.feet_weight`).
    Each frame the held feet move towards the current ones by ``1 - weight`` (free at 0, still at
    1: the foot locker's rule with the hold weight as the contact), the legs bend to put the ankles
    there (two-bone IK, hips fixed, bone lengths kept) and the toes sit at theirs (the foot keeps
    its length). A foot held with its toe higher than ``floor`` (m) (a knee up, a hop, a kick
    when the stop came) is put down, by up to ``lower`` (B,) metres a frame, to the other toe's
    height (half ``floor`` at most): a standing body stands on both feet. ``lowering`` (B, 2)
    says which feet are on their way down (None: none yet). ``fresh`` (B,) marks the characters
    whose hold begins now (not held the frame before): their rows of ``held`` and ``lowering`` are
    not used, so a character's hold starts as it would alone, whatever its batch-mates do.
    Returns the new positions (B, J, 3), held feet (B, 2, 2, 3) and lowering (B, 2) (None
    without ``lower``).
    """
    P = np.array(positions, dtype=np.float64)
    hip, knee, ankle, toe = (chains[:, i] for i in range(4))
    now = np.stack([P[:, ankle], P[:, toe]], axis=2)                    # (B, 2 feet, 2 joints, 3)
    w = np.asarray(weight, dtype=np.float64)[:, None, None, None]
    if held is not None and fresh is not None:
        held = np.where(fresh[:, None, None, None], now, held)
    held = now if held is None else w * held + (1.0 - w) * now
    if lower is not None:
        toe_y = held[:, :, 1, 1]                                        # (B, 2)
        down = np.minimum(toe_y[:, ::-1], floor / 2)                   # the other toe, or half-way
        if lowering is not None and fresh is not None:
            lowering = lowering & ~fresh[:, None]
        lowering = (toe_y > floor) if lowering is None else (lowering | (toe_y > floor))
        step = np.where(lowering, np.clip(toe_y - down, 0.0, np.asarray(lower, dtype=np.float64)[:, None]), 0.0)
        held = held.copy()
        held[..., 1] -= step[:, :, None]
    # a held foot out of the leg's reach (the network lifts its hips: a bounce, a hop) lowers the
    # whole body until both are reached, as a game's pelvis adjustment does: the feet stay put
    reach = (np.linalg.norm(P[:, knee] - P[:, hip], axis=-1)
             + np.linalg.norm(P[:, ankle] - P[:, knee], axis=-1) - REACH_MARGIN)          # (B, 2)
    to_foot = held[:, :, 0] - P[:, hip]
    across = np.hypot(to_foot[..., 0], to_foot[..., 2])
    above = -to_foot[..., 1]                                     # hip height over the held ankle
    drop = np.where(across < reach, above - np.sqrt(np.maximum(reach ** 2 - across ** 2, 0.0)), 0.0)
    P[..., 1] -= np.maximum(drop.max(axis=1), 0.0)[:, None]
    new_knee, new_ankle = two_bone_ik(P[:, hip], P[:, knee], P[:, ankle], held[:, :, 0])
    foot = held[:, :, 1] - held[:, :, 0]
    # the foot's own length (held toe - held ankle drifts from it only while the hold is partial)
    length = np.linalg.norm(P[:, toe] - P[:, ankle], axis=-1, keepdims=True)
    P[:, knee], P[:, ankle] = new_knee, new_ankle
    P[:, toe] = new_ankle + foot * (length / np.maximum(np.linalg.norm(foot, axis=-1, keepdims=True), 1e-9))
    return P, held, (lowering if lower is not None else None)


def hold_root(root: np.ndarray, facing: np.ndarray, new_pos: np.ndarray, new_dir: np.ndarray,
              joints: np.ndarray, vectors: Sequence[np.ndarray], move: np.ndarray, turn: np.ndarray):
    """Keep only part of the network's root step, moving its predicted body with the root.

    root, facing (B, 2): the current root; new_pos, new_dir (B, S, 2): the predicted trajectory,
    sample 0 the next root; joints (B, J, 3) predicted world positions; vectors: world 3-vectors
    (B, J, 3) to turn with the body (axes, velocities); move, turn (B,): the fraction of the
    predicted displacement and of the predicted change of facing that is kept (1: all, the
    paper's loop, those rows returned unchanged). The body and the trajectory are moved back and
    turned back about the next root, so the body stays where its root is and faces its way.
    Returns new_pos, new_dir, joints, [vectors].
    """
    rows = (move < 1.0) | (turn < 1.0)
    if not np.any(rows):
        return new_pos, new_dir, joints, list(vectors)
    shift = (1.0 - move)[:, None] * (new_pos[:, 0] - root)                     # (B, 2)
    pos = new_pos - shift[:, None]
    centre = pos[:, 0]
    before = np.arctan2(facing[:, 0], facing[:, 1])
    turned = np.arctan2(new_dir[:, 0, 0], new_dir[:, 0, 1])
    kept = before + turn * (np.mod(turned - before + np.pi, 2 * np.pi) - np.pi)
    g_new, g_kept = new_dir[:, :1], np.stack([np.sin(kept), np.cos(kept)], axis=-1)[:, None]
    pos = to_world2(to_local2(pos - centre[:, None], g_new), g_kept) + centre[:, None]
    direction = unit2(to_world2(to_local2(new_dir, g_new), g_kept), new_dir)
    rel = joints.copy()                         # moved back with the root, about the next root
    rel[..., 0] -= (shift[:, 0] + centre[:, 0])[:, None]
    rel[..., 2] -= (shift[:, 1] + centre[:, 1])[:, None]
    body = to_world3(to_local3(rel, g_new[:, 0]), g_kept[:, 0])
    body[..., 0] += centre[:, 0, None]
    body[..., 2] += centre[:, 1, None]
    turned_vectors = [to_world3(to_local3(v, g_new[:, 0]), g_kept[:, 0]) for v in vectors]
    r = rows[:, None, None]
    return (np.where(r, pos, new_pos), np.where(r, direction, new_dir), np.where(r, body, joints),
            [np.where(r, t, v) for t, v in zip(turned_vectors, vectors)])


def refit_on_feet(fit, positions: np.ndarray, rotations: np.ndarray, held: np.ndarray, rows: np.ndarray,
                  chains: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """The skeleton fit's legs put back on the held feet, and fitted again for their axes.

    fit: a :class:`~minifilm.motion.skeleton_fit.SkeletonFit`; positions (B, J, 3), rotations
    (B, J, 3, 3): its output for a pose whose feet were held (its rest bone lengths move the feet
    by the network's few millimetres of bone-length error, every frame, which reads as jitter);
    held (B, 2, 2, 3) the held feet; rows (B,) the characters held. The legs, at the rest lengths
    now, are bent onto the held feet again; fitting that pose reproduces it (it is already on the
    skeleton) and gives the legs' rotations. Other rows are returned unchanged.
    """
    again, _, _ = plant_feet(positions, held, np.ones(len(rows)), chains)
    again, again_rot = fit.fit(again, rotations)
    return (np.where(rows[:, None, None], again, positions),
            np.where(rows[:, None, None, None], again_rot, rotations))
