"""Feet of a retargeted motion: on the floor, and planted where the source's feet were planted.

After the pose transfer the target's feet follow the source's joint angles on other bone lengths,
so they float, sink and slide by a few centimetres. Here:

1. the floor: the target is lifted or lowered as a whole so that where its toe tips rest
   (:func:`minifilm.phases.contacts.estimate_floor_height`) is y = 0 (``retarget_clip.py``);
2. the contacts (:func:`plant_feet`): the source's foot contacts
   (:func:`minifilm.phases.contacts.foot_contacts` on its toe tips) say when each foot is planted.
   During each contact the target's toe tip stays at one point; the heights of the tips are
   changed only where the contact test would otherwise disagree with the source's, and near a
   contact the tip comes down towards the source tip's height. How, in order
   (:mod:`minifilm.body.tips`):

   * each foot is turned about its ankle by up to ``max_pitch`` towards its tip's height;
   * the body (hips and everything below) is shifted horizontally so the planted tips stay put;
   * the leg reaches for what is left with the two-bone IK of
     :func:`minifilm.motion.foot_ik.two_bone_ik` (hip fixed, thigh and shin lengths kept, knee in
     its bending plane); the foot moves rigidly with the ankle. A tip out of the leg's reach is
     approached as far as the straight leg goes (the body is not lowered: that does not come
     back on a round trip);
3. the thigh and shin rotations are turned by the smallest rotations onto the new knee and ankle.

Why each step moves as little as it does: a clip taken to another rig and back must come back
within 3 cm (the target of reports/2026-12-02_retargeting.md), and every change here is made on both passes.
"""
from __future__ import annotations

from typing import Sequence, Tuple

import numpy as np

from minifilm.motion.foot_ik import two_bone_ik
from minifilm.motion.skeleton_fit import rotation_between
from minifilm.phases.contacts import estimate_floor_height
from minifilm.body.tips import (HEIGHT_BAND, SPEED_THRESHOLD, band_heights, pin_targets, pitch_foot,
                                slide_correction, speeds)

__all__ = ["floor_height", "plant_feet"]

#: near a contact (within ``blend_seconds``, fading over as long again) a tip comes down to the
#: source tip's height while that is under this (metres), fading to its own height by twice it:
#: so the two land and lift off on the same frames
NEAR_FLOOR = 0.02


def floor_height(sensors: np.ndarray, fps: float) -> float:
    """Floor y (metres) under toe-tip sensors (F, 2, 3): the median height of their slow samples."""
    v = np.zeros_like(sensors)
    if len(sensors) >= 2:
        v[1:] = (sensors[1:] - sensors[:-1]) * fps
        v[0] = v[1]
    return estimate_floor_height(sensors[..., 1], np.linalg.norm(v, axis=-1))


def plant_feet(positions: np.ndarray, world: np.ndarray, parents: np.ndarray, legs: Sequence[Sequence[int]],
               contacts: np.ndarray, guides: np.ndarray, fps: float, body: Sequence[int], blend_seconds: float = 0.1,
               max_pitch: float = np.radians(5.0)) -> Tuple[np.ndarray, np.ndarray]:
    """Plant each leg's toe tip during its contacts, and give it the source's contacts (module doc).

    Args:
        positions: (F, J, 3) world joint positions, floor at y = 0.
        world:     (F, J, 3, 3) world rotations.
        parents:   (J,) the hierarchy.
        legs:      per leg, joint indices (upper leg, knee, ankle, sensor); the sensor is below the
                   ankle (a toe tip, or the toe joint).
        contacts:  (F, len(legs)) 0/1 source contacts, in the order of ``legs``.
        guides:    (F, len(legs), 3) the source's toe tips, its floor at y = 0 (unscaled: their
                   speeds are compared with the contact test's threshold).
        body:      the joints that move with the hips (the hips and everything below them).
        max_pitch: how far (radians) a foot may be turned about its ankle towards its tip's height.
                   5 degrees measured best (benchmarks/README.md): more changes the foot by more
                   than a round trip gives back, none misses contacts a slight turn catches.
    Returns:
        new (positions, world).
    """
    P, R = positions.copy(), world.copy()
    parents = np.asarray(parents)
    contacts = np.asarray(contacts)
    sensors = [int(leg[3]) for leg in legs]
    below = [_descendants(int(leg[2]), parents) for leg in legs]
    guide_speed = [speeds(guides[:, i], fps) for i in range(len(legs))]
    # where the source's tip passes the contact test, the target's may step no farther than it
    # (horizontally: the skating measure is the horizontal speed)
    limits = [np.where((v <= SPEED_THRESHOLD) & (np.abs(guides[:, i, 1]) <= HEIGHT_BAND),
                       speeds(guides[:, i] * np.array([1.0, 0.0, 1.0]), fps) / fps, np.nan)
              for i, v in enumerate(guide_speed)]
    # near a contact (the pins' weights), towards the source tip's height while it is near the floor
    weights = [pin_targets(P[:, j], c, fps, blend_seconds)[1] for j, c in zip(sensors, contacts.T)]
    near = [w * np.clip(2.0 - np.abs(guides[:, i, 1]) / NEAR_FLOOR, 0.0, 1.0) for i, w in enumerate(weights)]

    def heights(soft: bool):
        out = []
        for i, j in enumerate(sensors):
            h = band_heights(P[:, j, 1], speeds(P[:, j], fps), guides[:, i, 1], guide_speed[i], where=weights[i] > 0)
            out.append(h + near[i] * (guides[:, i, 1] - h) if soft else h)
        return out

    for leg, under, h in zip(legs, below, heights(soft=True)):
        pitch_foot(P, R, int(leg[2]), under, int(leg[3]), h, max_pitch)
    P[:, list(body)] += slide_correction(P[:, sensors], contacts, fps)[:, None]
    pins = [pin_targets(P[:, j], c, fps, blend_seconds, limit) for j, c, limit in zip(sensors, contacts.T, limits)]
    # the leg reaches for the pins and for the heights the contact test needs (not the softer
    # heights near a contact: those only the foot's turn goes for)
    for leg, under, h, (t, w) in zip(legs, below, heights(soft=False), pins):
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
