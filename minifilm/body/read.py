"""A motion file read once, its body found once: the one reader of every command.

A BVH file says neither its length unit nor which joint is what. A :class:`Body` answers both for
one motion, each question at most once: the built-in skeleton its joint names fit
(minifilm/body/rig.py), its humanoid parts by names checked against the hierarchy, else by
structure (minifilm/body/humanoid.py), its unit (minifilm/body/units.py) and its roles for
retargeting (minifilm/body/roles.py). The readers below hand on what each command needs, and
nothing after them asks again:

    read_in_metres(path)   -> motion, humanoid, unit   the viewer, ``generate --skeleton-bvh``
    load_for_phases(path)  -> motion, rig, unit        the phase recipe (``minifilm phases``)
    read_source(path)      -> motion, roles            retargeting's source (retarget_clip.py)
"""
from __future__ import annotations

import os
from functools import cached_property
from pathlib import Path
from typing import Optional, Tuple, Union

import numpy as np

from minifilm.body.humanoid import find_humanoid
from minifilm.body.parts import Humanoid, HumanoidError
from minifilm.body.rig import HumanoidRig, builtin_skeleton_of, humanoid_rig
from minifilm.body.roles import RigError, Roles, roles_from_humanoid, roles_from_mapping
from minifilm.body.units import BodyUnit, body_unit, scaled, unit_from_legs
from minifilm.files import note_input, read_json
from minifilm.motion.bvh import read_bvh
from minifilm.motion.motion import Motion
from minifilm.motion.skeletons import Skeleton, builtin_skeleton

__all__ = ["Body", "read_in_metres", "load_for_phases", "read_source"]


class Body:
    """Which joint of ``motion`` is what, and its unit: each found the first time it is asked, and
    kept (a HumanoidError too, raised again without looking again).

    motion: a Motion in the file's units (read with scale 1)."""

    def __init__(self, motion: Motion):
        self.motion = motion

    @cached_property
    def skeleton(self) -> Optional[Skeleton]:
        """The built-in skeleton whose joints the motion has (None if none)."""
        return builtin_skeleton_of(self.motion)

    @cached_property
    def _found(self) -> Tuple[Optional[Humanoid], Optional[HumanoidError]]:
        try:
            return find_humanoid(self.motion), None
        except HumanoidError as e:
            return None, e

    @property
    def humanoid(self) -> Humanoid:
        """Its humanoid parts; HumanoidError (naming the file) when it is not a humanoid."""
        h, error = self._found
        if error is not None:
            raise error
        return h

    @property
    def is_humanoid(self) -> bool:
        return self._found[1] is None

    @cached_property
    def unit(self) -> BodyUnit:
        """The file's unit from its legs and its skeleton (units.body_unit); HumanoidError as humanoid."""
        return body_unit(self.motion, self.humanoid, self.skeleton)

    def roles(self, map_path: Union[str, os.PathLike, None] = None) -> Roles:
        """Its roles: from the JSON map at ``map_path`` if given, else from its humanoid parts.
        RigError naming what could not be found."""
        if map_path is not None:
            mapping = read_json(note_input(Path(map_path)), "joint map", error=RigError)
            return roles_from_mapping(mapping, self.motion, where=f"joint map {map_path} for {self.motion.source}")
        if not self.is_humanoid:
            raise RigError(f"{self._found[1]}. A JSON map of its joints' roles makes it usable: `minifilm retarget "
                           f"FILE --map MAP.json --to 100style` (docs/retargeting.md) puts it on a rig that every "
                           f"command reads")
        return roles_from_humanoid(self.motion, self.humanoid)

    def on_skeleton(self, skeleton: Skeleton) -> Tuple[Motion, Optional[BodyUnit]]:
        """(the motion in metres, the unit used or None) on the built-in ``skeleton``: in that
        skeleton's ``bvh_scale`` while the body is of human height in it (unit None), else in the
        unit its legs give (units.body_unit: a 100STYLE or Bandai file saved in metres is read in
        metres, and the unit says so). A body without humanoid parts goes by the skeleton's unit;
        HumanoidError when the body does not stand along y (a file saved z-up)."""
        _check_upright(self.motion, skeleton)
        unit = body_unit(self.motion, self.humanoid, skeleton) if self.is_humanoid else None
        if unit is None or unit.metres_per_unit == skeleton.bvh_scale:
            return scaled(self.motion, skeleton.bvh_scale), None
        return scaled(self.motion, unit.metres_per_unit), unit

    def metres_per_unit(self, roles: Roles) -> float:
        """A built-in skeleton's unit when its body is of human height in it, else the common unit
        that makes the body 1.4-2.1 m tall (the one unit rule of every command); a rig the humanoid
        finder does not recognise goes by the legs its ``roles`` name."""
        if not self.is_humanoid:
            return unit_from_legs(self.motion, roles).metres_per_unit
        return self.unit.metres_per_unit


