"""How long does reading (and writing) a 5 MB BVH file take?

Builds a ~5 MB file by repeating the frames of a real file (default: the largest file under
../shared/data/bandai2, 132 channels per frame), then times ``read_bvh`` and ``write_bvh``
(best of several runs) and prints a table.

    python benchmarks/bvh_read.py [source.bvh] [--mb 5] [--repeat 5]
"""
import argparse
import os
import re
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

from minifilm.motion.bvh import read_bvh  # noqa: E402
from minifilm.motion.bvh_write import write_bvh

DATA = Path(os.environ.get("MINIFILM_SHARED_DATA", ROOT.parent / "shared" / "data"))


def tiled_copy(source: Path, target: Path, megabytes: float) -> int:
    """Write ``source``'s header plus its frames repeated up to ``megabytes``; returns the frame count."""
    text = source.read_text()
    head, rest = re.split(r"(?im)^\s*frames\s*:.*$", text, maxsplit=1)
    lines = [line for line in rest.split("\n") if line.strip()]
    frame_time, frames = lines[0], lines[1:]
    block = "\n".join(frames) + "\n"
    copies = max(1, int(megabytes * 1e6 / len(block)) + 1)
    n = copies * len(frames)
    target.write_text(head + f"Frames: {n}\n{frame_time}\n" + block * copies)
    return n


def best_of(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("source", nargs="?", type=Path, default=None)
    parser.add_argument("--mb", type=float, default=5.0)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    source = args.source or max((DATA / "bandai2").glob("*.bvh"), key=lambda p: p.stat().st_size)
    with tempfile.TemporaryDirectory() as tmp:
        big = Path(tmp) / "big.bvh"
        n = tiled_copy(source, big, args.mb)
        size = big.stat().st_size / 1e6
        motion = read_bvh(big)
        t_read = best_of(lambda: read_bvh(big), args.repeat)
        t_write = best_of(lambda: write_bvh(motion, Path(tmp) / "out.bvh"), max(1, args.repeat // 2))
    print(f"source: {source.name} ({motion.n_joints} joints, {sum(map(len, motion.channels))} channels)")
    print(f"{'operation':<10} {'MB':>6} {'frames':>8} {'seconds':>8} {'MB/s':>7}")
    print(f"{'read_bvh':<10} {size:6.2f} {n:8d} {t_read:8.3f} {size / t_read:7.1f}")
    print(f"{'write_bvh':<10} {size:6.2f} {n:8d} {t_write:8.3f} {size / t_write:7.1f}")


if __name__ == "__main__":
    main()
