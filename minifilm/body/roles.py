"""Which joint of a humanoid rig plays which part, by name: the roles that retargeting reads.

Retargeting (docs/retargeting.md) maps joints by *role*, not by name. A :class:`Roles` names, for
one rig, its hips, its spine chain up to the chest (where arms and neck branch), its neck chain up
to the head, and per side the arm (collar, shoulder, elbow, wrist, hand end) and the leg (upper
leg, knee, ankle, toe, toe end). Collars, toes and ends are optional: a rig without toes bends its
foot as one bone.

Roles come from (in this order): a user's JSON map (``--map``), the built-in rigs' name maps
below, or the humanoid parts that minifilm/body/humanoid.py finds (:func:`roles_from_humanoid`:
its joint indices as names, the neck as the chain from the chest up to the head, the hand's end
where the wrist has a single child). A file's reader (minifilm/body/read.py) finds them once.
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Dict, Optional, Tuple

import numpy as np

from minifilm.body.parts import Humanoid
from minifilm.errors import InputError
from minifilm.files import few

__all__ = ["RigError", "Limb", "Roles", "BUILTIN_ROLES", "roles_from_mapping", "roles_from_humanoid", "sensor_positions",
           "SIDES"]

SIDES = ("left", "right")


class RigError(InputError):
    """A rig that cannot be retargeted: not a humanoid, a part that cannot be found, a map naming
    joints the file does not have. The message names the file and what is missing."""


@dataclass(frozen=True)
class Limb:
    """One side's arm and leg joints (names; ``None`` where the rig has no such joint)."""
    shoulder: str
    elbow: str
    wrist: str
    upleg: str
    knee: str
    ankle: str
    collar: Optional[str] = None
    hand_end: Optional[str] = None
    toe: Optional[str] = None
    toe_end: Optional[str] = None

    @property
    def sensor(self) -> str:
        """The contact sensor: the toe tip (End Site) if the rig has one, else the toe, else the ankle."""
        return self.toe_end or self.toe or self.ankle

    def arm(self) -> Tuple[str, ...]:
        """collar?, shoulder, elbow, wrist, hand end? (the arm's joints from the chest outwards)."""
        return tuple(n for n in (self.collar, self.shoulder, self.elbow, self.wrist, self.hand_end) if n)

    def leg(self) -> Tuple[str, ...]:
        """upper leg, knee, ankle, toe?, toe end? (the leg's joints from the hip down)."""
        return tuple(n for n in (self.upleg, self.knee, self.ankle, self.toe, self.toe_end) if n)


@dataclass(frozen=True)
class Roles:
    """A humanoid rig's roles (joint names of one Motion).

    Attributes:
        hips:     the pelvis joint (the root of the body; may hang below a floor marker).
        spine:    joints after the hips up to the chest, chest last (>= 1 joint).
        neck:     joints after the chest up to the head, head last (>= 1 joint).
        head_end: the head's End Site, if any.
        left, right: the limbs.
    """
    hips: str
    spine: Tuple[str, ...]
    neck: Tuple[str, ...]
    left: Limb
    right: Limb
    head_end: Optional[str] = None
    source: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "spine", tuple(self.spine))
        object.__setattr__(self, "neck", tuple(self.neck))
        if not self.spine or not self.neck:
            raise RigError(f"{self.source or 'roles'}: the spine and the neck need at least one joint each "
                           f"(the chest, the head), got spine {list(self.spine)}, neck {list(self.neck)}")

    @property
    def chest(self) -> str:
        return self.spine[-1]

    @property
    def head(self) -> str:
        return self.neck[-1]

    def limb(self, side: str) -> Limb:
        return self.left if side == "left" else self.right

    def names(self) -> Tuple[str, ...]:
        """Every joint a role names."""
        out = [self.hips, *self.spine, *self.neck] + ([self.head_end] if self.head_end else [])
        for side in SIDES:
            out += list(self.limb(side).arm()) + list(self.limb(side).leg())
        return tuple(out)

    def check(self, motion, where: str = "") -> "Roles":
        """Self, after checking that every named joint exists in ``motion`` and that the chains
        are chains (each joint below the previous one); RigError naming what is wrong (and
        ``where`` the roles came from, e.g. a map file)."""
        where = where or motion.source
        names = self.names()
        missing = [n for n in names if n not in motion.names]
        if missing:
            raise RigError(f"{where}: the joint map names joints the file does not have: [{few(missing)}] "
                           f"(its joints are {few(motion.names, 10)})")
        dup = sorted(n for n, count in Counter(names).items() if count > 1)
        if dup:
            raise RigError(f"{where}: the joint map gives {few(dup)} more than one role")
        index = {n: i for i, n in enumerate(motion.names)}

        def below(child: str, ancestor: str) -> bool:
            a = int(motion.parents[index[child]])
            while a >= 0:
                if a == index[ancestor]:
                    return True
                a = int(motion.parents[a])
            return False

        chains = [("spine", (self.hips,) + self.spine), ("neck", (self.chest,) + self.neck)]
        for side in SIDES:
            limb = self.limb(side)
            chains.append((f"{side} arm", (self.chest,) + limb.arm()))
            chains.append((f"{side} leg", (self.hips,) + limb.leg()))
        if self.head_end:
            chains.append(("head end", (self.head, self.head_end)))
        for what, chain in chains:
            for a, b in zip(chain[:-1], chain[1:]):
                if not below(b, a):
                    raise RigError(f"{where}: in the {what}, {b!r} is not below {a!r} in the hierarchy "
                                   f"(a joint map must name each chain from the body outwards)")
        return self


