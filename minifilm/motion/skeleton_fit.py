"""Fit predicted joints onto a rigid skeleton: the pose the character can actually take.

The network predicts every exported joint's world position and forward/up axes independently, so
its bones stretch and shrink by a few millimetres from frame to frame (the released network's
8-9 cm collar and chest bones by up to 10 %). The original demo's arm IK re-solves the arm bones
one at a time towards the predicted positions with their lengths kept (docs/original-code.md §10.3
step 7); :class:`SkeletonFit` does the same for the whole body, on the source skeleton's rest
offsets:

* a joint with one exported child is swung by the smallest rotation from its predicted axes so the
  bone points at the predicted child (its twist still comes from the axes), and the child is put
  at the bone's rest length along that direction;
* a joint with several exported children (hips, upper chest) gets the best-fit (Kabsch) rotation
  of its rest bones onto the predicted ones;
* bones aim from where the fit has put their joint, not from where that joint was predicted, so a
  bone's length error moves only its own child and does not pile up sideways down the chain.

The result is forward kinematics of the skeleton: world positions and rotations of the exported
joints (N, Je, ...) that a BVH on the same skeleton reproduces exactly. The runtime uses it every
frame (:class:`minifilm.runtime.controller.Controller`, ``skeleton=``) and the BVH writer uses it to get local
rotations (:func:`minifilm.motion.retarget.retarget`).
"""
from __future__ import annotations

from typing import Sequence, Tuple

import numpy as np

from minifilm.motion.motion import Motion

__all__ = ["SkeletonFit", "rotation_between", "best_fit_rotation"]


def _unit(v: np.ndarray, eps: float = 1e-9) -> np.ndarray:
    # einsum rather than np.linalg.norm: this runs every frame on tiny arrays, where call overhead rules
    return v / np.sqrt(np.maximum(np.einsum("...i,...i->...", v, v), eps * eps))[..., None]


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b along the last axis (np.cross costs several times more on tiny arrays)."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation taking direction a to direction b: (..., 3, 3).

    Rodrigues with v = a x b and c = a . b (unit a, b): ``R = c I + [v]x + v v^T / (1 + c)``.
    Opposite directions (a = -b) have no unique smallest rotation; they get a half turn about an
    axis perpendicular to a.
    """
    a = _unit(np.asarray(a, dtype=np.float64))
    b = _unit(np.asarray(b, dtype=np.float64))
    v = _cross(a, b)
    c = np.einsum("...i,...i->...", a, b)
    opposite = c < -1 + 1e-9
    R = v[..., :, None] * (v / np.maximum(1.0 + c, 1e-12)[..., None])[..., None, :]
    for i in range(3):
        R[..., i, i] += c
    R[..., 0, 1] -= v[..., 2]
    R[..., 0, 2] += v[..., 1]
    R[..., 1, 0] += v[..., 2]
    R[..., 1, 2] -= v[..., 0]
    R[..., 2, 0] -= v[..., 1]
    R[..., 2, 1] += v[..., 0]
    if np.any(opposite):
        # half turn R = 2 n n^T - I about an axis n perpendicular to a: cross a with whichever
        # basis vector is least parallel to it
        e = np.where(np.abs(a[..., :1]) < 0.9, np.array([1.0, 0, 0]), np.array([0, 1.0, 0]))
        n = _unit(_cross(a, e))
        half = 2.0 * n[..., :, None] * n[..., None, :] - np.eye(3)
        R = np.where(opposite[..., None, None], half, R)
    return R


def best_fit_rotation(rest: np.ndarray, want: np.ndarray, prior: np.ndarray, prior_weight: float = 1e-6) -> np.ndarray:
    """Rotation R (N, 3, 3) best mapping rest bone vectors (C, 3) onto wanted ones (N, C, 3).

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


