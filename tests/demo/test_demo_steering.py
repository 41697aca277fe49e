"""Keys and sticks to the controller's target (minifilm/demo/steering.py): W walks along the
heading, D steps to the character's right, Q/E turn it, nothing held stops."""
import math

import numpy as np
import pytest

from minifilm.demo.steering import Steering, heading_vector, right_vector
from minifilm.synthetic.generator import rest_motion


def test_the_right_vector_is_the_characters_right():
    # a 100STYLE character facing +z (heading 0) has its left hip towards +x
    P, _ = rest_motion().world()
    names = rest_motion().names
    left_hip, right_hip = P[0, names.index("LeftHip")], P[0, names.index("RightHip")]
    across = (right_hip - left_hip)[[0, 2]]
    assert np.dot(across, right_vector(0.0)) > 0.2
    for theta in np.linspace(-3, 3, 7):                       # perpendicular, to the right, at any heading
        f, r = heading_vector(theta), right_vector(theta)
        assert abs(f @ r) < 1e-12 and f[0] * r[1] - f[1] * r[0] > 0


def test_keys_give_directions_relative_to_the_heading():
    s = Steering(walk_speed=1.3, run_speed=2.8)
    s.reset(theta=0.7)
    s.hold((0.0, 1.0), 0.0, 0.0)                               # W
    facing, velocity, speed = s.advance(1 / 60)
    np.testing.assert_allclose(velocity, 1.3 * heading_vector(0.7))
    np.testing.assert_allclose(facing, heading_vector(0.7))
    assert speed == 1.3
    s.hold((1.0, 0.0), 0.0, 1.0)                               # D with Shift: run to the right
    _, velocity, speed = s.advance(1 / 60)
    np.testing.assert_allclose(velocity, 2.8 * right_vector(0.7))
    s.hold((1.0, 1.0), 0.0, 0.0)                               # W + D: a diagonal at full walking speed
    _, velocity, _ = s.advance(1 / 60)
    assert np.linalg.norm(velocity) == pytest.approx(1.3)
    s.hold((0.0, -1.0), 0.0, 0.0)                              # S: backwards, still facing the heading
    facing, velocity, _ = s.advance(1 / 60)
    assert velocity @ facing == pytest.approx(-1.3)


def test_nothing_held_stops_and_a_stick_held_half_way_walks_slower():
    s = Steering(walk_speed=1.0, run_speed=3.0)
    s.hold((0.0, 0.0), 0.0, 1.0)
    _, velocity, speed = s.advance(1 / 60)
    assert speed == 0.0 and not velocity.any()
    s.hold((0.0, 0.5), 0.0, 0.5)                                # half a stick, trigger half way
    _, velocity, speed = s.advance(1 / 60)
    assert speed == pytest.approx(0.5 * 2.0)


def test_e_turns_right_and_q_left_at_the_turn_rate():
    s = Steering(turn_rate=math.radians(90))
    s.hold((0.0, 0.0), 1.0, 0.0)                               # E for one second
    for _ in range(60):
        facing, _, _ = s.advance(1 / 60)
    np.testing.assert_allclose(facing, right_vector(0.0), atol=1e-9)
    s.hold((0.0, 0.0), -1.0, 0.0)                              # Q for two seconds: 90 degrees left of the start
    for _ in range(120):
        facing, _, _ = s.advance(1 / 60)
    np.testing.assert_allclose(facing, -right_vector(0.0), atol=1e-9)
