"""Data-parallel training: each minibatch's forward and backward pass split across worker
processes, one BLAS thread each, so that training uses every core.

    parent                                     worker w (parallel_worker.py), w = 0 .. W-1
    draw the minibatch and its dropout masks   (the same draws, in the same order, as one
    (the trainer's generator, as in one          process makes: results do not depend on W)
    process); write it to shared memory  --->  1. forward + backward on rows lo_w:hi_w, the
                                                  gradient of (n_w / B) x its mean loss into
                                                  its own slot of the shared gradient buffer
                                         --->  2. the sum of the W slots over its part
                                                  a_w:b_w of the parameter vector, into the one
                                                  gradient buffer the trainer reads
    check the losses and the gradient,
    count the Adam step (ChunkedAdam.advance)
                                         --->  3. that Adam step on parameters a_w:b_w
                                                  (weights and moments in shared memory)

The sum and the Adam update are element by element, so splitting them by parameter changes no
number: it is ONE Adam step of the parameters, the same as ChunkedAdam.step in one process, only
computed by W processes at once (in one process they took ~30 % of a step, which would cap the
speed-up of 2 workers near 1.5x). A NaN or inf stops training after phase 2, before any weight
changes (Trainer.check_finite).

Why it equals one process: the losses are means over the minibatch's rows, so the gradient of
the whole minibatch is the sum over workers of (n_w / B) x the gradient of their share's mean;
the dropout keep-masks are drawn by the parent for the whole minibatch exactly as the one-process
forward pass draws them (site by site: Ψ, then Ω, then Φ) and each worker gets its rows of
them. Only the order of float32 sums changes (tests/train/test_parallel.py: 1e-6 relative).

With clips shared by the minibatch (TrainConfig.clips_per_batch), the samples are ordered by
their clip and split at clip boundaries, so each worker runs Ψ on its own clips only; with fewer
clips than workers a clip's Ψ runs in every worker that has samples of it (its gradient is still
the sum of its samples'). Shares may then be unequal; the weights n_w / B keep the mean right.

Processes: started with 'spawn' (a fresh interpreter: nothing of the parent's threads, locks or
BLAS state is inherited, so it is safe whatever the parent runs; and it is the start method every
platform has), with
OPENBLAS/OMP/MKL_NUM_THREADS=1 in their environment. They ignore SIGINT; the parent stops them
when it leaves (finished, Ctrl-C, SIGTERM, an error, a worker that died), and a worker stops by
itself when the parent's end of its pipe closes. The shared-memory segments are named
``minifilm_<parent pid>_<n>`` and unlinked by the parent on the way out. A worker that dies (killed,
out of memory) stops training with :class:`WorkerDied`, one message; when that happens before
phase 3 the weights are untouched by the step (during phase 3 they are partly updated, and the
run stops all the same; the checkpoints already written are whole).
"""
from __future__ import annotations

import contextlib
import itertools
import json
import math
import multiprocessing
import os
import signal
import threading
import time
from multiprocessing import connection, shared_memory

import numpy as np

from minifilm.model.style_model import StyleModel
from minifilm.nn.fast_optim import ChunkedAdam
from minifilm.train import parallel_worker

ONE_BLAS_THREAD = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
_names = itertools.count()


class WorkerDied(ChildProcessError):
    """A worker process of data-parallel training ended or failed during a step (an OSError, so the
    command prints it as one line); the weights were not updated with that step."""


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity; os.cpu_count() where that is unknown)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def supports(model) -> bool:
    """Data-parallel steps need the paper's StyleModel with its FiLM generator Ψ (the comparison
    variants of minifilm.baselines train in one process)."""
    return type(model) is StyleModel and model.film is not None


