"""Forward/backward pairs: the maths of every layer, as pure functions.

Each operation comes as a pair in the style of CS231n::

    out, cache = f_forward(...)
    grads = f_backward(dout, cache)

``dout`` is dL/d(out) and has ``out``'s shape; the backward function returns dL/d(input) for every
input, in the order the forward function takes them. Nothing here keeps state or changes its
arguments. Every function works in the dtype it is given: float32 in, float32 out (no silent
upcast to float64), so training can run in float32 and gradient checks in float64.

Conventions: batch first; weights are stored ``(in, out)``, experts ``(K, in, out)`` and 1-D conv
kernels ``(k, in_channels, filters)``; sequences are channels-last ``(B, T, C)``.

The convolution and max pooling of Ψ live in conv.py and are re-exported here, so every pair is
``F.<name>`` for ``from minifilm.nn import functional as F``. These are the plain forms; what
training runs where it differs is named in each docstring (fast_conv.py, fast_linear.py).
"""
from __future__ import annotations

import numpy as np

from minifilm.nn.conv import (conv1d_backward, conv1d_forward, max_pool1d_backward,  # noqa: F401 (re-exported)
                              max_pool1d_forward)
from minifilm.nn.checks import require, require_grad_shape, sum_to_shape


# --------------------------------------------------------------------------------------------
# Linear
# --------------------------------------------------------------------------------------------
def linear_forward(x: np.ndarray, W: np.ndarray, b: np.ndarray):
    """Affine map ``y = x W + b``.

    x: (B, I) (any leading axes are allowed: (..., I)); W: (I, O); b: (O,).
    Returns y: (..., O) and a cache for :func:`linear_backward`.
    """
    require(W.ndim == 2 and x.shape[-1] == W.shape[0],
            f"linear_forward: x has {x.shape[-1]} features (shape {x.shape}) but W is {W.shape}, "
            "expected (in, out) with in matching x's last axis")
    require(b.shape == (W.shape[1],), f"linear_forward: b is {b.shape}, expected ({W.shape[1]},)")
    return x @ W + b, (x, W)


def linear_backward(dout: np.ndarray, cache):
    """Gradients of :func:`linear_forward`: dx = dout Wᵀ (..., I), dW = xᵀ dout (I, O), db (O,).

    Ψ's dense layers run :func:`minifilm.nn.fast_linear.linear_fast_backward`, the same with dW in
    a reused buffer.
    """
    x, W = cache
    require_grad_shape("linear_backward", dout, x.shape[:-1] + (W.shape[1],))
    x2 = x.reshape(-1, W.shape[0])       # (N, I) with N = product of the leading axes
    d2 = dout.reshape(-1, W.shape[1])    # (N, O)
    return dout @ W.T, x2.T @ d2, d2.sum(axis=0)


# --------------------------------------------------------------------------------------------
# Activations
# --------------------------------------------------------------------------------------------
def elu_forward(x: np.ndarray):
    """ELU with alpha = 1 (Clevert et al. 2015): ``x`` if x > 0 else ``exp(x) - 1``. Any shape."""
    # expm1 on min(x, 0) avoids overflow warnings for large positive x and is exact near 0.
    out = np.where(x > 0, x, np.expm1(np.minimum(x, 0)))
    return out, (x, out)


def elu_backward(dout: np.ndarray, cache):
    """dx for :func:`elu_forward`; the slope for x <= 0 is exp(x) = out + 1."""
    x, out = cache
    require_grad_shape("elu_backward", dout, out.shape)
    return dout * np.where(x > 0, 1, out + 1).astype(dout.dtype, copy=False)


def relu_forward(x: np.ndarray):
    """ReLU ``max(x, 0)``. Any shape."""
    return np.maximum(x, 0), x


def relu_backward(dout: np.ndarray, cache):
    """dx for :func:`relu_forward` (slope 0 at x == 0)."""
    x = cache
    require_grad_shape("relu_backward", dout, np.shape(x))
    return dout * (x > 0)


