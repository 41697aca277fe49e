"""The straight walks of many FiLM vectors (walks.py), shared between this process and worker
processes. Refining a taught vector by its motion (motion_refit.py) walks the known styles once
and 18 vectors a round for 12 rounds: about a minute of one core. With workers, the known styles
walk in them while this process fits the vector teacher-forced, and every round is split, this
process walking a share too:

    with WalkPool(network, layout, stats, workers=1) as pool:
        pending = pool.submit(films, speed, seconds)             # all in the workers; go on meanwhile
        ...
        walks, faults = pool.walk(films, speed, seconds, check)  # split between all processes
        walks, faults = pending.result()

walks: each vector's window summaries (M, 2C); faults: the kinds of what is wrong with each walk
(``check``, a :class:`~minifilm.pipeline.walks.FaultCheck`; none without one).

Why the answer is that of one process: a character of a batch rollout depends only on its own
vector (the batch is the rows of the same matrix products), so a vector walks the same in any
share, to float32 round-off (a share of 2-4 vectors takes the network's vector-product path,
runtime/network.py). Tested against one process.

A worker gets the network once, as an ``.npz`` of its arrays (RuntimeNetwork.to_arrays), then
jobs as JSON (the vectors as base64 float32 bytes) and answers with the summaries as ``.npz``
bytes: nothing is pickled (minifilm/processes.py). A thread sends the messages, so this process
goes on while a worker is still starting (a pipe holds 64 KB; the network is tens of MB and a
worker reads it only once it has imported numpy). Worker processes are stopped when the pool is
left, however it is left; a worker that dies raises WorkerDied naming it.
"""
from __future__ import annotations

import base64
import io
import json
import queue
import threading
from typing import Callable, List, Optional, Tuple

import numpy as np

from minifilm.dataset.stats import NormStats
from minifilm.evaluation.style_judge import summaries
from minifilm.features.layout import FeatureLayout
from minifilm.pipeline.walks import FaultCheck, walk_blocks
from minifilm.processes import WithBytes, WorkerGroup, rebuilt_error, serve, spawn, stop
from minifilm.runtime.network import RuntimeNetwork

Walks = Tuple[List[np.ndarray], List[set]]


def walk_here(network, layout, stats, films: np.ndarray, speed: float, seconds: float,
              check: Optional[Callable] = None) -> Walks:
    """In this process: every vector's walk summaries, and the kinds of fault ``check`` finds."""
    films = np.asarray(films, np.float32)
    if not len(films):
        return [], []
    blocks, r = walk_blocks(network, layout, stats, films, speed, seconds)
    return [summaries(b) for b in blocks], [set(check(r, b)) if check else set() for b in range(len(films))]


def _npz(arrays: dict) -> bytes:
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return buffer.getvalue()


def worker(layout_text: str, conn) -> None:
    """The target of a worker process: the network (the first message, .npz bytes) and the layout,
    then the walks of every job it is sent."""
    def setup():
        with np.load(io.BytesIO(conn.recv_bytes()), allow_pickle=False) as z:
            network = RuntimeNetwork.from_arrays(dict(z))
        return network, FeatureLayout.from_dict(json.loads(layout_text))

    def job(state, m):
        network, layout = state
        films = np.frombuffer(base64.b64decode(m["films"]), "<f4").reshape(m["shape"])
        check = FaultCheck(**m["check"]) if m["check"] else None
        walks, faults = walk_here(network, layout, network.stats, films, m["speed"], m["seconds"], check)
        return WithBytes([sorted(f) for f in faults], _npz({f"w{i}": w for i, w in enumerate(walks)}))
    serve(conn, setup, job)


class Pending:
    """Walks sent to the workers by :meth:`WalkPool.submit`; :meth:`result` waits for them."""

    def __init__(self, pool: "WalkPool", shares: List[int], done: Optional[Walks] = None):
        self.pool, self.shares, self.done, self.asked = pool, shares, done, done is not None

    def result(self) -> Walks:
        if not self.asked:              # the replies are read once, whatever happens
            self.asked, self.pool.pending = True, None
            self.done = self.pool._collect(self.shares)
        if self.done is None:
            raise RuntimeError("WalkPool: these walks failed (the error was raised when they were collected)")
        return self.done


