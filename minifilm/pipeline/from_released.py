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

With ``workers`` > 1 (the default on a machine of several cores) the styles are cut into one
contiguous share per worker process (minifilm/parallel.py): each share is calibrated, then driven
gait after gait, its files written by the worker; this process writes the manifest and the
description, the rows in the order one process makes them (gait-major, then style order). The file
stems are made here from all the styles' names, so two styles of different shares never get one
file name.

Why the data set is nearly the one of one process: each style's paths come from its own seeded
generator (style_seed), and a character of a batch rollout depends only on its own inputs (the
batch is the rows of the same matrix products), so a style drives the same in any share, to
float32 round-off (a batch of 2-4 characters takes the network's vector-product path,
runtime/network.py); the calibration's batches mix styles too, with the same argument. Bit for
bit, two workers of four styles write what one process writes with ``batch=4`` (the same
products); against another batch size the round-off differs, and a few seconds of standing can
grow it: 8 styles' TR1 and ID files, 1 worker against 2, all within 0.01 (cm, degrees) but
Swimming's ID, 1.2. (A coupling between characters of one batch -- a walker's feet kept as the
held feet of another's stop, runtime/standing.py -- is fixed; before, 7 of 160 TR1 files differed
by up to 1.9 cm and 19 degrees.)
"""
from __future__ import annotations

import functools
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
from minifilm.pipeline.gait_scripts import GAIT_SHARES
# the driving (released_driver.py), named here too: the job's settings, and its parts for studies/
from minifilm.pipeline.released_driver import (FPS, ReleasedDataSettings, StyleDriver,  # noqa: F401 (re-exported)
                                               calibrate_styles, drive_gaits, style_seed)
from minifilm.parallel import executor, map_in_order, worker_count
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
    (module docstring); default every core this process may use, at most one per style; 1 drives
    them all in this process. The data set is the same for any number but for float32 round-off,
    which standing can grow (module docstring).
    """
    s = settings
    check_settings(s)
    try:
        worker_count(workers, 1)        # a count that is not one: refused before any work
    except ValueError as e:
        raise ValueError(f"make_released_dataset: {e}") from None
    rel = released(str(params))
    names = list(rel.styles) if s.styles is None else list(s.styles)
    unknown = [n for n in names if n not in rel.styles]
    if unknown or not names or len(set(names)) != len(names):
        raise InputError(f"--styles: {'unknown ' + str(unknown) if unknown else 'each style once, at least one'}; "
                         f"the released network has {' '.join(rel.styles)}")
    stems = style_file_names(names)
    n = worker_count(workers, len(names))
    bounds = np.linspace(0, len(names), n + 1).round().astype(int)
    shares = [names[a:b] for a, b in zip(bounds[:-1], bounds[1:])]
    own = previous_output(Path(out))
    t_start = time.perf_counter()
    with atomic_directory(out, "data set folder",
                          replaceable=lambda name: name in own or bool(_OWN_NAME.match(name))) as tmp, \
            executor(n, n) as pool:         # (left first: the workers end before the temporary goes)
        on = 1 if pool is None else pool
        if pool is not None:
            log(f"{len(names)} styles in {n} worker processes, each a share of them")
        calibrations = [None] * n
        if s.calibrate:
            t0 = time.perf_counter()
            calibrations = map_in_order(functools.partial(calibrate_share, params=str(params), settings=s), shares,
                                        on, doing="calibrating the speeds of", name=", ".join)
            log(f"speed calibration of {len(names)} styles: {time.perf_counter() - t0:.1f} s")
        jobs = [(gait, share, {st: stems[st] for st in share}, cal) for gait in s.gaits
                for share, cal in zip(shares, calibrations)]

        def said(i: int, rows: List[dict]) -> None:       # a gait's last share is back
            if i % n == n - 1:
                log(f"{jobs[i][0]}: {len(names)} styles x {rows[0]['frames'] / FPS:.1f} s, "
                    f"{time.perf_counter() - t_start:.1f} s from the start")
        driven = map_in_order(functools.partial(drive_share, params=str(params), folder=tmp, settings=s), jobs, on,
                              doing="driving", name=lambda job: f"gait {job[0]} of {', '.join(job[1])}", done=said)
        described = [row for rows in driven for row in rows]        # gait-major, then style order
        info = _write_description(tmp, params, s, names, described)
    log(f"{len(described)} files of {len(names)} styles -> {out} in {time.perf_counter() - t_start:.1f} s")
    return info


@functools.lru_cache(maxsize=1)
def released(params: str):
    """The released network in the folder ``params``, loaded once per process (each worker its own)."""
    return load_released(Path(params))


def calibrate_share(names: Sequence[str], params: str, settings: ReleasedDataSettings) -> list:
    """The speed calibrations of the styles ``names`` (StyleDriver.calibrate), wherever it runs."""
    driver = StyleDriver(released(params), names, {}, Path(), settings)
    driver.calibrate()
    return driver.calibrations


def drive_share(job, params: str, folder: Path, settings: ReleasedDataSettings) -> List[dict]:
    """One gait of a share of the styles, job = (gait, names, their file stems, their calibrations or
    None), wherever it runs: the files written into ``folder``, their rows in style order."""
    gait, names, stems, calibrations = job
    driver = StyleDriver(released(params), names, stems, folder, settings)
    driver.calibrations = calibrations
    return driver.gait(gait)


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
