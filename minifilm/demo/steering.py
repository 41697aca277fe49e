"""From what the user holds (keys, sticks) to the controller's target, frame by frame.

The user steers a *heading*: the direction the character should face, an angle ``theta`` with
unit vector ``(sin theta, cos theta)`` on the floor (world x, z; the convention of
:mod:`minifilm.runtime.control`). Q/E (or the right stick) turn it; WASD (or the left stick) give
a movement relative to it, so W walks along the heading, S backwards, A/D step sideways, and
holding nothing stops. The page's camera chases the body's facing, which turns after the
heading, so once the body has turned W is "into the screen". A 100STYLE character facing +z has its left side towards +x, so its right is the
heading turned by -90 degrees: ``(-cos theta, sin theta)``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Tuple

import numpy as np


def heading_vector(theta: float) -> np.ndarray:
    """(2,) unit world (x, z) direction of heading ``theta`` (radians; 0 = +z)."""
    return np.array([math.sin(theta), math.cos(theta)])


def right_vector(theta: float) -> np.ndarray:
    """(2,) the character's right when it faces heading ``theta``."""
    return np.array([-math.cos(theta), math.sin(theta)])


@dataclass
class Steering:
    """The held input of one character and the heading it turns.

    walk_speed, run_speed: m/s at speed 0 and 1 (a stick held half way gives half of it);
    turn_rate: rad/s of the heading at full turn.
    """

    walk_speed: float = 1.3
    run_speed: float = 2.8
    turn_rate: float = math.radians(120.0)
    theta: float = 0.0
    move: Tuple[float, float] = (0.0, 0.0)     # (right, forward) in [-1, 1]
    turn: float = 0.0                          # [-1, 1], > 0 to the right
    speed: float = 0.0                         # [0, 1], walk .. run

    def hold(self, move: Tuple[float, float], turn: float, speed: float) -> None:
        """The input now held (validated by :mod:`minifilm.demo.protocol`)."""
        self.move, self.turn, self.speed = (float(move[0]), float(move[1])), float(turn), float(speed)

    def reset(self, theta: float = 0.0) -> None:
        self.theta = float(theta)
        self.hold((0.0, 0.0), 0.0, 0.0)

    def advance(self, dt: float) -> Tuple[np.ndarray, np.ndarray, float]:
        """Turn the heading for ``dt`` seconds; returns the target facing (2,), the target velocity
        (2,) in m/s and the commanded speed (m/s) for the next frame."""
        # > 0 turns right, which lowers theta (+theta turns towards +x, the character's left)
        self.theta = math.remainder(self.theta - self.turn * self.turn_rate * dt, 2 * math.pi)
        right, forward = self.move
        amount = math.hypot(right, forward)
        facing = heading_vector(self.theta)
        if amount < 1e-6:
            return facing, np.zeros(2), 0.0
        # keys give length 1 or sqrt(2) (diagonals): full speed; a stick held part way goes slower
        speed = min(amount, 1.0) * (self.walk_speed + self.speed * (self.run_speed - self.walk_speed))
        direction = (forward * facing + right * right_vector(self.theta)) / amount
        return facing, speed * direction, speed
