"""Teach a trained run a new style from a short clip: fine-tune Ψ alone (Sec. 5.3.2, Figure 11).

    clip(s) on the run's skeleton -> labels (contacts, local phases) -> x, p, z rows and style clips
    -> fine-tune Ψ with Ω and Φ frozen -> FiLM vector of the new style -> the run's style library

The run folder gains the new style in styles.npz (every existing style keeps its stored vector
exactly, so its motion is bit-identical), a start frame in starts.npz, and the fine-tuned
checkpoint as ``model-<NAME>.npz`` beside the original, which is never overwritten. A clip far
outside the run's data also gives the style an adapter of its own (teach_adapter.py), kept in
the run's adapters.npz / adapters.json and applied only while that style is on. Everything is
checked before anything is written.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, List, Optional, Sequence

import numpy as np

from minifilm.body.read import Body
from minifilm.dataset.arrays import TrainData
from minifilm.features.compute import clip_features, frame_features, seconds_to_frames
from minifilm.motion.bvh import read_bvh
from minifilm.motion.editing import mirror, resample
from minifilm.motion.motion import Motion
from minifilm.motion.skeletons import builtin_skeleton
from minifilm.phases.label import label
from minifilm.files import check_name, check_writable, child_path, folder_lock, owned_writes, same_file_key

from minifilm.pipeline.motion_refit import Refit, RefitSettings
from minifilm.pipeline.run_folder import RunFolder
from minifilm.pipeline.run_motion_refit import clip_figures, refinable, refine_run_style
from minifilm.pipeline.run_rig import retarget_onto_run
from minifilm.pipeline.self_fed import SelfFed, self_fed_rounds
from minifilm.pipeline.teach_adapter import AdapterPlan, adapted_condition, adapter_kind, fit_style_adapter
from minifilm.runtime.adapted import AdaptedNetwork
from minifilm.runtime.adapter_file import write_adapters
from minifilm.runtime.control import CommandScript
from minifilm.runtime.held_body import toe_joints
from minifilm.runtime.network import RuntimeNetwork
from minifilm.runtime.walk_checks import count_strikes, walk_report
from minifilm.pipeline.teach_released import input_distance
from minifilm.train.finetune import finetune
from minifilm.train.trainer import TrainConfig, Trainer

@dataclass
class NewStyleResult:
    name: str
    seconds: float            # fine-tuning time
    steps: int
    frames: int               # training rows
    clips: int                # style clips
    loss_before: float        # MSE + BLL on the clip's rows with Ψ as trained
    loss_after: float         # ... with the fine-tuned Ψ
    nearest: str              # the trained style whose FiLM vector is closest to the new one
    checkpoint: Path
    rollout_errors: list = field(default_factory=list)   # m, before each self-fed round and after the last
    clip_seconds: float = 0.0
    share_beyond: float = 0.0     # share of the clip's normalised input numbers beyond 5 σ of the run's data
    worst: list = field(default_factory=list)              # [(feature, share of rows)] worst first
    check: object = None          # WalkReport of the new style rolled out (runtime/walk_checks.py)
    refit: Optional[Refit] = None  # the refinement by motion (run_motion_refit.py), if asked for
    adapter_info: Optional[dict] = None   # the style's adapter (teach_adapter.py), if it got one


def check_new_name(name: str, run: RunFolder, replace: bool) -> None:
    """``name`` may join the run: a valid name, new (or ``replace``), and its checkpoint's file
    name (``model-<NAME>.npz`` after :func:`minifilm.files.file_name`) is no other style's, also
    where the names differ only in the characters made safe (``A:B`` and ``A_B``) or in case
    (``Proud`` and ``proud``: one file on macOS and Windows), so no style's checkpoint is replaced."""
    check_name(name, "--name")
    library = run.styles()
    if name in library and not replace:
        raise ValueError(f"--name {name!r}: the run already has a style of that name (--replace to overwrite it)")
    if replace and name not in library:
        raise ValueError(f"--replace: the run has no style {name!r} to replace (its styles: "
                         f"{', '.join(library.names)}); leave out --replace to add a new style")
    mine = same_file_key(checkpoint_path(run, name).name)
    for other in library.names:
        if other != name and same_file_key(checkpoint_path(run, other).name) == mine:
            raise ValueError(f"--name {name!r}: its checkpoint {checkpoint_path(run, name).name} would be the file of "
                             f"the style {other!r} ({checkpoint_path(run, other).name}: names are made safe for "
                             "every file system and compared regardless of case); choose another name")


