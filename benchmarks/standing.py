"""Does the character stand when nothing is asked? Per style of the released network (issue 26).

    python benchmarks/standing.py                        # every style, stand-still on (the runtime's default)
    python benchmarks/standing.py --off                  # the paper's loop alone (no StandStill), to compare
    python benchmarks/standing.py --styles Neutral,Old   # some styles

All styles at once (one batch), as the demo runs them (the fitted pose fed back, no foot
locking): walk forwards for --walk seconds (command 2 m/s, uncalibrated: about 0.6 m/s for
Neutral), then nothing for --idle seconds. Reported per style: the walking speed, the root speed
over the second after the stop, and over the rest of the idle time (mean and the largest over any
quarter second), the contact changes (either foot crossing 0.5) and the toes' mean speed in that
rest. A style "stands" when the largest quarter-second speed is under 0.05 m/s and no contact
changes. (A style whose contacts hover about 0.5 with still toes counts as not standing; one whose
toes move at 0.2 m/s is shuffling its feet on the spot.)
"""
from __future__ import annotations

import argparse
import os
import sys
import time
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

STAND_SPEED = 0.05


def measure(src, styles, walk: float, idle: float, stand):
    fps = src.fps
    ctrl = Controller(src.network, src.layout, fps=fps, skeleton=Controller.skeleton_for(src.layout, src.skeleton),
                      feed_back_fit=True, stand=stand)
    end = walk + idle
    scripts = [CommandScript([(0, 2.0, 0, 0), (walk, 2.0, 0, 0), (walk + 0.01, 0, 0, 0), (end, 0, 0, 0)])
               for _ in styles]
    n = int(round(end * fps))
    r = ctrl.run(scripts, n, np.stack([src.library[s] for s in styles]))
    w0, w1, settled = int(0.5 * fps), int(walk * fps), int((walk + 1.0) * fps)
    q = int(round(0.25 * fps))
    names = list(src.layout.joint_names)
    toe_joints = [names.index("RightToe"), names.index("LeftToe")]
    rows = []
    for b, name in enumerate(styles):
        root = r.root_positions[b]
        speed = np.linalg.norm(np.diff(root, axis=0), axis=1) * fps
        rest = root[settled:]
        quarter = np.linalg.norm(rest[q:] - rest[:-q], axis=1) / (q / fps)
        changes = int(np.abs(np.diff((r.contacts[b, settled:] > 0.5).astype(int), axis=0)).sum())
        toes = r.positions[b, settled:][:, toe_joints]                       # (F, 2, 3)
        toe = float((np.linalg.norm(np.diff(toes, axis=0), axis=-1) * fps).mean())
        rows.append(dict(style=name, walk=speed[w0:w1].mean(), stop=speed[w1:settled].mean(),
                         idle=speed[settled:].mean(), quarter=quarter.max(), changes=changes, toe=toe))
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--params", type=Path, default=DATA / "released-lpn")
    ap.add_argument("--styles", help="comma-separated (default: every style)")
    ap.add_argument("--walk", type=float, default=2.0)
    ap.add_argument("--idle", type=float, default=6.0)
    ap.add_argument("--off", action="store_true", help="without StandStill (the paper's loop)")
    args = ap.parse_args(argv)
    if not (args.params / "Xmean.bin").is_file():
        sys.exit(f"error: the released network is not at {args.params}")
    src = DemoSource.released(args.params, calibrate=False)
    styles = args.styles.split(",") if args.styles else list(src.library.names)
    t0 = time.perf_counter()
    rows = measure(src, styles, args.walk, args.idle, None if args.off else StandStill())
    took = time.perf_counter() - t0
    print(f"# standing: {len(styles)} styles, walk {args.walk:g} s then idle {args.idle:g} s; "
          f"stand-still {'off' if args.off else 'on'}; {took:.0f} s; load {os.getloadavg()[0]:.1f}")
    print(f"{'style':14s} {'walk m/s':>8s} {'1st s':>7s} {'idle':>7s} {'max 0.25s':>9s} {'changes':>7s} "
          f"{'toes m/s':>8s}  stands")
    standing = []
    for row in rows:
        ok = row["quarter"] < STAND_SPEED and row["changes"] == 0
        standing.append(ok)
        print(f"{row['style']:14s} {row['walk']:8.2f} {row['stop']:7.3f} {row['idle']:7.3f} {row['quarter']:9.3f} "
              f"{row['changes']:7d} {row['toe']:8.3f}  {'yes' if ok else 'NO'}")
    quarters = np.array([r["quarter"] for r in rows])
    print(f"# {sum(standing)} of {len(rows)} styles stand (max quarter-second speed < {STAND_SPEED} m/s and no "
          f"contact change); median idle speed {np.median([r['idle'] for r in rows]):.3f} m/s, "
          f"worst {quarters.max():.3f} m/s ({rows[int(quarters.argmax())]['style']})")
    print("# not standing: " + (", ".join(r["style"] for r, ok in zip(rows, standing) if not ok) or "none"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
