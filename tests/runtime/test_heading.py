"""The runtime's turn correction (minifilm/runtime/heading.py): the predicted frame is turned about
its next root towards the steered heading, by a share of the error, only while moving."""
import numpy as np
import pytest

from minifilm.runtime.heading import HeadingFollow, rotate_about, signed_angle


def unit(deg):
    a = np.radians(np.atleast_1d(deg))
    return np.stack([np.sin(a), np.cos(a)], axis=-1)


def test_the_signed_angle_follows_the_heading_convention_and_wraps():
    assert np.degrees(signed_angle(unit(0), unit(90))) == pytest.approx([90])
    assert np.degrees(signed_angle(unit(170), unit(-170))) == pytest.approx([20])
    assert np.degrees(signed_angle(unit(-30), unit(-60))) == pytest.approx([-30])


def test_a_share_of_the_error_is_taken_up_capped_and_nothing_while_standing():
    f = HeadingFollow(tau=0.15, max_rate=360.0)
    dt = 1 / 60
    step = f.correction(unit([0, 0, 0]), unit([30, -30, 30]), np.array([True, True, False]), dt)
    share = 1 - np.exp(-dt / 0.15)
    assert np.degrees(step) == pytest.approx([30 * share, -30 * share, 0.0])
    big = f.correction(unit(0), unit(179), np.array([True]), dt)
    assert np.degrees(big) == pytest.approx([6.0])                   # 360 deg/s at most
    with pytest.raises(ValueError, match="tau"):
        HeadingFollow(tau=0.0)


def test_the_frame_is_turned_rigidly_about_the_next_root():
    rng = np.random.default_rng(0)
    centre = np.array([[1.0, 2.0]])
    pos = centre[:, None] + rng.normal(size=(1, 6, 2))
    pos[:, 0] = centre
    dirs = unit(rng.uniform(-180, 180, 6))[None]
    joints = rng.normal(size=(1, 5, 3)) + np.array([1.0, 0.0, 2.0])
    vel = rng.normal(size=(1, 5, 3))
    p2, d2, j2, (v2,) = rotate_about(centre, np.radians([90.0]), pos, dirs, joints, [vel])
    assert np.allclose(p2[:, 0], centre)                             # the next root stays
    assert np.allclose(np.linalg.norm(p2 - centre[:, None], axis=-1), np.linalg.norm(pos - centre[:, None], axis=-1))
    assert np.allclose(np.degrees(signed_angle(dirs[0], d2[0])), 90.0)
    assert np.allclose(j2[..., 1], joints[..., 1]) and np.allclose(np.linalg.norm(v2, axis=-1), np.linalg.norm(vel, axis=-1))
    # +90 degrees turns +z onto +x: a joint 1 m ahead of the root ends 1 m to its +x
    ahead = np.array([[[1.0, 0.5, 3.0]]])
    assert np.allclose(rotate_about(centre, np.radians([90.0]), pos, dirs, ahead, [])[2], [[[2.0, 0.5, 2.0]]])


def test_walking_with_the_heading_turning_the_released_body_follows_it(shared_data):
    from repo_paths import need_data
    from minifilm.demo.source import DemoSource
    from minifilm.runtime.control import CommandScript
    from minifilm.runtime.controller import Controller
    from minifilm.runtime.root_frames import floor_angle
    src = DemoSource.released(need_data(shared_data / "released-lpn", "the released network"), calibrate=False)
    styles = ["Neutral", "Old"]
    films = np.stack([src.library[s] for s in styles])
    scripts = [CommandScript([(0.0, 3.0, 0.0, 0.0), (5.0, 3.0, -600.0, 0.0)]) for _ in styles]  # W+E, 120 deg/s
    target = unit(-120.0 * 299 / 60)
    errors = {}
    for follow in (None, HeadingFollow()):
        ctrl = Controller(src.network, src.layout, skeleton=Controller.skeleton_for(src.layout, src.skeleton),
                          feed_back_fit=True, heading_follow=follow)
        r = ctrl.run(scripts, 300, films)
        errors[follow is not None] = floor_angle(r.root_facing[:, -1], target)
    assert np.all(errors[True] <= 30.0), errors
    assert errors[False].max() > 30.0, errors        # the paper's loop alone lags (Old barely turns)
