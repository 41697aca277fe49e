"""One worker's part of a data-parallel training step (minifilm/train/parallel.py), and the loop
of a worker process.

With W workers the parent process is worker 0 and W - 1 worker processes are workers 1 .. W-1;
all run :class:`Part`, on shared memory:

    data, m, v (N,)      the weights and Adam's moments (the one set every worker reads)
    slots (W, N)         one gradient slot per worker (slot 0 is the parent's model's ``.grad``)
    the step's fields    the minibatch and its dropout masks, written by the parent; a control
                         block (int64: the command number k, stop, what to do, the batch size,
                         each worker's rows); done (W,): each worker's progress; losses (W, 2);
                         finite (W,); Adam's scalars

Step k, in every worker w, on its rows lo_w:hi_w and its part a_w:b_w of the parameter vector:

    1. GRADIENTS  forward + backward on its rows -> slot w; its weighted losses -> losses[w]
                  done[w] = 3k + 1; then wait until every done >= 3k + 1
    2. SUM        slot 0 over a_w:b_w += the other slots there (slot 0 then holds the minibatch's
                  gradient); finite[w] = is that part finite;  done[w] = 3k + 2
    3. ADAM       (a whole step: after waiting for every done >= 3k + 2) only if every part and
                  every loss is finite -- each worker reads the same flags, so all decide alike
                  and a NaN leaves every weight untouched -- ChunkedAdam's update on a_w:b_w
                  done[w] = 3k + 3; the parent waits for every done >= 3k + 3 before step k + 1

No message is exchanged per step: each side waits for the other's counter in shared memory
(:func:`wait_until`: a few quick tries, then blocking on its semaphore, which a worker releases
for the others whenever its counter moves). A wait checks every CHECK_EVERY seconds without a
wake-up that the other side still runs, so it never outlives it.

A worker process gets one JSON text (the model's configuration, the segments' names and layout,
the parts, the loss settings, the dropout sites) and its number; it replies b"ok" on its pipe
once it is built, or b"er" + an error's text (also for an error during a step, when it sets
done[w] = FAILED). No object is ever pickled. It stops when the parent sets stop, or when the
parent is gone (its parent process id changes).

This module imports nothing heavy at the top: a worker ignores SIGINT (Ctrl-C reaches the whole
process group; the parent decides and stops the workers) before numpy is loaded.
"""
from __future__ import annotations

import json
import os
import platform
import signal
import sys

from minifilm.processes import attach

#: reply on the pipe: b"ok" once built, or b"er" + the error's text (utf-8)
OK, ERROR = b"ok", b"er"
#: what a command does (bits of the control block's OPS)
GRADIENTS, SUM, ADAM = 1, 2, 4
#: the control block (int64): fields, then (lo, hi, clo, chi) per worker from PARTS on
SEQ, STOP, OPS, BATCH, SHARED, N_ADAM, PARTS = range(7)
#: done[w] of a worker whose step raised an error (its text is on its pipe)
FAILED = -1
#: The counters are plain stores read by another process: x86 processors make a process's stores
#: visible to others in the order it made them (a counter is never seen before the data written
#: before it); ARM and POWER do not promise that without fences, which Python cannot emit, so
#: elsewhere training runs in one process (parallel.supports)
X86 = platform.machine().lower() in ("x86_64", "amd64", "i386", "i686", "x86")
#: waiting: quick tries before blocking, and seconds between checks that the other side is still there
SPIN, CHECK_EVERY = 20, 0.02


class Stopped(Exception):
    """The parent closed the pool or is gone: the worker process ends."""


def wait_until(ready, check, wake) -> None:
    """Return once ready() is true. A few quick tries first (on an idle machine the other side is
    microseconds away); then block on the semaphore ``wake``, which whoever may have made ready()
    true releases after doing so: blocking leaves the core to others (on a busy machine a
    spinning wait took the core its partner needed, see benchmarks/parallel_training.py --sync)
    and the kernel wakes the process at once. Wake-ups left from earlier waits are drained first,
    then ready() is asked again, so no wake-up is missed. check() runs whenever CHECK_EVERY s
    pass without one and raises when the other side has gone: a wait never blocks forever."""
    for _ in range(SPIN):
        if ready():
            return
    while wake.acquire(False):
        pass
    while not ready():
        if not wake.acquire(timeout=CHECK_EVERY):
            check()


