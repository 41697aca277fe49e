"""Adam (Kingma and Ba 2014), the textbook update over flat parameter buffers.

Each :class:`~minifilm.nn.params.Parameters` keeps all weights of a network in one vector, so a
step is a few vector operations per set instead of a loop over dozens of small arrays. Sets with
``trainable = False`` are skipped entirely (no update, no moment or step-count change): that is
how the paper fine-tunes only the FiLM generator on new styles (Sec. 5.3.2).

This is the plain form, written as the paper writes it. Training uses
:class:`minifilm.nn.fast_optim.ChunkedAdam`, the same update computed in place, chunk by chunk
(tests/nn/test_optimised_equivalence.py keeps the two equal).
"""
from __future__ import annotations

import numpy as np

from minifilm.nn.params import Parameters


def flush_subnormals(a: np.ndarray) -> np.ndarray:
    """Set the entries of ``a`` whose magnitude is below the smallest normal number of its dtype
    (``np.finfo(dtype).tiny``: 1.2e-38 in float32) to 0, in place; returns ``a``.

    Why: many CPUs (Intel's among them) take a slow microcode path for every operation on a
    subnormal number, and numpy cannot switch on the processor's flush-to-zero mode.
    """
    a[np.abs(a) < np.finfo(a.dtype).tiny] = 0
    return a


class Adam:
    """Adam with bias correction.

    For each trainable set, with g its gradient and t its own step count:

        m <- beta1 m + (1 - beta1) g              first moment (running mean of g)
        v <- beta2 v + (1 - beta2) g^2            second moment (running mean of g^2)
        m_hat = m / (1 - beta1^t),  v_hat = v / (1 - beta2^t)        bias correction
        data <- data - lr * m_hat / (sqrt(v_hat) + eps)

    Moments below the smallest normal float are set to 0 after every update
    (:func:`flush_subnormals`): where a unit's gradient stays 0 (a dead ReLU of Ψ) m shrinks by
    beta1 every step into the subnormal range, on which many CPUs compute slowly, and stays there
    for ~150 steps (v, shrinking by beta2, for ~16,000); 0 is what those moments decay to anyway.
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

    def step(self) -> None:
        """Update ``.data`` of every trainable set in place from its ``.grad``."""
        b1, b2 = self.beta1, self.beta2
        for i, p in enumerate(self.sets):
            if not p.trainable:
                continue
            self.steps[i] += 1
            t = self.steps[i]
            m, v, g = self.m[i], self.v[i], p.grad
            m[...] = flush_subnormals(b1 * m + (1 - b1) * g)
            v[...] = flush_subnormals(b2 * v + (1 - b2) * g * g)
            m_hat = m / (1 - b1 ** t)
            v_hat = v / (1 - b2 ** t)
            p.data -= (self.lr * m_hat / (np.sqrt(v_hat) + self.eps)).astype(p.dtype, copy=False)

    def state_dict(self) -> dict[str, np.ndarray]:
        """Moments and step counts as arrays (``np.savez``-ready): m.<i>, v.<i>, steps."""
        state = {"steps": np.array(self.steps, dtype=np.int64)}
        for i in range(len(self.sets)):
            state[f"m.{i}"] = self.m[i].copy()
            state[f"v.{i}"] = self.v[i].copy()
        return state

    def load_state_dict(self, state: dict) -> None:
        """Restore moments and step counts written by :meth:`state_dict` (same sets, same order).

        Subnormal moments (from a checkpoint written before they were flushed) are set to 0."""
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
            flush_subnormals(self.m[i])
            flush_subnormals(self.v[i])
        self.steps = [int(s) for s in steps]
