"""Does the live demo keep real time beside CPU-bound work, and does calibration spare its first minute?

    python benchmarks/demo_realtime.py                  # both parts (about 4 minutes)
    python benchmarks/demo_realtime.py --quick          # shorter walks and windows (about 1.5 minutes)
    python benchmarks/demo_realtime.py --run runs/train_small   # a trained run instead

Starts ``minifilm demo --port 0`` in a process of its own on 127.0.0.1 (as a user does, with a
new empty calibration cache in a temporary folder, removed at the end) and drives it with one
scripted page (a Python WebSocket client that reads every frame, as the browser does).

1. Real time beside CPU-bound processes. Once the start style's speed calibration is there, the
   page holds W (walk forward, 1.3 m/s asked) for --walk seconds with 0, 1 and 2 busy loops
   (``python -c "while True: pass"`` at this script's niceness) beside the server, started and
   killed by this script (always: also on Ctrl-C or an error). Per case: metres covered over
   seconds of wall time (the server's clock, ``t`` of the frames, so a client that reads late does
   not matter), its ratio to the commanded speed and to the speed of the case without busy loops,
   network steps per wall second (frame numbers over ``t``), the frames' ``behind`` / ``dropped``
   / ``stepsPerSecond``, the tasks runnable at its end (``runnable``, /proc/loadavg: the load
   average lags a 10 s case). The target holds when the speed is within 15 % of the commanded one, or
   when the frames said the loop was behind (``behind`` > 0 or ``dropped`` > 0), which the page shows.
2. Calibration against the first minute. A new server, a page at once holding W, and a switch to a
   style not yet calibrated every --window / 6 seconds (4 switches: each queues a measurement in
   the background worker). Steps per wall second, the intervals between frames (from ``t``) and
   the frames behind (``stepsPerSecond`` from the second second on: it counts the last second),
   over the first --window seconds and over a window of the same length from
   2 x --window seconds on. Not worse: steps per second at least 98 % of the later window's and
   the 95th percentile of the frame interval at most one frame period (1/60 s) above it.
   The released network's calibrations come with the package, so on it part 2 measures nothing
   unless ``--recalibrate`` is given (a run's styles are measured at its first start, as here).
   ``--only calibration --no-calibrate`` is the control: the same page with calibration off, to
   tell the calibration's cost from that of the other work on the machine. ``--busy N`` holds N
   busy loops beside the server for the whole of part 2 (the cores full, as on a shared machine:
   where a calibration that competes with the frame loop for the cores shows). ``gap_p99`` and
   ``late`` (frame intervals over two periods, 33 ms) show the stalls the 95th percentile hides.
   Printed too: when the frames first said every calibration asked for was measured.

Prints the CPU (/proc/cpuinfo), the cores and the 1-minute load average at the start and end
(other work shares the cores: the figures depend on it).
"""
from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import time

import numpy as np

from demo_soak import add_source_arguments, source_args  # this folder's soak script
from minifilm.demo.client import DemoClient
from minifilm.demo.process import DemoProcess

WALK = {"type": "input", "move": [0.0, 1.0], "turn": 0.0, "speed": 0.0}     # W held: 1.3 m/s asked
STOP = {"type": "input", "move": [0.0, 0.0], "turn": 0.0, "speed": 0.0}
TOLERANCE = 0.15                      # the target: within 15 % of commanded speed x wall time
NEW_STYLES = ("Zombie", "Old", "Drunk", "Angry", "Proud", "Robot")


def cpu_name() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return "unknown"


def load() -> float:
    return os.getloadavg()[0]


def runnable() -> int:
    """Tasks running or ready to run at this moment (/proc/loadavg; the 1-minute load average lags a
    10-second case by most of a minute). -1 where it cannot be read."""
    try:
        with open("/proc/loadavg") as f:
            return int(f.read().split()[3].split("/")[0])
    except (OSError, IndexError, ValueError):
        return -1


class BusyLoops:
    """``count`` CPU-bound Python processes, ended (SIGKILL) by :meth:`stop` or on leaving a ``with``."""

    def __init__(self, count: int):
        self.procs = []
        try:
            for _ in range(count):
                self.procs.append(subprocess.Popen([sys.executable, "-c", "while True: pass"],
                                                   stdin=subprocess.DEVNULL))
        except BaseException:
            self.stop()
            raise

    def stop(self) -> None:
        for p in self.procs:
            if p.poll() is None:
                p.kill()
            p.wait()
        self.procs = []

    def __enter__(self) -> "BusyLoops":
        return self

    def __exit__(self, *exc) -> None:
        self.stop()


