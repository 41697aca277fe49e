"""A 100STYLE-like data set made by the authors' released network (the first step of reports/2026-12-02_dense_style_space.md).

    minifilm dataset --from-released ../shared/data/released-lpn --out data/released100

100STYLE itself (4 million frames) is not always at hand; the released network's 100 styles are.
This job drives the network in each of its styles along scripted paths for every 100STYLE gait
(:mod:`minifilm.pipeline.gait_scripts`: walks, runs, turns, sidesteps, backwards, stops and
standing, at several speeds) and writes what it did as ``<Style>_<Gait>.bvh`` on the 100STYLE
skeleton, plus ``manifest.csv`` (``minifilm train --data`` reads the folder or the manifest) and
``dataset.json`` (settings, files, frames, and how minifilm's labelling agrees with the network).

The network is driven as ``minifilm generate --params`` does it, each style along its own seeded
paths (:mod:`minifilm.pipeline.released_driver`: the speed calibration, the fitting onto the
100STYLE skeleton, foot locking, the warm-up cut from every rollout).

With ``workers`` > 1 (the default on a machine of several cores) worker processes each drive a
share of the styles and write their files (:mod:`minifilm.pipeline.from_released_workers`); this
process writes the manifest and the description. The data set is the same but for float32
round-off, which standing can grow (from_released_workers.py says how much).
"""
from __future__ import annotations

import contextlib
import json
import re
import time
from dataclasses import asdict
from pathlib import Path
from typing import Callable, Dict, List, Optional, Sequence

import numpy as np

from minifilm.dataset.manifest import MADE_BY, MotionFile, write_manifest
from minifilm.dataset.survey import MIN_FRAMES
from minifilm.errors import InputError
from minifilm.evaluation.label_agreement import summarise
from minifilm.files import atomic_directory, atomic_write_text, file_names, read_json
from minifilm.pipeline.from_released_workers import ReleasedWorkers
from minifilm.pipeline.gait_scripts import GAIT_SHARES
# the driving (released_driver.py), named here too: the job's settings, and its parts for studies/
from minifilm.pipeline.released_driver import (FPS, ReleasedDataSettings, StyleDriver,  # noqa: F401 (re-exported)
                                               calibrate_styles, drive_gaits, style_seed)
from minifilm.processes import check_workers, default_workers
from minifilm.runtime.released import load_released

_OWN_NAME = re.compile(r"^[A-Za-z0-9]+_[A-Z]+[0-9]*\.bvh$|^manifest\.csv$|^dataset\.json$")


def min_seconds_per_style(gaits: Sequence[str] = tuple(GAIT_SHARES)) -> float:
    """The least ``seconds_per_style`` whose every gait file holds the frames a data set file needs
    (``MIN_FRAMES`` of minifilm/dataset/survey.py): its shortest gait gets the smallest share."""
    return MIN_FRAMES / (FPS * min(GAIT_SHARES[g] for g in gaits))


def style_file_names(names: Sequence[str]) -> Dict[str, str]:
    """style -> the stem of its files (``<stem>_<Gait>.bvh``): the style's name made safe for every
    file system (minifilm/files/names.py), distinct for every style also where two names would
    give one file name (``A:B`` and ``A_B``; ``Neutral_`` and ``neutral_``, one file on macOS):
    the later one is numbered (``A_B-2``). The manifest keeps each file's true style name, and
    ``minifilm dataset`` / ``train --data`` read such a folder by its manifest."""
    return file_names(names)


def previous_output(out: Path) -> set:
    """The names of the files a previous run of this job wrote into ``out`` (its dataset.json says
    it made the folder and lists them), so running the same command again replaces them; empty
    for any other folder."""
    marker = out / "dataset.json"
    if not marker.is_file():
        return set()
    try:
        info = read_json(marker, "data set description")
    except (InputError, OSError):
        return set()
    if not isinstance(info, dict) or info.get("made_by") != MADE_BY or not isinstance(info.get("files"), list):
        return set()
    names = {row.get("file") for row in info["files"] if isinstance(row, dict)}
    return {n for n in names if isinstance(n, str) and n.lower().endswith(".bvh") and "/" not in n} | \
        {"manifest.csv", "dataset.json"}


