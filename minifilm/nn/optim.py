"""Adam (Kingma and Ba 2014), in place over flat parameter buffers.

Each :class:`~minifilm.nn.params.Parameters` keeps all weights of a network in one vector, so a
step is a few in-place vector operations per set instead of a loop over dozens of small arrays.
Sets with ``trainable = False`` are skipped entirely (no update, no moment or step-count change):
that is how the paper fine-tunes only the FiLM generator on new styles (Sec. 5.3.2).
"""
from __future__ import annotations

import math

import numpy as np

from minifilm.nn.params import Parameters

# Numbers per chunk: 5 float32 arrays of it (w, g, m, v, scratch) take 1.3 MB, about the core's L2.
# Measured on the 2-core EPYC (benchmarks/kernels.py, 1 thread): 65536 is ~5% faster than 32768
# for the paper's 44 M parameters (53-55 ms a step, against 57 and 64 ms for 32768 and 16384) and
# equal for train_small's 707 k (0.68 ms with the numbers in cache, 0.85 ms after evicting them);
# one pass over the whole buffer per operation is 5-10% slower at 707 k.
#
# What else was tried: scipy.linalg.blas's in-place sscal / saxpy (9 calls a chunk instead of 12)
# are ~20% faster with one BLAS thread, but with OpenBLAS's default two threads on this shared
# machine their medians were up to 5x (707 k) and 15x (44 M) slower: OpenBLAS splits each
# level-1 call between its threads, and a thread waiting for a busy core stalls the step. numpy's
# ufuncs run on the calling thread only, so plain numpy stays. About a third of the time is
# np.sqrt: numpy ships float32 sqrt only in its baseline SSE build
# (numpy.lib.introspect.opt_func_info), at ~0.5 ns a number against ~0.1 for a division.
CHUNK = 65536


def _adam_chunk(w, g, m, v, buf, beta1, beta2, step_size, eps_hat):
    """One Adam update of a chunk, in place, with ``buf`` as the only temporary.

    m <- m + (1 - beta1)(g - m)         (= beta1 m + (1 - beta1) g)
    v <- v + (1 - beta2)(g^2 - v)       (= beta2 v + (1 - beta2) g^2)
    w <- w - step_size * m / (sqrt(v) + eps_hat)
    """
    np.subtract(g, m, out=buf)
    buf *= 1 - beta1
    m += buf
    np.multiply(g, g, out=buf)
    buf -= v
    buf *= 1 - beta2
    v += buf
    np.sqrt(v, out=buf)
    buf += eps_hat
    np.divide(m, buf, out=buf)
    buf *= step_size
    w -= buf


class Adam:
    """Adam with bias correction.

    For each trainable set, with g its gradient and t its own step count:
        m <- beta1 m + (1 - beta1) g,    v <- beta2 v + (1 - beta2) g^2
        data <- data - lr * m_hat / (sqrt(v_hat) + eps),  m_hat = m / (1 - beta1^t),
                                                         v_hat = v / (1 - beta2^t).
    Computed in the equivalent form of the Adam paper (Sec. 2): the bias corrections go into a
    scalar step size ``lr * sqrt(1 - beta2^t) / (1 - beta1^t)`` and ``eps * sqrt(1 - beta2^t)``.
    Each set counts its own steps, so a set that was frozen and is later unfrozen starts its
    bias correction at 1.
    """

    def __init__(self, parameter_sets: list[Parameters], lr: float = 1e-4, beta1: float = 0.9,
                 beta2: float = 0.999, eps: float = 1e-8):
        if isinstance(parameter_sets, Parameters):
            parameter_sets = [parameter_sets]
        self.sets = list(parameter_sets)
        if not self.sets:
            raise ValueError("Adam: no parameter sets given")
        if not (0.0 <= beta1 < 1.0 and 0.0 <= beta2 < 1.0):
            raise ValueError(f"Adam: beta1, beta2 must be in [0, 1), got {beta1}, {beta2}")
        self.lr, self.beta1, self.beta2, self.eps = lr, beta1, beta2, eps
        self.m = [np.zeros_like(p.data) for p in self.sets]
        self.v = [np.zeros_like(p.data) for p in self.sets]
        self.steps = [0] * len(self.sets)
        # One scratch chunk per dtype is enough: sets are updated one after the other.
        self._scratch = {p.dtype: np.empty(CHUNK, dtype=p.dtype) for p in self.sets}

    def step(self) -> None:
        """Update ``.data`` of every trainable set in place from its ``.grad``."""
        for i, p in enumerate(self.sets):
            if not p.trainable:
                continue
            self.steps[i] += 1
            t = self.steps[i]
            correction = math.sqrt(1 - self.beta2 ** t)
            step_size = self.lr * correction / (1 - self.beta1 ** t)
            eps_hat = self.eps * correction
            m, v, g, w, buf = self.m[i], self.v[i], p.grad, p.data, self._scratch[p.dtype]
            # Chunks small enough for the core's L2 cache: the ~11 passes below then run over
            # cached numbers, and main memory is read (w, g, m, v) and written (w, m, v) once.
            # Over the whole buffer at once every pass would go to main memory (about twice as
            # slow for the paper's Φ, 4.9 M numbers, and Ψ, 39 M).
            for lo in range(0, p.size, CHUNK):
                hi = min(lo + CHUNK, p.size)
                _adam_chunk(w[lo:hi], g[lo:hi], m[lo:hi], v[lo:hi], buf[: hi - lo],
                            self.beta1, self.beta2, step_size, eps_hat)

    def state_dict(self) -> dict[str, np.ndarray]:
        """Moments and step counts as arrays (``np.savez``-ready): m.<i>, v.<i>, steps."""
        state = {"steps": np.array(self.steps, dtype=np.int64)}
        for i in range(len(self.sets)):
            state[f"m.{i}"] = self.m[i].copy()
            state[f"v.{i}"] = self.v[i].copy()
        return state

    def load_state_dict(self, state: dict) -> None:
        """Restore moments and step counts written by :meth:`state_dict` (same sets, same order)."""
        steps = np.asarray(state["steps"]) if "steps" in state else None
        if steps is None or steps.shape != (len(self.sets),):
            raise ValueError(f"Adam.load_state_dict: 'steps' must hold {len(self.sets)} counts, "
                             f"got {None if steps is None else steps.shape}")
        for i, p in enumerate(self.sets):
            for key in (f"m.{i}", f"v.{i}"):
                if key not in state:
                    raise KeyError(f"Adam.load_state_dict: missing {key!r}")
                if np.asarray(state[key]).dtype.kind != "f":
                    raise ValueError(f"Adam.load_state_dict: {key!r} must hold floats, got {np.asarray(state[key]).dtype}")
                if np.shape(state[key]) != p.data.shape:
                    raise ValueError(f"Adam.load_state_dict: {key!r} is {np.shape(state[key])}, "
                                     f"expected {p.data.shape} (parameter set {i})")
                if not np.all(np.isfinite(state[key])) or (key[0] == "v" and np.any(np.asarray(state[key]) < 0)):
                    raise ValueError(f"Adam.load_state_dict: {key!r} holds non-finite"
                                     f"{' or negative' if key[0] == 'v' else ''} values")
        if steps.dtype.kind not in "iu" or np.any(steps < 0):
            raise ValueError(f"Adam.load_state_dict: step counts must be whole numbers >= 0, got {steps.tolist()}")
        for i in range(len(self.sets)):
            self.m[i][...] = state[f"m.{i}"]
            self.v[i][...] = state[f"v.{i}"]
        self.steps = [int(s) for s in steps]