def collect(page: DemoClient, seconds: float, schedule=()) -> list:
    """Every frame for ``seconds`` of this process's clock, as (t, n, x, z, behind, dropped,
    stepsPerSecond, calibration state, commanded, reachable); ``schedule``: (seconds, message)
    sent on the way."""
    rows, todo = [], sorted(schedule, key=lambda item: item[0])
    start = time.monotonic()
    while (now := time.monotonic() - start) < seconds:
        while todo and todo[0][0] <= now:
            page.send(todo.pop(0)[1])
        f = page.next_frame(timeout=10)
        rows.append((f["t"], f["n"], f["root"][0], f["root"][1], f["behind"], f["dropped"], f["stepsPerSecond"],
                     f["calibration"].get("state"), f["commanded"], f["reachable"]))
    return rows


def wait_calibrated(page: DemoClient, timeout: float = 300.0) -> float:
    """Seconds until the frames say the calibrations asked for are measured."""
    start = time.monotonic()
    while time.monotonic() - start < timeout:
        if page.next_frame(timeout=10)["calibration"].get("state") in ("done", "off"):
            return time.monotonic() - start
    raise RuntimeError(f"the start style's calibration was not measured within {timeout:.0f} s")


def walk_case(rows: list, busy: int) -> dict:
    t, n, x, z, behind, dropped, sps = (np.array([r[i] for r in rows], float) for i in range(7))
    wall = t[-1] - t[0]
    metres = float(np.hypot(x[-1] - x[0], z[-1] - z[0]))
    return dict(busy=busy, wall=wall, metres=metres, speed=metres / wall, commanded=rows[-1][8],
                reachable=rows[-1][9], steps_per_s=(n[-1] - n[0]) / wall, frames=len(rows),
                behind_frames=int((behind > 0).sum()), behind_max=int(behind.max()), dropped_max=int(dropped.max()),
                sps_median=float(np.median(sps)), sps_min=int(sps.min()))


def real_time(args, out) -> list:
    server = DemoProcess(*source_args(args))
    assert server.url.startswith("http://127.0.0.1:")           # traffic stays on this machine
    cases = []
    try:
        with DemoClient(server.url) as page:
            calibrated = wait_calibrated(page)
            out(f"# part 1: start style calibrated {calibrated:.1f} s after connecting (load {load():.2f})")
            page.send(WALK)
            collect(page, args.settle)                            # up to speed
            for busy in (0, 1, 2):
                with BusyLoops(busy):
                    collect(page, args.settle / 2)                # the scheduler shares the cores out
                    load_before = load()
                    case = walk_case(collect(page, args.walk), busy)
                    case["runnable"] = runnable()             # with the busy loops still running
                case.update(load_before=load_before, load_after=load())
                cases.append(case)
            page.send(STOP)
    finally:
        server.stop()
    base = cases[0]["speed"]
    for c in cases:
        c["ratio"] = c["speed"] / c["commanded"]
        c["vs_idle"] = c["speed"] / base
        c["shown"] = bool(c["behind_frames"] > 0 or c["dropped_max"] > 0)
        c["holds"] = bool(abs(c["ratio"] - 1) <= TOLERANCE or c["shown"])
    return cases


def window(rows: list, start: float, seconds: float, fps: float) -> dict:
    t0 = rows[0][0]
    part = [r for r in rows if start <= r[0] - t0 < start + seconds]
    t, n, behind, dropped = (np.array([r[i] for r in part], float) for i in (0, 1, 4, 5))
    # stepsPerSecond counts the last second: left out during the first second of the connection
    sps = np.array([r[6] for r in part if r[0] - t0 >= 1.0], float)
    gaps = 1e3 * np.diff(t)
    return dict(window=f"{start:.0f}-{start + seconds:.0f} s", steps_per_s=(n[-1] - n[0]) / (t[-1] - t[0]),
                sps_median=float(np.median(sps)), sps_min=int(sps.min()), frames_per_s=(len(t) - 1) / (t[-1] - t[0]),
                gap_median=float(np.median(gaps)), gap_p95=float(np.percentile(gaps, 95)), gap_max=float(gaps.max()),
                gap_p99=float(np.percentile(gaps, 99)), late=int((gaps > 2e3 / fps).sum()),
                behind_frames=int((behind > 0).sum()), dropped_max=int(dropped.max()),
                measuring=float(np.mean([r[7] == "measuring" for r in part])), period_ms=1e3 / fps)


