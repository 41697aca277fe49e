"""The parts of a humanoid skeleton that minifilm/body/humanoid.py finds: the ``Humanoid`` record of
joint indices per role, and ``HumanoidError``. (How they are found: minifilm/body/humanoid.py.)"""
from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Dict, Optional, Tuple

from minifilm.errors import InputError

__all__ = ["Humanoid", "HumanoidError", "ARM_ROLES", "LEG_ROLES", "LIMB_ROLES"]


class HumanoidError(InputError):
    """A skeleton whose humanoid parts (hips, spine, head, two arms, two legs with feet) cannot be
    found; the message names the file and the parts that are missing."""


#: per side, in chain order: (collar, upper arm, elbow, wrist) and (upper leg, knee, ankle, toe, toe tip)
ARM_ROLES = ("collar", "shoulder", "elbow", "wrist")
LEG_ROLES = ("hip", "knee", "ankle", "toe", "toe_tip")
LIMB_ROLES = tuple(f"{side}_{r}" for side in ("left", "right") for r in ARM_ROLES + LEG_ROLES)


@dataclass(frozen=True)
class Humanoid:
    """Joint indices (into the motion's ``names``) of a humanoid's parts.

    Attributes:
        names:        (J,) the motion's joint names, for messages.
        method:       ``"names"`` or ``"structure"``: how the parts were found.
        root:         the hierarchy's root (a floor marker such as Bandai's ``joint_Root``, or the hips).
        hips:         the pelvis, where legs and spine meet (the character root projects it, §5).
        spine:        joints from above the hips up to the chest (where the arms branch), bottom to top.
        neck:         the base of the neck (None when the head sits on the chest).
        head:         the head joint.
        {left,right}_collar:   the clavicle (None when the upper arm hangs off the spine directly).
        {left,right}_shoulder: the upper arm's joint (the shoulder), ``_elbow``, ``_wrist`` (hand).
        {left,right}_hip:      the upper leg's joint (the hip), ``_knee``, ``_ankle`` (foot).
        {left,right}_toe:      the toe joint (the ankle's child: a toe joint or the foot's End Site).
        {left,right}_toe_tip:  the end of the foot chain (the contact sensor; may be the toe itself).
        head_top:     the head's End Site (the top of the head in rigs that model it), else None.
    """

    names: Tuple[str, ...]
    method: str
    root: int
    hips: int
    spine: Tuple[int, ...]
    neck: Optional[int]
    head: int
    left_collar: Optional[int]
    left_shoulder: int
    left_elbow: int
    left_wrist: int
    left_hip: int
    left_knee: int
    left_ankle: int
    left_toe: int
    left_toe_tip: int
    right_collar: Optional[int]
    right_shoulder: int
    right_elbow: int
    right_wrist: int
    right_hip: int
    right_knee: int
    right_ankle: int
    right_toe: int
    right_toe_tip: int
    head_top: Optional[int] = None

    @property
    def chest(self) -> int:
        """The top of the spine (where the arms branch); the hips when there is no spine joint."""
        return self.spine[-1] if self.spine else self.hips

    def roles(self) -> Dict[str, Optional[int]]:
        """{role: joint index} for every part (``spine`` as ``spine0``, ``spine1``, ...)."""
        out: Dict[str, Optional[int]] = {}
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name in ("names", "method"):
                continue
            if f.name == "spine":
                out.update({f"spine{i}": j for i, j in enumerate(value)})
            else:
                out[f.name] = value
        return out

    def describe(self) -> Dict[str, Optional[str]]:
        """{role: joint name} (None for an absent optional part), for messages and tests."""
        return {r: (None if j is None else self.names[j]) for r, j in self.roles().items()}

    @property
    def contact_sensors(self) -> Tuple[int, int]:
        """(right toe tip, left toe tip): the foot-contact sensors, in ``Skeleton.contact_bones`` order."""
        return self.right_toe_tip, self.left_toe_tip

    @property
    def phase_bones(self) -> Tuple[int, int, int, int]:
        """(left wrist, right wrist, left toe, right toe): the local-phase end effectors' order (§3.1)."""
        return self.left_wrist, self.right_wrist, self.left_toe, self.right_toe
