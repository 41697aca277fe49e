"""Driving the authors' released network in some of its styles along each 100STYLE gait's scripted
path, and writing what it did as BVH files: the work of ``minifilm dataset --from-released``
(from_released.py), done by one process for all the styles or by each worker process for its
share (from_released.py: calibrate_share, drive_share).

How the network is driven (as ``minifilm generate --params`` does it): the per-style speed
calibration (measured for all the styles together, in batches), every frame fitted onto the
100STYLE skeleton and fed back, foot locking from the predicted contacts. All the styles (of one
process) walk one gait together as one batch (one network call per frame for up to ``batch``
styles). Each style's paths come from its own random generator, seeded by (seed, style name,
gait), so a style's paths do not depend on which other styles are written, nor on which process
drives it. The first ``warmup`` second of every rollout (which starts from the data's mean pose)
is cut off.
"""
from __future__ import annotations

import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, Iterator, List, Optional, Sequence, Tuple

import numpy as np

from minifilm.evaluation.label_agreement import agreement
from minifilm.features.layout import FeatureLayout
from minifilm.motion.bvh_write import write_bvh
from minifilm.motion.skeletons import STYLE100
from minifilm.phases.label import label
from minifilm.pipeline.gait_scripts import GAIT_SHARES, gait_script, gait_seconds
from minifilm.runtime.calibration import PerCharacterCalibration, SpeedCalibration
from minifilm.runtime.control import CommandScript
from minifilm.runtime.held_body import foot_locker
from minifilm.runtime.controller import Controller
from minifilm.runtime.start_state import root_joint_indices
from minifilm.runtime.rollout import Rollout
from minifilm.synthetic.generator import rest_motion

#: the frame rate of the files written (100STYLE's)
FPS = 60.0


@dataclass
class ReleasedDataSettings:
    """seconds_per_style: motion per style over all gaits (shared as ``GAIT_SHARES``);
    styles: names (default all of the network's); seed; warmup: seconds cut from each rollout's
    start; calibrate: per-style speed calibration; foot_lock; check_labels: label every file with
    minifilm's recipe and compare with the network's own contacts and phases; batch: styles per
    network call (of each process); calibration_commands / directions / seconds: the
    calibration's grid."""
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


class StyleDriver:
    """The released network driven in some of its styles: their speed calibration, then every
    gait's files written into ``folder``. One process drives all the styles with one; a worker
    (from_released.py: drive_share) drives its share with one.

    rel: the loaded network (runtime/released.py: load_released); names: the styles, in order;
    stems: style -> the stem of its files (made from all the data set's styles, so names stay
    distinct in a share); settings: the job's :class:`ReleasedDataSettings`.
    """

    def __init__(self, rel, names: Sequence[str], stems: Dict[str, str], folder: Path,
                 settings: ReleasedDataSettings):
        self.s, self.names, self.stems, self.folder = settings, list(names), stems, Path(folder)
        self.network = rel.network
        self.films = np.stack([rel.styles[n] for n in self.names])           # (S, 4H)
        self.layout = FeatureLayout.for_skeleton(STYLE100)
        self.skeleton = rest_motion()
        self.joints = root_joint_indices(self.layout, self.skeleton)
        self.calibrations: Optional[List[SpeedCalibration]] = None
        self.controller = Controller(self.network, self.layout, fps=FPS, feed_back_fit=True,
                                     skeleton=Controller.skeleton_for(self.layout, self.skeleton),
                                     foot_locker=foot_locker(self.layout) if settings.foot_lock else None)

    def calibrate(self) -> None:
        """Measure every style's speeds (the calibration the gaits then use)."""
        s = self.s
        self.calibrations = calibrate_styles(Controller(self.network, self.layout, fps=FPS), self.films,
                                             s.calibration_commands, s.calibration_directions, s.calibration_seconds)

    def gait(self, gait: str) -> List[dict]:
        """Drive every style along its path for ``gait``, write ``<stem>_<gait>.bvh`` for each into
        the folder, and return one row per style, in style order: file, style, gait, frames,
        mean_speed (m/s), and with check_labels the agreement of minifilm's labels with the
        network's own contacts and phases ('labels')."""
        s, rows = self.s, []
        for _, first, r in drive_gaits(self.controller, self.films, self.names, [gait], s.seconds_per_style,
                                       s.seed, s.warmup, self.calibrations, s.batch):
            chunk = self.names[first:first + len(r.positions)]
            rows += [self._write(r, b, style, gait) for b, style in enumerate(chunk)]
        return rows

    def _write(self, r: Rollout, b: int, style: str, gait: str) -> dict:
        """Character b of the rollout r, after the warm-up: its file written, its row."""
        w, n = int(round(self.s.warmup * FPS)), r.positions.shape[1]
        motion = r.to_motion(self.skeleton, self.joints, character=b).slice(w, n)
        path = self.folder / f"{self.stems[style]}_{gait}.bvh"
        write_bvh(motion, path, scale=STYLE100.bvh_scale)
        row = dict(file=path.name, style=style, gait=gait, frames=n - w,
                   mean_speed=float(np.linalg.norm(np.diff(r.root_positions[b, w:], axis=0), axis=1).mean() * FPS))
        if self.s.check_labels:
            row["labels"] = agreement(label(motion, STYLE100, style), r.contacts[b, w:], r.phases[b, w:])
        return row
