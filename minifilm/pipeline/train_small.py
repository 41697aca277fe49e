"""The main job: the whole method, end to end, on data minifilm makes itself (or on yours).

    minifilm train                      # synthetic data, default settings (= python examples/train_small.py)
    minifilm train --data DIR           # your own folder of <Style>_<Gait>.bvh files, or a CSV manifest
    minifilm train --quick              # a smaller, faster run of the same steps

Steps (each prints what it did):
 1. data:     generate the synthetic stylised locomotion set (8 styles x 6 gaits, 100STYLE skeleton,
              60 fps) and write it as BVH files, so it flows through the same pipeline as real data;
 2. phases:   measure local-phase extraction against the generator's true phases (Sec. 4.1);
 3. dataset:  read the BVH files, detect contacts, extract local phases, build x / p / z / clips,
              split 80/10/10 per file, normalise (Sec. 3.2);
 4. training: a small LPN + FiLM model (Eq. 1-7) with style-balanced minibatches (Sec. 4.3);
 5. results:  test error per style against the predict-the-mean baseline, a loss-curve PNG, one
              generated BVH per style made by the autoregressive runtime (Sec. 4.4), how well a
              style classifier recognises each style in it, and pictures of it (GIF, HTML player)
              (results.py).

``run`` is ``with main_job(...) as job`` (steps 1-3, the locked run folder built aside and swapped
in at the end), ``train`` (step 4: the Trainer's epochs) and ``finish`` (step 5);
examples/train_small.py uses ``main_job``, ``new_trainer`` and ``finish`` too, and shows step 4's epochs.

Everything is written to the run folder --out (default runs/train_small; see run_folder.py):
data/, model.npz (checkpoint with the normalisation statistics), styles.npz (FiLM vector per
style), starts.npz, skeleton.bvh, run.json, loss_curve.png, generated/*.bvh, and the pictures of the
result: generated/styles.gif (every style side by side) and generated/index.html (a 3-D player).
"""
from __future__ import annotations

import contextlib
import os
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Optional, Tuple

import numpy as np

from minifilm.dataset.build import build_dataset, resolve_files
from minifilm.errors import DataError, InputError
from minifilm.files import atomic_directory, few, folder_lock
from minifilm.model.config import ModelConfig
from minifilm.model.style_model import StyleModel
from minifilm.motion.bvh import bvh_duration, read_bvh
from minifilm.motion.skeletons import STYLE100, builtin_skeleton
from minifilm.phases.label import label
from minifilm.body.read import Body
from minifilm.body.retarget_batch import retarget_files
from minifilm.pipeline.run_folder import RunFolder, is_run_entry
from minifilm.pipeline.run_rig import load_target
from minifilm.pipeline.results import (generate_per_style, save_loss_curve, show_styles,  # noqa: F401
                                       style_library, style_recognition, test_table)
from minifilm.runtime.start_state import start_from_dataset
from minifilm.synthetic import generator as synthetic
from minifilm.train import mpi
from minifilm.train.trainer import TrainConfig, Trainer


