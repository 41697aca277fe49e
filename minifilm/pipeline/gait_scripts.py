"""Scripted paths for each 100STYLE gait, varied by a seed: what a character is asked to do while
the released network makes a data set (:mod:`minifilm.pipeline.from_released`).

100STYLE records every style in a handful of takes named by gait (docs/original-code.md §11):

    FW / BW   forwards / backwards walk        FR / BR   forwards / backwards run
    SW / SR   sideways walk / run              ID        idle (standing)
    TR1       transitions: walk, run, stop, stand, turn on the spot, walk again

Each gait here is a :class:`~minifilm.runtime.control.CommandScript` (open-loop keyframes of speed,
heading and direction of travel) with turns, speed changes and sidestep directions drawn from a
``np.random.Generator``, so the same seed gives the same paths. Speeds are what the user asks for
in m/s; the data-set job maps them through each style's measured speed calibration.

Every script holds its first command for ``warmup`` seconds before its own ``seconds`` begin: the
rollout starts from the data's mean pose, and that first second is cut from the written file.
"""
from __future__ import annotations

from typing import Dict, List, Tuple

import numpy as np

from minifilm.runtime.control import CommandScript

#: the gaits written, in order, and the share of a style's seconds each gets (sums to 1)
GAIT_SHARES: Dict[str, float] = {"FW": 0.20, "BW": 0.10, "FR": 0.15, "BR": 0.10,
                                 "SW": 0.10, "SR": 0.10, "ID": 0.10, "TR1": 0.15}

Key = Tuple[float, float, float, float]      # (time s, speed m/s, heading deg, move deg)


def _segments(rng: np.random.Generator, seconds: float, speed: Tuple[float, float], turn: Tuple[float, float],
              moves: Tuple[float, ...], hold: Tuple[float, float] = (1.5, 3.0), ramp: float = 0.6) -> List[Key]:
    """Keyframes of straight stretches joined by ``ramp``-second changes: each stretch lasts
    ``hold`` seconds (uniform), moves at a speed drawn from ``speed`` and in a direction drawn from
    ``moves`` (degrees from the facing), and turns the heading by ±``turn`` degrees on entry."""
    t, heading = 0.0, 0.0
    v, move = rng.uniform(*speed), float(rng.choice(moves))
    keys: List[Key] = [(0.0, v, heading, move)]
    while t < seconds:
        t_end = min(seconds, t + rng.uniform(*hold))
        keys.append((t_end, v, heading, move))
        if t_end >= seconds:
            break
        heading += float(rng.choice((-1.0, 1.0)) * rng.uniform(*turn))
        v, move = rng.uniform(*speed), float(rng.choice(moves))
        t = min(seconds, t_end + ramp)
        keys.append((t, v, heading, move))
    return keys


def _transitions(rng: np.random.Generator, seconds: float) -> List[Key]:
    """TR1: walk, run, walk, stop and stand, turn on the spot, walk off; repeated to fill the time."""
    keys: List[Key] = [(0.0, rng.uniform(1.0, 1.5), 0.0, 0.0)]
    t, heading = 0.0, 0.0
    plan = ("walk", "run", "walk", "stop", "turn", "walk")
    i = 0
    while t < seconds:
        what = plan[i % len(plan)]
        i += 1
        span = rng.uniform(1.5, 2.5)
        ramp = 0.6
        if what == "walk":
            v = rng.uniform(0.9, 1.5)
        elif what == "run":
            v = rng.uniform(2.5, 3.5)
        else:
            v = 0.0
        if what == "turn":
            heading += float(rng.choice((-1.0, 1.0)) * rng.uniform(90.0, 180.0))
        t_on = min(seconds, t + ramp)
        keys.append((t_on, v, heading, 0.0))
        t = min(seconds, t_on + span)
        keys.append((t, v, heading, 0.0))
    return keys


def gait_keys(gait: str, rng: np.random.Generator, seconds: float) -> List[Key]:
    """The keyframes ``(time, speed m/s, heading deg, move deg)`` of one gait for ``seconds``."""
    if gait == "FW":
        return _segments(rng, seconds, (0.8, 1.7), (20.0, 100.0), (0.0,))
    if gait == "BW":
        return _segments(rng, seconds, (0.5, 1.1), (15.0, 60.0), (180.0,))
    if gait == "FR":
        return _segments(rng, seconds, (2.5, 4.0), (20.0, 80.0), (0.0,))
    if gait == "BR":
        return _segments(rng, seconds, (1.4, 2.4), (10.0, 40.0), (180.0,))
    if gait == "SW":
        return _segments(rng, seconds, (0.5, 1.0), (0.0, 20.0), (90.0, -90.0), hold=(1.5, 2.5))
    if gait == "SR":
        return _segments(rng, seconds, (1.3, 2.0), (0.0, 20.0), (90.0, -90.0), hold=(1.2, 2.0))
    if gait == "ID":
        # standing, now and then turning a little on the spot (100STYLE's idle takes shift weight)
        keys = _segments(rng, seconds, (0.0, 0.0), (10.0, 45.0), (0.0,), hold=(2.0, 4.0), ramp=1.5)
        return [(t, 0.0, h, m) for t, _, h, m in keys]
    if gait == "TR1":
        return _transitions(rng, seconds)
    raise ValueError(f"gait_keys: no script for gait {gait!r}; known: {list(GAIT_SHARES)}")


def gait_script(gait: str, rng: np.random.Generator, seconds: float, warmup: float = 1.0) -> CommandScript:
    """A :class:`CommandScript` of ``warmup + seconds``: the first command held for ``warmup``
    seconds, then :func:`gait_keys` shifted by ``warmup``."""
    keys = gait_keys(gait, rng, seconds)
    shifted = [keys[0]] + [(t + warmup, v, h, m) for t, v, h, m in keys]
    return CommandScript(shifted)


def gait_seconds(seconds_per_style: float) -> Dict[str, float]:
    """Seconds per gait file for ``seconds_per_style`` in all (``GAIT_SHARES``)."""
    return {g: seconds_per_style * share for g, share in GAIT_SHARES.items()}
