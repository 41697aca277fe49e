"""Feet of a retargeted motion: on the floor, and planted where the source's feet were planted.

After the pose transfer the target's feet follow the source's joint angles on other bone lengths,
so they float, sink and slide by a few centimetres. Here:

1. the floor: the target is lifted or lowered as a whole so that where its toe tips rest
   (:func:`minifilm.phases.contacts.estimate_floor_height`) is y = 0;
2. the contacts: the source's foot contacts (:func:`minifilm.phases.contacts.foot_contacts` on its
   toe-tip sensors) say when each foot is planted. During each contact the target's toe tip is
   pinned at one point on the floor (the source's tip's mean position over the contact, scaled like
   the root's path, at y = 0); for ``blend_seconds`` on either side it follows the source's tip
   into and out of the pin; the leg reaches it with the two-bone
   IK of :func:`minifilm.motion.foot_ik.two_bone_ik` (hip fixed, thigh and shin lengths kept, knee
   in its bending plane) and the foot moves rigidly with the ankle. Where a pin is out of the leg's
   reach (the rigs' proportions differ), the whole body is first lowered just enough, smoothly.
3. the thigh and shin rotations are turned by the smallest rotations onto the new knee and ankle,
   the foot keeps its world rotation.
"""
from __future__ import annotations

from typing import Optional, Sequence, Tuple

import numpy as np

from minifilm.motion.foot_ik import two_bone_ik
from minifilm.motion.skeleton_fit import rotation_between
from minifilm.phases.contacts import estimate_floor_height

__all__ = ["floor_height", "contact_runs", "pin_targets", "speeds", "band_heights", "hips_drop", "pitch_foot", "slide_correction", "plant_feet"]


def floor_height(sensors: np.ndarray, fps: float) -> float:
    """Floor y (metres) under toe-tip sensors (F, 2, 3): the median height of their slow samples."""
    v = np.zeros_like(sensors)
    if len(sensors) >= 2:
        v[1:] = (sensors[1:] - sensors[:-1]) * fps
        v[0] = v[1]
    return estimate_floor_height(sensors[..., 1], np.linalg.norm(v, axis=-1))


def contact_runs(contacts: np.ndarray) -> list:
    """[(start, stop)] frame ranges where a 0/1 series (F,) is 1."""
    c = np.concatenate([[0], (np.asarray(contacts) > 0.5).astype(int), [0]])
    d = np.diff(c)
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def pin_targets(sensor: np.ndarray, contacts: np.ndarray, fps: float, blend_seconds: float = 0.1,
                step_limit: Optional[np.ndarray] = None) -> Tuple[np.ndarray, np.ndarray]:
    """Where one toe tip should be on the floor plane, and how much: (targets (F, 3), weights (F,)).

    ``sensor`` (F, 3) is the tip's position. During each contact run the target is one point, the
    tip's mean position over the run; for ``blend_seconds`` before and after it the tip moves away
    from the pin as it moves itself (its own steps, frame by frame), except that a step into a frame
    with a ``step_limit`` (F,) (metres, NaN: none) is no longer than that; over the next
    ``blend_seconds`` the weight falls smoothly to 0 (the nearer run wins between two). Only x and z
    are meant: y is the tip's own (heights are :func:`band_heights`')."""
    F = len(sensor)
    targets = sensor.copy()
    weights = np.zeros(F)
    blend = max(1, int(round(blend_seconds * fps)))
    limit = np.full(F, np.nan) if step_limit is None else np.asarray(step_limit, dtype=np.float64)
    flat = sensor.copy()
    flat[:, 1] = 0.0
    for start, stop in contact_runs(contacts):
        lo, hi = max(0, start - 2 * blend), min(F, stop + 2 * blend)
        want = np.empty((hi - lo, 3))
        want[start - lo:stop - lo] = flat[start:stop].mean(axis=0)
        # walk outwards from the run's edges: the frame whose speed a step sets is the later one
        for k, nxt, later in [(k, k + 1, k + 1) for k in range(start - 1, lo - 1, -1)] + \
                              [(k, k - 1, k) for k in range(stop, hi)]:
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