def calibration_minute(args, out) -> list:
    server = DemoProcess(*source_args(args), *(["--no-calibrate"] if args.no_calibrate else []),
                         *(["--recalibrate"] if args.recalibrate else []))
    assert server.url.startswith("http://127.0.0.1:")
    try:
        with DemoClient(server.url) as page:
            names = page.hello["styles"]
            start_style = max(page.hello["style"], key=page.hello["style"].get)   # the start mix's main style
            picks = [s for s in NEW_STYLES if s in names and s != start_style][:4]
            picks += [s for s in names if s != start_style and s not in picks][:4 - len(picks)]
            schedule = [(0.0, WALK)] + [(args.switch_every * (i + 1), {"type": "style", "weights": {s: 1.0},
                                                                      "seconds": 1.0}) for i, s in enumerate(picks)]
            out(f"# part 2: styles {', '.join(picks)} (start style {start_style}), one every "
                f"{args.switch_every:g} s, windows of {args.window:g} s (load {load():.2f})")
            with BusyLoops(args.busy):
                rows = collect(page, 3 * args.window + 1, schedule)
            fps = page.hello["fps"]
    finally:
        server.stop()
    last_switch = schedule[-1][0]
    done = [r[0] - rows[0][0] for r in rows if r[0] - rows[0][0] > last_switch + 0.5 and r[7] in ("done", "off")]
    out(f"calibrations asked for all measured {done[0]:.1f} s after the page connected" if done else
        f"calibrations still being measured at the end ({rows[-1][0] - rows[0][0]:.0f} s)")
    return [window(rows, 0.0, args.window, fps), window(rows, 2 * args.window, args.window, fps)]


def table(rows: list, columns: list, out) -> None:
    def fmt(v):
        if isinstance(v, bool):
            return "yes" if v else "no"
        if isinstance(v, float):
            return f"{v:.3f}" if abs(v) < 10 else f"{v:.1f}"
        return str(v)
    cells = [[fmt(r[c]) for c in columns] for r in rows]
    widths = [max(len(c), *(len(row[i]) for row in cells)) for i, c in enumerate(columns)]
    out("  ".join(c.ljust(w) for c, w in zip(columns, widths)))
    out("  ".join("-" * w for w in widths))
    for row in cells:
        out("  ".join(v.ljust(w) for v, w in zip(row, widths)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_source_arguments(ap)
    ap.add_argument("--quick", action="store_true", help="5 s walks, 20 s windows")
    ap.add_argument("--walk", type=float, help="seconds of W held per case (default 10; --quick 5)")
    ap.add_argument("--window", type=float, help="seconds per window of part 2 (default 60; --quick 20)")
    ap.add_argument("--only", choices=("realtime", "calibration"), help="one part only")
    ap.add_argument("--busy", type=int, default=0, help="busy loops beside the server during part 2 (default 0)")
    ap.add_argument("--no-calibrate", action="store_true",
                    help="part 2 as a control: the same page and switches with the demo's calibration off")
    ap.add_argument("--recalibrate", action="store_true",
                    help="part 2 measures every calibration (the released network's come with the package: "
                         "without this flag its part 2 measures none)")
    args = ap.parse_args()
    args.walk = args.walk or (5.0 if args.quick else 10.0)
    args.window = args.window or (20.0 if args.quick else 60.0)
    args.settle = 2.0
    args.switch_every = args.window / 6
    # SIGTERM ends the script as Ctrl-C does, through every finally (busy loops killed, server stopped)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))

    def out(line: str) -> None:
        print(line, flush=True)
    start_load = load()
    out(f"# demo real time: CPU {cpu_name()}, cores {os.cpu_count()}, load {start_load:.2f} at start, "
        f"niceness {os.nice(0)}")
    if args.only != "calibration":
        cases = real_time(args, out)
        out(f"## real time: W held {args.walk:g} s per case beside 0/1/2 busy loops (target: speed within "
            f"{100 * TOLERANCE:.0f} % of commanded, or frames behind shown)")
        table(cases, ["busy", "wall", "metres", "speed", "commanded", "ratio", "vs_idle", "steps_per_s", "frames",
                      "behind_frames", "behind_max", "dropped_max", "sps_median", "sps_min", "runnable",
                      "load_before", "load_after", "shown", "holds"], out)
    if args.only != "realtime":
        windows = calibration_minute(args, out)
        first, later = windows
        worse = (first["steps_per_s"] < 0.98 * later["steps_per_s"]
                 or first["gap_p95"] > later["gap_p95"] + first["period_ms"])
        out(f"## calibration{' OFF (control)' if args.no_calibrate else ''}"
            f"{f', {args.busy} busy loop(s) beside' if args.busy else ''}: first {args.window:g} s vs a "
            f"later {args.window:g} s (fresh cache; "
            f"'measuring': share of frames while a calibration ran)")
        table(windows, ["window", "steps_per_s", "sps_median", "sps_min", "frames_per_s", "gap_median", "gap_p95",
                        "gap_p99", "gap_max", "late", "behind_frames", "dropped_max", "measuring"], out)
        out(f"first window worse than the later one: {'yes' if worse else 'no'}")
    out(f"# load {start_load:.2f} at start, {load():.2f} at end")


if __name__ == "__main__":
    main()
