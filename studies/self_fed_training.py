"""Rollout-aware training of a whole run (minifilm/pipeline/self_fed_training.py), written as a new run folder.

    python studies/self_fed_training.py --run W/run --out W2/run --rounds 3
    python studies/dense_study.py --trained T --held H --work W2 --reuse-run ...   # measured as any run

The run's checkpoint is resumed (its Adam state too) and trained on for ``--rounds`` rounds on its
own training rows and the rows its rollouts along them visit; the style library is rebuilt from the
new Ψ. The source run is only read.
"""
from __future__ import annotations

import argparse
import os
import shutil
import time
from dataclasses import replace
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

from minifilm.dataset.dataset import Dataset  # noqa: E402
from minifilm.pipeline.results import style_library, test_table  # noqa: E402
from minifilm.pipeline.self_fed import SelfFed  # noqa: E402
from minifilm.pipeline.self_fed_training import self_fed_training  # noqa: E402
from minifilm.train.trainer import Trainer  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--run", type=Path, required=True, help="a trained run folder (minifilm train)")
    ap.add_argument("--out", type=Path, required=True, help="the new run folder (must not exist)")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--horizon", type=int, default=60, help="frames per rollout")
    ap.add_argument("--every", type=int, default=60, help="a rollout starts every so many frames of a file")
    ap.add_argument("--control", action="store_true", help="the same rounds on the training rows alone "
                    "(as many more teacher-forced steps), to tell the gathered rows' effect from more training")
    a = ap.parse_args()
    if a.out.exists():
        raise SystemExit(f"--out {a.out}: exists; give a new folder")
    settings = SelfFed(rounds=a.rounds, horizon=a.horizon, every=a.every)
    caches = sorted((a.run / "cache").glob("dataset-*.npz"))
    if not caches:
        raise SystemExit(f"{a.run}: no dataset cache (cache/dataset-*.npz)")
    ds = Dataset.load(caches[0])
    trainer = Trainer.resume(a.run / "model.npz")
    trainer.config = replace(trainer.config, checkpoint_path=None, progress=False)
    t0, c0 = time.perf_counter(), time.process_time()
    errors = self_fed_training(trainer, ds, settings, aggregate=not a.control)
    took, cpu = time.perf_counter() - t0, time.process_time() - c0
    tmp = a.out.with_name(a.out.name + ".partial")
    if tmp.exists():
        shutil.rmtree(tmp)
    shutil.copytree(a.run, tmp, ignore=shutil.ignore_patterns("model-*.npz", "*.lock", "generated"))
    trainer.save(tmp / "model.npz")
    style_library(trainer, ds).save(tmp / "styles.npz")
    tmp.rename(a.out)
    test_table(trainer, ds)
    print(f"[self-fed training] {a.rounds} rounds in {took:.0f} s ({cpu:.0f} CPU s, load {os.getloadavg()[0]:.1f}); "
          f"rollout error {' -> '.join(f'{e * 100:.2f}' for e in errors)} cm; new run {a.out}")


if __name__ == "__main__":
    main()
