"""Scratch buffers reused from call to call: the fast layers' workspaces (fast_conv.py,
fast_linear.py). The plain layers allocate their arrays afresh and never need one."""
from __future__ import annotations

import numpy as np


def scratch(work: dict | None, name: str, shape: tuple, dtype, zeros: bool = False) -> np.ndarray:
    """The array ``work[name]`` of this shape and dtype, made (and kept in ``work``) if it is missing.

    Why: reusing a layer's big arrays from step to step avoids the page faults of mapping them
    afresh (the measurements are in reports/2026-12-02_naive_beside_fast.md). ``work=None``: a new
    array every call. A workspace belongs to ONE layer: what is taken from it (and the caches and
    gradients that point into it) is overwritten by that layer's next call. ``zeros=True``: a new
    array starts zeroed (for callers that write only part of it and rely on the rest staying 0).
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
