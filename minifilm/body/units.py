"""A file's length unit (metres per file unit) and a body's standing height.

A BVH file does not say its unit. When its joint names are one of the built-in skeletons
(minifilm/motion/skeletons.py) and that skeleton's ``bvh_scale`` gives a human height, the unit is
that one. Otherwise (other names, or known names written in another unit: the 100STYLE skeleton in
millimetres) it is inferred from the body: the thigh and shin together are about 0.49 of a standing adult's height
(Drillis & Contini 1966: 0.245 + 0.246), and a standing human is 1.4-2.1 m tall, so

    stature (file units) = (thigh + shin) / 0.49

and the unit is the common one (millimetre, centimetre, inch, CMU ASF unit, decimetre, foot, metre)
that puts the stature within 1.4-2.1 m (at most one does: neighbouring units differ by more than
2.1 / 1.4). A body that fits none is scaled to a typical 1.7 m, and ``BodyUnit.how`` says so.
Bone lengths do not change with the pose, so this holds for a file that starts crouching or mid-run.

``standing_height`` measures what the viewer shows: the head's top above the floor over the first
second (tests check it is 1.4-2.1 m on every real file).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence, Tuple

import numpy as np

from minifilm.body.parts import Humanoid, HumanoidError
from minifilm.body.roles import SIDES, Roles
from minifilm.motion.motion import Motion
from minifilm.motion.skeletons import Skeleton

__all__ = ["BodyUnit", "KNOWN_UNITS", "STATURE_RANGE", "LEG_FRACTION", "body_unit", "unit_from_legs",
           "unit_for_stature", "leg_length", "leg_bones", "stature_from_legs", "scaled", "standing_height"]

#: (name, metres per unit) of the units motion capture files are written in
KNOWN_UNITS: Tuple[Tuple[str, float], ...] = (
    ("millimetres", 0.001), ("centimetres", 0.01), ("inches", 0.0254), ("CMU ASF units (inches / 0.45)", 0.0254 / 0.45),
    ("decimetres", 0.1), ("feet", 0.3048), ("metres", 1.0))
#: a standing human's height, metres
STATURE_RANGE = (1.4, 2.1)
TYPICAL_STATURE = 1.7
#: thigh + shin as a fraction of the standing height (Drillis & Contini 1966)
LEG_FRACTION = 0.49
#: the top of the head above a head joint that has no head-top End Site, as a fraction of the leg
#: (thigh + shin): head joints sit near the skull's base, about 0.1 of the height below its top
HEAD_ABOVE_JOINT = 0.2


@dataclass(frozen=True)
class BodyUnit:
    """metres_per_unit: multiply the file's lengths by it; stature: the body's standing height in
    metres estimated from its legs; how: where the unit came from, for messages."""

    metres_per_unit: float
    stature: float
    how: str


def leg_bones(motion: Motion, legs: Sequence[Tuple[int, int, int]]) -> float:
    """Thigh + shin (hip to knee to ankle), averaged over ``legs``, in the motion's units.

    legs: (hip, knee, ankle) joint indices per leg, however they were found (a humanoid's parts,
    or a rig's roles). Bone lengths do not change with the pose,
    so the first frame serves."""
    P = np.asarray(motion.world()[0][0])                                         # (J, 3) first frame
    total = sum(np.linalg.norm(P[knee] - P[hip]) + np.linalg.norm(P[ankle] - P[knee]) for hip, knee, ankle in legs)
    return float(total / len(legs))


def leg_length(motion: Motion, h: Humanoid) -> float:
    """Thigh + shin (hip to knee to ankle), averaged over both legs, in the motion's units."""
    return leg_bones(motion, [tuple(getattr(h, f"{side}_{r}") for r in ("hip", "knee", "ankle"))
                              for side in ("left", "right")])


def stature_from_legs(thigh_and_shin: float) -> float:
    """A body's standing height from its thigh + shin (any unit; the same unit out): the one
    definition every unit guess uses (LEG_FRACTION, module docstring)."""
    return thigh_and_shin / LEG_FRACTION


def body_unit(motion: Motion, h: Humanoid, skeleton: Optional[Skeleton]) -> BodyUnit:
    """The unit of ``motion`` (read with scale 1: file units) from its humanoid parts ``h`` and the
    built-in ``skeleton`` its names fit (None if none), both found once by its reader
    (minifilm/body/read.py): the skeleton's unit while the body is of human height in it, else
    from its height (module docstring)."""
    stature_units = stature_from_legs(leg_length(motion, h))
    lo, hi = STATURE_RANGE
    if skeleton is not None and lo <= stature_units * skeleton.bvh_scale <= hi:
        s = skeleton.bvh_scale
        return BodyUnit(s, stature_units * s, f"the {skeleton.name!r} skeleton's unit ({s:g} m)")
    unit = unit_for_stature(stature_units)      # names of a known skeleton, written in another unit
    if skeleton is not None:
        unit = BodyUnit(unit.metres_per_unit, unit.stature,
                        f"{unit.how}, not the {skeleton.name!r} skeleton's usual {skeleton.bvh_scale:g} m "
                        f"(that would make it {stature_units * skeleton.bvh_scale:.3g} m tall)")
    return unit


def unit_from_legs(motion: Motion, roles: Roles) -> BodyUnit:
    """The unit of a rig known by its roles alone (a JSON map of a rig the humanoid finder does not
    recognise), as for a humanoid: the stature from the roles' thigh + shin, then the common unit
    that makes it 1.4-2.1 m. (The hips' standing height, ``body/proportions.leg_length``, is longer
    than thigh + shin by the pelvis and the ankle's height, so it does not fit that fraction.)"""
    idx = {n: i for i, n in enumerate(motion.names)}
    legs = [(idx[roles.limb(s).upleg], idx[roles.limb(s).knee], idx[roles.limb(s).ankle]) for s in SIDES]
    return unit_for_stature(stature_from_legs(leg_bones(motion, legs)))


def unit_for_stature(stature_units: float) -> BodyUnit:
    """The first common unit (KNOWN_UNITS) that makes a body ``stature_units`` tall 1.4-2.1 m;
    failing every one, the scale that makes it TYPICAL_STATURE."""
    lo, hi = STATURE_RANGE
    if not stature_units > 1e-9:                # all-zero offsets: a point, no height to go by
        raise HumanoidError(f"the legs have no length (thigh + shin = {stature_units:g} file units): the "
                            "skeleton's offsets are zero, so it has no size and no unit can be found")
    for name, s in KNOWN_UNITS:
        if lo <= stature_units * s <= hi:
            return BodyUnit(s, stature_units * s,
                            f"{name}: a {stature_units * s:.2f} m tall body (from its legs)")
    s = TYPICAL_STATURE / max(stature_units, 1e-12)
    return BodyUnit(s, TYPICAL_STATURE, f"no common unit gives a {lo}-{hi} m body; scaled to {TYPICAL_STATURE} m")


def scaled(motion: Motion, metres_per_unit: float) -> Motion:
    """``motion`` with every length multiplied by ``metres_per_unit`` (a new Motion).

    Forward kinematics is linear in the lengths, so world positions already computed for
    ``motion`` are scaled rather than computed again (the rotations are the same)."""
    out = Motion(list(motion.names), motion.parents.copy(), motion.offsets * metres_per_unit,
                 list(motion.channels), motion.rotations.copy(), motion.translations * metres_per_unit,
                 motion.frame_time, motion.source)
    if motion._fk_cache is not None:
        positions, rotations = motion._fk_cache
        out._fk_cache = (positions * metres_per_unit, rotations)
    return out


def standing_height(positions, h: Humanoid, fps: float, seconds: float = 1.0) -> float:
    """The head's top above the floor: its 95th percentile over the first ``seconds``, metres if
    ``positions`` are (the tallest the body stands there, so a crouch or a runner's lean early on
    counts little).

    positions (F, J, 3), y up, joints as in the motion ``h`` was found on. The floor is the 2nd
    percentile over the clip of the lowest toe tip or ankle (where the feet rest; not each frame's
    lowest foot, which is in the air while running). The head's top is its End Site when it has a
    long one (a modelled head top, as in 100STYLE), else the head joint plus HEAD_ABOVE_JOINT of
    the leg (thigh + shin)."""
    P = np.asarray(positions, dtype=np.float64)
    feet = [h.left_toe_tip, h.right_toe_tip, h.left_ankle, h.right_ankle]
    floor = float(np.percentile(P[:, feet, 1].min(axis=1), 2))
    P = P[:max(1, min(P.shape[0], int(round(seconds * fps))))]
    leg = np.mean([np.linalg.norm(P[:, getattr(h, f"{s}_knee")] - P[:, getattr(h, f"{s}_hip")], axis=-1)
                   + np.linalg.norm(P[:, getattr(h, f"{s}_ankle")] - P[:, getattr(h, f"{s}_knee")], axis=-1)
                   for s in ("left", "right")], axis=0)                               # (n,)
    head = P[:, h.head, 1]
    top = head + HEAD_ABOVE_JOINT * leg
    if h.head_top is not None:
        site_length = np.linalg.norm(P[:, h.head_top] - P[:, h.head], axis=-1)
        if np.median(site_length) >= 0.5 * HEAD_ABOVE_JOINT * np.median(leg):
            top = np.maximum(head, P[:, h.head_top, 1])
    return float(np.percentile(top, 95) - floor)
