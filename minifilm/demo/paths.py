"""The two paths the demo page draws ahead of its character, as the frame message's ``future``,
``futureFacing`` and ``path`` (world x, z in metres, flat lists of points: ``future`` and
``futureFacing`` one per future trajectory sample, 6, at 0, 0.2, .., 1.0 s ahead; ``path`` one
every ``PATH_SPACING`` seconds over the same second, so that a turn is drawn as a smooth arc).

- ``future`` / ``futureFacing``: the predicted trajectory, the network's own future trajectory
  output (the 2 x 6 trajectory positions and directions of the output frame z, Sec. 3.2, read
  back into the controller's state, sample 0 being the root now) and the facing it predicts at
  each sample. At the next frame it is blended with the user's trajectory (Sec. 4.4) and fed
  back as the input's future.
- ``path``: where the held input leads over the same times if it stays held: the heading turning
  as Q/E turn it and the movement relative to it, at the speed the character is steered at (the
  command scaled to what the style can do). The character's steering is advanced on a copy, so
  this is what the next frames will ask for (within a centimetre or two of the frames' own
  1/60 s steps).
"""
from __future__ import annotations

import copy
import math
from typing import Dict, List

import numpy as np

from minifilm.features.layout import CURRENT_SAMPLE

#: seconds between the points of the commanded path sent to the page (each step integrated at its
#: midpoint: on a full-rate turn the drawn arc is within millimetres of the continuous one)
PATH_SPACING = 0.1


def future_seconds(layout) -> np.ndarray:
    """(S,) seconds ahead of each future trajectory sample (0 first)."""
    return np.asarray(layout.trajectory_seconds[CURRENT_SAMPLE:], dtype=np.float64)


def commanded_path(steering, root: np.ndarray, seconds: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """(S, 2) world positions the held input reaches at ``seconds`` (S,) ahead of ``root`` (2,),
    increasing from 0.

    ``steering``: a :class:`~minifilm.demo.steering.Steering` (not changed: a copy is advanced);
    ``scale``: the share of the commanded speed the character is steered at. Each interval is one
    midpoint step: the heading turned half way, the velocity there, the heading turned the rest."""
    s = copy.copy(steering)
    out = np.empty((len(seconds), 2))
    pos, t = np.array(root, dtype=np.float64), 0.0
    for k, until in enumerate(seconds):
        h = until - t
        if h > 1e-12:
            _, velocity, _ = s.advance(h / 2)
            pos = pos + scale * h * velocity
            s.advance(h / 2)
            t = until
        out[k] = pos
    return out


class PathCache:
    """:func:`commanded_path`, faster: the same held input gives the same path turned with the
    heading (the steering's velocity is relative to the heading, and its turning does not depend
    on where the heading points), so the path is worked out once at heading 0 from the origin,
    and then only rotated to the heading and moved to the root. Tested equal to the plain one.

    Remembers the paths of the last ``size`` different inputs (held keys, speed scale)."""

    def __init__(self, size: int = 64):
        self.size = size
        self._paths: Dict[tuple, np.ndarray] = {}

    def path(self, steering, root: np.ndarray, seconds: np.ndarray, scale: float = 1.0) -> np.ndarray:
        key = (steering.move, steering.turn, steering.speed, steering.walk_speed, steering.run_speed,
               steering.turn_rate, round(float(scale), 6), tuple(np.round(seconds, 9)))
        local = self._paths.get(key)
        if local is None:
            if len(self._paths) >= self.size:
                self._paths.clear()
            at_zero = copy.copy(steering)
            at_zero.theta = 0.0
            local = self._paths[key] = commanded_path(at_zero, np.zeros(2), seconds, float(scale))
        # heading 0 is +z; heading theta's (sin, cos) and right (-cos, sin) are those of 0 turned by theta
        c, s = math.cos(steering.theta), math.sin(steering.theta)
        turned = np.stack([c * local[:, 0] + s * local[:, 1], -s * local[:, 0] + c * local[:, 1]], axis=1)
        return turned + np.asarray(root, dtype=np.float64)


_PATHS = PathCache()


def frame_paths(character) -> Dict[str, List[float]]:
    """The frame message's ``future``, ``futureFacing`` and ``path`` for a demo
    :class:`~minifilm.demo.character.Character` (after its step)."""
    st = character.ctrl.state
    scale = character.reachable / character.commanded if character.commanded > 1e-9 else 1.0
    horizon = future_seconds(character.source.layout)[-1]
    seconds = np.linspace(0.0, horizon, int(round(horizon / PATH_SPACING)) + 1)
    path = _PATHS.path(character.steering, st.root[0], seconds, scale if math.isfinite(scale) else 1.0)
    return {"future": np.round(st.future_pos[0], 4).reshape(-1).tolist(),
            "futureFacing": np.round(st.future_dir[0], 4).reshape(-1).tolist(),
            "path": np.round(path, 4).reshape(-1).tolist()}
