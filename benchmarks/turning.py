"""Does the body follow the heading while walking and turning (W+E held), per style?

    python benchmarks/turning.py --run runs/train_small           # a run folder of minifilm train
    python benchmarks/turning.py --params ../shared/data/released-lpn [--styles Neutral Old]

Every style at once (one batch), driven as the demo drives it (its source's settings: the skeleton
fit, fed back for the released network, the run's own position bias and start frames; the
forward speed calibration, a run's with the commands its data holds): the heading turns right at
--turn-rate deg/s from the start while the character is asked to walk along it at --speed m/s,
for --seconds. Printed per
style: the angle between the body's facing (the root's) and the heading at the end, its largest
over the last second, how far the heading and the facing turned, and the mean root speed.
Target: heading error after 5 s <= 30 degrees.
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

from minifilm.demo.source import DemoSource  # noqa: E402
from minifilm.runtime.calibration import PerCharacterCalibration, calibrate_speed  # noqa: E402
from minifilm.runtime.control import CommandScript  # noqa: E402
from minifilm.runtime.controller import Controller  # noqa: E402
from minifilm.runtime.root_frames import floor_angle  # noqa: E402


def turned(directions: np.ndarray) -> np.ndarray:
    """Total signed turn (degrees) of (B, F, 2) floor directions, unwrapped."""
    a = np.unwrap(np.arctan2(directions[..., 0], directions[..., 1]), axis=1)
    return np.degrees(a[:, -1] - a[:, 0])


def turning_figures(source, styles, speed=1.3, turn_rate=120.0, seconds=5.0, calibrate=True):
    """Per style: (error at the end, largest error over the last second, heading turn, facing
    turn, mean speed), degrees and m/s."""
    ctrl = Controller(source.network, source.layout, fps=source.fps,
                      skeleton=Controller.skeleton_for(source.layout, source.skeleton),
                      feed_back_fit=source.feed_back_fit, **source.options)
    fps, n = source.fps, int(round(seconds * source.fps))
    films = np.stack([source.library[s] for s in styles])
    cal = None
    if calibrate and source.calibrate:
        cal = PerCharacterCalibration([calibrate_speed(ctrl, f, commands=source.calibration_commands, directions=(0.0,))
                                       for f in films])
    # the demo's E: the heading turns right (towards -x from +z), the walk is along it
    scripts = [CommandScript([(0.0, speed, 0.0, 0.0), (seconds, speed, -turn_rate * seconds, 0.0)])
               for _ in styles]
    starts = [source.starts.get(s, (None, None)) for s in styles]
    x = None if any(sx is None for sx, _ in starts) else np.stack([sx for sx, _ in starts])
    p = None if any(sp is None for _, sp in starts) else np.stack([sp for _, sp in starts])
    r = ctrl.run(scripts, n, films, phases=p, calibration=cal, start_x=x)
    t = np.arange(n) / fps
    heading = np.radians(-turn_rate * t)
    target = np.stack([np.sin(heading), np.cos(heading)], axis=-1)[None]               # (1, F, 2)
    error = floor_angle(r.root_facing, target)                                               # (B, F)
    last = error[:, -int(round(fps)):]
    step = np.linalg.norm(np.diff(r.root_positions, axis=1), axis=-1)
    heading_turn = -turn_rate * (n - 1) / fps
    return [(error[b, -1], last[b].max(), heading_turn, turned(r.root_facing)[b], step[b].sum() * fps / (n - 1))
            for b in range(len(styles))]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    src = ap.add_mutually_exclusive_group(required=True)
    src.add_argument("--run", type=Path)
    src.add_argument("--params", type=Path)
    ap.add_argument("--styles", nargs="+")
    ap.add_argument("--speed", type=float, default=1.3)
    ap.add_argument("--turn-rate", type=float, default=120.0)
    ap.add_argument("--seconds", type=float, default=5.0)
    args = ap.parse_args(argv)
    source = DemoSource.run_folder(args.run) if args.run else DemoSource.released(args.params)
    styles = args.styles or list(source.library.names)
    rows = turning_figures(source, styles, args.speed, args.turn_rate, args.seconds)
    print(f"{source.name}: W+E for {args.seconds:g} s (walk {args.speed:g} m/s, heading turning "
          f"{args.turn_rate:g} deg/s)")
    print(f"{'style':16s} {'error end':>9s} {'last 1 s':>8s} {'heading':>8s} {'facing':>8s} {'m/s':>5s}")
    errors = []
    for name, (end, worst, h, f, v) in zip(styles, rows):
        errors.append(end)
        print(f"{name:16s} {end:9.1f} {worst:8.1f} {h:8.0f} {f:8.0f} {v:5.2f}")
    errors = np.array(errors)
    print(f"heading error after {args.seconds:g} s: median {np.median(errors):.1f}, worst {errors.max():.1f} deg "
          f"({styles[int(errors.argmax())]}); {np.sum(errors <= 30)}/{len(errors)} styles within 30 deg")
    return 0


if __name__ == "__main__":
    sys.exit(main())
