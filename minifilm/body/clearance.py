"""Toes kept out of the floor in swing: the foot and the toe turned up about the ankle and the ball.

The pose transfer gives a target foot the source foot's pitch (shifted by the rigs' flat-foot
pitches). Right after toe-off the toes point down, and a foot longer than the source's reaches
further down: the 100STYLE toe tip (24 cm ahead of the ankle, Bandai's 12) sank 5-7 cm below
the floor on the Bandai clips. Here, per leg and frame, as little as that needs:

1. the foot (ankle and everything below it) is turned up about the ankle, in the vertical plane
   of the ankle -> ball line, until the ball (the toe joint) is no lower than the floor bound;
2. the toe (toe joint and below) is turned up about the ball until the tip is no lower than it,
   as a real foot's toes bend up at toe-off (at most until the toe points ``max_toe_up`` above
   the horizontal; a rig without a toe bone of its own takes it all by step 1, on the tip).

Each angle is smoothed in time by its upper envelope (a running maximum, then a Hann window of
the same width), so the turn fades in and out over ``smooth_seconds`` and is never less than
needed. Nothing turns while the source's foot is in contact (the planted tip would leave the
floor, and the contacts would disagree): the turn fades in over ``ramp_seconds`` after a contact
and out before the next, so the first frame or two after toe-off may still dip (by up to 1.5 cm
on the Bandai files, against 5-7 cm before). The toe bend costs nothing on a round trip through a rig whose foot
bone ends at the ball (Bandai: its foot is aimed along the ankle -> ball line); the foot's turn
comes back as a higher foot (measured: benchmarks/README.md).
"""
from __future__ import annotations

from typing import Callable, Optional, Sequence, Tuple

import numpy as np

from minifilm.motion.skeleton_fit import rotation_between

__all__ = ["FLOOR_SLACK", "upper_envelope", "needed_lift", "turn_up", "away_from", "clear_floor",
           "clear_floor_keeping_contacts"]


#: how far (metres) below the floor (or the source's own tip, where that is lower) a ball or tip
#: may go: the sources' own tips go 0.2 cm below their floor, and 0.5 cm more keeps the foot's
#: turn small enough for the Bandai round trip (0.5 cm: one Bandai-1 file's toe at 3.02 cm p95)
FLOOR_SLACK = 0.007


def upper_envelope(x: np.ndarray, radius: int) -> np.ndarray:
    """(F,) a smooth series never below ``x`` (F,): its running maximum over ±radius frames, then a
    Hann-weighted mean over the same ±radius (each mean is over values all >= x at its centre)."""
    x = np.asarray(x, dtype=np.float64)
    if radius < 1 or len(x) < 2:
        return x.copy()
    padded = np.pad(x, radius, mode="edge")
    windows = np.lib.stride_tricks.sliding_window_view(padded, 2 * radius + 1)
    dilated = np.pad(windows.max(axis=1), radius, mode="edge")
    kernel = np.hanning(2 * radius + 3)[1:-1]
    return np.convolve(dilated, kernel / kernel.sum(), mode="valid")


def needed_lift(pivot: np.ndarray, point: np.ndarray, floor: np.ndarray, max_up: float = np.pi / 2) -> np.ndarray:
    """(F,) the upward turn (radians, >= 0) about ``pivot`` (F, 3), in the vertical plane through
    pivot and ``point`` (F, 3), that puts the point no lower than ``floor`` (F,) heights; the
    point ends no more than ``max_up`` above the pivot's horizontal (a pivot under the floor: as
    high as that goes)."""
    r = point - pivot
    flat = np.hypot(r[:, 0], r[:, 2])
    length = np.maximum(np.linalg.norm(r, axis=-1), 1e-9)
    now = np.arctan2(r[:, 1], flat)
    want = np.arcsin(np.clip((floor - pivot[:, 1]) / length, -1.0, np.sin(max_up)))
    return np.where(point[:, 1] < floor, np.maximum(want - now, 0.0), 0.0)


def turn_up(P: np.ndarray, R: np.ndarray, pivot: int, aim: int, moved: Sequence[int], angle: np.ndarray) -> None:
    """Turn joint ``pivot``'s rotation and the joints ``moved`` (its descendants) up by ``angle``
    (F,) radians about the pivot, in the vertical plane of the pivot -> ``aim`` line; in place on
    P (F, J, 3) and R (F, J, 3, 3)."""
    a = P[:, pivot]
    r = P[:, aim] - a
    flat = np.maximum(np.hypot(r[:, 0], r[:, 2]), 1e-9)
    length = np.maximum(np.linalg.norm(r, axis=-1), 1e-9)
    now = np.arctan2(r[:, 1], flat)
    new = np.cos(now + angle)[:, None] * (r * np.array([1.0, 0.0, 1.0])) / flat[:, None]
    new[:, 1] = np.sin(now + angle)
    Q = rotation_between(r / length[:, None], new)
    R[:, pivot] = Q @ R[:, pivot]
    for j in moved:
        P[:, j] = a + (Q @ (P[:, j] - a)[..., None])[..., 0]
        R[:, j] = Q @ R[:, j]


