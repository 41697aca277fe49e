"""The straight walks of many FiLM vectors (walks.py), shared between this process and worker
processes. Refining a taught vector by its motion (motion_refit.py) walks the known styles once
and 18 vectors a round for 12 rounds: about a minute of one core. With workers, the known styles
walk in them while this process fits the vector teacher-forced (one of those fits goes to a
worker too, once its walks are done), and every round is split, this process walking a share:

    with WalkPool(network, layout, stats, workers=1) as pool:
        pending = pool.submit(films, speed, seconds)             # all in the workers; go on meanwhile
        fit = pool.submit_fit(rows, prior, start, settings)      # in worker 0, after its walks
        ...
        walks, faults = pool.walk(films, speed, seconds, check)  # split between all processes
        walks, faults = pending.result()
        fit.result()                                             # a FitResult

walks: each vector's window summaries (M, 2C); faults: what is wrong with each walk, kind -> how
bad (``check``, a :class:`~minifilm.pipeline.walks.FaultCheck`; none without one).

Why the answer is that of one process: a character of a batch rollout depends only on its own
vector (the batch is the rows of the same matrix products), so a vector walks the same in any
share, to float32 round-off (a share of 2-4 vectors takes the network's vector-product path,
runtime/network.py). Tested against one process.

A worker gets the network once, as an ``.npz`` of its arrays (RuntimeNetwork.to_arrays), and
reads its expert weights (20 MB for the released network) from one shared-memory segment that
this process reads too: one copy fits the processor's shared cache where two would not, and a
round of walks in two processes is about 12 % faster so. Then it gets jobs as JSON (the vectors
as base64 float32 bytes; a fit's rows and prior as ``.npz`` bytes after it) and answers with
``.npz`` bytes: nothing is pickled (minifilm/processes.py). For each worker one thread sends its
messages, so this process goes on while the worker is still starting (a pipe holds 64 KB; the
network is tens of MB and a worker reads it only once it has imported numpy), and one reads its
replies as they come, so a worker never waits with a reply this process has not asked for yet.
Worker processes and the segment are gone when the pool is left, however it is left; a worker
that dies raises WorkerDied naming it.
"""
from __future__ import annotations

import base64
import io
import itertools
import json
import os
import queue
import sys
import threading
from dataclasses import asdict
from multiprocessing import shared_memory
from typing import Callable, List, Mapping, Optional, Tuple

import numpy as np

from minifilm.dataset.stats import NormStats
from minifilm.evaluation.style_judge import summaries
from minifilm.features.layout import FeatureLayout
from minifilm.pipeline.walks import POSITION_BIAS, FaultCheck, walk_blocks
from minifilm.processes import (WithBytes, WorkerDied, WorkerGroup, attach, read_reply, rebuilt_error, serve,
                                 spawn, stop)
from minifilm.runtime.network import RuntimeNetwork
from minifilm.train.film_fit import FitResult, FitSettings, FrozenRows, StylePrior, fit_film

Walks = Tuple[List[np.ndarray], List[set]]
_segments = itertools.count()
#: seconds between a receiver thread's looks at its worker's pipe (the most leaving can wait for it)
RECEIVER_LOOKS = 0.05


def walk_here(network, layout, stats, films: np.ndarray, speed: float, seconds: float,
              check: Optional[Callable] = None, position_bias: float = POSITION_BIAS) -> Walks:
    """In this process: every vector's walk summaries, and the faults ``check`` finds (a mapping
    kind -> severity as FaultCheck gives, or a set of kinds from another check)."""
    films = np.asarray(films, np.float32)
    if not len(films):
        return [], []
    blocks, r = walk_blocks(network, layout, stats, films, speed, seconds, position_bias)
    return [summaries(b) for b in blocks], [_faults(check(r, b)) if check else {} for b in range(len(films))]


def _faults(found):
    return dict(found) if isinstance(found, Mapping) else set(found)


def _npz(arrays: dict) -> bytes:
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return buffer.getvalue()


