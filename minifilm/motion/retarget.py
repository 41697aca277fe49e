"""Predicted joint positions + forward/up axes -> local rotations on a source skeleton -> Motion.

The network predicts, for each exported joint, its position and the forward (third column) and up
(second column) axes of its world rotation (docs/original-code.md §6.1). To write a BVH that opens in
Blender we need the local rotation of every joint of the *source* skeleton, in its own hierarchy:

1. world rotation from the axes: re-orthonormalise (fwd wins, up is made perpendicular to it) and
   stack ``R = [up x fwd, up, fwd]`` as columns (:func:`axes_to_rotation`);
2. optionally fit the rotations to the predicted positions (``fit_positions``): the bones are
   swung or, at joints with several children, best-fit rotated onto the predicted positions with
   their rest lengths kept (:class:`~minifilm.motion.skeleton_fit.SkeletonFit`, the paper's arm IK
   for the whole body, Sec. 4.4);
3. ``local_j = world_parent(j)^T world_j``; the root's translation is the predicted root-joint
   position, every other joint keeps its rest offset (so bone lengths are exactly the skeleton's).

Joints of the source skeleton that were not exported (End Sites, dropped bones) keep their rest
offset and the identity local rotation. Retargeting between different rigs is in minifilm/body/.
"""
from __future__ import annotations

from typing import Optional, Sequence

import numpy as np

from minifilm.motion.motion import Motion
from minifilm.motion.skeleton_fit import SkeletonFit, _cross, _unit, rotation_between

__all__ = ["axes_to_rotation", "rotation_between", "world_to_local", "retarget"]  # rotation_between: re-exported


def axes_to_rotation(forward: np.ndarray, up: np.ndarray) -> np.ndarray:
    """World rotation matrices from forward (column 2) and up (column 1) axes.

    Args:
        forward, up: (..., 3), not necessarily unit or orthogonal.
    Returns:
        (..., 3, 3) proper rotations with ``R[..., :, 2] = normalize(forward)`` and
        ``R[..., :, 1]`` the unit part of ``up`` perpendicular to it; ``R[..., :, 0] = up x fwd``.
    """
    f = _unit(np.asarray(forward, dtype=np.float64))
    u = np.asarray(up, dtype=np.float64)
    u = _unit(u - np.einsum("...i,...i->...", u, f)[..., None] * f)
    R = np.empty(f.shape + (3,))
    R[..., 0], R[..., 1], R[..., 2] = _cross(u, f), u, f
    return R


def world_to_local(world: np.ndarray, parents: np.ndarray) -> np.ndarray:
    """Local rotations ``parent_world^T world`` (root: world itself). world (..., J, 3, 3)."""
    local = world.copy()
    for j, p in enumerate(parents):
        if p >= 0:
            local[..., j, :, :] = np.swapaxes(world[..., p, :, :], -1, -2) @ world[..., j, :, :]
    return local


def retarget(positions: np.ndarray, rotations: np.ndarray, skeleton: Motion, joint_indices: Sequence[int],
             frame_time: Optional[float] = None, fit_positions: bool = True, source: str = "minifilm") -> Motion:
    """Put predicted world joints back onto a source skeleton as a :class:`Motion`.

    Args:
        positions: (F, Je, 3) world positions of the exported joints, metres.
        rotations: (F, Je, 3, 3) their world rotations (e.g. from :func:`axes_to_rotation`).
        skeleton: a Motion whose hierarchy, offsets and channels define the output skeleton
            (its frames are not used), e.g. the 100STYLE BVH header.
        joint_indices: (Je,) index into ``skeleton`` joints of each exported joint (see
            :class:`~minifilm.motion.skeleton_fit.SkeletonFit`).
        frame_time: seconds per frame of the output (default: the skeleton's).
        fit_positions: fit rotations to the predicted positions (see module doc).
    Returns:
        Motion on ``skeleton`` with F frames: exported joint 0 placed at positions[:, 0], every
        other joint at its rest offset.
    """
    P = np.asarray(positions, dtype=np.float64)
    Rw = np.asarray(rotations, dtype=np.float64)
    idx = np.asarray(joint_indices, dtype=np.int64)
    if P.ndim != 3 or Rw.shape != P.shape[:2] + (3, 3) or idx.shape != P.shape[1:2]:
        raise ValueError(f"retarget: positions {P.shape}, rotations {Rw.shape} and joint_indices "
                         f"{idx.shape} disagree; expected (F, Je, 3), (F, Je, 3, 3), (Je,)")
    try:
        body = SkeletonFit(skeleton, idx)
    except ValueError as e:
        raise ValueError(f"retarget: {e}") from None
    F, J = len(P), skeleton.n_joints
    if fit_positions:
        world, _ = body.world(P, Rw)
    else:
        world = np.empty((F, J, 3, 3))
        for j in range(J):  # parents come first, so world[parent] is ready
            e = body.exported[j]
            if e >= 0:
                world[:, j] = Rw[:, e]
            else:
                world[:, j] = world[:, skeleton.parents[j]] if skeleton.parents[j] >= 0 else np.eye(3)
    local = world_to_local(world, skeleton.parents)
    translations = np.broadcast_to(body.offsets, (F, J, 3)).copy()
    translations[:, body.root] = P[:, 0] - body.above_root
    return Motion(list(skeleton.names), skeleton.parents.copy(), body.offsets.copy(), list(skeleton.channels), local,
                  translations, skeleton.frame_time if frame_time is None else frame_time, source)
