"""Trajectory control: scripts, the future-trajectory blend (§10.4) and the path-distance metric."""
import numpy as np
import pytest

from minifilm.runtime.control import (CommandScript, PathScript, blend_future_trajectory, distance_to_path,
                              figure_eight, heading_vector, make_script, strafe, walk_run_stop)


def simulate(script, seconds, fps=60.0):
    """A point character that moves exactly with the commanded velocity (ideal follower)."""
    script.reset()
    pos, face = script.start()
    track = [pos.copy()]
    for k in range(int(seconds * fps)):
        face, vel = script.command(k / fps, pos, face)
        pos = pos + vel / fps
        track.append(pos.copy())
    return np.array(track)


def test_heading_vector_convention():
    np.testing.assert_allclose(heading_vector(0.0), [0, 1], atol=1e-12)
    np.testing.assert_allclose(heading_vector(np.pi / 2), [1, 0], atol=1e-12)


def test_distance_to_path_closed_form():
    path = np.array([[0.0, 0.0], [10.0, 0.0]])
    pts = np.array([[5.0, 2.0], [-3.0, 4.0], [12.0, 0.0]])
    np.testing.assert_allclose(distance_to_path(pts, path), [2.0, 5.0, 2.0])


def test_command_script_integrates_velocity():
    # 2 s forward at 1 m/s along +z, then a sidestep at +90 deg (+x) for 2 s at 0.5 m/s
    s = CommandScript([(0, 1.0, 0, 0), (2, 1.0, 0, 0), (2, 0.5, 0, 90), (4, 0.5, 0, 90)])
    end = s.path[-1]
    np.testing.assert_allclose(end, [1.0, 2.0], atol=0.02)
    face, vel = s.command(3.0, np.zeros(2), np.array([0, 1.0]))
    np.testing.assert_allclose(face, [0, 1], atol=1e-12)
    np.testing.assert_allclose(vel, [0.5, 0], atol=1e-12)
    with pytest.raises(ValueError, match="time, speed, heading_deg, move_deg"):
        CommandScript([(0, 1.0, 0)])


def test_figure_eight_is_followed_by_ideal_character():
    s = figure_eight(seconds=40, speed=1.3, size=3.0)
    track = simulate(s, 40)
    d = distance_to_path(track, s.path)
    assert d.mean() < 0.15 and d.max() < 0.5
    # it actually goes round: covers both lobes (x of both signs) and travels ~ speed * time
    assert track[:, 0].min() < -2.5 and track[:, 0].max() > 2.5
    travelled = np.linalg.norm(np.diff(track, axis=0), axis=1).sum()
    assert abs(travelled - 1.3 * 40) < 0.05 * 1.3 * 40


def test_walk_run_stop_speeds():
    s = walk_run_stop(seconds=30, speed=1.3, run=3.5)
    track = simulate(s, 30)
    speed = np.linalg.norm(np.diff(track, axis=0), axis=1) * 60
    assert abs(speed[5 * 60] - 1.3) < 1e-6
    assert abs(speed[15 * 60] - 3.5) < 1e-6
    assert speed[-60:].max() < 1e-9  # stopped at the end


@pytest.mark.parametrize("seconds", [1.0, 5.0, 9.0])
def test_walk_run_stop_any_length(seconds):
    """Short scripts keep their keyframes in order: walk, run, walk, stop in thirds of the time."""
    track = simulate(walk_run_stop(seconds=seconds, speed=1.0, run=2.0), seconds)
    speed = np.linalg.norm(np.diff(track, axis=0), axis=1) * 60
    n = len(speed)
    assert abs(speed[n // 6] - 1.0) < 1e-6 and abs(speed[n // 3: 2 * n // 3].max() - 2.0) < 1e-6
    assert speed[-2] < 1e-6
    with pytest.raises(ValueError, match="positive"):
        walk_run_stop(seconds=0.0)


def test_strafe_keeps_facing_while_moving_sideways():
    s = strafe(seconds=12, speed=1.0)
    s.reset()
    pos, face = s.start()
    sideways = 0
    for k in range(12 * 60):
        face, vel = s.command(k / 60, pos, face)
        np.testing.assert_allclose(face, [0, 1])
        if np.linalg.norm(vel) > 0 and abs(vel[0]) > 0.9 * np.linalg.norm(vel):
            sideways += 1
        pos = pos + vel / 60
    assert sideways > 6 * 60


def test_make_script_unknown_name():
    with pytest.raises(KeyError, match="figure8"):
        make_script("moonwalk", 10)


def test_path_script_rejects_bad_waypoints():
    with pytest.raises(ValueError, match="waypoints"):
        PathScript([[0, 0, 0]])


def test_blend_keeps_root_and_weights_far_samples_to_user():
    # network predicts standing still facing +z; user wants 1 m/s along +x facing +x
    S = 6
    P = np.zeros((1, S, 2))
    D = np.tile([0.0, 1.0], (1, S, 1))
    p, d = blend_future_trajectory(P, D, np.array([[1.0, 0.0]]), np.array([[1.0, 0.0]]), sample_dt=0.2)
    np.testing.assert_allclose(p[0, 0], [0, 0])
    np.testing.assert_allclose(d[0, 0], [0, 1])
    # last sample follows the user fully: steps of the user's displacement weighted by 1-(1-w)^0.75
    w = np.arange(1, S) / (S - 1)
    expected_x = np.cumsum((1 - (1 - w) ** 0.75) * 0.2)
    np.testing.assert_allclose(p[0, 1:, 0], expected_x)
    np.testing.assert_allclose(d[0, -1], [1, 0])
    np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 1.0)
    # and if the network already does what the user wants, nothing changes
    P2 = np.zeros((1, S, 2)); P2[0, :, 0] = 0.2 * np.arange(S)
    D2 = np.tile([1.0, 0.0], (1, S, 1))
    p2, d2 = blend_future_trajectory(P2, D2, np.array([[1.0, 0.0]]), np.array([[1.0, 0.0]]), 0.2)
    np.testing.assert_allclose(p2, P2, atol=1e-12)
    np.testing.assert_allclose(d2, D2, atol=1e-12)