def _limb(shoulder, elbow, wrist, upleg, knee, ankle, collar=None, hand_end=None, toe=None, toe_end=None) -> Limb:
    return Limb(shoulder, elbow, wrist, upleg, knee, ankle, collar, hand_end, toe, toe_end)


#: The built-in rigs' roles by name (minifilm/motion/skeletons.py describes the same rigs).
BUILTIN_ROLES: Dict[str, Roles] = {
    "100style": Roles(
        "Hips", ("Chest", "Chest2", "Chest3", "Chest4"), ("Neck", "Head"),
        _limb("LeftShoulder", "LeftElbow", "LeftWrist", "LeftHip", "LeftKnee", "LeftAnkle",
              "LeftCollar", "LeftWristSite", "LeftToe", "LeftToeSite"),
        _limb("RightShoulder", "RightElbow", "RightWrist", "RightHip", "RightKnee", "RightAnkle",
              "RightCollar", "RightWristSite", "RightToe", "RightToeSite"),
        head_end="HeadSite", source="100style"),
    "bandai": Roles(
        "Hips", ("Spine", "Chest"), ("Neck", "Head"),
        _limb("UpperArm_L", "LowerArm_L", "Hand_L", "UpperLeg_L", "LowerLeg_L", "Foot_L",
              "Shoulder_L", "Hand_LSite", "Toes_L", "Toes_LSite"),
        _limb("UpperArm_R", "LowerArm_R", "Hand_R", "UpperLeg_R", "LowerLeg_R", "Foot_R",
              "Shoulder_R", "Hand_RSite", "Toes_R", "Toes_RSite"),
        head_end="HeadSite", source="bandai"),
    "cmu": Roles(
        "Hips", ("LowerBack", "Spine", "Spine1"), ("Neck", "Neck1", "Head"),
        _limb("LeftArm", "LeftForeArm", "LeftHand", "LeftUpLeg", "LeftLeg", "LeftFoot",
              "LeftShoulder", "LeftHandIndex1", "LeftToeBase", "LeftToeBaseSite"),
        _limb("RightArm", "RightForeArm", "RightHand", "RightUpLeg", "RightLeg", "RightFoot",
              "RightShoulder", "RightHandIndex1", "RightToeBase", "RightToeBaseSite"),
        head_end="HeadSite", source="cmu"),
    "cmu-mb": Roles(
        "hip", ("abdomen", "chest"), ("neck", "head"),
        _limb("lShldr", "lForeArm", "lHand", "lThigh", "lShin", "lFoot", "lCollar", "lMid1", None, "lFootSite"),
        _limb("rShldr", "rForeArm", "rHand", "rThigh", "rShin", "rFoot", "rCollar", "rMid1", None, "rFootSite"),
        head_end=None, source="cmu-mb"),
}

_LIMB_KEYS = ("collar", "shoulder", "elbow", "wrist", "hand_end", "upleg", "knee", "ankle", "toe", "toe_end")
_REQUIRED_LIMB = ("shoulder", "elbow", "wrist", "upleg", "knee", "ankle")