def speeds(points: np.ndarray, fps: float) -> np.ndarray:
    """(F,) backward-difference speed (m/s) of points (F, 3), frame 0 copying frame 1 (as contacts.py)."""
    v = np.zeros(len(points))
    if len(points) >= 2:
        v[1:] = np.linalg.norm(points[1:] - points[:-1], axis=-1) * fps
        v[0] = v[1]
    return v


def band_heights(height: np.ndarray, speed: np.ndarray, guide: np.ndarray, guide_speed: np.ndarray,
                 speed_threshold: float = 0.15, band: float = 0.01, margin: float = 0.003) -> np.ndarray:
    """(F,) the height (floor at 0) a target toe tip should have so that the contact test of
    :func:`minifilm.phases.contacts.foot_contacts` (slow and within ``band`` of the floor) says on
    every frame what it says for the source's tip, changing the tip's own ``height`` (F,) only
    where it has to.

    Where the source's tip (``guide`` heights and ``guide_speed``, (F,) each) passes the test, the
    tip takes its height (then the floor the test estimates on the target, the median height of its
    slow tips, is the source's too); where the source's tip does not pass but the target's slow tip
    would, it takes the source tip's height if that is out of the band, else is lifted (or lowered)
    ``margin`` out of it. Anywhere else the tip keeps its own height: feet of other lengths lift
    their tips differently, and forcing the source's heights there bends the knee or the foot (a
    round trip pays it twice)."""
    src_in = (guide_speed <= speed_threshold) & (np.abs(guide) <= band)
    own_in = (speed <= speed_threshold) & (np.abs(height) <= band)
    away = np.where(np.abs(guide) > band, guide, np.where(height < 0, -1.0, 1.0) * (band + margin))
    return np.where(src_in, guide, np.where(own_in, away, height))


def hips_drop(P: np.ndarray, legs: Sequence[Sequence[int]], wants: Sequence[np.ndarray], weights: Sequence[np.ndarray],
              fps: float, smooth_seconds: float = 0.1, reach: float = 0.999) -> np.ndarray:
    """(F,) how far (metres) to lower the body so that every pinned foot can be reached.

    A pinned ankle farther from its hip than ``reach`` times the leg's length (proportions differ:
    a wider pelvis, a longer foot) pulls the hips straight down just enough, in proportion to the
    pin's weight; the drop is then widened by a running maximum and smoothed over
    ``smooth_seconds`` so the body does not bob."""
    F = len(P)
    drop = np.zeros(F)
    for (hip, knee, ankle, _), want, w in zip(legs, wants, weights):
        length = reach * (np.linalg.norm(P[:, knee] - P[:, hip], axis=-1) + np.linalg.norm(P[:, ankle] - P[:, knee], axis=-1))
        d = want - P[:, hip]
        horizontal = np.hypot(d[:, 0], d[:, 2])
        below = np.sqrt(np.maximum(length ** 2 - horizontal ** 2, 0.0))      # how far below the hip it may be
        need = np.maximum(0.0, -d[:, 1] - below)
        drop = np.maximum(drop, w * need)
    k = max(1, int(round(smooth_seconds * fps)))
    padded = np.pad(drop, k, mode="edge")
    widened = np.max(np.stack([padded[i:i + F] for i in range(2 * k + 1)]), axis=0)
    kernel = np.hanning(2 * k + 3)[1:-1]
    kernel /= kernel.sum()
    return np.convolve(np.pad(widened, k, mode="edge"), kernel, mode="valid")