def worker(layout_text: str, segment: str, conn) -> None:
    """The target of a worker process: the network (the first message, .npz bytes; its expert
    weights read from the shared-memory ``segment``) and the layout, then every job it is sent."""
    def setup():
        with np.load(io.BytesIO(conn.recv_bytes()), allow_pickle=False) as z:
            network = RuntimeNetwork.from_arrays(dict(z))
        shared = attach(segment)
        return network.sharing(shared.buf, fill=False), FeatureLayout.from_dict(json.loads(layout_text)), shared

    def job(state, m):
        network, layout, _ = state
        if m.get("kind") == "fit":
            return _fit_reply(m)
        films = np.frombuffer(base64.b64decode(m["films"]), "<f4").reshape(m["shape"])
        check = FaultCheck(**m["check"]) if m["check"] else None
        walks, faults = walk_here(network, layout, network.stats, films, m["speed"], m["seconds"], check,
                                  m["position_bias"])
        return WithBytes(faults, _npz({f"w{i}": w for i, w in enumerate(walks)}))     # FaultCheck: dicts
    serve(conn, setup, job)


def _fit_reply(m: dict) -> WithBytes:
    """A teacher-forced fit in a worker (:meth:`WalkPool.submit_fit`): its result as figures and arrays."""
    with np.load(io.BytesIO(m["data"]), allow_pickle=False) as z:
        arrays = dict(z)
    fit = fit_film(FrozenRows.from_arrays(arrays), StylePrior.from_arrays(arrays), arrays["start"],
                   FitSettings(**m["settings"]))
    figures = {k: getattr(fit, k) for k in ("start_loss", "loss", "holdout_loss", "steps", "best_step")}
    figures["history"] = [[float(v) for v in h] for h in fit.history]
    return WithBytes(figures, _npz({"film": fit.film, "snapshots": np.stack(fit.snapshots)}))


def _fit_result(reply: dict) -> FitResult:
    with np.load(io.BytesIO(reply["data"]), allow_pickle=False) as z:
        film, snapshots = z["film"], list(z["snapshots"])
    f = reply["ok"]
    history = [(int(s), loss, held) for s, loss, held in f["history"]]
    return FitResult(film, f["start_loss"], f["loss"], f["holdout_loss"], f["steps"], f["best_step"], history,
                     snapshots)


class Pending:
    """Work sent to the workers (:meth:`WalkPool.submit`, :meth:`WalkPool.submit_fit`); :meth:`result`
    waits for it. ``collect()`` reads its replies; a worker answers in the order it was sent work,
    so the pool reads every earlier piece of work's replies first."""

    def __init__(self, pool: "WalkPool", collect: Optional[Callable] = None, done=None):
        self.pool, self.collect, self.done, self.error = pool, collect, done, None
        self.asked = collect is None

    def read(self) -> None:
        """Read the replies, once; an error in the work is kept for :meth:`result`."""
        if not self.asked:
            self.asked = True
            try:
                self.done = self.collect()
            except WorkerDied:
                raise
            except Exception as e:      # noqa: BLE001 -- the work's own error, raised by result()
                self.error = e

    def result(self):
        self.pool._read_until(self)
        if self.error is not None:
            raise self.error
        return self.done


