"""A 100STYLE-like data set made by the authors' released network (the first step of reports/2026-12-02_dense_style_space.md).

    minifilm dataset --from-released ../shared/data/released-lpn --out data/released100

100STYLE itself (4 million frames) is not always at hand; the released network's 100 styles are.
This job drives the network in each of its styles along scripted paths for every 100STYLE gait
(:mod:`minifilm.pipeline.gait_scripts`: walks, runs, turns, sidesteps, backwards, stops and
standing, at several speeds) and writes what it did as ``<Style>_<Gait>.bvh`` on the 100STYLE
skeleton, plus ``manifest.csv`` (``minifilm train --data`` reads the folder or the manifest) and
``dataset.json`` (settings, files, frames, and how minifilm's labelling agrees with the network).

How the network is driven (as ``minifilm generate --params`` does it): the per-style speed
calibration (measured here for all styles in one batch), every frame fitted onto the 100STYLE
skeleton and fed back, foot locking from the predicted contacts. All styles walk one gait together
as one batch (one network call per frame for up to ``batch`` styles). Each style's paths come from
its own random generator, seeded by (seed, style name, gait), so a style's paths do not depend on
which other styles are written. The first ``warmup`` second of every rollout (which starts from
the data's mean pose) is cut off.
"""
from __future__ import annotations

import json
import re
import time
import zlib
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable, Dict, Iterator, List, Optional, Sequence, Tuple

import numpy as np

from minifilm.dataset.manifest import MADE_BY, MotionFile, write_manifest
from minifilm.errors import InputError
from minifilm.evaluation.label_agreement import agreement, summarise
from minifilm.features.layout import FeatureLayout
from minifilm.dataset.survey import MIN_FRAMES
from minifilm.files import atomic_directory, atomic_write_text, file_names, read_json
from minifilm.motion.bvh_write import write_bvh
from minifilm.motion.foot_ik import FootLocker
from minifilm.motion.skeletons import STYLE100
from minifilm.phases.label import label
from minifilm.pipeline.gait_scripts import GAIT_SHARES, gait_script, gait_seconds
from minifilm.runtime.calibration import PerCharacterCalibration, SpeedCalibration
from minifilm.runtime.control import CommandScript
from minifilm.runtime.controller import Controller
from minifilm.runtime.start_state import root_joint_indices
from minifilm.runtime.rollout import Rollout
from minifilm.runtime.released import load_released
from minifilm.synthetic.generator import rest_motion

_OWN_NAME = re.compile(r"^[A-Za-z0-9]+_[A-Z]+[0-9]*\.bvh$|^manifest\.csv$|^dataset\.json$")
FPS = 60.0


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


@dataclass
class ReleasedDataSettings:
    """seconds_per_style: motion per style over all gaits (shared as ``GAIT_SHARES``);
    styles: names (default all of the network's); seed; warmup: seconds cut from each rollout's
    start; calibrate: per-style speed calibration; foot_lock; check_labels: label every file with
    minifilm's recipe and compare with the network's own contacts and phases; batch: styles per
    network call; calibration_commands / directions / seconds: the calibration's grid."""
    seconds_per_style: float = 60.0
    styles: Optional[Sequence[str]] = None
    seed: int = 0
    warmup: float = 1.0
    calibrate: bool = True
    foot_lock: bool = True
    check_labels: bool = True
    batch: int = 100
    # up to 16 m/s: the network approaches its top speed slowly (Neutral: 1.46 m/s at 6, 1.8 at 16)
    calibration_commands: Sequence[float] = (0.5, 1.0, 2.0, 3.0, 4.0, 6.0, 10.0, 16.0)
    calibration_directions: Sequence[float] = (0.0, 90.0, 180.0)
    calibration_seconds: float = 5.0
    gaits: Sequence[str] = field(default_factory=lambda: tuple(GAIT_SHARES))


def calibrate_styles(controller: Controller, films: np.ndarray, commands: Sequence[float],
                     directions: Sequence[float], seconds: float, batch: int = 400) -> List[SpeedCalibration]:
    """One :class:`SpeedCalibration` per style, the styles measured together (as
    :func:`~minifilm.runtime.calibration.calibrate_speed` does for one): every (style, direction,
    command) is a character of one batch of at most ``batch``; the speed is measured over the
    second half. films (S, D) -> S calibrations."""
    n = int(round(seconds * controller.fps))
    k0 = n // 2
    jobs = [(s, d, v) for s in range(len(films)) for d in directions for v in commands]
    achieved = np.empty(len(jobs))
    for a in range(0, len(jobs), batch):
        part = jobs[a:a + batch]
        scripts = [CommandScript([(0.0, v, 0.0, d), (seconds, v, 0.0, d)]) for _, d, v in part]
        r = controller.run(scripts, n, films[[s for s, _, _ in part]])
        dist = np.sum(np.linalg.norm(np.diff(r.root_positions[:, k0:], axis=1), axis=-1), axis=1)
        achieved[a:a + len(part)] = dist / ((n - 1 - k0) / controller.fps)
    per_style = achieved.reshape(len(films), len(directions), len(commands))
    return [SpeedCalibration(np.asarray(commands, np.float64), per_style[s], tuple(directions))
            for s in range(len(films))]


def style_seed(seed: int, style: str, gait: str) -> np.random.Generator:
    """The generator of one style's path for one gait: independent of the other styles written."""
    return np.random.default_rng([seed, zlib.crc32(style.encode()), zlib.crc32(gait.encode())])


