"""Build the training data of a folder of BVH files and report frames and clips per style and split.

    minifilm dataset DIR                  # <Style>_<Gait>.bvh files (100STYLE naming) or a Bandai Namco folder
    minifilm dataset manifest.csv         # file,style,gait[,start,end][,mirror] for files named otherwise
    minifilm dataset --from-released ../shared/data/released-lpn --out DATA [--seconds-per-style 60]
                                          # make a 100STYLE-named data set with the released network

A Bandai Namco folder (``dataset-N_{content}_{style}_{id}.bvh``) is read by its file names. The arrays are cached as .npz under --cache (default ``.cache/datasets``), keyed by the
files' paths and contents, the settings and the code, so a second run is fast.
The files are labelled in --workers processes at once (default: every core this process may use);
the data set is the same for any number of them (each file is labelled by the same code wherever
it runs, and collected in the files' order).

With ``--from-released`` the command makes a data set instead of reading one: the authors' network
walks, runs, turns, sidesteps, walks backwards, stops and stands in each of its styles, and the
motion is written as ``<Style>_<Gait>.bvh`` plus ``manifest.csv`` and ``dataset.json`` into --out
(minifilm/pipeline/from_released.py), ready for ``minifilm train --data DATA``. The styles are
driven in --workers processes at once, each a share of them (default: every core this process may
use, at most one per style); the data set is the same for any number but for float32 round-off
(minifilm/pipeline/from_released.py says how much).
"""
from __future__ import annotations

import time
from pathlib import Path

from minifilm.cli.args import in_range, input_path, output_folder, positive
from minifilm.dataset.build import build_dataset, resolve_files
from minifilm.errors import InputError

HELP = "build and cache the training data of BVH files"


def add_arguments(parser) -> None:
    parser.add_argument("source", type=input_path, nargs="?", help="a folder of BVH files or a CSV manifest")
    parser.add_argument("--cache", type=output_folder, default=Path(".cache/datasets"), help="cache folder")
    parser.add_argument("--no-cache", action="store_true", help="always rebuild, write no cache")
    parser.add_argument("--mirror", default="*", help="comma-separated styles to mirror, '*' = all, '' = none")
    parser.add_argument("--clip-seconds", type=positive(float, 60.0), default=4.0, help="style clip length (default 4 s)")
    parser.add_argument("--seed", type=in_range(0, 2**32 - 1, int), default=0)
    parser.add_argument("--fps", type=in_range(1.0, 1000.0), default=None, help="resample every file to this rate")
    parser.add_argument("--workers", type=in_range(1, 1024, int), default=None,
                        help="processes labelling the files at once (with --from-released: driving the "
                             "network, each a share of the styles), one BLAS thread each (default: the cores this "
                             "process may use, at most one per file or style); the data set is the same for any "
                             "number (with --from-released: nearly, see the command's description)")
    parser.add_argument("--split-files", action="store_true",
                        help="whole files go to train/val/test (per style) instead of 80/10/10 segments "
                             "of every file; better for many short files such as Bandai")
    made = parser.add_argument_group("making a data set with the released network (--from-released)")
    made.add_argument("--from-released", type=input_path, metavar="DIR",
                      help="the released network's parameter folder: write a data set made by it into --out")
    made.add_argument("--out", type=output_folder, help="the data set folder to write (replaced whole)")
    made.add_argument("--seconds-per-style", type=positive(float, 3600.0), default=60.0,
                      help="motion per style over all gaits (default 60 s)")
    made.add_argument("--styles", nargs="+", help="released style names (default: all 100)")
    made.add_argument("--batch", type=in_range(1, 10_000, int), default=100, help="styles per network call")
    made.add_argument("--no-calibrate", action="store_true", help="command the raw speeds (no calibration)")
    made.add_argument("--no-foot-lock", action="store_true", help="leave the feet as predicted")
    made.add_argument("--no-label-check", action="store_true",
                      help="skip labelling every file to compare with the network's own contacts and phases")


def run_from_released(args) -> int:
    from minifilm.pipeline.from_released import ReleasedDataSettings, make_released_dataset  # only here: runtime
    if args.source is not None or args.out is None:
        raise InputError("--from-released DIR writes a data set: give --out DATA and no source folder")
    s = ReleasedDataSettings(seconds_per_style=args.seconds_per_style, styles=args.styles, seed=args.seed,
                             calibrate=not args.no_calibrate, foot_lock=not args.no_foot_lock,
                             check_labels=not args.no_label_check, batch=args.batch)
    info = make_released_dataset(args.from_released, args.out, s, workers=args.workers)
    if "label_agreement" in info:
        print("minifilm's labels against the network's own outputs, per style "
              "(contacts: share of equal frames; phase: median foot-phase error, cycles; share within 0.1):")
        for style, a in info["label_agreement"].items():
            err = "-" if a["phase_error"] is None else f"{a['phase_error']:.3f}"
            within = "-" if a["phase_within"] is None else f"{a['phase_within']:.2f}"
            print(f"  {style:20s} contacts {a['contacts']:.3f}  phase {err}  within {within}")
    print(f"train on it: minifilm train --data {args.out}")
    return 0


def run(args) -> int:
    if args.from_released is not None:
        return run_from_released(args)
    made = [f for f, v in (("--out", args.out), ("--styles", args.styles)) if v is not None]
    if args.source is None or made:
        raise InputError("give a folder of BVH files or a CSV manifest to read"
                         + (f"; {', '.join(made)} only with --from-released" if made else ""))
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
                       split_unit="files" if args.split_files else "segments", workers=args.workers)
    took = time.perf_counter() - t0
    how = f"loaded from cache {ds.cache_path}" if ds.loaded \
        else "built" + ("" if ds.cache_path is None else f", cached in {ds.cache_path}")
    print(f"\n{how} in {took:.1f} s" + (f" (first build took {ds.build_seconds:.1f} s)" if ds.loaded else "") + "\n")
    print("rows (frames, mirrored copies included) and clips per style and split:")
    print(ds.summary())
    empty = [name for name in ("val", "test") if len(getattr(ds, name)) == 0]
    if empty:       # minifilm train refuses such a data set; say it here too
        print(f"note: the {' and '.join(empty)} split(s) have no frames: training on this data set has nothing "
              "to validate or test on" + (" (with --split-files every style needs at least three files)"
                                          if args.split_files else ""))
    return 0
