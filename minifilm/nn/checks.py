"""Checks every forward/backward pair uses: shapes that name the culprit (the inputs, and the
incoming gradient against the output), and summing a gradient back to a broadcast input's shape."""
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