def softmax_forward(x: np.ndarray):
    """Softmax over the last axis, with the row maximum subtracted so exp never overflows.

    (The original runtime does not subtract the maximum; the result is the same, only safer.)
    x: (..., K) -> y: (..., K), rows summing to 1.
    """
    e = np.exp(x - x.max(axis=-1, keepdims=True))
    y = e / e.sum(axis=-1, keepdims=True)
    return y, y


def softmax_backward(dout: np.ndarray, cache):
    """dx = y * (dout - sum(dout * y)) row by row (the Jacobian diag(y) - y y^T applied to dout)."""
    y = cache
    require_grad_shape("softmax_backward", dout, y.shape)
    return y * (dout - np.sum(dout * y, axis=-1, keepdims=True))


# --------------------------------------------------------------------------------------------
# Layer normalisation without affine (the paper applies FiLM right after it, Eq. 3)
# --------------------------------------------------------------------------------------------
def layer_norm_forward(x: np.ndarray, unbiased: bool = True, eps: float = 1e-6):
    """Layer norm over the last axis, no learnable scale or shift: ``(x - mu) / (sigma + eps)``.

    This is the bracket in Eq. (3). ``sigma`` is the standard deviation of each row, unbiased
    (divide by H - 1) or biased (divide by H). The original trains with ``unbiased=True,
    eps=1e-6`` and runs with ``unbiased=False, eps=0.0`` (docs/original-code.md §10.2).
    x: (..., H) -> y: (..., H).
    """
    H = x.shape[-1]
    require(H >= 2 or not unbiased,
            f"layer_norm_forward: the unbiased std needs at least 2 features, x is {x.shape}")
    mu = x.mean(axis=-1, keepdims=True)
    xc = x - mu
    sigma = np.sqrt(np.sum(xc * xc, axis=-1, keepdims=True) / (H - 1 if unbiased else H))
    s = sigma + eps
    return xc / s, (xc, sigma, s, H - 1 if unbiased else H)


def layer_norm_backward(dout: np.ndarray, cache):
    """dx for :func:`layer_norm_forward`.

    With y = xc / s, s = sigma + eps and sigma = sqrt(sum(xc^2) / n):
    dL/dxc = g / s - xc * sum(g * xc) / (s^2 * n * sigma), and dx = dL/dxc - mean(dL/dxc),
    where the mean of the second term is zero because xc has zero mean.
    A constant row (sigma = 0) gets gradient g / s - mean(g / s), the limit of the formula.
    """
    xc, sigma, s, n = cache
    require_grad_shape("layer_norm_backward", dout, xc.shape)
    gs = dout / s
    dot = np.sum(dout * xc, axis=-1, keepdims=True)
    denom = s * s * n * sigma
    coef = np.divide(dot, denom, out=np.zeros_like(dot), where=denom > 0)
    return gs - gs.mean(axis=-1, keepdims=True) - xc * coef


# --------------------------------------------------------------------------------------------
# FiLM (Perez et al. 2018): the affine part of Eq. (3)
# --------------------------------------------------------------------------------------------
def film_forward(h: np.ndarray, gamma: np.ndarray, beta: np.ndarray):
    """Feature-wise linear modulation ``gamma * h + beta`` (Eq. 3).

    h, gamma, beta: (B, H), one gamma and beta per sample (the FiLM generator's output, Eq. 2).
    gamma and beta may also be (H,) to modulate the whole batch with one style.
    """
    require(np.broadcast_shapes(h.shape, gamma.shape, beta.shape) == h.shape,
            f"film_forward: gamma {gamma.shape} and beta {beta.shape} must match h {h.shape} "
            "(or broadcast to it)")
    return gamma * h + beta, (h, gamma, beta.shape)


def film_backward(dout: np.ndarray, cache):
    """Gradients of :func:`film_forward`: dh, dgamma, dbeta (each with its input's shape)."""
    h, gamma, beta_shape = cache
    require_grad_shape("film_backward", dout, h.shape)
    return (dout * gamma, sum_to_shape(dout * h, gamma.shape), sum_to_shape(dout, beta_shape))


