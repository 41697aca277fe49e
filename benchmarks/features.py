"""Feature extraction throughput (frames per second), paper Sec. 3.2 / minifilm/features/compute.py.

    python benchmarks/features.py            # add --quick for fewer repeats

Rows:
  x,p,z from arrays     frame_features_from_arrays: trajectory + joints + phases for every frame
  clips from arrays     clip_features_from_arrays: 4 s clips, stride 2 s
  x,p,z from Motion     frame_features on a real BVH motion (FK cached, velocities, root transforms)
  dataset pipeline      one Bandai file end to end as minifilm/dataset/build.py does it: read BVH, FK, contacts,
                        local phases, features of the file and its mirror (phases dominate)
The machine's cores are shared, so the load average is printed; medians of several runs.
"""
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from minifilm.dataset.file_rows import featurise
from minifilm.dataset.settings import DatasetSettings
from minifilm.dataset.splits import split_segments
from minifilm.features.compute import clip_features_from_arrays, frame_features, frame_features_from_arrays
from minifilm.motion.bvh import read_bvh
from minifilm.motion.editing import mirror
from minifilm.motion.skeletons import BANDAI
from minifilm.phases.label import label

ROOT = Path(__file__).resolve().parents[1]

DATA = Path(os.environ.get("MINIFILM_SHARED_DATA", ROOT.parent / "shared" / "data"))
BANDAI_FILE = DATA / "bandai2" / "dataset-2_walk_elderly_002.bvh"


def median_s(fn, repeat):
    fn()                                                   # warm-up
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def random_character(F, J, rng):
    """World arrays of a character walking on a wavy line (values only need to be realistic)."""
    t = np.arange(F) / 60.0
    heading = 0.3 * np.sin(0.5 * t)
    c, s = np.cos(heading), np.sin(heading)
    root_rot = np.zeros((F, 3, 3))
    root_rot[:, 0, 0], root_rot[:, 0, 2], root_rot[:, 1, 1] = c, s, 1
    root_rot[:, 2, 0], root_rot[:, 2, 2] = -s, c
    root_pos = np.stack([np.cumsum(s) / 60, np.zeros(F), np.cumsum(c) / 60], axis=1)
    positions = root_pos[:, None] + rng.normal(0, 0.3, (F, J, 3)) + [0, 1, 0]
    q, _ = np.linalg.qr(rng.normal(size=(F, J, 3, 3)))
    velocities = rng.normal(size=(F, J, 3))
    return positions, q, velocities, root_pos, root_rot


def main():
    quick = "--quick" in sys.argv
    repeat = 3 if quick else 7
    rng = np.random.default_rng(0)
    rows = []
    F, J, fps = 18000, 25, 60.0                          # a 5-minute 100STYLE file
    arrays = random_character(F, J, rng)
    phases, contacts = rng.normal(size=(F, 8)), np.zeros((F, 2))
    t = median_s(lambda: frame_features_from_arrays(*arrays, phases, contacts, fps), repeat)
    rows.append(("x,p,z from arrays", f"{F} frames, J={J}, 60 fps", F, t))
    t = median_s(lambda: clip_features_from_arrays(*arrays, fps), repeat)
    rows.append(("clips from arrays", f"{F} frames, 4 s / 2 s", F, t))

    if BANDAI_FILE.is_file():

        m = read_bvh(BANDAI_FILE, scale=BANDAI.bvh_scale)
        n = m.n_frames
        zeros8, zeros2 = np.zeros((n, 8)), np.zeros((n, 2))
        t = median_s(lambda: frame_features(m, BANDAI, zeros8, zeros2), repeat)
        rows.append(("x,p,z from Motion", f"{BANDAI_FILE.name}, {n} frames", n, t))

        settings = DatasetSettings()

        def pipeline():
            motion = read_bvh(BANDAI_FILE, scale=BANDAI.bvh_scale)
            labels = label(motion, BANDAI, "elderly")
            segs = split_segments(motion.n_frames, np.random.default_rng(0))
            for m, lab in ((motion, labels), (mirror(motion), labels.mirrored())):
                featurise(m, BANDAI, lab.contacts, lab.vectors, segs, motion.fps, True, settings, np.float32)

        t = median_s(pipeline, repeat)
        rows.append(("dataset pipeline", f"{BANDAI_FILE.name} + mirror", n, t))
    else:
        print(f"# {BANDAI_FILE} not found: real-data rows skipped")

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"# feature extraction throughput; numpy {np.__version__}, cores {os.cpu_count()}, "
          f"load average {load:.2f}, median of {repeat}")
    print(f"{'what':<20} {'input':<42} {'ms':>9} {'frames/s':>12}")
    print("-" * 86)
    for what, desc, frames, secs in rows:
        print(f"{what:<20} {desc:<42} {1e3 * secs:>9.1f} {frames / secs:>12,.0f}")


if __name__ == "__main__":
    main()
