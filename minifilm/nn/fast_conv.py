"""The convolution of minifilm/nn/conv.py, fast: what training runs (Ψ's conv blocks).

The same 'same'-padded convolution as :func:`minifilm.nn.conv.conv1d_forward`, computed one of two
exact ways, picked per call by a flop model (:func:`_conv1d_method`):

* "im2col": as in conv.py, but the window matrix is one copy of a strided view, and the big
  buffers come from a per-layer workspace (minifilm/nn/workspaces.py::scratch);
* "fft": with N >= T + k//2 frames of zero padding the DFT's circular convolution equals the
  zero-padded one, so each frequency becomes one (B, C) @ (C, F) product. Nothing is
  approximated: the results differ from im2col's by float rounding only.

tests/nn/test_fast_conv.py keeps both equal to the plain pair; the measurements behind the
choices (flop rates, slab size, what else was tried) are in
reports/2026-12-01_fft_convolution_and_adam.md and reports/2026-12-02_naive_beside_fast.md.
"""
from __future__ import annotations

import functools

import numpy as np
import scipy.fft
from numpy.lib.stride_tricks import sliding_window_view

from minifilm.nn.checks import check_conv1d_inputs, require, require_grad_shape
from minifilm.nn.workspaces import scratch


def _im2col(x: np.ndarray, k: int, work: dict | None = None, name: str = "cols") -> np.ndarray:
    """conv.py::im2col with both buffers from ``work``: (B, T, C) -> cols (B*T, k*C).

    In the zero-padded, channels-last sample xp (T + k - 1, C), the window of frame t is the k*C
    CONSECUTIVE numbers starting at xp[t, 0], so the windows are a strided view of the flat padded
    samples (length k*C, every C numbers) and making cols contiguous is one row-by-row copy.
    """
    B, T, C = x.shape
    pad = k // 2
    # only the middle is written, so the zero padding of a reused buffer stays zero
    xp = scratch(work, name + ".padded", (B, T + k - 1, C), x.dtype, zeros=True)
    xp[:, pad: pad + T] = x
    windows = sliding_window_view(xp.reshape(B, -1), k * C, axis=1)[:, ::C]   # (B, T, k*C) view
    cols = scratch(work, name, (B * T, k * C), x.dtype)
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


_FFT_SLAB = 1 << 22   # bytes of spectrum per rfft / irfft call, so no temporary is large


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
    """"fft" where a flop count says it is clearly cheaper than "im2col", else "im2col".

    Forward plus dW: im2col does 4 B T k C F flops, fft about 12 nf (k + B) C F. The factor 1.8
    (im2col's one big product runs faster per flop) and the fixed 5e6 (fft's overhead) are rates
    measured with benchmarks/kernels.py (reports/2026-12-01_fft_convolution_and_adam.md). So fft
    for a batch of long clips (train_small's Ψ from batch ~8, the paper's from ~4), im2col for
    single clips.
    """
    nf = _fft_len(T + k // 2) // 2 + 1
    direct = 4.0 * B * T * k * C * F
    spectral = 12.0 * nf * (k + B) * C * F
    return "fft" if 1.8 * spectral + 5e6 < direct else "im2col"


def conv1d_fast_forward(x: np.ndarray, W: np.ndarray, b: np.ndarray, work: dict | None = None,
                        method: str = "auto"):
    """:func:`minifilm.nn.conv.conv1d_forward`, fast. x (B, T, C), W (k, C, F) k odd, b (F,) -> y (B, T, F).

    ``method``: "im2col", "fft" or "auto" (:func:`_conv1d_method` picks); the backward pass uses
    the same one. ``work``: the layer's workspace (see :func:`~minifilm.nn.workspaces.scratch`).
    """
    k, C, F = W.shape
    check_conv1d_inputs(x, W, b)
    require(method in ("auto", "im2col", "fft"),
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
    X3 = scratch(work, "fft.X3", (3, B, nf, C), x.dtype)
    _rfft_planes(x, N, X3, +1)
    H3 = scratch(work, "fft.H3", (3, nf, C, F), x.dtype)
    np.matmul(Mk, W.reshape(k, C * F), out=H3.reshape(3 * nf, C * F))
    P = scratch(work, "fft.P", (3, B, nf, F), x.dtype)
    np.matmul(X3.transpose(0, 2, 1, 3), H3, out=P.transpose(0, 2, 1, 3))     # per frequency
    y = np.empty((B, T, F), x.dtype)
    _irfft_planes(P, N, y, +1, bias=b)
    return y, ("fft", X3, H3, x.shape, W, work)


def conv1d_fast_backward(dout: np.ndarray, cache, need_dx: bool = True):
    """Gradients of :func:`conv1d_fast_forward`: dx (B, T, C) (None with ``need_dx=False``),
    dW (k, C, F), db (F,), by the forward's method ("im2col": as conv.py::conv1d_backward; "fft":
    :func:`_conv1d_fft_backward`). With a workspace, dW and the other big buffers live in it: add
    dW to your gradients before the layer's next call.
    """
    method, work = cache[0], cache[-1]
    (B, T, _), F = cache[-3], cache[-2].shape[2]
    require_grad_shape("conv1d_backward", dout, (B, T, F))
    if method == "fft":
        dx, dW = _conv1d_fft_backward(dout, cache, need_dx)
        return dx, dW, dout.sum(axis=(0, 1))
    _, cols, (B, T, C), W, _ = cache
    k, _, F = W.shape
    d2 = dout.reshape(B * T, F)
    dW = np.matmul(cols.T, d2, out=scratch(work, "dW", (k * C, F), np.result_type(cols, d2)))
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
    D3 = scratch(work, "fft.D3", (3, B, nf, F), X3.dtype)
    _rfft_planes(dout, N, D3, -1)
    Q = scratch(work, "fft.Q", (3, nf, C, F), X3.dtype)
    np.matmul(X3.transpose(0, 2, 3, 1), D3.transpose(0, 2, 1, 3), out=Q)    # (3, nf, C, F)
    dW = scratch(work, "dW", (k * C, F), X3.dtype)
    np.matmul(Mlag, Q.reshape(3 * nf, C * F), out=dW.reshape(k, C * F))
    dx = None
    if need_dx:
        S = scratch(work, "fft.S", (3, B, nf, C), X3.dtype)
        np.matmul(D3.transpose(0, 2, 1, 3), H3.transpose(0, 1, 3, 2), out=S.transpose(0, 2, 1, 3))
        dx = np.empty((B, T, C), X3.dtype)
        _irfft_planes(S, N, dx, -1)
    return dx, dW.reshape(k, C, F)
