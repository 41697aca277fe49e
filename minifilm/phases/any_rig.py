"""The phase recipe on any humanoid rig, not only the built-in skeletons (Sec. 4.1).

The local phases need four things from a skeleton: the hips (whose frame the hand and foot
positions are taken in, §3.4), the four end effectors [left hand, right hand, left foot, right
foot] (§3.1), the two toe-tip contact sensors [right, left] (§2), and the hips-local axis pointing
to the character's front (which signs the hands' principal component, Sec. 4.1.3). A built-in
:class:`~minifilm.motion.skeletons.Skeleton` names them; for any other humanoid file
:class:`HumanoidRig` takes them from the parts :func:`~minifilm.body.humanoid.find_humanoid`
finds (by names or by structure):

    hips           Humanoid.hips
    phase bones    Humanoid.phase_bones      (left wrist, right wrist, left toe, right toe)
    contact bones  Humanoid.contact_sensors  (right toe tip, left toe tip)
    facing axis    estimated: the body's forward (left hip -> right hip line x up) in the hips' frame

``load_for_phases(path)`` reads a file in metres with one of the two: the built-in skeleton its
joint names fit (read with that skeleton's unit, exactly as before), else its humanoid parts
(read with the unit of minifilm/body/units.py). A file that is neither raises HumanoidError.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Optional, Tuple, Union

import numpy as np

from minifilm.body.units import BodyUnit, body_unit, scaled
from minifilm.motion.bvh import read_bvh
from minifilm.body.humanoid import Humanoid, HumanoidError, find_humanoid
from minifilm.motion.motion import Motion
from minifilm.motion.skeletons import Skeleton, builtin_skeleton, detect_skeleton

__all__ = ["HumanoidRig", "humanoid_rig", "facing_axis_of", "load_for_phases"]


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


def humanoid_rig(motion: Motion, humanoid: Optional[Humanoid] = None) -> HumanoidRig:
    """The phase recipe's rig of any humanoid ``motion`` (HumanoidError when it is none)."""
    h = humanoid if humanoid is not None else find_humanoid(motion)
    return HumanoidRig(h, facing_axis_of(motion, h), f"any humanoid (parts found by {h.method})")


def load_for_phases(path: Union[str, os.PathLike], skeleton_name: Optional[str] = None
                    ) -> Tuple[Motion, Union[Skeleton, HumanoidRig], Optional[BodyUnit]]:
    """Read ``path`` in metres with the rig to label it with: (motion, rig, unit).

    ``skeleton_name`` picks a built-in skeleton; without it the built-in skeleton whose joints the
    file has is used (its ``bvh_scale``, unit None), else the file's humanoid parts and the unit
    from its legs (``body_unit``). HumanoidError when the file is not a humanoid; BVHError /
    OSError as ``read_bvh``."""
    if skeleton_name:
        skeleton = builtin_skeleton(skeleton_name)
        return read_bvh(path, scale=skeleton.bvh_scale), skeleton, None
    raw = read_bvh(path, scale=1.0)
    try:
        skeleton = detect_skeleton(raw)
    except ValueError:
        skeleton = None
    if skeleton is not None:            # the file is read once; scaling it gives the same numbers
        return scaled(raw, skeleton.bvh_scale), skeleton, None
    h = find_humanoid(raw)
    unit = body_unit(raw, h)
    motion = scaled(raw, unit.metres_per_unit)
    return motion, humanoid_rig(motion, h), unit
