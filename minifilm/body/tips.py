"""Where a retargeted toe tip should be near the source's foot contacts (used by feet.py).

The target's contacts must come out as the source's: the test of
:func:`minifilm.phases.contacts.foot_contacts` (the tip slow, under 0.15 m/s, and within 1 cm of
the floor) must say the same on every frame. The rigs' feet differ (the 100STYLE toe tip is 24 cm
ahead of the ankle, Bandai's 12), so the transferred tips rise, sink and slide differently from the
source's. Each helper moves the tip as little as that needs, so that a clip taken to another rig and
back comes back where it was:

* :func:`band_heights`: heights only where the contact test would disagree;
* :func:`slide_correction`: the body, not the legs, makes up for a planted tip's slide;
* :func:`pin_targets`: a planted tip stays put; beside a contact it moves as it moves itself, no
  faster than the source's tip where that one passes the test;
* :func:`pitch_foot`: a little of the height is taken up by turning the foot about its ankle.
"""
from __future__ import annotations

from typing import Optional, Sequence, Tuple

import numpy as np

from minifilm.motion.skeleton_fit import rotation_between

__all__ = ["SPEED_THRESHOLD", "HEIGHT_BAND", "contact_runs", "speeds", "band_heights", "slide_correction",
           "pin_targets", "pitch_foot"]

#: the contact test's thresholds (minifilm.phases.contacts.foot_contacts' defaults, the paper's)
SPEED_THRESHOLD, HEIGHT_BAND = 0.15, 0.01


def contact_runs(contacts: np.ndarray) -> list:
    """[(start, stop)] frame ranges where a 0/1 series (F,) is 1."""
    c = np.concatenate([[0], (np.asarray(contacts) > 0.5).astype(int), [0]])
    d = np.diff(c)
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def speeds(points: np.ndarray, fps: float) -> np.ndarray:
    """(F,) backward-difference speed (m/s) of points (F, 3), frame 0 copying frame 1 (as contacts.py)."""
    v = np.zeros(len(points))
    if len(points) >= 2:
        v[1:] = np.linalg.norm(points[1:] - points[:-1], axis=-1) * fps
        v[0] = v[1]
    return v


def band_heights(height: np.ndarray, speed: np.ndarray, guide: np.ndarray, guide_speed: np.ndarray,
                 margin: float = 0.003, where: Optional[np.ndarray] = None) -> np.ndarray:
    """(F,) the height (floor at 0) a target toe tip should have so that the contact test says on
    every frame what it says for the source's tip, changing the tip's own ``height`` (F,) (at
    ``speed`` (F,), m/s) only where it has to.

    Where the source's tip (``guide`` heights and ``guide_speed``, (F,) each) passes the test, the
    tip takes its height (so the floor the test estimates on the target, the median height of its
    slow tips, is the source's too); where the source's tip does not pass but the target's slow tip
    would, it takes the source tip's height if that is out of the band, else is lifted (or
    lowered) ``margin`` out of it. Anywhere else the tip keeps its own height: feet of other
    lengths lift their tips differently, and forcing the source's heights there bends the knee (a
    round trip pays it twice). ``where`` (F,) bool, if given, is where this may be done at all:
    near the source's contacts (a single frame passing the test elsewhere is voted away by the
    contact test's majority filter, and following it would jerk the leg)."""
    src_in = (guide_speed <= SPEED_THRESHOLD) & (np.abs(guide) <= HEIGHT_BAND)
    own_in = (speed <= SPEED_THRESHOLD) & (np.abs(height) <= HEIGHT_BAND)
    away = np.where(np.abs(guide) > HEIGHT_BAND, guide, np.where(height < 0, -1.0, 1.0) * (HEIGHT_BAND + margin))
    out = np.where(src_in, guide, np.where(own_in, away, height))
    return out if where is None else np.where(where, out, height)


def slide_correction(sensors: np.ndarray, contacts: np.ndarray, fps: float, smooth_seconds: float = 0.1) -> np.ndarray:
    """(F, 3) horizontal shift of the body that keeps planted toe tips where they were put down.

    ``sensors`` (F, L, 3) toe tips, ``contacts`` (F, L) 0/1. On a frame where foot i is in contact
    it wants the shift pin_i - tip_i (pin_i: the tip's mean over that contact run); the shift is the
    mean over the feet in contact, linearly interpolated over frames without a contact, then
    smoothed over ``smooth_seconds``. Every step is linear in the tips, so a round trip (rig A -> B
    -> A with the same contacts) takes the first pass's shift back, up to the source tips' own
    slide; moving the legs instead (the leg IK) would bend the knees differently on each pass."""
    F, L = sensors.shape[:2]
    total, count = np.zeros((F, 3)), np.zeros(F)
    for i in range(L):
        for start, stop in contact_runs(contacts[:, i]):
            tips = sensors[start:stop, i]
            total[start:stop] += tips.mean(axis=0) - tips
            count[start:stop] += 1
    shift = np.zeros((F, 3))
    on = count > 0
    if not np.any(on):
        return shift
    frames = np.flatnonzero(on)
    k = max(1, int(round(smooth_seconds * fps / 2)))
    kernel = np.hanning(2 * k + 3)[1:-1]
    kernel /= kernel.sum()
    for axis in (0, 2):
        shift[:, axis] = np.interp(np.arange(F), frames, total[on, axis] / count[on])
        shift[:, axis] = np.convolve(np.pad(shift[:, axis], k, mode="edge"), kernel, mode="valid")
    return shift


