"""Data-parallel training: each minibatch's forward and backward pass split across W workers, one
BLAS thread each, so that training uses every core. This process is worker 0 and computes its own
share; W - 1 worker processes compute the others.

    this process (worker 0)                     every worker w (parallel_worker.Part)
    draw the minibatch and its dropout masks    (the same draws, in the same order, as one process
    with the trainer's generator; write them      makes: results do not depend on W)
    to shared memory, count Adam's step,
    write its scalars; command k  ------->  1. forward + backward on rows lo_w:hi_w, the gradient
                                               of (n_w / B) x its mean loss into its slot w
                                            2. the sum of the W slots over its part a_w:b_w of
                                               the parameter vector, into slot 0; is it finite?
                                            3. if every part and loss is finite: Adam's step on
                                               a_w:b_w (weights and moments in shared memory)
    wait for every worker's step k  <------

The phases wait on each other through counters in shared memory (parallel_worker.py says how),
not pipe messages. The sum and the Adam update are element by element, so splitting them by
parameter changes no number: it is the ChunkedAdam step of one process, number for number. A NaN
or inf stops training before any weight changes, with the one-process message (check_finite).

Why it equals one process: the losses are means over the minibatch's rows, so the gradient of
the whole minibatch is the sum over workers of (n_w / B) x the gradient of their share's mean;
the dropout keep-masks are drawn for the whole minibatch exactly as the one-process forward pass
draws them (site by site: Ψ, then Ω, then Φ) and each worker uses its rows of them. Only the order
of float32 sums changes (tests/train/test_parallel.py: 1e-6 relative).

With clips shared by the minibatch (TrainConfig.clips_per_batch), the samples are ordered by
their clip and split at clip boundaries, so each worker runs Ψ on its own clips only; with fewer
clips than workers a clip's Ψ runs in every worker that has samples of it (its gradient is still
the sum of its samples'). Shares may then be unequal; the weights n_w / B keep the mean right.

Processes: started with 'spawn' (a fresh interpreter: nothing of the parent's threads, locks or
BLAS state is inherited, so it is safe whatever the parent runs; and it is the start method every
platform has), with OPENBLAS/OMP/MKL_NUM_THREADS=1 in their environment. They ignore SIGINT; this
process stops them when it leaves (finished, Ctrl-C, SIGTERM, an error, a worker that died), and a
worker stops by itself when this process is gone. The shared-memory segments are named
``minifilm_<parent pid>_<n>`` and unlinked on the way out. A worker that dies (killed, out of
memory) stops training with :class:`WorkerDied`, one message, within CHECK_EVERY seconds; when that
happens before phase 3 the weights are untouched by the step (during phase 3 they are partly
updated, and the run stops all the same; the checkpoints already written are whole).
"""
from __future__ import annotations

import contextlib
import itertools
import json
import math
import multiprocessing
import os
import time
from multiprocessing import connection, shared_memory

import numpy as np

from minifilm.model.style_model import StyleModel
from minifilm.nn.fast_optim import ChunkedAdam
from minifilm.processes import WorkerDied, how_it_ended, starting_workers
from minifilm.train import parallel_worker as pw
from minifilm.train.parallel_shares import default_workers, shares

_names = itertools.count()


def supports(model) -> bool:
    """Data-parallel steps need the paper's StyleModel with its FiLM generator Ψ (the comparison
    variants of minifilm.baselines train in one process) and an x86 processor (parallel_worker.X86)."""
    return type(model) is StyleModel and model.film is not None and pw.X86


