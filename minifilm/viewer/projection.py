"""The 2-D projection the GIF / MP4 renderer draws with: a perspective ``Camera`` and ``project``.

The renderer does its own projection in NumPy and hands matplotlib plain 2-D lines, instead of
using matplotlib's 3-D axes: that is several times faster (no 3-D artist machinery per frame), and
the drawn numbers are exactly ``project(positions, camera)``, which a test can check against the
BVH forward kinematics.

Screen coordinates: x to the right, y up, in units of the focal plane, so the view spans
y in [-1, 1] and x in [-aspect, aspect] for a vertical field of view ``fov``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import List

import numpy as np
from scipy.ndimage import gaussian_filter1d

__all__ = ["Camera", "project", "follow_cameras", "grid_step"]

UP = np.array([0.0, 1.0, 0.0])


@dataclass(frozen=True)
class Camera:
    """A perspective camera looking at ``target`` from a direction given by two angles.

    Attributes:
        target:    (3,) point at the centre of the view, metres.
        azimuth:   radians about +y; the eye is at
                   ``target + distance * (cos(el) sin(az), sin(el), cos(el) cos(az))``.
        elevation: radians above the horizontal (positive looks down onto the floor).
        distance:  eye-to-target distance, metres.
        fov:       vertical field of view, radians.
    """

    target: tuple
    azimuth: float
    elevation: float
    distance: float
    fov: float = np.radians(30.0)

    @property
    def eye(self) -> np.ndarray:
        ce = np.cos(self.elevation)
        direction = np.array([ce * np.sin(self.azimuth), np.sin(self.elevation), ce * np.cos(self.azimuth)])
        return np.asarray(self.target, dtype=np.float64) + self.distance * direction

    def basis(self) -> np.ndarray:
        """(3, 3) rows: right, up, forward (unit vectors, world axes)."""
        forward = np.asarray(self.target, dtype=np.float64) - self.eye
        forward /= np.linalg.norm(forward)
        right = np.cross(forward, UP)
        right /= np.linalg.norm(right)
        return np.stack([right, np.cross(right, forward), forward])


def project(points: np.ndarray, camera: Camera, near: float = 1e-3) -> np.ndarray:
    """Perspective projection of world points to screen coordinates.

    Args:
        points: (..., 3) world positions, metres.
        camera: the camera.
        near:   points closer than ``near * distance`` in depth (or behind the eye) become NaN,
                which matplotlib draws as a gap in a line.
    Returns:
        (..., 2) screen x (right) and y (up); the view spans y in [-1, 1].
    """
    cam = (np.asarray(points, dtype=np.float64) - camera.eye) @ camera.basis().T  # (..., 3) right, up, depth
    depth = cam[..., 2:3]
    focal = 1.0 / np.tan(camera.fov / 2.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        xy = focal * cam[..., :2] / depth
    return np.where(depth > near * camera.distance, xy, np.nan)


def depth_of(points: np.ndarray, camera: Camera) -> np.ndarray:
    """(...,) distance of ``points`` (..., 3) along the viewing direction, metres."""
    return (np.asarray(points, dtype=np.float64) - camera.eye) @ camera.basis()[2]


def follow_cameras(root_xz: np.ndarray, fps: float, size: float, heading: float,
                   elevation: float = np.radians(12.0)) -> List[Camera]:
    """One camera per frame, following a character's root.

    Args:
        root_xz: (N, 2) horizontal root position (world x, z) at each drawn frame, metres.
        fps:     drawn frames per second (sets the smoothing window in frames).
        size:    body size, metres: the camera stands ``3.4 * size`` away and aims ``0.52 * size``
                 above the floor, which frames a standing person with room for a step.
        heading: radians about +y of the character's overall direction of travel; the camera looks
                 from 60 degrees to its side (a three-quarter view shows both the stride and the
                 arm swing of a gait).
    The target is the root's floor position smoothed over about 0.25 s, so the root's side-to-side
    sway shows as motion of the character instead of shaking the whole picture.
    """

    xz = np.asarray(root_xz, dtype=np.float64)
    if len(xz) > 2:
        sigma = max(0.25 * fps, 1e-3)
        # Point-symmetric padding keeps a steady walk exact at both ends (padding by repeating
        # the end point would make the camera lag behind the walker near the first/last frame).
        n = min(len(xz) - 1, int(np.ceil(4 * sigma)))
        padded = np.concatenate([2 * xz[0] - xz[n:0:-1], xz, 2 * xz[-1] - xz[-2:-n - 2:-1]])
        xz = gaussian_filter1d(padded, sigma=sigma, axis=0, mode="nearest")[n:n + len(xz)]
    azimuth = heading + np.radians(60.0)
    return [Camera(target=(float(x), 0.52 * size, float(z)), azimuth=float(azimuth),
                   elevation=float(elevation), distance=3.4 * size) for x, z in xz]


def heading_of(trail: np.ndarray) -> float:
    """Direction of travel (radians about +y, 0 = +z) from first to last point of an (F, 3) path.

    0 when the path does not move (an in-place clip).
    """
    d = np.asarray(trail[-1] - trail[0], dtype=np.float64)
    if np.hypot(d[0], d[2]) < 1e-6:
        return 0.0
    return float(np.arctan2(d[0], d[2]))


def grid_step(size: float) -> float:
    """Floor grid spacing for a body of ``size`` metres: a 1-2-5 number near ``size / 3.4``.

    0.5 m for a person (size ~1.7 m); a file in other units keeps about as many lines.
    """
    raw = max(size / 3.4, 1e-9)
    decade = 10.0 ** np.floor(np.log10(raw))
    for m in (1.0, 2.0, 5.0, 10.0):
        if raw <= m * decade * 1.5:
            return float(m * decade)
    return float(10.0 * decade)