@dataclass
class Settings:
    """The main job's settings (the numbers were measured, see each comment)."""

    seed: int = 0
    out: Path = Path("runs/train_small")
    styles: Tuple[str, ...] = tuple(synthetic.STYLES)   # Neutral, PendulumHands, LeftHop, Limp, ...
    seconds_per_clip: float = 10.0       # synthetic seconds per style and gait
    gaits: Tuple[str, ...] = ("FW", "BW", "FR", "SW", "TR", "ID")   # idle files are skipped, as in 100STYLE
    clip_seconds: float = 2.0            # style clip y fed to the FiLM generator (paper: 4 s)
    # 30: with 4 clips per batch an epoch takes 3-4 s, and 30 epochs gave test MSE 0.048 against
    # 0.054 after 20, style recognition 1.00, every style stepping and 0.21 m from the path over
    # 60 s (benchmarks/trained_rollout.py), in about two minutes; a cosine learning-rate decay over
    # 20 epochs was worse (MSE 0.058, recognition 0.89), so the rate stays constant
    epochs: int = 30
    batch_size: int = 32
    # 1e-3 kills the ReLUs of the FiLM generator Ψ within 12 epochs (all of conv1's, most of its
    # dense layer's), so several styles get the same FiLM vector (its bias) and share one motion;
    # 3e-4 and 5e-4 keep them alive (benchmarks/trained_rollout.py; the paper uses 1e-4 for its 62x
    # larger network)
    learning_rate: float = 5e-4
    lr_schedule: str = "constant"        # or "cosine" (TrainConfig.lr_schedule)
    input_noise: float = 0.0             # TrainConfig.input_noise (0: none, the paper)
    clips_per_batch: Optional[int] = 4   # None: one style clip per sample, as the original (studies/clip_sharing.py)
    model: dict = field(default_factory=dict)   # overrides of ModelConfig.small
    generate_seconds: float = 10.0       # length of each generated BVH
    # weight of the user's trajectory in the near future samples (the demo's 0.75 suits the
    # released network; a small model's own trajectory drifts more: with 2 the mean distance to a
    # figure-eight over 60 s fell from 0.31-3.9 m to 0.20-0.85 m across five trained models)
    position_bias: float = 2.0
    # your own data (--data): "files" sends whole files to train / val / test (per style), "segments"
    # cuts every file 80/10/10; "auto" picks files when the median file is under 20 s (a 10 %
    # window of a short file is shorter than the 2 s trajectory window of the features)
    split: str = "auto"
    # PAPER: Sec. 3.2 adds the mirrors of the symmetric styles. Nothing is mirrored by default: the
    # synthetic set can simply be made longer; --mirror mirrors every file of your own data (a
    # manifest's mirror column chooses file by file)
    mirror: bool = False                 # also train on the left/right mirror of every file
    fps: Optional[float] = None          # your own data: resample every file to this rate (None: as recorded)
    rig: Optional[str] = None            # your own data: retarget every file onto this rig first (docs/retargeting.md)
    # processes labelling the files of the data set (concurrent.futures; None: every core this process
    # may use, 1: in this process). Training runs in this process, or across the ranks of mpiexec
    # (minifilm/train/mpi.py). The data set is the same for any number.
    workers: Optional[int] = None

    def quick(self) -> "Settings":
        """A much smaller run of every step (seconds instead of minutes)."""
        return replace(self, seconds_per_clip=6.0, gaits=("FW", "FR", "TR"), epochs=2, generate_seconds=2.0,
                       model=dict(self.model, hidden=32, conv_filters=8, film_dense=32))


def log(msg: str = "") -> None:
    print(msg, flush=True)


# ---- 1. data --------------------------------------------------------------------------------------
def make_synthetic(out: Path, styles, gaits, seconds: float, seed: int):
    """Generate and write the synthetic set; returns the clips (with their true phases)."""
    t0 = time.perf_counter()
    clips = synthetic.default_dataset(seed=seed, seconds=seconds, styles=styles, gaits=gaits)
    synthetic.write_dataset(out, clips)
    frames = sum(c.motion.n_frames for c in clips)
    log(f"[data] {len(clips)} synthetic files ({len(styles)} styles x {len(gaits)} gaits, "
        f"{frames} frames at 60 fps) written to {out} in {time.perf_counter() - t0:.1f} s")
    return clips


# ---- 2. phase accuracy ----------------------------------------------------------------------------
def circular_error(a, b):
    """|a - b| on the unit circle of cycles, in [0, 0.5]."""
    d = np.abs(a - b) % 1.0
    return np.minimum(d, 1.0 - d)