def views(shm, layout: dict) -> dict:
    """{field: ndarray view into ``shm``} from {field: [byte offset, shape, dtype]}."""
    import numpy as np   # (here: loaded once the worker ignores SIGINT, see above)
    return {k: np.ndarray(tuple(shape), dtype=np.dtype(dt), buffer=shm.buf, offset=off)
            for k, (off, shape, dt) in layout.items()}


def flat_views(shm, total: int, workers: int, dtype):
    """(data, m, v, slots) views of the flat segment: three (N,) arrays then (W, N)."""
    import numpy as np   # (as in views)
    data, m, v = np.ndarray((3, total), dtype=dtype, buffer=shm.buf)
    slots = np.ndarray((workers, total), dtype=dtype, buffer=shm.buf, offset=3 * total * dtype.itemsize)
    return data, m, v, slots


class Part:
    """Worker w's part of every step (see the module's docstring), on ``model`` whose weights are
    the shared ``data`` and whose gradients are slot w."""

    def __init__(self, spec: dict, w: int, model, flat: tuple, step: dict, wake: list):
        import numpy as np   # (here: loaded once the worker ignores SIGINT, see the module's docstring)
        from minifilm.nn.fast_optim import CHUNK, adam_span
        from minifilm.train.objective import all_finite, objective
        self.np, self.adam_span, self.all_finite, self.objective = np, adam_span, all_finite, objective
        self.w, self.model, self.workers, self.wake = w, model, spec["workers"], wake
        self.span = spec["spans"][w]
        self.data, self.m, self.v, self.slots = flat
        self.batch = step
        self.control, self.done = step["control"], step["done"][:, 0]    # (done: one per 64 bytes)
        self.losses, self.finite, self.adam = step["losses"], step["finite"], step["adam"]
        self.clip_sites, self.sample_sites = spec["clip_sites"], spec["sample_sites"]
        self.scratch = np.empty(CHUNK, dtype=model.dtype)
        loss = spec["loss"]
        self.loss_kw = {"bll_weight": loss["bll_weight"],
                        "positions_idx": None if loss["positions_idx"] is None else np.asarray(loss["positions_idx"]),
                        "parents": None if loss["parents"] is None else np.asarray(loss["parents"]),
                        "z_mean": np.asarray(loss["z_mean"]), "z_std": np.asarray(loss["z_std"])}

    def set_done(self, value: int) -> None:
        """done[w] = value, then wake every other worker (one may be waiting for it)."""
        self.done[self.w] = value
        for other, sem in enumerate(self.wake):
            if other != self.w:
                sem.release()

    def wait_all(self, target: int, check) -> None:
        """Wait until every worker's done >= target (see :func:`wait_until`)."""
        done = self.done
        wait_until(lambda: bool((done >= target).all()), check, self.wake[self.w])

    def finite_step(self) -> bool:
        """Every part of the summed gradient and both losses of the minibatch are finite (the same
        answer in every worker: all read the same flags)."""
        return bool(self.finite.all()) and bool(self.np.isfinite(self.losses.sum(axis=0)).all())

    def step(self, k: int, check) -> None:
        """Step k (the control block says which phases); check() as for :func:`wait_until`."""
        c, w = self.control, self.w
        ops = int(c[OPS])
        if ops & GRADIENTS:
            self.losses[w] = self.gradients(*(int(x) for x in c[PARTS + 4 * w:PARTS + 4 * w + 4]),
                                            int(c[BATCH]), bool(c[SHARED]))
        self.set_done(3 * k + 1)
        a, z = self.span
        if ops & SUM:
            self.wait_all(3 * k + 1, check)
            total = self.slots[0, a:z]
            for other in self.slots[1:]:
                total += other[a:z]
            self.finite[w] = self.all_finite(total)
        self.set_done(3 * k + 2)
        if ops & ADAM:
            whole = ops & GRADIENTS and ops & SUM
            if whole:
                self.wait_all(3 * k + 2, check)
            if not whole or self.finite_step():
                self.update(a, z, int(c[N_ADAM]))
        self.set_done(3 * k + 3)

    def gradients(self, lo, hi, clo, chi, batch, shared):
        """Forward and backward on rows lo:hi (clips clo:chi) of the step's minibatch with the
        masks the parent drew; the gradient of (hi - lo) / B x the share's mean loss goes into
        this worker's slot. Returns (mse, bll) x (hi - lo) / B."""
        np, b = self.np, self.batch
        self.model.zero_grad()
        if hi == lo:                                   # a batch smaller than the number of workers
            return 0.0, 0.0
        masks = {site: b["mask." + site][lo:hi] for site in self.sample_sites}
        masks.update({site: b["mask." + site][clo:chi] for site in self.clip_sites})
        kw = {"clip_index": b["clip_index"][lo:hi] - clo} if shared else {}
        pred = self.model.forward(b["x"][lo:hi], b["p"][lo:hi], b["clips"][clo:chi], train=True, masks=masks, **kw)
        mse, bll, dpred = self.objective(pred, b["z"][lo:hi], **self.loss_kw)
        share = (hi - lo) / batch
        dpred *= np.asarray(share, dtype=dpred.dtype)
        self.model.backward(dpred, need_input_grads=False)
        return mse * share, bll * share

    def update(self, a: int, z: int, n_sets: int) -> None:
        """ChunkedAdam's step on a:z of each listed set (nn/fast_optim.py::adam_span), the
        scalars the parent wrote: beta1, beta2, then (lo, hi, step_size, eps_hat) per set."""
        beta1, beta2 = float(self.adam[0]), float(self.adam[1])
        for lo, hi, step_size, eps_hat in self.adam[2:2 + 4 * n_sets].reshape(-1, 4).tolist():
            lo, hi = max(int(lo), a), min(int(hi), z)
            if lo < hi:
                self.adam_span(self.data[lo:hi], self.slots[0, lo:hi], self.m[lo:hi], self.v[lo:hi], self.scratch,
                               beta1, beta2, step_size, eps_hat)


