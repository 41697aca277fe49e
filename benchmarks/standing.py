"""Does the character stand when nothing is asked, and start again at once? Per style of the released network.

    python benchmarks/standing.py                        # every style, stand-still on (the runtime's default)
    python benchmarks/standing.py --no-hold              # the stand-still without the held body (root and phases only)
    python benchmarks/standing.py --off                  # the paper's loop alone (no StandStill), to compare
    python benchmarks/standing.py --styles Neutral,Old   # some styles
    python benchmarks/standing.py --go                   # also the start: time from a command to walking

All styles at once (one batch), as the demo runs them (the fitted pose fed back, no foot
locking): walk forwards for --walk seconds (command 2 m/s, uncalibrated: about 0.6 m/s for
Neutral), then nothing for --idle seconds. Reported per style, over the rest of the idle time
from 1 s after the stop: the walking speed, the root speed over the second after the stop and
over the rest (mean and the largest over any quarter second), the contact changes (either
reported contact crossing 0.5), the toes' mean speed, the steps the feet really take (a toe
speeding up past 0.15 m/s, the contact labeller's "slow" limit: a foot lifted or slid, whatever
the contacts say) and how far the facing turned. A style "stands" when the largest quarter-second
speed is under 0.05 m/s, with no contact change and no step.

With --go each style is stopped three times (after walk - 0.5, walk and walk + 0.5 s, so the
feet come to rest in different places), idles --idle seconds and is then asked to walk again:
the frames from the command until the root first goes faster than 0.3 m/s, and the metres it
covers in the first half second, averaged over the three.
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
#: m/s: a toe faster than this is not resting (the contact labeller's speed limit, phases/contacts.py)
TOE_SLOW = 0.15
GO_SPEED = 0.3


def controller(src, stand) -> Controller:
    return Controller(src.network, src.layout, fps=src.fps, skeleton=Controller.skeleton_for(src.layout, src.skeleton),
                      feed_back_fit=True, stand=stand)


def toe_joints(src) -> list:
    names = list(src.layout.joint_names)
    return [names.index("RightToe"), names.index("LeftToe")]


def measure(src, styles, walk: float, idle: float, stand):
    """Walk, then nothing: one row of figures per style (see the module docstring)."""
    fps = src.fps
    end = walk + idle
    scripts = [CommandScript([(0, 2.0, 0, 0), (walk, 2.0, 0, 0), (walk + 0.01, 0, 0, 0), (end, 0, 0, 0)])
               for _ in styles]
    r = controller(src, stand).run(scripts, int(round(end * fps)), np.stack([src.library[s] for s in styles]))
    w0, w1, settled = int(0.5 * fps), int(walk * fps), int((walk + 1.0) * fps)
    q = int(round(0.25 * fps))
    rows = []
    for b, name in enumerate(styles):
        root = r.root_positions[b]
        speed = np.linalg.norm(np.diff(root, axis=0), axis=1) * fps
        rest = root[settled:]
        quarter = np.linalg.norm(rest[q:] - rest[:-q], axis=1) / (q / fps)
        changes = int(np.abs(np.diff((r.contacts[b, settled:] > 0.5).astype(int), axis=0)).sum())
        toes = r.positions[b, settled:][:, toe_joints(src)]                        # (F, 2, 3)
        toe_speed = np.linalg.norm(np.diff(toes, axis=0), axis=-1) * fps           # (F - 1, 2)
        moving = (toe_speed > TOE_SLOW).astype(int)
        steps = int((np.diff(moving, axis=0) > 0).sum() + moving[0].sum())
        heading = np.unwrap(np.arctan2(r.root_facing[b, settled:, 0], r.root_facing[b, settled:, 1]))
        rows.append(dict(style=name, walk=speed[w0:w1].mean(), stop=speed[w1:settled].mean(),
                         idle=speed[settled:].mean(), quarter=quarter.max(), changes=changes,
                         toe=float(toe_speed.mean()), steps=steps,
                         turn=float(np.degrees(heading.max() - heading.min()))))
    return rows


def measure_go(src, styles, walk: float, idle: float, stand):
    """Stop after walk - 0.5, walk, walk + 0.5 s, idle, walk again: {style: (frames to > GO_SPEED,
    metres in the first 0.5 s)}, each averaged over the three stops (inf where never)."""
    fps = src.fps
    frames = {s: [] for s in styles}
    metres = {s: [] for s in styles}
    for w in (walk - 0.5, walk, walk + 0.5):
        go = w + idle
        end = go + 2.0
        scripts = [CommandScript([(0, 2.0, 0, 0), (w, 2.0, 0, 0), (w + 0.01, 0, 0, 0), (go, 0, 0, 0),
                                  (go + 0.01, 2.0, 0, 0), (end, 2.0, 0, 0)]) for _ in styles]
        r = controller(src, stand).run(scripts, int(round(end * fps)), np.stack([src.library[s] for s in styles]))
        k0 = int(round(go * fps))                     # the last frame stepped with nothing asked
        for b, name in enumerate(styles):
            speed = np.linalg.norm(np.diff(r.root_positions[b, k0:], axis=0), axis=1) * fps   # [0]: the command's frame
            fast = np.flatnonzero(speed > GO_SPEED)
            frames[name].append(float(fast[0] + 1) if len(fast) else np.inf)
            half = int(round(0.5 * fps))
            metres[name].append(float(np.linalg.norm(r.root_positions[b, k0 + half] - r.root_positions[b, k0])))
    return {s: (float(np.mean(frames[s])), float(np.mean(metres[s]))) for s in styles}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--params", type=Path, default=DATA / "released-lpn")
    ap.add_argument("--styles", help="comma-separated (default: every style)")
    ap.add_argument("--walk", type=float, default=2.0)
    ap.add_argument("--idle", type=float, default=6.0)
    ap.add_argument("--off", action="store_true", help="without StandStill (the paper's loop)")
    ap.add_argument("--no-hold", action="store_true", help="StandStill(hold=False): root and phases only")
    ap.add_argument("--go", action="store_true", help="also measure the start after idling (3 stops per style)")
    args = ap.parse_args(argv)
    if not (args.params / "Xmean.bin").is_file():
        sys.exit(f"error: the released network is not at {args.params}")
    if args.walk < 1.0 or args.idle < 2.0:
        sys.exit("error: --walk must be at least 1 s and --idle at least 2 s (the rest is measured from 1 s after the stop)")
    src = DemoSource.released(args.params, calibrate=False)
    styles = args.styles.split(",") if args.styles else list(src.library.names)
    stand = None if args.off else StandStill(hold=not args.no_hold)
    mode = "off" if args.off else ("on, without the hold" if args.no_hold else "on")
    t0 = time.perf_counter()
    rows = measure(src, styles, args.walk, args.idle, stand)
    go = measure_go(src, styles, args.walk, min(args.idle, 3.0), stand) if args.go else None
    took = time.perf_counter() - t0
    print(f"# standing: {len(styles)} styles, walk {args.walk:g} s then idle {args.idle:g} s; stand-still {mode}; "
          f"{took:.0f} s; load {os.getloadavg()[0]:.1f}")
    print(f"{'style':17s} {'walk m/s':>8s} {'1st s':>6s} {'idle':>6s} {'max .25s':>8s} {'changes':>7s} "
          f"{'toes m/s':>8s} {'steps':>5s} {'turn deg':>8s}" + (f" {'go frames':>9s} {'m in .5s':>8s}" if go else "")
          + "  stands")
    standing = []
    for row in rows:
        ok = row["quarter"] < STAND_SPEED and row["changes"] == 0 and row["steps"] == 0
        standing.append(ok)
        extra = f" {go[row['style']][0]:9.1f} {go[row['style']][1]:8.2f}" if go else ""
        print(f"{row['style']:17s} {row['walk']:8.2f} {row['stop']:6.3f} {row['idle']:6.3f} {row['quarter']:8.3f} "
              f"{row['changes']:7d} {row['toe']:8.3f} {row['steps']:5d} {row['turn']:8.1f}{extra}  {'yes' if ok else 'NO'}")
    quarters = np.array([r["quarter"] for r in rows])
    print(f"# {sum(standing)} of {len(rows)} styles stand (max quarter-second speed < {STAND_SPEED} m/s, no contact "
          f"change, no toe faster than {TOE_SLOW} m/s); no contact change: {sum(r['changes'] == 0 for r in rows)}; "
          f"no step: {sum(r['steps'] == 0 for r in rows)}; median idle speed {np.median([r['idle'] for r in rows]):.3f} "
          f"m/s, worst {quarters.max():.3f} m/s ({rows[int(quarters.argmax())]['style']}); turned more than 5 degrees: "
          f"{sum(r['turn'] > 5 for r in rows)}")
    print("# not standing: " + (", ".join(r["style"] for r, ok in zip(rows, standing) if not ok) or "none"))
    if go:
        f = np.array([v[0] for v in go.values()])
        m = np.array([v[1] for v in go.values()])
        fin = np.isfinite(f)
        print(f"# start after {min(args.idle, 3.0):g} s idle (3 stops each): frames to > {GO_SPEED} m/s median "
              f"{np.median(f[fin]):.2f}, mean {f[fin].mean():.2f} over {fin.sum()} styles (never: "
              f"{', '.join(s for s, v in go.items() if not np.isfinite(v[0])) or 'none'}); metres in the first 0.5 s "
              f"median {np.median(m):.3f}, mean {m.mean():.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