class WalkPool(WorkerGroup):
    """``workers`` processes beside this one walking vectors of ``network`` (module docstring);
    0 workers: everything in this process, no context needed."""
    what = "walks"

    def __init__(self, network, layout: FeatureLayout, stats: NormStats, workers: int):
        self.network, self.layout, self.stats, self.workers = network, layout, stats, max(0, int(workers))
        self.procs, self.conns, self.pending, self.sender = [], [], None, None
        self.ready, self.outbox = [], None

    def __enter__(self) -> "WalkPool":
        if self.workers:
            data = _npz(self.network.to_arrays())
            self.procs, self.conns = spawn(self.workers, worker, (json.dumps(self.layout.to_dict()),),
                                           "minifilm-walk-worker")
            self.ready = [False] * self.workers
            self.outbox = queue.Queue()
            self.sender = threading.Thread(target=self._send_all, daemon=True, name="minifilm-walk-sender")
            self.sender.start()
            for w in range(self.workers):
                self._send(w, data)
        return self

    def __exit__(self, kind, error, trace) -> None:
        if self.sender is not None:
            self.outbox.put(None)
        # (a send still blocked fails: its pipe is closed)
        stop(self.procs, self.conns, at_once=kind is not None)
        if self.sender is not None:
            self.sender.join(timeout=2.0)
        self.procs, self.conns, self.pending, self.sender = [], [], None, None

    def submit(self, films: np.ndarray, speed: float, seconds: float, check: Optional[FaultCheck] = None) -> Pending:
        """Start the walks in the workers only (this process is free meanwhile); without workers,
        walk them now."""
        films = np.asarray(films, np.float32)
        if not self.procs:
            return Pending(self, [], walk_here(self.network, self.layout, self.stats, films, speed, seconds, check))
        self._finish_pending()
        shares = self._send_shares(films, speed, seconds, check, len(self.procs))
        self.pending = Pending(self, shares)
        return self.pending

    def walk(self, films: np.ndarray, speed: float, seconds: float, check: Optional[Callable] = None) -> Walks:
        """The walks, split between this process (the first share) and the workers."""
        films = np.asarray(films, np.float32)
        if not self.procs:
            return walk_here(self.network, self.layout, self.stats, films, speed, seconds, check)
        if check is not None and not isinstance(check, FaultCheck):
            raise TypeError("WalkPool.walk: with workers, the check must be a FaultCheck (it is sent as JSON)")
        self._finish_pending()
        bounds = np.linspace(0, len(films), len(self.procs) + 2).round().astype(int)
        shares = self._send_shares(films[bounds[1]:], speed, seconds, check, len(self.procs), bounds[1:] - bounds[1])
        try:
            walks, faults = walk_here(self.network, self.layout, self.stats, films[:bounds[1]], speed, seconds, check)
        except Exception:
            self._collect(shares)       # their replies read, so the pipes stay in step for the next walk
            raise
        theirs = self._collect(shares)
        return walks + theirs[0], faults + theirs[1]

    # ---- talking to the workers ------------------------------------------------------------------
    def _finish_pending(self) -> None:
        if self.pending is not None:
            self.pending.result()

    def _send_shares(self, films, speed, seconds, check, n, bounds=None) -> List[int]:
        """Send worker w films[bounds[w]:bounds[w+1]] (default: n equal shares); -> the share sizes."""
        if bounds is None:
            bounds = np.linspace(0, len(films), n + 1).round().astype(int)
        sizes = []
        for w in range(n):
            share = np.ascontiguousarray(films[bounds[w]:bounds[w + 1]], "<f4")
            message = {"films": base64.b64encode(share.tobytes()).decode("ascii"), "shape": list(share.shape),
                       "speed": float(speed), "seconds": float(seconds), "check": check.to_dict() if check else None}
            self._send(w, json.dumps(message).encode())
            sizes.append(len(share))
        return sizes

    def _collect(self, sizes: List[int]) -> Walks:
        walks, faults, error = [], [], None
        for w, n in enumerate(sizes):
            reply = self._reply(w, f"walking {n} vectors")
            if "error" in reply:
                error = error or rebuilt_error(reply)
                continue
            with np.load(io.BytesIO(reply["data"]), allow_pickle=False) as z:
                walks += [z[f"w{i}"] for i in range(n)]
            faults += [set(f) for f in reply["ok"]]
        if error is not None:           # every reply read first, so the pipes stay in step
            raise error
        return walks, faults

    def _send(self, w: int, data: bytes) -> None:
        """Queue a message for worker w: the sender thread sends it, so this process never waits
        for a worker still starting to read it (a worker that has died is found by _reply)."""
        self.outbox.put((w, data))

    def _send_all(self) -> None:
        """The sender thread: the queued messages in order, until None."""
        while (item := self.outbox.get()) is not None:
            w, data = item
            try:
                self.conns[w].send_bytes(data)
            except Exception:       # noqa: BLE001 -- died, or its pipe closed by __exit__ mid-send: _reply says so
                pass

    def _reply(self, w: int, doing: str) -> dict:
        """Worker w's next reply (after its 'ready', the first time), its arrays in 'data'."""
        if not self.ready[w]:
            self.ready[w] = True
            reply = self.read(w, "starting")
            if "error" in reply:
                raise rebuilt_error(reply)
        return self.read(w, doing)
