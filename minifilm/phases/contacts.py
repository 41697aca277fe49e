"""Foot contacts from toe-tip sensors (Sec. 4.1.2; docs/original-code.md §2).

A sensor is in contact when it is slow *and* near the floor:

    raw[k] = (|v(k)| <= 0.15 m/s) and (|y(k) − floor| <= 0.01 m)

with ``v`` the backward-difference velocity in m/s (§1.4), then a majority filter over a clamped
window (11 frames at 60 fps; ties keep the raw value). Everything is defined in seconds and metres,
so 30, 60 and 120 fps files give the same contacts for the same motion.

Difference to the original: its floor is the plane y = 0 of the Unity scene. Not every dataset
stands on y = 0 (and a retargeted skeleton may float or sink a few centimetres), so ``floor_height``
is a parameter, estimated by default as the median height of the slow sensor samples (where the
toes rest), or a low percentile of the heights.

Any humanoid file, not only the built-in skeletons: ``humanoid_contacts`` takes the toe tips and
hips of the humanoid parts its reader found (minifilm/body/read.py, once per file) and a motion in
metres (read with the unit of minifilm/body/units.py), so the thresholds above mean what they say.
"""
from __future__ import annotations

from typing import Optional, Tuple

import numpy as np


__all__ = ["estimate_floor_height", "foot_contacts", "majority_filter", "gait_contacts", "humanoid_contacts"]

#: 11 frames at 60 fps (the original's FilterWidth = 5 each side), as a duration.
DEFAULT_FILTER_SECONDS = 10.0 / 60.0


def estimate_floor_height(heights, speeds=None, speed_threshold: float = 0.15,
                          percentile: float = 2.0) -> float:
    """Floor height (metres) from contact-sensor heights.

    Args:
        heights: (F, ...) heights (y) of the contact sensors, metres; all entries are pooled.
        speeds: optional (F, ...) sensor speeds in m/s. When given, the floor is the median height
            of the slow samples (speed <= speed_threshold): where the toes rest. This is robust to
            skeletons whose two feet rest a centimetre apart in height (retargeted data), which a
            low percentile would put on the lower foot only.
        percentile: without speeds (or with fewer than 2 % slow samples), the ``percentile``-th
            percentile of all heights: a low percentile rather than the minimum, so a few glitch
            frames below the floor do not drag it down.
    """
    h = np.asarray(heights, dtype=np.float64)
    finite = np.isfinite(h)
    if not np.any(finite):
        raise ValueError("estimate_floor_height: no finite heights given")
    if speeds is not None:
        sp = np.asarray(speeds, dtype=np.float64)
        if sp.shape != h.shape:
            raise ValueError(f"estimate_floor_height: speeds {sp.shape} and heights {h.shape} differ in shape")
        slow = finite & (sp <= speed_threshold)
        if slow.sum() >= max(1, 0.02 * h.size):
            return float(np.median(h[slow]))
    return float(np.percentile(h[finite], percentile))


def majority_filter(raw, half_width: int) -> np.ndarray:
    """Majority vote of 0/1 values over the clamped window ``[k - h, k + h] ∩ [0, F-1]``.

    raw (F, ...) of 0/1 -> (F, ...) of 0.0/1.0: 1 where ones outnumber zeros, 0 where zeros
    outnumber ones, the raw value on a tie (docs/original-code.md §2, "Filter").
    """
    x = (np.asarray(raw) > 0.5).astype(np.int64)
    n = x.shape[0]
    if n == 0 or half_width <= 0:
        return x.astype(np.float64)
    csum = np.concatenate([np.zeros((1,) + x.shape[1:], np.int64), np.cumsum(x, axis=0)])
    k = np.arange(n)
    lo, hi = np.maximum(k - half_width, 0), np.minimum(k + half_width, n - 1) + 1
    ones = csum[hi] - csum[lo]
    count = (hi - lo).reshape((n,) + (1,) * (x.ndim - 1))
    zeros = count - ones
    out = np.where(ones > zeros, 1, np.where(zeros > ones, 0, x))
    return out.astype(np.float64)