def checkpoint_path(run: RunFolder, name: str) -> Path:
    """Where the fine-tuned checkpoint of the style ``name`` is kept: RUN/model-<NAME>.npz."""
    return child_path(run.path, f"model-{name}", ".npz")


def read_clip(path, run: RunFolder, log: Callable[[str], None]) -> Motion:
    """One file on the run's skeleton, in metres (a file saved in another unit than the
    skeleton's usual one is read in its own, and said so), at the run's frame rate (resampled, and
    said so)."""
    body = Body(read_bvh(path, scale=1.0))
    if body.motion.n_frames < 2:
        raise ValueError(f"{path}: {body.motion.n_frames} frame: too short to teach a style")
    missing = [n for n in run.layout.joint_names if n not in body.motion.names]
    if missing:      # another rig: retargeted onto the run's skeleton (minifilm/body/retarget_batch.py)
        motion = retarget_onto_run(path, run.path, log)
    else:
        motion, unit = body.on_skeleton(builtin_skeleton(run.skeleton_name))
        if unit is not None:
            log(f"    {Path(path).name}: {unit.how}")
    if abs(motion.fps - run.fps) > 1e-3 * run.fps:
        log(f"    {Path(path).name}: {motion.fps:g} fps resampled to the run's {run.fps:g} fps")
        motion = resample(motion, run.fps)
    return motion


