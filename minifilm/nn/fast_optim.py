"""Adam, fast: the update of minifilm/nn/optim.py computed in place, chunk by chunk.

The same numbers as :class:`minifilm.nn.optim.Adam` up to rounding
(tests/nn/test_optimised_equivalence.py); training uses this one. Two changes, both for speed:

* the bias corrections go into two scalars (the Adam paper's Sec. 2 form), so each number needs no
  m_hat or v_hat array: ``data -= step_size * m / (sqrt(v) + eps_hat)`` with
  ``step_size = lr * sqrt(1 - beta2^t) / (1 - beta1^t)`` and ``eps_hat = eps * sqrt(1 - beta2^t)``;
* the flat buffers are updated CHUNK numbers at a time with one scratch array, so the ~16 passes
  of a step run over numbers in the core's cache, and main memory is read and written once.

Moments below the smallest normal float are set to 0 in the chunk, as in the plain Adam (why:
optim.py). The chunk size and what else was tried are in reports/2026-12-01_fft_convolution_and_adam.md.
"""
from __future__ import annotations

import math

import numpy as np

from minifilm.nn.optim import Adam

CHUNK = 65536


def _adam_chunk(w, g, m, v, buf, beta1, beta2, step_size, eps_hat, tiny):
    """One Adam update of a chunk, in place, with ``buf`` as the only temporary.

    m <- m + (1 - beta1)(g - m)         (= beta1 m + (1 - beta1) g), then 0 where |m| < tiny
    v <- v + (1 - beta2)(g^2 - v)       (= beta2 v + (1 - beta2) g^2), then 0 where v < tiny
    w <- w - step_size * m / (sqrt(v) + eps_hat)
    """
    np.subtract(g, m, out=buf)
    buf *= 1 - beta1
    m += buf
    np.abs(m, out=buf)                                     # flush: m *= (|m| >= tiny)
    np.greater_equal(buf, tiny, out=buf, casting="unsafe")
    m *= buf
    np.multiply(g, g, out=buf)
    buf -= v
    buf *= 1 - beta2
    v += buf
    np.greater_equal(v, tiny, out=buf, casting="unsafe")   # v >= 0: no abs needed
    v *= buf
    np.sqrt(v, out=buf)
    buf += eps_hat
    np.divide(m, buf, out=buf)
    buf *= step_size
    w -= buf


class ChunkedAdam(Adam):
    """:class:`~minifilm.nn.optim.Adam` with the same state and checkpoints, a faster step."""

    def __init__(self, parameter_sets, lr: float = 1e-4, beta1: float = 0.9, beta2: float = 0.999,
                 eps: float = 1e-8):
        super().__init__(parameter_sets, lr, beta1, beta2, eps)
        # One scratch chunk per dtype is enough: sets are updated one after the other.
        self._scratch = {p.dtype: np.empty(CHUNK, dtype=p.dtype) for p in self.sets}

    def advance(self) -> list:
        """Count one step for every trainable set; returns [(set index, step_size, eps_hat)] of
        those sets, the scalars of :func:`adam_span`."""
        out = []
        for i, p in enumerate(self.sets):
            if not p.trainable:
                continue
            self.steps[i] += 1
            t = self.steps[i]
            correction = math.sqrt(1 - self.beta2 ** t)
            out.append((i, self.lr * correction / (1 - self.beta1 ** t), self.eps * correction))
        return out

    def scratch(self, dtype) -> np.ndarray:
        """The scratch chunk for sets of ``dtype`` (made on first use)."""
        buf = self._scratch.get(dtype)
        if buf is None or len(buf) < CHUNK:              # a new dtype, or CHUNK changed
            buf = self._scratch[dtype] = np.empty(CHUNK, dtype=dtype)
        return buf

    def step(self) -> None:
        """Update ``.data`` of every trainable set in place from its ``.grad``."""
        for i, step_size, eps_hat in self.advance():
            p = self.sets[i]
            adam_span(p.data, p.grad, self.m[i], self.v[i], self.scratch(p.dtype), self.beta1, self.beta2,
                      step_size, eps_hat)


def adam_span(w, g, m, v, buf, beta1, beta2, step_size, eps_hat) -> None:
    """The update of :class:`ChunkedAdam` on flat arrays w, g, m, v (N,) (a whole set, or any slice
    of one: every number is updated on its own), CHUNK numbers at a time with ``buf`` (>= CHUNK,
    same dtype) as scratch."""
    tiny = np.finfo(w.dtype).tiny
    for lo in range(0, len(w), CHUNK):
        hi = min(lo + CHUNK, len(w))
        _adam_chunk(w[lo:hi], g[lo:hi], m[lo:hi], v[lo:hi], buf[: hi - lo], beta1, beta2, step_size, eps_hat, tiny)
