"""The live demo page's own cost: its frame time in the browser, with the mannequin and with sticks.

    python benchmarks/page_draw.py                    # 3 runs of 12 s per drawing (about 2 minutes)
    python benchmarks/page_draw.py --seconds 20 --repeat 5 --size 1280x720

Starts ``minifilm demo --port 0`` (the released network, in a process of its own) and opens its
page in headless Chromium (Debian's, through playwright; WebGL on the CPU: SwiftShader, as in the
browser tests). The page walks in a circle (W and E held) and the time between the page's
``requestAnimationFrame`` callbacks is read from ``minifilmDemo.drawIntervals()`` (the last 1,200
drawn frames; the first 2 s of each drawing are left out). A browser calls the page at most at
the display rate (60 Hz here), so a median of 16.7 ms means the page kept up; more means drawing a
frame took longer. Each run measures the body (mannequin, the default) and the sticks one after
the other, in alternating order. Prints per drawing the median and 99th percentile of every run,
the minimum over runs of each, the triangles three.js drew per frame, the CPU time all of the
browser's processes (and playwright's driver) used per drawn frame (from /proc: less sensitive to
the load than the intervals, since software WebGL draws on the CPU), and the 1-minute load average
(other work shares the cores). The server's own frame time is demo_soak.py's.
"""
from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

from minifilm.demo.process import DemoProcess
from machine import cpu_name

DATA = Path(os.environ.get("MINIFILM_SHARED_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))
CHROMIUM = os.environ.get("MINIFILM_CHROMIUM", "/usr/bin/chromium")
ARGS = ["--use-angle=swiftshader", "--enable-unsafe-swiftshader"]


def descendants(root: int, skip: int) -> list:
    """Process ids under ``root`` (Linux /proc), leaving out ``skip`` and its children."""
    parent = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as f:
                    parent[int(entry)] = int(f.read().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                pass
    out, todo = [], [root]
    while todo:
        p = todo.pop()
        for child, par in parent.items():
            if par == p and child != skip:
                out.append(child)
                todo.append(child)
    return out


def cpu_seconds(pids) -> float:
    """User + system CPU seconds of ``pids`` so far."""
    total = 0
    for pid in pids:
        try:
            with open(f"/proc/{pid}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
            total += int(fields[11]) + int(fields[12])
        except (OSError, IndexError, ValueError):
            pass
    return total / os.sysconf("SC_CLK_TCK")


def measure(page, body: bool, seconds: float, pids) -> dict:
    page.evaluate(f"minifilmDemo.setToggle('body', {str(body).lower()})")
    page.wait_for_timeout(2000)                                   # settle; these intervals are dropped
    start, cpu0 = page.evaluate("performance.now()"), cpu_seconds(pids)
    page.wait_for_timeout(int(seconds * 1000))
    cpu = cpu_seconds(pids) - cpu0
    kept = np.array(page.evaluate(f"minifilmDemo.drawIntervals({start})"))
    info = page.evaluate("minifilmDemo.renderInfo()")
    return {"median": float(np.median(kept)), "p99": float(np.percentile(kept, 99)), "frames": len(kept),
            "fps": len(kept) / seconds, "cpu_ms": 1e3 * cpu / max(1, len(kept)),
            "triangles": info["triangles"], "meshes": info["meshes"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--params", type=Path, default=DATA / "released-lpn")
    ap.add_argument("--seconds", type=float, default=12.0, help="measured seconds per drawing and run")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--size", default="960x600", help="the browser window, WxH pixels")
    args = ap.parse_args()
    w, h = (int(v) for v in args.size.split("x"))
    from playwright.sync_api import sync_playwright             # optional: benchmarks and browser tests only
    results = {True: [], False: []}
    loads = []
    with DemoProcess("--params", args.params, "--no-calibrate") as demo, sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        page = browser.new_page(viewport={"width": w, "height": h})
        page.goto(demo.url)
        for _ in range(600):
            if page.evaluate("window.minifilmDemo && minifilmDemo.ready && minifilmDemo.frames > 10"):
                break
            time.sleep(0.1)
        page.keyboard.down("KeyW")
        page.keyboard.down("KeyE")
        pids = descendants(os.getpid(), skip=demo.proc.pid)          # the browser's processes and driver
        for r in range(args.repeat):
            for body in ((True, False) if r % 2 == 0 else (False, True)):
                results[body].append(measure(page, body, args.seconds, pids))
                loads.append(os.getloadavg()[0])
        browser.close()
    print(f"demo page frame time (requestAnimationFrame intervals), headless Chromium + SwiftShader, "
          f"{w}x{h}, {cpu_name()}, {os.cpu_count()} cores, load {min(loads):.1f}-{max(loads):.1f}")
    for body, name in ((True, "mannequin"), (False, "sticks")):
        rs = results[body]
        medians = ", ".join(f"{x['median']:.1f}" for x in rs)
        p99s = ", ".join(f"{x['p99']:.1f}" for x in rs)
        print(f"  {name:9s}: median {min(x['median'] for x in rs):.1f} ms (runs {medians}), "
              f"p99 {min(x['p99'] for x in rs):.1f} ms (runs {p99s}), {rs[0]['triangles']} triangles, "
              f"{rs[0]['meshes']} meshes drawn, {np.mean([x['fps'] for x in rs]):.1f} drawn frames/s, "
              f"browser CPU {min(x['cpu_ms'] for x in rs):.1f} ms per drawn frame (min over runs)")


if __name__ == "__main__":
    main()
