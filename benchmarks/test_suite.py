"""Where the test suite's time goes: its wall time, peak memory and slowest tests.

    python benchmarks/test_suite.py                        # the whole suite
    python benchmarks/test_suite.py tests/nn tests/model   # or what pytest is given
    python benchmarks/test_suite.py -m gradcheck --top 20

Runs ``python -m pytest -q --durations=N`` (N = --durations, 40 by default) in a subprocess from
the repository root, shows its output as it goes, then prints the CPU, the load average before and
after, the wall time and the CPU time, the peak resident memory and the --top slowest tests (15 by
default). Every argument this script does not know is handed to pytest.

The peak memory is that of the largest single process of the run (pytest, or a process a test
starts), the figure ``/usr/bin/time -v`` calls "Maximum resident set size": ru_maxrss of
getrusage(RUSAGE_CHILDREN) once the run has ended, which covers every descendant that was waited
for. Not a test: run it on a machine as quiet as you can, and read the load beside the times.
"""
import argparse
import os
import re
import resource
import subprocess
import sys
import time
from pathlib import Path

from machine import cpu_name

ROOT = Path(__file__).resolve().parents[1]
#: a line of the --durations report: "12.34s call     <test id>"
DURATION = re.compile(r"^(\d+\.\d+)s (setup|call|teardown)\s+(\S.*)$")


def load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--durations", type=int, default=40, help="pytest's --durations (default 40)")
    ap.add_argument("--top", type=int, default=15, help="how many of the slowest tests to list (default 15)")
    args, pytest_args = ap.parse_known_args()

    before = load()
    command = [sys.executable, "-m", "pytest", "-q", f"--durations={args.durations}", *pytest_args]
    print("$ python", " ".join(command[1:]), flush=True)
    start = time.perf_counter()
    lines = []
    env = dict(os.environ, PYTHONUNBUFFERED="1")          # its progress as it goes, not in blocks
    with subprocess.Popen(command, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                          errors="replace") as run:
        for line in run.stdout:               # shown as it comes, kept for the summary
            sys.stdout.write(line)
            lines.append(line.rstrip("\n"))
    wall = time.perf_counter() - start
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)     # the run's whole tree, once it has ended

    slowest = sorted(((float(m[1]), m[2], m[3]) for m in map(DURATION.match, lines) if m), reverse=True)
    outcome = next((line.strip("= ") for line in reversed(lines) if re.search(r"\d+ (passed|failed|error)", line)),
                   "no summary line")
    print(f"\nCPU          {cpu_name()}, {os.cpu_count()} cores")
    print(f"load         {before} before, {load()} after (1, 5, 15 min)")
    print(f"result       {outcome} (exit code {run.returncode})")
    print(f"wall time    {wall:.0f} s ({wall / 60:.1f} min)")
    print(f"CPU time     {usage.ru_utime + usage.ru_stime:.0f} s (user + system; beside the wall time on a busy machine)")
    print(f"peak memory  {usage.ru_maxrss / 1024 ** 2:.2f} GB (largest process)")         # ru_maxrss: kB on Linux
    print(f"\n{min(args.top, len(slowest))} slowest of the {len(slowest)} durations pytest reported:")
    for seconds, phase, test in slowest[:args.top]:
        print(f"  {seconds:8.2f} s  {phase:<8}  {test}")
    return run.returncode


if __name__ == "__main__":
    sys.exit(main())
