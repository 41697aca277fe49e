"""Retargeting where a run folder is involved: a run's skeleton as a target rig, a clip of another
rig put on a run's skeleton (``minifilm finetune``).

minifilm/body/ knows rigs from names and BVH files; a run folder is the pipeline's, so it is read
here (:class:`~minifilm.pipeline.run_folder.RunFolder`) and handed over as a template.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Callable, Union

from minifilm.pipeline.run_folder import RunFolder
from minifilm.body.read import read_source
from minifilm.body.retarget_clip import retarget_motion
from minifilm.body.roles import RigError
from minifilm.body.target import BUILTIN_RIGS, Rig, load_rig, rig_from_template

__all__ = ["load_target", "retarget_onto_run"]


def load_target(target: Union[str, os.PathLike], map_path=None, scale=None) -> Rig:
    """A target rig from a built-in name, a run folder or a BVH file (:func:`minifilm.body.target.load_rig`
    for names and files; a run folder's skeleton.bvh and bvh_scale here)."""
    path = Path(os.fspath(target))
    if path.is_dir():
        if not (path / "run.json").is_file():
            raise RigError(f"{path}: a folder, but not a run folder (no run.json); give a built-in rig "
                           f"({', '.join(BUILTIN_RIGS)}), a run folder or a BVH file")
        run = RunFolder.load(path)
        return rig_from_template(run.template(), str(path), run.bvh_scale, map_path)
    return load_rig(target, map_path, scale)


def retarget_onto_run(path, run_path, log: Callable[[str], None] = print):
    """A clip of another rig on a run's skeleton (``minifilm finetune``), saying so; RigError
    naming what is missing when either is not a humanoid minifilm recognises."""
    rig = load_target(run_path)
    motion, roles = read_source(path)
    result = retarget_motion(motion, rig, roles)
    log(f"    {Path(path).name}: not on the run's skeleton ({len(motion.names)} joints, hips {roles.hips!r}); "
        f"retargeted onto it")
    return result