def phase_accuracy(clips):
    """Median circular error (cycles) of the extracted local phases per end effector, over the frames
    where the generator says the limb really oscillates; feet split by source (contact / PCA)."""
    errors = {}
    for c in clips:
        labels = label(c.motion, STYLE100, c.style)
        sources = labels.sources
        err = circular_error(labels.phases.phase, c.true_phase)
        for slot, name in enumerate(("left hand", "right hand", "left foot", "right foot")):
            key = f"{name} ({sources[slot]})"
            errors.setdefault(key, []).append(err[c.phase_active[:, slot], slot])
    log("[phases] median circular error against the generator's true phases (cycles):")
    table = {}
    for key, parts in errors.items():
        e = np.concatenate(parts)
        table[key] = float(np.median(e)) if len(e) else float("nan")
        log(f"    {key:<24} {table[key]:.4f}   ({len(e)} frames)")
    return table


# ---- 4. training ----------------------------------------------------------------------------------
def new_trainer(job: "Job") -> Trainer:
    """The small LPN + FiLM model (Ω, Φ, Ψ) and its Trainer (Adam, the random generator, the history,
    a checkpoint after every epoch on rank 0); prints the [train] header. Under mpiexec every rank
    builds the same model from the same seed, and the Trainer shares each minibatch among them."""
    ds, s = job.ds, job.settings
    layout = ds.layout
    train_data, val_data = ds.train_data("train"), ds.train_data("val")
    config = ModelConfig.small(layout.x_dim, layout.z_dim, train_data.clips.shape[1], layout.clip_dim,
                               phase_dim=layout.phase_dim, **s.model)
    model = StyleModel(config, np.random.default_rng(s.seed))
    trainer = Trainer(model, ds.stats,
                      TrainConfig(epochs=s.epochs, batch_size=s.batch_size, lr=s.learning_rate, seed=s.seed,
                                  lr_schedule=s.lr_schedule, clips_per_batch=s.clips_per_batch,
                                  input_noise=s.input_noise, progress=False if job.work is None else None,
                                  checkpoint_path=None if job.work is None else str(job.work / "model.npz")),
                      positions_idx=layout.joint_columns("z", "position"), parents=np.asarray(layout.parents),
                      style_names=ds.styles, ranks=job.ranks)
    if job.work is not None:
        n_params = sum(p.size for p in model.parameter_sets())
        where = ("this process" if job.ranks is None else
                 f"{job.ranks.size} MPI ranks, each minibatch split among them")
        log(f"[train] {n_params:,} parameters; {len(train_data)} training / {len(val_data)} validation frames; "
            f"clips {train_data.clips.shape[1]} x {layout.clip_dim}; training in {where}")
        log(f"    {'epoch':>5} {'train MSE':>10} {'train BLL':>10} {'val MSE':>9} {'val BLL':>9} {'time':>7}")
    return trainer


def log_epoch(job: "Job", record: dict, seconds: float) -> None:
    """One line per epoch (rank 0): training and validation losses, and the epoch's time."""
    if job.work is not None:
        log(f"    {record['epoch']:>5} {record['train']['mse']:>10.4f} {record['train']['bll']:>10.4f} "
            f"{record['val']['mse']:>9.4f} {record['val']['bll']:>9.4f} {seconds:>6.1f}s")


def train(job: "Job") -> Trainer:
    """Train the small LPN + FiLM model, one line per epoch; checkpoint after every epoch
    (examples/train_small.py spells out the same epochs, minibatch by minibatch)."""
    trainer = new_trainer(job)
    train_data, val_data = job.ds.train_data("train"), job.ds.train_data("val")
    for _ in range(job.settings.epochs):
        t0 = time.perf_counter()
        record = trainer.end_epoch(trainer.train_epoch(train_data), val_data)
        log_epoch(job, record, time.perf_counter() - t0)
    return trainer


def data_settings(data: Path, s: Settings) -> dict:
    """Dataset settings for the user's own data: the split unit and mirroring (see Settings)."""
    split = s.split
    if split == "auto":
        files = resolve_files(data)
        median = float(np.median([bvh_duration(f.path) for f in files]))
        per_style = min(sum(f.style == style for f in files) for style in {f.style for f in files})
        # whole files only when each style can give one to validation and one to test
        split = "files" if median < 20.0 and per_style >= 3 else "segments"
        why = f"median file {median:.1f} s, at least {per_style} file(s) per style"
        log(f"[dataset] {why}: {'whole files' if split == 'files' else 'segments of every file'} "
            f"go to train / val / test (--split to choose)")
    return {"split_unit": split, "mirror_styles": ("*",) if s.mirror else (), "fps": s.fps}


