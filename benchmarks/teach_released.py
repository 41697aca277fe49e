"""Teaching the released network, tested where the answer is known: re-fit its own styles.

    python benchmarks/teach_released.py                   # 10 styles (every 10th), 30 s each
    python benchmarks/teach_released.py --styles Neutral Old --seconds 10

Each style walks a figure-eight for --seconds in its own vector; that motion is taught back with
the style's vector hidden (the prior is made of the other 99; then, as ``finetune`` does, the fit
is refined by the motion it makes for --motion-rounds rounds) and the hidden vector's rank among
the 100 is printed three ways (minifilm/pipeline/refit_released.py): by distance in FiLM space,
by how close its predictions are to the fitted vector's on held-out rows, and by loss (a check of
the labels). Also the teaching time and whether the fitted style walks. --json writes the rows.

Then by motion (unless --judge-seconds 0; minifilm/pipeline/judge_taught.py): every fitted vector
and the 100 released walk --judge-seconds straight at 1.3 m/s in one batch, and each fitted
style's motion (second half) is ranked by Fréchet distance among the released styles' motion
(first halves) and classified by --seeds classifiers trained on it. And why the FiLM distance
cannot find the style (minifilm/pipeline/refit_released.py, ``sensitivity``): how many of the
2,048 directions carry the output's sensitivity, and how much of the fit's error lies in them.
--fitted NPZ keeps the fitted vectors; given an existing file, only the motion is judged again.
"""
from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from minifilm.features.layout import FeatureLayout  # noqa: E402
from minifilm.motion.skeletons import STYLE100  # noqa: E402
from minifilm.pipeline.judge_taught import judge_refits  # noqa: E402
from minifilm.pipeline.motion_refit import RefitSettings  # noqa: E402
from minifilm.pipeline.refit_released import generated_motions, refit  # noqa: E402
from minifilm.runtime.released import load_released  # noqa: E402
from minifilm.train.film_fit import FitSettings  # noqa: E402

REPO = Path(__file__).resolve().parents[1]


