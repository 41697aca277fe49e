"""Tests for minifilm.motion.kinematics: checked against SciPy, closed forms and geometric properties."""
import re

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from minifilm.motion import editing as E
from minifilm.motion import kinematics as K
from minifilm.motion.motion import Motion

ORDERS = ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"]


def rx(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def ry(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rz(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


HAND = {"X": rx, "Y": ry, "Z": rz}


def random_angles(rng, n):
    a = rng.uniform(-np.pi, np.pi, (n, 3))
    a[:, 1] = rng.uniform(-np.pi / 2 + 1e-3, np.pi / 2 - 1e-3, n)   # principal branch of the middle angle
    return a


# ------------------------------------------------------------------ Euler angles

@pytest.mark.parametrize("order", ORDERS)
def test_euler_to_matrix_matches_hand_product_and_scipy_intrinsic(order):
    rng = np.random.default_rng(1)
    a = rng.uniform(-4, 4, (50, 3))
    R = K.euler_to_matrix(a, order)
    hand = np.stack([HAND[order[0]](x) @ HAND[order[1]](y) @ HAND[order[2]](z) for x, y, z in a])
    np.testing.assert_allclose(R, hand, atol=1e-12)
    # SciPy: capital letters = intrinsic rotations, the BVH convention.
    np.testing.assert_allclose(R, Rotation.from_euler(order, a).as_matrix(), atol=1e-12)


@pytest.mark.parametrize("order", ORDERS)
def test_matrix_to_euler_recovers_principal_angles_and_agrees_with_scipy(order):
    rng = np.random.default_rng(2)
    a = random_angles(rng, 200)
    R = Rotation.from_euler(order, a).as_matrix()
    back = K.matrix_to_euler(R, order)
    np.testing.assert_allclose(back, a, atol=1e-9)
    np.testing.assert_allclose(back, Rotation.from_matrix(R).as_euler(order), atol=1e-9)


@pytest.mark.parametrize("order", ORDERS)
def test_matrix_to_euler_round_trips_any_rotation_including_gimbal_lock(order):
    rng = np.random.default_rng(3)
    R = Rotation.random(300, random_state=4).as_matrix()
    a = rng.uniform(-np.pi, np.pi, (20, 3))
    a[:10, 1] = np.pi / 2
    a[10:, 1] = -np.pi / 2
    R = np.concatenate([R, K.euler_to_matrix(a, order)])
    back = K.euler_to_matrix(K.matrix_to_euler(R, order), order)
    np.testing.assert_allclose(back, R, atol=1e-9)


def test_euler_rejects_unknown_order():
    with pytest.raises(ValueError, match="Euler order"):
        K.euler_to_matrix(np.zeros(3), "XXY")


# ------------------------------------------------------------------ quaternions

def test_quaternions_agree_with_scipy_including_half_turns():
    R = Rotation.random(500, random_state=5).as_matrix()
    half_turns = Rotation.from_rotvec(np.pi * np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1],
                                                        [1, 1, 0] / np.sqrt(2)])).as_matrix()
    R = np.concatenate([R, half_turns, np.eye(3)[None]])
    q = K.matrix_to_quat(R)
    ref = Rotation.from_matrix(R).as_quat(scalar_first=True)
    # q and -q are the same rotation
    sign = np.sign(np.sum(q * ref, axis=-1, keepdims=True))
    np.testing.assert_allclose(q, sign * ref, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-12)
    np.testing.assert_allclose(K.quat_to_matrix(q), R, atol=1e-12)


def test_quat_multiply_composes_like_matrices():
    R1 = Rotation.random(50, random_state=6).as_matrix()
    R2 = Rotation.random(50, random_state=7).as_matrix()
    q = K.quat_multiply(K.matrix_to_quat(R1), K.matrix_to_quat(R2))
    np.testing.assert_allclose(K.quat_to_matrix(q), R1 @ R2, atol=1e-12)


def test_slerp_is_constant_speed_along_the_short_arc():
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    q0 = K.matrix_to_quat(np.eye(3))
    q1 = K.matrix_to_quat(Rotation.from_rotvec(2.0 * axis).as_matrix())
    for t in (0.0, 0.25, 0.5, 1.0):
        expected = Rotation.from_rotvec(2.0 * t * axis).as_matrix()
        for other in (q1, -q1):   # the double cover must not change the path
            np.testing.assert_allclose(K.quat_to_matrix(K.slerp(q0, other, t)), expected, atol=1e-12)
    # nearly identical quaternions: no division by ~0
    q2 = K.matrix_to_quat(Rotation.from_rotvec(1e-9 * axis).as_matrix())
    assert np.all(np.isfinite(K.slerp(q0, q2, 0.5)))


# ------------------------------------------------------------------ forward kinematics

