"""What machine a benchmark ran on, for its report (no side effects on import, unlike common.py)."""
from __future__ import annotations

import os
import platform


def cpu_name() -> str:
    """The CPU's model name, family and model from /proc/cpuinfo (Linux: a VM may call every AMD
    EPYC just that; family 25 is Zen 3 or 4, model 17 Zen 4, family 26 Zen 5), else what platform
    knows."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            info = {}
            for line in f:
                key, _, value = line.partition(":")
                info.setdefault(key.strip(), value.strip())
        return f"{info['model name']} (family {info['cpu family']}, model {info['model']})"
    except (OSError, KeyError):
        return platform.processor() or "unknown CPU"


def autogroup() -> str:
    """Whether Linux's autogroup scheduling is on: then all processes of one login session (a
    command and its worker processes) share ONE group's part of the CPUs against the other login
    sessions, so on a shared machine a second worker process may only split that part."""
    try:
        with open("/proc/sys/kernel/sched_autogroup_enabled") as f:
            on = f.read().strip() == "1"
    except OSError:
        return "autogroup scheduling unknown"
    return "autogroup scheduling on (the processes of one login session share one group's CPU)" if on else "no autogroup"


def load() -> str:
    """The load averages over 1, 5 and 15 minutes (other processes sharing the cores make timings noisy)."""
    try:
        return "load average " + " / ".join(f"{x:.2f}" for x in os.getloadavg()) + " (1 / 5 / 15 min)"
    except OSError:
        return "load average unknown"