class SkeletonFit:
    """The exported joints of a layout placed on a source skeleton (see the module doc).

    Args:
        skeleton: a Motion whose hierarchy and rest offsets define the body (its frames are not
            used), e.g. the 100STYLE BVH header.
        joint_indices: (Je,) index into ``skeleton`` joints of each exported joint. Exported joint 0
            is the skeleton's root or hangs below joints that are not exported (Bandai's
            ``joint_Root`` above ``Hips``); those stay at rest with no rotation.
    """

    def __init__(self, skeleton: Motion, joint_indices: Sequence[int]):
        idx = np.asarray(joint_indices, dtype=np.int64)
        J = skeleton.n_joints
        if idx.ndim != 1 or len(idx) == 0 or idx.min() < 0 or idx.max() >= J or len(set(idx.tolist())) != len(idx):
            raise ValueError(f"SkeletonFit: joint_indices must be distinct indices into the "
                             f"{J} joints of {skeleton.source}, got {idx.tolist()}")
        parents = np.asarray(skeleton.parents)
        self.skeleton, self.joint_indices, self.parents = skeleton, idx, parents
        self.offsets = np.asarray(skeleton.offsets, dtype=np.float64)
        self.root = root = int(idx[0])
        exported = -np.ones(J, dtype=np.int64)
        exported[idx] = np.arange(len(idx))
        self.exported = exported
        ancestors = []                          # joints above exported joint 0, from the top down
        a = parents[root]
        while a >= 0:
            ancestors.insert(0, int(a))
            a = parents[a]
        if any(exported[a] >= 0 for a in ancestors):
            raise ValueError(f"exported joint 0 ({skeleton.names[root]}) must be the first "
                             f"exported joint of its chain in {skeleton.source}")
        for j in idx[1:]:
            a = parents[j]
            while a >= 0 and a != root:
                a = parents[a]
            if a != root:
                raise ValueError(f"exported joint {skeleton.names[j]} is not below "
                                 f"{skeleton.names[root]} (exported joint 0) in {skeleton.source}")
        self.ancestors = ancestors
        # ancestors stay at rest with identity rotations, so exported joint 0's parent sits here
        self.above_root = self.offsets[ancestors].sum(axis=0) if ancestors else np.zeros(3)

        # the exported children each exported joint is fitted to (a zero-length bone has no direction)
        self.fit_children = [[c for c in range(J) if parents[c] == j and exported[c] >= 0
                              and np.linalg.norm(self.offsets[c]) > 1e-9] if exported[j] >= 0 else []
                             for j in range(J)]
        below = np.zeros(J, dtype=bool)          # has an exported joint at or below it
        for j in range(J - 1, -1, -1):
            below[j] |= exported[j] >= 0
            if parents[j] >= 0:
                below[parents[j]] |= below[j]
        # the joints forward kinematics must visit: exported joints and the links between them
        self.order = [j for j in range(J) if below[j] and (j == root or j not in ancestors)
                      and self._under_root(j)]
        self.swing = [j for j in range(J) if len(self.fit_children[j]) == 1]
        self.kabsch = [j for j in range(J) if len(self.fit_children[j]) > 1]
        # a swung joint whose rotation is needed before the end (it carries a joint it is not
        # fitted to, e.g. a dropped bone with exported joints below) is rotated on the way
        self.swing_early = {j for j in self.swing
                            if any(parents[c] == j and c in self.order and c not in self.fit_children[j]
                                   for c in range(J))}
        self.rest_length = np.linalg.norm(self.offsets, axis=-1)
        self.levels = self._plan()
        rotated = {j for level in self.levels for j in level[4]}
        self.late = np.array([j for j in self.swing if j not in rotated], dtype=np.int64)
        self.late_child = np.array([self.fit_children[j][0] for j in self.late], dtype=np.int64)
        self.leaves = np.array([j for j in idx if j not in rotated and j not in self.late], dtype=np.int64)

    def _plan(self):
        """Forward kinematics level by level (a level = joints at the same depth below exported
        joint 0), each level as two vectorised groups: 'aim' joints (the one fitted child of a
        swung parent: placed at rest length towards the prediction, no rotation needed yet) and
        'rigid' joints (placed by the parent's final rotation and the rest offset). Returns a list
        of (aim children, aim parents, rigid children, rigid parents, joints rotated at this level)."""
        depth = {self.root: 0}
        for j in self.order[1:]:
            depth[j] = depth[int(self.parents[j])] + 1
        levels = []
        for d in range(max(depth.values()) + 1):
            joints = [j for j in self.order if depth[j] == d]
            aim = [j for j in joints if d > 0 and self.parents[j] in self.swing
                   and self.parents[j] not in self.swing_early and j in self.fit_children[self.parents[j]]]
            rigid = [j for j in joints if d > 0 and j not in aim]
            rotated = [j for j in joints if j in self.kabsch or j in self.swing_early or self.exported[j] < 0]
            levels.append((np.array(aim, dtype=np.int64), self.parents[aim].astype(np.int64),
                           np.array(rigid, dtype=np.int64), self.parents[rigid].astype(np.int64), rotated))
        return levels

    def _under_root(self, j: int) -> bool:
        while j >= 0 and j != self.root:
            j = self.parents[j]
        return j == self.root

    def check(self, positions: np.ndarray, rotations: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        P = np.asarray(positions, dtype=np.float64)
        Rw = np.asarray(rotations, dtype=np.float64)
        Je = len(self.joint_indices)
        if P.ndim != 3 or P.shape[1:] != (Je, 3) or Rw.shape != P.shape[:2] + (3, 3):
            raise ValueError(f"positions {P.shape} and rotations {Rw.shape} do not match {Je} "
                             f"exported joints; expected (N, {Je}, 3) and (N, {Je}, 3, 3)")
        return P, Rw

    def world(self, positions: np.ndarray, rotations: np.ndarray, all_joints: bool = True
              ) -> Tuple[np.ndarray, np.ndarray]:
        """World rotations (N, J, 3, 3) of the skeleton's joints, fitted to the predicted positions,
        and forward-kinematics positions (N, J, 3) of the joints in ``order`` (others are 0).

        positions (N, Je, 3) and rotations (N, Je, 3, 3): the predicted world positions and world
        rotations (e.g. :func:`~minifilm.motion.retarget.axes_to_rotation`) of the exported joints.
        ``all_joints=False`` leaves the rotations of joints that are not exported unset (faster).
        """
        P, Rw = self.check(positions, rotations)
        N, J = len(P), self.skeleton.n_joints
        ex, par, off = self.exported, self.parents, self.offsets
        world = np.empty((N, J, 3, 3))
        done = np.zeros(J, dtype=bool)             # world[j] final
        fk = np.zeros((N, J, 3))
        fk[:, self.root] = P[:, 0]
        for aim, aim_parent, rigid, rigid_parent, rotated in self.levels:
            if len(aim):
                # the swing will point the bone at the prediction: the child lands on it at rest length
                fk[:, aim] = fk[:, aim_parent] + self.rest_length[aim, None] * _unit(P[:, ex[aim]] - fk[:, aim_parent])
            if len(rigid):
                fk[:, rigid] = fk[:, rigid_parent] + np.einsum("nkij,kj->nki", world[:, rigid_parent], off[rigid])
            for j in rotated:
                if ex[j] < 0:
                    world[:, j] = world[:, par[j]] if par[j] >= 0 else np.eye(3)
                elif j in self.kabsch:
                    kids = self.fit_children[j]
                    world[:, j] = best_fit_rotation(off[kids], P[:, ex[kids]] - fk[:, j, None], Rw[:, ex[j]])
                else:                                  # a swing needed early
                    c = self.fit_children[j][0]
                    world[:, j] = rotation_between(Rw[:, ex[j]] @ off[c], P[:, ex[c]] - fk[:, j]) @ Rw[:, ex[j]]
                done[j] = True
        late, kids = self.late, self.late_child
        if len(late):  # every remaining swing in one batched call
            R0 = Rw[:, ex[late]]                                           # (N, k, 3, 3)
            swing = rotation_between(np.einsum("nkij,kj->nki", R0, off[kids]), fk[:, kids] - fk[:, late])
            world[:, late] = swing @ R0
            done[late] = True
        world[:, self.leaves] = Rw[:, ex[self.leaves]]     # exported joints with nothing to aim at
        done[self.leaves] = True
        if all_joints:
            for j in range(J):  # joints outside the fit follow their parent
                if not done[j]:
                    world[:, j] = world[:, par[j]] if par[j] >= 0 else np.eye(3)
        return world, fk

    def fit(self, positions: np.ndarray, rotations: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """The exported joints on the skeleton: positions (N, Je, 3) and rotations (N, Je, 3, 3)."""
        world, fk = self.world(positions, rotations, all_joints=False)
        return fk[:, self.joint_indices], world[:, self.joint_indices]