def test_forward_kinematics_closed_form_chain():
    # Root at (1, 2, 3) turned 90 deg about +y; child 1 m along local x, bent 90 deg about z;
    # grandchild 0.5 m along its local x.
    F = 2
    rot = np.tile(np.eye(3), (F, 3, 1, 1))
    rot[:, 0] = ry(np.pi / 2)
    rot[:, 1] = rz(np.pi / 2)
    trans = np.zeros((F, 3, 3))
    trans[:, 0] = [1, 2, 3]
    trans[:, 1] = [1, 0, 0]
    trans[:, 2] = [0.5, 0, 0]
    trans[1, 0] = [0, 0, 0]
    P, W = K.forward_kinematics(rot, trans, [-1, 0, 1])
    # ry(90) maps x -> -z; rz(90) then maps x -> y (untouched by ry)
    np.testing.assert_allclose(P[0], [[1, 2, 3], [1, 2, 2], [1, 2.5, 2]], atol=1e-12)
    np.testing.assert_allclose(P[1], [[0, 0, 0], [0, 0, -1], [0, 0.5, -1]], atol=1e-12)
    np.testing.assert_allclose(W[0, 2], ry(np.pi / 2) @ rz(np.pi / 2), atol=1e-12)


def test_forward_kinematics_rejects_bad_parent_order():
    with pytest.raises(ValueError, match="parent"):
        K.forward_kinematics(np.tile(np.eye(3), (1, 2, 1, 1)), np.zeros((1, 2, 3)), [1, -1])


def test_axes_are_matrix_columns():
    R = Rotation.random(4, random_state=8).as_matrix()
    np.testing.assert_allclose(K.forward_axis(R), R @ [0, 0, 1])
    np.testing.assert_allclose(K.up_axis(R), R @ [0, 1, 0])
    np.testing.assert_allclose(K.right_axis(R), R @ [1, 0, 0])


def test_velocities_backward_difference_first_frame_copies_second():
    t = np.arange(5) / 60.0
    x = np.stack([2.0 * t, -t ** 2, np.zeros_like(t)], axis=-1)[:, None, :]  # (F, 1, 3)
    v = K.velocities(x, 60.0)
    np.testing.assert_allclose(v[1:, 0, 0], 2.0)
    np.testing.assert_allclose(v[1:, 0, 1], -(t[1:] ** 2 - t[:-1] ** 2) * 60.0)
    np.testing.assert_allclose(v[0], v[1])
    assert np.all(K.velocities(x[:1], 60.0) == 0)


# ------------------------------------------------------------------ root-relative coordinates

def test_look_rotation_matches_the_explicit_matrix():
    f = np.array([[3.0, 0.7, 4.0], [0.0, 1.0, 0.0]])
    R = K.look_rotation(f)
    fx, fz = 0.6, 0.8
    np.testing.assert_allclose(R[0], [[fz, 0, fx], [0, 1, 0], [-fx, 0, fz]], atol=1e-12)
    np.testing.assert_allclose(R[1], np.eye(3))  # no horizontal part -> facing +Z
    np.testing.assert_allclose(np.linalg.det(R), 1.0)


def test_to_local_closed_form_and_inverses():
    # Root at (1, 0, 2) facing +x: a point 1 m in front of it is local (0, 0, 1),
    # a point 1 m to its right (-z in world) is local (1, 0, 0).
    p = np.array([[1.0, 0.0, 2.0]])
    R = K.look_rotation(np.array([[1.0, 0.0, 0.0]]))
    pts = np.array([[[2.0, 0.0, 2.0], [1.0, 0.5, 1.0]]])          # (F=1, N=2, 3)
    np.testing.assert_allclose(K.to_local(pts, p, R), [[[0, 0, 1], [1, 0.5, 0]]], atol=1e-12)
    np.testing.assert_allclose(K.directions_to_local(np.array([[1.0, 0, 0]]), R), [[0, 0, 1]], atol=1e-12)

    rng = np.random.default_rng(9)
    F = 6
    pos = rng.normal(size=(F, 3))
    rot = Rotation.random(F, random_state=10).as_matrix()
    x = rng.normal(size=(F, 4, 3))
    np.testing.assert_allclose(K.from_local(K.to_local(x, pos, rot), pos, rot), x, atol=1e-12)
    np.testing.assert_allclose(K.directions_from_local(K.directions_to_local(x, rot), rot), x, atol=1e-12)
    # per-frame use with (F, 3) points too
    np.testing.assert_allclose(K.to_local(pos, pos, rot), 0.0, atol=1e-12)


# ------------------------------------------------------------------ mirroring

