"""Build the training data of a folder of BVH files and report frames per style and split.

    python examples/build_dataset.py ../shared/data/bandai2 --split-files
    python examples/build_dataset.py path/to/100STYLE                 # <Style>_<Gait>.bvh files
    python examples/build_dataset.py my_manifest.csv                  # file,style,gait[,start,end][,mirror]

A walk-through of the dataset API; ``minifilm dataset`` does the same with more options.
"""
import argparse
from pathlib import Path

from minifilm.cli import report_errors
from minifilm.cli.args import positive
from minifilm.dataset.build import build_dataset


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("source", help="a folder of BVH files or a CSV manifest")
    ap.add_argument("--cache", default=".cache/datasets", help="cache folder")
    ap.add_argument("--split-files", action="store_true", help="whole files per split (many short files)")
    ap.add_argument("--clip-seconds", type=positive(float, 60.0), default=4.0, help="style clip length (the paper: 4 s)")
    args = ap.parse_args()

    source = Path(args.source)      # 100STYLE or Bandai Namco file names are understood as they are
    # read, label (contacts, local phases), featurise (x, p, z, clips), split, normalise, cache
    ds = build_dataset(source, cache_dir=args.cache, mirror_styles=("*",), clip_seconds=args.clip_seconds,
                       clip_stride_seconds=args.clip_seconds / 2, split_unit="files" if args.split_files else "segments")
    print(ds.summary())
    train = ds.train_data("train")           # normalised arrays, as the trainer takes them
    print(f"training arrays: x {train.x.shape}, p {train.p.shape}, z {train.z.shape}, clips {train.clips.shape}")


if __name__ == "__main__":
    report_errors(main)
