"""Helpers every forward/backward pair uses: shape checks that name the culprit (the inputs, and
the incoming gradient against the output), summing a gradient back to a broadcast input's shape,
and scratch buffers reused from call to call."""
from __future__ import annotations

import numpy as np


def require(ok: bool, message: str) -> None:
    """Raise a ValueError with ``message`` unless ``ok`` (shape checks that name the culprit)."""
    if not ok:
        raise ValueError(message)


def require_grad_shape(where: str, dout: np.ndarray, shape: tuple) -> None:
    """A backward pass's incoming gradient must have its output's shape exactly: numpy would
    silently broadcast a (1, H) dout over a (B, H) output and return a gradient that is neither
    (every sample given the same gradient), so a mismatch is a ValueError naming ``where``."""
    if np.shape(dout) != tuple(shape):
        raise ValueError(f"{where}: dout is {np.shape(dout)}, expected the output's shape {tuple(shape)}")


def sum_to_shape(grad: np.ndarray, shape: tuple) -> np.ndarray:
    """Sum ``grad`` over the axes that numpy broadcasting added or stretched to reach ``shape``."""
    while grad.ndim > len(shape):
        grad = grad.sum(axis=0)
    for axis, n in enumerate(shape):
        if n == 1 and grad.shape[axis] != 1:
            grad = grad.sum(axis=axis, keepdims=True)
    return grad


def scratch(work: dict | None, name: str, shape: tuple, dtype, zeros: bool = False) -> np.ndarray:
    """A scratch array kept in ``work`` between calls (a new one when ``work`` is None).

    Why: on this kind of machine a fresh array of more than 32 MB is mapped from the operating
    system on every call and the first write to each page costs a page fault (about 1.3 ms per MB
    here, a third of a paper-size training step). A layer that keeps a ``work`` dict and passes
    it to every call reuses its big buffers instead. A workspace belongs to ONE layer: arrays
    taken from it (and the caches and gradients that point into them) are overwritten by that
    layer's next call. ``zeros=True``: a new array starts zeroed (callers that write only part of
    it rely on the rest staying zero across reuses).
    """
    shape = tuple(shape)
    dtype = np.dtype(dtype)
    if work is not None:
        a = work.get(name)
        if a is not None and a.shape == shape and a.dtype == dtype:
            return a
    a = np.zeros(shape, dtype) if zeros else np.empty(shape, dtype)
    if work is not None:
        work[name] = a
    return a
