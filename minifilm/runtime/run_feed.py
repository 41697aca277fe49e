"""The run feed: a perfect straight run shown to the network as its trajectory input (the demo's Shift).

PAPER: not in the paper's loop (Sec. 4.4), where the trajectory input is the root's own past and
the blended future. Told only its own past (walking), the released network walks on (Neutral at
most 1.8 m/s, whatever speed is asked); shown a run, it runs at the speed it learnt for the style
(Neutral 2.06 m/s, ``benchmarks/run_speed.py``). ``Controller.run_feed`` gives the weights (B,)
of the run in the input (:class:`~minifilm.runtime.controller.Controller`); the controller's own
history and future are not changed, only what the network is shown.
"""
from __future__ import annotations

import numpy as np

from minifilm.runtime.root_frames import unit2


def run_trajectory(positions: np.ndarray, directions: np.ndarray, weights: np.ndarray, speed: float,
                   facing: np.ndarray, velocity: np.ndarray, times: np.ndarray):
    """The trajectory input blended into a straight run.

    positions (B, 12, 2): the samples relative to the root (world axes); directions (B, 12, 2);
    weights (B,) in [0, 1]: how much of the run (0: the input as it is); speed: m/s of the run;
    facing, velocity (B, 2): the user's command (the run goes along the velocity, or the facing
    when it is zero); times (12,): seconds of the samples (negative in the past).
    Returns positions, directions (B, 12, 2), new arrays.
    """
    w = weights[:, None, None]
    norm = np.linalg.norm(velocity, axis=-1, keepdims=True)
    way = np.where(norm > 1e-9, velocity / np.maximum(norm, 1e-9), facing)          # (B, 2)
    ideal_p = way[:, None] * (speed * times)[None, :, None]
    ideal_d = np.broadcast_to(facing[:, None], directions.shape)
    return (1 - w) * positions + w * ideal_p, unit2((1 - w) * directions + w * ideal_d, directions)