def pitch_foot(P: np.ndarray, R: np.ndarray, ankle: int, below: Sequence[int], sensor: int, height: np.ndarray,
               max_pitch: float) -> None:
    """Turn each frame's foot about the ankle, in the vertical plane of the ankle -> sensor line,
    so that the sensor is at ``height`` (F,) (as near as ``max_pitch`` radians allows), in place.

    P (F, J, 3) world positions and R (F, J, 3, 3) world rotations; the ankle stays where it is,
    the ankle's rotation and every joint in ``below`` (the ankle's descendants) turn with it."""
    a = P[:, ankle]
    r = P[:, sensor] - a
    length = np.maximum(np.linalg.norm(r, axis=-1), 1e-9)
    flat = np.maximum(np.hypot(r[:, 0], r[:, 2]), 1e-9)
    now = np.arctan2(r[:, 1], flat)
    want = np.arcsin(np.clip((height - a[:, 1]) / length, -0.99, 0.99))
    turn = np.clip(want - now, -max_pitch, max_pitch)
    new = np.cos(now + turn)[:, None] * np.stack([r[:, 0], np.zeros(len(r)), r[:, 2]], -1) / flat[:, None]
    new[:, 1] = np.sin(now + turn)
    Q = rotation_between(r / length[:, None], new)                 # (F, 3, 3) about the foot's side axis
    R[:, ankle] = Q @ R[:, ankle]
    for j in below:
        P[:, j] = a + (Q @ (P[:, j] - a)[..., None])[..., 0]
        R[:, j] = Q @ R[:, j]


def slide_correction(sensors: np.ndarray, contacts: np.ndarray, fps: float, smooth_seconds: float = 0.1) -> np.ndarray:
    """(F, 3) horizontal shift of the body that keeps planted toe tips where they were put down.

    ``sensors`` (F, L, 3) toe tips, ``contacts`` (F, L) 0/1. On a frame where foot i is in contact
    it wants the shift pin_i - tip_i (pin_i: the tip's mean over that contact run); the shift is
    the mean over the feet in contact, linearly interpolated over frames without a contact, then
    smoothed over ``smooth_seconds``. Every step is linear in the tips, so a round trip (rig A -> B
    -> A with the same contacts) undoes the first pass's shift, up to the source tips' own slide."""
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
    for axis in (0, 2):
        shift[:, axis] = np.interp(np.arange(F), frames, total[on, axis] / count[on])
    k = max(1, int(round(smooth_seconds * fps / 2)))
    kernel = np.hanning(2 * k + 3)[1:-1]
    kernel /= kernel.sum()
    for axis in (0, 2):
        shift[:, axis] = np.convolve(np.pad(shift[:, axis], k, mode="edge"), kernel, mode="valid")
    return shift


NEAR = 0.02
SPEED, BAND = 0.15, 0.01


