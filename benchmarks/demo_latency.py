"""Input-to-motion latency of the live demo on this machine (target: at most 100 ms).

    python benchmarks/demo_latency.py                   # 150 key changes, 3 runs (about a minute)
    python benchmarks/demo_latency.py --browser         # also through headless Chromium's keyboard

Starts ``minifilm demo --port 0`` in a process of its own on 127.0.0.1 and measures the time from
sending a key message (a new direction to walk in) to the arrival of the first frame whose
commanded direction is that new one: the server applies a page's messages at the start of the
next frame, so this is the wait for the next frame (up to 1/60 s), the frame itself, and the way
there and back. Messages are sent at random moments of the frame period, a person's rate (a
change every 80-160 ms), only to that server, and the script stops after --changes per run.

With --browser the same is measured inside a headless Chromium page (Debian's, with playwright):
a real key press (playwright's keyboard, through the browser's input pipeline) to the page's
``minifilmDemo.latencyMs`` (from the keydown handler's send to the first frame acknowledging it),
while the page also renders (on the CPU: SwiftShader, sharing the cores with the server).

Prints the median, 95th percentile and maximum per run, the minimum of the run medians, and the
1-minute load average (other work shares the cores).
"""
from __future__ import annotations

import argparse
import os
import random
import sys
import time

import numpy as np

from demo_soak import add_source_arguments, source_args  # this folder's soak script
from minifilm.demo.client import DemoClient
from minifilm.demo.process import DemoProcess

DIRECTIONS = [(0.0, 1.0), (1.0, 0.0), (0.0, -1.0), (-1.0, 0.0), (0.7, 0.7), (-0.7, 0.7)]
KEYS = ["KeyW", "KeyD", "KeyS", "KeyA"]


def expected_direction(frame: dict, move) -> np.ndarray:
    """Unit world direction of ``move`` (right, forward) at the frame's heading."""
    h = np.array(frame["heading"])
    right = np.array([-h[1], h[0]])
    d = move[1] * h + move[0] * right
    return d / np.linalg.norm(d)


def python_page(url: str, changes: int, rng: random.Random) -> np.ndarray:
    """Latencies (ms) of ``changes`` direction changes sent by a Python page."""
    out = []
    with DemoClient(url) as page:
        page.next_frame()
        current = None
        for _ in range(changes):
            move = rng.choice([d for d in DIRECTIONS if d != current])
            time.sleep(rng.uniform(0.08, 0.16))                  # a random moment in the frame period
            sent = time.perf_counter()
            seq = page.send({"type": "input", "move": list(move), "turn": 0.0, "speed": 0.0})
            while True:
                f = page.next_frame(timeout=5)
                v = np.array(f["velocity"])
                if f["ack"] is not None and f["ack"] >= seq and np.linalg.norm(v) > 0 and \
                        np.dot(v / np.linalg.norm(v), expected_direction(f, move)) > 0.999:
                    out.append(1e3 * (time.perf_counter() - sent))
                    break
            current = move
        page.send({"type": "input", "move": [0, 0], "turn": 0, "speed": 0})
    return np.array(out)


def browser_page(url: str, changes: int, rng: random.Random) -> np.ndarray:
    """Latencies (ms) measured by the demo page itself for real key presses in headless Chromium."""
    try:
        from playwright.sync_api import sync_playwright  # optional: only for --browser
    except ImportError:
        sys.exit("error: --browser needs playwright (pip install playwright) and Chromium at /usr/bin/chromium")
    out = []
    with sync_playwright() as p:
        chromium = p.chromium.launch(executable_path=os.environ.get("MINIFILM_CHROMIUM", "/usr/bin/chromium"),
                                     args=["--use-angle=swiftshader", "--enable-unsafe-swiftshader"])
        page = chromium.new_page(viewport={"width": 960, "height": 600})
        page.goto(url)
        for _ in range(600):
            if page.evaluate("window.minifilmDemo && minifilmDemo.ready && minifilmDemo.frames > 10"):
                break
            page.wait_for_timeout(50)
        key = None
        for _ in range(changes):
            new = rng.choice([k for k in KEYS if k != key])
            page.wait_for_timeout(rng.uniform(80, 160))
            if key:
                page.keyboard.up(key)                            # (sends "stop": not timed)
            page.wait_for_timeout(50)
            before = page.evaluate("minifilmDemo.sent")
            page.keyboard.down(new)
            for _ in range(200):                                 # until the frame for that key arrived
                got = page.evaluate(f"minifilmDemo.sent > {before} && minifilmDemo.frame.ack === "
                                    f"minifilmDemo.sent ? minifilmDemo.latencyMs : null")
                if got is not None:
                    out.append(got)
                    break
                page.wait_for_timeout(5)
            key = new
        page.keyboard.up(key)
        chromium.close()
    return np.array(out)


def report(label: str, runs) -> None:
    for i, ms in enumerate(runs, 1):
        print(f"{label} run {i}: {len(ms)} changes, median {np.median(ms):.1f} ms, 95th percentile "
              f"{np.percentile(ms, 95):.1f} ms, max {ms.max():.1f} ms, min {ms.min():.1f} ms")
    print(f"{label}: min of the run medians {min(np.median(ms) for ms in runs):.1f} ms (target <= 100 ms)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_source_arguments(ap)
    ap.add_argument("--changes", type=int, default=150, help="key changes per run")
    ap.add_argument("--repeat", type=int, default=3, help="runs (one server for all)")
    ap.add_argument("--browser", action="store_true", help="also measure through headless Chromium")
    args = ap.parse_args()
    rng = random.Random(0)
    print(f"# demo latency: {args.changes} changes x {args.repeat}; cores {os.cpu_count()}, "
          f"load {os.getloadavg()[0]:.2f}")
    server = DemoProcess(*source_args(args))
    assert server.url.startswith("http://127.0.0.1:")           # traffic stays on this machine
    try:
        report("python page", [python_page(server.url, args.changes, rng) for _ in range(args.repeat)])
        if args.browser:
            report("chromium page", [browser_page(server.url, max(20, args.changes // 3), rng)
                                     for _ in range(args.repeat)])
    finally:
        server.stop()
    print(f"# load after {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
