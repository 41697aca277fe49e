"""Fitting predicted joints onto a rigid skeleton (minifilm.motion.skeleton_fit)."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from minifilm.motion.motion import Motion
from minifilm.motion.skeleton_fit import SkeletonFit


def skeleton():
    """Hips with a spine (two exported children of the chest), a leg, and an arm whose shoulder
    is a dropped (not exported) joint with exported joints below it."""
    names = ["Hips", "Chest", "Head", "Shoulder", "Elbow", "Hand", "Leg", "Foot", "FootSite"]
    parents = [-1, 0, 1, 1, 3, 4, 0, 6, 7]
    rng = np.random.default_rng(0)
    offsets = rng.normal(size=(9, 3)) * 0.2
    offsets[0] = 0
    F = 1
    ch = [("Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation")] + \
         [("Zrotation", "Xrotation", "Yrotation")] * 7 + [()]
    return Motion(names, parents, offsets, ch, np.broadcast_to(np.eye(3), (F, 9, 3, 3)).copy(),
                  np.broadcast_to(offsets, (F, 9, 3)).copy(), 1 / 30, "toy")


EXPORTED = np.array([0, 1, 2, 4, 5, 6, 7])          # Shoulder and FootSite are not exported


def fk(skel, world_local_rot, root):
    """Independent FK: (N, J, 3) from local rotations (N, J, 3, 3) and root positions (N, 3)."""
    N, J = world_local_rot.shape[:2]
    R, P = np.empty_like(world_local_rot), np.empty((N, J, 3))
    for j, p in enumerate(skel.parents):
        if p < 0:
            R[:, j], P[:, j] = world_local_rot[:, j], root
        else:
            R[:, j] = R[:, p] @ world_local_rot[:, j]
            P[:, j] = P[:, p] + R[:, p] @ skel.offsets[j]
    return P, R


def posed(N=16, seed=0):
    skel = skeleton()
    local = Rotation.random(N * 9, random_state=seed).as_matrix().reshape(N, 9, 3, 3)
    local[:, 3] = np.eye(3)                 # a dropped joint never rotates, or no fit could know it
    P, R = fk(skel, local, np.random.default_rng(seed).normal(size=(N, 3)))
    return skel, P, R


def test_a_pose_the_skeleton_can_take_is_returned_unchanged():
    skel, P, R = posed()
    pos, rot = SkeletonFit(skel, EXPORTED).fit(P[:, EXPORTED], R[:, EXPORTED])
    np.testing.assert_allclose(pos, P[:, EXPORTED], atol=1e-6)   # up to the Kabsch tie-break prior
    np.testing.assert_allclose(rot, R[:, EXPORTED], atol=1e-5)


def test_stretched_bones_come_back_to_rest_length_along_the_predicted_direction():
    skel, P, R = posed(seed=1)
    fit = SkeletonFit(skel, EXPORTED)
    rng = np.random.default_rng(2)
    noisy = P[:, EXPORTED] + rng.normal(size=P[:, EXPORTED].shape) * 0.02
    pos, rot = fit.fit(noisy, R[:, EXPORTED])
    parents_e = [-1, 0, 1, -1, 3, 0, 5]       # exported parent of each exported joint (Elbow's is dropped)
    for e, pe in enumerate(parents_e):
        if pe >= 0:
            rest = np.linalg.norm(skel.offsets[EXPORTED[e]])
            np.testing.assert_allclose(np.linalg.norm(pos[:, e] - pos[:, pe], axis=-1), rest, rtol=1e-9)
    # single-child bones point where the prediction points, from where the fit put the joint
    for e, pe in ((6, 5), (4, 3)):            # Leg -> Foot, Elbow -> Hand
        want = noisy[:, e] - pos[:, pe]
        got = pos[:, e] - pos[:, pe]
        cos = np.sum(want * got, -1) / np.linalg.norm(want, axis=-1) / np.linalg.norm(got, axis=-1)
        np.testing.assert_allclose(cos, 1.0, atol=1e-9)
    # rotations are proper and carry the positions: FK of the fitted locals gives the fitted positions
    np.testing.assert_allclose(np.linalg.det(rot), 1.0, atol=1e-9)


def test_fit_matches_the_bvh_writer():
    """retarget() builds its local rotations from the same fit, so FK of the BVH lands on fit()."""
    from minifilm.motion.retarget import retarget

    skel, P, R = posed(seed=3)
    noisy = P[:, EXPORTED] + np.random.default_rng(4).normal(size=P[:, EXPORTED].shape) * 0.01
    pos, _ = SkeletonFit(skel, EXPORTED).fit(noisy, R[:, EXPORTED])
    m = retarget(noisy, R[:, EXPORTED], skel, EXPORTED)
    P2, _ = fk(skel, m.rotations, m.translations[:, 0])
    np.testing.assert_allclose(P2[:, EXPORTED], pos, atol=1e-9)


def test_bad_shapes_and_orders_are_named():
    skel, P, R = posed()
    fit = SkeletonFit(skel, EXPORTED)
    with pytest.raises(ValueError, match=r"expected \(N, 7, 3\)"):
        fit.fit(P[:, :5], R[:, :5])
    with pytest.raises(ValueError, match="must be the first exported joint"):
        SkeletonFit(skel, [1, 0, 2])
    with pytest.raises(ValueError, match="distinct indices"):
        SkeletonFit(skel, [0, 1, 1])