def check_inputs(s: Settings, data: Optional[Path]) -> None:
    """InputError for settings that cannot make a run, before anything is written: unknown or no
    synthetic styles / gaits, only idle gaits, or a --data that is not a folder of BVH files or a
    manifest (resolve_files names what is wrong)."""
    if data is not None:
        resolve_files(data)
        return
    own_data_only = [name for name, value in (("split", s.split != "auto"), ("mirror", s.mirror),
                                              ("fps", s.fps is not None), ("rig", s.rig is not None)) if value]
    if own_data_only:
        raise InputError(f"{', '.join(own_data_only)}: only with your own data (the synthetic set is made "
                         "at 60 fps, split 80/10/10 and not mirrored)")
    unknown = [x for x in s.styles if x not in synthetic.STYLES] + [g for g in s.gaits if g not in synthetic.GAITS]
    if unknown:
        raise InputError(f"unknown synthetic styles or gaits {unknown}; styles are {', '.join(synthetic.STYLES)}, "
                         f"gaits {', '.join(synthetic.GAITS)}")
    if not s.styles or not [g for g in s.gaits if g != "ID"]:
        raise InputError("--styles / --gaits: give at least one style and one gait that is not idle (ID)")


def prepare_data(s: Settings, data: Optional[Path], out: Path, executor=None):
    """The synthetic files (with their phase check) unless ``data`` is given, then the dataset
    (cached in ``out``/cache); its files labelled by ``executor`` (a concurrent.futures executor)
    when given, else by ``s.workers`` processes."""
    own_data = data is not None
    if data is None:
        data = out / "data"
        clips = make_synthetic(data, s.styles, s.gaits, s.seconds_per_clip, s.seed)
        phase_accuracy(clips)
    t0 = time.perf_counter()
    extra = {} if not own_data else data_settings(data, s)
    named = data                            # the user's folder or manifest, for messages
    if own_data and s.rig is not None:      # a folder of mixed rigs: every file onto one rig first
        data = retarget_files(resolve_files(data), load_target(s.rig), out / "data", log)
    ds = build_dataset(data, cache_dir=out / "cache", progress=True, clip_seconds=s.clip_seconds,
                       clip_stride_seconds=s.clip_seconds / 2, seed=s.seed,
                       workers=s.workers if executor is None else executor, **extra)
    log(f"[dataset] {'loaded from its cache' if ds.loaded else 'built'} in {time.perf_counter() - t0:.1f} s")
    log(ds.summary())
    empty = [name for name in ("val", "test") if len(getattr(ds, name)) == 0]
    if empty:   # nothing to validate or test on: say so now, not after training
        raise DataError(f"{named}: the {' and '.join(empty)} split(s) have no frames: "
                        + ("with whole files per split (--split files) every style needs at least three files; "
                           if extra.get("split_unit") == "files" else "the files are too short to split; ")
                        + "give more or longer files, or use --split segments")
    return ds


@dataclass
class Job:
    """The main job under way: its settings, the data folder (None: synthetic), the run folder
    ``out``, the folder ``work`` the run is built in (swapped in for ``out`` when complete; None on
    the ranks of mpiexec other than 0, which write nothing), the dataset, the time it started and
    the MPI ranks (None: one process)."""

    settings: Settings
    data: Optional[Path]
    out: Path
    work: Optional[Path]
    ds: object
    t_start: float
    ranks: object = None