class WalkPool(WorkerGroup):
    """``workers`` processes beside this one walking vectors of ``network`` (module docstring);
    0 workers: everything in this process, no context needed. position_bias: the controller's
    (walks.candidate_rollouts)."""
    what = "walks"

    def __init__(self, network, layout: FeatureLayout, stats: NormStats, workers: int,
                 position_bias: float = POSITION_BIAS):
        self.network, self.layout, self.stats, self.workers = network, layout, stats, max(0, int(workers))
        self.position_bias = float(position_bias)
        self.procs, self.conns, self.pending, self.threads = [], [], [], []
        self.ready, self.outboxes, self.inboxes = [], [], []
        # with workers: the network whose expert weights are in the shared segment (the one copy
        # every process reads, so the CPU's shared cache can hold it); without, ``network``
        self.here, self.segment = network, None
        self.leaving = threading.Event()

    def __enter__(self) -> "WalkPool":
        if self.workers:
            try:
                self._start()
            except BaseException:
                self.__exit__(*sys.exc_info())
                raise
        return self

    def _start(self) -> None:
        """The shared weights, the worker processes and their sender and receiver threads."""
        self.leaving.clear()
        data = _npz(self.network.to_arrays())
        self.segment = shared_memory.SharedMemory(f"minifilm_{os.getpid()}_walks_{next(_segments)}",
                                                  create=True, size=self.network.expert_bytes)
        self.here = self.network.sharing(self.segment.buf, fill=True)
        self.procs, self.conns = spawn(self.workers, worker, (json.dumps(self.layout.to_dict()), self.segment.name),
                                       "minifilm-walk-worker")
        self.ready = [False] * self.workers
        self.outboxes = [queue.Queue() for _ in self.procs]
        self.inboxes = [queue.Queue() for _ in self.procs]
        self.threads = [threading.Thread(target=run, args=(w, self.conns[w]), daemon=True,
                                         name=f"minifilm-walk-{what}-{w}")
                        for w in range(self.workers)
                        for run, what in ((self._send_all, "sender"), (self._receive_all, "receiver"))]
        for t in self.threads:
            t.start()
        for w in range(self.workers):
            self._send(w, data)

    def __exit__(self, kind, error, trace) -> None:
        self.leaving.set()
        for box in self.outboxes:
            box.put(None)
        # (a send still blocked fails, and a receiver stops: the pipes are closed)
        stop(self.procs, self.conns, at_once=kind is not None)
        for t in self.threads:
            t.join(timeout=2.0)
        self.procs, self.conns, self.pending, self.threads = [], [], [], []
        self.here = self.network
        if self.segment is not None:
            segment, self.segment = self.segment, None
            try:
                segment.close()
            except BufferError:     # a view of it is still held somewhere: freed with that view
                pass
            segment.unlink()

    def sharing_words(self) -> str:
        """', shared with N worker process(es) (ids ...)' for a log line; '' without workers."""
        if not self.pids:
            return ""
        return (f", shared with {len(self.pids)} worker process{'es' if len(self.pids) > 1 else ''} "
                f"(ids {', '.join(map(str, self.pids))})")

    def submit(self, films: np.ndarray, speed: float, seconds: float, check: Optional[FaultCheck] = None) -> Pending:
        """Start the walks in the workers only (this process is free meanwhile); without workers,
        walk them now."""
        films = np.asarray(films, np.float32)
        if not self.procs:
            return Pending(self, done=walk_here(self.network, self.layout, self.stats, films, speed, seconds, check,
                                                self.position_bias))
        shares = self._send_shares(films, speed, seconds, check, len(self.procs))
        return self._pending(lambda: self._collect(shares))

    def submit_fit(self, rows: FrozenRows, prior: StylePrior, start: np.ndarray, settings: FitSettings,
                   worker: int = 0) -> Pending:
        """A teacher-forced fit (:func:`~minifilm.train.film_fit.fit_film`) in worker ``worker``, after
        the work it was sent before; without workers, fitted now. ``result()``: its FitResult,
        the same numbers as this process's."""
        if not self.procs:
            return Pending(self, done=fit_film(rows, prior, start, settings))
        w = int(worker) % len(self.procs)
        data = _npz({**rows.to_arrays(), **prior.to_arrays(), "start": np.asarray(start, np.float64)})
        self._send(w, json.dumps({"kind": "fit", "settings": asdict(settings), "bytes": len(data)}).encode())
        self._send(w, data)
        return self._pending(lambda: _fit_result(self._answer(w, "fitting a FiLM vector")))

    def walk(self, films: np.ndarray, speed: float, seconds: float, check: Optional[Callable] = None) -> Walks:
        """The walks, split between this process (the first share) and the workers."""
        films = np.asarray(films, np.float32)
        if not self.procs:
            return walk_here(self.network, self.layout, self.stats, films, speed, seconds, check, self.position_bias)
        if check is not None and not isinstance(check, FaultCheck):
            raise TypeError("WalkPool.walk: with workers, the check must be a FaultCheck (it is sent as JSON)")
        self._read_until(None)
        bounds = np.linspace(0, len(films), len(self.procs) + 2).round().astype(int)
        shares = self._send_shares(films[bounds[1]:], speed, seconds, check, len(self.procs), bounds[1:] - bounds[1])
        try:
            walks, faults = walk_here(self.here, self.layout, self.stats, films[:bounds[1]], speed, seconds, check,
                                      self.position_bias)
        except Exception:
            self._collect(shares)       # their replies read, so the pipes stay in step for the next walk
            raise
        theirs = self._collect(shares)
        return walks + theirs[0], faults + theirs[1]

    # ---- talking to the workers ------------------------------------------------------------------
    def _pending(self, collect: Callable) -> Pending:
        p = Pending(self, collect)
        self.pending.append(p)
        return p

    def _read_until(self, last: Optional[Pending]) -> None:
        """Read the replies of the work sent before ``last`` and of ``last`` (None: of all of it)."""
        while self.pending:
            p = self.pending.pop(0)
            p.read()
            if p is last:
                return

    def _send_shares(self, films, speed, seconds, check, n, bounds=None) -> List[int]:
        """Send worker w films[bounds[w]:bounds[w+1]] (default: n equal shares); -> the share sizes."""
        if bounds is None:
            bounds = np.linspace(0, len(films), n + 1).round().astype(int)
        sizes = []
        for w in range(n):
            share = np.ascontiguousarray(films[bounds[w]:bounds[w + 1]], "<f4")
            message = {"films": base64.b64encode(share.tobytes()).decode("ascii"), "shape": list(share.shape),
                       "speed": float(speed), "seconds": float(seconds), "check": check.to_dict() if check else None,
                       "position_bias": self.position_bias}
            self._send(w, json.dumps(message).encode())
            sizes.append(len(share))
        return sizes

    def _answer(self, w: int, doing: str) -> dict:
        """Worker w's reply to one piece of work; its error raised as this process's."""
        reply = self._reply(w, doing)
        if "error" in reply:
            raise rebuilt_error(reply)
        return reply

    def _collect(self, sizes: List[int]) -> Walks:
        walks, faults, error = [], [], None
        for w, n in enumerate(sizes):
            reply = self._reply(w, f"walking {n} vectors")
            if "error" in reply:
                error = error or rebuilt_error(reply)
                continue
            with np.load(io.BytesIO(reply["data"]), allow_pickle=False) as z:
                walks += [z[f"w{i}"] for i in range(n)]
            faults += [_faults(f) for f in reply["ok"]]
        if error is not None:           # every reply read first, so the pipes stay in step
            raise error
        return walks, faults

    def _send(self, w: int, data: bytes) -> None:
        """Queue a message for worker w: its sender thread sends it, so this process never waits
        for a worker still starting or busy to read it (a worker that has died is found by _reply)."""
        self.outboxes[w].put(data)

    def _send_all(self, w: int, conn) -> None:
        """Worker w's sender thread: the messages queued for it in order, until None."""
        while (data := self.outboxes[w].get()) is not None:
            try:
                conn.send_bytes(data)
            except Exception:       # noqa: BLE001 -- died, or its pipe closed by __exit__ mid-send: _reply says so
                pass

    def _receive_all(self, w: int, conn) -> None:
        """Worker w's receiver thread: its replies read as they come, so a worker never waits with
        a reply larger than the pipe holds while this process is busy; None once its pipe closes.
        It looks in now and then rather than wait on the pipe: a thread waiting on it would keep it
        open after __exit__ closes it, and the worker would not see that it is to leave."""
        while not self.leaving.is_set():
            try:
                if not conn.poll(RECEIVER_LOOKS):
                    continue
                reply = read_reply(conn)
            except (EOFError, OSError):     # it has died, or __exit__ closed the pipe
                break
            self.inboxes[w].put(reply)
        self.inboxes[w].put(None)

    def _reply(self, w: int, doing: str) -> dict:
        """Worker w's next reply (after its 'ready', the first time), its arrays in 'data'."""
        if not self.ready[w]:
            self.ready[w] = True
            reply = self._next(w, "starting")
            if "error" in reply:
                raise rebuilt_error(reply)
        return self._next(w, doing)

    def _next(self, w: int, doing: str) -> dict:
        reply = self.inboxes[w].get()
        if reply is None:
            self.inboxes[w].put(None)       # every later read says the same
            raise self.died(w, doing)
        return reply
