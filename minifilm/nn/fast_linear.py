"""The linear layer's backward pass with its weight gradient in a reused buffer (Ψ's dense layers).

The same numbers as :func:`minifilm.nn.functional.linear_backward`; only where dW lives differs.
Ψ's first dense layer has a large weight matrix (the paper's: 15,360 x 2,048, its 240 clip frames
pooled twice by 2 to 60, times 256 filters), whose gradient would otherwise be a fresh array every
step (benchmarks/README.md, "Peak memory of a training step, batch 32").
"""
from __future__ import annotations

import numpy as np

from minifilm.nn.checks import require_grad_shape
from minifilm.nn.workspaces import scratch


def linear_fast_backward(dout: np.ndarray, cache, work: dict | None):
    """Gradients of :func:`minifilm.nn.functional.linear_forward`: dx (..., I), dW (I, O), db (O,),
    with dW written into ``work["dW"]`` (see :func:`~minifilm.nn.workspaces.scratch`): add it to your
    gradients before the layer's next call."""
    x, W = cache
    require_grad_shape("linear_backward", dout, x.shape[:-1] + (W.shape[1],))
    x2 = x.reshape(-1, W.shape[0])       # (N, I) with N = product of the leading axes
    d2 = dout.reshape(-1, W.shape[1])    # (N, O)
    dW = np.matmul(x2.T, d2, out=scratch(work, "dW", W.shape, np.result_type(x2, d2)))
    return dout @ W.T, dW, d2.sum(axis=0)