class DataParallel:
    """W workers -- this process and W - 1 worker processes -- computing a
    :class:`~minifilm.train.trainer.Trainer`'s steps. Use as a context manager
    (:func:`data_parallel`). :meth:`train_step` is Trainer.train_step split across them;
    :meth:`gradients` and :meth:`update` are its two halves (for tests and benchmarks).

    While it is open, the trainer's parameters and Adam's moments live in shared memory (the
    workers read them; the model's ``.grad`` is slot 0, which holds the summed gradient after a
    step); on :meth:`close` they move back into private arrays with their values.
    """

    def __init__(self, trainer, workers: int):
        if workers < 2:
            raise ValueError(f"DataParallel: needs at least 2 workers, got {workers}")
        if not supports(trainer.model):
            raise ValueError("DataParallel: only the StyleModel with its FiLM generator, on x86, trains in parallel")
        self.trainer, self.model, self.workers = trainer, trainer.model, workers
        self.procs, self.conns, self.segments = [], [], []
        self.k = 0                                              # commands given so far
        #: seconds of this process's own work (the minibatch and masks into shared memory), of its share
        #: (worker 0's phases) and of waiting for the others at the end (benchmarks/parallel_training.py)
        self.seconds = {"parent": 0.0, "share": 0.0, "waiting": 0.0}
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
        # one segment: weights, Adam's m and v, then the W gradient slots (slot 0: this process's)
        flat = self._segment((3 + W) * total * dtype.itemsize)
        data, m, v, slots = pw.flat_views(flat, total, W, dtype)
        slots.fill(0)
        for ps, off in zip(sets, offsets):     # this process's weights and gradients move into shared memory
            ps.bind(data[off:off + ps.size], slots[0, off:off + ps.size])
        self.set_spans = [(off, off + ps.size) for ps, off in zip(sets, offsets)]
        # each worker sums and updates one part of the parameter vector (64-byte aligned parts)
        cuts = [min(total, -(-(w * total // W) // 16) * 16) for w in range(W)] + [total]
        spans = list(zip(cuts[:-1], cuts[1:]))
        opt = trainer.optimizer
        self.optimizer = opt if isinstance(opt, ChunkedAdam) and opt.sets == sets else None
        if self.optimizer is not None:          # Adam's moments too (copied back by close())
            for i, off in enumerate(offsets[:-1]):
                m[off:off + sets[i].size] = opt.m[i]
                v[off:off + sets[i].size] = opt.v[i]
                opt.m[i], opt.v[i] = m[off:off + sets[i].size], v[off:off + sets[i].size]

        clip_sites, sample_sites, row_shape = self._dropout_sites()
        fields = {"x": ((B, c.x_dim), dtype), "p": ((B, c.phase_dim), dtype), "z": ((B, c.z_dim), dtype),
                  "clips": ((B, c.clip_frames, c.clip_channels), dtype), "clip_index": ((B,), np.int64),
                  "control": ((pw.PARTS + 4 * W,), np.int64), "done": ((W, 8), np.int64),
                  "losses": ((W, 2), np.float64), "finite": ((W,), np.int64),
                  "adam": ((2 + 4 * len(sets),), np.float64)}
        fields.update({"mask." + s: ((B, *row_shape[s]), np.bool_) for s in clip_sites + sample_sites})
        layout, nbytes = {}, 0
        for name, (shape, dt) in fields.items():
            nbytes = -(-nbytes // 64) * 64                     # each field 64-byte aligned
            layout[name] = [nbytes, list(shape), np.dtype(dt).str]
            nbytes += math.prod(shape) * np.dtype(dt).itemsize
        step = self._segment(nbytes)
        self.batch = pw.views(step, layout)
        self.batch["control"].fill(0)
        self.batch["done"].fill(0)

        stats = trainer.stats
        spec = {"model_config": c.to_dict(), "dtype": dtype.str, "total": total,
                "sets": [[off, ps.size] for ps, off in zip(sets, offsets)],
                "flat": flat.name, "step": step.name, "layout": layout, "workers": W, "spans": spans,
                "clip_sites": clip_sites, "sample_sites": sample_sites,
                "loss": {"bll_weight": trainer.config.bll_weight,
                         "positions_idx": None if trainer.positions_idx is None else np.asarray(trainer.positions_idx).tolist(),
                         "parents": None if trainer.parents is None else np.asarray(trainer.parents).tolist(),
                         "z_mean": np.asarray(stats.z_mean, dtype=np.float64).tolist(),
                         "z_std": np.asarray(stats.z_std, dtype=np.float64).tolist()}}
        # worker w's semaphore: released by the others whenever their counters (or the command) move
        self.wake = [multiprocessing.get_context("spawn").Semaphore(0) for _ in range(W)]
        self.part = pw.Part(spec, 0, model, (data, m, v, slots), self.batch, self.wake)
        self._start(json.dumps(spec))

    def _start(self, text: str) -> None:
        """Start workers 1 .. W-1 and wait until each has built its model."""
        ctx = multiprocessing.get_context("spawn")
        with starting_workers():            # one BLAS thread each, SIGINT ignored while they start
            for w in range(1, self.workers):
                mine, theirs = ctx.Pipe()
                proc = ctx.Process(target=pw.main, args=(text, w, theirs, self.wake), daemon=True,
                                   name=f"minifilm-train-worker-{w}")
                proc.start()
                theirs.close()
                self.procs.append(proc)
                self.conns.append(mine)
        waiting = dict(enumerate(self.conns, start=1))
        while waiting:
            ready = connection.wait(list(waiting.values()) + [self.procs[w - 1].sentinel for w in waiting])
            for w, conn in list(waiting.items()):
                if conn in ready:
                    try:
                        message = conn.recv_bytes()
                    except (EOFError, OSError):
                        self._died(w, "starting", False)
                    if message[:2] != pw.OK:
                        raise WorkerDied(f"training stopped: worker {w} failed at starting: "
                                         f"{message[2:].decode(errors='replace')}")
                    del waiting[w]
                elif self.procs[w - 1].sentinel in ready:
                    self._died(w, "starting", False)

    @property
    def pids(self) -> list:
        """The process ids of workers 0 .. W-1 (worker 0 is this process)."""
        return [os.getpid()] + [p.pid for p in self.procs]

    # ---- a step ----------------------------------------------------------------------------------
    def train_step(self, b) -> tuple:
        """Trainer.train_step of minibatch ``b`` (a trainer.Minibatch) split across the workers:
        its gradients, the NaN check, Adam's step; returns (mse, bll). A NaN or inf raises the
        trainer's TrainingDiverged with no weight changed."""
        t = self.trainer
        if self.optimizer is None:                  # another optimiser: it steps in this process
            mse, bll = self.gradients(b)
            t.check_finite(b, mse, bll)
            t.optimizer.lr = t.learning_rate(t.epoch + b.index / b.count)
            t.optimizer.step()
        else:
            t.optimizer.lr = t.learning_rate(t.epoch + b.index / b.count)
            mse, bll = self._command(pw.GRADIENTS | pw.SUM | pw.ADAM, b, b.where)
        t.step += 1
        return mse, bll

    def gradients(self, b) -> tuple:
        """The gradients of minibatch ``b`` in the model's ``.grad``; returns (mse, bll)."""
        return self._command(pw.GRADIENTS | pw.SUM, b, b.where)

    def update(self, optimizer) -> None:
        """The optimiser's step on ``.grad``: the workers step a ChunkedAdam bound to this pool."""
        if optimizer is not self.optimizer:
            optimizer.step()
        else:
            self._command(pw.ADAM, None, f"the Adam step {self.trainer.step + 1}")

    def _write_minibatch(self, b) -> None:
        """Minibatch ``b`` and its dropout masks into shared memory, the rows ordered by clip; the
        masks drawn as one process's forward pass draws them; each worker's rows."""
        rng, p_drop, B = self.trainer.rng, self.model.config.dropout, len(b.x)
        clip_index = b.kw.get("clip_index")
        shared = clip_index is not None
        M = len(b.clips)
        if B > len(self.batch["x"]) or M > len(self.batch["clips"]):
            raise ValueError(f"DataParallel: a minibatch of {B} samples and {M} clips is larger than the "
                             f"{len(self.batch['x'])} it was set up for")
        order = np.argsort(clip_index, kind="stable") if shared else np.arange(B)
        if p_drop > 0:          # draw order and shapes as Dropout.forward's, Ψ's sites first
            for site in self.part.clip_sites:
                view = self.batch["mask." + site][:M]
                np.greater_equal(rng.random(view.shape), p_drop, out=view)
            for site in self.part.sample_sites:
                view = self.batch["mask." + site][:B]
                view[...] = (rng.random(view.shape) >= p_drop)[order]
        for name in ("x", "p", "z"):
            np.take(getattr(b, name), order, axis=0, out=self.batch[name][:B])
        self.batch["clips"][:M] = b.clips
        if shared:
            np.take(clip_index, order, out=self.batch["clip_index"][:B])
        parts = shares(B, self.batch["clip_index"][:B] if shared else None, M, self.workers)
        control = self.batch["control"]
        control[pw.BATCH], control[pw.SHARED] = B, int(shared)
        control[pw.PARTS:] = np.asarray(parts, dtype=np.int64).ravel()

    def _command(self, ops: int, b, where: str) -> tuple:
        """Run one command (bits of parallel_worker's GRADIENTS, SUM, ADAM) in every worker, this
        process being worker 0; returns the minibatch's (mse, bll) (0, 0 without GRADIENTS)."""
        t0 = time.perf_counter()
        opt, control, part = self.optimizer, self.batch["control"], self.part
        if ops & pw.GRADIENTS:
            self._write_minibatch(b)
        steps = list(opt.steps) if opt is not None else None
        if ops & pw.ADAM:               # count the step; its scalars for every worker
            scalars = [(*self.set_spans[i], step_size, eps_hat) for i, step_size, eps_hat in opt.advance()]
            adam = self.batch["adam"]
            adam[:2] = opt.beta1, opt.beta2
            adam[2:2 + 4 * len(scalars)] = np.asarray(scalars, dtype=np.float64).ravel()
            control[pw.N_ADAM] = len(scalars)
        control[pw.OPS] = ops
        self.k += 1
        control[pw.SEQ] = self.k                # the command: the workers start now
        part.set_done(3 * self.k)
        t1 = time.perf_counter()

        def check():                            # a worker that died or failed: WorkerDied
            for w, proc in enumerate(self.procs, start=1):
                if part.done[w] == pw.FAILED:
                    text = self.conns[w - 1].recv_bytes()[2:].decode(errors="replace") \
                        if self.conns[w - 1].poll(1.0) else "no message"
                    raise WorkerDied(f"training stopped: worker {w} failed at {where}: {text}")
                if proc.exitcode is not None:
                    self._died(w, where, updating=bool(ops & pw.ADAM) and part.done[0] >= 3 * self.k + 2)

        part.step(self.k, check)
        t2 = time.perf_counter()
        part.wait_all(3 * self.k + 3, check)
        self.seconds["parent"] += t1 - t0
        self.seconds["share"] += t2 - t1
        self.seconds["waiting"] += time.perf_counter() - t2
        mse, bll = (float(x) for x in part.losses.sum(axis=0))
        if ops & pw.ADAM and ops & pw.GRADIENTS and not part.finite_step():
            opt.steps[:] = steps                # not counted: no weight changed
            self.trainer.check_finite(b, mse, bll)          # raises TrainingDiverged, naming what
        return mse, bll

    def _died(self, w: int, where: str, updating: bool):
        proc = self.procs[w - 1]
        raise WorkerDied(f"training stopped: worker {w} (process {proc.pid}) {how_it_ended(proc)} at {where}; "
                         + ("the step's update is incomplete (the checkpoints written so far are whole)" if updating
                            else "the weights were not updated with that step"))

    # ---- the end ---------------------------------------------------------------------------------
    def close(self) -> None:
        """Stop the workers (they end when told so or when this process is gone; any still running
        after 5 s are terminated), move the parameters back into private arrays, unlink the shared
        memory."""
        batch = getattr(self, "batch", None)
        if batch is not None:
            batch["control"][pw.STOP] = 1
            for sem in getattr(self, "wake", [])[1:]:
                sem.release()
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
            self.batch = self.part = None
        for shm in self.segments:
            with contextlib.suppress(BufferError):  # a view still alive: unlinking frees it all the same
                shm.close()
            shm.unlink()
        self.segments = []

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


@contextlib.contextmanager
def data_parallel(trainer, workers: int | None = None):
    """A :class:`DataParallel` for ``trainer`` with ``workers`` processes (None: default_workers),
    or None -- train in this process -- for 1 worker or a model that cannot be split."""
    n = default_workers(trainer) if workers is None else int(workers)
    if n < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    if n == 1 or not supports(trainer.model):
        yield None
        return
    with DataParallel(trainer, n) as pool:
        yield pool
