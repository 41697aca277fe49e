"""Retarget every file of a data set onto one rig (``minifilm train --data DIR --rig TARGET``).

Files recorded on different rigs (Bandai Namco, Xia's CMU skeleton, CMU's MotionBuilder export,
100STYLE) cannot share a data set: features are read from one skeleton's joints. In the data
set step each file is put on the target rig (:func:`minifilm.motion.retarget_clip.retarget_motion`)
and written into a folder of the run; the data set is then built from those files with the
original labels and frame ranges (retargeting keeps every frame and the frame rate).
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Callable, List, Sequence

from minifilm.files import file_names
from minifilm.motion.bvh_write import write_bvh
from minifilm.motion.retarget_clip import read_source, retarget_motion
from minifilm.motion.rig import Rig

__all__ = ["retarget_files", "retarget_onto_run", "tracks_on"]


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


def retarget_onto_run(path, run_path, log: Callable[[str], None] = print):
    """A clip of another rig on a run's skeleton (``minifilm finetune``), saying so; RigError
    naming what is missing when either is not a humanoid minifilm recognises."""
    from minifilm.motion.rig import load_rig
    rig = load_rig(run_path)
    motion, roles = read_source(path)
    result = retarget_motion(motion, rig, roles)
    log(f"    {Path(path).name}: not on the run's skeleton ({len(motion.names)} joints, hips {roles.hips!r}); "
        f"retargeted onto it")
    return result


def tracks_on(paths: Sequence, target) -> list:
    """Viewer tracks of BVH files retargeted onto ``target`` (``minifilm view --on``): each file is
    put on the rig, written to a temporary folder and read back as the viewer reads any file
    (true size, contacts), titled '<name> on <rig>'."""
    import tempfile
    from minifilm.motion.rig import load_rig
    from minifilm.viewer.builders import track_with_contacts
    rig = load_rig(target)
    tracks = []
    with tempfile.TemporaryDirectory(prefix="minifilm-view-") as tmp:
        for i, path in enumerate(paths):
            motion, roles = read_source(path)
            out = Path(tmp) / f"{i}.bvh"
            write_bvh(retarget_motion(motion, rig, roles), out, scale=rig.bvh_scale)
            tracks.append(track_with_contacts(out, name=f"{Path(path).stem} on {Path(rig.name).name}"))
    return tracks
