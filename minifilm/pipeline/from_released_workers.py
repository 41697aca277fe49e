"""Making the released network's data set (from_released.py) in worker processes, one BLAS thread
each, so that it uses every core: each worker drives a contiguous share of the styles.

    parent (make_released_dataset)                 worker w (spawned, minifilm/processes.py)
    params folder, output folder, settings;
    start W workers  ----------------------------> (one JSON text, given at its start)
    its share: style names + file stems  --------> load_released(params); a StyleDriver of its share
                                        <--------- ready
    calibrate  ----------------------------------> StyleDriver.calibrate() (if calibrating)
    gait FW  ------------------------------------> StyleDriver.gait('FW'): drive, write its
                                                   <stem>_FW.bvh files straight into the output
                                                   folder (the atomic_directory's temporary), label
                                        <--------- its rows (JSON: file, style, gait, frames, speed,
                                                   label agreement)
    gait BW, FR, ...  (each sent once the job two before it is back from every worker, so a
    worker always has its next gait waiting; the rows are collected gait by gait, worker 0's first)

The parent joins the rows in the order one process makes them (gait-major, then style order) and
writes manifest.csv and dataset.json itself. The file stems are made by the parent from all the
styles' names (style_file_names), so two styles of different shares never get one file name.

Why the data set is nearly the one of one process: each style's paths come from its own seeded
generator (style_seed), and a character of a batch rollout depends only on its own inputs (the
batch is the rows of the same matrix products), so a style drives the same in any share, to
float32 round-off (a batch of 2-4 characters takes the network's vector-product path,
runtime/network.py); the calibration's batches mix styles too, with the same argument. Tested
against one process (short files). Bit for bit, two workers of four styles write what one
process writes with ``batch=4`` (the same products); against another batch size the round-off
differs, and a few seconds of standing can grow it: 8 styles' TR1 and ID files, 1 worker against
2, all within 0.01 (cm, degrees) but Swimming's ID, 1.2. (A coupling between characters of one
batch -- a walker's feet kept as the held feet of another's stop, runtime/standing.py -- is
fixed; before, 7 of 160 TR1 files differed by up to 1.9 cm and 19 degrees.)

Errors: a worker's error comes back as one JSON line and is raised as the same error
(rebuilt_error), the first worker's first when several fail on one gait. A worker that dies raises
WorkerDied naming it, its process and what it was doing. Stopping: Ctrl-C or SIGTERM raise in the
parent (the workers ignore SIGINT), which terminates the workers on its way out of the ``with``
block, before the output folder's temporary is removed: the folder is left as it was, or whole.
Nothing is pickled (messages are JSON text).
"""
from __future__ import annotations

import json
from dataclasses import asdict
from multiprocessing import connection
from pathlib import Path
from typing import Dict, List, Sequence

import numpy as np

from minifilm.pipeline.released_driver import ReleasedDataSettings, StyleDriver
from minifilm.processes import WorkerGroup, rebuilt_error, serve, spawn
from minifilm.runtime.released import load_released


def worker(common_text: str, conn) -> None:
    """The target of a worker process: the params folder, output folder and settings from
    ``common_text`` (JSON), its share of the styles from the first message; then it calibrates
    or drives a gait for every job it is sent."""
    def setup():
        common, share = json.loads(common_text), json.loads(conn.recv_bytes())
        settings = ReleasedDataSettings(**common["settings"])
        return StyleDriver(load_released(Path(common["params"])), share["names"], share["stems"],
                           Path(common["folder"]), settings)

    def job(driver: StyleDriver, m: dict):
        if m["do"] == "calibrate":
            driver.calibrate()
            return len(driver.names)
        return driver.gait(m["gait"])
    serve(conn, setup, job)


