"""Teaching the released network, tested where the answer is known: re-fit its own styles.

    python benchmarks/teach_released.py                   # 10 styles (every 10th), 30 s each
    python benchmarks/teach_released.py --styles Neutral Old --seconds 10

Each style walks a figure-eight for --seconds in its own vector; that motion is taught back with
the style's vector hidden (the prior is made of the other 99) and the hidden vector's rank among
the 100 is printed three ways (minifilm/pipeline/refit_released.py): by distance in FiLM space,
by how close its predictions are to the fitted vector's on held-out rows, and by loss (a check of
the labels). Also the teaching time and whether the fitted style walks. --json writes the rows.
"""
from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from minifilm.pipeline.refit_released import generated_motions, refit  # noqa: E402
from minifilm.runtime.released import load_released  # noqa: E402
from minifilm.train.film_fit import FitSettings  # noqa: E402

REPO = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--params", type=Path, default=REPO.parent / "shared" / "data" / "released-lpn")
    ap.add_argument("--styles", nargs="*", help="style names (default every 10th of the network's)")
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--prior-weights", type=float, nargs="+", default=[0.3, 1.0, 3.0],
                    help="one fit per weight, the rollouts choose (default: finetune's 0.3 1 3)")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    rel = load_released(args.params)
    names = args.styles or list(rel.styles)[::10]
    t0 = time.perf_counter()
    motions = generated_motions(rel, names, args.seconds)
    print(f"{len(names)} styles walked {args.seconds:g} s each in {time.perf_counter() - t0:.0f} s", flush=True)
    rows = []
    print(f"{'style':16s} {'film rank':>9s} {'output rank':>11s} {'loss rank':>9s}  nearest (film / output)   "
          f"{'teach s':>7s}  steps/s (clip)  walks")
    for name, motion in zip(names, motions):
        r = refit(rel, name, motion, FitSettings(steps=args.steps), prior_weights=tuple(args.prior_weights))
        rows.append(r)
        print(f"{name:16s} {r['film_rank']:9d} {r['output_rank']:11d} {r['loss_rank']:9d}  "
              f"{r['nearest_film']} / {r['nearest_output']:12s} {r['seconds']:7.1f}  "
              f"{r['steps_per_s']:.2f} ({r['clip_steps_per_s']:.2f})  {r['walks']}", flush=True)
    for key in ("film_rank", "output_rank", "loss_rank"):
        ranks = np.array([r[key] for r in rows])
        print(f"{key}: rank 1 for {int(np.sum(ranks == 1))} of {len(rows)} (median rank {np.median(ranks):g})")
    print(f"teaching time: median {np.median([r['seconds'] for r in rows]):.1f} s per {args.seconds:g} s clip; "
          f"load {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
