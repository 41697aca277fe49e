"""Clip sharing (TrainConfig.clips_per_batch): training time and quality for 1, 4 and 32 clips per batch.

    python studies/clip_sharing.py                   # a short version (4 epochs each, ~4 min)
    python studies/clip_sharing.py --epochs 20       # the length the choice was made at (~20 min)

The original code pairs every sample of a minibatch with its own style clip, so Ψ runs on 32
clips per step (the paper does not say); minibatches hold one style, so a few clips of it could
serve the whole batch and Ψ would run on those only. For each setting (1, 4 clips per batch, and
32: one clip per sample, the original) this trains the main job's model on the main job's synthetic data (one BLAS
thread) and reports:

* seconds per epoch and test MSE (normalised units, every style weighted equally);
* style recognition of generated motion: 10 s of every style along a figure-eight, the fraction of
  0.75 s windows a style classifier trained on the data recognises as that style; the mean
  distance to the path and the number of styles still stepping;
* FiLM-code separation: the silhouette of Ψ(clip) of every training clip, grouped by style;
* a held-out style: the model trained without ``--holdout`` (default Drunk), then Ψ alone
  fine-tuned on it with the same clip setting; the silhouette of the held-out style's codes
  among all styles, before and after.
"""
from __future__ import annotations

import argparse
import math
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")    # before numpy: one BLAS thread, as the main job
os.environ.setdefault("OMP_NUM_THREADS", "1")

import time  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from minifilm.dataset.build import build_dataset  # noqa: E402
from minifilm.evaluation.compare_tools import film_codes, film_separation, fit_stats, style_subset  # noqa: E402
from minifilm.evaluation.style_classifier import classify_rollout, train_style_classifier  # noqa: E402
from minifilm.model.config import ModelConfig  # noqa: E402
from minifilm.model.style_model import StyleModel  # noqa: E402
from minifilm.pipeline.train_small import Settings, make_synthetic  # noqa: E402
from minifilm.runtime.control import figure_eight  # noqa: E402
from minifilm.runtime.controller import Controller  # noqa: E402
from minifilm.runtime.start_state import start_from_dataset  # noqa: E402
from minifilm.runtime.network import RuntimeNetwork  # noqa: E402
from minifilm.train.finetune import finetune  # noqa: E402
from minifilm.train.trainer import TrainConfig, Trainer  # noqa: E402


def new_trainer(ds, data, s: Settings, clips, seed, names, stats):
    L = ds.layout
    cfg = ModelConfig.small(L.x_dim, L.z_dim, data.clips.shape[1], L.clip_dim, phase_dim=L.phase_dim, **s.model)
    tc = TrainConfig(epochs=s.epochs, batch_size=s.batch_size, lr=s.learning_rate, seed=seed,
                     clips_per_batch=clips, lr_schedule=s.lr_schedule, progress=False)
    return Trainer(StyleModel(cfg, np.random.default_rng(seed)), stats, tc, L.joint_columns("z", "position"),
                   np.asarray(L.parents), style_names=names)


def rollouts(trainer, ds, seconds=10.0):
    """Every style along a figure-eight in one batch, as the main job generates it."""
    tr = ds.train_data("train")
    films = np.stack([film_codes(trainer.model, tr.clips[tr.clip_style == i]).mean(axis=0)
                      for i in range(len(ds.styles))])
    net = RuntimeNetwork.from_model(trainer.model, trainer.stats)
    ctl = Controller(net, ds.layout, fps=ds.fps, position_bias=Settings().position_bias)
    x0, p0 = (np.stack(a) for a in zip(*(start_from_dataset(ds, n) for n in ds.styles)))
    n = int(round(seconds * ds.fps))
    scripts = [figure_eight(seconds) for _ in ds.styles]
    return ctl.run(scripts, n, films, phases=p0, start_x=x0), scripts[0].path