# --------------------------------------------------------------------------------------------
# Dropout (Srivastava et al. 2014), inverted: scaled at training time, identity at test time
# --------------------------------------------------------------------------------------------
def dropout_forward(x: np.ndarray, p: float, rng: np.random.Generator | None = None,
                    mask: np.ndarray | None = None, train: bool = True):
    """Inverted dropout: keep each unit with probability 1 - p and scale kept units by 1/(1 - p).

    x: any shape. mask: boolean keep-mask of x's shape (True = keep); when None it is drawn from
    ``rng``. When ``train`` is False or ``p == 0`` this is the identity (no rng needed), so the
    expected activation is the same in training and at run time.
    """
    require(0.0 <= p < 1.0, f"dropout_forward: p must be in [0, 1), got {p}")
    if np.asarray(x).dtype.kind != "f":
        # scaled in x's dtype, 1 / (1 - p) would round to an integer (1 for p < 0.5)
        raise TypeError(f"dropout_forward: x must be a floating-point array, got {np.asarray(x).dtype}")
    if not train or p == 0.0:
        return x, None
    if mask is None:
        if rng is None:
            raise ValueError("dropout_forward: training with p > 0 needs an rng "
                             "(np.random.Generator) or an explicit mask")
        mask = rng.random(x.shape) >= p
    # an if, not require(): require's message is formatted on every call, and a dtype formats slowly
    if mask.shape != x.shape or mask.dtype != np.bool_:
        raise ValueError(f"dropout_forward: mask must be a boolean array of shape {x.shape}, "
                         f"got {mask.dtype} {mask.shape}")
    scale = x.dtype.type(1.0 / (1.0 - p))   # keep x's dtype
    return x * mask * scale, (mask, scale)


def dropout_backward(dout: np.ndarray, cache):
    """dx for :func:`dropout_forward`: the same mask and scale applied to dout."""
    if cache is None:
        return dout
    mask, scale = cache
    require_grad_shape("dropout_backward", dout, mask.shape)
    return dout * mask * scale


# --------------------------------------------------------------------------------------------
# Mixture of experts (Sec. 4.1: Phi's weights are blended per sample by the gating output alpha)
# --------------------------------------------------------------------------------------------
def expert_blend_forward(x: np.ndarray, alpha: np.ndarray, W: np.ndarray, b: np.ndarray):
    """The gated-expert layer as the paper describes it: blend the experts' weights, then multiply.

        W_b = sum_k a_bk W_k    b_b = sum_k a_bk b_k    y_b = x_b W_b + b_b

    x: (B, I); alpha: (B, K) (Ω's output, rows summing to 1); W: (K, I, O); b: (K, O) -> y: (B, O).
    The plain form: it builds a (B, I, O) weight per sample. :func:`expert_linear_forward` computes
    the same sum without it (4-8x faster) and is the one the networks use.
    """
    K, I, O = W.shape
    require(x.ndim == 2 and x.shape[1] == I and alpha.shape == (x.shape[0], K) and b.shape == (K, O),
            f"expert_blend_forward: x {x.shape}, alpha {alpha.shape}, W {W.shape}, b {b.shape}; "
            f"expected (B, {I}), (B, {K}), (K, I, O), ({K}, {O})")
    W_b = np.einsum("bk,kio->bio", alpha, W)                    # (B, I, O): one weight per sample
    y = np.einsum("bi,bio->bo", x, W_b) + alpha @ b              # (B, O)
    return y, (x, alpha, W, b, W_b)


def expert_blend_backward(dout: np.ndarray, cache):
    """Gradients of :func:`expert_blend_forward`: dx (B, I), dalpha (B, K), dW (K, I, O), db (K, O).

    dx_b = W_b dout_b; the blended weight's gradient dW_b = outer(x_b, dout_b) goes to each expert
    by its weight, dW_k = sum_b a_bk dW_b, and to the gate, dalpha_bk = <W_k, dW_b> + b_k . dout_b.
    """
    x, alpha, W, b, W_b = cache
    require_grad_shape("expert_blend_backward", dout, (x.shape[0], W.shape[2]))
    dx = np.einsum("bo,bio->bi", dout, W_b)
    dW_b = x[:, :, None] * dout[:, None, :]                       # (B, I, O)
    dW = np.einsum("bk,bio->kio", alpha, dW_b)
    dalpha = np.einsum("kio,bio->bk", W, dW_b) + dout @ b.T
    return dx, dalpha, dW, alpha.T @ dout


