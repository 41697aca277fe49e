"""Predicted joint positions + forward/up axes -> local rotations on a source skeleton -> Motion.

The network predicts, for each exported joint, its position and the forward (third column) and up
(second column) axes of its world rotation (original-pipeline §6.1). To write a BVH that opens in
Blender we need the local rotation of every joint of the *source* skeleton, in its own hierarchy:

1. world rotation from the axes: re-orthonormalise (fwd wins, up is made perpendicular to it) and
   stack ``R = [up x fwd, up, fwd]`` as columns (:func:`axes_to_rotation`);
2. optionally fit the rotations to the predicted positions (``fit_positions``): a bone with one
   exported child is swung (smallest rotation) to point at it, so its twist still comes from the
   predicted axes; a joint with several exported children (hips, upper chest) gets the best-fit
   (Kabsch) rotation of its rest bones onto the predicted ones. Bones aim from where forward
   kinematics has put the joint, so each child is off only by its own bone's length error, which
   does not accumulate sideways down the chain (this plays the role of the paper's arm IK,
   Sec. 4.4, for the whole body);
3. ``local_j = world_parent(j)^T world_j``; the root's translation is the predicted root-joint
   position, every other joint keeps its rest offset (so bone lengths are exactly the skeleton's).

Joints of the source skeleton that were not exported (End Sites, dropped bones) keep their rest
offset and the identity local rotation.
"""
from __future__ import annotations

from typing import Optional, Sequence

import numpy as np

from .motion import Motion

__all__ = ["axes_to_rotation", "rotation_between", "world_to_local", "retarget"]


def _unit(v: np.ndarray, eps: float = 1e-9) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), eps)


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
    u = _unit(u - np.sum(u * f, axis=-1, keepdims=True) * f)
    x = np.cross(u, f)
    return np.stack([x, u, f], axis=-1)


def rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation taking direction a to direction b (Rodrigues): (..., 3, 3).

    Opposite directions (a = -b) have no unique smallest rotation; they get a half turn about an
    axis perpendicular to a.
    """
    a = _unit(np.asarray(a, dtype=np.float64))
    b = _unit(np.asarray(b, dtype=np.float64))
    v = np.cross(a, b)
    c = np.sum(a * b, axis=-1)
    opposite = c < -1 + 1e-9
    if np.any(opposite):
        # any axis perpendicular to a: cross with whichever basis vector is least parallel
        e = np.where(np.abs(a[..., :1]) < 0.9, np.array([1.0, 0, 0]), np.array([0, 1.0, 0]))
        axis = _unit(np.cross(a, e))
        v = np.where(opposite[..., None], axis, v)
    K = np.zeros(v.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2] = -v[..., 2], v[..., 1]
    K[..., 1, 0], K[..., 1, 2] = v[..., 2], -v[..., 0]
    K[..., 2, 0], K[..., 2, 1] = -v[..., 1], v[..., 0]
    scale = np.where(opposite, 1.0, 1.0 / np.maximum(1.0 + c, 1e-12))[..., None, None]
    I = np.broadcast_to(np.eye(3), K.shape)
    R = I + K + scale * (K @ K)
    # half turn: R = 2 n n^T - I for the chosen perpendicular unit axis n
    if np.any(opposite):
        half = 2.0 * v[..., :, None] * v[..., None, :] - I
        R = np.where(opposite[..., None, None], half, R)
    return R


def _best_fit_rotation(rest: np.ndarray, want: np.ndarray, prior: np.ndarray, prior_weight: float = 1e-6) -> np.ndarray:
    """Rotation R (F, 3, 3) best mapping rest bone vectors (C, 3) onto wanted ones (F, C, 3).

    Kabsch: maximise sum_c want_c . (R rest_c) + w tr(prior^T R) by SVD. The small prior term
    (the rotation from the predicted axes) only breaks ties, e.g. when all children are collinear.
    """
    scale = float(np.mean(np.sum(rest * rest, axis=-1)))
    H = np.einsum("ci,fcj->fij", rest, want) + prior_weight * scale * np.swapaxes(prior, -1, -2)
    U, _, Vt = np.linalg.svd(H)
    V = np.swapaxes(Vt, -1, -2)
    d = np.sign(np.linalg.det(V @ np.swapaxes(U, -1, -2)))
    D = np.broadcast_to(np.eye(3), H.shape).copy()
    D[:, 2, 2] = d
    return V @ D @ np.swapaxes(U, -1, -2)


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
        joint_indices: (Je,) index into ``skeleton`` joints of each exported joint; exported joint 0
            is the skeleton's root or hangs below joints that are not exported (Bandai's
            ``joint_Root`` above ``Hips``), which are then kept at rest with no rotation.
        frame_time: seconds per frame of the output (default: the skeleton's).
        fit_positions: fit rotations to the predicted positions (see module doc).
    Returns:
        Motion on ``skeleton`` with F frames: exported joint 0 placed at positions[:, 0], every
        other joint at its rest offset.
    """
    P = np.asarray(positions, dtype=np.float64)
    Rw = np.asarray(rotations, dtype=np.float64)
    idx = np.asarray(joint_indices, dtype=np.int64)
    F, Je = P.shape[:2]
    if P.shape != (F, Je, 3) or Rw.shape != (F, Je, 3, 3) or idx.shape != (Je,):
        raise ValueError(f"retarget: positions {P.shape}, rotations {Rw.shape} and joint_indices "
                         f"{idx.shape} disagree; expected (F, Je, 3), (F, Je, 3, 3), (Je,)")
    J = skeleton.n_joints
    if idx.min() < 0 or idx.max() >= J or len(set(idx.tolist())) != Je:
        raise ValueError(f"retarget: joint_indices must be {Je} distinct indices into the "
                         f"{J} joints of {skeleton.source}, got {idx.tolist()}")
    root = idx[0]
    parents = skeleton.parents
    offsets = skeleton.offsets
    exported = -np.ones(J, dtype=np.int64)
    exported[idx] = np.arange(Je)
    ancestors = []                          # joints above exported joint 0, from the top down
    a = parents[root]
    while a >= 0:
        ancestors.insert(0, a)
        a = parents[a]
    if any(exported[a] >= 0 for a in ancestors):
        raise ValueError(f"retarget: exported joint 0 ({skeleton.names[root]}) must be the first "
                         f"exported joint of its chain in {skeleton.source}")
    for j in idx[1:]:
        a = parents[j]
        while a >= 0 and a != root:
            a = parents[a]
        if a != root:
            raise ValueError(f"retarget: exported joint {skeleton.names[j]} is not below "
                             f"{skeleton.names[root]} (exported joint 0) in {skeleton.source}")
    # ancestors stay at rest with identity rotations, so exported joint 0's parent sits here
    above_root = offsets[ancestors].sum(axis=0) if ancestors else np.zeros(3)

    world = np.empty((F, J, 3, 3))
    for j in range(J):  # parents come first, so world[parent] is ready
        e = exported[j]
        if e >= 0:
            world[:, j] = Rw[:, e]
        else:
            world[:, j] = world[:, parents[j]] if parents[j] >= 0 else np.eye(3)

    if fit_positions:
        children = [[c for c in range(J) if parents[c] == j and exported[c] >= 0
                     and np.linalg.norm(offsets[c]) > 1e-9] for j in range(J)]
        fk = np.zeros((F, J, 3))             # where forward kinematics puts each joint so far
        fk[:, root] = P[:, 0]
        for j in range(J):  # parents first: fk[j] and the parent's final rotation are known
            if parents[j] >= 0 and j != root:
                if exported[j] < 0:
                    world[:, j] = world[:, parents[j]]
                fk[:, j] = fk[:, parents[j]] + world[:, parents[j]] @ offsets[j]
            if exported[j] < 0 or not children[j]:
                continue
            rest = offsets[children[j]]                                     # (C, 3)
            # aim from where the joint really is (not where it was predicted), so position
            # errors do not accumulate down the chain: each bone only adds its length error
            want = P[:, exported[children[j]]] - fk[:, j, None]             # (F, C, 3)
            if len(children[j]) == 1:
                bone_now = world[:, j] @ rest[0]
                world[:, j] = rotation_between(bone_now, want[:, 0]) @ world[:, j]
            else:
                world[:, j] = _best_fit_rotation(rest, want, world[:, j])
    local = world_to_local(world, parents)
    translations = np.broadcast_to(offsets, (F, J, 3)).copy()
    translations[:, root] = P[:, 0] - above_root
    return Motion(list(skeleton.names), parents.copy(), offsets.copy(), list(skeleton.channels), local,
                  translations, skeleton.frame_time if frame_time is None else frame_time, source)
