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
              style classifier recognises each style in it, and pictures of it (GIF, HTML player).

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
from minifilm.files import atomic_directory, file_names, folder_lock
from minifilm.evaluation.style_classifier import classify_rollout, train_style_classifier
from minifilm.model.config import ModelConfig
from minifilm.model.style_model import StyleModel
from minifilm.motion.bvh import bvh_duration, read_bvh
from minifilm.motion.bvh_write import write_bvh
from minifilm.motion.skeletons import STYLE100, builtin_skeleton
from minifilm.phases.label import label
from minifilm.pipeline.run_folder import RunFolder, is_run_entry
from minifilm.runtime.control import make_script
from minifilm.runtime.controller import (Controller, NonFiniteOutputError, root_joint_indices,
                                         start_from_dataset)
from minifilm.runtime.network import RuntimeNetwork
from minifilm.runtime.style_library import StyleLibrary
from minifilm.synthetic import generator as synthetic
from minifilm.train.trainer import TrainConfig, Trainer
from minifilm.viewer.builders import tracks_from_rollout
from minifilm.viewer.deps import pyplot, save_figure
from minifilm.viewer.gif import write_gif
from minifilm.viewer.html import write_html


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
    # 3e-4 and 5e-4 keep them alive (benchmarks/trained_rollout.py; the paper uses 1e-4 for its 40x
    # larger network)
    learning_rate: float = 5e-4
    lr_schedule: str = "constant"        # or "cosine" (TrainConfig.lr_schedule)
    clips_per_batch: Optional[int] = 4   # None: one style clip per sample, as the paper (benchmarks/clip_sharing.py)
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
    mirror: bool = False                 # also train on the left/right mirror of every file
    fps: Optional[float] = None          # your own data: resample every file to this rate (None: as recorded)

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
def train(ds, out: Path, s: Settings) -> Trainer:
    """Train the small LPN + FiLM model, one line per epoch; checkpoint after every epoch."""
    layout = ds.layout
    train_data, val_data = ds.train_data("train"), ds.train_data("val")
    config = ModelConfig.small(layout.x_dim, layout.z_dim, train_data.clips.shape[1], layout.clip_dim,
                               phase_dim=layout.phase_dim, **s.model)
    model = StyleModel(config, np.random.default_rng(s.seed))
    trainer = Trainer(model, ds.stats,
                      TrainConfig(epochs=s.epochs, batch_size=s.batch_size, lr=s.learning_rate, seed=s.seed,
                                  lr_schedule=s.lr_schedule, clips_per_batch=s.clips_per_batch,
                                  checkpoint_path=str(out / "model.npz")),
                      positions_idx=layout.joint_columns("z", "position"), parents=np.asarray(layout.parents),
                      style_names=ds.styles)
    n_params = sum(p.size for p in model.parameter_sets())
    log(f"[train] {n_params:,} parameters; {len(train_data)} training / {len(val_data)} validation frames; "
        f"clips {train_data.clips.shape[1]} x {layout.clip_dim}")
    log(f"    {'epoch':>5} {'train MSE':>10} {'train BLL':>10} {'val MSE':>9} {'val BLL':>9} {'time':>7}")
    for epoch in range(1, s.epochs + 1):
        t0 = time.perf_counter()
        trainer.fit(train_data, val_data, epochs=epoch)
        rec = trainer.history[-1]
        log(f"    {epoch:>5} {rec['train']['mse']:>10.4f} {rec['train']['bll']:>10.4f} "
            f"{rec['val']['mse']:>9.4f} {rec['val']['bll']:>9.4f} {time.perf_counter() - t0:>6.1f}s")
    return trainer


# ---- 5. results -----------------------------------------------------------------------------------
def test_table(trainer: Trainer, ds) -> dict:
    """Test MSE per style (normalised units) against predicting the training mean (which is 0 in
    normalised units, so its MSE is the mean squared normalised target)."""
    test = ds.train_data("test")
    result = trainer.evaluate(test)
    log("[test] MSE per style, normalised units (predict-the-mean baseline in brackets):")
    log(f"    {'style':<14} {'model':>8} {'baseline':>9}")
    baselines = []
    for s, name in enumerate(ds.styles):
        rows = test.style == s
        if not np.any(rows):
            continue
        base = float(np.mean(test.z[rows].astype(np.float64) ** 2))
        baselines.append(base)
        log(f"    {name:<14} {result['per_style'][name]['mse']:>8.4f} {base:>9.4f}")
    log(f"    {'mean':<14} {result['mse']:>8.4f} {np.mean(baselines):>9.4f}")
    return result