def clear_floor(P: np.ndarray, R: np.ndarray, parents: np.ndarray, feet: Sequence[Sequence[Optional[int]]],
                floor: np.ndarray, fps: float, contacts: Optional[np.ndarray] = None, smooth_seconds: float = 1 / 15,
                ramp_seconds: float = 0.05, max_toe_up: float = np.radians(30.0)) -> None:
    """Keep each foot's ball and tip above ``floor`` (F, len(feet)) heights (module doc); in place.

    Args:
        P, R:   (F, J, 3) world positions, (F, J, 3, 3) world rotations, floor at y = 0.
        parents: (J,) the hierarchy.
        feet:   per foot (ankle, toe, tip) joint indices; toe is None on a rig without a toe bone
                (then the foot is turned for the tip).
        floor:  the lowest height (metres) each foot's ball and tip may have, per frame.
        contacts: (F, len(feet)) 0/1 the source's contacts: no turn there (the feet are planted),
                  fading in over ``ramp_seconds`` after each and out before.
        smooth_seconds: how long each turn fades in and out.
    """
    radius = max(1, int(round(smooth_seconds * fps / 2)))
    F = len(P)
    free = np.ones((F, len(feet))) if contacts is None else np.stack(
        [away_from(c, max(1, int(round(ramp_seconds * fps)))) for c in np.asarray(contacts).T], axis=1)
    for i, (ankle, toe, tip) in enumerate(feet):
        ball = toe if toe is not None and toe != tip else tip
        lift = needed_lift(P[:, ankle], P[:, ball], floor[:, i])
        if np.any(lift > 0):
            turn_up(P, R, ankle, ball, _descendants(ankle, parents), free[:, i] * upper_envelope(lift, radius))
        if ball == tip:
            continue
        bend = needed_lift(P[:, ball], P[:, tip], floor[:, i], max_up=max_toe_up)
        if np.any(bend > 0):
            turn_up(P, R, ball, tip, _descendants(ball, parents), free[:, i] * upper_envelope(bend, radius))


def clear_floor_keeping_contacts(P: np.ndarray, R: np.ndarray, parents: np.ndarray, feet, floor: np.ndarray,
                                 fps: float, contacts: np.ndarray, contact_test: Callable[[np.ndarray], np.ndarray],
                                 passes: int = 4) -> Tuple[np.ndarray, np.ndarray]:
    """:func:`clear_floor` on copies of P and R, with no turn where a foot is planted or where
    turning would change what the target's own contact test says; returns new (P, R).

    ``contacts`` (F, L): the source's; ``contact_test``: positions (F, J, 3) -> (F, L) 0/1, the
    target's test. A foot is held where the source's test or the target's own (before any turn)
    says contact: a turn moves a tip that test holds still (skating). Where a turn still makes
    or takes away a contact (a tip turned up and back slows into the test's band just after
    toe-off), that frame and one either side are held too, and the turn is made again, up to
    ``passes`` times."""
    own = contact_test(P)
    hold = np.maximum(np.asarray(contacts, dtype=np.float64), own)
    for _ in range(passes):
        P1, R1 = P.copy(), R.copy()
        clear_floor(P1, R1, parents, feet, floor, fps, hold)
        changed = (contact_test(P1) != own).astype(np.float64)
        if not np.any(changed):
            break
        hold = np.maximum(hold, np.maximum(changed, np.maximum(np.r_[changed[1:], changed[-1:]],
                                                               np.r_[changed[:1], changed[:-1]])))
    return P1, R1


def away_from(contacts: np.ndarray, ramp: int) -> np.ndarray:
    """(F,) 0 on the frames of a 0/1 series (F,) that are 1, rising as a raised cosine to 1 by
    ``ramp`` + 1 frames away from the nearest such frame (1 everywhere without any)."""
    on = np.flatnonzero(np.asarray(contacts) > 0.5)
    if len(on) == 0:
        return np.ones(len(contacts))
    frames = np.arange(len(contacts))
    k = np.clip(np.searchsorted(on, frames), 1, len(on) - 1) if len(on) > 1 else np.zeros(len(frames), int)
    dist = np.abs(frames - on[k]) if len(on) == 1 else np.minimum(np.abs(frames - on[k - 1]), np.abs(frames - on[k]))
    return 0.5 - 0.5 * np.cos(np.pi * np.clip(dist / (ramp + 1), 0.0, 1.0))


def _descendants(joint: int, parents: np.ndarray) -> list:
    out, stack = [], [joint]
    while stack:
        kids = [int(c) for c in np.flatnonzero(np.asarray(parents) == stack.pop())]
        out += kids
        stack += kids
    return out
