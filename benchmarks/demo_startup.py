"""How long from ``minifilm demo`` starting to its page being served? (target: at most 3 s)

    python benchmarks/demo_startup.py                    # 3 starts, each with an empty calibration cache
    python benchmarks/demo_startup.py --repo /path/to/other/checkout   # another version (e.g. main)

Each start runs ``python -m minifilm demo --params DIR --port 0`` in a process of its own (the
code of --repo, default this checkout, through PYTHONPATH), and times from just before the process
is started to the end of the first ``GET /`` answered with 200 (the URL it prints). The
speed-calibration cache is a new temporary folder per start (so nothing is cached: the slowest
case), never the user's. Reported: each time, the minimum and the median, with the
1-minute load average and the CPU (the machine is shared: the minimum is the start-up's own cost).
"""
from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

from machine import cpu_name

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("MINIFILM_SHARED_DATA", ROOT.parent / "shared" / "data"))
URL = re.compile(r"http://127\.0\.0\.1:\d+/")


def start_once(repo: Path, params: Path, cache: str, timeout: float = 300.0) -> float:
    env = dict(os.environ, PYTHONPATH=str(repo), MINIFILM_CACHE=cache)
    started = time.monotonic()
    proc = subprocess.Popen([sys.executable, "-m", "minifilm", "demo", "--params", str(params), "--port", "0"],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env, cwd=repo)
    try:
        seen = ""
        while True:
            line = proc.stdout.readline()
            if not line:
                raise RuntimeError("the demo ended before serving:\n" + seen)
            seen += line
            found = URL.search(line)
            if found:
                break
            if time.monotonic() - started > timeout:
                raise RuntimeError("no URL in time:\n" + seen)
        opener = urllib.request.build_opener(urllib.request.ProxyHandler({}))
        with opener.open(found.group(0), timeout=30) as r:
            r.read()
            assert r.status == 200
        return time.monotonic() - started
    finally:
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--params", type=Path, default=DATA / "released-lpn")
    ap.add_argument("--repo", type=Path, default=ROOT, help="the checkout whose code is started")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    load = os.getloadavg()[0]
    times = []
    with tempfile.TemporaryDirectory(prefix="minifilm-startup-") as tmp:
        for _ in range(args.repeat):
            times.append(start_once(args.repo, args.params, tempfile.mkdtemp(dir=tmp)))
    print(f"# demo start-up ({args.repo}): command start -> page "
          f"served; CPU {cpu_name()}, {os.cpu_count()} cores; load {load:.1f} before, {os.getloadavg()[0]:.1f} after")
    print("  " + ", ".join(f"{t:.2f} s" for t in times))
    print(f"  min {min(times):.2f} s, median {statistics.median(times):.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