def expert_linear_forward(x: np.ndarray, alpha: np.ndarray, W: np.ndarray, b: np.ndarray):
    """Per-sample blend of K expert linear layers: ``y_b = x_b (sum_k a_bk W_k) + sum_k a_bk b_k``,
    the same numbers as :func:`expert_blend_forward` (tests/nn/test_optimised_equivalence.py).

    x: (B, I); alpha: (B, K); W: (K, I, O); b: (K, O) -> y: (B, O).

    Fast form (never builds the (B, I, O) per-sample weights): since
    ``y_b = sum_k sum_i a_bk x_bi W_kio``, put Z_b = outer(a_b, x_b) flattened to K*I numbers and
    ``y = Z @ W.reshape(K*I, O) + alpha @ b``: one matrix product. At run time
    (minifilm/runtime/network.py) the experts are laid side by side instead, (I, K*O), which is
    the same sum with one product per layer and no outer product.
    """
    K, I, O = W.shape
    require(x.ndim == 2 and x.shape[1] == I,
            f"expert_linear_forward: x is {x.shape}, expected (B, {I}) to match W {W.shape}")
    require(alpha.shape == (x.shape[0], K),
            f"expert_linear_forward: alpha is {alpha.shape}, expected ({x.shape[0]}, {K})")
    require(b.shape == (K, O), f"expert_linear_forward: b is {b.shape}, expected ({K}, {O})")
    Z = (alpha[:, :, None] * x[:, None, :]).reshape(-1, K * I)   # (B, K*I)
    y = Z @ W.reshape(K * I, O) + alpha @ b                      # (B, O)
    return y, (x, alpha, W, b, Z)


def expert_linear_backward(dout: np.ndarray, cache, weights: bool = True):
    """Gradients of :func:`expert_linear_forward`: dx (B, I), dalpha (B, K), dW (K, I, O), db (K, O).

    Three matrix products: dZ = dout W^T, dW = Z^T dout, db = alpha^T dout; then dZ (B, K, I) is
    contracted with alpha for dx and with x for dalpha (plus the bias path dout b^T).
    weights=False: dW and db are None (frozen experts, as when a style's vector or adapter is fitted).
    """
    x, alpha, W, b, Z = cache
    K, I, O = W.shape
    require_grad_shape("expert_linear_backward", dout, (x.shape[0], O))
    dZ = (dout @ W.reshape(K * I, O).T).reshape(-1, K, I)       # (B, K, I)
    dW = (Z.T @ dout).reshape(K, I, O) if weights else None
    db = alpha.T @ dout if weights else None                     # (K, O)
    dx = np.matmul(alpha[:, None, :], dZ)[:, 0, :]               # (B, I) = sum_k a_bk dZ_bk
    dalpha = np.matmul(dZ, x[:, :, None])[:, :, 0] + dout @ b.T  # (B, K)
    return dx, dalpha, dW, db


# --------------------------------------------------------------------------------------------
# Gather rows (a style clip shared by several samples: Ψ runs once per clip)
# --------------------------------------------------------------------------------------------
def gather_forward(x: np.ndarray, index: np.ndarray):
    """Rows of x by index: ``y[b] = x[index[b]]``. x: (C, ...), index: (B,) ints in [0, C) -> (B, ...)."""
    index = np.asarray(index)
    require(index.ndim == 1 and np.issubdtype(index.dtype, np.integer),
            f"gather_forward: index must be 1-D integers, got {index.dtype} {index.shape}")
    require(index.size > 0, "gather_forward: index is empty (a batch of 0 samples)")
    lo, hi = int(index.min()), int(index.max())
    require(lo >= 0 and hi < x.shape[0], f"gather_forward: index must lie in [0, {x.shape[0]}), got {lo}..{hi}")
    return x[index], (index, x.shape)


def gather_backward(dout: np.ndarray, cache):
    """dx for :func:`gather_forward`: each row of x receives the sum of the rows gathered from it."""
    index, shape = cache
    require_grad_shape("gather_backward", dout, (len(index),) + tuple(shape[1:]))
    dx = np.zeros(shape, dtype=dout.dtype)
    np.add.at(dx, index, dout)
    return dx
