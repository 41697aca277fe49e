"""Every style of the authors' released network, all in one batch: the run-time checks (bone lengths, hips, speed, distance to the path).

    python benchmarks/released_styles.py                      # 100 styles, 15 s, skeleton fit, calibrated
    python benchmarks/released_styles.py --minute             # the same for a minute (about 8 minutes)
    python benchmarks/released_styles.py --fit none --no-calibrate --seconds 180
    python benchmarks/released_styles.py --styles Neutral Morris Lunge

Every style walks a figure-eight at --speed m/s (default 1.3; with each style's measured speed
calibration unless --no-calibrate), as one batch of characters. Printed per style, after the first
second: the worst bone's coefficient of variation of length in the network's *own* prediction
(before the velocity blend and the skeleton fit) and which bone it is, the same for the output
(0 with a fit: the output is a pose of the skeleton), the hips' height range, the mean root speed,
the mean and largest distance of the root to the path. Then a summary: how many styles stay under
5 % bone CV, the median, and how the network's CV changes between the first and the last 10 s
(growth would mean drift; a constant level means the network's accuracy).
"""
from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

REPO = Path(__file__).resolve().parents[1]

from minifilm.cli import report_errors  # noqa: E402
from minifilm.features.layout import FeatureLayout  # noqa: E402
from minifilm.motion.bvh import read_bvh  # noqa: E402
from minifilm.motion.measures import bone_length_cv  # noqa: E402
from minifilm.motion.skeletons import STYLE100  # noqa: E402
from minifilm.runtime.calibration import PerCharacterCalibration, calibrate_speed  # noqa: E402
from minifilm.runtime.control import figure_eight  # noqa: E402
from minifilm.runtime.controller import Controller  # noqa: E402
from minifilm.runtime.released import load_released  # noqa: E402

SHARED = REPO.parent / "shared" / "data"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--params", default=str(SHARED / "released-lpn"))
    ap.add_argument("--skeleton-bvh", default=str(SHARED / "100style" / "Neutral_FR_first3frames.bvh"))
    ap.add_argument("--styles", nargs="+", help="default: all")
    ap.add_argument("--seconds", type=float, default=15.0, help="seconds per style (default 15; see --minute)")
    ap.add_argument("--minute", action="store_true", help="the full minute per style (about 8 minutes here)")
    ap.add_argument("--speed", type=float, default=1.3)
    ap.add_argument("--fit", choices=("feedback", "output", "none"), default="feedback",
                    help="skeleton fit fed back to the network (default, as generate_released.py), output only, or none")
    ap.add_argument("--no-calibrate", action="store_true", help="command the raw speed")
    ap.add_argument("--position-bias", type=float, default=0.75, help="Controller position_bias")
    args = ap.parse_args(argv)
    if args.minute:
        args.seconds = 60.0
    rel = load_released(args.params)
    names = args.styles or list(rel.styles)
    unknown = [n for n in names if n not in rel.styles]
    if unknown:
        raise ValueError(f"unknown styles {unknown}; the released network has {list(rel.styles)}")
    layout = FeatureLayout.for_skeleton(STYLE100)
    parents = np.asarray(STYLE100.parents)
    net = rel.network
    body = None if args.fit == "none" else Controller.skeleton_for(layout, read_bvh(args.skeleton_bvh))
    ctrl = Controller(net, layout, skeleton=body, feed_back_fit=args.fit == "feedback", position_bias=args.position_bias)
    films = np.stack([rel.styles[n] for n in names])
    cal = None
    if not args.no_calibrate:
        t0 = time.perf_counter()
        cal = PerCharacterCalibration([calibrate_speed(ctrl, f, directions=(0.0,)) for f in films])
        print(f"speed calibration of {len(names)} styles: {time.perf_counter() - t0:.0f} s")
    n = int(round(args.seconds * 60))
    scripts = [figure_eight(args.seconds, speed=args.speed) for _ in names]
    t0 = time.perf_counter()
    r = ctrl.run(scripts, n, films, calibration=cal)
    print(f"{len(names)} styles x {n} frames in {time.perf_counter() - t0:.0f} s; figure-eight at {args.speed} m/s, "
          f"skeleton fit {args.fit}, calibration {'off' if args.no_calibrate else 'on'}, position_bias {args.position_bias}")
    metrics = r.metrics(parents, scripts[0].path)
    print(f"{'style':18s} {'bone CV':>8s} {'worst bone':>14s} {'output':>7s} {'hips m':>10s} {'speed':>6s} {'path mean/max m':>16s}")
    cvs, early, late = [], [], []
    k10 = 600
    for b, (name, m) in enumerate(zip(names, metrics)):
        net_pos = r.network_positions[b, 60:]
        cv = bone_length_cv(net_pos, parents)
        cvs.append(cv.max())
        early.append(bone_length_cv(net_pos[:k10], parents).max())
        late.append(bone_length_cv(net_pos[-k10:], parents).max())
        print(f"{name:18s} {cv.max():8.1%} {STYLE100.joints[cv.argmax()]:>14s} {m['bone_cv_max']:7.1%} "
              f"{m['hips_min']:4.2f}-{m['hips_max']:.2f} {m['speed']:6.2f} {m['path_mean']:8.2f}/{m['path_max']:<7.2f}")
    cvs = np.array(cvs)
    hips_ok = sum(0.6 < m["hips_min"] and m["hips_max"] < 1.2 for m in metrics)
    print(f"network bone CV under 5 %: {np.sum(cvs < 0.05)}/{len(cvs)} styles; median {np.median(cvs):.1%}, "
          f"worst {cvs.max():.1%} ({names[int(cvs.argmax())]})")
    if n > 2 * k10 + 60:
        print(f"first 10 s vs last 10 s, median over styles: {np.median(early):.1%} -> {np.median(late):.1%}")
    print(f"output bone CV max {max(m['bone_cv_max'] for m in metrics):.2%}; hips within 0.6-1.2 m: "
          f"{hips_ok}/{len(metrics)}; mean path distance {np.mean([m['path_mean'] for m in metrics]):.2f} m, "
          f"mean speed {np.mean([m['speed'] for m in metrics]):.2f} m/s")
    return 0


if __name__ == "__main__":
    report_errors(main)