def foot_contacts(sensor_positions, fps: float, floor_height: Optional[float] = None,
                  speed_threshold: float = 0.15, height_threshold: float = 0.01,
                  filter_seconds: float = DEFAULT_FILTER_SECONDS) -> np.ndarray:
    """0/1 foot contacts per frame (Sec. 4.1.2).

    Args:
        sensor_positions: (F, 2, 3) world positions (metres, y up) of the toe-tip sensors in the
            order [right, left] (``Skeleton.contact_bones``).
        fps: frames per second; velocities are per second, the filter window is in seconds.
        floor_height: floor y in metres; ``None`` estimates it with ``estimate_floor_height``
            (median height of the slow sensor samples).
        speed_threshold: maximum sensor speed in contact, m/s (paper: v_max = 0.15).
        height_threshold: maximum |y − floor| in contact, metres (paper: d_max = 0.01). Like the
            original's sphere-against-plane test, a sensor more than this *below* the floor is
            not in contact either.
        filter_seconds: span of the majority window; half width round(filter_seconds * fps / 2)
            frames (5 at 60 fps: 11 frames). 0 disables the filter.
    Returns:
        (F, 2) float array of 0.0/1.0 in the order [right, left].
    """
    p = np.asarray(sensor_positions, dtype=np.float64)
    if p.ndim != 3 or p.shape[1:] != (2, 3):
        raise ValueError(f"foot_contacts: sensor_positions must have shape (F, 2, 3), got {p.shape}")
    if not (fps > 0):
        raise ValueError(f"foot_contacts: fps must be positive, got {fps}")
    if p.shape[0] == 0:
        return np.zeros((0, 2))
    v = np.zeros_like(p)
    if p.shape[0] >= 2:  # backward difference, frame 0 copies frame 1 (docs/original-code.md §1.4)
        v[1:] = (p[1:] - p[:-1]) * fps
        v[0] = v[1]
    speed = np.linalg.norm(v, axis=-1)
    if floor_height is None:    # PAPER: the paper does not say where the floor is; the original:
        # y = 0, its scene's plane. Estimated here, since not every file stands on y = 0.
        floor_height = estimate_floor_height(p[..., 1], speed, speed_threshold)
    floor = float(floor_height)
    raw = (speed <= speed_threshold) & (np.abs(p[..., 1] - floor) <= height_threshold)
    # PAPER: the paper does not filter the labels; the original takes the majority of 11 frames
    # (at 60 fps) around each, as here: short flickers of the raw label vanish
    half = int(np.floor(filter_seconds * fps / 2 + 0.5))
    return majority_filter(raw, half)


#: humanoid_contacts' defaults for motion capture of any source: a stance foot may slide at up
#: to this fraction of the hips' median ground speed, and rest this far above or below the floor
GAIT_SPEED_FRACTION = 0.3
GAIT_HEIGHT_THRESHOLD = 0.03


def gait_contacts(positions, sensors, hips: int, fps: float, speed_threshold: Optional[float] = None,
                  height_threshold: Optional[float] = None, **kwargs) -> np.ndarray:
    """Foot contacts with thresholds that hold on motion capture of any source and on generated
    motion: :func:`foot_contacts` with the speed threshold max(0.15, GAIT_SPEED_FRACTION x the
    hips' median ground speed) and the height threshold GAIT_HEIGHT_THRESHOLD unless given.

    positions (F, J, 3) world, metres; sensors (2,): [right, left] toe-tip joints; hips: the hips
    joint; kwargs: ``floor_height``, ``filter_seconds``. Returns (F, 2) of 0.0/1.0.

    PAPER: its 0.15 m/s and 1 cm were set on 100STYLE (60 fps, clean, feet on y = 0). They find no
    contact at all in CMU 08_01 (120 fps; its toe tips slide at about 0.2 m/s and rest 1.6-7 cm up
    through a stance) nor in a network's own walk whose feet slide at 0.3 m/s, and miss every
    stance of one foot in about 40 % of the runs of Bandai-Namco's dataset 2."""
    positions = np.asarray(positions)
    if speed_threshold is None:
        ground = positions[:, hips, ::2]                                              # (F, 2) x, z
        speed = np.linalg.norm(np.diff(ground, axis=0), axis=-1) * fps if len(ground) > 1 else np.zeros(1)
        speed_threshold = max(0.15, GAIT_SPEED_FRACTION * float(np.median(speed)))
    if height_threshold is None:
        height_threshold = GAIT_HEIGHT_THRESHOLD
    return foot_contacts(positions[:, np.asarray(sensors)], fps, speed_threshold=speed_threshold,
                         height_threshold=height_threshold, **kwargs)


def humanoid_contacts(motion, humanoid, **kwargs) -> Tuple[np.ndarray, np.ndarray]:
    """Foot contacts of any humanoid motion, from the toe tips of its parts (:func:`gait_contacts`).

    motion: a Motion in metres (e.g. ``read_in_metres(path)`` of minifilm/body/read.py); humanoid:
    its parts (a ``minifilm.body.parts.Humanoid``), found once by its reader: its
    ``contact_sensors`` and ``hips`` are read. kwargs: as :func:`gait_contacts` (pass the paper's
    thresholds to get them). Returns contacts (F, 2) of 0.0/1.0 and sensors (2,): the joint
    indices [right toe tip, left toe tip]."""
    sensors = np.array(humanoid.contact_sensors, dtype=np.int64)
    return gait_contacts(motion.world()[0], sensors, humanoid.hips, motion.fps, **kwargs), sensors
