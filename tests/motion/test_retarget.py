"""Retargeting predicted positions + axes onto a source skeleton (minifilm.motion.retarget)."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from minifilm.motion.motion import Motion
from minifilm.motion.retarget import axes_to_rotation, retarget, rotation_between


def fk(local, translations, parents):
    """Independent forward kinematics for the tests: (F, J, 3) world positions, (F, J, 3, 3)."""
    F, J = local.shape[:2]
    R = np.empty_like(local)
    P = np.empty((F, J, 3))
    for j, p in enumerate(parents):
        if p < 0:
            R[:, j], P[:, j] = local[:, j], translations[:, j]
        else:
            R[:, j] = R[:, p] @ local[:, j]
            P[:, j] = P[:, p] + np.einsum("fij,fj->fi", R[:, p], translations[:, j])
    return P, R


def toy_skeleton(F=1):
    """Root with a 3-bone spine, an arm with an End Site, and a leg with a dropped toe."""
    names = ["Hips", "Spine", "Head", "HeadSite", "Arm", "Hand", "HandSite", "Leg", "Foot", "Toe", "ToeSite"]
    parents = [-1, 0, 1, 2, 1, 4, 5, 0, 7, 8, 9]
    rng = np.random.default_rng(3)
    offsets = rng.normal(size=(11, 3)) * 0.2
    offsets[0] = 0
    channels = [("Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation")] + \
               [("Yrotation", "Xrotation", "Zrotation")] * 10
    for j in (3, 6, 10):
        channels[j] = ()
    rot = np.broadcast_to(np.eye(3), (F, 11, 3, 3)).copy()
    tr = np.broadcast_to(offsets, (F, 11, 3)).copy()
    return Motion(names, parents, offsets, channels, rot, tr, 1 / 60, "toy")


def test_axes_to_rotation_orthonormal_and_keeps_forward():
    rng = np.random.default_rng(0)
    f, u = rng.normal(size=(100, 3)), rng.normal(size=(100, 3))
    R = axes_to_rotation(f, u)
    np.testing.assert_allclose(R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)
    np.testing.assert_allclose(R[:, :, 2], f / np.linalg.norm(f, axis=1, keepdims=True), atol=1e-12)
    # a true rotation's own axes give it back
    Q = Rotation.random(50, random_state=1).as_matrix()
    np.testing.assert_allclose(axes_to_rotation(Q[:, :, 2], Q[:, :, 1]), Q, atol=1e-12)


def test_rotation_between_maps_a_to_b_including_opposite():
    rng = np.random.default_rng(1)
    a, b = rng.normal(size=(200, 3)), rng.normal(size=(200, 3))
    a[0] = [0, 0, 1.0]; b[0] = [0, 0, -2.0]
    R = rotation_between(a, b)
    got = np.einsum("nij,nj->ni", R, a / np.linalg.norm(a, axis=1, keepdims=True))
    np.testing.assert_allclose(got, b / np.linalg.norm(b, axis=1, keepdims=True), atol=1e-9)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-9)


def exported_pose(F=20, seed=0):
    skel = toy_skeleton()
    rng = np.random.default_rng(seed)
    local = Rotation.random(F * 11, random_state=seed).as_matrix().reshape(F, 11, 3, 3)
    local[:, [3, 6, 10]] = np.eye(3)  # End Sites carry no rotation
    tr = np.broadcast_to(skel.offsets, (F, 11, 3)).copy()
    tr[:, 0] = rng.normal(size=(F, 3))
    P, R = fk(local, tr, skel.parents)
    idx = np.array([0, 1, 2, 4, 5, 6, 7, 8, 9])  # HeadSite and ToeSite not exported
    return skel, local, P, R, idx


@pytest.mark.parametrize("fit", [False, True])
def test_retarget_recovers_exact_pose(fit):
    skel, local, P, R, idx = exported_pose()
    axes_R = axes_to_rotation(R[:, idx][..., 2], R[:, idx][..., 1])
    m = retarget(P[:, idx], axes_R, skel, idx, fit_positions=fit)
    np.testing.assert_allclose(m.rotations[:, idx], local[:, idx], atol=1e-9)
    np.testing.assert_allclose(m.rotations[:, [3, 10]], np.broadcast_to(np.eye(3), (20, 2, 3, 3)), atol=1e-12)
    P2, _ = fk(m.rotations, m.translations, m.parents)
    np.testing.assert_allclose(P2, P, atol=1e-9)
    assert m.channels == skel.channels and m.names == skel.names


def test_fit_positions_follows_positions_when_axes_are_off():
    skel, local, P, R, idx = exported_pose(seed=5)
    noisy = Rotation.from_rotvec(np.random.default_rng(2).normal(size=(20 * 9, 3)) * 0.3).as_matrix()
    R_noisy = noisy.reshape(20, 9, 3, 3) @ R[:, idx]
    loose = retarget(P[:, idx], R_noisy, skel, idx, fit_positions=False)
    fitted = retarget(P[:, idx], R_noisy, skel, idx, fit_positions=True)
    err_loose = np.abs(fk(loose.rotations, loose.translations, skel.parents)[0][:, idx] - P[:, idx]).max()
    Pf = fk(fitted.rotations, fitted.translations, skel.parents)[0]
    # the positions are consistent with the skeleton, so fitting recovers every exported joint
    np.testing.assert_allclose(Pf[:, idx], P[:, idx], atol=1e-5)  # up to the tiny tie-break prior
    assert err_loose > 0.01


def test_retarget_errors_name_the_problem():
    skel, local, P, R, idx = exported_pose()
    swapped = idx.copy()
    swapped[[0, 1]] = idx[[1, 0]]                     # Spine first, below the exported Hips
    with pytest.raises(ValueError, match="must be the first exported joint of its chain"):
        retarget(P[:, swapped], R[:, swapped], skel, swapped)
    with pytest.raises(ValueError, match="Leg is not below Spine"):
        retarget(P[:, idx[1:]], R[:, idx[1:]], skel, idx[1:])   # the leg hangs from the Hips
    with pytest.raises(ValueError, match="disagree"):
        retarget(P[:, idx], R[:, idx], skel, idx[:-1])


@pytest.mark.parametrize("fit", [False, True])
def test_joints_above_the_exported_root_stay_at_rest(fit):
    """Bandai files have a floor marker ``joint_Root`` above ``Hips``; exporting from the hips
    keeps the marker at rest and still reproduces every exported joint."""
    skel, local, P, R, idx = exported_pose(seed=7)
    below = np.array([1, 2, 4, 5, 6])                 # Spine and everything under it, no Hips
    m = retarget(P[:, below], R[:, below], skel, below, fit_positions=fit)
    np.testing.assert_allclose(m.rotations[:, 0], np.broadcast_to(np.eye(3), (20, 3, 3)), atol=1e-12)
    np.testing.assert_allclose(m.translations[:, 0], np.broadcast_to(skel.offsets[0], (20, 3)))
    P2, _ = fk(m.rotations, m.translations, m.parents)
    np.testing.assert_allclose(P2[:, below], P[:, below], atol=1e-9)
