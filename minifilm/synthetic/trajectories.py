"""User-like root trajectories and gait timelines for the synthetic generator.

Everything is a per-frame array, built vectorised: a gait timeline (speed, travel direction in the
facing frame, stride frequency, walk/run timing, ...), piecewise constant per gait segment and
smoothed so that changes of gait become transitions; then a root path on the floor by integrating
the velocity with a smoothly wandering yaw rate (turns) and speed changes; then the stride phase by
integrating the stride frequency.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, List, Tuple

import numpy as np
from scipy.ndimage import gaussian_filter1d

from minifilm.synthetic.styles import GAIT_PARAMS, GAITS, StyleParams

__all__ = ["smooth_noise", "gait_segments", "GaitTimeline", "gait_timeline", "RootPath", "root_path"]

#: The fields of a timeline that come from ``GaitParams`` (smoothed together in transitions).
_FIELDS = ("speed", "stride_freq", "run", "swing_height", "heel_off", "arm_scale", "elbow_extra")


def smooth_noise(rng: np.random.Generator, n: int, fps: float, seconds: float) -> np.ndarray:
    """(n,) smooth random signal with unit standard deviation and correlation time ``seconds``.

    White noise filtered by a Gaussian of sigma = seconds * fps frames, rescaled by the closed-form
    std of filtered unit white noise, 1 / sqrt(2 sqrt(pi) sigma), so the scale does not depend on n.
    """
    sigma = max(seconds * fps, 1e-3)
    x = gaussian_filter1d(rng.standard_normal(n), sigma, mode="reflect")
    return x * np.sqrt(2.0 * np.sqrt(np.pi) * sigma)


def gait_segments(gait: str, seconds: float, rng: np.random.Generator) -> List[Tuple[str, float, float]]:
    """The schedule of a clip: a list of (gait code, sidestep sign, duration in seconds).

    A plain gait is one segment, except SW whose sidestep direction flips every 2.5-4 s. TR strings
    1.5-3 s segments of the other gaits together, never the same gait twice in a row.
    """
    if gait not in GAITS:
        raise ValueError(f"unknown gait {gait!r}; expected one of {GAITS}")
    out: List[Tuple[str, float, float]] = []
    t = 0.0
    if gait == "SW":
        sign = float(rng.choice([-1.0, 1.0]))
        while t < seconds:
            d = float(rng.uniform(2.5, 4.0))
            out.append(("SW", sign, d))
            sign, t = -sign, t + d
    elif gait == "TR":
        current = str(rng.choice(["ID", "FW"]))
        while t < seconds:
            d = float(rng.uniform(1.5, 3.0))
            out.append((current, float(rng.choice([-1.0, 1.0])), d))
            t += d
            current = str(rng.choice([g for g in ("FW", "BW", "FR", "SW", "ID") if g != current]))
    else:
        out.append((gait, 1.0, seconds))
    return out


@dataclass
class GaitTimeline:
    """Per-frame locomotion parameters, all (N,) unless noted.

    velocity_local: (N, 2) desired velocity (x, z) in the facing frame, m/s.
    speed: its norm. stride_freq: Hz. run: 0 walk .. 1 run timing. swing_height: m.
    heel_off: rad. arm_scale, elbow_extra: arm swing factor and extra elbow flexion (rad).
    gait: (N,) gait code of the segment each frame belongs to (before smoothing).
    """

    velocity_local: np.ndarray
    speed: np.ndarray
    stride_freq: np.ndarray
    run: np.ndarray
    swing_height: np.ndarray
    heel_off: np.ndarray
    arm_scale: np.ndarray
    elbow_extra: np.ndarray
    gait: np.ndarray


def gait_timeline(gait: str, n: int, fps: float, rng: np.random.Generator, style: StyleParams,
                  transition_seconds: float = 0.3) -> GaitTimeline:
    """Per-frame gait parameters for ``n`` frames of gait ``gait`` in style ``style``.

    Segments are piecewise constant, then smoothed with a Gaussian of ``transition_seconds``: that is
    what turns a change of gait into a transition (e.g. FW -> FR speeds up while the duty factor
    drops). Moving gaits get ±15 % speed changes (more with ``style.noise``); a Drunk-like style also
    gets a wandering sideways drift and irregular stride frequency.
    """
    segments = gait_segments(gait, n / fps + 1.0, rng)
    values: Dict[str, np.ndarray] = {k: np.zeros(n) for k in _FIELDS}
    direction = np.zeros((n, 2))
    codes = np.empty(n, dtype=object)
    start = 0
    for code, sign, duration in segments:
        stop = min(n, start + int(round(duration * fps)))
        if stop <= start:
            break
        g = GAIT_PARAMS[code]
        for k in _FIELDS:
            values[k][start:stop] = getattr(g, k)
        direction[start:stop] = (sign * g.direction[0], g.direction[1])
        codes[start:stop] = code
        start = stop
    if start < n:  # the schedule is a second longer than needed; this is only a guard
        for k in _FIELDS:
            values[k][start:] = values[k][start - 1]
        direction[start:], codes[start:] = direction[start - 1], codes[start - 1]

    speed = values["speed"] * style.speed_scale
    speed = speed * (1.0 + (0.15 + 0.1 * style.noise) * smooth_noise(rng, n, fps, 1.0))
    velocity = direction * speed[:, None]
    velocity[:, 0] += 0.25 * style.noise * smooth_noise(rng, n, fps, 0.6) * (speed > 0.05)
    sigma = transition_seconds * fps
    velocity = gaussian_filter1d(velocity, sigma, axis=0, mode="nearest")
    smoothed = {k: gaussian_filter1d(values[k], sigma, mode="nearest") for k in _FIELDS if k != "speed"}
    freq = smoothed["stride_freq"] * style.stride_freq_scale
    freq = freq * (1.0 + 0.25 * style.noise * smooth_noise(rng, n, fps, 0.4))
    # Faster walking also means a slightly higher cadence (stride length and frequency both grow).
    ref = np.maximum(gaussian_filter1d(values["speed"], sigma, mode="nearest") * style.speed_scale, 0.3)
    freq = freq * np.clip(np.linalg.norm(velocity, axis=1) / ref, 0.8, 1.2) ** 0.3
    return GaitTimeline(velocity_local=velocity, speed=np.linalg.norm(velocity, axis=1),
                        stride_freq=np.maximum(freq, 0.3), run=smoothed["run"],
                        swing_height=smoothed["swing_height"], heel_off=smoothed["heel_off"],
                        arm_scale=smoothed["arm_scale"], elbow_extra=smoothed["elbow_extra"], gait=codes)


@dataclass
class RootPath:
    """The character's root on the floor: position (N, 3) with y = 0, facing yaw (N,) radians
    (unwrapped; the facing direction is (sin yaw, 0, cos yaw)) and velocity (N, 3) m/s."""

    position: np.ndarray
    yaw: np.ndarray
    velocity: np.ndarray


def root_path(timeline: GaitTimeline, fps: float, rng: np.random.Generator, turn_rate: float = 0.5,
              noise: float = 0.0) -> RootPath:
    """Integrate the timeline's velocity along a turning path.

    The yaw rate is smooth noise of ``turn_rate`` rad/s (occasional turns of tens of degrees),
    faded out as the speed drops below 0.6 m/s (no turning on the spot) and limited when running so
    the lateral acceleration stays human (|ω| v <= 2.5 m/s²). ``noise`` adds quick wobble (Drunk).
    """
    n = timeline.speed.size
    speed = timeline.speed
    omega = turn_rate * smooth_noise(rng, n, fps, 1.2) + 0.6 * noise * smooth_noise(rng, n, fps, 0.3)
    omega = omega * np.clip(speed / 0.6, 0.0, 1.0)
    omega = np.clip(omega, -2.5 / np.maximum(speed, 1.0), 2.5 / np.maximum(speed, 1.0))
    yaw = float(rng.uniform(-np.pi, np.pi)) + np.cumsum(omega) / fps
    s, c = np.sin(yaw), np.cos(yaw)
    vx, vz = timeline.velocity_local[:, 0], timeline.velocity_local[:, 1]
    # Columns of Ry(yaw): the facing frame's +x (the character's left) is (c, 0, -s), +z is (s, 0, c).
    velocity = np.stack([c * vx + s * vz, np.zeros(n), -s * vx + c * vz], axis=1)
    position = np.cumsum(velocity, axis=0) / fps
    position -= position[0]
    return RootPath(position=position, yaw=yaw, velocity=velocity)