def save_loss_curve(history, path: Path, shown: Optional[Path] = None) -> None:
    """The training and validation losses per epoch as a PNG at ``path`` (``shown``: the path to
    print, when the file is written in a run still being built)."""
    try:
        plt = pyplot()
    except ImportError as e:
        log(f"[plot] no loss curve: {e}")
        return
    epochs = [r["epoch"] for r in history]
    fig, ax = plt.subplots(figsize=(6, 4))
    for split, style in (("train", "-"), ("val", "--")):
        ax.plot(epochs, [r[split]["mse"] for r in history], style, color="C0", label=f"{split} MSE")
        ax.plot(epochs, [r[split]["bll"] for r in history], style, color="C1", label=f"{split} BLL")
    ax.set_xlabel("epoch")
    ax.set_ylabel("loss (normalised units)")
    ax.set_yscale("log")
    ax.legend()
    ax.set_title("minifilm train_small: LPN + FiLM")
    fig.tight_layout()
    save_figure(fig, path, dpi=100)
    log(f"[plot] loss curve saved to {shown or path}")


def style_library(trainer: Trainer, ds) -> StyleLibrary:
    """One FiLM vector per style: Ψ averaged over the style's training clips (Sec. 4.4)."""
    train_data = ds.train_data("train")
    library = StyleLibrary()
    for s, name in enumerate(ds.styles):
        library.add_from_clips(name, trainer.model, train_data.clips[train_data.clip_style == s])
    return library


def generate_per_style(trainer: Trainer, ds, run: RunFolder, library: StyleLibrary, template, seconds: float,
                       shown: Optional[Path] = None):
    """One BVH per style from the autoregressive runtime (Sec. 4.4): a figure-eight path, the motion
    put back on the source skeleton. Each style starts in mid-stride from a frame of its own forward
    walk (pose, trajectory and phases): from the data's mean pose a network this small may never
    get going. The files are ``generated/<style>.bvh`` in ``run``, named safely after the styles
    (minifilm/files/names.py); ``shown`` is the run folder to print."""
    network = RuntimeNetwork.from_model(trainer.model, trainer.stats)
    # every frame is put on the source skeleton (rigid bones); the network keeps seeing its own
    # prediction (fed back, the fitted pose made small models stop stepping more often:
    # benchmarks/trained_rollout.py --fit)
    joints = root_joint_indices(ds.layout, template)
    controller = Controller(network, ds.layout, fps=ds.fps, skeleton=Controller.skeleton_for(ds.layout, template),
                            position_bias=run.position_bias)
    n_frames = int(round(seconds * ds.fps))
    out = run.path / "generated"
    out.mkdir(exist_ok=True)
    files = file_names(ds.styles)
    starts = run.starts()
    log(f"[generate] {seconds:g} s per style along a figure-eight:")
    rollouts = {}
    for name in ds.styles:
        script = make_script("figure8", seconds)
        start_x, phases = starts[name]
        try:
            rollout = controller.run(script, n_frames, library[name], phases=phases, start_x=start_x)
        except NonFiniteOutputError:     # an under-trained model: say so, and go on with the others
            log(f"    {name:<14} diverged (the network's output became non-finite); no BVH written")
            continue
        path = out / f"{files[name]}.bvh"
        write_bvh(rollout.to_motion(template, joints), path, scale=run.bvh_scale)
        path = (shown or run.path) / "generated" / path.name
        hips = rollout.positions[0, :, 0, 1]
        speed = np.linalg.norm(np.diff(rollout.root_positions[0], axis=0), axis=1).mean() * ds.fps
        log(f"    {name:<14} hips {hips.mean():.2f} m  speed {speed:.2f} m/s   -> {path}")
        rollouts[name] = rollout
    return rollouts


def style_recognition(ds, rollouts: dict, seed: int = 0) -> dict:
    """How well the generated motion carries each style: the fraction of 0.75 s windows of each
    style's generated motion (after its first second) that a style classifier trained on the
    run's own data recognises as that style (minifilm/evaluation/style_classifier.py). Its
    accuracy on the data's held-out rows is the ceiling."""
    t0 = time.perf_counter()
    classifier, info = train_style_classifier(ds, seed=seed)
    per_style = {}
    for name, rollout in rollouts.items():
        probs = classify_rollout(classifier, ds, rollout, window=info["window"], stride=info["stride"])[0]
        per_style[name] = float(np.mean(probs.argmax(axis=1) == ds.styles.index(name))) if len(probs) else float("nan")
    scored = [v for v in per_style.values() if np.isfinite(v)]       # a style too short for one window has none
    mean = float(np.mean(scored)) if scored else float("nan")
    def score(v: float) -> str:  # a run too short for one window has no score, not "nan"
        return f"{v:.2f}" if np.isfinite(v) else "n/a (too short for one window)"

    log(f"[style] recognition of each style's generated motion by a classifier trained on the data "
        f"(held-out real windows: {score(info['heldout_acc'])}; {time.perf_counter() - t0:.1f} s):")
    for name, acc in per_style.items():
        log(f"    {name:<14} {score(acc)}")
    log(f"    mean style recognition {score(mean)}")
    return {"per_style": per_style, "mean": mean, "heldout": info["heldout_acc"]}