def refit_settings(text: str, **fields) -> RefitSettings:
    """finetune's refinement settings with ``fields`` and the fields ``text`` names ('key=value,...',
    the --motion option here and in teach_real_clips.py) changed."""
    for item in filter(None, text.split(",")):
        key, value = item.split("=")
        fields[key.strip()] = type(getattr(RefitSettings, key.strip()))(value)
    return RefitSettings(**fields)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--params", type=Path, default=REPO.parent / "shared" / "data" / "released-lpn")
    ap.add_argument("--styles", nargs="*", help="style names (default every 10th of the network's)")
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--prior-weights", type=float, nargs="+", default=[0.3, 1.0, 3.0],
                    help="one fit per weight, the rollouts choose (default: finetune's 0.3 1 3)")
    ap.add_argument("--motion-rounds", type=int, default=RefitSettings.rounds,
                    help="rounds of refining each fit by the motion it makes, as finetune does (0: the "
                         "teacher-forced fit alone, as before; minifilm/pipeline/motion_refit.py)")
    ap.add_argument("--motion", default="", help="other settings of the refinement, e.g. 'population=32,elite=8' "
                                                 "(RefitSettings' fields; default: finetune's)")
    ap.add_argument("--judge-seconds", type=float, default=20.0, help="rollout judged by motion (0: skip)")
    ap.add_argument("--seeds", type=int, default=3, help="classifier seeds (the minimum recognition counts)")
    ap.add_argument("--fitted", type=Path, help="an .npz of the fitted vectors: written, or if it exists read "
                                                "(then only the motion is judged)")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    rel = load_released(args.params)
    names = args.styles or list(rel.styles)[::10]
    if args.fitted and args.fitted.is_file():
        with np.load(args.fitted, allow_pickle=False) as f:
            fitted = {str(n): f["films"][i] for i, n in enumerate(f["names"])}
        print(f"fitted vectors of {len(fitted)} styles read from {args.fitted}")
        by_motion(rel, fitted, args)
        return
    t0 = time.perf_counter()
    motions = generated_motions(rel, names, args.seconds)
    print(f"{len(names)} styles walked {args.seconds:g} s each in {time.perf_counter() - t0:.0f} s", flush=True)
    rows = []
    print(f"{'style':16s} {'film rank':>9s} {'output rank':>11s} {'loss rank':>9s}  nearest (film / output)   "
          f"{'teach s':>7s}  steps/s (clip)  walks")
    for name, motion in zip(names, motions):
        r = refit(rel, name, motion, FitSettings(steps=args.steps), prior_weights=tuple(args.prior_weights),
                  by_motion=refit_settings(args.motion, rounds=args.motion_rounds) if args.motion_rounds > 0 else None)
        rows.append(r)
        print(f"{name:16s} {r['film_rank']:9d} {r['output_rank']:11d} {r['loss_rank']:9d}  "
              f"{r['nearest_film']} / {r['nearest_output']:12s} {r['seconds']:7.1f}  "
              f"{r['steps_per_s']:.2f} ({r['clip_steps_per_s']:.2f})  {r['walks']}", flush=True)
    for key in ("film_rank", "output_rank", "loss_rank"):
        ranks = np.array([r[key] for r in rows])
        print(f"{key}: rank 1 for {int(np.sum(ranks == 1))} of {len(rows)} (median rank {np.median(ranks):g})")
    print("why the FiLM distance misleads: directions (of 2,048) holding 90 % / 99 % of the output's sensitivity, "
          "share of the fit's error in the 99 % ones, RMS output change per unit FiLM distance along the error / "
          "towards the nearest other style / median direction / top direction")
    for r in rows:
        v = r["sensitivity"]
        print(f"{r['style']:16s} {v['k90']:4d} / {v['k99']:4d}   {v['error_share_in_k99']:5.1%}   {v['gain_error']:.3f} / "
              f"{v['gain_other']:.3f} ({r['nearest_other']}) / {v['gain_median']:.4f} / {v['gain_top']:.3f}")
    print(f"teaching time: median {np.median([r['seconds'] for r in rows]):.1f} s per {args.seconds:g} s clip; "
          f"load {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    fitted = {r["style"]: np.asarray(r.pop("film"), np.float32) for r in rows}
    if args.fitted:
        np.savez(args.fitted, names=np.array(list(fitted)), films=np.stack(list(fitted.values())))
    judged = by_motion(rel, fitted, args)
    for r in rows:
        r["by_motion"] = judged.get(r["style"])
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))


def by_motion(rel, fitted: dict, args) -> dict:
    """Rank and recognition of each fitted style's motion among the released styles' motion."""
    if args.judge_seconds <= 0:
        return {}
    t0 = time.perf_counter()
    j = judge_refits(rel, FeatureLayout.for_skeleton(STYLE100), fitted, seconds=args.judge_seconds,
                     seeds=range(args.seeds))
    print(f"by motion ({args.judge_seconds:g} s straight at 1.3 m/s, {time.perf_counter() - t0:.0f} s): released "
          f"styles ranking themselves first {j['released_self']}/100, their minimum recognition median "
          f"{j['released_recognition_min']:.2f}")
    print(f"{'style':16s} {'Fréchet rank':>12s}  nearest by Fréchet            recognised min (seeds)   classifiers pick")
    for name, r in j["fitted"].items():
        near = ", ".join(f"{n} {d:.0f}" for n, d in r["nearest"][:2])
        seeds = ", ".join(f"{x:.2f}" for x in r["recognition"])
        picked = ", ".join(f"{n} {s:.0%}" for n, s in r["picked"][:2])
        print(f"{name:16s} {r['rank']:12d}  {near:28s} {r['recognition_min']:.2f} ({seeds})  {picked}", flush=True)
    ranks = np.array([r["rank"] for r in j["fitted"].values()])
    rec = np.array([r["recognition_min"] for r in j["fitted"].values()])
    print(f"by motion: Fréchet rank 1 for {int(np.sum(ranks == 1))} of {len(ranks)}; recognised >= 0.8 (minimum over "
          f"{args.seeds} seeds) for {int(np.sum(rec >= 0.8))} of {len(rec)}")
    return j["fitted"]


if __name__ == "__main__":
    main()
