"""The authors' released network in the comparison's rollout table: driven along the same commanded
figure-eight for the same seconds as every variant (no speed calibration, no foot locking: exactly
as the variants are driven), in each seen style it has, and measured with the same functions
(minifilm/evaluation/compare_rollouts.py).

Where the network comes from: ``--released DIR``, or by default the folder a data set made by
``minifilm dataset --from-released`` names in its dataset.json (skipped with a note when that
folder is not on this machine). The network runs at its own 60 fps; its rollout is thinned to the
data set's rate before it is measured, so the style classifier sees the rate it was trained on.
"""
from __future__ import annotations

from dataclasses import fields, replace
from pathlib import Path

import numpy as np

from minifilm.dataset.manifest import MADE_BY
from minifilm.errors import InputError
from minifilm.evaluation.compare_report_tools import report_name
from minifilm.evaluation.compare_rollouts import measure_rollout, run_films
from minifilm.features.layout import FeatureLayout
from minifilm.files import read_json
from minifilm.motion.skeletons import STYLE100
from minifilm.runtime.released import load_released

#: the frame rate the released network was trained at
RELEASED_FPS = 60.0


def released_folder(args):
    """(folder or None, where it was named): --released, else the dataset.json of a data set made by
    the released network; (None, None) when neither names one."""
    if getattr(args, "released", None) is not None:
        return Path(args.released), "--released"
    if args.data in (None, "synthetic"):
        return None, None
    marker = Path(args.data) / "dataset.json"
    if not marker.is_file():
        return None, None
    try:
        info = read_json(marker, "data set description")
    except InputError:
        return None, None
    if not isinstance(info, dict) or info.get("made_by") != MADE_BY or not info.get("params"):
        return None, None
    folder = Path(str(info["params"]))
    # older data sets hold the path as given, relative to where `dataset` ran: try beside the data too
    if not folder.is_absolute() and not folder.is_dir() and (marker.parent / folder).is_dir():
        folder = marker.parent / folder
    return folder, "the data set's dataset.json"


def thin(rollout, step: int):
    """Every ``step``-th frame of a Rollout (all its per-frame arrays), fps divided by ``step``."""
    if step == 1:
        return rollout
    per_frame = {f.name: getattr(rollout, f.name)[:, ::step] for f in fields(rollout)
                 if isinstance(getattr(rollout, f.name), np.ndarray)}
    return replace(rollout, fps=rollout.fps / step, **per_frame)


def released_rollout(ctx, args):
    """The released network's rollout summary (compare_rollouts.measure_rollout) for the seen styles
    it knows, or None when no network is named; {'skipped': reason} when it cannot be run here."""
    folder, named_by = released_folder(args)
    if folder is None:
        return None
    shown = report_name(folder)
    if not folder.is_dir():
        if named_by == "--released":
            raise InputError(f"--released {folder}: no such folder")
        return {"skipped": f"the released network named by {named_by} ({folder.name}) is not on this machine"}
    if ctx.ds.skeleton != STYLE100.name:
        if named_by == "--released":
            raise InputError(f"--released: the released network runs on the 100STYLE skeleton; the data's is "
                             f"{ctx.ds.skeleton!r}")
        return {"skipped": f"the data's skeleton is {ctx.ds.skeleton!r}, not 100STYLE"}
    step = RELEASED_FPS / ctx.ds.fps
    if abs(step - round(step)) > 1e-9 or round(step) < 1:
        return {"skipped": f"the data's {ctx.ds.fps:g} fps does not divide the network's {RELEASED_FPS:g} fps"}
    rel = load_released(folder)
    styles = [s for s in ctx.seen if s in rel.styles]
    if not styles:
        return {"skipped": f"none of the seen styles is one of the released network's {len(rel.styles)}"}
    layout = FeatureLayout.for_skeleton(STYLE100)
    films = np.stack([rel.styles[s] for s in styles])
    rollout = run_films(rel.network, layout, RELEASED_FPS, films, args.rollout_seconds)
    if rollout is not None:
        rollout = thin(rollout, int(round(step)))
    names = list(layout.joint_names)
    toes = [names.index(STYLE100.phase_bones[3]), names.index(STYLE100.phase_bones[2])]
    hands = layout.joint_columns("clip", "position")[[names.index(b) for b in STYLE100.phase_bones[:2]]]
    summary = measure_rollout(rollout, ctx, styles, parents=layout.parents, toes=toes, hands=hands)
    return {"source": shown, "named_by": named_by, "styles": styles, "rollout": summary}
