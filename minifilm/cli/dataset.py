"""Build the training data of a folder of BVH files and report frames and clips per style and split.

    minifilm dataset DIR                  # <Style>_<Gait>.bvh files (100STYLE naming) or a Bandai Namco folder
    minifilm dataset manifest.csv         # file,style,gait[,start,end][,mirror] for files named otherwise

A Bandai Namco folder (``dataset-N_{content}_{style}_{id}.bvh``) is read by its file names. The arrays are cached as .npz under --cache (default ``.cache/datasets``), keyed by the
files' paths, sizes and modification times, the settings and the code, so a second run is fast.
"""
from __future__ import annotations

import time
from pathlib import Path

from minifilm.cli.args import in_range, input_path, output_folder, positive
from minifilm.dataset.build import build_dataset, resolve_files
from minifilm.errors import InputError

HELP = "build and cache the training data of BVH files"


def add_arguments(parser) -> None:
    parser.add_argument("source", type=input_path, help="a folder of BVH files or a CSV manifest")
    parser.add_argument("--cache", type=output_folder, default=Path(".cache/datasets"), help="cache folder")
    parser.add_argument("--no-cache", action="store_true", help="always rebuild, write no cache")
    parser.add_argument("--mirror", default="*", help="comma-separated styles to mirror, '*' = all, '' = none")
    parser.add_argument("--clip-seconds", type=positive(float, 60.0), default=4.0, help="style clip length (default 4 s)")
    parser.add_argument("--seed", type=in_range(0, 2**32 - 1, int), default=0)
    parser.add_argument("--fps", type=in_range(1.0, 1000.0), default=None, help="resample every file to this rate")
    parser.add_argument("--split-files", action="store_true",
                        help="whole files go to train/val/test (per style) instead of 80/10/10 segments "
                             "of every file; better for many short files such as Bandai")


def run(args) -> int:
    source = args.source
    mirror = tuple(s.strip() for s in args.mirror.split(",") if s.strip())
    styles = {f.style for f in resolve_files(source)}
    unknown = [m for m in mirror if m != "*" and m not in styles]
    if unknown:    # a typo would otherwise quietly mirror nothing
        raise InputError(f"--mirror {args.mirror}: no style called {', '.join(map(repr, unknown))} in {source} "
                         f"(its styles: {', '.join(sorted(styles))})")
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
    return 0
