"""Does a trained run move at the speed the demo asks, with and without its speed calibration?

    python benchmarks/trained_speed.py --run runs/train_small

For every style of the run: the demo's controller settings for a run (its position bias, the body
turned towards the heading), the style's own start frame, then 8 s of one command held (forward
at the walk speed, sideways and backwards at 1 m/s, forward at the run speed), speed measured
over the last 5 s. Each cell: the speed reached / the speed asked, and the worst bone's
coefficient of variation of length in the network's own prediction (how far the pose stretched).
Left of the arrow uncalibrated, right of it through the style's calibration measured with
``RUN_CALIBRATION_COMMANDS`` (what ``minifilm demo --run`` does), the ask capped at the style's
measured top speed that way (as the demo's panel does, "goes at most ... m/s this way").
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from minifilm.demo.calibration_cache import max_speed
from minifilm.demo.source import DemoSource
from minifilm.runtime.calibration import PerCharacterCalibration, calibrate_speed
from minifilm.runtime.control import CommandScript
from minifilm.runtime.controller import Controller

SECONDS, SETTLE = 8.0, 3.0


def held(source, film, x, p, speed, direction, calibration=None):
    """(speed reached m/s, worst bone CV of the network's own pose) of one command held."""
    ctrl = Controller(source.network, source.layout, fps=source.fps, **source.options)
    script = CommandScript([(0.0, speed, 0.0, direction), (SECONDS, speed, 0.0, direction)])
    r = ctrl.run([script], int(SECONDS * source.fps), film, phases=p, start_x=x,
                 calibration=None if calibration is None else PerCharacterCalibration([calibration]))
    m = r.metrics(source.layout.parents, warmup_seconds=SETTLE)[0]
    return m["speed"], m.get("network_bone_cv_max", m["bone_cv_max"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--run", required=True, help="a run folder (minifilm train --out, examples/train_small.py)")
    ap.add_argument("--walk-speed", type=float, default=1.3)
    ap.add_argument("--run-speed", type=float, default=2.8)
    args = ap.parse_args()
    source = DemoSource.run_folder(args.run)
    asks = [("W", args.walk_speed, 0.0), ("strafe", 1.0, 90.0), ("back", 1.0, 180.0), ("Shift+W", args.run_speed, 0.0)]
    print(f"{'style':14s} {'calib. s':>8s}" + "".join(f"{f'{n} {v:g} m/s':>36s}" for n, v, _ in asks))
    errors = {False: [], True: []}
    for name in source.library.names:
        film, (x, p) = source.library[name], source.starts.get(name, (None, None))
        t0 = time.perf_counter()
        ctrl = Controller(source.network, source.layout, fps=source.fps, **source.options)
        cal = calibrate_speed(ctrl, film, commands=source.calibration_commands, phases=p, start_x=x)
        spent = time.perf_counter() - t0
        cells = []
        for _, speed, direction in asks:
            reachable = min(speed, max_speed(cal, direction))
            s0, cv0 = held(source, film, x, p, speed, direction)
            s1, cv1 = held(source, film, x, p, reachable, direction, cal)
            errors[False].append(abs(s0 / speed - 1))
            errors[True].append(abs(s1 / reachable - 1))
            cells.append(f"{s0:4.2f}/{speed:3.1f} cv {cv0:.2f} -> {s1:4.2f}/{reachable:3.2f} cv {cv1:.2f}")
        print(f"{name:14s} {spent:8.1f}" + "".join(f"{c:>36s}" for c in cells), flush=True)
    for calibrated, e in errors.items():
        e = np.array(e)
        print(f"{'calibrated' if calibrated else 'uncalibrated':12s}: |reached / asked - 1| median {np.median(e):.2f}, "
              f"worst {e.max():.2f}, within 15 % in {np.mean(e <= 0.15):.0%} of {len(e)} cells")


if __name__ == "__main__":
    main()
