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

from typing import Sequence, Tuple

import numpy as np

from minifilm.motion.foot_ik import two_bone_ik
from minifilm.motion.skeleton_fit import rotation_between
from minifilm.phases.contacts import estimate_floor_height

__all__ = ["floor_height", "contact_runs", "pin_targets", "hips_drop", "plant_feet"]


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


def pin_targets(sensor: np.ndarray, guide: np.ndarray, contacts: np.ndarray, fps: float, blend_seconds: float = 0.1,
                floor: float = 0.0, near_floor: float = 0.02) -> Tuple[np.ndarray, np.ndarray]:
    """Where one toe tip should be, and how much: (targets (F, 3), weights (F,) in [0, 1]).

    ``sensor`` (F, 3) is the tip's position after the transfer, ``guide`` (F, 3) the source's tip
    (floor at 0; not scaled, so that the tip moves at the source tip's speed). During each contact run
    the target is one point: the tip's own mean position over the run, on the floor. For
    ``blend_seconds`` before and after it the tip moves from the pin as the guide moves from its
    position at the run's edge, and over the next ``blend_seconds`` the weight falls smoothly to 0
    (the nearer run wins between two); its height there is the guide's own (above the floor) while
    the guide is within ``near_floor`` metres of the floor, fading to the tip's own height by twice
    that: the tip lands and takes off as the source's does, so the contacts found on the result
    agree with the source's."""
    F = len(sensor)
    targets = sensor.copy()
    weights = np.zeros(F)
    blend = max(1, int(round(blend_seconds * fps)))
    for start, stop in contact_runs(contacts):
        pin = sensor[start:stop].mean(axis=0)
        pin[1] = floor
        lo, hi = max(0, start - 2 * blend), min(F, stop + 2 * blend)
        k = np.arange(lo, hi)
        dist = np.where(k < start, start - k, np.where(k >= stop, k - stop + 1, 0))
        # out of the pin the tip moves as the source's does; the weight fades after `blend` frames
        w = 0.5 + 0.5 * np.cos(np.pi * np.clip((dist - blend) / (blend + 1), 0, 1))
        edge = np.where(k < start, start, stop - 1)
        want = np.where((dist == 0)[:, None], pin, pin + guide[k] - guide[edge])
        # out of the run, while the source's tip is near its floor (where the contact test's height
        # threshold decides), the tip is at the source tip's own height above it: the pin's height
        # plus the guide's rise from the run's edge sat up to a centimetre lower and counted as a
        # contact where a slow pivoting source tip did not. Higher up it fades to the tip's own
        # height: feet of other lengths lift their tips differently, and forcing the source's
        # height there bends the knee by several centimetres (paid twice on a round trip).
        own = np.clip((guide[k, 1] - near_floor) / near_floor, 0.0, 1.0)
        height = (1.0 - own) * (floor + guide[k, 1]) + own * sensor[k, 1]
        want[:, 1] = np.where(dist == 0, floor, height)
        better = w > weights[lo:hi]
        targets[lo:hi][better] = want[better]
        weights[lo:hi] = np.maximum(weights[lo:hi], w)
    return targets, weights


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


def plant_feet(positions: np.ndarray, world: np.ndarray, parents: np.ndarray, legs: Sequence[Sequence[int]],
               contacts: np.ndarray, guides: np.ndarray, fps: float, body: Sequence[int], blend_seconds: float = 0.1
               ) -> Tuple[np.ndarray, np.ndarray]:
    """Pin each leg's sensor to the floor during its contacts (module doc, steps 2-3).

    Args:
        positions: (F, J, 3) world joint positions, floor at y = 0.
        world:     (F, J, 3, 3) world rotations.
        parents:   (J,) the hierarchy.
        legs:      per leg, joint indices (upper leg, knee, ankle, sensor); the sensor is rigid
                   with the ankle (a toe tip, or the toe joint).
        contacts:  (F, len(legs)) 0/1 source contacts, in the order of ``legs``.
        guides:    (F, len(legs), 3) the source's toe tips (:func:`pin_targets`).
        body:      the joints that move with the hips (the hips and everything below them).
    Returns:
        new (positions, world): the body lowered where a pinned foot could not be reached
        (:func:`hips_drop`), then the legs' knees, ankles and everything below them moved; the
        world rotations of the upper legs and knees turn to match, those below the ankle are kept.
    """
    P, R = positions.copy(), world.copy()
    pins = [pin_targets(P[:, leg[3]], guides[:, i], c, fps, blend_seconds)
            for i, (leg, c) in enumerate(zip(legs, np.asarray(contacts).T))]
    wants = [P[:, leg[2]] + (t - P[:, leg[3]]) for leg, (t, _) in zip(legs, pins)]   # ankle where the sensor is pinned
    drop = hips_drop(P, legs, wants, [w for _, w in pins], fps)
    P[:, list(body), 1] -= drop[:, None]
    for leg, (targets, w) in zip(legs, pins):
        hip, knee, ankle, sensor = (int(i) for i in leg)
        shift = w[:, None] * (targets - P[:, sensor])
        new_knee, new_ankle = two_bone_ik(P[:, hip], P[:, knee], P[:, ankle], P[:, ankle] + shift)
        swing_thigh = rotation_between(P[:, knee] - P[:, hip], new_knee - P[:, hip])
        shin_now = (swing_thigh @ (P[:, ankle] - P[:, knee])[..., None])[..., 0]
        swing_shin = rotation_between(shin_now, new_ankle - new_knee)
        R[:, hip] = swing_thigh @ R[:, hip]
        R[:, knee] = swing_shin @ swing_thigh @ R[:, knee]
        delta = new_ankle - P[:, ankle]
        P[:, knee], P[:, ankle] = new_knee, new_ankle
        for j in _descendants(ankle, np.asarray(parents)):
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
