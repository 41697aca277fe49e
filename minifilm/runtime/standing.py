"""Standing still when nothing is asked: what the runtime adds to the paper's loop at zero command.

Measured on the released network (Neutral, ``benchmarks/standing.py``): with a zero command after
walking, the character kept going at 0.37 m/s, stepping, for as long as it ran. Three things keep
it going, each found by switching it off:

1. **The trajectory blend** (Sec. 4.4, ``blend_future_trajectory``) keeps 85 % of the network's
   own predicted step for the nearest future sample and 68 % for the next: at a zero command the
   future the network is shown still moves, so it keeps moving. With the near samples pinned to
   the root, the stepping stopped but the root still slid at 0.2 m/s.
2. **The past trajectory** is the root's own history: once it slides, the past says "moving",
   which the network continues. Nothing in the loop ever damps this.
3. **The phases** (``p <- 0.5 p_pred + 0.5 (p + dp_pred)``, docs/original-code.md §10.2 step 7)
   keep their amplitude: the gating network keeps blending the experts of a gait cycle. In the
   data a standing body has amplitude near zero (its contacts do not oscillate). The released
   network was never trained on the idle clips (the authors' exporter skipped them), only on the
   stops inside the transition clips, so it does not find its own way there.

So while the commanded velocity is zero, :class:`StandStill`:

- pins every future sample to the root (the stop the user asked for, at once);
- fades the network's remaining root displacement out over ``settle`` seconds (smoothstep), moving
  the predicted body with it, so the root history becomes still and the network sees a still past
  (turning on the spot needs no travel either);
- and, while the target facing is not being turned either (turning on the spot is stepping, not
  standing), decays the phase amplitudes with time constant ``phase_tau`` seconds, towards the
  standing phases of the data. (Judged by the target, not by the facing reached: some styles
  drift their facing while standing, and would otherwise never count as idle.)

None of this happens while anything is held; the paper's loop is unchanged then. ``Controller(...,
stand=None)`` turns it off (the runtime as the authors' demo had it).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: below this commanded speed (m/s) the command is "stand"
STILL_SPEED = 1e-6
#: a target facing that moved more than this (degrees) since the last frame is being turned by the
#: user: the character turns on the spot (stepping), it does not stand
TURNING_DEG = 0.05


@dataclass(frozen=True)
class StandStill:
    """How the runtime stands still at a zero command (see the module docstring).

    settle: seconds over which the network's own root displacement is faded out once idle.
    phase_tau: seconds, the time constant of the phase amplitudes' decay while idle.
    """

    settle: float = 0.5
    phase_tau: float = 0.05

    def __post_init__(self):
        if not (self.settle > 0 and np.isfinite(self.settle)):
            raise ValueError(f"StandStill: settle must be a positive number of seconds, got {self.settle}")
        if not (self.phase_tau > 0 and np.isfinite(self.phase_tau)):
            raise ValueError(f"StandStill: phase_tau must be a positive number of seconds, got {self.phase_tau}")

    @staticmethod
    def still(target_velocity: np.ndarray) -> np.ndarray:
        """(B,) True where the command asks for no movement."""
        return np.linalg.norm(np.asarray(target_velocity, dtype=np.float64), axis=-1) < STILL_SPEED

    @staticmethod
    def idle(target_velocity: np.ndarray, target_facing: np.ndarray, previous_target: np.ndarray) -> np.ndarray:
        """(B,) True where nothing is asked: no movement, and the target facing where it was last
        frame (within ``TURNING_DEG``: the user is not turning the character on the spot)."""
        tf = np.asarray(target_facing, dtype=np.float64)
        f = np.asarray(previous_target, dtype=np.float64)
        cos = np.sum(tf * f, axis=-1) / np.maximum(np.linalg.norm(tf, axis=-1) * np.linalg.norm(f, axis=-1), 1e-9)
        return StandStill.still(target_velocity) & (cos >= np.cos(np.radians(TURNING_DEG)))

    @staticmethod
    def pin_future(future_pos: np.ndarray, still: np.ndarray) -> np.ndarray:
        """Future positions (B, S, 2) with every sample of the ``still`` rows at the root (sample 0)."""
        out = future_pos.copy()
        out[still, 1:] = out[still, :1]
        return out

    def root_weight(self, idle_seconds: np.ndarray) -> np.ndarray:
        """(B,) how much of the network's root displacement is kept: 1 while moving, a smoothstep
        down to 0 over ``settle`` seconds of idling."""
        u = np.clip(np.asarray(idle_seconds, dtype=np.float64) / self.settle, 0.0, 1.0)
        return 1.0 - u * u * (3.0 - 2.0 * u)

    def phase_factor(self, idle: np.ndarray, dt: float) -> np.ndarray:
        """(B,) the factor the phases (amplitude times (sin, cos)) are multiplied by this frame."""
        return np.where(idle, np.exp(-dt / self.phase_tau), 1.0)
