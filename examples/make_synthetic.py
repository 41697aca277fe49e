"""Write minifilm's synthetic stylised locomotion as 100STYLE-like BVH files.

    python examples/make_synthetic.py out/synthetic              # the default set
    python examples/make_synthetic.py out/synth --seconds 20 --styles Neutral,Drunk --gaits FW,TR

Writes ``<Style>_<Gait>.bvh`` (the 100STYLE skeleton, 60 fps, centimetres) plus
``<Style>_<Gait>.truth.npz`` with the generator's true phases and contacts, and prints how long
generating the set took and a line per clip.
"""
import argparse
import time
from pathlib import Path

import numpy as np

from minifilm.synthetic.generator import DEFAULT_GAITS, STYLES, default_dataset, write_dataset

# ---- settings -----------------------------------------------------------------------------------
SEED = 0
SECONDS = 6.0
FPS = 60


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("out", type=Path, help="folder to write the BVH files into")
    parser.add_argument("--seed", type=int, default=SEED)
    parser.add_argument("--seconds", type=float, default=SECONDS, help="length of each clip")
    parser.add_argument("--fps", type=float, default=FPS)
    parser.add_argument("--styles", default=",".join(STYLES), help="comma-separated style names")
    parser.add_argument("--gaits", default=",".join(DEFAULT_GAITS), help="comma-separated gait codes")
    args = parser.parse_args()

    styles = [s for s in args.styles.split(",") if s]
    gaits = [g for g in args.gaits.split(",") if g]
    start = time.perf_counter()
    clips = default_dataset(seed=args.seed, seconds=args.seconds, styles=styles, gaits=gaits,
                            fps=args.fps)
    generated = time.perf_counter() - start
    paths = write_dataset(args.out, clips)
    written = time.perf_counter() - start - generated

    print(f"{'file':24s} {'frames':>6s} {'contact R':>9s} {'contact L':>9s}  gaits")
    for clip, path in zip(clips, paths):
        contact = clip.true_contacts.mean(axis=0)
        seen = list(dict.fromkeys(clip.frame_gaits))           # in order of appearance
        print(f"{path.name:24s} {clip.motion.n_frames:6d} {contact[0]:9.2f} {contact[1]:9.2f}  "
              f"{'>'.join(seen)}")
    frames = sum(c.motion.n_frames for c in clips)
    print(f"\n{len(clips)} clips, {frames} frames ({frames / args.fps:.0f} s of motion): generated in "
          f"{generated:.2f} s, written in {written:.2f} s to {args.out}")


if __name__ == "__main__":
    np.seterr(all="raise")  # any overflow / invalid value in the generator is a bug: fail loudly
    main()
