"""The main job: data -> local phases -> dataset -> training -> test table -> generated motion.

    minifilm train                      # synthetic data (8 styles x 6 gaits), default settings
    minifilm train --data DIR           # your own BVH files: 100STYLE or Bandai Namco naming, or a CSV manifest
    minifilm train --data pool.csv --rig 100style --fps 60   # files of several rigs, retargeted onto one
    minifilm train --quick              # a smaller, faster run of the same steps

    mpiexec -n 2 minifilm train         # each minibatch split across 2 MPI ranks (minifilm/train/mpi.py)

The same job as ``python examples/train_small.py``; the steps are in minifilm/pipeline/train_small.py.
Writes a run folder (--out, default runs/train_small) that ``minifilm generate --run`` reads.
"""
from __future__ import annotations

from dataclasses import fields, replace

from minifilm.cli.args import in_range, input_path, non_empty, output_folder, positive
from minifilm.errors import InputError
from minifilm.model.config import ModelConfig
from minifilm.pipeline.train_small import Settings
from minifilm.pipeline.run_rig import load_target
from minifilm.pipeline.train_small import run as run_job
from minifilm.train import mpi

HELP = "the main job: synthetic or your data -> trained model -> generated motion"


def add_arguments(parser) -> None:
    d = Settings()
    parser.add_argument("--data", type=input_path, help="folder of <Style>_<Gait>.bvh files, or a CSV manifest "
                        "(file,style,gait[,start,end]) for other datasets (default: synthetic data)")
    parser.add_argument("--out", type=output_folder, default=d.out, help=f"output (run) folder (default {d.out})")
    parser.add_argument("--epochs", type=in_range(1, 100_000, int), help=f"training epochs (default {d.epochs})")
    parser.add_argument("--seed", type=in_range(0, 2**32 - 1, int), default=d.seed)
    parser.add_argument("--quick", action="store_true", help="a smaller, faster run of every step")
    parser.add_argument("--styles", help="comma-separated synthetic styles (default: all)")
    parser.add_argument("--gaits", help=f"comma-separated synthetic gaits (default: {','.join(d.gaits)})")
    parser.add_argument("--seconds", type=positive(float, 3600.0), help="synthetic seconds per style and gait")
    parser.add_argument("--clip-seconds", type=positive(float, 60.0),
                        help=f"length of the style clips y that Ψ reads (default {d.clip_seconds:g} s; the paper "
                             "4 s); shorter for data of short files")
    parser.add_argument("--generate-seconds", type=positive(float, 3600.0), help="seconds of motion generated per style")
    parser.add_argument("--split", choices=("auto", "files", "segments"), default="auto",
                        help="with --data: whole files to train/val/test, or 80/10/10 segments of every file "
                             "(auto: whole files when the median file is under 20 s)")
    parser.add_argument("--split-files", dest="split", action="store_const", const="files",
                        help="with --data: the same as --split files")
    parser.add_argument("--mirror", action="store_true", help="with --data: also train on every file's mirror")
    parser.add_argument("--fps", type=in_range(1.0, 1000.0), help="with --data: resample every file to this "
                        "frame rate (needed when the files were recorded at different rates)")
    parser.add_argument("--rig", type=non_empty("--rig"), metavar="TARGET",
                        help="with --data: retarget every file onto this rig first (100style, bandai, cmu, a run "
                             "folder or a BVH file), so files of different skeletons make one data set")
    parser.add_argument("--clips-per-batch", type=in_range(1, 4096, int), default=d.clips_per_batch,
                        help="style clips per minibatch, shared by its samples (default "
                             f"{d.clips_per_batch}; 32 = one clip per sample, as the original)")
    parser.add_argument("--batch-size", type=in_range(1, 4096, int), default=d.batch_size,
                        help=f"samples per minibatch (default {d.batch_size}, the original's; the paper gives none)")
    parser.add_argument("--learning-rate", type=positive(float, 1.0), default=d.learning_rate,
                        help=f"Adam's learning rate (default {d.learning_rate:g}; the paper's 1e-4 is for its 62x "
                             "larger network)")
    parser.add_argument("--model", choices=("small", "paper"), default="small",
                        help="the network's sizes: small (the main job's: K = 4, hidden 128, 32 filters; 707,420 "
                             "parameters for 100STYLE) or paper (Sec. 4's: K = 8, hidden 512, 256 filters of 25; 44 M "
                             "parameters with --clip-seconds 4, a third of a second a step on one core: for "
                             "mpiexec on many cores, docs/scaling.md)")
    parser.add_argument("--workers", type=in_range(1, 1024, int), default=None,
                        help="processes labelling the data set's files (default: every core this process may use; "
                             "1: all in this process). Training runs in this process; to split each minibatch "
                             "across processes or machines, start the job with mpiexec -n N")


#: ModelConfig's sizes of the paper that do not come from the data (the others: the features' layout)
PAPER_SIZES = {f.name: getattr(ModelConfig.paper(), f.name) for f in fields(ModelConfig)
               if f.name not in ("x_dim", "z_dim", "phase_dim", "clip_frames", "clip_channels")}


def settings(args) -> Settings:
    clips = None if args.clips_per_batch is None or args.clips_per_batch >= args.batch_size else args.clips_per_batch
    s = Settings(seed=args.seed, out=args.out, split=args.split, mirror=args.mirror, clips_per_batch=clips,
                 fps=args.fps, rig=args.rig, workers=args.workers, batch_size=args.batch_size,
                 learning_rate=args.learning_rate, model=PAPER_SIZES if args.model == "paper" else {})
    if args.quick:
        s = s.quick()
    changes = {"epochs": args.epochs, "seconds_per_clip": args.seconds, "generate_seconds": args.generate_seconds,
               "clip_seconds": args.clip_seconds,
               "styles": args.styles and tuple(args.styles.split(",")),
               "gaits": args.gaits and tuple(args.gaits.split(","))}
    return replace(s, **{k: v for k, v in changes.items() if v is not None})


def check_options(args) -> None:
    """InputError for options that would be silently ignored (the real-data ones without --data,
    the synthetic set's with it) and for a --rig that is not one, before any work starts."""
    if args.data is None:
        given = [flag for flag, value in (("--split", args.split != "auto"), ("--mirror", args.mirror),
                                          ("--fps", args.fps is not None), ("--rig", args.rig is not None))
                 if value]
        if given:
            raise InputError(f"{', '.join(given)}: only with --data (the synthetic set is made at 60 fps, "
                             "split 80/10/10 and not mirrored)")
    else:
        given = [flag for flag, value in (("--styles", args.styles), ("--gaits", args.gaits),
                                          ("--seconds", args.seconds)) if value is not None]
        if given:
            raise InputError(f"{', '.join(given)}: only for the synthetic set, not with --data "
                             "(the styles of your data come from its file names or manifest)")
    if args.rig is not None:       # a wrong target is one line now, not after the data set step
        load_target(args.rig)


def run(args) -> int:
    check_options(args)
    run_job(settings(args), args.data, mpi.world())     # under mpiexec: data-parallel (train/mpi.py)
    return 0
