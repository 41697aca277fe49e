"""Features x, p, z and clips y (minifilm/features/compute.py).

Expected values come from closed forms (a character walking on a straight line or on a circle,
built by hand here), from forward kinematics of real BVH files, and from the authors' released
normalisation statistics; never from running the code under test.
"""
import numpy as np
import pytest

from minifilm.features.compute import (
    clip_features_from_arrays, decode_joints, decode_trajectory, frame_features_from_arrays,
    seconds_to_frames, trajectory_offsets, trajectory_sample_frames)
from minifilm.features.layout import FeatureLayout


# ----------------------------------------------------------------------------- toy character
def yaw(theta):
    """LookRotation of the facing (sin t, 0, cos t): columns right, up, forward (docs/original-code.md §0.3)."""
    c, s = np.cos(theta), np.sin(theta)
    R = np.zeros(np.shape(theta) + (3, 3))
    R[..., 0, 0], R[..., 0, 2] = c, s
    R[..., 1, 1] = 1.0
    R[..., 2, 0], R[..., 2, 2] = -s, c
    return R


def rot_x(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


HIP_HEIGHT = 0.9
CHILD_OFFSET = np.array([0.1, -0.5, 0.2])   # in the hip frame
CHILD_TILT = rot_x(0.3)


def toy(heading, root_xz):
    """Two-joint character: hips above the root facing ``heading``; a child fixed in its frame.

    heading (F,), root_xz (F, 2). Returns world positions (F, 2, 3), rotations (F, 2, 3, 3),
    backward-difference velocities (F, 2, 3) * fps (set later), root_pos, root_rot.
    """
    F = heading.shape[0]
    R = yaw(heading)
    root = np.stack([root_xz[:, 0], np.zeros(F), root_xz[:, 1]], axis=1)
    hips = root + np.array([0, HIP_HEIGHT, 0])
    child = hips + R @ CHILD_OFFSET
    positions = np.stack([hips, child], axis=1)
    rotations = np.stack([R, R @ CHILD_TILT], axis=1)
    return positions, rotations, root, R


def backward_velocity(positions, fps):
    v = np.empty_like(positions)
    v[1:] = (positions[1:] - positions[:-1]) * fps
    v[0] = v[1]
    return v


def circle_walk(F, fps, speed, omega):
    """Heading omega t, position (s/w)(1 - cos wt, 0, sin wt): the facing is the walking direction."""
    t = np.arange(F) / fps
    theta = omega * t
    xz = np.stack([(speed / omega) * (1 - np.cos(theta)), (speed / omega) * np.sin(theta)], axis=1)
    return toy(theta, xz)


def circle_sample(speed, omega, tau):
    """Closed form of one trajectory sample tau seconds away, in the current root's frame."""
    a = omega * tau
    return np.array([(speed / omega) * (1 - np.cos(a)), (speed / omega) * np.sin(a), np.sin(a), np.cos(a)])


# ----------------------------------------------------------------------------- time windows
@pytest.mark.parametrize("fps, expected", [
    (60, [-60, -50, -40, -30, -20, -10, 0, 12, 24, 36, 48, 60]),   # docs/original-code.md §5 table
    (30, [-30, -25, -20, -15, -10, -5, 0, 6, 12, 18, 24, 30]),
    (120, [-120, -100, -80, -60, -40, -20, 0, 24, 48, 72, 96, 120]),
    (25, [-25, -21, -17, -13, -8, -4, 0, 5, 10, 15, 20, 25]),       # 20.83 -> 21, 4.17 -> 4
])
def test_trajectory_offsets_in_frames(fps, expected):
    assert trajectory_offsets(fps).tolist() == expected


def test_seconds_to_frames_rounds_halves_away_from_zero():
    assert seconds_to_frames([0.5, -0.5, 1.5, -1.5, 0.49], 1.0).tolist() == [1, -1, 2, -2, 0]


def test_sample_reflection_indices():
    # segment [10, 20): a past target 7 reflects about 10 to 13, a future target 23 about 19 to 15
    ref, pivot = trajectory_sample_frames(np.array([11, 18]), np.array([-4, 0, 5]), 10, 20)
    assert ref.tolist() == [[13, 11, 16], [14, 18, 15]]
    assert pivot.tolist() == [[10, -1, -1], [-1, -1, 19]]
    # a target far beyond a short segment is clamped into it
    ref, pivot = trajectory_sample_frames(np.array([1]), np.array([-10, 10]), 0, 3)
    assert ref.tolist() == [[2, 0]] and pivot.tolist() == [[0, 2]]


# ----------------------------------------------------------------------------- closed forms
@pytest.mark.parametrize("fps", [30, 60, 120])
def test_straight_walk_closed_form(fps):
    """Walking straight at 1.3 m/s with a constant 0.7 rad heading, x and z are known exactly:
    the samples lie on the local z axis at speed * time, even where they are reflected."""
    F, speed, heading = 3 * fps, 1.3, 0.7
    t = np.arange(F) / fps
    d = np.array([np.sin(heading), np.cos(heading)])
    positions, rotations, root, R = toy(np.full(F, heading), np.array([2.0, -1.0]) + speed * t[:, None] * d)
    vel = backward_velocity(positions, fps)
    phases = np.random.default_rng(0).normal(size=(F, 8))
    contacts = (np.arange(F)[:, None] % np.array([3, 4]) == 0).astype(float)
    f = frame_features_from_arrays(positions, rotations, vel, root, R, phases, contacts, fps,
                                   dtype=np.float64)
    layout = FeatureLayout(2, (-1, 0), ("Hips", "Child"))
    assert f.x.shape == (F - 2, layout.x_dim) and f.z.shape == (F - 2, layout.z_dim)
    assert f.frames.tolist() == list(range(1, F - 1))
    offsets = trajectory_offsets(fps)
    traj = f.x[:, layout.x_trajectory].reshape(-1, 12, 4)
    expected = np.stack([np.zeros(12), speed * offsets / fps, np.zeros(12), np.ones(12)], axis=1)
    np.testing.assert_allclose(traj, np.broadcast_to(expected, traj.shape), atol=1e-12)
    # joints: hips above the root facing forward, the child at its fixed offset; velocity along z
    cols = lambda field: f.x[:, layout.joint_columns("x", field)]
    np.testing.assert_allclose(cols("position")[:, 0], np.tile([0, HIP_HEIGHT, 0], (F - 2, 1)), atol=1e-12)
    np.testing.assert_allclose(cols("position")[:, 1], np.tile(CHILD_OFFSET + [0, HIP_HEIGHT, 0], (F - 2, 1)), atol=1e-12)
    np.testing.assert_allclose(cols("forward")[:, 1], np.tile(CHILD_TILT[:, 2], (F - 2, 1)), atol=1e-12)
    np.testing.assert_allclose(cols("up")[:, 1], np.tile(CHILD_TILT[:, 1], (F - 2, 1)), atol=1e-12)
    np.testing.assert_allclose(cols("velocity"), np.tile([0, 0, speed], (F - 2, 2, 1)), atol=1e-9)
    # z: the next root is speed/fps ahead; the next hips too; phases, updates, contacts of k+1
    np.testing.assert_allclose(f.z[:, layout.z_root_delta], np.tile([0, speed / fps, 0, 1], (F - 2, 1)), atol=1e-12)
    zpos = f.z[:, layout.joint_columns("z", "position")]
    np.testing.assert_allclose(zpos[:, 0], np.tile([0, HIP_HEIGHT, speed / fps], (F - 2, 1)), atol=1e-12)
    k = f.frames
    np.testing.assert_allclose(f.p, phases[k])
    np.testing.assert_allclose(f.z[:, layout.z_phases], phases[k + 1])
    np.testing.assert_allclose(f.z[:, layout.z_phase_updates], phases[k + 1] - phases[k])
    np.testing.assert_array_equal(f.z[:, layout.z_contacts], contacts[k + 1])


@pytest.mark.parametrize("fps", [30, 60])
def test_circle_walk_closed_form(fps):
    """On a circle the sample tau seconds away is ((s/w)(1-cos wt), (s/w) sin wt, sin wt, cos wt)."""
    F, speed, omega = 4 * fps, 1.1, 0.9
    positions, rotations, root, R = circle_walk(F, fps, speed, omega)
    vel = backward_velocity(positions, fps)
    f = frame_features_from_arrays(positions, rotations, vel, root, R, np.zeros((F, 8)),
                                   np.zeros((F, 2)), fps, dtype=np.float64)
    layout = FeatureLayout(2, (-1, 0), ("Hips", "Child"))
    taus = trajectory_offsets(fps) / fps
    inside = (f.frames >= fps) & (f.frames + fps < F)       # rows whose samples are all real frames
    expected = np.concatenate([circle_sample(speed, omega, tau) for tau in taus])
    np.testing.assert_allclose(f.x[inside, :48], np.tile(expected, (inside.sum(), 1)), atol=1e-10)
    # z: samples 6..11 of the next frame, seen from the current root
    expected_z = np.concatenate([circle_sample(speed, omega, tau + 1 / fps) for tau in taus[6:]])
    inside_z = f.frames + 1 + fps < F
    np.testing.assert_allclose(f.z[inside_z, :24], np.tile(expected_z, (inside_z.sum(), 1)), atol=1e-10)
    # hips velocity: a chord of the circle over one frame, in the current root's frame
    a = omega / fps
    v_expected = np.array([-(speed / omega) * (1 - np.cos(a)), 0, (speed / omega) * np.sin(a)]) * fps
    v = f.x[:, layout.joint_columns("x", "velocity")[0]]
    np.testing.assert_allclose(v, np.tile(v_expected, (len(f), 1)), atol=1e-10)


def test_segment_rows_never_read_outside_the_segment():
    """Changing every frame outside [start, stop) must not change a single feature of the segment."""
    fps, F, start, stop = 30, 200, 80, 110
    positions, rotations, root, R = circle_walk(F, fps, 1.0, 0.5)
    vel = backward_velocity(positions, fps)
    phases, contacts = np.random.default_rng(1).normal(size=(F, 8)), np.zeros((F, 2))
    a = frame_features_from_arrays(positions, rotations, vel, root, R, phases, contacts, fps, start, stop)
    rng = np.random.default_rng(2)
    outside = np.r_[0:start, stop:F]
    p2, v2, r2 = positions.copy(), vel.copy(), root.copy()
    p2[outside] += rng.normal(size=p2[outside].shape)
    v2[outside] += rng.normal(size=v2[outside].shape)
    r2[outside] += rng.normal(size=r2[outside].shape)
    b = frame_features_from_arrays(p2, rotations, v2, r2, R, phases, contacts, fps, start, stop)
    assert a.frames.tolist() == list(range(start + 1, stop - 1))
    np.testing.assert_array_equal(a.x, b.x)
    np.testing.assert_array_equal(a.z, b.z)


def test_short_segment_reflection_is_point_reflection():
    """Straight walk, segment shorter than the window: the first sample one frame before the
    segment is the reflection of the one after it about the first frame (docs/original-code.md §5)."""
    fps, F = 30, 60
    t = np.arange(F) / fps
    positions, rotations, root, R = toy(np.zeros(F), np.stack([np.zeros(F), t * (1 + t)], axis=1))
    vel = backward_velocity(positions, fps)
    f = frame_features_from_arrays(positions, rotations, vel, root, R, np.zeros((F, 8)),
                                   np.zeros((F, 2)), fps, start=20, stop=30, dtype=np.float64)
    # row of frame 21, sample 1 s back: target -9 -> ref 29 (clamped), P = 2 P(20) - P(29)
    z = lambda k: t[k] * (1 + t[k])
    row = f.x[0, :48].reshape(12, 4)
    assert row[0, 1] == pytest.approx(2 * z(20) - z(29) - z(21))
    # future 1 s: target 51 -> 2*29 - 51 = 7 -> clamped to 20, P = 2 P(29) - P(20)
    assert row[11, 1] == pytest.approx(2 * z(29) - z(20) - z(21))


def test_clip_windows_and_own_root():
    fps, F = 30, 250
    positions, rotations, root, R = circle_walk(F, fps, 1.2, 0.4)
    vel = backward_velocity(positions, fps)
    y = clip_features_from_arrays(positions, rotations, vel, root, R, fps, 4.0, 2.0, dtype=np.float64)
    # T = 120 frames, stride 60, windows start at 1: [1,121), [61,181), [121,241)
    assert y.shape == (3, 120, 24)
    # every frame is expressed in its own root, so on a uniform circle all frames are identical
    np.testing.assert_allclose(y, np.broadcast_to(y[0, 5], y.shape), atol=1e-9)
    np.testing.assert_allclose(y[0, 0, 0:3], [0, HIP_HEIGHT, 0], atol=1e-12)
    # a segment of exactly T frames gives none; T + 1 gives one
    assert clip_features_from_arrays(positions, rotations, vel, root, R, fps, start=0, stop=120).shape[0] == 0
    assert clip_features_from_arrays(positions, rotations, vel, root, R, fps, start=0, stop=121).shape[0] == 1


def test_decode_inverts_features():
    fps, F = 60, 130
    positions, rotations, root, R = circle_walk(F, fps, 1.0, 1.3)
    vel = backward_velocity(positions, fps)
    f = frame_features_from_arrays(positions, rotations, vel, root, R, np.zeros((F, 8)),
                                   np.zeros((F, 2)), fps, dtype=np.float64)
    k = f.frames
    pos, fwd, up, v = decode_joints(f.x[:, 48:], root[k], R[k])
    np.testing.assert_allclose(pos, positions[k], atol=1e-12)
    np.testing.assert_allclose(fwd, rotations[k][..., :, 2], atol=1e-12)
    np.testing.assert_allclose(up, rotations[k][..., :, 1], atol=1e-12)
    np.testing.assert_allclose(v, vel[k], atol=1e-12)
    # z's first sample is the next root
    traj_pos, traj_dir = decode_trajectory(f.z[:, :24], root[k], R[k])
    np.testing.assert_allclose(traj_pos[:, 0], root[k + 1], atol=1e-12)
    np.testing.assert_allclose(traj_dir[:, 0], R[k + 1][..., :, 2], atol=1e-12)


def test_bad_shapes_are_named():
    fps, F = 30, 20
    positions, rotations, root, R = circle_walk(F, fps, 1.0, 1.0)
    with pytest.raises(ValueError, match="phases has shape"):
        frame_features_from_arrays(positions, rotations, positions, root, R, np.zeros((F, 4)),
                                   np.zeros((F, 2)), fps)
    with pytest.raises(ValueError, match=r"segment \[5, 40\)"):
        frame_features_from_arrays(positions, rotations, positions, root, R, np.zeros((F, 8)),
                                   np.zeros((F, 2)), fps, start=5, stop=40)


# ----------------------------------------------------------------------------- real BVH files
REAL_FILES = [  # (path under shared data, expected fps)
    ("bandai2/dataset-2_walk_normal_001.bvh", 30),
    ("100style/Neutral_FR_first3frames.bvh", 60),
    ("bvh/xia/neutral_01_000.bvh", 120),
    ("bvh/bandai1/dataset-1_walk-left_normal_001.bvh", 30),
    ("bvh/cmu/08_01_trimmed.bvh", 120),
]


def _load(shared_data, rel):
    from minifilm.motion.bvh import read_bvh
    from minifilm.body.rig import detect_skeleton

    skeleton = detect_skeleton(read_bvh(shared_data / rel))
    return read_bvh(shared_data / rel, scale=skeleton.bvh_scale), skeleton


def _root_of_frame(motion, skeleton, k):
    """Root at frame k computed here from FK: hips on the floor, LookRotation of the flat facing."""
    wp, wr = motion.world()
    h = motion.index(skeleton.hips)
    f = wr[k, h] @ np.asarray(skeleton.facing_axis)
    return wp[k, h] * [1, 0, 1], yaw(np.arctan2(f[0], f[2]))


@pytest.mark.parametrize("rel, fps", REAL_FILES)
def test_reconstruct_world_joints_from_x_and_root_trajectory(shared_data, rel, fps):
    """Chain z's root deltas from the first root, then rebuild the world joints of every row from
    x's joint block: they match forward kinematics within 1e-5 m (features stored in float32)."""
    from minifilm.features.compute import frame_features

    motion, skeleton = _load(shared_data, rel)
    assert round(motion.fps) == fps
    F = motion.n_frames
    f = frame_features(motion, skeleton, np.zeros((F, 8)), np.zeros((F, 2)))
    assert f.x.dtype == np.float32
    layout = FeatureLayout.for_skeleton(skeleton)
    assert f.x.shape == (F - 2, layout.x_dim) and f.z.shape == (F - 2, layout.z_dim)
    r, R = _root_of_frame(motion, skeleton, f.frames[0])
    roots = [(r, R)]
    for delta in f.z[:-1, layout.z_root_delta].astype(np.float64):   # root of frame k+1 in root k
        r = R @ np.array([delta[0], 0.0, delta[1]]) + r
        d = R @ np.array([delta[2], 0.0, delta[3]])
        R = yaw(np.arctan2(d[0], d[2]))
        roots.append((r, R))
    root_pos = np.array([a for a, _ in roots])
    root_rot = np.array([b for _, b in roots])
    pos, fwd, up, _ = decode_joints(f.x[:, layout.x_joints], root_pos, root_rot)
    wp, wr = motion.world()
    idx = skeleton.joint_indices(motion)
    k = f.frames
    assert np.abs(pos - wp[k][:, idx]).max() < 1e-5
    assert np.abs(fwd - wr[k][:, idx][..., :, 2]).max() < 1e-5
    assert np.abs(up - wr[k][:, idx][..., :, 1]).max() < 1e-5
    # the x trajectory samples that fall inside the file are the roots of those frames
    offsets = trajectory_offsets(motion.fps)
    tpos, _ = decode_trajectory(f.x[:, layout.x_trajectory], root_pos, root_rot)
    for s, o in enumerate(offsets):
        rows = np.flatnonzero((k + o >= k[0]) & (k + o <= k[-1]))
        if rows.size:
            np.testing.assert_allclose(tpos[rows, s], root_pos[rows + o], atol=1e-5)


def test_matches_released_statistics_on_100style(shared_data):
    """The real 100STYLE frame against the authors' released Xmean / Xstd (docs/original-code.md §13.1): the
    current sample is [0,0,0,1], the hips sit at x = z = 0 facing +z, and every column is within
    4 released standard deviations of the released mean (a wrong order or axis would not be)."""
    from minifilm.features.compute import frame_features

    motion, skeleton = _load(shared_data, "100style/Neutral_FR_first3frames.bvh")
    assert skeleton.name == "100style"
    f = frame_features(motion, skeleton, np.zeros((3, 8)), np.zeros((3, 2)), dtype=np.float64)
    x_mean = np.fromfile(shared_data / "released-lpn/Xmean.bin", "<f4").astype(np.float64)
    x_std = np.fromfile(shared_data / "released-lpn/Xstd.bin", "<f4").astype(np.float64)
    layout = FeatureLayout.for_skeleton(skeleton)
    assert x_mean.shape == (layout.x_dim,) == (348,)
    np.testing.assert_allclose(f.x[0, 24:28], x_mean[24:28], atol=1e-12)
    np.testing.assert_allclose(f.x[0, [48, 50, 51]], 0.0, atol=1e-12)   # hips x, z; hips fwd x
    assert np.all(np.abs(f.x[0] - x_mean) / x_std < 4.0)
