"""Keeping the body on the heading the user steers while it walks: the runtime's turn correction.

The paper's loop (Sec. 4.4) turns the character only through the future trajectory it is shown:
the far samples face the user's heading, the near ones keep the network's prediction, and the
root turns by whatever the network predicts for its next frame. A network that turns slowly then
never catches up with a heading that keeps turning (holding W+E): measured with
``benchmarks/turning.py``, after 5 s of walking with the heading turning at 120 deg/s the body of
the small trained run (``examples/train_small.py``) had turned 5-100 degrees of the heading's
598 (errors of 70-140 degrees, the root spinning in place in some styles), and the released
network's lagged 47-146 degrees (Old turned 92 degrees).

So while a movement is asked, :class:`HeadingFollow` turns the predicted next frame (root facing,
future trajectory, joints and their axes and velocities, all about the next root) towards the
target facing by a share of the remaining error each frame: ``angle = err (1 - exp(-dt / tau))``,
at most ``max_rate`` deg/s. The network's own turning comes first; the correction only makes up
what it leaves, as a game's root-motion correction does. At a zero command nothing is changed (the
stand-still's own rules apply, ``standing.py``), so a turn on the spot is still the network's steps.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from minifilm.runtime.root_frames import to_world2, to_world3


def rotate_about(centre: np.ndarray, angle: np.ndarray, positions: np.ndarray, directions: np.ndarray,
                 joints: np.ndarray, vectors: Sequence[np.ndarray]):
    """Turn a predicted frame by ``angle`` (B,) radians (heading convention: +angle turns +z
    towards +x) about the floor points ``centre`` (B, 2): trajectory positions and directions
    (B, S, 2), joint positions (B, J, 3) and joint vectors (B, J, 3 each). New arrays."""
    g = np.stack([np.sin(angle), np.cos(angle)], axis=-1)                   # (B, 2) rotation
    pos = to_world2(positions - centre[:, None], g[:, None]) + centre[:, None]
    direction = to_world2(directions, g[:, None])
    rel = joints.copy()
    rel[..., 0] -= centre[:, 0, None]
    rel[..., 2] -= centre[:, 1, None]
    body = to_world3(rel, g)
    body[..., 0] += centre[:, 0, None]
    body[..., 2] += centre[:, 1, None]
    return pos, direction, body, [to_world3(v, g) for v in vectors]


def signed_angle(from_dir: np.ndarray, to_dir: np.ndarray) -> np.ndarray:
    """Radians in (-pi, pi] turning floor directions ``from_dir`` onto ``to_dir`` (B, 2)."""
    a = np.arctan2(to_dir[..., 0], to_dir[..., 1]) - np.arctan2(from_dir[..., 0], from_dir[..., 1])
    return np.mod(a + np.pi, 2 * np.pi) - np.pi


@dataclass(frozen=True)
class HeadingFollow:
    """tau: seconds, the time constant with which the remaining heading error is taken up;
    max_rate: deg/s, the largest correction."""

    tau: float = 0.15
    max_rate: float = 360.0

    def __post_init__(self):
        for name in ("tau", "max_rate"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and v > 0 and np.isfinite(v)):
                raise ValueError(f"HeadingFollow: {name} must be a positive finite number, got {v!r}")

    def correction(self, predicted: np.ndarray, target: np.ndarray, moving: np.ndarray, dt: float) -> np.ndarray:
        """(B,) radians to turn the predicted next facing (B, 2) towards the target (B, 2);
        0 where not ``moving`` (B,)."""
        err = signed_angle(predicted, target)
        step = np.clip(err * (1.0 - np.exp(-dt / self.tau)), -np.radians(self.max_rate) * dt,
                       np.radians(self.max_rate) * dt)
        return np.where(moving, step, 0.0)

    def apply(self, target_facing, moving, new_pos, new_dir, joints, vectors, dt):
        """The predicted frame turned by :meth:`correction` about its next root (new_pos[:, 0])."""
        angle = self.correction(new_dir[:, 0], target_facing, moving, dt)
        if not np.any(angle != 0):
            return new_pos, new_dir, joints, list(vectors)
        return rotate_about(new_pos[:, 0], angle, new_pos, new_dir, joints, vectors)