def roles_from_mapping(mapping, motion, where: str = "joint map") -> Roles:
    """Roles from a user's map (parsed JSON), checked against ``motion``.

    The map is ``{"hips": "pelvis", "spine": ["spine_01", "spine_02"], "neck": ["neck", "head"],
    "head_end": "headSite", "left": {"shoulder": ..., "elbow": ..., "wrist": ..., "upleg": ...,
    "knee": ..., "ankle": ..., "collar": ..., "hand_end": ..., "toe": ..., "toe_end": ...},
    "right": {...}}``; collar, hand_end, toe, toe_end and head_end may be left out.
    """
    if not isinstance(mapping, dict):
        raise RigError(f"{where}: expected a JSON object with hips, spine, neck, left and right, "
                       f"got {type(mapping).__name__}")
    unknown = sorted(set(mapping) - {"hips", "spine", "neck", "head_end", "left", "right"})
    if unknown:
        raise RigError(f"{where}: unknown keys {few(unknown)}; expected hips, spine, neck, head_end, left, right")
    missing = [k for k in ("hips", "spine", "neck", "left", "right") if k not in mapping]
    if missing:
        raise RigError(f"{where}: missing {missing} (a map names hips, spine, neck, left and right)")

    def name(value, key):
        if not isinstance(value, str) or not value:
            raise RigError(f"{where}: {key} must be a joint name, got {few([value], 1)}")
        return value

    def names(value, key):
        value = [value] if isinstance(value, str) else value
        if not isinstance(value, list) or not value:
            raise RigError(f"{where}: {key} must be a list of joint names from the body outwards, got {few([value], 1)}")
        return tuple(name(v, key) for v in value)

    limbs = {}
    for side in SIDES:
        m = mapping[side]
        if not isinstance(m, dict):
            raise RigError(f"{where}: {side} must be an object with {', '.join(_REQUIRED_LIMB)}")
        bad = sorted(set(m) - set(_LIMB_KEYS))
        if bad:
            raise RigError(f"{where}: {side}: unknown keys {few(bad)}; expected {', '.join(_LIMB_KEYS)}")
        lack = [k for k in _REQUIRED_LIMB if k not in m]
        if lack:
            raise RigError(f"{where}: {side}: missing {lack}")
        limbs[side] = Limb(**{k: name(v, f"{side}.{k}") for k, v in m.items()})
    head_end = mapping.get("head_end")
    roles = Roles(name(mapping["hips"], "hips"), names(mapping["spine"], "spine"), names(mapping["neck"], "neck"),
                  limbs["left"], limbs["right"], head_end=None if head_end is None else name(head_end, "head_end"),
                  source=where)
    return roles.check(motion, where)


def sensor_positions(positions: np.ndarray, motion, roles: Roles) -> np.ndarray:
    """(F, 2, 3) world positions of the toe-tip contact sensors, [right, left] (as Skeleton.contact_bones)."""
    return positions[:, [motion.names.index(roles.right.sensor), motion.names.index(roles.left.sensor)]]


def roles_from_humanoid(motion, h: Humanoid) -> Roles:
    """The roles of ``motion`` from its humanoid parts ``h`` (found on it once, by its reader):
    RigError when it has no spine joint between the hips and the chest."""
    n = motion.names
    if not h.spine:
        raise RigError(f"{motion.source}: no spine joint between the hips {n[h.hips]!r} and the arms; "
                       "retargeting needs at least a chest")
    neck = tuple(n[j] for j in _path(motion, h.chest, h.head))       # the whole chain, chest to head
    roles = Roles(n[h.hips], tuple(n[j] for j in h.spine), neck, _limb_of(motion, h, "left"),
                  _limb_of(motion, h, "right"), head_end=None if h.head_top is None else n[h.head_top],
                  source=motion.source)
    return roles.check(motion)


def _limb_of(motion, h: Humanoid, side: str) -> Limb:
    n = motion.names
    part = {r: getattr(h, f"{side}_{r}") for r in ("collar", "shoulder", "elbow", "wrist", "hip", "knee", "ankle",
                                                     "toe", "toe_tip")}
    toe, tip = part["toe"], part["toe_tip"]
    toe_is_site = not any(int(p) == toe for p in motion.parents)       # the foot's End Site, not a joint
    return Limb(shoulder=n[part["shoulder"]], elbow=n[part["elbow"]], wrist=n[part["wrist"]],
                upleg=n[part["hip"]], knee=n[part["knee"]], ankle=n[part["ankle"]],
                collar=None if part["collar"] is None else n[part["collar"]],
                hand_end=_only_child(motion, part["wrist"]),
                toe=None if toe_is_site else n[toe],
                toe_end=n[tip] if (toe_is_site or tip != toe) else None)


def _only_child(motion, j: int):
    kids = [c for c in range(motion.n_joints) if int(motion.parents[c]) == j]
    return motion.names[kids[0]] if len(kids) == 1 else None


def _path(motion, top: int, bottom: int):
    """Joints below ``top`` down to ``bottom`` (inclusive), top first."""
    out = [bottom]
    while int(motion.parents[out[-1]]) != top:
        out.append(int(motion.parents[out[-1]]))
    return out[::-1]
