"""A retargeting target: a rig's hierarchy, its roles, its units. ``load_rig`` reads one from a name.

A :class:`Rig` is everything :func:`minifilm.body.retarget_clip.retarget_motion` needs to know
about a skeleton to put motion on it: one frame of it (hierarchy, rest offsets, channel order), the
role of its joints (:class:`~minifilm.body.roles.Roles`) and the BVH length unit it is
written in, read and found once (:class:`minifilm.body.read.Body`). A target can be

* a built-in rig: ``100style`` (the 100STYLE header, in minifilm/synthetic/body.py), ``bandai``
  or ``cmu`` (minifilm/body/builtin_rigs.py);
* a run folder written by ``minifilm train``: its ``skeleton.bvh`` and ``bvh_scale``, through
  :func:`rig_from_template` (minifilm/pipeline/run_rig.py reads the folder);
* any BVH file: its hierarchy; its first frame is not used (the rest pose is the zero pose).
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Optional, Tuple, Union

import numpy as np

from minifilm.body.read import Body
from minifilm.body.roles import BUILTIN_ROLES, RigError, Roles
from minifilm.body.units import scaled
from minifilm.files import note_input
from minifilm.motion.bvh import parse_bvh, read_bvh
from minifilm.motion.motion import Motion
from minifilm.motion.skeletons import Skeleton, builtin_skeleton
from minifilm.body import builtin_rigs
from minifilm.body.builtin_rigs import BANDAI_FOOT_SHAPE
from minifilm.body.proportions import foot_shape_of
from minifilm.synthetic.generator import rest_motion

__all__ = ["Rig", "load_rig", "builtin_rig", "rig_from_template", "BUILTIN_RIGS"]

BUILTIN_RIGS = ("100style", "bandai", "cmu")


@dataclass
class Rig:
    """A target rig.

    Attributes:
        name:      '100style', 'bandai', 'cmu', or the file / folder it came from.
        template:  a Motion of one frame whose hierarchy, offsets (metres) and channels are the rig's.
        roles:     the rig's roles.
        bvh_scale: BVH units -> metres of the rig's files (0.01 for centimetres).
        skeleton:  the built-in Skeleton description whose joints the rig has (None if none fits).
        foot_shape: (pitch, toe bend) of its foot flat on the floor, radians (None: from its rest
                   pose, see :func:`minifilm.body.proportions.foot_shape_of`).
    """
    name: str
    template: Motion
    roles: Roles
    bvh_scale: float
    skeleton: Optional[Skeleton] = None
    foot_shape: Optional[Tuple[float, float]] = None


def _rest(motion: Motion, name: str) -> Motion:
    """One frame of ``motion``'s hierarchy at rest: identity rotations, offsets as translations."""
    J = motion.n_joints
    return Motion(list(motion.names), motion.parents.copy(), motion.offsets.copy(), list(motion.channels),
                  np.broadcast_to(np.eye(3), (1, J, 3, 3)).copy(), motion.offsets[None].copy(),
                  motion.frame_time, name)


def builtin_rig(name: str) -> Rig:
    """The built-in rig ``name`` ('100style', 'bandai' or 'cmu'); RigError naming them otherwise."""
    if name == "100style":
        template, scale = rest_motion(), 0.01
    elif name in ("bandai", "cmu"):
        text = builtin_rigs.BANDAI_HIERARCHY if name == "bandai" else builtin_rigs.CMU_HIERARCHY
        scale = builtin_skeleton(name).bvh_scale
        n_channels = sum(len(line.split()) - 2 for line in text.splitlines() if line.strip().startswith("CHANNELS"))
        frame = " ".join(["0"] * n_channels)
        template = parse_bvh(f"{text}MOTION\nFrames: 1\nFrame Time: {1 / 30 if name == 'bandai' else 1 / 120}\n{frame}\n",
                             source=f"built-in {name} rig", scale=scale)
    else:
        raise RigError(f"unknown rig {name!r}; the built-in rigs are {', '.join(BUILTIN_RIGS)} "
                       "(or give a run folder or a BVH file)")
    shape = BANDAI_FOOT_SHAPE if name == "bandai" else None
    return Rig(name, _rest(template, name), BUILTIN_ROLES[name], scale, builtin_skeleton(name), shape)


def load_rig(target: Union[str, os.PathLike], map_path: Union[str, os.PathLike, None] = None,
             scale: Optional[float] = None) -> Rig:
    """A target rig from a built-in name, a run folder or a BVH file (see the module doc).

    ``map_path`` names the target's roles (needed for a rig minifilm does not recognise);
    ``scale`` is the BVH unit of a file (default: a built-in skeleton's, else guessed)."""
    text = os.fspath(target)
    if text in BUILTIN_RIGS and not Path(text).exists():
        return builtin_rig(text)
    path = Path(text)
    if path.is_dir():
        raise RigError(f"{path}: a folder; a run folder's rig is read by "
                       "minifilm.pipeline.run_rig.load_target (as the commands do), a rig file is a BVH file")
    if not path.exists():
        raise RigError(f"{text}: no such rig; give a built-in rig ({', '.join(BUILTIN_RIGS)}), a run folder "
                       "or a BVH file")
    body = Body(read_bvh(note_input(path), scale=1.0))
    roles = body.roles(map_path)
    if scale is None:
        scale = body.metres_per_unit(roles)     # the names' skeleton's unit if the body agrees
    m = scaled(body.motion, scale)              # read once, scaled (units.scaled)
    return Rig(path.stem, _rest(m, str(path)), roles, float(scale), body.skeleton, foot_shape_of(m, roles))


def rig_from_template(template: Motion, name: str, bvh_scale: float, map_path=None) -> Rig:
    """A rig from one frame of a skeleton in metres (e.g. a run folder's skeleton.bvh), its roles
    found as for a file (:meth:`minifilm.body.read.Body.roles`)."""
    body = Body(template)
    roles, skeleton = body.roles(map_path), body.skeleton
    shape = BANDAI_FOOT_SHAPE if skeleton is not None and skeleton.name == "bandai" else None
    return Rig(name, _rest(template, name), roles, float(bvh_scale), skeleton, shape)