def quality(trainer, ds, classifier, info):
    r, path = rollouts(trainer, ds)
    probs = classify_rollout(classifier, ds, r, window=info["window"], stride=info["stride"])
    hits = probs.argmax(axis=2) == np.arange(len(ds.styles))[:, None]
    metrics = r.metrics(ds.layout.parents, path)
    k0 = int(round(ds.fps))
    stepping = sum(float(r.phases[b, k0:, 4:8].std(axis=0).min()) > 0.2 for b in range(len(ds.styles)))
    return {"recognition": hits.mean(axis=1), "path": float(np.mean([m["path_mean"] for m in metrics])),
            "stepping": stepping}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--epochs", type=int, default=4, help="training epochs per model (the main job: 30)")
    ap.add_argument("--clips", default="1,4,32", help="clips per batch to compare; 32 = one per sample (the original)")
    ap.add_argument("--holdout", default="Drunk", help="the style held out for the fine-tuning test")
    ap.add_argument("--finetune-steps", type=int, default=300)
    ap.add_argument("--work", type=Path, default=Path("runs/clip_sharing"))
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--lr-schedule", choices=("constant", "cosine"), default="constant")
    a = ap.parse_args()
    s = replace(Settings(seed=a.seed), epochs=a.epochs, lr_schedule=a.lr_schedule)
    data_dir = a.work / "data"
    if not any(data_dir.glob("*.bvh")):
        make_synthetic(data_dir, s.styles, s.gaits, s.seconds_per_clip, s.seed)
    ds = build_dataset(data_dir, cache_dir=a.work / "cache", progress=False, clip_seconds=s.clip_seconds,
                       clip_stride_seconds=s.clip_seconds / 2, seed=s.seed)
    classifier, info = train_style_classifier(ds, seed=a.seed)
    tr, test = ds.train_data("train"), ds.train_data("test")
    seen = [n for n in ds.styles if n != a.holdout]
    seen_stats = fit_stats(ds, seen)
    seen_train = style_subset(ds, "train", seen, seen_stats)
    new_train = style_subset(ds, "train", [a.holdout], seen_stats)
    all_train = style_subset(ds, "train", seen + [a.holdout], seen_stats)
    print(f"# {len(ds.styles)} styles, {len(tr)} training frames, {len(tr.clips)} clips of "
          f"{tr.clips.shape[1]} frames; {a.epochs} epochs; classifier held-out accuracy {info['heldout_acc']:.2f}; "
          f"BLAS threads {os.environ.get('OPENBLAS_NUM_THREADS')}; load {os.getloadavg()[0]:.2f}", flush=True)
    rows = []
    for text in a.clips.split(","):
        clips = int(text)
        setting = None if clips >= s.batch_size else clips          # 32: one clip per sample, the original
        trainer = new_trainer(ds, tr, s, setting, a.seed, ds.styles, ds.stats)
        t0 = time.perf_counter()
        trainer.fit(tr)
        epoch_s = (time.perf_counter() - t0) / a.epochs
        mse = trainer.evaluate(test)["mse"]
        q = quality(trainer, ds, classifier, info)
        sep = film_separation(film_codes(trainer.model, tr.clips), tr.clip_style)["silhouette"]
        # the held-out style: train on the others, fine-tune Ψ alone on it
        held = new_trainer(ds, seen_train, s, setting, a.seed, seen, seen_stats)
        held.fit(seen_train)
        path = a.work / f"held_{clips}.npz"
        held.save(path)
        per_epoch = max(1, len(new_train) // s.batch_size)
        ft_cfg = TrainConfig(epochs=max(1, math.ceil(a.finetune_steps / per_epoch)), batch_size=s.batch_size,
                             lr=s.learning_rate, seed=a.seed + 1, clips_per_batch=setting, progress=False)
        ft = finetune(path, new_train, config=ft_cfg, style_names=[a.holdout])
        focus = len(seen)
        before = film_separation(film_codes(held.model, all_train.clips), all_train.clip_style, focus)
        after = film_separation(film_codes(ft.model, all_train.clips), all_train.clip_style, focus)
        rows.append((clips, epoch_s, mse, q, sep, before["focus_silhouette"], after["focus_silhouette"]))
        print(f"clips/batch {clips:>2}: {epoch_s:5.1f} s/epoch, test MSE {mse:.4f}, recognition "
              f"{q['recognition'].mean():.2f} (min {q['recognition'].min():.2f}), path {q['path']:.2f} m, "
              f"stepping {q['stepping']}/{len(ds.styles)}, FiLM silhouette {sep:.2f}, held-out {a.holdout} "
              f"{before['focus_silhouette']:.2f} -> {after['focus_silhouette']:.2f}; load {os.getloadavg()[0]:.2f}",
              flush=True)
    print("\n| clips per batch | s / epoch | test MSE | recognition (mean / min) | path m | stepping | "
          "FiLM silhouette | held-out style silhouette before -> after fine-tuning |")
    print("|---|---|---|---|---|---|---|---|")
    for clips, epoch_s, mse, q, sep, b, f in rows:
        print(f"| {clips}{' (the original)' if clips >= s.batch_size else ''} | {epoch_s:.1f} | {mse:.4f} | "
              f"{q['recognition'].mean():.2f} / {q['recognition'].min():.2f} | {q['path']:.2f} | "
              f"{q['stepping']}/{len(ds.styles)} | {sep:.2f} | {b:.2f} -> {f:.2f} |")


if __name__ == "__main__":
    main()
