"""The GIF's camera: projection geometry and the follow path."""
import numpy as np
import pytest

from minifilm.viewer import Camera, project
from minifilm.viewer.projection import follow_cameras, grid_step, heading_of


def test_target_projects_to_the_centre_and_up_is_up():
    cam = Camera(target=(1.0, 0.8, -2.0), azimuth=0.7, elevation=0.3, distance=5.0)
    np.testing.assert_allclose(project(np.array(cam.target), cam), [0.0, 0.0], atol=1e-12)
    above = project(np.array(cam.target) + [0, 0.5, 0], cam)
    assert above[1] > 0 and abs(above[0]) < 1e-12


def test_projection_matches_a_hand_computed_view():
    # Eye on +z looking at the origin: x stays right, y up, depth is 5 - z.
    cam = Camera(target=(0.0, 0.0, 0.0), azimuth=0.0, elevation=0.0, distance=5.0, fov=np.radians(90))
    pts = np.array([[1.0, 2.0, 0.0], [1.0, 0.0, 3.0], [-2.0, -1.0, -5.0]])
    expected = pts[:, :2] / (5.0 - pts[:, 2:3])  # focal 1 for a 90 degree field of view
    np.testing.assert_allclose(project(pts, cam), expected, atol=1e-12)
    assert cam.eye == pytest.approx([0, 0, 5])


def test_points_behind_the_camera_are_not_drawn():
    cam = Camera(target=(0.0, 0.0, 0.0), azimuth=0.0, elevation=0.0, distance=5.0)
    xy = project(np.array([[0.0, 0.0, 6.0], [0.0, 0.0, 4.0]]), cam)
    assert np.isnan(xy[0]).all() and np.isfinite(xy[1]).all()


def test_follow_cameras_track_the_smoothed_root_from_the_side():
    t = np.arange(90) / 30.0
    root = np.stack([0.05 * np.sin(2 * np.pi * 2 * t), 1.5 * t], axis=1)  # sway +-5 cm, 1.5 m/s along z
    cams = follow_cameras(root, 30.0, 1.7, heading=0.0)
    targets = np.array([c.target for c in cams])
    assert np.all(targets[:, 1] == pytest.approx(0.52 * 1.7))
    np.testing.assert_allclose(targets[:, 2], root[:, 1], atol=1e-9)  # follows a steady walk exactly
    assert np.abs(targets[15:-15, 0]).max() < 0.01  # the 5 cm sway is smoothed away (ends are pinned)
    assert all(c.distance == pytest.approx(3.4 * 1.7) and c.azimuth == pytest.approx(np.radians(60)) for c in cams)


def test_heading_and_grid_step():
    trail = np.array([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]])
    assert heading_of(trail) == pytest.approx(np.pi / 2)
    assert heading_of(np.zeros((2, 3))) == 0.0
    assert grid_step(1.7) == 0.5 and grid_step(0.17) == 0.05 and grid_step(170.0) == 50.0
