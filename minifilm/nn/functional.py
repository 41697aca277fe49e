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

Dependencies: numpy, and scipy.fft for the FFT path of the convolution (scipy's pocketfft
transforms many channels at once with SIMD and was 4-5x faster than numpy.fft on Ψ's clips).
"""
from __future__ import annotations

import functools

import numpy as np
import scipy.fft
from numpy.lib.stride_tricks import sliding_window_view


def _require(ok: bool, message: str) -> None:
    """Raise a ValueError with ``message`` unless ``ok`` (shape checks that name the culprit)."""
    if not ok:
        raise ValueError(message)


def _sum_to_shape(grad: np.ndarray, shape: tuple) -> np.ndarray:
    """Sum ``grad`` over the axes that numpy broadcasting added or stretched to reach ``shape``."""
    while grad.ndim > len(shape):
        grad = grad.sum(axis=0)
    for axis, n in enumerate(shape):
        if n == 1 and grad.shape[axis] != 1:
            grad = grad.sum(axis=axis, keepdims=True)
    return grad


def _scratch(work: dict | None, name: str, shape: tuple, dtype, zeros: bool = False) -> np.ndarray:
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


# --------------------------------------------------------------------------------------------
# Linear
# --------------------------------------------------------------------------------------------
def linear_forward(x: np.ndarray, W: np.ndarray, b: np.ndarray):
    """Affine map ``y = x W + b``.

    x: (B, I) (any leading axes are allowed: (..., I)); W: (I, O); b: (O,).
    Returns y: (..., O) and a cache for :func:`linear_backward`.
    """
    _require(W.ndim == 2 and x.shape[-1] == W.shape[0],
             f"linear_forward: x has {x.shape[-1]} features (shape {x.shape}) but W is {W.shape}, "
             "expected (in, out) with in matching x's last axis")
    _require(b.shape == (W.shape[1],), f"linear_forward: b is {b.shape}, expected ({W.shape[1]},)")
    return x @ W + b, (x, W)


def linear_backward(dout: np.ndarray, cache, work: dict | None = None):
    """Gradients of :func:`linear_forward`: dx (..., I), dW (I, O), db (O,).

    With ``work`` (see :func:`_scratch`) dW is written into a buffer kept there: add it to your
    gradients before the next call.
    """
    x, W = cache
    x2 = x.reshape(-1, W.shape[0])       # (N, I) with N = product of the leading axes
    d2 = dout.reshape(-1, W.shape[1])    # (N, O)
    dW = np.matmul(x2.T, d2, out=_scratch(work, "dW", W.shape, np.result_type(x2, d2)))
    return dout @ W.T, dW, d2.sum(axis=0)


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
    return dout * np.where(x > 0, 1, out + 1).astype(dout.dtype, copy=False)


def relu_forward(x: np.ndarray):
    """ReLU ``max(x, 0)``. Any shape."""
    return np.maximum(x, 0), x


def relu_backward(dout: np.ndarray, cache):
    """dx for :func:`relu_forward` (slope 0 at x == 0)."""
    x = cache
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
    return y * (dout - np.sum(dout * y, axis=-1, keepdims=True))


# --------------------------------------------------------------------------------------------
# Layer normalisation without affine (the paper applies FiLM right after it, Eq. 3)
# --------------------------------------------------------------------------------------------
def layer_norm_forward(x: np.ndarray, unbiased: bool = True, eps: float = 1e-6):
    """Layer norm over the last axis, no learnable scale or shift: ``(x - mu) / (sigma + eps)``.

    This is the bracket in Eq. (3). ``sigma`` is the standard deviation of each row, unbiased
    (divide by H - 1) or biased (divide by H). The original trains with ``unbiased=True,
    eps=1e-6`` and runs with ``unbiased=False, eps=0.0`` (original-pipeline §10.2).
    x: (..., H) -> y: (..., H).
    """
    H = x.shape[-1]
    _require(H >= 2 or not unbiased,
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
    _require(np.broadcast_shapes(h.shape, gamma.shape, beta.shape) == h.shape,
             f"film_forward: gamma {gamma.shape} and beta {beta.shape} must match h {h.shape} "
             "(or broadcast to it)")
    return gamma * h + beta, (h, gamma, beta.shape)


def film_backward(dout: np.ndarray, cache):
    """Gradients of :func:`film_forward`: dh, dgamma, dbeta (each with its input's shape)."""
    h, gamma, beta_shape = cache
    return (dout * gamma, _sum_to_shape(dout * h, gamma.shape), _sum_to_shape(dout, beta_shape))


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
    _require(0.0 <= p < 1.0, f"dropout_forward: p must be in [0, 1), got {p}")
    if not train or p == 0.0:
        return x, None
    if mask is None:
        if rng is None:
            raise ValueError("dropout_forward: training with p > 0 needs an rng "
                             "(np.random.Generator) or an explicit mask")
        mask = rng.random(x.shape) >= p
    _require(mask.shape == x.shape and mask.dtype == np.bool_,
             f"dropout_forward: mask must be a boolean array of shape {x.shape}, "
             f"got {mask.dtype} {mask.shape}")
    scale = x.dtype.type(1.0 / (1.0 - p))   # keep x's dtype
    return x * mask * scale, (mask, scale)


def dropout_backward(dout: np.ndarray, cache):
    """dx for :func:`dropout_forward`: the same mask and scale applied to dout."""
    if cache is None:
        return dout
    mask, scale = cache
    return dout * mask * scale


# --------------------------------------------------------------------------------------------
# Mixture of experts (Sec. 4.1: Phi's weights are blended per sample by the gating output alpha)
# --------------------------------------------------------------------------------------------
def blend_experts(alpha: np.ndarray, W: np.ndarray, b: np.ndarray):
    """Blend K expert layers with one set of weights: ``sum_k alpha_k W_k``, ``sum_k alpha_k b_k``.

    alpha: (K,); W: (K, I, O); b: (K, O) -> W_blend (I, O), b_blend (O,). This is how the original
    runtime evaluates a single frame (original-pipeline §10.2 step 3).
    """
    K, I, O = W.shape
    _require(alpha.shape == (K,), f"blend_experts: alpha is {alpha.shape}, expected ({K},)")
    return (alpha @ W.reshape(K, I * O)).reshape(I, O), alpha @ b


def expert_linear_single(x: np.ndarray, alpha: np.ndarray, W: np.ndarray, b: np.ndarray) -> np.ndarray:
    """One sample, no cache (run-time inference, Sec. 4.4): ``sum_k alpha_k (x W_k + b_k)``.

    x: (I,); alpha: (K,); W: (K, I, O); b: (K, O) -> (O,). The fast form of
    :func:`expert_linear_forward` for a single sample: one matrix-vector product over the K*I
    numbers of outer(alpha, x). At batch 1 the cost is reading the K expert matrices (19.7 MB
    for the paper's Φ), so nothing else is allocated or copied.
    """
    K, I, O = W.shape
    return np.multiply.outer(alpha, x).reshape(K * I) @ W.reshape(K * I, O) + alpha @ b


def expert_linear_forward(x: np.ndarray, alpha: np.ndarray, W: np.ndarray, b: np.ndarray):
    """Per-sample blend of K expert linear layers: ``y_b = x_b (sum_k a_bk W_k) + sum_k a_bk b_k``.

    x: (B, I); alpha: (B, K); W: (K, I, O); b: (K, O) -> y: (B, O).

    Fast form (never builds the (B, I, O) per-sample weights): since
    ``y_b = sum_k sum_i a_bk x_bi W_kio``, put Z_b = outer(a_b, x_b) flattened to K*I numbers and
    ``y = Z @ W.reshape(K*I, O) + alpha @ b``: one matrix product. This holds at batch 1 too,
    where it reads every expert weight once; blending the weights first (the original's run-time
    path, :func:`blend_experts`) reads them once as well but also writes and re-reads the (I, O)
    blend, about 10% slower in this memory-bound case.
    """
    K, I, O = W.shape
    _require(x.ndim == 2 and x.shape[1] == I,
             f"expert_linear_forward: x is {x.shape}, expected (B, {I}) to match W {W.shape}")
    _require(alpha.shape == (x.shape[0], K),
             f"expert_linear_forward: alpha is {alpha.shape}, expected ({x.shape[0]}, {K})")
    _require(b.shape == (K, O), f"expert_linear_forward: b is {b.shape}, expected ({K}, {O})")
    Z = (alpha[:, :, None] * x[:, None, :]).reshape(-1, K * I)   # (B, K*I)
    y = Z @ W.reshape(K * I, O) + alpha @ b                      # (B, O)
    return y, (x, alpha, W, b, Z)


def expert_linear_backward(dout: np.ndarray, cache):
    """Gradients of :func:`expert_linear_forward`: dx (B, I), dalpha (B, K), dW (K, I, O), db (K, O).

    Three matrix products: dZ = dout W^T, dW = Z^T dout, db = alpha^T dout; then dZ (B, K, I) is
    contracted with alpha for dx and with x for dalpha (plus the bias path dout b^T).
    """
    x, alpha, W, b, Z = cache
    K, I, O = W.shape
    dZ = (dout @ W.reshape(K * I, O).T).reshape(-1, K, I)       # (B, K, I)
    dW = (Z.T @ dout).reshape(K, I, O)
    db = alpha.T @ dout                                          # (K, O)
    dx = np.matmul(alpha[:, None, :], dZ)[:, 0, :]               # (B, I) = sum_k a_bk dZ_bk
    dalpha = np.matmul(dZ, x[:, :, None])[:, :, 0] + dout @ b.T  # (B, K)
    return dx, dalpha, dW, db


# --------------------------------------------------------------------------------------------
# 1-D convolution over time and max pooling (the FiLM generator Psi, Eq. 2)
# --------------------------------------------------------------------------------------------
# Two exact ways to compute the same 'same' convolution. conv1d_forward picks the cheaper one
# (method="auto", see _conv1d_method) and records it in its cache, and conv1d_backward follows:
#
#   "im2col"  one matrix product on the im2col matrix (B*T, k*C): 2*B*T*k*C*F flops.
#   "fft"     in the frequency domain a convolution over time is one (B, C) @ (C, F) product per
#             frequency. With N >= T + k//2 frames of zero padding the DFT's circular convolution
#             equals the zero-padded one, so nothing is approximated: results differ from im2col's
#             by float rounding only (tests/test_optimised_equivalence.py). About
#             2*3*(N/2+1)*(B + k)*C*F flops: 5-8x fewer than im2col for Ψ at batch 32.
def _im2col(x: np.ndarray, k: int, work: dict | None = None, name: str = "cols") -> np.ndarray:
    """(B, T, C) -> cols (B*T, k*C): row (b, t) holds frames t - k//2 .. t + k//2, zero-padded.

    In the zero-padded, channels-last sample xp (T + k - 1, C), the window of frame t is the k*C
    CONSECUTIVE numbers starting at xp[t, 0]. So the windows are a strided view of the flat
    padded samples (sliding windows of length k*C taken every C numbers), and the one copy that
    makes cols contiguous for the matrix product is a row-by-row memcpy. Row layout is tap-major,
    (j, c), matching W (k, C, F). Both buffers come from ``work`` when given (see _scratch).
    """
    B, T, C = x.shape
    pad = k // 2
    # only the middle is written, so the zero padding of a reused buffer stays zero
    xp = _scratch(work, name + ".padded", (B, T + k - 1, C), x.dtype, zeros=True)
    xp[:, pad: pad + T] = x
    windows = sliding_window_view(xp.reshape(B, -1), k * C, axis=1)[:, ::C]   # (B, T, k*C) view
    cols = _scratch(work, name, (B * T, k * C), x.dtype)
    cols.reshape(B, T, k * C)[...] = windows                                  # the one copy
    return cols


def _fft_len(n: int) -> int:
    """The smallest N >= n whose only prime factors are 2, 3 and 5 (fast for the FFT)."""
    while True:
        r = n
        for f in (2, 3, 5):
            while r % f == 0:
                r //= f
        if r == 1:
            return n
        n += 1


@functools.lru_cache(maxsize=32)
def _fft_bases(N: int, k: int, dtype: np.dtype):
    """Real DFT matrices of the "fft" convolution for transform length N and kernel size k.

    Frequencies w = 0 .. N//2, p = k//2, theta(w, s) = 2 pi w s / N.
    Mk (3*nf, k): kernel spectrum planes [Re H, Im H, Re H + Im H] = Mk @ W, where
        H[w] = sum_j W[j] exp(-i theta(w, p - j))  (the DFT of the kernel flipped in time).
    Mlag (k, 3*nf): the k lags j - p of an inverse real DFT, applied to the three Gauss products
        (Q0, Q1, Q2) of a cross-spectrum R = (Q0 - Q1) + i (Q2 - Q0 - Q1):
        lag(s) = (1/N) sum_w c_w (Re R[w] cos theta(w, s) - Im R[w] sin theta(w, s)), c_w = 2
        except at w = 0 and w = N/2 (1).
    """
    p, nf = k // 2, N // 2 + 1
    w = np.arange(nf)[:, None]
    th = 2 * np.pi * w * (p - np.arange(k))[None, :] / N                   # (nf, k)
    Mk = np.concatenate([np.cos(th), -np.sin(th), np.cos(th) - np.sin(th)])
    c = np.full(nf, 2.0)
    c[0] = 1.0
    if N % 2 == 0:
        c[-1] = 1.0
    ph = 2 * np.pi * (np.arange(k) - p)[:, None] * np.arange(nf)[None, :] / N   # (k, nf)
    cos, sin = c * np.cos(ph) / N, c * np.sin(ph) / N
    Mlag = np.concatenate([cos + sin, sin - cos, -sin], axis=1)
    Mk, Mlag = Mk.astype(dtype), Mlag.astype(dtype)
    Mk.flags.writeable = Mlag.flags.writeable = False
    return Mk, Mlag


_FFT_SLAB = 1 << 22   # bytes of spectrum per rfft / irfft call: temporaries stay small and cached


def _rfft_planes(x: np.ndarray, N: int, planes: np.ndarray, sign: int) -> None:
    """planes (3, B, nf, C) <- [Re X, s Im X, Re X + s Im X] with X = rfft(x, n=N) over time and
    s = sign: the three operands of Gauss's three-product complex multiplication."""
    B, _, C = x.shape
    step = max(1, _FFT_SLAB // (planes.shape[2] * C * 2 * x.itemsize))
    for lo in range(0, B, step):
        X = scipy.fft.rfft(x[lo: lo + step], n=N, axis=1)                   # (b, nf, C)
        re, im = planes[0, lo: lo + step], planes[1, lo: lo + step]
        np.copyto(re, X.real)
        if sign > 0:
            np.copyto(im, X.imag)
        else:
            np.negative(X.imag, out=im)
        np.add(re, im, out=planes[2, lo: lo + step])


def _irfft_planes(P: np.ndarray, N: int, out: np.ndarray, sign: int, bias=None) -> None:
    """out (B, T, F) <- the first T frames of irfft(Z, n=N) (+ bias), where Z is put together from
    Gauss's three products P (3, B, nf, F): Re Z = P0 - P1, Im Z = sign (P2 - P0 - P1)."""
    _, B, nf, F = P.shape
    T = out.shape[1]
    step = max(1, _FFT_SLAB // (nf * F * 2 * P.itemsize))
    ctype = np.result_type(P.dtype, np.complex64)
    for lo in range(0, B, step):
        p0, p1, p2 = P[0, lo: lo + step], P[1, lo: lo + step], P[2, lo: lo + step]
        Z = np.empty(p0.shape, ctype)
        zr, zi = Z.real, Z.imag
        np.subtract(p0, p1, out=zr)
        np.subtract(p2, p0, out=zi)
        zi -= p1
        if sign < 0:
            np.negative(zi, out=zi)
        y = scipy.fft.irfft(Z, n=N, axis=1, overwrite_x=True)[:, :T]         # (b, T, F)
        if bias is None:
            np.copyto(out[lo: lo + step], y)
        else:
            np.add(y, bias, out=out[lo: lo + step])


def _conv1d_method(B: int, T: int, C: int, F: int, k: int) -> str:
    """"fft" where it is clearly cheaper than "im2col", else "im2col".

    A flop count of the forward pass and dW (dx, when needed, favours "fft" further) with the
    rates measured on a 2-core AMD EPYC (benchmarks/kernels.py): im2col's one big product runs
    ~1.8x faster per flop than fft's small per-frequency products and FFTs, and fft pays ~60 us of
    fixed cost (about 5 Mflop). So "fft" wins from batch ~8 for train_small's Ψ (k = 9) and
    from batch ~4 for the paper's (k = 25); at batch 1 im2col is 3-7x faster.
    """
    nf = _fft_len(T + k // 2) // 2 + 1
    direct = 4.0 * B * T * k * C * F
    spectral = 12.0 * nf * (k + B) * C * F
    return "fft" if 1.8 * spectral + 5e6 < direct else "im2col"


def conv1d_forward(x: np.ndarray, W: np.ndarray, b: np.ndarray, work: dict | None = None,
                   method: str = "auto"):
    """1-D convolution over time, stride 1, 'same' zero padding (cross-correlation, as in TF).

    ``y[b, t, f] = sum_j sum_c x[b, t + j - k//2, c] W[j, c, f] + b[f]`` with x zero outside [0, T).
    x: (B, T, C) channels-last; W: (k, C, F) with k odd; b: (F,) -> y: (B, T, F).
    ``method``: "im2col" (one matrix product on the im2col matrix, see :func:`_im2col`), "fft"
    (products per frequency, see the notes above and :func:`_conv1d_fft_forward`), or "auto"
    (the cheaper of the two for these sizes). The backward pass uses the same method.
    ``work``: the layer's workspace (see :func:`_scratch`); the big matrices (the im2col matrix
    is 230 MB for the paper's first layer at batch 32) are then reused from call to call.
    """
    k, C, F = W.shape
    _require(k % 2 == 1, f"conv1d_forward: kernel size must be odd for 'same' padding, W is {W.shape}")
    _require(x.ndim == 3 and x.shape[2] == C,
             f"conv1d_forward: x is {x.shape}, expected (B, T, {C}) to match W {W.shape}")
    _require(b.shape == (F,), f"conv1d_forward: b is {b.shape}, expected ({F},)")
    _require(method in ("auto", "im2col", "fft"),
             f"conv1d_forward: method must be 'auto', 'im2col' or 'fft', got {method!r}")
    B, T, _ = x.shape
    x = np.asarray(x, dtype=np.result_type(x, W))
    if method == "auto":
        method = _conv1d_method(B, T, C, F, k)
    if method == "fft":
        return _conv1d_fft_forward(x, W, b, work)
    cols = _im2col(x, k, work)                                   # (B*T, k*C)
    y = cols @ W.reshape(k * C, F)                               # (B*T, F)
    y += b                                                       # in place: no second buffer
    return y.reshape(B, T, F), ("im2col", cols, x.shape, W, work)


def _conv1d_fft_forward(x, W, b, work):
    """The "fft" method: with p = k//2, N = _fft_len(T + p) and X = rfft(x, n=N) over time,
    Y[w] = X[w] @ H[w] for each of the N//2 + 1 frequencies, H the DFT of the flipped kernel
    (see _fft_bases), and y = the first T frames of irfft(Y). Each complex product is three real
    ones (Gauss): P_i = X3_i @ H3_i with X3 = [Xr, Xi, Xr + Xi], H3 = [Hr, Hi, Hr + Hi], then
    Re Y = P0 - P1 and Im Y = P2 - P0 - P1. The kernel has only k taps, so its spectrum is one
    matrix product (3*nf, k) @ (k, C*F) instead of an FFT of the zero-padded kernel."""
    B, T, C = x.shape
    k, _, F = W.shape
    N = _fft_len(T + k // 2)
    nf = N // 2 + 1
    Mk, _ = _fft_bases(N, k, x.dtype)
    X3 = _scratch(work, "fft.X3", (3, B, nf, C), x.dtype)
    _rfft_planes(x, N, X3, +1)
    H3 = _scratch(work, "fft.H3", (3, nf, C, F), x.dtype)
    np.matmul(Mk, W.reshape(k, C * F), out=H3.reshape(3 * nf, C * F))
    P = _scratch(work, "fft.P", (3, B, nf, F), x.dtype)
    np.matmul(X3.transpose(0, 2, 1, 3), H3, out=P.transpose(0, 2, 1, 3))     # per frequency
    y = np.empty((B, T, F), x.dtype)
    _irfft_planes(P, N, y, +1, bias=b)
    return y, ("fft", X3, H3, x.shape, W, work)


def conv1d_backward(dout: np.ndarray, cache, need_dx: bool = True):
    """Gradients of :func:`conv1d_forward`: dx (B, T, C), dW (k, C, F), db (F,).

    "im2col": dW = cols^T dout (one matrix product on the forward's im2col matrix). dx is itself
    a 'same' convolution, of dout with the kernel flipped in time and transposed to (k, F, C):
    dx[t] = sum_j dout[t - j + k//2] W[j]^T, again one product on an im2col matrix.
    "fft": see :func:`_conv1d_fft_backward`. db = sum(dout) either way.
    With ``need_dx=False`` dx is skipped (None is returned in its place): a network's first
    layer never needs the gradient of its input data, and for the paper's Ψ that product costs as
    much as the layer's whole forward pass. With a workspace (given to the forward pass) dW and
    the other big buffers live in it: add dW to your gradients before the layer's next call.
    """
    method, work = cache[0], cache[-1]
    if method == "fft":
        dx, dW = _conv1d_fft_backward(dout, cache, need_dx)
        return dx, dW, dout.sum(axis=(0, 1))
    _, cols, (B, T, C), W, _ = cache
    k, _, F = W.shape
    d2 = dout.reshape(B * T, F)
    dW = np.matmul(cols.T, d2, out=_scratch(work, "dW", (k * C, F), np.result_type(cols, d2)))
    db = d2.sum(axis=0)
    dx = None
    if need_dx:
        W_flip = W[::-1].transpose(0, 2, 1).reshape(k * F, C)    # (k*F, C)
        dx = (_im2col(dout, k, work, "dout_cols") @ W_flip).reshape(B, T, C)
    return dx, dW.reshape(k, C, F), db


def _conv1d_fft_backward(dout, cache, need_dx):
    """dx and dW of the "fft" method, with D = rfft(dout, n=N) and D3 = [Dr, -Di, Dr - Di].

    dW[j] = sum_{b,t} x[b, t + j - p]^T dout[b, t] is lag j - p of the cross-correlation of x and
    dout, whose DFT is R[w] = sum_b X[w]^T conj(D[w]) (C, F): Gauss's products Q = X3^T @ D3 per
    frequency, then the k lags in one matrix product (k, 3*nf) @ (3*nf, C*F) (Mlag, _fft_bases).
    dx[t] = sum_j dout[t - j + p] W[j]^T, a correlation with the kernel: DX[w] = D[w] H[w]^H
    = conj(conj(D[w]) H[w]^T), i.e. S = D3 @ H3^T, Re DX = S0 - S1, Im DX = -(S2 - S0 - S1).
    """
    _, X3, H3, (B, T, C), W, work = cache
    k, _, F = W.shape
    nf = X3.shape[2]
    N = _fft_len(T + k // 2)
    _, Mlag = _fft_bases(N, k, X3.dtype)
    dout = np.asarray(dout, dtype=X3.dtype)
    D3 = _scratch(work, "fft.D3", (3, B, nf, F), X3.dtype)
    _rfft_planes(dout, N, D3, -1)
    Q = _scratch(work, "fft.Q", (3, nf, C, F), X3.dtype)
    np.matmul(X3.transpose(0, 2, 3, 1), D3.transpose(0, 2, 1, 3), out=Q)    # (3, nf, C, F)
    dW = _scratch(work, "dW", (k * C, F), X3.dtype)
    np.matmul(Mlag, Q.reshape(3 * nf, C * F), out=dW.reshape(k, C * F))
    dx = None
    if need_dx:
        S = _scratch(work, "fft.S", (3, B, nf, C), X3.dtype)
        np.matmul(D3.transpose(0, 2, 1, 3), H3.transpose(0, 1, 3, 2), out=S.transpose(0, 2, 1, 3))
        dx = np.empty((B, T, C), X3.dtype)
        _irfft_planes(S, N, dx, -1)
    return dx, dW.reshape(k, C, F)


def max_pool1d_forward(x: np.ndarray):
    """Max pooling over time with size 2 and stride 2: (B, T, C) -> (B, T // 2, C).

    With odd T the last frame has no partner and is dropped (as with TF's 'valid' padding).
    Ties pick the first frame of the pair. The pairs are the even and odd frames (two strided
    views), so the forward pass is one ``np.maximum`` and the cache one boolean array.
    """
    _require(x.ndim == 3 and x.shape[1] >= 2,
             f"max_pool1d_forward: x is {x.shape}, expected (B, T, C) with T >= 2")
    T2 = x.shape[1] // 2
    even, odd = x[:, 0: 2 * T2: 2], x[:, 1: 2 * T2: 2]          # (B, T2, C) views
    first = even >= odd                                          # where the first frame wins
    return np.maximum(even, odd), (x.shape, first)


def max_pool1d_backward(dout: np.ndarray, cache):
    """dx for :func:`max_pool1d_forward`: each gradient goes to the frame that won its pair."""
    (B, T, C), first = cache
    T2 = T // 2
    dx = np.empty((B, T, C), dtype=dout.dtype)
    dx[:, 2 * T2:] = 0                                           # the dropped odd frame, if any
    # Multiplying by the boolean masks is ~10x faster than np.copyto(..., where=) or np.where
    # here; the only difference is that a non-finite dout (a diverged run) also reaches the losing
    # frame, as inf * 0 = nan, where those would give 0.
    np.multiply(dout, first, out=dx[:, 0: 2 * T2: 2])
    np.multiply(dout, ~first, out=dx[:, 1: 2 * T2: 2])
    return dx
