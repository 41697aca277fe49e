"""Roles for retargeting from the humanoid parts that :mod:`minifilm.body.humanoid` finds.

humanoid.py recognises a skeleton (by names, else by structure) and names its parts as joint
indices; retargeting (:mod:`minifilm.rigs.joint_map`) names them as joint names, with the neck
as a chain up to the head and the hand's end where the wrist has a single child.
"""
from __future__ import annotations

from minifilm.body.humanoid import Humanoid, HumanoidError, find_humanoid
from minifilm.rigs.joint_map import Limb, RigError, Roles

__all__ = ["roles_from_humanoid", "roles_of"]


def _only_child(motion, j: int):
    kids = [c for c in range(motion.n_joints) if int(motion.parents[c]) == j]
    return motion.names[kids[0]] if len(kids) == 1 else None


def _path(motion, top: int, bottom: int):
    """Joints below ``top`` down to ``bottom`` (inclusive), top first."""
    out = [bottom]
    while int(motion.parents[out[-1]]) != top:
        out.append(int(motion.parents[out[-1]]))
    return out[::-1]


def _limb(motion, h: Humanoid, side: str) -> Limb:
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


def roles_from_humanoid(motion, h: Humanoid = None) -> Roles:
    """The retargeting roles of ``motion`` (RigError, naming what is missing, when it is not a
    humanoid that humanoid.py recognises, or has no spine joint between hips and chest)."""
    try:
        h = h if h is not None else find_humanoid(motion)
    except HumanoidError as e:
        raise RigError(f"{e}. A JSON map of its joints' roles makes it usable: `minifilm retarget FILE "
                       f"--map MAP.json --to 100style` (docs/retargeting.md) puts it on a rig that every "
                       f"command reads") from None
    n = motion.names
    if not h.spine:
        raise RigError(f"{motion.source}: no spine joint between the hips {n[h.hips]!r} and the arms; "
                       "retargeting needs at least a chest")
    neck = tuple(n[j] for j in _path(motion, h.chest, h.head))       # the whole chain, chest to head
    roles = Roles(n[h.hips], tuple(n[j] for j in h.spine), neck, _limb(motion, h, "left"), _limb(motion, h, "right"),
                  head_end=None if h.head_top is None else n[h.head_top], source=motion.source)
    return roles.check(motion)


def roles_of(motion) -> Roles:
    """Alias of :func:`roles_from_humanoid` for a motion alone."""
    return roles_from_humanoid(motion)