def check_settings(s: ReleasedDataSettings) -> None:
    """InputError for settings that cannot make a data set."""
    if s.warmup < 0 or s.batch < 1:
        raise InputError(f"warmup {s.warmup}, batch {s.batch}: need warmup >= 0, batch >= 1")
    unknown_gaits = [g for g in s.gaits if g not in GAIT_SHARES]
    if unknown_gaits or not s.gaits:
        raise InputError(f"gaits {list(s.gaits)}: unknown or none; known {list(GAIT_SHARES)}")
    least = min_seconds_per_style(s.gaits)
    if not s.seconds_per_style >= least:
        shortest = min(s.gaits, key=GAIT_SHARES.__getitem__)
        raise InputError(f"--seconds-per-style {s.seconds_per_style:g}: at least {least:g} s, so that the shortest "
                         f"gait file ({shortest}, {GAIT_SHARES[shortest]:.0%} of it) holds the {MIN_FRAMES} frames "
                         f"minifilm train needs of every file at {FPS:g} fps (to train with the default 4 s "
                         "style clips give a minute or so)")


def make_released_dataset(params: Path, out: Path, settings: ReleasedDataSettings = ReleasedDataSettings(),
                          log: Callable[[str], None] = print, workers: Optional[int] = None) -> dict:
    """Write the data set into the folder ``out`` (atomically: the whole folder or nothing) and
    return its description (also written as ``out/dataset.json``).

    workers: processes driving the network at once, each a contiguous share of the styles
    (from_released_workers.py); default every core this process may use, at most one per style;
    1 drives them all in this process. The data set is the same for any number but for float32
    round-off, which standing can grow (from_released_workers.py says how much).
    """
    s = settings
    check_settings(s)
    check_workers(workers, "make_released_dataset")
    rel = load_released(params)
    names = list(rel.styles) if s.styles is None else list(s.styles)
    unknown = [n for n in names if n not in rel.styles]
    if unknown or not names or len(set(names)) != len(names):
        raise InputError(f"--styles: {'unknown ' + str(unknown) if unknown else 'each style once, at least one'}; "
                         f"the released network has {' '.join(rel.styles)}")
    stems = style_file_names(names)
    workers = min(default_workers(len(names)) if workers is None else workers, len(names))
    own = previous_output(Path(out))
    t_start = time.perf_counter()
    described: List[dict] = []
    with atomic_directory(out, "data set folder",
                          replaceable=lambda name: name in own or bool(_OWN_NAME.match(name))) as tmp, \
            _drivers(params, rel, names, stems, tmp, s, workers, log) as driver:
        if s.calibrate:
            t0 = time.perf_counter()
            driver.calibrate()
            log(f"speed calibration of {len(names)} styles: {time.perf_counter() - t0:.1f} s")
        for gait in s.gaits:
            t0 = time.perf_counter()
            rows = driver.gait(gait)
            log(f"{gait}: {len(names)} styles x {rows[0]['frames'] / FPS:.1f} s in {time.perf_counter() - t0:.1f} s")
            described += rows
        info = _write_description(tmp, params, s, names, described)
    log(f"{len(described)} files of {len(names)} styles -> {out} in {time.perf_counter() - t_start:.1f} s")
    return info


@contextlib.contextmanager
def _drivers(params, rel, names, stems, folder: Path, s: ReleasedDataSettings, workers: int, log):
    """What drives the styles: a :class:`StyleDriver` of them all here (1 worker), or worker
    processes each driving a share (the same calibrate() and gait(), the rows in style order),
    stopped when the block is left, however it is left."""
    if workers <= 1:
        yield StyleDriver(rel, names, stems, folder, s)
        return
    with ReleasedWorkers(params, names, stems, folder, s, workers) as pool:
        log(f"{len(names)} styles in {workers} worker processes (ids {', '.join(map(str, pool.pids))})")
        yield pool


def _write_description(folder: Path, params, s: ReleasedDataSettings, names: Sequence[str],
                       described: List[dict]) -> dict:
    """Write manifest.csv and dataset.json of the files ``described`` (rows of
    :meth:`StyleDriver.gait`, gait-major) into ``folder``; returns the description."""
    write_manifest([MotionFile(folder / r["file"], r["style"], r["gait"]) for r in described], folder / "manifest.csv")
    info = dict(made_by=MADE_BY, params=str(Path(params).resolve()),  # absolute: read from any folder
                settings={k: (list(v) if isinstance(v, (tuple, list)) else v) for k, v in asdict(s).items()},
                styles=list(names), gaits=list(s.gaits), fps=FPS, files=described)
    if s.check_labels:
        info["label_agreement"] = {st: summarise([r["labels"] for r in described if r["style"] == st]) for st in names}
    info = _no_nan(info)     # JSON has no NaN: a file without a measurable phase says null
    atomic_write_text(folder / "dataset.json", json.dumps(info, indent=1, allow_nan=False) + "\n")
    return info


def _no_nan(value):
    if isinstance(value, dict):
        return {k: _no_nan(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_no_nan(v) for v in value]
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value
