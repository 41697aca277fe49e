"""Building a data set in worker processes (build_dataset's map over the files, minifilm/parallel.py):
wall time, CPU time / wall time and speed-up of ``minifilm dataset DIR --no-cache --workers W`` for
W = 1 and 2.

    python benchmarks/dataset_build.py                    # the Bandai-Namco-2 folder, each count once
    python benchmarks/dataset_build.py --repeats 2        # each count twice, interleaved (1, 2, 1, 2)
    python benchmarks/dataset_build.py --files 60         # only the first 60 files (a quick look)
    python benchmarks/dataset_build.py --data DIR         # another folder (or a .csv manifest)

Each build is the command as a user runs it, in a process of its own (start-up, survey, labelling,
statistics; no cache read or written), with one BLAS thread in every process (the command's own
setting, which its workers inherit). A row's wall time is
the least of its repeats (the run the machine's other load disturbed least); CPU is the user +
system time of the command and its workers (getrusage of the waited-for children), so CPU / wall
near 2 means two cores were busy. The data set's summary table must be the same for every count:
the script stops if it is not. The load average and the CPU are printed: on a shared machine the
other jobs' load decides how much a second worker can gain.
"""
from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from machine import autogroup, cpu_name, load

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("MINIFILM_SHARED_DATA", ROOT.parent / "shared" / "data"))


def uptime() -> str:
    try:
        return subprocess.run(["uptime"], capture_output=True, text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return load()


def build(source: Path, workers: int) -> tuple[float, float, str]:
    """(wall s, CPU s, the data set's summary table) of one ``minifilm dataset`` run."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "minifilm", "dataset", str(source), "--no-cache", "--workers",
                        str(workers)], capture_output=True, text=True, cwd=ROOT)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode != 0:
        raise SystemExit(f"minifilm dataset --workers {workers} failed:\n{r.stderr[-2000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, r.stdout.split("rows (frames", 1)[-1]


def first_files(source: Path, n: int, into: Path) -> Path:
    """A folder of links to the first ``n`` BVH files of ``source`` (sorted by name)."""
    for p in sorted(source.glob("*.bvh"))[:n]:
        os.symlink(p, into / p.name)
    return into


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=DATA / "bandai2", help="a folder of BVH files or a manifest "
                    "(default: the shared Bandai-Namco-2 folder)")
    ap.add_argument("--files", type=int, help="only the first N files of the folder")
    ap.add_argument("--repeats", type=int, default=1, help="runs of each worker count (the least time counts)")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        source = first_files(a.data, a.files, Path(tmp)) if a.files else a.data
        n_files = len(list(Path(source).glob("*.bvh"))) if Path(source).is_dir() else "?"
        print(f"# {cpu_name()}; {os.cpu_count()} logical CPUs, {len(os.sched_getaffinity(0))} usable; {autogroup()}")
        print(f"# {a.data.name}{f' (first {a.files} files)' if a.files else ''}: {n_files} files; "
              f"`minifilm dataset DIR --no-cache --workers W`, one BLAS thread per process")
        print(f"# before: {uptime()}")
        runs = {1: [], 2: []}
        tables = set()
        for _ in range(a.repeats):
            for w in runs:
                wall, cpu, table = build(source, w)
                tables.add(table)
                runs[w].append((wall, cpu))
                print(f"#   {w} worker{'s' if w > 1 else ''}: {wall:.1f} s wall, {cpu:.1f} s CPU; then {load()}",
                      flush=True)
        if len(tables) != 1:
            raise SystemExit("the data sets differ between worker counts")
        print(f"# after: {uptime()}")
        one = min(runs[1])[0]
        print("\n| workers | wall s (least of {}) | all runs s | CPU s | CPU / wall | speed-up |".format(a.repeats))
        print("|---|---|---|---|---|---|")
        for w, r in runs.items():
            wall, cpu = min(r)
            print(f"| {w} | {wall:.1f} | {', '.join(f'{x:.1f}' for x, _ in r)} | {cpu:.1f} | {cpu / wall:.2f} | "
                  f"{one / wall:.2f}x |")
        print("\nthe data set is the same for both counts (its summary table compared)")


if __name__ == "__main__":
    main()
