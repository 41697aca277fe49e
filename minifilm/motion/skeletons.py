"""Skeleton descriptions: which joints are exported, the phase end effectors, contact sensors, facing.

A ``Skeleton`` names joints of a ``Motion`` (read from a BVH file); it holds no motion itself.
The paper's features (Sec. 3.2) use the *exported* joints in ``joints`` order; the local phases
(Sec. 4.1, docs/original-code.md §3.1) use the four ``phase_bones`` (left hand, right hand, left
foot, right foot, in that order); foot contacts (§2) use the two ``contact_bones`` (right toe tip,
left toe tip). The character's root (§5) is the ``hips`` joint projected on the floor y = 0, and its
facing is the hips-local ``facing_axis`` in world space, flattened.

Describing your own skeleton takes a few lines; ``parents_from_motion`` derives the parents of the
exported joints from a file's hierarchy (nearest exported ancestor)::

    from minifilm.motion.bvh import read_bvh
    from minifilm.motion.skeletons import Skeleton, parents_from_motion

    m = read_bvh("my_walk.bvh", scale=0.01)
    joints = ("Pelvis", "Spine", "Head", "L_Hand", "R_Hand", "L_Foot", "L_Toe", "R_Foot", "R_Toe")
    MINE = Skeleton("mine", joints, parents_from_motion(m, joints), hips="Pelvis",
                    phase_bones=("L_Hand", "R_Hand", "L_Toe", "R_Toe"),
                    contact_bones=("R_ToeSite", "L_ToeSite"), facing_axis=(0.0, 0.0, 1.0))

Units: a BVH file is read with ``read_bvh(path, scale=skeleton.bvh_scale)``; the built-ins carry
the scale that gives a standing hip height of about 0.8-1.0 m on the shared real data.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence, Tuple

import numpy as np

from minifilm.errors import InputError
from minifilm.motion.kinematics import look_rotation


class MissingJointsError(InputError, KeyError):
    """A motion lacks joints a skeleton reads (a file of another rig, or the wrong --skeleton).
    An InputError (one line in the CLI) and, for older callers, a KeyError."""

    def __str__(self) -> str:  # the message, not KeyError's repr of it
        return str(self.args[0]) if self.args else ""


@dataclass(frozen=True)
class Skeleton:
    """Which joints of a motion the pipeline uses, and what they mean.

    Attributes:
        name:          short identifier, e.g. ``"100style"``.
        joints:        (J_exp,) exported joint names, in feature order.
        parents:       (J_exp,) parent of each exported joint as an index into ``joints``, -1 for the root.
        hips:          the joint whose floor projection is the character root (§5).
        phase_bones:   (left hand, right hand, left foot, right foot) end effectors for local phases (§3.1).
        contact_bones: (right toe tip, left toe tip) contact sensors (§2).
        facing_axis:   the hips-local axis pointing to the character's front (100STYLE: +Z).
        bvh_scale:     BVH units -> metres for this dataset's files (0.01 for centimetres).
    """

    name: str
    joints: Tuple[str, ...]
    parents: Tuple[int, ...]
    hips: str
    phase_bones: Tuple[str, str, str, str]
    contact_bones: Tuple[str, str]
    facing_axis: Tuple[float, float, float] = (0.0, 0.0, 1.0)
    bvh_scale: float = 0.01

    def __post_init__(self) -> None:
        # Normalise sequences to tuples so the dataclass stays hashable and immutable.
        for field_name in ("joints", "parents", "phase_bones", "contact_bones", "facing_axis"):
            object.__setattr__(self, field_name, tuple(getattr(self, field_name)))
        where = f"Skeleton {self.name!r}"
        if len(self.parents) != len(self.joints):
            raise ValueError(f"{where}: {len(self.parents)} parents for {len(self.joints)} joints")
        if len(set(self.joints)) != len(self.joints):
            raise ValueError(f"{where}: duplicate joint names in {self.joints}")
        for j, p in enumerate(self.parents):
            if not (-1 <= p < j) or (p == -1) != (j == 0):
                raise ValueError(f"{where}: joint {self.joints[j]!r} has parent {p}; expected -1 for the "
                                 f"first joint and an earlier index otherwise")
        if len(self.phase_bones) != 4:
            raise ValueError(f"{where}: phase_bones must be (left hand, right hand, left foot, right foot)")
        if len(self.contact_bones) != 2:
            raise ValueError(f"{where}: contact_bones must be (right toe tip, left toe tip)")
        axis = np.asarray(self.facing_axis, dtype=np.float64)
        if axis.shape != (3,) or not np.isclose(np.linalg.norm(axis), 1.0):
            raise ValueError(f"{where}: facing_axis must be a unit 3-vector, got {self.facing_axis}")
        if not (self.bvh_scale > 0 and np.isfinite(self.bvh_scale)):
            raise ValueError(f"{where}: bvh_scale must be positive, got {self.bvh_scale}")

    @property
    def n_joints(self) -> int:
        return len(self.joints)

    def required_joints(self) -> Tuple[str, ...]:
        """Every joint name this skeleton reads from a motion (exported, hips, phase and contact bones)."""
        extra = (self.hips,) + self.phase_bones + self.contact_bones
        return self.joints + tuple(n for n in dict.fromkeys(extra) if n not in self.joints)

    def missing_joints(self, motion) -> Tuple[str, ...]:
        """The required joints that ``motion`` lacks (empty when it fits)."""
        present = set(motion.names)
        return tuple(n for n in self.required_joints() if n not in present)

    def _indices(self, motion, names: Sequence[str], what: str) -> np.ndarray:
        missing = [n for n in names if n not in motion.names]
        if missing:
            raise MissingJointsError(f"skeleton {self.name!r}: {what} {missing} not found in {motion.source} "
                                     f"(its joints are {list(motion.names)})")
        return np.array([motion.names.index(n) for n in names], dtype=np.int64)

    def joint_indices(self, motion) -> np.ndarray:
        """(J_exp,) indices of the exported joints in ``motion.names``; KeyError naming missing joints."""
        return self._indices(motion, self.joints, "exported joints")

    def phase_indices(self, motion) -> np.ndarray:
        """(4,) motion indices of (left hand, right hand, left foot, right foot)."""
        return self._indices(motion, self.phase_bones, "phase bones")

    def contact_indices(self, motion) -> np.ndarray:
        """(2,) motion indices of (right toe tip, left toe tip)."""
        return self._indices(motion, self.contact_bones, "contact bones")

    def hips_index(self, motion) -> int:
        return int(self._indices(motion, (self.hips,), "hips joint")[0])


def parents_from_motion(motion, joints: Sequence[str]) -> Tuple[int, ...]:
    """Parents of ``joints`` (indices into ``joints``): each joint's nearest ancestor in ``motion``
    that is itself in ``joints``; -1 when there is none."""
    index = {n: i for i, n in enumerate(joints)}
    missing = [n for n in joints if n not in motion.names]
    if missing:
        raise MissingJointsError(f"parents_from_motion: joints {missing} not in {motion.source}")
    parents = []
    for name in joints:
        a = int(motion.parents[motion.names.index(name)])
        while a >= 0 and motion.names[a] not in index:
            a = int(motion.parents[a])
        parents.append(index[motion.names[a]] if a >= 0 else -1)
    return tuple(parents)


# ----------------------------------------------------------------------------------------------
# Built-in skeletons
# ----------------------------------------------------------------------------------------------

#: 100STYLE (docs/original-code.md §1.2): the 23 joints with channels plus the two wrist End Sites;
#: the head and toe End Sites are dropped (the toe sites are the contact sensors).
STYLE100 = Skeleton(
    name="100style",
    joints=("Hips", "Chest", "Chest2", "Chest3", "Chest4", "Neck", "Head",
            "RightCollar", "RightShoulder", "RightElbow", "RightWrist", "RightWristSite",
            "LeftCollar", "LeftShoulder", "LeftElbow", "LeftWrist", "LeftWristSite",
            "RightHip", "RightKnee", "RightAnkle", "RightToe",
            "LeftHip", "LeftKnee", "LeftAnkle", "LeftToe"),
    parents=(-1, 0, 1, 2, 3, 4, 5, 4, 7, 8, 9, 10, 4, 12, 13, 14, 15, 0, 17, 18, 19, 0, 21, 22, 23),
    hips="Hips",
    phase_bones=("LeftWristSite", "RightWristSite", "LeftToe", "RightToe"),
    contact_bones=("RightToeSite", "LeftToeSite"),
    facing_axis=(0.0, 0.0, 1.0),
    bvh_scale=0.01,
)

#: Bandai Namco Research Motion Dataset 1 and 2 (22 joints with channels, centimetres). The root
#: ``joint_Root`` is a marker on the floor (fixed at the origin in dataset 2; carrying the
#: translation in some dataset-1 files), not a body joint, so it is not exported: 21 joints, rooted
#: at ``Hips``. The End Sites of the hands and toes have zero offsets (they coincide with their
#: parents), so the hands and toe joints are the phase bones and the toe End Sites the contact
#: sensors. The hips' local +Z points forward (checked against the walking direction of every
#: shared Bandai walk/run file, tests/motion/test_skeletons.py); the bones run along local x.
BANDAI = Skeleton(
    name="bandai",
    joints=("Hips", "Spine", "Chest", "Neck", "Head",
            "Shoulder_L", "UpperArm_L", "LowerArm_L", "Hand_L",
            "Shoulder_R", "UpperArm_R", "LowerArm_R", "Hand_R",
            "UpperLeg_L", "LowerLeg_L", "Foot_L", "Toes_L",
            "UpperLeg_R", "LowerLeg_R", "Foot_R", "Toes_R"),
    parents=(-1, 0, 1, 2, 3, 2, 5, 6, 7, 2, 9, 10, 11, 0, 13, 14, 15, 0, 17, 18, 19),
    hips="Hips",
    phase_bones=("Hand_L", "Hand_R", "Toes_L", "Toes_R"),
    contact_bones=("Toes_RSite", "Toes_LSite"),
    facing_axis=(0.0, 0.0, 1.0),
    bvh_scale=0.01,
)

#: The 31-joint CMU skeleton (Hips, LHipJoint, ..., RThumb), as used by the Xia et al. 2015 style
#: clips retargeted in deep-motion-editing. Its units are the CMU ASF length unit (hip height about
#: 17): 0.056444 = 0.0254 / 0.45 turns them into metres (hip height about 0.95 m).
CMU = Skeleton(
    name="cmu",
    joints=("Hips", "LHipJoint", "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase",
            "RHipJoint", "RightUpLeg", "RightLeg", "RightFoot", "RightToeBase",
            "LowerBack", "Spine", "Spine1", "Neck", "Neck1", "Head",
            "LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand", "LeftFingerBase", "LeftHandIndex1", "LThumb",
            "RightShoulder", "RightArm", "RightForeArm", "RightHand", "RightFingerBase", "RightHandIndex1",
            "RThumb"),
    parents=(-1, 0, 1, 2, 3, 4, 0, 6, 7, 8, 9, 0, 11, 12, 13, 14, 15, 13, 17, 18, 19, 20, 21, 20,
             13, 24, 25, 26, 27, 28, 27),
    hips="Hips",
    phase_bones=("LeftHandIndex1", "RightHandIndex1", "LeftToeBase", "RightToeBase"),
    contact_bones=("RightToeBaseSite", "LeftToeBaseSite"),
    facing_axis=(0.0, 0.0, 1.0),
    bvh_scale=0.0254 / 0.45,
)

#: The CMU data in the MotionBuilder-friendly conversion (``hip``, ``abdomen``, ``rThigh``, ...,
#: 43 joints with fingers and eyes, e.g. ``08_01``), centimetres. Its names share nothing with the
#: 31-joint CMU skeleton, so it is its own description: the 21 body joints (no fingers, eyes or toe
#: joints). The feet have no toe joint: the foot joints are the foot phase bones and their End
#: Sites (at the toe tips) the contact sensors.
CMU_MB = Skeleton(
    name="cmu-mb",
    joints=("hip", "abdomen", "chest", "neck", "head",
            "rCollar", "rShldr", "rForeArm", "rHand",
            "lCollar", "lShldr", "lForeArm", "lHand",
            "rButtock", "rThigh", "rShin", "rFoot",
            "lButtock", "lThigh", "lShin", "lFoot"),
    parents=(-1, 0, 1, 2, 3, 2, 5, 6, 7, 2, 9, 10, 11, 0, 13, 14, 15, 0, 17, 18, 19),
    hips="hip",
    phase_bones=("lHand", "rHand", "lFoot", "rFoot"),
    contact_bones=("rFootSite", "lFootSite"),
    facing_axis=(0.0, 0.0, 1.0),
    bvh_scale=0.01,
)

BUILTIN_SKELETONS: Tuple[Skeleton, ...] = (STYLE100, BANDAI, CMU, CMU_MB)


def builtin_skeleton(name: str) -> Skeleton:
    """The built-in skeleton called ``name`` ('100style', 'bandai', 'cmu', 'cmu-mb'); ValueError
    naming the known ones otherwise."""
    known = {s.name: s for s in BUILTIN_SKELETONS}
    if name not in known:
        raise ValueError(f"unknown skeleton {name!r}; the built-in skeletons are {sorted(known)}")
    return known[name]


def facing_directions(motion, skeleton: Skeleton) -> np.ndarray:
    """(F, 3) unit horizontal facing: the hips' ``facing_axis`` in world space, y zeroed, normalised
    (docs/original-code.md §5). A facing with no horizontal part falls back to +Z."""
    _, world_R = motion.world()
    axis = np.asarray(skeleton.facing_axis, dtype=np.float64)
    f = world_R[:, skeleton.hips_index(motion)] @ axis
    return look_rotation(f)[..., :, 2]


def root_transforms(motion, skeleton: Skeleton) -> Tuple[np.ndarray, np.ndarray]:
    """The character root per frame (docs/original-code.md §5).

    Returns:
        root_pos (F, 3): the hips' world position projected on the floor, ``(x_h, 0, z_h)``.
        root_rot (F, 3, 3): ``LookRotation`` of the flattened facing ``f``:
            ``[[fz, 0, fx], [0, 1, 0], [-fx, 0, fz]]`` (columns right, up, forward).
    """
    positions, world_R = motion.world()
    h = skeleton.hips_index(motion)
    root_pos = positions[:, h] * np.array([1.0, 0.0, 1.0])
    facing = world_R[:, h] @ np.asarray(skeleton.facing_axis, dtype=np.float64)
    return root_pos, look_rotation(facing)
