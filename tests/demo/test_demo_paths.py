"""The paths the demo page draws ahead of its character (minifilm/demo/paths.py): the held input's
path against the straight line and the circular arc it must follow, and the frame message's
``future`` / ``futureFacing`` / ``path`` against the controller's state."""
import math

import numpy as np
import pytest

from demo_helpers import tiny_source  # noqa: F401  (a fixture)
from minifilm.demo.calibrations import Calibrations
from minifilm.demo.character import Character, DemoSettings
from minifilm.demo.paths import PathCache, commanded_path
from minifilm.demo.protocol import InputMessage, encode
from minifilm.demo.steering import Steering

SECONDS = np.linspace(0.0, 1.0, 11)


def test_walking_straight_is_a_line_along_the_heading():
    s = Steering(walk_speed=1.3, theta=0.7)
    s.hold((0.0, 1.0), 0.0, 0.0)
    path = commanded_path(s, np.array([2.0, -1.0]), SECONDS)
    heading = np.array([math.sin(0.7), math.cos(0.7)])
    np.testing.assert_allclose(path, [2.0, -1.0] + 1.3 * SECONDS[:, None] * heading, atol=1e-12)
    assert s.theta == 0.7                                          # the character's own steering untouched


def test_walking_and_turning_is_the_circle_the_heading_turns_on():
    # W + E at full turn: heading theta(t) = theta0 - w t, the root on a circle of radius v / w
    v, w, theta0 = 1.3, math.radians(120.0), 0.3
    s = Steering(walk_speed=v, turn_rate=w, theta=theta0)
    s.hold((0.0, 1.0), 1.0, 0.0)
    path = commanded_path(s, np.zeros(2), SECONDS)
    th = theta0 - w * SECONDS
    arc = np.stack([(v / w) * (np.cos(th) - math.cos(theta0)), -(v / w) * (np.sin(th) - math.sin(theta0))], axis=1)
    assert np.abs(path - arc).max() < 0.005                        # metres: a smooth arc, not a chord of it
    assert np.abs(path[-1]).max() > 0.5                            # and it went somewhere


def test_a_scaled_command_shortens_the_path_and_nothing_held_stays_put():
    s = Steering(walk_speed=1.3)
    s.hold((1.0, 0.0), 0.0, 0.0)                                   # D: to the right, (-cos 0, sin 0)
    np.testing.assert_allclose(commanded_path(s, np.zeros(2), SECONDS, scale=0.5)[-1], [-0.65, 0.0], atol=1e-12)
    s.hold((0.0, 0.0), 1.0, 0.0)                                   # only turning: the root stays
    np.testing.assert_allclose(commanded_path(s, np.array([1.0, 2.0]), SECONDS), np.tile([1.0, 2.0], (11, 1)))


def test_the_cached_path_equals_the_plain_one_at_any_heading():
    rng = np.random.default_rng(3)
    cache = PathCache(size=4)
    for _ in range(40):
        s = Steering(theta=float(rng.uniform(-math.pi, math.pi)))
        s.hold(tuple(rng.choice([-1.0, 0.0, 0.5, 1.0], 2)), float(rng.choice([-1.0, 0.0, 1.0])), float(rng.uniform(0, 1)))
        root, scale = rng.normal(size=2) * 5, float(rng.choice([1.0, 0.6]))
        np.testing.assert_allclose(cache.path(s, root, SECONDS, scale), commanded_path(s, root, SECONDS, scale),
                                   atol=1e-12)
    assert len(cache._paths) <= 4                                  # it forgets, it does not grow


def test_frames_carry_the_predicted_trajectory_and_the_held_path(tiny_source):
    ch = Character(1, tiny_source, Calibrations(tiny_source), DemoSettings(style=tiny_source.default_style()))
    ch.submit(InputMessage((0.0, 1.0), 0.0, 0.0, seq=1))
    for _ in range(5):
        frame, _ = ch.step()
    st = ch.ctrl.state
    S = st.future_pos.shape[1]
    assert len(frame["future"]) == len(frame["futureFacing"]) == 2 * S == 12
    np.testing.assert_allclose(np.reshape(frame["future"], (S, 2)), st.future_pos[0], atol=1e-4)
    np.testing.assert_allclose(np.reshape(frame["futureFacing"], (S, 2)), st.future_dir[0], atol=1e-4)
    path = np.reshape(frame["path"], (-1, 2))
    assert len(path) == 11
    np.testing.assert_allclose(path[0], frame["root"], atol=1e-4)  # from where the character stands...
    heading = np.array(frame["heading"])
    assert (path[-1] - path[0]) @ heading == pytest.approx(frame["reachable"] * 1.0, abs=1e-3)   # ...1 s ahead
    assert all(math.isfinite(x) for k in ("future", "futureFacing", "path") for x in frame[k])
    encode(frame)                                                  # JSON without NaN
