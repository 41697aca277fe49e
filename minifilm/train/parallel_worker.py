"""The worker process of data-parallel training (minifilm/train/parallel.py): its share of each
minibatch's forward and backward pass.

A worker is started with the 'spawn' method and gets one JSON text: the model's configuration,
the names and layouts of two shared-memory segments (one flat segment holding the weights, the
summed gradient, Adam's two moments and one gradient slot per worker; one holding the step's
minibatch and dropout masks), its part a:b of the parameter vector, the loss settings and the
dropout sites. It builds the model, points its weights at the shared ones and its gradients at
its own slot, and then answers messages (float64 arrays, the first number saying which):

    GRADIENTS lo hi clo chi B shared   forward and backward on rows lo:hi (clips clo:chi) with the
                                       masks the parent drew; the gradient of (hi - lo) / B x the
                                       share's mean loss into its slot; reply the weighted MSE, BLL
    SUM a b                            the summed gradient over a:b = the sum of the W slots there
    ADAM a b beta1 beta2 (lo hi step_size eps_hat)...   ChunkedAdam's update on a:b of each
                                       listed set lo:hi (nn/fast_optim.py::adam_span)

Replies are b"ok" + 2 float64, or b"er" + the error's text. No object is ever pickled.

This module imports nothing heavy at the top: the worker ignores SIGINT (Ctrl-C reaches the
whole process group; the parent decides and stops the workers) before numpy is loaded.
"""
from __future__ import annotations

import json
import os
import signal
import sys

#: reply to a message: b"ok" + 2 float64, or b"er" + the error's text (utf-8)
OK, ERROR = b"ok", b"er"
#: the messages (the first number of each)
GRADIENTS, SUM, ADAM = 1, 2, 3


def attach(name: str):
    """The existing shared-memory segment ``name``. The worker shares the parent's resource
    tracker (the 'spawn' start method passes it on), whose record of the segment is a set: the
    worker's registration adds nothing, and the parent's unlink removes it."""
    from multiprocessing import shared_memory   # (here: this module's top stays light, see above)
    return shared_memory.SharedMemory(name=name)


def views(shm, layout: dict) -> dict:
    """{field: ndarray view into ``shm``} from {field: [byte offset, shape, dtype]}."""
    import numpy as np   # (here: loaded once the worker ignores SIGINT, see above)
    return {k: np.ndarray(tuple(shape), dtype=np.dtype(dt), buffer=shm.buf, offset=off)
            for k, (off, shape, dt) in layout.items()}


def main(spec_text: str, slot: int, conn) -> None:
    """The worker's loop (the target of multiprocessing.Process); returns when the parent closes
    its end of the pipe or goes away."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        worker = Worker(json.loads(spec_text), slot)
    except Exception as e:    # noqa: BLE001 -- told to the parent, which raises it as one message
        conn.send_bytes(ERROR + f"{type(e).__name__}: {e}".encode())
        return
    conn.send_bytes(OK + bytes(16))
    while True:
        try:
            message = conn.recv_bytes()
        except (EOFError, OSError):          # the parent closed the pipe or died: stop
            return
        try:
            reply = OK + worker.answer(message)
        except Exception as e:  # noqa: BLE001
            reply = ERROR + f"{type(e).__name__}: {e}".encode()
        try:
            conn.send_bytes(reply)
        except (BrokenPipeError, OSError):
            return


class Worker:
    """The model bound to shared memory, and one step on a share of a minibatch."""

    def __init__(self, spec: dict, slot: int):
        # here, not at the top: loaded once the worker ignores SIGINT (see the module's docstring)
        import numpy as np
        from minifilm.model.config import ModelConfig
        from minifilm.model.style_model import StyleModel
        from minifilm.train.objective import objective

        self.np, self.objective = np, objective
        self.model = StyleModel(ModelConfig.from_dict(spec["model_config"]), np.random.default_rng(0),
                                dtype=np.dtype(spec["dtype"]))
        from minifilm.nn.fast_optim import CHUNK, adam_span   # (as above)
        self.adam_span = adam_span
        self.segments = [attach(spec["flat"]), attach(spec["step"])]
        flat, step = self.segments
        total, W, dtype = spec["total"], spec["workers"], self.model.dtype
        self.data, self.grad, self.m, self.v = np.ndarray((4, total), dtype=dtype, buffer=flat.buf)
        self.slots = np.ndarray((W, total), dtype=dtype, buffer=flat.buf, offset=4 * total * dtype.itemsize)
        for ps, (off, size) in zip(self.model.parameter_sets(), spec["sets"]):
            ps.bind(self.data[off:off + size], self.slots[slot, off:off + size])
        self.scratch = np.empty(CHUNK, dtype=dtype)
        self.batch = views(step, spec["layout"])
        self.clip_sites, self.sample_sites = spec["clip_sites"], spec["sample_sites"]
        loss = spec["loss"]
        self.loss_kw = {"bll_weight": loss["bll_weight"],
                        "positions_idx": None if loss["positions_idx"] is None else np.asarray(loss["positions_idx"]),
                        "parents": None if loss["parents"] is None else np.asarray(loss["parents"]),
                        "z_mean": np.asarray(loss["z_mean"]), "z_std": np.asarray(loss["z_std"])}

    def answer(self, message: bytes) -> bytes:
        """Carry out one message (see the module's docstring); returns the 16 bytes of the reply."""
        np = self.np
        m = np.frombuffer(message, dtype=np.float64)
        op = int(m[0])
        if op == GRADIENTS:
            return self.gradients(*(int(x) for x in m[1:7]))
        a, z = int(m[1]), int(m[2])
        if op == SUM:
            np.sum(self.slots[:, a:z], axis=0, out=self.grad[a:z])
        elif op == ADAM:
            beta1, beta2 = float(m[3]), float(m[4])
            for lo, hi, step_size, eps_hat in m[5:].reshape(-1, 4).tolist():
                lo, hi = max(int(lo), a), min(int(hi), z)
                if lo < hi:
                    self.adam_span(self.data[lo:hi], self.grad[lo:hi], self.m[lo:hi], self.v[lo:hi], self.scratch,
                                   beta1, beta2, step_size, eps_hat)
        else:
            raise ValueError(f"unknown message {op}")
        return bytes(16)

    def gradients(self, lo, hi, clo, chi, batch, shared) -> bytes:
        """Forward and backward on rows lo:hi (clips clo:chi) of the step's minibatch; the
        gradient of (hi - lo) / B x the share's mean loss goes into this worker's slot."""
        np, b = self.np, self.batch
        self.model.zero_grad()
        if hi == lo:                                   # a batch smaller than the number of workers
            return np.zeros(2).tobytes()
        masks = {site: b["mask." + site][lo:hi] for site in self.sample_sites}
        masks.update({site: b["mask." + site][clo:chi] for site in self.clip_sites})
        kw = {"clip_index": b["clip_index"][lo:hi] - clo} if shared else {}
        pred = self.model.forward(b["x"][lo:hi], b["p"][lo:hi], b["clips"][clo:chi], train=True, masks=masks, **kw)
        mse, bll, dpred = self.objective(pred, b["z"][lo:hi], **self.loss_kw)
        share = (hi - lo) / batch
        dpred *= np.asarray(share, dtype=dpred.dtype)
        self.model.backward(dpred, need_input_grads=False)
        return np.array([mse * share, bll * share]).tobytes()


if __name__ == "__main__":      # not a command
    sys.exit(f"{os.path.basename(__file__)}: started by minifilm.train.parallel, not by hand")