@pytest.mark.parametrize("name,other", [
    ("LeftArm", "RightArm"), ("RightWristSite", "LeftWristSite"), ("LHipJoint", "RHipJoint"),
    ("RThumb", "LThumb"), ("rCollar", "lCollar"), ("Hand_L", "Hand_R"), ("Toes_RSite", "Toes_LSite"),
    ("leftEye", "rightEye"), ("Hips", "Hips"), ("LowerBack", "LowerBack"), ("Leg", "Leg"),
])
def test_mirror_name(name, other):
    assert E.mirror_name(name) == other


def _mirror_check(motion):
    m = E.mirror(motion)
    P, W = motion.world()
    Pm, Wm = m.world()
    sym = E.mirror_pairs(motion.names)
    M = np.diag([-1.0, 1.0, 1.0])
    S = E.joint_reflections(motion)
    np.testing.assert_allclose(Pm, P[:, sym] * [-1, 1, 1], atol=1e-9)
    np.testing.assert_allclose(Wm, M @ W[:, sym] @ S, atol=1e-9)
    np.testing.assert_allclose(np.linalg.det(Wm), 1.0, atol=1e-9)
    back = E.mirror(m)
    np.testing.assert_allclose(back.world()[0], P, atol=1e-9)
    return sym


def test_mirror_real_files(shared_data):
    from minifilm.motion.bvh import read_bvh
    files = [shared_data / "100style" / "Neutral_FR_first3frames.bvh",
             shared_data / "bvh" / "bandai1" / "dataset-1_walk_normal_001.bvh",
             shared_data / "bvh" / "xia" / "sexy_01_000.bvh",
             shared_data / "bvh" / "cmu" / "08_01_trimmed.bvh"]
    for path in files:
        motion = read_bvh(path)
        sym = _mirror_check(motion)
        # every side-specific joint found its partner
        for j, name in enumerate(motion.names):
            if "Left" in name or "Right" in name or re.search(r"_[LR](Site)?$", name):
                assert sym[j] != j, (path.name, name)


def test_joint_reflections_per_skeleton(shared_data):
    """T-pose skeletons (CMU, Xia, 100STYLE) mirror every joint with diag(-1, 1, 1), as the
    original does; the Bandai skeleton's axes run along its bones (limbs -I, spine diag(1, 1, -1),
    hips diag(1, -1, 1))."""
    from minifilm.motion.bvh import read_bvh
    M = np.diag([-1.0, 1.0, 1.0])
    for path in (shared_data / "100style" / "Neutral_FR_first3frames.bvh", shared_data / "bvh" / "cmu" / "08_01_trimmed.bvh",
                 shared_data / "bvh" / "xia" / "angry_13_000.bvh"):
        S = E.joint_reflections(read_bvh(path))
        np.testing.assert_array_equal(S, np.broadcast_to(M, S.shape), err_msg=path.name)
    bandai = read_bvh(shared_data / "bvh" / "bandai1" / "dataset-1_walk_normal_001.bvh")
    S = E.joint_reflections(bandai)
    expected = {"Hips": [1, -1, 1], "Spine": [1, 1, -1], "Head": [1, 1, -1], "UpperArm_L": [-1, -1, -1],
                "Hand_R": [-1, -1, -1], "Foot_L": [-1, -1, -1]}
    for name, diagonal in expected.items():
        np.testing.assert_array_equal(S[bandai.index(name)], np.diag(diagonal), err_msg=name)


def test_joint_reflections_agree_across_files(shared_data):
    """Measured from each file's motion, yet the same for every file of a skeleton: walking,
    running, walking backwards and turning (the reference joint on the floor aside)."""
    from minifilm.motion.bvh import read_bvh
    folder = shared_data / "bvh" / "bandai1"
    files = sorted(folder.glob("*.bvh"))
    first = read_bvh(files[0])
    reference = E.joint_reflections(first)
    for path in files[1:]:
        S = E.joint_reflections(read_bvh(path))
        for j, name in enumerate(first.names):
            if name not in ("joint_Root", "Head", "HeadSite"):      # the root never rotates; a sidestep turns the head
                np.testing.assert_array_equal(S[j], reference[j], err_msg=f"{path.name}: {name}")


def test_mirrored_features_lie_where_real_features_do(shared_data):
    """The point of S_j: a mirrored Bandai walk's features, z-scored by the real walk's own mean
    and deviation, look like real data (the original's M R M puts them ~25 deviations off)."""
    from minifilm.features.compute import frame_features
    from minifilm.motion.bvh import read_bvh
    from minifilm.motion.skeletons import builtin_skeleton
    from minifilm.phases.label import label
    motion = read_bvh(shared_data / "bvh" / "bandai1" / "dataset-1_walk_normal_001.bvh")
    skeleton = builtin_skeleton("bandai")
    rows = []
    for m in (motion, E.mirror(motion)):
        labels = label(m, skeleton, "walk")
        rows.append(frame_features(m, skeleton, labels.vectors, labels.contacts, fps=m.fps).x)
    mean, std = rows[0].mean(axis=0), rows[0].std(axis=0) + 1e-3
    assert np.mean(np.abs((rows[1] - mean) / std)) < 1.5


