"""The speed-calibration worker process of the demo (see ``calibrations.py``).

This module is what a spawned worker imports first, so it imports nothing that loads numpy at
its top: :func:`start` first gives the worker one BLAS thread and a low priority, then loads the
network. (OpenBLAS reads its thread count once, when numpy is imported; with two threads each a
batch-1 step spins on a shared machine, and the worker's measurement took 40 times longer.)
"""
from __future__ import annotations

import os
import threading
import time

_SOURCE = None


def start(params: str, pack: str = "") -> None:
    """Worker initialiser: one BLAS thread, nice 10 (the frame loop comes first; not SCHED_IDLE,
    which on a busy shared machine starved the measurement for minutes), the released
    network, and a watch on the server: the worker ends when the server has gone, however it went
    (killed, it cannot shut its pool down)."""
    global _SOURCE
    parent = os.getppid()

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(1.0)
        os._exit(0)
    threading.Thread(target=watch, name="parent-watch", daemon=True).start()
    for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[name] = "1"
    try:
        os.nice(10)
    except OSError:
        pass
    # after the thread count is set: this imports numpy
    from minifilm.demo.source import DemoSource
    _SOURCE = DemoSource.released(params, calibrate=True, pack=pack or None)


def measure_style(name: str):
    """The SpeedCalibration of style ``name`` (in the worker)."""
    return measure(_SOURCE, name)


def measure(source, name: str):
    """The SpeedCalibration of style ``name`` of a :class:`~minifilm.demo.source.DemoSource` (in the
    worker, or in the server's process when there is no worker)."""
    from minifilm.runtime.calibration import calibrate_speed   # here: numpy loads after the
    from minifilm.runtime.controller import Controller         # worker's thread count is set
    ctrl = Controller(source.network, source.layout, fps=source.fps, **source.options)
    x, p = source.starts.get(name, (None, None))
    return calibrate_speed(ctrl, source.library[name], phases=p, start_x=x)
