"""Retarget every file of a data set onto one rig (``minifilm train --data DIR --rig TARGET``).

Files recorded on different rigs (Bandai Namco, Xia's CMU skeleton, CMU's MotionBuilder export,
100STYLE) cannot share a data set: features are read from one skeleton's joints. In the data
set step each file is put on the target rig (:func:`minifilm.body.retarget_clip.retarget_motion`)
and written into a folder of the run; the data set is then built from those files with the
original labels and frame ranges (retargeting keeps every frame and the frame rate).
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Callable, List, Sequence

from minifilm.files import file_names
from minifilm.motion.bvh_write import write_bvh
from minifilm.body.read import read_source
from minifilm.body.retarget_clip import retarget_motion
from minifilm.body.target import Rig

__all__ = ["retarget_files"]


def retarget_files(files: Sequence, rig: Rig, folder: Path, log: Callable[[str], None] = print) -> List:
    """``files`` (:class:`minifilm.dataset.manifest.MotionFile`) retargeted onto ``rig``, written
    into ``folder`` (one BVH per file, in the rig's units); returns the same entries pointing at
    the new files. A file already on the rig (same joint names) is retargeted too, so every file
    stands on the same floor."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    keys = [f"{i:04d}_{Path(f.path).stem}" for i, f in enumerate(files)]
    names = file_names(keys)
    out = []
    rigs = {}
    for key, f in zip(keys, files):
        motion, roles = read_source(f.path)
        result = retarget_motion(motion, rig, roles)
        path = folder / f"{names[key]}.bvh"
        write_bvh(result, path, scale=rig.bvh_scale)
        rigs[roles.hips + "/" + roles.chest] = rigs.get(roles.hips + "/" + roles.chest, 0) + 1
        out.append(replace(f, path=path))
    log(f"[dataset] retargeted {len(files)} files onto the {rig.name} rig ({len(rigs)} source rig(s)) into {folder}")
    return out
