"""Build the training dataset of a folder of BVH files and report frames per style and split.

    python examples/build_dataset.py                        # ../shared/data/bandai2 (Bandai, 30 fps)
    python examples/build_dataset.py path/to/100STYLE       # <Style>_<Gait>.bvh files
    python examples/build_dataset.py my_manifest.csv        # file,style,gait[,start,end][,mirror]

A Bandai Namco folder (``dataset-N_{content}_{style}_{id}.bvh``) gets a manifest written next to
the cache. The arrays are cached as .npz under --cache (default ``.cache/datasets``), keyed by the
files' paths, sizes and modification times, the settings and the code, so a second run is fast.
"""
import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from minifilm.dataset.build import build_dataset  # noqa: E402
from minifilm.dataset.manifest import write_bandai_manifest  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("source", nargs="?", default=str(ROOT.parent / "shared" / "data" / "bandai2"),
                    help="a folder of BVH files or a CSV manifest")
    ap.add_argument("--cache", default=str(ROOT / ".cache" / "datasets"), help="cache folder")
    ap.add_argument("--no-cache", action="store_true", help="always rebuild, write no cache")
    ap.add_argument("--mirror", default="*", help="comma-separated styles to mirror, '*' = all, '' = none")
    ap.add_argument("--clip-seconds", type=float, default=4.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--fps", type=float, default=None, help="resample every file to this rate")
    ap.add_argument("--split-files", action="store_true",
                    help="whole files go to train/val/test (per style) instead of 80/10/10 segments "
                         "of every file; better for many short files such as Bandai")
    args = ap.parse_args(argv)

    source = Path(args.source)
    if source.is_dir() and any(source.glob("dataset-*_*_*_*.bvh")):
        source = write_bandai_manifest(source, Path(args.cache) / f"{source.name}-manifest.csv")
        print(f"wrote Bandai manifest {source}")
    mirror = tuple(s for s in args.mirror.split(",") if s)
    t0 = time.perf_counter()
    ds = build_dataset(source, cache_dir=None if args.no_cache else args.cache,
                       mirror_styles=mirror, clip_seconds=args.clip_seconds,
                       clip_stride_seconds=args.clip_seconds / 2, seed=args.seed, fps=args.fps,
                       split_unit="files" if args.split_files else "segments")
    took = time.perf_counter() - t0
    how = f"loaded from cache {ds.cache_path}" if ds.build_seconds == 0 or took < 0.5 * ds.build_seconds \
        else "built" + ("" if ds.cache_path is None else f", cached in {ds.cache_path}")
    print(f"\n{how} in {took:.1f} s (first build took {ds.build_seconds:.1f} s)\n")
    print("rows (frames, mirrored copies included) and clips per style and split:")
    print(ds.summary())


if __name__ == "__main__":
    from minifilm.cli import run

    run(main)
