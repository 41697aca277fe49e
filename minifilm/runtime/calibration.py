"""Speed calibration: the command that makes a network really move at the speed the user asks for.

The network follows the user's trajectory only partly (near future samples keep its own
prediction, docs/original-code.md §10.4), so commanding v m/s gives a slower walk. The original demo
hid this behind a per-style "velocity bias" of unclear units (§12 item 16); here the map from
commanded to achieved speed is measured per style and direction (:func:`calibrate_speed`) and
inverted (:class:`SpeedCalibration`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Generator, Optional, Sequence

import numpy as np

from minifilm.runtime.control import CommandScript
from minifilm.runtime.root_frames import floor_angle

#: commanded speeds (m/s) a calibration measures: far beyond the user's speeds, because the
#: network follows the commanded future only partly (the released Neutral runs at its fastest,
#: about 1.8 m/s, at 12-24 m/s commanded; benchmarks/run_speed.py)
CALIBRATION_COMMANDS = (0.5, 1.0, 2.0, 3.0, 4.0, 6.0, 8.0, 12.0, 16.0, 24.0)
#: commanded speeds for a model trained here: within what a small model's data holds. Commands
#: far beyond it (CALIBRATION_COMMANDS' 24 m/s) stretched the train_small model's bones (a bone's
#: length varied by up to 69 %); up to 4 m/s every style of that run reached the speeds asked,
#: its bones as steady as uncalibrated (benchmarks/trained_speed.py)
RUN_CALIBRATION_COMMANDS = (0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0)
#: directions of travel (degrees from the facing) a calibration measures
CALIBRATION_DIRECTIONS = (0.0, 90.0, 180.0)


@dataclass
class SpeedCalibration:
    """Measured steady-state root speed (m/s) for each commanded speed (m/s), for one style, per
    direction of travel relative to the facing (degrees: 0 forwards, 90 sideways, 180 backwards;
    left and right are taken as symmetric).

    The network follows the user's trajectory only partly (near future samples keep its own
    prediction, §10.4), so commanding v gives a slower walk. The original demo hid this behind a
    per-style "velocity bias" of unclear units (docs/original-code.md §12 item 16); here the map is
    measured (:func:`calibrate_speed`) and inverted by linear interpolation (in speed, then in
    direction).

    commanded (N,); achieved (N,) or (D, N); directions (D,) degrees in [0, 180].
    """

    commanded: np.ndarray
    achieved: np.ndarray
    directions: Sequence[float] = (0.0,)

    def __post_init__(self):
        c = np.asarray(self.commanded, dtype=np.float64)
        a = np.atleast_2d(np.asarray(self.achieved, dtype=np.float64))
        d = np.asarray(self.directions, dtype=np.float64).reshape(-1)
        if a.shape != (len(d), len(c)):
            raise ValueError(f"SpeedCalibration: achieved has shape {a.shape}, expected "
                             f"({len(d)} directions, {len(c)} commands)")
        order, dorder = np.argsort(c), np.argsort(d)
        a = np.maximum.accumulate(a[dorder][:, order], axis=1)     # monotone in the command
        self.commanded = np.r_[0.0, c[order]]
        self.achieved = np.concatenate([np.zeros((len(d), 1)), a], axis=1)
        self.directions = d[dorder]

    def command_for(self, speed, direction=0.0) -> np.ndarray:
        """Commanded speed that achieves ``speed`` when moving at ``direction`` degrees from the
        facing (clamped to the largest calibrated command)."""
        speed = np.asarray(speed, dtype=np.float64)
        ramp = 1e-9 * np.arange(self.achieved.shape[1])          # strictly increasing for interp
        per_dir = np.stack([np.interp(speed, a + ramp, self.commanded) for a in self.achieved])
        if len(self.directions) == 1:
            return per_dir[0]
        ang = np.clip(np.abs(np.asarray(direction, dtype=np.float64)), 0.0, 180.0)
        ang = np.broadcast_to(ang, speed.shape)
        i = np.clip(np.searchsorted(self.directions, ang, side="right") - 1, 0, len(self.directions) - 2)
        d0, d1 = self.directions[i], self.directions[i + 1]
        t = np.clip((ang - d0) / np.maximum(d1 - d0, 1e-9), 0.0, 1.0)
        c0 = np.take_along_axis(per_dir, i[None], axis=0)[0]
        c1 = np.take_along_axis(per_dir, (i + 1)[None], axis=0)[0]
        return (1 - t) * c0 + t * c1

    def apply(self, velocity: np.ndarray, facing: Optional[np.ndarray] = None) -> np.ndarray:
        """Rescale velocities (..., 2) so their magnitude is the calibrated command; the direction
        of travel is measured against ``facing`` (..., 2) (forwards if not given)."""
        v = np.asarray(velocity, dtype=np.float64)
        n = np.linalg.norm(v, axis=-1)
        direction = 0.0 if facing is None else floor_angle(v, np.asarray(facing, dtype=np.float64))
        scale = self.command_for(n, direction) / np.maximum(n, 1e-9)
        return np.where((n > 1e-9)[..., None], v * scale[..., None], 0.0)


class PerCharacterCalibration:
    """One :class:`SpeedCalibration` per character of a batch (e.g. one per style), usable as
    ``Controller.run(..., calibration=)``."""

    def __init__(self, calibrations: Sequence[SpeedCalibration]):
        self.calibrations = list(calibrations)

    def apply(self, velocity: np.ndarray, facing: Optional[np.ndarray] = None) -> np.ndarray:
        """velocity, facing (B, 2) -> (B, 2), character b through calibration b."""
        v = np.asarray(velocity, dtype=np.float64)
        if v.ndim != 2 or len(v) != len(self.calibrations):
            raise ValueError(f"PerCharacterCalibration: velocity {v.shape} must be ({len(self.calibrations)}, 2)")
        return np.stack([c.apply(v[b], None if facing is None else facing[b])
                         for b, c in enumerate(self.calibrations)])


def _calibration_plan(fps: float, commands, directions, seconds: float, settle: float):
    """(frames, first measured frame, one CommandScript per (direction, command), direction-major)."""
    n = int(round(seconds * fps))
    k0 = int(round(settle * fps))
    if k0 >= n - 1:
        raise ValueError(f"calibrate_speed: settle ({settle} s) must be shorter than seconds ({seconds} s)")
    scripts = [CommandScript([(0.0, float(v), 0.0, float(d)), (seconds, float(v), 0.0, float(d))])
               for d in directions for v in commands]
    return n, k0, scripts


def _measured(roots: np.ndarray, k0: int, fps: float, commands, directions) -> SpeedCalibration:
    """The calibration of root paths (B, n, 2): the mean speed along each path after frame k0."""
    n = roots.shape[1]
    dist = np.sum(np.linalg.norm(np.diff(roots[:, k0:], axis=1), axis=-1), axis=1)
    achieved = (dist / ((n - 1 - k0) / fps)).reshape(len(directions), len(commands))
    return SpeedCalibration(np.asarray(commands, dtype=np.float64), achieved, tuple(directions))


def calibrate_speed(controller, film: np.ndarray,
                    commands: Sequence[float] = CALIBRATION_COMMANDS,
                    directions: Sequence[float] = CALIBRATION_DIRECTIONS,
                    seconds: float = 8.0, settle: float = 4.0, phases: Optional[np.ndarray] = None,
                    start_x: Optional[np.ndarray] = None) -> SpeedCalibration:
    """Move at each commanded speed in each direction (degrees from the facing: 0 forwards, 90
    sideways, 180 backwards), all at once as one batch, and measure the mean root speed after
    ``settle`` seconds. ``film`` is the style (4H,); ``phases`` (8,) and ``start_x`` (x_dim,)
    the start state (see :meth:`~minifilm.runtime.controller.Controller.reset`; default the data's means).

    The default commands are the released network's. A small network trained on little data must
    not be commanded far outside its data: give it ``RUN_CALIBRATION_COMMANDS`` (the demo does).

    :func:`calibrate_speed_stepwise` measures the same one network step at a time."""
    n, k0, scripts = _calibration_plan(controller.fps, commands, directions, seconds, settle)
    r = controller.run(scripts, n, film, phases=phases, start_x=start_x)
    return _measured(r.root_positions, k0, controller.fps, commands, directions)


def calibrate_speed_stepwise(controller, film: np.ndarray,
                             commands: Sequence[float] = CALIBRATION_COMMANDS,
                             directions: Sequence[float] = CALIBRATION_DIRECTIONS,
                             seconds: float = 8.0, settle: float = 4.0, phases: Optional[np.ndarray] = None,
                             start_x: Optional[np.ndarray] = None) -> Generator[None, None, SpeedCalibration]:
    """:func:`calibrate_speed` as a generator that yields once after the start and once after each
    network step of the batch, and returns the same :class:`SpeedCalibration` (its ``value`` in
    ``StopIteration``; tested equal). A frame loop runs it in slices of its idle time (the live
    demo, ``minifilm/demo/calibrations.py``): each ``next()`` costs one batch step, a few ms.

    The same commands reach ``controller.step`` in the same order as ``Controller.run`` gives them
    (scripts, then the step), so the roots, and the speeds measured on them, are the same."""
    n, k0, scripts = _calibration_plan(controller.fps, commands, directions, seconds, settle)
    for s in scripts:
        s.reset()
    starts = [s.start() for s in scripts]
    controller.reset(np.array([p for p, _ in starts]), np.array([f for _, f in starts]), phases, start_x)
    B = len(scripts)
    roots = np.empty((B, n, 2))
    tf, tv = np.empty((B, 2)), np.empty((B, 2))
    yield
    for k in range(n):
        t = k / controller.fps
        state = controller.state
        for b, s in enumerate(scripts):
            tf[b], tv[b] = s.command(t, state.root[b], state.facing[b])
        roots[:, k] = controller.step(tf, tv, film)["root"]
        yield
    return _measured(roots, k0, controller.fps, commands, directions)
