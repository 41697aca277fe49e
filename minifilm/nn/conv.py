"""1-D convolution over time and max pooling: the layers of Ψ, the FiLM generator (Eq. 2). Plain forms.

Forward/backward pairs as in functional.py (which re-exports them, so ``F.conv1d_forward`` works).
The convolution is written the way a reader meets it first: im2col, then one matrix product.
Training runs the same convolution from minifilm/nn/fast_conv.py (reused buffers, and an exact
FFT form for a batch of long clips), tested equal to this one in tests/nn/test_fast_conv.py.
"""
from __future__ import annotations

import numpy as np

from minifilm.nn.checks import require, require_grad_shape


def im2col(x: np.ndarray, k: int) -> np.ndarray:
    """(B, T, C) -> cols (B*T, k*C): row (b, t) holds frames t - k//2 .. t + k//2 of sample b,
    zero outside [0, T), flattened tap-major, (j, c), to match W (k, C, F) reshaped to (k*C, F)."""
    B, T, C = x.shape
    p = k // 2
    xp = np.pad(x, ((0, 0), (p, p), (0, 0)))                      # (B, T + 2p, C), zeros at both ends
    cols = np.stack([xp[:, j: j + T] for j in range(k)], axis=2)   # (B, T, k, C): tap j is frame t + j - p
    return cols.reshape(B * T, k * C)


def conv1d_forward(x: np.ndarray, W: np.ndarray, b: np.ndarray):
    """1-D convolution over time, stride 1, 'same' zero padding (cross-correlation, as in TF).

    ``y[b, t, f] = sum_j sum_c x[b, t + j - p, c] W[j, c, f] + b[f]`` with p = k//2 and x zero
    outside [0, T); as a matrix product, ``y = im2col(x) @ W.reshape(k*C, F) + b``.
    x: (B, T, C) channels-last; W: (k, C, F) with k odd; b: (F,) -> y: (B, T, F).
    """
    k, C, F = W.shape
    require(k % 2 == 1, f"conv1d_forward: kernel size must be odd for 'same' padding, W is {W.shape}")
    require(x.ndim == 3 and x.shape[2] == C,
            f"conv1d_forward: x is {x.shape}, expected (B, T, {C}) to match W {W.shape}")
    require(b.shape == (F,), f"conv1d_forward: b is {b.shape}, expected ({F},)")
    require(x.shape[0] > 0 and x.shape[1] > 0,
            f"conv1d_forward: x is {x.shape}: a batch of 0 clips or clips of 0 frames")
    B, T, _ = x.shape
    x = np.asarray(x, dtype=np.result_type(x, W))
    cols = im2col(x, k)                                           # (B*T, k*C)
    y = cols @ W.reshape(k * C, F) + b                            # (B*T, F)
    return y.reshape(B, T, F), (cols, x.shape, W)


def conv1d_backward(dout: np.ndarray, cache, need_dx: bool = True):
    """Gradients of :func:`conv1d_forward`: dx (B, T, C), dW (k, C, F), db (F,).

    With G = dout as (B*T, F): dW = colsᵀ G and db = the column sums of G. dx is itself a 'same'
    convolution, of dout with the kernel flipped in time and transposed to (k, F, C):
    ``dx[t] = sum_j dout[t - j + p] W[j]ᵀ`` = im2col(dout) @ W[::-1] as (k*F, C)
    (docs/backprop.md derives it). ``need_dx=False`` returns None for dx: a network's first
    layer never needs the gradient of its input data.
    """
    cols, (B, T, C), W = cache
    k, _, F = W.shape
    require_grad_shape("conv1d_backward", dout, (B, T, F))
    G = dout.reshape(B * T, F)
    dW = (cols.T @ G).reshape(k, C, F)
    db = G.sum(axis=0)
    dx = None
    if need_dx:
        W_flip = W[::-1].transpose(0, 2, 1).reshape(k * F, C)    # (k*F, C)
        dx = (im2col(dout, k) @ W_flip).reshape(B, T, C)
    return dx, dW, db


def max_pool1d_forward(x: np.ndarray):
    """Max pooling over time with size 2 and stride 2: (B, T, C) -> (B, T // 2, C).

    ``y[t] = max(x[2t], x[2t+1])``. With odd T the last frame has no partner and is dropped (as
    with TF's 'valid' padding). Ties pick the first frame of the pair. The pairs are the even and
    odd frames (two strided views), so the cache is one boolean array: where the first frame won.
    """
    require(x.ndim == 3 and x.shape[1] >= 2,
            f"max_pool1d_forward: x is {x.shape}, expected (B, T, C) with T >= 2")
    T2 = x.shape[1] // 2
    even, odd = x[:, 0: 2 * T2: 2], x[:, 1: 2 * T2: 2]          # (B, T2, C) views
    first = even >= odd                                          # where the first frame wins
    return np.maximum(even, odd), (x.shape, first)


def max_pool1d_backward(dout: np.ndarray, cache):
    """dx for :func:`max_pool1d_forward`: each gradient goes to the frame that won its pair."""
    (B, T, C), first = cache
    T2 = T // 2
    require_grad_shape("max_pool1d_backward", dout, (B, T2, C))
    dx = np.empty((B, T, C), dtype=dout.dtype)
    dx[:, 2 * T2:] = 0                                           # the dropped odd frame, if any
    # Multiplying by the masks (rather than np.where) is the fast way (benchmarks/README.md); a
    # non-finite dout (a diverged run) then also reaches the losing frame, as inf * 0 = nan.
    np.multiply(dout, first, out=dx[:, 0: 2 * T2: 2])
    np.multiply(dout, ~first, out=dx[:, 1: 2 * T2: 2])
    return dx
