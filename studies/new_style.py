"""A new style from a short clip, on real motion capture (the paper's Sec. 5.3.2 / Figure 11).

    python studies/new_style.py                            # one style held out, 3 epochs (~4 min)
    python studies/new_style.py --all --epochs 30          # every style held out in turn, the main job's training

On the Bandai-Namco-2 data (5 styles, 30 fps): hold one style out, train the main job's model on
the other four with ``minifilm train``'s pipeline (whole files to train / val / test), then teach
the run the held-out style from at most 30 s of it with ``minifilm finetune``'s code (Ψ alone).
Reported per held-out style (one seed each):

* the whole training pipeline's time, and each trained style's recognition in its generated motion
  (the main job's classifier, trained on the run's data);
* the fine-tuning time;
* the new style's recognition in its generated motion (10 s along a figure-eight), by a classifier
  trained on the run's data plus the held-out style's other files (never the fine-tuning clip);
* the silhouette of the new style's FiLM codes among all styles' (the fine-tuned Ψ on every
  training clip of the five styles; the held-out style's clips from its other files);
* whether a trained style's generated motion is bit-identical before and after fine-tuning.
"""
from __future__ import annotations

import argparse
import csv
import os
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")     # before numpy: as minifilm train does
os.environ.setdefault("OMP_NUM_THREADS", "1")
ROOT = Path(__file__).resolve().parents[1]

import time  # noqa: E402
from dataclasses import replace  # noqa: E402

import numpy as np  # noqa: E402

from minifilm.dataset.build import build_dataset  # noqa: E402
from minifilm.dataset.manifest import bandai_files  # noqa: E402
from minifilm.evaluation.compare_tools import film_codes, film_separation  # noqa: E402
from minifilm.evaluation.style_classifier import classify_rollout, train_style_classifier  # noqa: E402
from minifilm.motion.bvh import bvh_duration  # noqa: E402
from minifilm.pipeline.new_style import teach_style  # noqa: E402
from minifilm.pipeline.run_folder import RunFolder  # noqa: E402
from minifilm.pipeline.train_small import Settings, run as train_run  # noqa: E402
from minifilm.runtime.control import figure_eight  # noqa: E402
from minifilm.train.checkpoint import build_style_model, load_checkpoint, load_model_arrays  # noqa: E402

DATA = Path(os.environ.get("MINIFILM_SHARED_DATA", ROOT.parent / "shared" / "data"))


def write_manifest(files, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["file", "style", "gait"])
        for m in files:
            w.writerow([str(Path(m.path).resolve()), m.style, m.gait])
    return path


def clip_files(files, seconds: float):
    """Walk files of the held-out style, in name order, up to ``seconds`` of motion in all."""
    walks = sorted((f for f in files if f.gait == "walk"), key=lambda f: Path(f.path).name) or sorted(
        files, key=lambda f: Path(f.path).name)
    chosen, total = [], 0.0
    for f in walks:
        d = bvh_duration(f.path)
        if total + d > seconds and chosen:
            break
        chosen.append(f)
        total += d
    return chosen, total


def rollout(run: RunFolder, style: str, seconds: float = 10.0):
    x0, p0 = run.start_states([style])
    n = int(round(seconds * run.fps))
    return run.controller().run(figure_eight(seconds), n, run.styles()[style], phases=p0, start_x=x0)


