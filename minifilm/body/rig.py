"""Which rig a file is: a built-in skeleton its joint names fit, else the humanoid its parts make.

The phase recipe (Sec. 4.1) reads a rig; the local phases need four things from a skeleton: the
hips (whose frame the hand and foot positions are taken in, §3.4), the four end effectors [left
hand, right hand, left foot, right foot] (§3.1), the two toe-tip contact sensors [right, left] (§2), and the hips-local axis pointing
to the character's front (which signs the hands' principal component, Sec. 4.1.3). A built-in
:class:`~minifilm.motion.skeletons.Skeleton` names them; for any other humanoid file
:class:`HumanoidRig` takes them from the parts :func:`~minifilm.body.humanoid.find_humanoid`
finds (by names or by structure):

    hips           Humanoid.hips
    phase bones    Humanoid.phase_bones      (left wrist, right wrist, left toe, right toe)
    contact bones  Humanoid.contact_sensors  (right toe tip, left toe tip)
    facing axis    estimated: the body's forward (left hip -> right hip line x up) in the hips' frame

:func:`detect_skeleton` is the one test of a file's joint names against the built-in skeletons;
minifilm/body/read.py reads a file once and takes its rig from here.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence, Tuple

import numpy as np

from minifilm.body.parts import Humanoid, HumanoidError
from minifilm.motion.motion import Motion
from minifilm.motion.skeletons import BUILTIN_SKELETONS, Skeleton

__all__ = ["detect_skeleton", "builtin_skeleton_of", "HumanoidRig", "humanoid_rig", "facing_axis_of"]


def builtin_skeleton_of(motion, candidates: Sequence[Skeleton] = BUILTIN_SKELETONS) -> Optional[Skeleton]:
    """The candidate whose required joints are all present in ``motion`` (the one with most exported
    joints if several fit), None if none does."""
    fitting = [s for s in candidates if not s.missing_joints(motion)]
    return max(fitting, key=lambda s: s.n_joints) if fitting else None


def detect_skeleton(motion, candidates: Sequence[Skeleton] = BUILTIN_SKELETONS) -> Skeleton:
    """:func:`builtin_skeleton_of`, or ValueError listing every candidate and what it misses."""
    skeleton = builtin_skeleton_of(motion, candidates)
    if skeleton is not None:
        return skeleton
    lines = []
    for s in candidates:
        missing = s.missing_joints(motion)
        shown = ", ".join(missing[:6]) + (f", ... ({len(missing)} in all)" if len(missing) > 6 else "")
        lines.append(f"  {s.name}: missing {shown}")
    raise ValueError(f"detect_skeleton: no known skeleton fits {motion.source} (joints "
                     f"{list(motion.names)[:8]}...):\n" + "\n".join(lines) +
                     "\nDescribe your own with minifilm.motion.skeletons.Skeleton.")


@dataclass(frozen=True)
class HumanoidRig:
    """What the phase recipe reads of a skeleton (the ``Skeleton`` methods it calls), from a
    Humanoid's parts: indices into the motion the humanoid was found on.

    humanoid: the parts; facing_axis (3,): unit hips-local forward axis; name: for titles."""

    humanoid: Humanoid
    facing_axis: Tuple[float, float, float]
    name: str

    def hips_index(self, motion=None) -> int:
        return int(self.humanoid.hips)

    def phase_indices(self, motion=None) -> np.ndarray:
        """(4,) [left hand, right hand, left foot, right foot] joint indices."""
        return np.array(self.humanoid.phase_bones, dtype=np.int64)

    def contact_indices(self, motion=None) -> np.ndarray:
        """(2,) [right toe tip, left toe tip] joint indices."""
        return np.array(self.humanoid.contact_sensors, dtype=np.int64)


def facing_axis_of(motion: Motion, h: Humanoid) -> Tuple[float, float, float]:
    """The hips-local axis pointing to the character's front, (3,) unit.

    Each frame's forward is horizontal and perpendicular to the line from the right hip to the
    left (left = up x forward, so forward = left x up), taken into the hips' frame (R_hips^T f);
    the mean over the clip, normalised. On the built-in skeletons it lies within a few degrees of
    their declared +Z (tests/phases/test_label_any_rig.py)."""
    positions, rotations = motion.world()
    left = positions[:, h.left_hip] - positions[:, h.right_hip]                        # (F, 3)
    forward = np.cross(left, [0.0, 1.0, 0.0])
    forward[:, 1] = 0.0
    norm = np.linalg.norm(forward, axis=-1, keepdims=True)
    ok = norm[:, 0] > 1e-9
    if not np.any(ok):
        raise HumanoidError(f"{motion.source}: the hips have no left-right width, so the body's front is unknown")
    forward = forward[ok] / norm[ok]
    local = np.einsum("fji,fj->fi", rotations[ok, h.hips], forward)                    # R^T f
    axis = local.mean(axis=0)
    n = float(np.linalg.norm(axis))
    if n < 1e-6:
        raise HumanoidError(f"{motion.source}: the hips turn every way relative to the body's front")
    return tuple(float(a) for a in axis / n)


def humanoid_rig(motion: Motion, h: Humanoid) -> HumanoidRig:
    """The phase recipe's rig of a humanoid ``motion`` from its parts ``h`` (found on it once)."""
    return HumanoidRig(h, facing_axis_of(motion, h), f"any humanoid (parts found by {h.method})")
