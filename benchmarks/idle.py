"""Is the standing character alive? The released network idling, per style, as the demo runs it.

    python benchmarks/idle.py                     # 10 styles (every 10th of the 100)
    python benchmarks/idle.py --all               # all 100 styles
    python benchmarks/idle.py --amplitude 0       # the still phases of before (a statue), to compare

All styles at once (one batch; the fitted pose fed back, as in the demo): walk forwards for 2 s
(command 2 m/s), then nothing for 7 s. Over the 5 s from 2 s after the stop, per style: the root's
mean speed, how far any foot joint (toes and ankles) moved from where it was at the window's
start, and the joint that moved furthest (the largest distance from its own start position).
The targets: root < 0.05 m/s, no foot moves more than 2 cm, some joint moves at least 1 cm.
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("MINIFILM_SHARED_DATA", ROOT.parent / "shared" / "data"))

from minifilm.demo.source import DemoSource  # noqa: E402
from minifilm.runtime.control import CommandScript  # noqa: E402
from minifilm.runtime.controller import Controller  # noqa: E402
from minifilm.runtime.standing import StandStill  # noqa: E402

FEET = ("RightToe", "LeftToe", "RightAnkle", "LeftAnkle")


def idle_figures(source, styles, amplitude: float, walk: float = 2.0, idle: float = 7.0, window: float = 5.0):
    """Per style (root m/s, foot cm, joint cm, joint name) over ``window`` s from 2 s after the stop."""
    body = Controller.skeleton_for(source.layout, source.skeleton)
    ctrl = Controller(source.network, source.layout, fps=source.fps, skeleton=body, feed_back_fit=True,
                      stand=StandStill(idle_amplitude=amplitude))
    scripts = [CommandScript([(0, 2, 0, 0), (walk, 2, 0, 0), (walk + 1e-6, 0, 0, 0), (walk + idle, 0, 0, 0)])
               for _ in styles]
    fps = source.fps
    r = ctrl.run(scripts, int(round((walk + idle) * fps)), np.stack([source.library[s] for s in styles]))
    k, w = int(round((walk + 2.0) * fps)), int(round(window * fps))
    pos, root = r.positions[:, k:k + w], r.root_positions[:, k:k + w]
    names = list(source.layout.joint_names)
    feet = [names.index(n) for n in FEET]
    root_speed = np.linalg.norm(np.diff(root, axis=1), axis=-1).sum(axis=1) / window
    moved = np.linalg.norm(pos - pos[:, :1], axis=-1).max(axis=1)                 # (B, J) metres
    foot = moved[:, feet].max(axis=1)
    return [(root_speed[b], 100 * foot[b], 100 * moved[b].max(), names[int(moved[b].argmax())])
            for b in range(len(styles))]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--params", default=str(DATA / "released-lpn"))
    ap.add_argument("--all", action="store_true", help="all styles (default: every 10th)")
    ap.add_argument("--styles", nargs="+")
    ap.add_argument("--amplitude", type=float, default=StandStill.idle_amplitude,
                    help="StandStill.idle_amplitude (0: still phases)")
    args = ap.parse_args(argv)
    source = DemoSource.released(args.params, calibrate=False)
    names = list(source.library.names)
    styles = args.styles or (names if args.all else names[::10][:10])
    rows = idle_figures(source, styles, args.amplitude)
    print(f"idle, released network, idle_amplitude {args.amplitude}: 5 s from 2 s after a stop")
    print(f"{'style':16s} {'root m/s':>9s} {'foot cm':>8s} {'joint cm':>9s}  joint")
    ok = 0
    for name, (rs, foot, joint, jname) in zip(styles, rows):
        good = rs < 0.05 and foot <= 2.0 and joint >= 1.0
        ok += good
        print(f"{name:16s} {rs:9.3f} {foot:8.2f} {joint:9.2f}  {jname}{'' if good else '   <- misses a target'}")
    print(f"{ok}/{len(styles)} styles stand (root < 0.05 m/s, feet within 2 cm) and move (a joint >= 1 cm)")
    return 0 if ok == len(styles) else 1


if __name__ == "__main__":
    sys.exit(main())