#: the least share of the hips-to-toes distance that is vertical (y) in an upright body: about
#: 0.9-1 standing, walking or running, over 0.6 crouching; about 0 in a file saved z-up
UPRIGHT = 0.5


def _check_upright(motion: Motion, skeleton: Skeleton) -> None:
    """HumanoidError unless the hips stand above the toe tips along y on most frames: BVH is read
    y-up, and a z-up file's walk would otherwise be labelled (no step found) without a word."""
    P = motion.world()[0]
    down = P[:, [skeleton.hips_index(motion)]] - P[:, skeleton.contact_indices(motion)]       # (F, 2, 3)
    share = float(np.median(down[..., 1] / np.maximum(np.linalg.norm(down, axis=-1), 1e-12)))
    if not share > UPRIGHT:
        raise HumanoidError(f"{motion.source}: the body does not stand along y (the hips are above the feet by "
                            f"{share:.2f} of their distance, upright is about 1): minifilm reads BVH with y up, "
                            "and a file saved with z up must be rotated first")


def read_in_metres(path: Union[str, os.PathLike]) -> Tuple[Motion, Optional[Humanoid], BodyUnit]:
    """Read a BVH file in metres: (motion, its humanoid parts or None, the unit used).

    The unit is :func:`~minifilm.body.units.body_unit`'s for a humanoid. A skeleton that is not a
    humanoid (no height to go by) is read in centimetres, the commonest unit, and ``BodyUnit.how``
    says why. BVHError / OSError as ``read_bvh``."""
    body = Body(read_bvh(path, scale=1.0))
    if not body.is_humanoid:
        return scaled(body.motion, 0.01), None, BodyUnit(0.01, float("nan"), f"centimetres assumed: {body._found[1]}")
    return scaled(body.motion, body.unit.metres_per_unit), body.humanoid, body.unit


def load_for_phases(path: Union[str, os.PathLike], skeleton_name: Optional[str] = None
                    ) -> Tuple[Motion, Union[Skeleton, HumanoidRig], Optional[BodyUnit]]:
    """Read ``path`` in metres with the rig to label it with: (motion, rig, unit).

    ``skeleton_name`` picks a built-in skeleton; without it the built-in skeleton whose joints the
    file has is used (in its unit, or the one its legs give: :meth:`Body.on_skeleton`; the unit is
    None when the skeleton's own served), else the file's humanoid parts and the unit from its legs
    (``body_unit``). HumanoidError when the file is not a humanoid; BVHError / OSError as
    ``read_bvh``."""
    body = Body(read_bvh(path, scale=1.0))
    skeleton = builtin_skeleton(skeleton_name) if skeleton_name else body.skeleton
    if skeleton is not None:             # the file is read once; scaling it gives the same numbers
        motion, unit = body.on_skeleton(skeleton)
        return motion, skeleton, unit
    motion = scaled(body.motion, body.unit.metres_per_unit)
    return motion, humanoid_rig(motion, body.humanoid), body.unit


def read_source(path: Union[str, os.PathLike], map_path=None, scale: Optional[float] = None) -> Tuple[Motion, Roles]:
    """(motion in metres, roles) of a BVH file of any humanoid rig: the unit is ``scale`` if given,
    else :meth:`Body.metres_per_unit`'s; the roles from the JSON map at ``map_path``, else from its
    humanoid parts (RigError naming what is missing)."""
    path = note_input(Path(path))
    if scale is not None:
        motion = read_bvh(path, scale=scale)
        return motion, Body(motion).roles(map_path)
    body = Body(read_bvh(path, scale=1.0))
    roles = body.roles(map_path)
    return scaled(body.motion, body.metres_per_unit(roles)), roles       # read once, scaled (units.scaled)