def one(holdout: str, files, a, s: Settings) -> dict:
    work = a.work / holdout
    seen = [f for f in files if f.style != holdout]
    held = [f for f in files if f.style == holdout]
    clip, clip_seconds = clip_files(held, a.clip_seconds)
    run_dir = work / "run"
    t0 = time.perf_counter()
    result = train_run(replace(s, out=run_dir), write_manifest(seen, work / "seen.csv"))
    train_seconds = time.perf_counter() - t0
    run = RunFolder.load(run_dir)
    trained = result["recognition"]["per_style"]
    probe = sorted(trained)[0]
    before = rollout(run, probe).positions

    t0 = time.perf_counter()
    taught = teach_style(run_dir, holdout, [f.path for f in clip], log=lambda m: None)
    finetune_seconds = time.perf_counter() - t0
    run = RunFolder.load(run_dir)
    identical = bool(np.array_equal(before, rollout(run, probe).positions))

    # a classifier of all five styles: the run's data plus the held-out style's other files
    clip_paths = {str(Path(f.path).resolve()) for f in clip}
    rest = [f for f in files if str(Path(f.path).resolve()) not in clip_paths]
    ds = build_dataset(write_manifest(rest, work / "all_but_clip.csv"), cache_dir=work / "cache", progress=False,
                       clip_seconds=s.clip_seconds, clip_stride_seconds=s.clip_seconds / 2, seed=s.seed,
                       split_unit="files")
    classifier, info = train_style_classifier(ds, seed=s.seed)
    probs = classify_rollout(classifier, ds, rollout(run, holdout), window=info["window"], stride=info["stride"])[0]
    recognised = float(np.mean(probs.argmax(axis=1) == ds.styles.index(holdout)))

    # FiLM codes of every training clip of the five styles, by the fine-tuned Ψ
    meta, arrays = load_checkpoint(taught.checkpoint)
    tuned = build_style_model(meta)
    load_model_arrays(tuned, arrays, taught.checkpoint)
    _, stats = run.model_and_stats()
    clips = stats.normalize_clip(ds.train.clips, ds.layout.x_joints).astype(np.float32)
    codes = film_codes(tuned, clips)
    sep = film_separation(codes, ds.train.clip_style, focus=ds.styles.index(holdout))
    return {"holdout": holdout, "train_s": train_seconds, "trained": trained, "finetune_s": finetune_seconds,
            "clip_s": clip_seconds, "clip_files": len(clip), "new": recognised, "silhouette": sep["focus_silhouette"],
            "identical": identical, "heldout_acc": info["heldout_acc"]}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=DATA / "bandai2", help="a Bandai-Namco folder")
    ap.add_argument("--holdout", default="feminine", help="the held-out style (without --all)")
    ap.add_argument("--all", action="store_true", help="hold out every style in turn")
    ap.add_argument("--epochs", type=int, default=3, help="training epochs (the main job's: 30)")
    ap.add_argument("--clip-seconds", type=float, default=30.0, help="at most this much of the new style")
    ap.add_argument("--work", type=Path, default=Path("runs/new_style"))
    a = ap.parse_args()
    files = bandai_files(a.data)
    styles = sorted({f.style for f in files})
    s = replace(Settings(), epochs=a.epochs, generate_seconds=10.0)
    print(f"# {a.data}: {len(files)} files, styles {styles}; {a.epochs} epochs; BLAS threads "
          f"{os.environ.get('OPENBLAS_NUM_THREADS')}; load {os.getloadavg()[0]:.2f}", flush=True)
    rows = []
    for holdout in (styles if a.all else [a.holdout]):
        r = one(holdout, files, a, s)
        rows.append(r)
        print(f"{holdout}: training {r['train_s']:.0f} s, trained styles recognised "
              f"{min(r['trained'].values()):.2f}-{max(r['trained'].values()):.2f}; fine-tuning on {r['clip_s']:.1f} s "
              f"({r['clip_files']} files) {r['finetune_s']:.1f} s; new style recognised {r['new']:.2f}; "
              f"silhouette {r['silhouette']:.2f}; trained style bit-identical {r['identical']}; "
              f"load {os.getloadavg()[0]:.2f}", flush=True)
    print("\n| held out | training (whole pipeline) | trained styles recognised (min) | fine-tuning | "
          "new style recognised | new style's FiLM silhouette | trained styles bit-identical |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['holdout']} | {r['train_s'] / 60:.1f} min | {min(r['trained'].values()):.2f} | "
              f"{r['finetune_s']:.0f} s ({r['clip_s']:.0f} s of clip) | {r['new']:.2f} | {r['silhouette']:.2f} | "
              f"{'yes' if r['identical'] else 'NO'} |")


if __name__ == "__main__":
    main()