def plant_feet(positions: np.ndarray, world: np.ndarray, parents: np.ndarray, legs: Sequence[Sequence[int]],
               contacts: np.ndarray, guides: np.ndarray, fps: float, body: Sequence[int], blend_seconds: float = 0.1,
               max_pitch: float = np.radians(30.0)) -> Tuple[np.ndarray, np.ndarray]:
    """Plant each leg's toe tip during its contacts, and give it the source's contacts (module doc).

    Args:
        positions: (F, J, 3) world joint positions, floor at y = 0.
        world:     (F, J, 3, 3) world rotations.
        parents:   (J,) the hierarchy.
        legs:      per leg, joint indices (upper leg, knee, ankle, sensor); the sensor is below the
                   ankle (a toe tip, or the toe joint).
        contacts:  (F, len(legs)) 0/1 source contacts, in the order of ``legs``.
        guides:    (F, len(legs), 3) the source's toe tips, its floor at y = 0 (:func:`band_heights`).
        body:      the joints that move with the hips (the hips and everything below them).
        max_pitch: how far (radians) a foot may be turned about its ankle to put its tip at its
                   height; what is left is the leg's (two-bone IK).
    Returns:
        new (positions, world): the body shifted horizontally so planted tips stay put
        (:func:`slide_correction`) and lowered where a tip could not be reached (:func:`hips_drop`);
        each foot pitched about its ankle to its tip's height (:func:`band_heights`,
        :func:`pitch_foot`); the legs' knees, ankles and everything below them moved by the
        two-bone IK for what is left; the world rotations of the upper legs and knees turn to match.
    """
    P, R = positions.copy(), world.copy()
    parents = np.asarray(parents)
    contacts = np.asarray(contacts)
    sensors = [int(leg[3]) for leg in legs]
    below = [_descendants(int(leg[2]), parents) for leg in legs]
    guide_speed = [speeds(guides[:, i], fps) for i in range(len(legs))]
    # where the source's tip passes the contact test the target's may move no faster than it
    limits = [np.where((v <= SPEED) & (np.abs(guides[:, i, 1]) <= BAND), speeds(guides[:, i] * [1, 0, 1], fps) / fps, np.nan)
              for i, v in enumerate(guide_speed)]
    near = [w * np.clip(2.0 - np.abs(guides[:, i, 1]) / NEAR, 0.0, 1.0)
            for i, (_, w) in enumerate(pin_targets(P[:, j], c, fps, blend_seconds) for j, c in zip(sensors, contacts.T))]

    def heights(P_, soft=True):
        out = []
        for i, j in enumerate(sensors):
            h = band_heights(P_[:, j, 1], speeds(P_[:, j], fps), guides[:, i, 1], guide_speed[i])
            out.append(h + near[i] * (guides[:, i, 1] - h) if soft else h)
        return out

    def pitch_and_slide(P_, R_):
        """Pitch the feet to their heights, then shift the body so planted tips stay put; the pins."""
        for leg, under, h in zip(legs, below, heights(P_)):
            pitch_foot(P_, R_, int(leg[2]), under, int(leg[3]), h, max_pitch)
        # the body, not the legs, makes up for a planted tip's slide: the legs keep the source's
        # directions (the rigs' legs, scaled by one ratio, carry their feet over different distances)
        P_[:, list(body)] += slide_correction(P_[:, sensors], contacts, fps)[:, None]
        return [pin_targets(P_[:, j], c, fps, blend_seconds, limit) for j, c, limit in zip(sensors, contacts.T, limits)]

    # the height is the foot's to reach (a pitch about the ankle leaves the knee and ankle where
    # the bone directions put them); what the pitch cannot do is the leg's, and the body drops
    # where even the leg cannot
    trial_P, trial_R = P.copy(), R.copy()
    pins = pitch_and_slide(trial_P, trial_R)
    wants, reach = [], []
    for leg, h, (t, w) in zip(legs, heights(trial_P, False), pins):
        shift = w[:, None] * (t - trial_P[:, leg[3]])
        shift[:, 1] = h - trial_P[:, leg[3], 1]
        wants.append(trial_P[:, leg[2]] + shift)
        reach.append(np.maximum(w, np.abs(shift[:, 1]) > 1e-6))
    drop = hips_drop(trial_P, legs, wants, reach, fps)
    P[:, list(body), 1] -= drop[:, None]
    pins = pitch_and_slide(P, R)
    for leg, under, h, (t, w) in zip(legs, below, heights(P, False), pins):
        hip, knee, ankle, sensor = (int(i) for i in leg)
        shift = w[:, None] * (t - P[:, sensor])
        shift[:, 1] = h - P[:, sensor, 1]
        new_knee, new_ankle = two_bone_ik(P[:, hip], P[:, knee], P[:, ankle], P[:, ankle] + shift)
        swing_thigh = rotation_between(P[:, knee] - P[:, hip], new_knee - P[:, hip])
        shin_now = (swing_thigh @ (P[:, ankle] - P[:, knee])[..., None])[..., 0]
        swing_shin = rotation_between(shin_now, new_ankle - new_knee)
        R[:, hip] = swing_thigh @ R[:, hip]
        R[:, knee] = swing_shin @ swing_thigh @ R[:, knee]
        delta = new_ankle - P[:, ankle]
        P[:, knee], P[:, ankle] = new_knee, new_ankle
        for j in under:
            P[:, j] += delta
    return P, R


def _descendants(joint: int, parents: np.ndarray) -> list:
    """Every joint below ``joint``."""
    out, stack = [], [joint]
    while stack:
        kids = [int(c) for c in np.flatnonzero(parents == stack.pop())]
        out += kids
        stack += kids
    return out