class ReleasedWorkers(WorkerGroup):
    """``workers`` processes, each driving a contiguous share of ``names`` and writing its files
    into ``folder``; :meth:`calibrate` and :meth:`gait` are those of a :class:`StyleDriver` of all
    the styles, called in the job's order (calibrate if settings.calibrate, then settings.gaits).
    Use it as a context manager: the workers start when it is entered and are stopped when it is
    left, however it is left."""

    what = "from-released"

    def __init__(self, params: Path, names: Sequence[str], stems: Dict[str, str], folder: Path,
                 settings: ReleasedDataSettings, workers: int):
        bounds = np.linspace(0, len(names), workers + 1).round().astype(int)
        self.shares = [list(names[a:b]) for a, b in zip(bounds[:-1], bounds[1:])]
        self.stems, self.workers = stems, workers
        self.common = json.dumps({"params": str(params), "folder": str(folder),
                                  "settings": dict(asdict(settings), styles=None)})
        #: the jobs every worker is sent, in order
        self.plan = ([{"do": "calibrate"}] if settings.calibrate else []) + \
            [{"do": "gait", "gait": g} for g in settings.gaits]
        self.procs, self.conns = [], []
        self.sent = self.collected = 0          # jobs sent to every worker / collected from every worker
        self.answered = [0] * workers           # replies read from each worker ('ready' the first)

    def __enter__(self) -> "ReleasedWorkers":
        self.procs, self.conns = spawn(self.workers, worker, (self.common,), "minifilm-released-worker")
        try:        # (a few hundred bytes: the pipe holds them while a worker starts)
            for w, share in enumerate(self.shares):
                self._send(w, {"names": share, "stems": {n: self.stems[n] for n in share}})
        except BaseException as e:      # (a failed __enter__ gets no __exit__)
            self.__exit__(type(e), e, e.__traceback__)
            raise
        return self

    def calibrate(self) -> None:
        """Every worker calibrates its styles."""
        self._next({"do": "calibrate"})

    def gait(self, gait: str) -> List[dict]:
        """Every worker drives its styles along ``gait``; their rows in style order."""
        return [row for rows in self._next({"do": "gait", "gait": gait}) for row in rows]

    # ---- talking to the workers ------------------------------------------------------------------
    def _next(self, job: dict) -> list:
        """Every worker's answer to ``job``, which must be the next of the plan, in worker order."""
        k = self.collected
        if k >= len(self.plan) or self.plan[k] != job:
            raise RuntimeError(f"ReleasedWorkers: {job} asked for, but the next job is "
                               f"{self.plan[k] if k < len(self.plan) else 'none'}")
        while self.sent < min(k + 2, len(self.plan)):   # this job and the next one waiting in the pipes
            for w in range(self.workers):
                self._send(w, self.plan[self.sent])
            self.sent += 1
        replies = self._collect()
        self.collected += 1
        errors = [r for r in replies if "error" in r]
        if errors:                      # every reply read first; the first worker's error
            raise rebuilt_error(errors[0])
        return [r["ok"] for r in replies]

    def _collect(self) -> List[dict]:
        """Every worker's reply to the job being collected (after its 'ready'), whichever answers
        first; a worker that dies meanwhile raises WorkerDied at once."""
        replies: Dict[int, dict] = {}
        while len(replies) < self.workers:
            waiting = [w for w in range(self.workers) if w not in replies]
            ready = connection.wait([self.conns[w] for w in waiting] + [self.procs[w].sentinel for w in waiting])
            for w in waiting:
                if self.conns[w] in ready or self.procs[w].sentinel in ready:
                    starting = self.answered[w] == 0
                    reply = self._read(w)
                    if starting and "error" in reply:       # it could not start: it has ended
                        raise rebuilt_error(reply)
                    if not starting:
                        replies[w] = reply
        return [replies[w] for w in range(self.workers)]

    def _send(self, w: int, message: dict) -> None:
        self.send(w, message, self._doing(w))

    def _read(self, w: int) -> dict:
        reply = self.read(w, self._doing(w))
        self.answered[w] += 1
        return reply

    def _doing(self, w: int) -> str:
        """What worker w is doing: the first job it has not answered."""
        k = self.answered[w] - 1
        if k < 0:
            return "starting"
        if self.plan[k]["do"] == "calibrate":
            return f"calibrating the speeds of its {len(self.shares[w])} styles"
        return f"driving gait {self.plan[k]['gait']}"
