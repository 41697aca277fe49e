"""Plot the foot contacts and local phases of a BVH file like the paper's Figure 4 (Sec. 4.1).

    python examples/plot_phases.py path/to/file.bvh --out phases.png

A walk-through of the labelling API; ``minifilm phases FILE.bvh`` does the same with more options
(a time range, the skeleton, a style's phase sources).
"""
import argparse

import numpy as np

from minifilm.cli import report_errors
from minifilm.cli.args import png_path
from minifilm.files import check_writable
from minifilm.motion.bvh import read_bvh
from minifilm.body.rig import detect_skeleton
from minifilm.phases.label import label
from minifilm.viewer.phase_plot import plot_phases


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("bvh")
    ap.add_argument("--out", type=png_path, default="phases.png", help="the picture to write (PNG)")
    args = ap.parse_args()
    check_writable(args.out, "--out")       # before the work: a typo in the path costs nothing

    # The skeleton (which joints carry the phases and the contacts, its units) from the joint names.
    skeleton = detect_skeleton(read_bvh(args.bvh, scale=1.0))
    motion = read_bvh(args.bvh, scale=skeleton.bvh_scale)                # metres
    # One recipe: foot contacts from the toe tips, then the four local phases (Eq. 1).
    labels = label(motion, skeleton)
    t = np.arange(motion.n_frames) / motion.fps
    plot_phases(t, labels.phases, labels.contacts, labels.sources, args.out, title=args.bvh)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    report_errors(main)