@contextlib.contextmanager
def main_job(s: Settings, data: Optional[Path] = None, ranks=None):
    """Steps 1-3 (check the settings, make the synthetic data with its phase check unless ``data``
    is given, build the dataset), then the body of the ``with`` block (training and ``finish``).

    The run is built in a new folder beside ``s.out`` and swapped in whole when the block ends
    without an error (minifilm/files/atomic.py), with the folder locked meanwhile
    (minifilm/files/lock.py): an earlier run there stays whole and usable until then, whatever
    stops this one (an error, Ctrl-C, SIGTERM, SIGKILL), and a second command writing the same
    folder is refused. Under mpiexec (``ranks``, minifilm/train/mpi.py) rank 0 alone does all of
    this, the other ranks labelling files for it, and every rank gets the data set. Yields a
    :class:`Job`."""
    out = Path(s.out)
    t_start = time.perf_counter()
    work = None
    with contextlib.ExitStack() as stack:
        def steps_1_to_3(executor=None):
            nonlocal work
            check_inputs(s, data)          # before the run folder is touched
            stack.enter_context(folder_lock(out))
            work = stack.enter_context(atomic_directory(out, "run folder", replaceable=is_run_entry))
            say_replaced(out)
            reuse_cache(out / "cache", work / "cache")
            return prepare_data(s, data, work, executor)
        ds = steps_1_to_3() if ranks is None else ranks.from_rank0(steps_1_to_3)
        yield Job(s, data, out, work, ds, t_start, ranks)
    if work is not None:
        log(f"[done] {time.perf_counter() - t_start:.0f} s in all; outputs in {out}")


def finish(job: Job, trainer: Trainer) -> dict:
    """Step 5: checkpoint, test table, loss curve, style library, generated motion, style
    recognition, pictures, written into the run being built (printed with the run folder's
    paths). Returns the test result (MSE per style) with the style recognition under
    'recognition'. Nothing on the ranks of mpiexec other than 0 (None)."""
    ds, out, work, s = job.ds, job.out, job.work, job.settings
    if work is None:
        return None
    trainer.save(work / "model.npz")
    log(f"[train] checkpoint (model, optimiser, normalisation statistics) saved to {out / 'model.npz'}")
    result = test_table(trainer, ds)
    save_loss_curve(trainer.history, work / "loss_curve.png", shown=out / "loss_curve.png")

    skeleton = builtin_skeleton(ds.skeleton)
    template, _ = Body(read_bvh(ds.files[0]["path"], scale=1.0)).on_skeleton(skeleton)   # the source skeleton, in metres
    folder = RunFolder.prepare(work, ds.layout, ds.fps, ds.skeleton, skeleton.bvh_scale, template,
                               s.position_bias)
    library = style_library(trainer, ds)
    folder.save_styles(library)
    folder.save_starts({name: start_from_dataset(ds, name) for name in ds.styles})
    rollouts = generate_per_style(trainer, ds, folder, library, template, s.generate_seconds, shown=out)
    result["recognition"] = style_recognition(ds, rollouts, s.seed)
    show_styles(rollouts, ds.layout, work / "generated", min(6.0, s.generate_seconds), shown=out / "generated")
    folder.commit()
    return result


def run(s: Settings, data: Optional[Path] = None, ranks=None) -> dict:
    """The whole main job (``minifilm train``); returns the test result (MSE per style) with the
    style recognition of the generated motion under 'recognition' (None on ranks other than 0)."""
    with mpi.one_job(ranks), main_job(s, data, ranks) as job:
        result = finish(job, train(job))
    return result


def say_replaced(out: Path) -> None:
    """Say that ``out`` holds a run which this one replaces when complete, and the styles taught
    to it (``finetune --run``) that go with it."""
    if (out / "run.json").is_file():
        taught = sorted(p.name for p in out.glob("model-*.npz"))
        log(f"[train] {out} holds an earlier run: it stays as it is until this one is complete, which then "
            "replaces it" + (f" with the {len(taught)} style(s) taught to it ({few(taught)})" if taught else ""))


def reuse_cache(old: Path, new: Path) -> None:
    """Link the dataset caches of the run being replaced into the new one (a cache of your own
    data takes a while to build); the old run's files stay as they are."""
    if not old.is_dir():
        return
    new.mkdir(parents=True, exist_ok=True)
    for f in old.glob("dataset-*.npz"):
        with contextlib.suppress(OSError):
            os.link(f, new / f.name)
