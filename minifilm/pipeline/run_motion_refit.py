"""A trained run's new style refined by the motion it makes (``minifilm finetune --run
--motion-rounds N``): after Ψ is fine-tuned on the clip (the paper's Sec. 5.3.2), the style's
vector -- the mean of Ψ over the clip's style clips -- goes through the same search as a style
taught to the released network (motion_refit.py):

    start: mean Ψ over the clip         known: the run's other styles' vectors
    search directions: the 16 leading principal directions of the known vectors
    objective: the Fréchet distance of the run's own straight walk in a vector to the clip's
               windows, over the distance to the nearest walk of the 10 known styles nearest the clip

Teacher-forced, Ψ's vector predicts the clip's next frame; walked on its own it may drift to a
trained neighbour, as the released network's fitted vectors did. Only the stored vector changes:
Ψ, Ω and Φ are the fine-tuned checkpoint's, and every other style keeps its vector.

The walks are those of walks.py: 60 frames a second on the 100STYLE skeleton (the skeleton every
run made from the released network's data or retargeted onto it has), with the run's own
controller setting (its position bias); a run on another skeleton or at another rate is refused
with one message before anything is fine-tuned.
"""
from __future__ import annotations

import functools
from typing import Callable, Optional, Sequence

import numpy as np

from minifilm.motion.skeletons import STYLE100
from minifilm.pipeline.motion_refit import Refit, RefitSettings, refine_by_motion
from minifilm.pipeline.run_folder import RunFolder
from minifilm.parallel import executor, worker_count
from minifilm.pipeline.walks import FPS, WALK_WORKERS, FaultCheck, rows_summaries, straight_path, walk
from minifilm.runtime.held_body import toe_joints
from minifilm.runtime.network import RuntimeNetwork
from minifilm.runtime.walk_checks import count_strikes


def refinable(run: RunFolder) -> str:
    """Why the run's styles cannot be refined by motion ('' when they can)."""
    if abs(run.fps - FPS) > 1e-3 * FPS:
        return f"the run is at {run.fps:g} fps; the walks of the refinement are at {FPS:g}"
    if run.skeleton_name != STYLE100.name or list(run.layout.joint_names) != list(STYLE100.joints):
        return f"the run's skeleton is {run.skeleton_name!r}; the walks of the refinement are on {STYLE100.name!r}"
    return ""


def clip_figures(run: RunFolder, segments: Sequence) -> tuple:
    """(speed m/s, steps per second, median hip height m) of the clip's raw rows ``segments``
    [(x, p, z) per file]: the speed from the last trajectory point (clamped to 0.3-4 m/s, as the
    walks are), the steps from the contacts, the hips from the root joint's height."""
    layout = run.layout
    x = np.concatenate([seg[0] for seg in segments])
    hips = float(np.median(x[:, layout.joint_columns("x", "position")[0, 1]]))
    traj = layout.trajectory_columns("x", len(layout.trajectory_seconds) - 1)
    speed = float(np.clip(np.median(np.hypot(x[:, traj[0]], x[:, traj[1]])) / layout.trajectory_seconds[-1], 0.3, 4))
    contacts = np.concatenate([seg[2][:, layout.z_contacts] for seg in segments])
    return speed, count_strikes(contacts) / (len(contacts) / run.fps), hips


def refine_run_style(run: RunFolder, model, stats, film: np.ndarray, known: dict, segments: Sequence,
                     settings: RefitSettings, workers: Optional[int] = 1,
                     log: Callable[[str], None] = print) -> Refit:
    """The run's style ``film`` (D,) moved until its walk looks like the clip ``segments`` (raw
    rows per file, as new_style.clip_training_data gives them; no mirrored copy). model, stats:
    the fine-tuned model (its Ω and Φ are the run's) and the run's statistics. known: the run's
    other styles {name: (D,)}. workers: processes sharing the walks (minifilm/parallel.py; None:
    every usable core, at most WALK_WORKERS; 1: all in this process)."""
    why = refinable(run)
    if why:
        raise ValueError(f"--motion-rounds: {why}")
    windows = rows_summaries([seg[0] for seg in segments], stats, run.layout)
    if len(windows) < 2:
        raise ValueError(f"--motion-rounds: the clip is too short to compare a walk with "
                         f"({len(windows)} window(s) of 0.75 s)")
    speed, steps_per_s, hips = clip_figures(run, segments)
    check = FaultCheck(toe_joints(run.layout.joint_names),
                       straight_path(speed, settings.seconds + 1), steps_per_s, hips)
    network = RuntimeNetwork.from_model(model, stats)
    n = worker_count(workers, WALK_WORKERS)
    with executor(n, n) as pool:
        log(f"refining by motion: {settings.rounds} rounds of {settings.population} walks"
            + (f" in {n} worker processes" if pool is not None else "") + " ...")
        walks = functools.partial(walk, network, run.layout, stats, position_bias=run.position_bias, pool=pool,
                                  shares=n)
        return refine_by_motion(network, run.layout, stats, np.asarray(film, np.float64), known, windows, speed,
                                settings, problems=check, walks=walks, log=log)