def show_styles(rollouts: dict, layout, out: Path, gif_seconds: float = 6.0, shown: Optional[Path] = None) -> None:
    """See the result: every style's generated motion side by side in an animated GIF (the first
    ``gif_seconds``) and in the offline HTML player (all of it), written into ``out`` (``shown``:
    the folder to print)."""
    shown = shown or out
    names = list(rollouts)
    if not names:
        log("[view] no generated motion to show")
        return
    toes = [layout.joint_names.index(t) for t in ("RightToe", "LeftToe")] if "RightToe" in layout.joint_names else None
    tracks = [tracks_from_rollout(rollouts[n], layout.parents, [n], layout.joint_names, toes)[0] for n in names]
    write_html(tracks, out / "index.html", title="minifilm: generated styles")
    log(f"[view] every style in a 3-D player (opens offline in a browser): {shown / 'index.html'}")
    try:
        write_gif(tracks, out / "styles.gif", seconds=gif_seconds, size=(200, 250))
        log(f"[view] every style side by side, first {gif_seconds:g} s: {shown / 'styles.gif'}")
    except ImportError as e:
        log(f"[view] no GIF: {e}")


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
    unknown = [x for x in s.styles if x not in synthetic.STYLES] + [g for g in s.gaits if g not in synthetic.GAITS]
    if unknown:
        raise InputError(f"unknown synthetic styles or gaits {unknown}; styles are {', '.join(synthetic.STYLES)}, "
                         f"gaits {', '.join(synthetic.GAITS)}")
    if not s.styles or not [g for g in s.gaits if g != "ID"]:
        raise InputError("--styles / --gaits: give at least one style and one gait that is not idle (ID)")


def prepare_data(s: Settings, data: Optional[Path], out: Path):
    """The synthetic files (with their phase check) unless ``data`` is given, then the dataset
    (cached in ``out``/cache)."""
    own_data = data is not None
    if data is None:
        data = out / "data"
        clips = make_synthetic(data, s.styles, s.gaits, s.seconds_per_clip, s.seed)
        phase_accuracy(clips)
    t0 = time.perf_counter()
    extra = {} if not own_data else data_settings(data, s)
    ds = build_dataset(data, cache_dir=out / "cache", progress=True, clip_seconds=s.clip_seconds,
                       clip_stride_seconds=s.clip_seconds / 2, seed=s.seed, **extra)
    log(f"[dataset] built in {time.perf_counter() - t0:.1f} s")
    log(ds.summary())
    empty = [name for name in ("val", "test") if len(getattr(ds, name)) == 0]
    if empty:   # nothing to validate or test on: say so now, not after training
        raise DataError(f"{data}: the {' and '.join(empty)} split(s) have no frames: "
                        + ("with whole files per split (--split files) every style needs at least three files; "
                           if extra.get("split_unit") == "files" else "the files are too short to split; ")
                        + "give more or longer files, or use --split segments")
    return ds


def run(s: Settings, data: Optional[Path] = None) -> dict:
    """The whole main job; returns the test result (MSE per style) with the style recognition
    of the generated motion under 'recognition'.

    The run is built in a new folder beside ``s.out`` and swapped in whole when it is complete
    (minifilm/files/atomic.py), with the folder locked meanwhile (minifilm/files/lock.py): an
    earlier run there stays whole and usable until then, whatever stops this one (an error,
    Ctrl-C, SIGTERM, SIGKILL), and a second command writing the same folder is refused."""
    check_inputs(s, data)          # before the run folder is touched
    out = Path(s.out)
    t_start = time.perf_counter()
    with folder_lock(out), atomic_directory(out, "run folder", replaceable=is_run_entry) as work:
        reuse_cache(out / "cache", work / "cache")
        ds = prepare_data(s, data, work)
        trainer = train(ds, work, s)
        trainer.save(work / "model.npz")
        log(f"[train] checkpoint (model, optimiser, normalisation statistics) saved to {out / 'model.npz'}")
        result = test_table(trainer, ds)
        save_loss_curve(trainer.history, work / "loss_curve.png", shown=out / "loss_curve.png")

        skeleton = builtin_skeleton(ds.skeleton)
        template = read_bvh(ds.files[0]["path"], scale=skeleton.bvh_scale)   # the source skeleton, its own units
        folder = RunFolder.prepare(work, ds.layout, ds.fps, ds.skeleton, skeleton.bvh_scale, template,
                                   s.position_bias)
        library = style_library(trainer, ds)
        library.save(work / "styles.npz")
        folder.save_starts({name: start_from_dataset(ds, name) for name in ds.styles})
        rollouts = generate_per_style(trainer, ds, folder, library, template, s.generate_seconds, shown=out)
        result["recognition"] = style_recognition(ds, rollouts, s.seed)
        show_styles(rollouts, ds.layout, work / "generated", min(6.0, s.generate_seconds), shown=out / "generated")
        folder.commit()
    log(f"[done] {time.perf_counter() - t_start:.0f} s in all; outputs in {out}")
    return result


def reuse_cache(old: Path, new: Path) -> None:
    """Link the dataset caches of the run being replaced into the new one (a cache of your own
    data takes a while to build); the old run's files stay as they are."""
    if not old.is_dir():
        return
    new.mkdir(parents=True, exist_ok=True)
    for f in old.glob("dataset-*.npz"):
        with contextlib.suppress(OSError):
            os.link(f, new / f.name)
