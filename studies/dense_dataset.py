"""How long `minifilm dataset --from-released` takes: wall and CPU time for some styles, extrapolated to 100.

    python studies/dense_dataset.py                          # 10 styles x 60 s (the default size)
    python studies/dense_dataset.py --styles 100             # the whole data set
    python studies/dense_dataset.py --styles 10 --no-label-check

Writes into a temporary folder (deleted). Prints wall and CPU seconds (the rollout runs on one BLAS
thread, so CPU seconds are what an idle core would take when the machine is shared), the load, and a
linear extrapolation to 100 styles from the per-style cost (an upper bound: batching more styles
into one network call makes each cheaper).
"""
from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from minifilm.pipeline.from_released import ReleasedDataSettings, make_released_dataset  # noqa: E402
from minifilm.runtime.released import load_released  # noqa: E402

SHARED = Path(os.environ.get("MINIFILM_SHARED_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--params", type=Path, default=SHARED / "released-lpn")
    ap.add_argument("--styles", type=int, default=10, help="how many styles (the first N, evenly spread)")
    ap.add_argument("--seconds-per-style", type=float, default=60.0)
    ap.add_argument("--no-label-check", action="store_true")
    a = ap.parse_args()
    names = list(load_released(a.params).styles)
    step = max(1, len(names) // a.styles)
    chosen = names[::step][:a.styles]
    s = ReleasedDataSettings(seconds_per_style=a.seconds_per_style, styles=chosen, check_labels=not a.no_label_check)
    load0 = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        w0, c0 = time.perf_counter(), time.process_time()
        make_released_dataset(a.params, Path(tmp) / "data", s, log=lambda m: print("  " + m, flush=True))
        wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    n = len(chosen)
    print(f"{n} styles x {a.seconds_per_style:g} s: wall {wall:.0f} s, CPU {cpu:.0f} s (load {load0:.1f} -> "
          f"{os.getloadavg()[0]:.1f}); 100 styles extrapolated linearly: wall {wall / n * 100 / 60:.1f} min, "
          f"CPU {cpu / n * 100 / 60:.1f} min")


if __name__ == "__main__":
    main()
