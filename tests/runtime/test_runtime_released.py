"""The runtime driving the authors' released network (../shared/data/released-lpn).

A minute of motion (3,600 frames at 60 fps) for three walking styles at once (one batch), put on
the 100STYLE skeleton every frame: the network's own bone lengths stable, hips at a human height,
the commanded figure-eight followed; style blending; BVH export read back with the project's
reader; foot locking.
"""
import numpy as np
import pytest

from minifilm.runtime.control import distance_to_path, figure_eight, straight_walk
from minifilm.motion.bvh import read_bvh
from minifilm.motion.bvh_write import write_bvh
from minifilm.runtime.held_body import foot_locker
from minifilm.motion.measures import foot_sliding
from minifilm.features.layout import FeatureLayout
from minifilm.motion.skeletons import STYLE100
from minifilm.runtime.controller import Controller
from minifilm.runtime.start_state import root_joint_indices
from minifilm.runtime.network import RuntimeNetwork
from minifilm.runtime.style_library import StyleLibrary
from repo_paths import need_data

WALKING = ("Neutral", "Old", "Zombie")
MINUTE = 3600


@pytest.fixture(scope="module")
def released(shared_data):
    from minifilm.runtime.released import load_released

    folder = need_data(shared_data / "released-lpn", "the released network")
    rel = load_released(folder)
    net = RuntimeNetwork.from_model(rel.model, rel.stats, runtime_layer_norm=True)
    layout = FeatureLayout.for_skeleton(STYLE100)
    return net, layout, StyleLibrary(rel.styles)


@pytest.fixture(scope="module")
def skeleton(shared_data):
    header = need_data(shared_data / "100style" / "Neutral_FR_first3frames.bvh", "the 100STYLE header")
    return read_bvh(header)


@pytest.fixture(scope="module")
def minute(released, skeleton):
    net, layout, lib = released
    scripts = [figure_eight(MINUTE / 60, speed=1.3) for _ in WALKING]
    films = np.stack([lib[s] for s in WALKING])
    # as examples/generate_released.py runs it: the fitted pose fed back, as the demo feeds back its post-IK pose
    ctrl = Controller(net, layout, skeleton=Controller.skeleton_for(layout, skeleton), feed_back_fit=True)
    return ctrl.run(scripts, MINUTE, films), scripts


def bone_cv(P, parents):
    bones = np.linalg.norm(P[:, 1:] - P[:, parents[1:]], axis=-1)         # (F, 24)
    return bones.std(axis=0) / bones.mean(axis=0)


def test_minute_rollout_is_stable_and_follows_the_path(minute):
    r, scripts = minute
    assert np.all(np.isfinite(r.positions))
    parents = np.array(STYLE100.parents)
    for b, style in enumerate(WALKING):
        # after the first second (the start pose is the data's mean pose); the network's own
        # prediction, before the velocity blend and the skeleton fit
        cv = bone_cv(r.network_positions[b, 60:].astype(np.float64), parents)
        assert cv.max() < 0.05, f"{style}: bone {STYLE100.joints[1 + cv.argmax()]} varies {cv.max():.1%}"
        # the output is a pose of the skeleton: rigid bones
        assert bone_cv(r.positions[b, 60:], parents).max() < 1e-6
        hips = r.positions[b, :, 0, 1]
        assert 0.6 < hips.min() and hips.max() < 1.2, f"{style}: hips between {hips.min():.2f} and {hips.max():.2f} m"
        d = distance_to_path(r.root_positions[b], scripts[b].path)
        print(f"{style}: bone CV max {cv.max():.2%}, hips {hips.min():.2f}-{hips.max():.2f} m, "
              f"path distance mean {d.mean():.2f} m, max {d.max():.2f} m")
        assert d.mean() < 0.5, f"{style}: mean distance to the commanded path {d.mean():.2f} m"
        # it keeps walking: the root travels at least 15 m in the minute
        travelled = np.linalg.norm(np.diff(r.root_positions[b], axis=0), axis=1).sum()
        assert travelled > 15.0, f"{style}: root travelled only {travelled:.1f} m in a minute"


def test_bvh_export_reads_back_and_reproduces_positions(minute, skeleton, tmp_path):
    r, _ = minute
    layout = FeatureLayout.for_skeleton(STYLE100)
    idx = root_joint_indices(layout, skeleton)
    F = 600
    part = type(r)(*(getattr(r, k)[:, :F] for k in ("positions", "rotations", "contacts", "phases",
                                                    "root_positions", "root_facing", "targets")), r.fps)
    motion = part.to_motion(skeleton, idx)
    write_bvh(motion, tmp_path / "out.bvh")
    back = read_bvh(tmp_path / "out.bvh")
    assert back.names == skeleton.names and back.channels == skeleton.channels
    assert back.n_frames == F and abs(back.frame_time - 1 / 60) < 1e-6
    P, _ = back.world()
    # the runtime's skeleton motion (fixed bone lengths) comes back from the file exactly
    P_mem, _ = motion.world()
    assert np.abs(P - P_mem).max() < 1e-3
    # and it reproduces the generated joint positions (the BVH text keeps 6 decimals of cm / degree)
    err = np.linalg.norm(P[:, idx] - r.positions[0, :F], axis=-1)            # (F, 25) metres
    print(f"BVH FK vs generated joints: mean {err.mean() * 100:.5f} cm, max {err.max() * 100:.5f} cm")
    assert err.max() < 0.01
    assert err.mean() < 1e-4


def test_style_blend_endpoints_exact_and_intermediate_smooth(released):
    net, layout, lib = released
    a, b = "Neutral", "Zombie"
    weights = [0.0, 0.25, 0.5, 0.75, 1.0]
    films = np.stack([lib[a]] + [lib.blend({a: 1 - w, b: w}) for w in weights] + [lib[b]])
    F = 300
    r = Controller(net, layout).run([straight_walk(F / 60) for _ in films], F, films)
    np.testing.assert_array_equal(films[1], films[0])
    np.testing.assert_array_equal(films[-2], films[-1])
    np.testing.assert_array_equal(r.positions[1], r.positions[0])   # same film -> same motion, bit for bit
    np.testing.assert_array_equal(r.positions[-2], r.positions[-1])
    # pose in the root's frame, averaged over the last 3 s: moves steadily from a to b
    x_local = r.positions[1:-1, 120:, :, 0] - r.root_positions[1:-1, 120:, None, 0]
    pose = np.stack([x_local, r.positions[1:-1, 120:, :, 1]], axis=-1).mean(axis=1)  # (5, J, 2)
    step = np.array([np.linalg.norm(pose[i + 1] - pose[i]) for i in range(4)])
    total = np.linalg.norm(pose[-1] - pose[0])
    assert total > 0.05, "the two styles should differ visibly"
    assert step.max() < 0.6 * total, f"a jump between neighbouring weights: steps {step}, total {total}"


def test_foot_locking_reduces_sliding(released):
    net, layout, lib = released
    toes = [layout.joint_names.index("RightToe"), layout.joint_names.index("LeftToe")]
    F = 600
    slide = {}
    for lock in (False, True):
        locker = foot_locker(layout) if lock else None
        r = Controller(net, layout, foot_locker=locker).run(figure_eight(F / 60), F, lib["Neutral"])
        slide[lock] = foot_sliding(r.positions[0, 60:], r.contacts[0, 60:], toes, fps=60)
    print(f"foot sliding (toe speed in contact): {slide[False]:.3f} m/s without, {slide[True]:.3f} m/s with locking")
    assert slide[True] < 0.5 * slide[False]