def pin_targets(sensor: np.ndarray, contacts: np.ndarray, fps: float, blend_seconds: float = 0.1,
                step_limit: Optional[np.ndarray] = None) -> Tuple[np.ndarray, np.ndarray]:
    """Where one toe tip should be on the floor plane, and how much: (targets (F, 3), weights (F,)).

    ``sensor`` (F, 3) is the tip's position. During each contact run the target is one point, the
    tip's mean position over the run; for ``blend_seconds`` before and after it the tip moves away
    from the pin by its own steps, frame by frame, except that a step into a frame with a
    ``step_limit`` (F,) (metres; NaN: none) is no longer than that; over the next ``blend_seconds``
    the weight falls smoothly to 0 (the nearer run wins between two). Only x and z are meant: y is
    the tip's own (heights are :func:`band_heights`')."""
    F = len(sensor)
    targets = sensor.copy()
    weights = np.zeros(F)
    blend = max(1, int(round(blend_seconds * fps)))
    limit = np.full(F, np.nan) if step_limit is None else np.asarray(step_limit, dtype=np.float64)
    flat = sensor * np.array([1.0, 0.0, 1.0])
    for start, stop in contact_runs(contacts):
        lo, hi = max(0, start - 2 * blend), min(F, stop + 2 * blend)
        want = np.empty((hi - lo, 3))
        want[start - lo:stop - lo] = flat[start:stop].mean(axis=0)
        # outwards from the run's edges; a step sets the speed of the later of its two frames
        steps = [(k, k + 1, k + 1) for k in range(start - 1, lo - 1, -1)] + [(k, k - 1, k) for k in range(stop, hi)]
        for k, nxt, later in steps:
            step = flat[k] - flat[nxt]
            n = np.linalg.norm(step)
            if np.isfinite(limit[later]) and n > limit[later]:
                step = step * (limit[later] / n)
            want[k - lo] = want[nxt - lo] + step
        want[:, 1] = sensor[lo:hi, 1]
        k = np.arange(lo, hi)
        dist = np.where(k < start, start - k, np.where(k >= stop, k - stop + 1, 0))
        w = 0.5 + 0.5 * np.cos(np.pi * np.clip((dist - blend) / (blend + 1), 0, 1))
        better = w > weights[lo:hi]
        targets[lo:hi][better] = want[better]
        weights[lo:hi] = np.maximum(weights[lo:hi], w)
    return targets, weights


def pitch_foot(P: np.ndarray, R: np.ndarray, ankle: int, below: Sequence[int], sensor: int, height: np.ndarray,
               max_pitch: float) -> None:
    """Turn each frame's foot about the ankle, in the vertical plane of the ankle -> sensor line,
    towards putting the sensor at ``height`` (F,), by at most ``max_pitch`` radians; in place.

    P (F, J, 3) world positions and R (F, J, 3, 3) world rotations; the ankle stays where it is,
    its rotation and every joint in ``below`` (the ankle's descendants) turn with the foot. The
    foot must not point straight down (pose.place_feet stops it 5 degrees short)."""
    a = P[:, ankle]
    r = P[:, sensor] - a
    length = np.maximum(np.linalg.norm(r, axis=-1), 1e-9)
    flat = np.maximum(np.hypot(r[:, 0], r[:, 2]), 1e-9)
    now = np.arctan2(r[:, 1], flat)
    # short of straight down, unless the foot already points further (then it may stay)
    lo, hi = np.minimum(-0.99, np.sin(now)), np.maximum(0.99, np.sin(now))
    want = np.arcsin(np.clip((height - a[:, 1]) / length, lo, hi))
    turned = now + np.clip(want - now, -max_pitch, max_pitch)
    new = np.cos(turned)[:, None] * (r * np.array([1.0, 0.0, 1.0])) / flat[:, None]
    new[:, 1] = np.sin(turned)
    Q = rotation_between(r / length[:, None], new)                 # (F, 3, 3) about the foot's side axis
    R[:, ankle] = Q @ R[:, ankle]
    for j in below:
        P[:, j] = a + (Q @ (P[:, j] - a)[..., None])[..., 0]
        R[:, j] = Q @ R[:, j]
