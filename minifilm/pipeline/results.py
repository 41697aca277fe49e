"""Step 5 of the main job: what a trained run shows (used by pipeline/train_small.py and
examples/train_small.py).

    test_table          test MSE per style against predicting the mean (normalised units)
    save_loss_curve     loss_curve.png (matplotlib, loaded only here)
    style_library       one FiLM vector per style: Ψ averaged over the style's clips (Sec. 4.4)
    generate_per_style  one BVH per style from the autoregressive runtime along a figure-eight
    style_recognition   how well a style classifier recognises each style in that motion
    show_styles         every style side by side: an animated GIF and the offline HTML player

The viewer and the evaluation code are imported inside the functions that use them, so importing
the job does not load them before the results are drawn.
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import Optional

import numpy as np

from minifilm.files import file_names
from minifilm.motion.bvh_write import write_bvh
from minifilm.pipeline.run_folder import RunFolder
from minifilm.runtime.control import make_script
from minifilm.runtime.controller import Controller, NonFiniteOutputError
from minifilm.runtime.held_body import toe_joints
from minifilm.runtime.start_state import root_joint_indices
from minifilm.runtime.network import RuntimeNetwork
from minifilm.runtime.style_library import StyleLibrary
from minifilm.train.trainer import Trainer


def log(msg: str = "") -> None:
    print(msg, flush=True)


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
    from minifilm.viewer.deps import pyplot, save_figure      # the viewer loads only when drawing
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
    from minifilm.evaluation.style_classifier import classify_rollout, train_style_classifier  # loaded when used
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
    # the viewer loads only when the pictures are drawn (not when the job is imported)
    from minifilm.viewer.builders import tracks_from_rollout
    from minifilm.viewer.gif import write_gif
    from minifilm.viewer.html import write_html
    shown = shown or out
    names = list(rollouts)
    if not names:
        log("[view] no generated motion to show")
        return
    toes = toe_joints(layout.joint_names)
    tracks = [tracks_from_rollout(rollouts[n], layout.parents, [n], layout.joint_names, toes)[0] for n in names]
    write_html(tracks, out / "index.html", title="minifilm: generated styles")
    log(f"[view] every style in a 3-D player (opens offline in a browser): {shown / 'index.html'}")
    try:
        write_gif(tracks, out / "styles.gif", seconds=gif_seconds, size=(200, 250))
        log(f"[view] every style side by side, first {gif_seconds:g} s: {shown / 'styles.gif'}")
    except ImportError as e:
        log(f"[view] no GIF: {e}")