def shares(batch: int, clip_index, n_clips: int, workers: int):
    """[(lo, hi, clo, chi)] per worker: rows lo:hi of the minibatch and the clips clo:chi they use.
    clip_index (batch,) sorted ascending (the rows ordered by clip), or None: one clip per sample
    (clip rows = sample rows)."""
    if clip_index is None:
        return [(w * batch // workers, (w + 1) * batch // workers) * 2 for w in range(workers)]
    counts = np.bincount(clip_index, minlength=n_clips)
    starts = np.concatenate([[0], np.cumsum(counts)])          # rows of clip j: starts[j]:starts[j+1]
    out = []
    for w in range(workers):
        if n_clips >= workers:                                  # split at clip boundaries
            clo, chi = w * n_clips // workers, (w + 1) * n_clips // workers
            lo, hi = int(starts[clo]), int(starts[chi])
        else:                                                   # split the rows; clips may repeat
            lo, hi = w * batch // workers, (w + 1) * batch // workers
            if hi == lo:
                out.append((lo, hi, 0, 0))
                continue
            clo, chi = int(clip_index[lo]), int(clip_index[hi - 1]) + 1
        out.append((lo, hi, clo, chi))
    return out


class DataParallel:
    """W worker processes computing the gradients of a :class:`~minifilm.train.trainer.Trainer`'s
    minibatches. Use as a context manager (:func:`data_parallel`); :meth:`gradients` replaces the
    in-process zero_grad / forward / losses / backward of a step.

    While it is open, the trainer's parameters live in shared memory (the workers read them); on
    :meth:`close` they move back into private arrays with their values.
    """

    def __init__(self, trainer, workers: int):
        if workers < 2:
            raise ValueError(f"DataParallel: needs at least 2 workers, got {workers}")
        if not supports(trainer.model):
            raise ValueError("DataParallel: only the StyleModel with its FiLM generator trains in parallel")
        self.trainer, self.model, self.workers = trainer, trainer.model, workers
        self.procs, self.conns, self.segments = [], [], []
        self.step_index = 0
        #: seconds of the parent's own work in gradients() (masks, the minibatch into shared memory)
        #: and of waiting for the workers (all three phases); for benchmarks/parallel_training.py
        self.seconds = {"parent": 0.0, "waiting": 0.0}
        try:
            self._open()
        except BaseException:
            self.close()
            raise

    # ---- set-up ----------------------------------------------------------------------------------
    def _segment(self, nbytes: int):
        shm = shared_memory.SharedMemory(name=f"minifilm_{os.getpid()}_{next(_names)}", create=True,
                                         size=max(1, nbytes))
        self.segments.append(shm)
        return shm

    def _dropout_sites(self):
        """([Ψ's sites], [Ω's then Φ's sites], {site: shape of one row}) from a one-sample training
        pass with a throw-away generator: the order in which one process draws the masks."""
        c, dtype = self.model.config, self.model.dtype
        x, p = np.zeros((1, c.x_dim), dtype), np.zeros((1, c.phase_dim), dtype)
        clips = np.zeros((1, c.clip_frames, c.clip_channels), dtype)
        self.model.forward(x, p, clips, train=True, rng=np.random.default_rng(0))
        m = self.model
        rows = {site: mask.shape[1:] for net in (m.film, m.gating, m.motion) for site, mask in net.used_masks.items()}
        return list(m.film.used_masks), list(m.gating.used_masks) + list(m.motion.used_masks), rows

    def _open(self):
        model, trainer, W = self.model, self.trainer, self.workers
        c, dtype, B = model.config, model.dtype, trainer.config.batch_size
        sets = model.parameter_sets()
        offsets = np.concatenate([[0], np.cumsum([ps.size for ps in sets])]).tolist()
        total = offsets[-1]
        # one segment: weights, the summed gradient, Adam's m and v, then the W gradient slots
        flat = self._segment((4 + W) * total * dtype.itemsize)
        data, grad, m, v = np.ndarray((4, total), dtype=dtype, buffer=flat.buf)
        self.slots = np.ndarray((W, total), dtype=dtype, buffer=flat.buf, offset=4 * total * dtype.itemsize)
        self.slots.fill(0)
        for ps, off in zip(sets, offsets):     # the parent's weights and gradients move into shared memory
            ps.bind(data[off:off + ps.size], grad[off:off + ps.size])
        self.set_spans = [(off, off + ps.size) for ps, off in zip(sets, offsets)]
        # each worker sums and updates one part of the parameter vector (64-byte aligned parts)
        cuts = [min(total, -(-(w * total // W) // 16) * 16) for w in range(W)] + [total]
        self.spans = list(zip(cuts[:-1], cuts[1:]))
        opt = trainer.optimizer
        self.optimizer = opt if isinstance(opt, ChunkedAdam) and opt.sets == sets else None
        if self.optimizer is not None:          # Adam's moments too (copied back by close())
            for i, off in enumerate(offsets[:-1]):
                m[off:off + sets[i].size] = opt.m[i]
                v[off:off + sets[i].size] = opt.v[i]
                opt.m[i], opt.v[i] = m[off:off + sets[i].size], v[off:off + sets[i].size]

        self.clip_sites, self.sample_sites, row_shape = self._dropout_sites()
        fields = {"x": ((B, c.x_dim), dtype), "p": ((B, c.phase_dim), dtype), "z": ((B, c.z_dim), dtype),
                  "clips": ((B, c.clip_frames, c.clip_channels), dtype), "clip_index": ((B,), np.int64)}
        fields.update({"mask." + s: ((B, *row_shape[s]), np.bool_) for s in self.clip_sites + self.sample_sites})
        layout, nbytes = {}, 0
        for name, (shape, dt) in fields.items():
            nbytes = -(-nbytes // 64) * 64                     # each field 64-byte aligned
            layout[name] = [nbytes, list(shape), np.dtype(dt).str]
            nbytes += math.prod(shape) * np.dtype(dt).itemsize
        step = self._segment(nbytes)
        self.batch = parallel_worker.views(step, layout)

        stats = trainer.stats
        spec = {"model_config": c.to_dict(), "dtype": dtype.str, "total": total,
                "sets": [[off, ps.size] for ps, off in zip(sets, offsets)],
                "flat": flat.name, "step": step.name, "layout": layout, "workers": W, "spans": self.spans,
                "clip_sites": self.clip_sites, "sample_sites": self.sample_sites,
                "loss": {"bll_weight": trainer.config.bll_weight,
                         "positions_idx": None if trainer.positions_idx is None else np.asarray(trainer.positions_idx).tolist(),
                         "parents": None if trainer.parents is None else np.asarray(trainer.parents).tolist(),
                         "z_mean": np.asarray(stats.z_mean, dtype=np.float64).tolist(),
                         "z_std": np.asarray(stats.z_std, dtype=np.float64).tolist()}}
        text = json.dumps(spec)
        ctx = multiprocessing.get_context("spawn")
        saved = {k: os.environ.get(k) for k in ONE_BLAS_THREAD}
        os.environ.update(ONE_BLAS_THREAD)          # read by the workers' numpy when it loads
        # A worker started with SIGINT ignored keeps it ignored from its first instruction (Python
        # then installs no KeyboardInterrupt handler), so a Ctrl-C while it is still importing
        # prints nothing from it; the parent's own handler is back as soon as the workers exist.
        main_thread = threading.current_thread() is threading.main_thread()
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if main_thread else None
        try:
            for w in range(W):
                mine, theirs = ctx.Pipe()
                proc = ctx.Process(target=parallel_worker.main, args=(text, w, theirs), daemon=True,
                                   name=f"minifilm-train-worker-{w}")
                proc.start()
                theirs.close()
                self.procs.append(proc)
                self.conns.append(mine)
        finally:
            if main_thread:     # (None: a handler set outside Python; Python's own takes its place)
                signal.signal(signal.SIGINT, signal.default_int_handler if previous is None else previous)
            for k, v in saved.items():
                if v is None:
                    os.environ.pop(k, None)
                else:
                    os.environ[k] = v
        self._collect("starting")

    @property
    def pids(self) -> list:
        return [p.pid for p in self.procs]

    # ---- a step ----------------------------------------------------------------------------------
    def _send(self, messages, where: str, updating: bool = False) -> None:
        """One message to each worker; a worker that has gone (its pipe broken) is WorkerDied,
        named as :meth:`_collect` names it, not an OSError of the pipe."""
        for w, (conn, message) in enumerate(zip(self.conns, messages)):
            try:
                conn.send_bytes(np.asarray(message, dtype=np.float64).tobytes())
            except OSError:             # BrokenPipeError, ConnectionResetError: the worker is gone
                self._died(w, where, updating)

    def gradients(self, b) -> tuple:
        """The gradients of minibatch ``b`` (a trainer.Minibatch) in the model's ``.grad`` buffers,
        computed by the workers; returns (mse, bll) of the whole minibatch. Draws the dropout masks
        from the trainer's generator as one process's forward pass would."""
        t_start = time.perf_counter()
        rng, p_drop, B = self.trainer.rng, self.model.config.dropout, len(b.x)
        clip_index = b.kw.get("clip_index")
        shared = clip_index is not None
        M = len(b.clips)
        if B > len(self.batch["x"]) or M > len(self.batch["clips"]):
            raise ValueError(f"DataParallel: a minibatch of {B} samples and {M} clips is larger than the "
                             f"{len(self.batch['x'])} it was set up for")
        order = np.argsort(clip_index, kind="stable") if shared else np.arange(B)
        if p_drop > 0:          # draw order and shapes as Dropout.forward's, Ψ's sites first
            for site in self.clip_sites:
                view = self.batch["mask." + site][:M]
                np.greater_equal(rng.random(view.shape), p_drop, out=view)
            for site in self.sample_sites:
                view = self.batch["mask." + site][:B]
                view[...] = (rng.random(view.shape) >= p_drop)[order]
        for name in ("x", "p", "z"):
            np.take(getattr(b, name), order, axis=0, out=self.batch[name][:B])
        self.batch["clips"][:M] = b.clips
        if shared:
            np.take(clip_index, order, out=self.batch["clip_index"][:B])
        parts = shares(B, self.batch["clip_index"][:B] if shared else None, M, self.workers)
        self._send([(parallel_worker.GRADIENTS, *part, B, int(shared)) for part in parts], b.where)
        self.step_index += 1
        t_sent = time.perf_counter()
        losses = self._collect(b.where)
        self._send([(parallel_worker.SUM, a, z) for a, z in self.spans], b.where)
        self._collect(b.where)
        self.seconds["parent"] += t_sent - t_start
        self.seconds["waiting"] += time.perf_counter() - t_sent
        return float(losses[:, 0].sum()), float(losses[:, 1].sum())

    def update(self, optimizer) -> None:
        """The optimiser's step on the gradients of :meth:`gradients`: a ChunkedAdam bound to
        this pool is stepped by the workers, each on its part of the parameters; any other
        optimiser steps in this process (it reads the same shared buffers)."""
        if optimizer is not self.optimizer:
            optimizer.step()
            return
        t0 = time.perf_counter()
        scalars = [x for i, step_size, eps_hat in optimizer.advance()
                   for x in (*self.set_spans[i], step_size, eps_hat)]
        where = f"the Adam step {self.trainer.step + 1}"
        self._send([(parallel_worker.ADAM, a, z, optimizer.beta1, optimizer.beta2, *scalars) for a, z in self.spans],
                   where, updating=True)
        self._collect(where, updating=True)
        self.seconds["waiting"] += time.perf_counter() - t0

    def _collect(self, where: str, updating: bool = False) -> np.ndarray:
        """(W, 2) float64 replies of every worker; WorkerDied when one ends or reports an error."""
        replies = [None] * self.workers
        waiting = dict(enumerate(self.conns))
        while waiting:
            ready = connection.wait(list(waiting.values()) + [self.procs[w].sentinel for w in waiting])
            for w, conn in list(waiting.items()):
                if conn in ready:
                    try:
                        message = conn.recv_bytes()
                    except (EOFError, OSError):
                        self._died(w, where, updating)
                    if message[:2] != parallel_worker.OK:
                        raise WorkerDied(f"training stopped: worker {w} failed at {where}: "
                                         f"{message[2:].decode(errors='replace')}")
                    replies[w] = np.frombuffer(message[2:], dtype=np.float64)
                    del waiting[w]
                elif self.procs[w].sentinel in ready:
                    self._died(w, where, updating)
        return np.stack(replies)

    def _died(self, w: int, where: str, updating: bool):
        proc = self.procs[w]
        proc.join(timeout=1.0)
        code = proc.exitcode
        how = (f"was killed by {signal.Signals(-code).name}" if code is not None and code < 0
               else f"exited with code {code}")
        raise WorkerDied(f"training stopped: worker {w} (process {proc.pid}) {how} at {where}; "
                         + ("the step's update is incomplete (the checkpoints written so far are whole)" if updating
                            else "the weights were not updated with that step"))

    # ---- the end ---------------------------------------------------------------------------------
    def close(self) -> None:
        """Stop the workers (they end when their pipe closes; any still running after 5 s are
        terminated), move the parameters back into private arrays, unlink the shared memory."""
        for conn in self.conns:
            conn.close()
        for proc in self.procs:
            proc.join(timeout=5.0)
        for proc in self.procs:
            if proc.is_alive():
                proc.terminate()
                proc.join(timeout=2.0)
            if proc.is_alive():
                proc.kill()
                proc.join()
        self.procs, self.conns = [], []
        if self.segments:
            for ps in self.model.parameter_sets():
                ps.bind(ps.data.copy(), ps.grad.copy())
            opt = getattr(self, "optimizer", None)
            if opt is not None:
                opt.m = [a.copy() for a in opt.m]
                opt.v = [a.copy() for a in opt.v]
            self.batch = self.slots = None
        for shm in self.segments:
            try:
                shm.close()
            except BufferError:     # a view still alive somewhere: unlinking frees it all the same
                pass
            shm.unlink()
        self.segments = []

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


@contextlib.contextmanager
def data_parallel(trainer, workers: int | None = None):
    """A :class:`DataParallel` for ``trainer`` with ``workers`` processes (None: every usable core),
    or None -- train in this process -- for 1 worker or a model that cannot be split."""
    n = usable_cores() if workers is None else int(workers)
    if n < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    if n == 1 or not supports(trainer.model):
        yield None
        return
    with DataParallel(trainer, n) as pool:
        yield pool