def test_mirror_rejects_asymmetric_hierarchy():
    m = Motion(["Hips", "LeftLeg", "Spine", "RightLeg"], [-1, 0, 0, 2], np.zeros((4, 3)),
               [("Yrotation",)] * 4, np.tile(np.eye(3), (1, 4, 1, 1)), np.zeros((1, 4, 3)), 1 / 30)
    with pytest.raises(ValueError, match="symmetric"):
        E.mirror(m)


# ------------------------------------------------------------------ resampling

def _spinning_motion(fps, seconds):
    """Root turning about +y at 1 rad/s and walking along x at 1.5 m/s; child with a fixed bend."""
    t = np.arange(int(round(seconds * fps)) + 1) / fps
    F = len(t)
    rot = np.tile(np.eye(3), (F, 2, 1, 1))
    rot[:, 0] = Rotation.from_rotvec(np.outer(t, [0, 1.0, 0])).as_matrix()
    rot[:, 1] = rx(0.3)
    trans = np.zeros((F, 2, 3))
    trans[:, 0, 0] = 1.5 * t
    trans[:, 1] = [0, 0.5, 0]
    return Motion(["Hips", "Chest"], [-1, 0], [[0, 0, 0], [0, 0.5, 0]],
                  [("Xposition", "Yposition", "Zposition", "Yrotation", "Xrotation", "Zrotation"),
                   ("Yrotation", "Xrotation", "Zrotation")], rot, trans, 1.0 / fps)


def test_resample_halving_keeps_every_second_frame(shared_data):
    from minifilm.motion.bvh import read_bvh
    real = read_bvh(shared_data / "bvh" / "bandai1" / "dataset-1_walk_normal_001.bvh")
    # exact 1/30 s so that 15 fps frames fall exactly on old frames
    m = Motion(real.names, real.parents, real.offsets, real.channels, real.rotations, real.translations, 1 / 30)
    half = E.resample(m, 15)
    assert half.fps == pytest.approx(15)
    assert half.n_frames == (m.n_frames - 1) // 2 + 1
    np.testing.assert_allclose(half.rotations, m.rotations[::2], atol=1e-10)
    np.testing.assert_allclose(half.translations, m.translations[::2], atol=1e-12)


def test_resample_120_60_120_reconstructs_constant_speed_motion():
    m = _spinning_motion(120, 2.0)
    down = E.resample(m, 60)
    np.testing.assert_allclose(down.world()[0], m.world()[0][::2], atol=1e-10)
    up = E.resample(down, 120)
    assert up.n_frames == m.n_frames
    # slerp/lerp midpoints of a constant-velocity motion are exactly the dropped frames
    np.testing.assert_allclose(up.rotations, m.rotations, atol=1e-10)
    np.testing.assert_allclose(up.world()[0], m.world()[0], atol=1e-10)


def test_resample_to_non_integer_ratio_interpolates_in_time():
    m = _spinning_motion(60, 1.0)
    r = E.resample(m, 25)
    t = np.arange(r.n_frames) / 25
    assert t[-1] <= 1.0 + 1e-9 and r.n_frames == 26
    np.testing.assert_allclose(r.translations[:, 0, 0], 1.5 * t, atol=1e-12)
    # angle about y grows at 1 rad/s (slerp between frames 1/60 s apart is exact for constant spin)
    expected = Rotation.from_rotvec(np.outer(t, [0, 1.0, 0])).as_matrix()
    np.testing.assert_allclose(r.rotations[:, 0], expected, atol=1e-10)


def test_resample_60_to_30_with_rounded_frame_time(shared_data):
    """Files store 1/60 s as 0.016667: halving the rate must still pick every second frame."""
    from minifilm.motion.bvh import read_bvh
    real = read_bvh(shared_data / "100style" / "Neutral_FR_first3frames.bvh")
    assert real.frame_time == 0.016667
    half = E.resample(real, 30)
    assert half.n_frames == 2 and half.frame_time == pytest.approx(1 / 30)
    np.testing.assert_allclose(half.world()[0], real.world()[0][::2], atol=1e-12)
    # a long synthetic take, where a rounded frame time would otherwise drift by frames
    spin = _spinning_motion(60, 20.0)
    spin = Motion(spin.names, spin.parents, spin.offsets, spin.channels, spin.rotations, spin.translations,
                  0.016667)
    half = E.resample(spin, 30)
    assert half.n_frames == (spin.n_frames - 1) // 2 + 1
    np.testing.assert_allclose(half.rotations, spin.rotations[::2], atol=1e-10)
    np.testing.assert_allclose(half.translations, spin.translations[::2], atol=1e-12)
