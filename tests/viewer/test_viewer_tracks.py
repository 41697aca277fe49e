"""Track: validation, and the builders from a Motion / BVH file (which joints and bones are drawn)."""
import numpy as np
import pytest

from minifilm.motion.bvh import BVHError, read_bvh
from minifilm.viewer import Track, as_tracks, track_from_bvh, track_from_motion

from repo_paths import need_data
from viewer_helpers import foot_contacts, synthetic_walker


def test_synthetic_track_is_the_forward_kinematics(walker):
    track = track_from_motion(walker, name="walker")
    P, _ = walker.world()
    assert track.name == "walker"
    assert track.joint_names == walker.names  # no joint sits on its parent: all kept
    np.testing.assert_array_equal(track.positions, P)
    np.testing.assert_array_equal(track.parents, walker.parents)
    assert track.fps == pytest.approx(30.0)
    assert track.root == 0
    np.testing.assert_allclose(track.trail[:, [0, 2]], P[:, 0, [0, 2]])
    assert np.all(track.trail[:, 1] == 0)


def test_default_name_is_the_file_stem(walker):
    assert track_from_motion(walker).name == "synthetic"


def test_bandai_drops_zero_sites_and_the_static_root(bandai_walk):
    motion = read_bvh(bandai_walk)
    track = track_from_bvh(bandai_walk)
    P, _ = motion.world()
    assert "joint_Root" not in track.joint_names  # fixed at the origin: would draw a stretching line
    assert not any(n.endswith("Site") for n in track.joint_names)  # all zero-length in Bandai files
    assert track.joint_names[0] == "Hips" and track.root == 0
    idx = [motion.names.index(n) for n in track.joint_names]
    # the viewer scales positions computed in the file's unit (units.scaled): equal up to rounding
    np.testing.assert_allclose(track.positions, P[:, idx], rtol=1e-12, atol=1e-12)
    # Every drawn bone keeps its length: no translation link is drawn as a bone.
    lengths = np.linalg.norm(track.positions[:, track.bones[:, 0]] - track.positions[:, track.bones[:, 1]], axis=2)
    assert np.ptp(lengths, axis=0).max() < 1e-6
    assert lengths.min() > 0.01
    # Parents in the track are the file's hierarchy, renumbered.
    for j, p in enumerate(track.parents):
        if p >= 0:
            assert motion.parents[idx[j]] == idx[p]


def test_a_moving_floor_root_is_not_drawn_either(shared_data):
    # Bandai 1 walk-back: the translation is on joint_Root, which moves on the floor under Hips.
    path = need_data(shared_data / "bvh" / "bandai1" / "dataset-1_walk-back_normal_001.bvh", "a real BVH")
    motion = read_bvh(path)
    assert np.ptp(motion.world()[0][:, 0], axis=0).max() > 1.0  # joint_Root walks
    track = track_from_bvh(path)
    assert "joint_Root" not in track.joint_names and track.joint_names[0] == "Hips"
    assert (track.parents < 0).sum() == 1


def test_non_rigid_bones_stay_drawn(walker):
    # A generated skeleton whose shin stretches must show it, not lose the bone.
    leg = walker.names.index("LeftLeg")
    walker.translations[:, leg, 1] *= np.linspace(1.0, 1.3, walker.n_frames)
    track = track_from_motion(walker)
    assert list(track.parents) == list(walker.parents)


def test_explicit_joints_reattach_to_the_nearest_kept_ancestor(walker):
    track = track_from_motion(walker, joints=["Hips", "LeftUpLeg", "LeftFoot", 3])
    assert track.joint_names == ["Hips", "HeadSite", "LeftUpLeg", "LeftFoot"]
    assert list(track.parents) == [-1, 0, 0, 2]


def test_contact_joints_by_name_map_to_track_indices(walker):
    P, _ = walker.world()
    feet = [walker.names.index("LeftFootSite"), walker.names.index("RightFootSite")]
    contacts = foot_contacts(P, 30.0, feet)
    track = track_from_motion(walker, contacts=contacts, contact_joints=["LeftFootSite", "RightFootSite"])
    assert [track.joint_names[j] for j in track.contact_joints] == ["LeftFootSite", "RightFootSite"]
    assert track.in_contact().shape == contacts.shape


def test_as_tracks_accepts_tracks_motions_and_paths(walker, bandai_walk):
    tracks = as_tracks([walker, str(bandai_walk), track_from_motion(walker, name="x")])
    assert [t.name for t in tracks] == ["synthetic", bandai_walk.stem, "x"]
    with pytest.raises(TypeError, match="cannot draw a int"):
        as_tracks([3])
    with pytest.raises(ValueError, match="no tracks"):
        as_tracks([])


def _track(**changes):
    args = dict(name="t", positions=np.zeros((4, 3, 3)), parents=[-1, 0, 1], fps=30.0)
    args["positions"][:, :, 1] = [0.0, 1.0, 2.0]
    args.update(changes)
    return Track(**args)


@pytest.mark.parametrize("changes, message", [
    (dict(positions=np.zeros((0, 3, 3))), "no frames"),
    (dict(positions=np.zeros((4, 3))), r"shape \(4, 3\), expected \(frames, joints, 3\)"),
    (dict(parents=[-1, 0]), r"parents has shape \(2,\), expected \(3,\)"),
    (dict(parents=[-1, 2, 1]), r"parents\[1\] = 2"),
    (dict(fps=0.0), "fps must be positive"),
    (dict(contacts=np.zeros((4, 1))), "without contact_joints"),
    (dict(contacts=np.zeros((3, 1)), contact_joints=[2]), r"contacts has shape \(3, 1\), expected \(4, 1\)"),
    (dict(contacts=np.full((4, 1), 1.5), contact_joints=[2]), r"must lie in \[0, 1\]; frame 0"),
    (dict(contacts=np.zeros((4, 1)), contact_joints=[7]), "not a joint index"),
    (dict(trail=np.zeros((4, 2))), r"trail has shape"),
    (dict(root=5), "root = 5"),
])
def test_bad_tracks_raise_one_clear_error(changes, message):
    with pytest.raises(ValueError, match=message):
        _track(**changes)


def test_non_finite_positions_name_frame_and_joint():
    P = np.zeros((5, 3, 3))
    P[3, 2, 1] = np.nan
    with pytest.raises(ValueError, match=r"Track 't': positions are not finite .* frame 3, Head"):
        Track("t", P, [-1, 0, 1], 30.0, joint_names=["Hips", "Spine", "Head"])


def test_empty_motion_is_one_clear_error():
    empty = synthetic_walker().slice(0, 0)
    with pytest.raises(ValueError, match="synthetic.bvh: the motion has no frames"):
        track_from_motion(empty)


def test_unreadable_and_non_bvh_files(tmp_path):
    with pytest.raises(FileNotFoundError, match="missing.bvh"):
        track_from_bvh(tmp_path / "missing.bvh")
    junk = tmp_path / "picture.bvh"
    junk.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(range(256)))
    with pytest.raises(BVHError, match="picture.bvh"):
        track_from_bvh(junk)


def test_unknown_joint_names_are_named(walker):
    with pytest.raises(ValueError, match="'Tail', which is not a joint"):
        track_from_motion(walker, joints=["Hips", "Tail"])