def main(spec_text: str, w: int, conn, wake: list) -> None:
    """A worker process (the target of multiprocessing.Process): build the model on the shared
    buffers, then run :meth:`Part.step` for every command until the parent stops or goes."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    parent = os.getppid()
    try:   # imports here, once SIGINT is ignored (see the module's docstring)
        import numpy as np
        from minifilm.model.config import ModelConfig
        from minifilm.model.style_model import StyleModel
        spec = json.loads(spec_text)
        model = StyleModel(ModelConfig.from_dict(spec["model_config"]), np.random.default_rng(0),
                           dtype=np.dtype(spec["dtype"]))
        segments = [attach(spec["flat"]), attach(spec["step"])]
        flat = flat_views(segments[0], spec["total"], spec["workers"], model.dtype)
        for ps, (off, size) in zip(model.parameter_sets(), spec["sets"]):
            ps.bind(flat[0][off:off + size], flat[3][w, off:off + size])
        part = Part(spec, w, model, flat, views(segments[1], spec["layout"]), wake)
    except Exception as e:    # noqa: BLE001 -- told to the parent, which raises it as one message
        conn.send_bytes(ERROR + f"{type(e).__name__}: {e}".encode())
        return
    conn.send_bytes(OK)
    control = part.control

    def check():
        if control[STOP] or os.getppid() != parent:
            raise Stopped

    k = 0
    try:
        while True:
            k += 1
            wait_until(lambda: control[SEQ] >= k or control[STOP], check, wake[w])
            check()
            part.step(k, check)
    except Stopped:
        return
    except Exception as e:  # noqa: BLE001
        part.set_done(FAILED)
        try:
            conn.send_bytes(ERROR + f"{type(e).__name__}: {e}".encode())
        except OSError:
            pass


if __name__ == "__main__":      # not a command
    sys.exit(f"{os.path.basename(__file__)}: started by minifilm.train.parallel, not by hand")