def clip_training_data(motions: Sequence[Motion], files, run: RunFolder, stats, clip_frames: int, name: str,
                       with_mirror: bool = False):
    """TrainData (one style, id 0) of the clips, normalised with the run's statistics, the raw
    start frame (x, p) from the middle of the first file, and the raw rows of each file (and its
    mirror) as (x, p, z) of consecutive frames, for rollouts along the clip (self_fed.py)."""
    skeleton = builtin_skeleton(run.skeleton_name)
    clip_seconds = clip_frames / run.fps
    xs, ps, zs, ys = [], [], [], []
    labelled = [label(motion, skeleton, name) for motion in motions]
    # the clip as a whole must hold locomotion; one file of it may have no step the contact test
    # finds (a fast one-legged hop, a turn on the spot) and still show the style
    if sum(count_strikes(lab.contacts) for lab in labelled) < 2:
        seconds = sum(m.n_frames for m in motions) / run.fps
        where = files[0] if len(files) == 1 else f"{len(files)} files ({', '.join(str(f) for f in files)})"
        raise ValueError(f"{where}: fewer than two foot steps in {seconds:.1f} s (a style is learnt from "
                         "locomotion: walk or run in it for a few steps)")
    for motion, path, labels in zip(motions, files, labelled):
        variants = [(motion, labels)] + ([(mirror(motion), labels.mirrored())] if with_mirror else [])
        for m, lab in variants:
            rows = frame_features(m, skeleton, lab.vectors, lab.contacts, fps=run.fps)
            xs.append(rows.x)
            ps.append(rows.p)
            zs.append(rows.z)
            ys.append(clip_features(m, skeleton, clip_seconds, clip_seconds / 2, fps=run.fps))
    clips = np.concatenate(ys)
    if len(clips) == 0:
        where = str(files[0]) if len(files) == 1 else f"{len(files)} files"
        raise ValueError(f"{where}: " + too_short(max(m.n_frames for m in motions), clip_seconds, run.fps,
                                                 len(files)))
    x, p, z = np.concatenate(xs), np.concatenate(ps), np.concatenate(zs)
    segments = list(zip(xs, ps, zs))
    start = (np.asarray(xs[0][len(xs[0]) // 2], np.float64), np.asarray(ps[0][len(ps[0]) // 2], np.float64))
    f32 = np.float32
    data = TrainData(x=stats.normalize_x(x).astype(f32), p=stats.normalize_p(p).astype(f32),
                     z=stats.normalize_z(z).astype(f32), style=np.zeros(len(x), np.int64),
                     clips=stats.normalize_clip(clips, run.layout.x_joints).astype(f32),
                     clip_style=np.zeros(len(clips), np.int64), style_names=[name])
    return data, start, segments


def teach_style(run_path, name: str, files: Sequence, steps: int = 400, lr: float = 5e-4, seed: int = 0,
                replace: bool = False, log: Callable[[str], None] = print, with_mirror: bool = False,
                self_fed: Optional[SelfFed] = None, motion: Optional[RefitSettings] = None,
                workers: Optional[int] = 1, adapter: AdapterPlan = AdapterPlan()) -> NewStyleResult:
    """Fine-tune the run's Ψ on ``files`` and add ``name`` to its style library (see the module
    docstring). ``self_fed``: rollout-aware rounds after the teacher-forced steps (self_fed.py;
    None, the default: teacher forcing alone, as the paper. On the 90-style runs of
    studies/dense_study.py, SelfFed() lowered the rollout error along the clip by 10-32 % for
    each of five held-out styles but reproduced no more of them on a new path: see
    benchmarks/README.md). ``motion``: then the style's vector is refined by the motion it makes
    (run_motion_refit.py; None or 0 rounds, the default: not), its walks shared by ``workers``
    processes (minifilm/parallel.py; None: every usable core, at most WALK_WORKERS; 1: this one).
    ``adapter``: whether the style gets an adapter of its own (auto: when more than 1 % of the
    clip's input numbers lie beyond 5 σ of the run's data).
    Raises ValueError naming the file or setting that is wrong; the run folder is then untouched.
    The run folder is locked meanwhile: a second command writing it is refused."""
    RunFolder.load(run_path)                    # a run folder at all, before a lock file is made beside it
    with folder_lock(run_path):
        return _teach_style(RunFolder.load(run_path), name, files, steps, lr, seed, replace, log, with_mirror,
                            self_fed, motion if motion is not None and motion.rounds > 0 else None, workers, adapter)


def _teach_style(run: RunFolder, name: str, files: Sequence, steps: int, lr: float, seed: int, replace: bool,
                 log: Callable[[str], None], with_mirror: bool, self_fed: Optional[SelfFed],
                 motion: Optional[RefitSettings], workers: Optional[int], adapter: AdapterPlan) -> NewStyleResult:
    log(f"[finetune] teaching {run.path} the style {name!r} from {len(files)} file(s)")
    check_new_name(name, run, replace)
    if motion is not None and refinable(run):
        raise ValueError(f"--motion-rounds: {refinable(run)}")
    checkpoint = checkpoint_path(run, name)
    written = (checkpoint, run.path / "styles.npz", run.path / "starts.npz", run.path / "adapters.npz",
               run.path / "adapters.json")
    with owned_writes(*written):        # finetune owns these files of the run (minifilm/files/state.py)
        return _teach(run, name, files, steps, lr, seed, log, with_mirror, self_fed, checkpoint, written,
                      motion, workers, adapter)


def _teach(run: RunFolder, name: str, files: Sequence, steps: int, lr: float, seed: int,
           log: Callable[[str], None], with_mirror: bool, self_fed: Optional[SelfFed], checkpoint: Path,
           written, motion: Optional[RefitSettings], workers: Optional[int], plan: AdapterPlan) -> NewStyleResult:
    for path in written:   # before the work
        check_writable(path, f"run folder {run.path}:")
    files = [Path(f) for f in files]
    if not files:
        raise ValueError("no clip given: name one or more BVH files of the new style")
    library = run.styles()
    model, stats = run.model_and_stats()
    motions: List[Motion] = [read_clip(f, run, log) for f in files]
    data, start, segments = clip_training_data(motions, files, run, stats, model.config.clip_frames, name, with_mirror)

    batch = min(32, len(data))
    epochs = max(1, math.ceil(steps / (len(data) // batch)))
    # 4 clips per minibatch, as the main job trains (TrainConfig.clips_per_batch)
    config = TrainConfig(epochs=epochs, batch_size=batch, lr=lr, seed=seed, clips_per_batch=4, progress=False)
    before = Trainer.resume(run.checkpoint, config, restore_optimizer=False).evaluate(data)["loss"]
    t0 = time.perf_counter()
    tuned = finetune(run.checkpoint, data, config=config, style_names=[name])
    rollout_errors = []
    if self_fed is not None and self_fed.rounds > 0:
        log(f"[finetune] {self_fed.rounds} rollout-aware round(s) along the clip")
        rollout_errors = self_fed_rounds(tuned, data, segments, run.layout, stats, self_fed, log)
    seconds = time.perf_counter() - t0
    after = tuned.evaluate(data)["loss"]

    library.add_from_clips(name, tuned.model, data.clips)   # existing styles: stored vectors untouched
    refit = None
    if motion is not None:
        own = segments[::2] if with_mirror else segments       # the clip as recorded, not its mirror
        refit = refine_run_style(run, tuned.model, stats, library[name], {n: library[n] for n in library.names
                                 if n != name}, own, motion, workers, log=lambda m: log("[finetune] " + m))
        library.add(name, refit.film)
    share, worst = input_distance(data.x, run.layout)
    network, cond = RuntimeNetwork.from_model(tuned.model, stats), library[name]
    adapters, adapter_info = _adapters_kept(run, network, library, name), None
    kind = adapter_kind(plan, share > 0.01, 0.0, 0.0)
    if kind is not None:
        own = segments[::2] if with_mirror else segments
        others = {n: library[n] for n in library.names if n != name}
        log(f"[finetune] the clip lies far outside the run's data: a {kind} adapter of its own beside the vector")
        adapters[name], adapter_info = fit_style_adapter(
            tuned.model, network, run.controller, (data.x, data.p, data.z), library[name], others,
            clip_figures(run, own)[0], plan, kind, log=lambda m: log("[finetune] " + m))
        network, cond = AdaptedNetwork(network, [adapters[name]]), adapted_condition(library[name])
    check = rollout_check(run, network, cond, start, segments)
    if adapter_info is not None and check is not None:
        adapter_info.update(steps_per_s=check.steps_per_s, hips=check.hips, toe_on_floor=check.toe_on_floor)
    others = [n for n in library.names if n != name]
    nearest = min(others, key=lambda n: float(np.linalg.norm(library[n] - library[name]))) if others else ""
    # styles.npz last: the new style exists for a reader only once its checkpoint and start are there
    tuned.save(checkpoint)
    starts = run.starts()
    starts[name] = start
    run.save_starts(starts)
    for f in ("adapters.npz", "adapters.json"):      # written anew below (or none left)
        if (run.path / f).exists() and not adapters:
            (run.path / f).unlink()
    write_adapters(run.path, adapters)
    run.save_styles(library)
    return NewStyleResult(name, seconds, tuned.step, len(data), len(data.clips), before, after, nearest, checkpoint,
                          rollout_errors, sum(m.n_frames for m in motions) / run.fps, share, worst, check, refit,
                          adapter_info)


def _adapters_kept(run: RunFolder, network, library, name: str) -> dict:
    """The run's adapters but the one of ``name`` (a style replaced is taught anew)."""
    return {n: a for n, a in run.adapters(network, [n for n in library.names]).items() if n != name}


def shortest_clip_frames(clip_seconds: float, fps: float) -> int:
    """Frames a file needs for one style clip: the window's frames and one more (each frame's
    velocity comes from the frame before it; see ``clip_features_from_arrays``)."""
    return int(seconds_to_frames(clip_seconds, fps)) + 1


def too_short(longest_frames: int, clip_seconds: float, fps: float, n_files: int = 1) -> str:
    """The message for files too short for one style clip: the real minimum and what they have."""
    need = shortest_clip_frames(clip_seconds, fps)
    which = "the longest file has" if n_files > 1 else "the file has"
    return (f"too short for one style clip: the model reads {clip_seconds:g} s windows, which need at least "
            f"{need} frames ({need / fps:.3f} s at {fps:g} fps, the window and one frame before it); "
            f"{which} {longest_frames} ({longest_frames / fps:.3f} s)")


def rollout_check(run: RunFolder, network, film, start, segments, seconds: float = 6.0):
    """The new style (``film``: its condition for ``network``) walked straight ahead at the clip's
    speed from its start frame: a WalkReport against the clip's steps per second and hip height."""
    toes = toe_joints(run.layout.joint_names)                 # [right, left]
    if toes is None:
        return None
    speed, clip_steps, clip_hips = clip_figures(run, segments)
    ctrl = run.controller(network)
    n = int(round(seconds * run.fps))
    r = ctrl.run(CommandScript([(0.0, speed, 0.0, 0.0), (seconds, speed, 0.0, 0.0)]), n, film,
                 phases=start[1][None], start_x=start[0])
    path = np.array([[0.0, 0.0], [0.0, 2 * speed * seconds]])
    return walk_report(r, 0, toes, path,
                       clip_steps_per_s=clip_steps, clip_hips=clip_hips)