def drive_gaits(controller: Controller, films: np.ndarray, names: Sequence[str], gaits: Sequence[str],
                seconds_per_style: float, seed: int, warmup: float,
                calibrations: Optional[Sequence] = None, batch: int = 100) -> Iterator[Tuple[str, int, Rollout]]:
    """Drive ``controller`` in every style along each gait's scripted path, up to ``batch`` styles at once.

    films (S, D) are the styles' FiLM vectors, ``names`` their names (each style's paths come from
    :func:`style_seed`). A gait gets its :data:`GAIT_SHARES` share of ``seconds_per_style``, after
    ``warmup`` seconds (the first ``round(warmup * fps)`` frames of each rollout; cut them).
    calibrations: one per style, each anything with ``apply(velocity, facing)`` (a
    :class:`SpeedCalibration`), or None. Yields (gait, index of the chunk's first style, Rollout).
    """
    seconds = gait_seconds(seconds_per_style)
    fps = controller.fps
    w = int(round(warmup * fps))
    for gait in gaits:
        n = w + max(2, int(round(seconds[gait] * fps)))
        for a in range(0, len(names), batch):
            chunk = names[a:a + batch]
            scripts = [gait_script(gait, style_seed(seed, st, gait), n / fps - warmup, warmup) for st in chunk]
            cal = None if calibrations is None else PerCharacterCalibration(calibrations[a:a + len(chunk)])
            yield gait, a, controller.run(scripts, n, films[a:a + len(chunk)], calibration=cal)


def make_released_dataset(params: Path, out: Path, settings: ReleasedDataSettings = ReleasedDataSettings(),
                          log: Callable[[str], None] = print) -> dict:
    """Write the data set into the folder ``out`` (atomically: the whole folder or nothing) and
    return its description (also written as ``out/dataset.json``)."""
    s = settings
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
    rel = load_released(params)
    names = list(rel.styles) if s.styles is None else list(s.styles)
    unknown = [n for n in names if n not in rel.styles]
    if unknown or not names or len(set(names)) != len(names):
        raise InputError(f"--styles: {'unknown ' + str(unknown) if unknown else 'each style once, at least one'}; "
                         f"the released network has {' '.join(rel.styles)}")
    films = np.stack([rel.styles[n] for n in names])
    stems = style_file_names(names)
    layout = FeatureLayout.for_skeleton(STYLE100)
    skeleton = rest_motion()
    joints = root_joint_indices(layout, skeleton)
    fps = FPS
    own = previous_output(Path(out))
    t_start = time.perf_counter()

    cals = None
    if s.calibrate:
        t0 = time.perf_counter()
        cals = calibrate_styles(Controller(rel.network, layout, fps=fps), films, s.calibration_commands,
                                s.calibration_directions, s.calibration_seconds)
        log(f"speed calibration of {len(names)} styles: {time.perf_counter() - t0:.1f} s")

    ctrl = Controller(rel.network, layout, fps=fps, skeleton=Controller.skeleton_for(layout, skeleton),
                      feed_back_fit=True,
                      foot_locker=FootLocker.from_names(layout.joint_names) if s.foot_lock else None)
    w = int(round(s.warmup * fps))
    files: List[MotionFile] = []
    described: List[dict] = []
    checks: Dict[str, List[dict]] = {n: [] for n in names}
    with atomic_directory(out, "data set folder",
                          replaceable=lambda name: name in own or bool(_OWN_NAME.match(name))) as tmp:
        t0 = time.perf_counter()
        for gait, first, r in drive_gaits(ctrl, films, names, s.gaits, s.seconds_per_style, s.seed, s.warmup,
                                          cals, s.batch):
            n = r.positions.shape[1]
            for b, style in enumerate(names[first:first + len(r.positions)]):
                motion = r.to_motion(skeleton, joints, character=b).slice(w, n)
                path = tmp / f"{stems[style]}_{gait}.bvh"
                write_bvh(motion, path, scale=STYLE100.bvh_scale)
                files.append(MotionFile(out / path.name, style, gait))
                row = dict(file=path.name, style=style, gait=gait, frames=n - w,
                           mean_speed=float(np.linalg.norm(np.diff(r.root_positions[b, w:], axis=0),
                                                           axis=1).mean() * fps))
                if s.check_labels:
                    lab = label(motion, STYLE100, style)
                    row["labels"] = agreement(lab, r.contacts[b, w:], r.phases[b, w:])
                    checks[style].append(row["labels"])
                described.append(row)
            if first + len(r.positions) == len(names):
                log(f"{gait}: {len(names)} styles x {(n - w) / fps:.1f} s in {time.perf_counter() - t0:.1f} s")
                t0 = time.perf_counter()
        write_manifest([MotionFile(tmp / f.path.name, f.style, f.gait) for f in files], tmp / "manifest.csv")
        info = dict(made_by=MADE_BY, params=str(Path(params).resolve()),  # absolute: read from any folder
                    settings={k: (list(v) if isinstance(v, (tuple, list)) else v) for k, v in asdict(s).items()},
                    styles=names, gaits=list(s.gaits), fps=fps, files=described)
        if s.check_labels:
            info["label_agreement"] = {st: summarise(rows) for st, rows in checks.items()}
        info = _no_nan(info)     # JSON has no NaN: a file without a measurable phase says null
        atomic_write_text(tmp / "dataset.json", json.dumps(info, indent=1, allow_nan=False) + "\n")
    log(f"{len(files)} files of {len(names)} styles -> {out} in {time.perf_counter() - t_start:.1f} s")
    return info


def _no_nan(value):
    if isinstance(value, dict):
        return {k: _no_nan(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_no_nan(v) for v in value]
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value
