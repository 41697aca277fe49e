"""The sinusoid fit behind the local phases, vectorised: what labelling runs (Sec. 4.1.4).

The same fit as minifilm/phases/sinusoid_fit_plain.py::fit_sinusoids_plain, which a reader
should meet first: it writes the method out frame by frame and says where and why it departs from
the original (docs/original-code.md §4.1-§4.4). The two agree to rounding
(tests/phases/test_sinusoid_fit_plain.py). Here every frame is fitted at once:

* frames are processed in blocks; the windows of a block are rows of (frames x samples) arrays;
* the normal matrices of all interior windows are the same for a given frequency, so they are
  computed once (and kept for the next sweep, with the edge blocks' own when they are small);
  the right-hand sides of a whole block for the whole grid are one matrix product;
* each 3x3 system is solved in closed form (adjugate inverse), elementwise over the batch;
* infeasible grid candidates that cannot beat a feasible one are never projected (the plain fit
  prunes the same way, so both see the same losses);
* the bounds come from a sparse-table range minimum / maximum (:func:`range_reduce`).

Speed figures: benchmarks/phases.py and benchmarks/README.md ("Labelling and features"); how
they were reached: reports/2026-12-02_naive_beside_fast.md.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from minifilm.phases.sinusoid_fit_plain import SinusoidFit, window_half_width

__all__ = ["SinusoidFit", "fit_sinusoids", "overflow_window", "phase_slope_frequency", "range_reduce",
           "window_half_width"]


def overflow_window(k: np.ndarray, half: np.ndarray, n: int):
    """First and last frame of windows ``[k-half, k+half]`` shifted (not cut) to stay inside [0, n-1].

    The original's ``GatherByOverflowWindow``: a window that runs off one end is moved inwards so it
    keeps ``2*half+1`` frames (fewer only when the signal is shorter). Returns (lo, hi) inclusive.
    """
    k = np.asarray(k)
    half = np.asarray(half)
    lo = np.maximum(k - half, 0)
    hi = np.minimum(k + half, n - 1)
    lo2 = np.maximum(lo - ((k + half) - hi), 0)
    hi2 = np.minimum(hi + (lo - (k - half)), n - 1)
    return lo2, hi2


def _basis(offsets: np.ndarray, freqs: np.ndarray, fps: float):
    """sin and cos of 2πFτ; offsets in frames (..., E, 1) or (..., E), freqs broadcastable."""
    angle = (2 * np.pi / fps) * offsets * freqs
    return np.sin(angle), np.cos(angle)


def _solve_bounded(g, r, yy, vmin, vmax):
    """Weighted least squares for (c1, c2, B) with the §4.2 bounds, elementwise over any batch shape.

    g = (gss, gsc, gsb, gcc, gcb, gbb): the symmetric normal matrix Σw b bᵀ for b = (sin, cos, 1);
    r = (rs, rc, rb) = Σ w y b; yy = Σ w y². All broadcast to one batch shape, whose last axis
    holds the candidate frequencies of one window. Returns c1, c2, B and the weighted squared error
    (for candidates that cannot be the best, see the pruning below, a lower bound of it).
    """
    a, b, c, d, e, f = g
    rs, rc, rb = r
    ridge = 1e-10 * (a + d + f) + 1e-300  # keeps degenerate windows (e.g. 1-2 frames) finite
    a, d, f = a + ridge, d + ridge, f + ridge
    # Inverse of the symmetric 3x3 matrix by its adjugate (cheap when shared by many windows).
    A11, A12, A13 = d * f - e * e, c * e - b * f, b * e - c * d
    A22, A23, A33 = a * f - c * c, b * c - a * e, a * d - b * b
    det = a * A11 + b * A12 + c * A13
    A11, A12, A13, A22, A23 = A11 / det, A12 / det, A13 / det, A22 / det, A23 / det
    A33 = A33 / det
    c1 = A11 * rs + A12 * rc + A13 * rb
    c2 = A12 * rs + A22 * rc + A23 * rb
    B = A13 * rs + A23 * rc + A33 * rb
    sse = yy - (c1 * rs + c2 * rc + B * rb)  # at the unconstrained optimum cᵀGc = cᵀr
    amax = vmax - vmin
    active = (B < vmin) | (B > vmax) | (c1 * c1 + c2 * c2 > amax * amax)
    # Pruning along the last axis (the frequency grid): a bound can only raise the error, so an
    # infeasible candidate whose unconstrained error already exceeds the best feasible one cannot
    # win; it keeps its unconstrained values (a lower bound on its error).
    best_feasible = np.min(np.where(active, np.inf, sse), axis=-1, keepdims=True)
    active &= sse < best_feasible
    if not np.any(active):
        return c1, c2, B, sse
    shape = sse.shape
    idx = np.nonzero(active)
    pick = lambda x: np.broadcast_to(x, shape)[idx]
    a, b, c, d, e, f, rs, rc, rb, yy, lo, hi = map(pick, (a, b, c, d, e, f, rs, rc, rb, yy, vmin, vmax))
    Bc = np.clip(pick(B), lo, hi)
    x1, x2 = pick(c1), pick(c2)
    # Offset bound: with B clipped, the best (c1, c2) for that fixed B (a 2x2 system).
    moved = Bc != pick(B)
    s, t = rs - c * Bc, rc - e * Bc
    det2 = a * d - b * b
    x1 = np.where(moved, (d * s - b * t) / det2, x1)
    x2 = np.where(moved, (a * t - b * s) / det2, x2)
    # Amplitude bound: project (c1, c2) back onto the disc of radius vmax - vmin.
    amp = np.hypot(x1, x2)
    scale = np.where(amp > hi - lo, (hi - lo) / np.maximum(amp, 1e-300), 1.0)
    x1, x2 = x1 * scale, x2 * scale
    quad = a * x1 * x1 + d * x2 * x2 + f * Bc * Bc + 2 * (b * x1 * x2 + c * x1 * Bc + e * x2 * Bc)
    c1, c2, B, sse = (np.array(np.broadcast_to(x, shape)) for x in (c1, c2, B, sse))
    c1[idx], c2[idx], B[idx] = x1, x2, Bc
    sse[idx] = yy - 2 * (x1 * rs + x2 * rc + Bc * rb) + quad
    return c1, c2, B, sse


def _design(offsets, weights, freqs, fps):
    """Basis and normal matrix of windows at frequencies ``freqs``.

    offsets (n' or 1, E) frames relative to the fitted frame, weights like offsets, freqs (G,) for a
    grid shared by all windows, or (n', 1) one frequency per window.
    Returns s, c (n'|1, E, G') and g (6 arrays of shape (n'|1, G')): the normal matrix entries.
    """
    s, c = _basis(offsets[..., None], freqs if freqs.ndim == 1 else freqs[:, None, :], fps)
    w = weights[..., None]
    ws, wc = w * s, w * c
    g = (np.sum(ws * s, axis=-2), np.sum(ws * c, axis=-2), np.sum(ws, axis=-2),
         np.sum(wc * c, axis=-2), np.sum(wc, axis=-2), np.sum(w, axis=-2) + 0 * s[..., 0, :])
    return s, c, g


def _rhs(s, c, weights, targets):
    """Right-hand sides r = Σ w y (sin, cos, 1) and Σ w y² for targets (n, E); batch (n, G')."""
    wy = weights * targets  # (n, E)
    if s.shape[0] == 1 and targets.shape[0] != 1:
        rs, rc = wy @ s[0], wy @ c[0]                       # BLAS: (n, E) @ (E, G)
    else:
        rs, rc = (wy[:, None, :] @ s)[:, 0], (wy[:, None, :] @ c)[:, 0]  # batched (1, E) @ (E, G')
    rb = np.sum(wy, axis=-1)[:, None]
    yy = np.sum(wy * targets, axis=-1)[:, None]
    return (rs, rc, rb), yy


@dataclass
class _Windows:
    """Extended windows (data window plus P connect frames each side) for a block of frames."""

    frames: np.ndarray   # (n,) frame indices k
    index: np.ndarray    # (n, E) clipped frame index j of each slot
    offsets: np.ndarray  # (n' , E) j - k (n' = 1 when shared by all frames of the block)
    w_data: np.ndarray   # (n', E) 1 on the data window, 0 elsewhere
    w_conn: np.ndarray   # (n', E) (1 - i/P)^2 on connect slots inside the signal, 0 elsewhere


def _windows(frames: np.ndarray, n: int, half: int, shared: bool) -> _Windows:
    length = min(2 * half + 1, n)
    lo, _ = overflow_window(frames, np.full_like(frames, half), n)
    lo = np.minimum(lo, n - length)
    slot = np.arange(length + 2 * half)                       # (E,)
    j = lo[:, None] - half + slot                             # (n, E) unclipped
    inside = (j >= 0) & (j < n)
    is_data = (slot >= half) & (slot < half + length)
    i = np.where(slot < half, half - slot, slot - (half + length) + 1)  # connect distance 1..P
    w_conn_slot = np.where(is_data, 0.0, (1.0 - i / half) ** 2)
    w_data = np.broadcast_to(is_data.astype(float), j.shape) * inside
    w_conn = w_conn_slot * inside
    offsets = (j - frames[:, None]).astype(float)
    if shared:
        offsets, w_data, w_conn = offsets[:1], w_data[:1], w_conn[:1]
    return _Windows(frames, np.clip(j, 0, n - 1), offsets, np.asarray(w_data), np.asarray(w_conn))


def _fit_block(win: _Windows, values, prev_fit, freqs, fps, vmin, vmax, use_connect, cache, name):
    """Best (c1, c2, B, F) for one block of frames: grid search, parabolic refinement, re-solve.

    ``cache`` keeps the grid's basis and normal matrices between blocks and sweeps, under
    (``name``, use_connect): ``name`` is "interior" for the windows every interior block shares,
    and the block's own number for an edge block.
    """
    weights = win.w_data + (win.w_conn if use_connect else 0.0)
    targets = np.where(win.w_data > 0, values[win.index], prev_fit[win.index] if use_connect else 0.0)
    shared = win.offsets.shape[0] == 1
    key = (name, use_connect)
    design = cache.get(key)
    if design is None:
        design = _design(win.offsets, weights, freqs, fps)
        # kept for the next sweep, unless it is large (edge windows at high frame rates, where
        # keeping every block's would cost gigabytes: those are recomputed instead)
        if shared or win.offsets.size * len(freqs) <= BLOCK_NUMBERS // 8:
            cache[key] = design
    s, c, g = design
    r, yy = _rhs(s, c, weights, targets)
    lo_b, hi_b = vmin[:, None], vmax[:, None]
    c1, c2, B, sse = _solve_bounded(g, r, yy, lo_b, hi_b)
    n, G = sse.shape
    rows = np.arange(n)
    best = np.argmin(sse, axis=1)
    # Parabolic interpolation of the loss in log F around the best grid point.
    logf = np.log(freqs)
    step = logf[1] - logf[0] if G > 1 else 0.0
    inner = (best > 0) & (best < G - 1)
    bm, bp = np.clip(best - 1, 0, G - 1), np.clip(best + 1, 0, G - 1)
    l0, l1, l2 = sse[rows, bm], sse[rows, best], sse[rows, bp]
    curv = l0 - 2 * l1 + l2
    delta = np.where(inner & (curv > 0), 0.5 * (l0 - l2) / np.where(curv > 0, curv, 1.0), 0.0)
    f_ref = np.exp(logf[best] + np.clip(delta, -1, 1) * step)[:, None]  # (n, 1)
    offsets = np.broadcast_to(win.offsets, targets.shape)
    wts = np.broadcast_to(weights, targets.shape)
    s2, c2_, g2 = _design(offsets, wts, f_ref, fps)
    r2, yy2 = _rhs(s2, c2_, wts, targets)
    d1, d2, dB, sse2 = (x[:, 0] for x in _solve_bounded(g2, r2, yy2, lo_b, hi_b))
    better = sse2 < l1
    pick = lambda refined, grid: np.where(better, refined, grid[rows, best])
    return pick(d1, c1), pick(d2, c2), pick(dB, B), np.where(better, f_ref[:, 0], freqs[best])


def range_reduce(x: np.ndarray, lo: np.ndarray, hi: np.ndarray, op) -> np.ndarray:
    """``op.reduce(x[lo[k]:hi[k]+1])`` for every k at once (sparse table, O(F log F)).

    op is np.minimum or np.maximum; lo <= hi are inclusive frame indices.
    """
    levels = [x]
    while (1 << len(levels)) <= x.size:
        prev, h = levels[-1], 1 << (len(levels) - 1)
        levels.append(op(prev[:-h], prev[h:]))
    span = hi - lo + 1
    lev = np.floor(np.log2(span)).astype(int)
    out = np.empty(lo.shape)
    for l in np.unique(lev):
        sel = lev == l
        out[sel] = op(levels[l][lo[sel]], levels[l][hi[sel] - (1 << l) + 1])
    return out


#: Numbers in one block's largest arrays (about 64 MB of float64 each).
BLOCK_NUMBERS = 8_000_000


def fit_sinusoids(signal, fps: float, window_seconds: float = 0.5, min_frequency: float = 0.25,
                  max_frequency: float = 4.0, n_frequencies: int = 48, sweeps: int = 3,
                  skip_threshold: float = 1e-3, block: int = 2048,
                  phase_slope_seconds: float = 1.0) -> SinusoidFit:
    """Fit ``A sin(2π(F t − S)) + B`` around every frame of ``signal`` (deterministic, vectorised).

    Args:
        signal:  (F,) preprocessed source function (docs/original-code.md §3.7).
        fps:     frames per second of the signal.
        window_seconds: data window, 2P+1 frames with P = round(window_seconds*fps/2) (31 at 60 fps).
        min_frequency, max_frequency: bounds on F in Hz (§4.2: 1/MaxFrequency and MaxFrequency).
        n_frequencies: size of the log-spaced frequency grid.
        sweeps:  Jacobi sweeps; the first fits the data alone, the others add the connect terms.
        skip_threshold: frames whose data window has Σ|v| below this keep all parameters 0.
        block:   frames processed at once, at most; fewer at high frame rates (``BLOCK_NUMBERS``).
        phase_slope_seconds: span of the phase track whose slope is the reported frequency (see
            the module docstring); 0 reports each window's own F.
    Returns:
        SinusoidFit with (F,) arrays.
    """
    v = np.asarray(signal, dtype=np.float64)
    if v.ndim != 1 or v.size == 0:
        raise ValueError(f"fit_sinusoids: signal must be a non-empty 1-D array, got shape {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError("fit_sinusoids: signal contains NaN or inf")
    if not (fps > 0 and 0 < min_frequency < max_frequency):
        raise ValueError(f"fit_sinusoids: need fps > 0 and 0 < min_frequency < max_frequency, "
                         f"got fps={fps}, frequencies=({min_frequency}, {max_frequency})")
    n = v.size
    half = window_half_width(window_seconds, fps)
    length = min(2 * half + 1, n)
    freqs = np.geomspace(min_frequency, max_frequency, n_frequencies)

    # Data-window statistics for the bounds and the skip rule.
    k = np.arange(n)
    lo, _ = overflow_window(k, np.full(n, half), n)
    lo = np.minimum(lo, n - length)
    data = np.lib.stride_tricks.sliding_window_view(v, length)[lo]  # (F, L) view rows
    skipped = np.abs(data).sum(axis=1) < skip_threshold
    # Bounds from every sample the loss looks at (data window plus connect frames), see docstring.
    ext_lo, ext_hi = np.maximum(lo - half, 0), np.minimum(lo + length - 1 + half, n - 1)
    vmin, vmax = range_reduce(v, ext_lo, ext_hi, np.minimum), range_reduce(v, ext_lo, ext_hi, np.maximum)

    # Frames whose extended window lies fully inside the signal share offsets and weights.
    interior = (k >= 2 * half) & (k <= n - 1 - 2 * half) & (length == 2 * half + 1)
    # A block's arrays hold (frames x samples x frequencies) numbers and the samples grow with the
    # frame rate: fewer frames per block at high rates keep memory flat (2048 at 60 fps, ~160 at 1000).
    block = max(1, min(int(block), BLOCK_NUMBERS // ((4 * half + 1) * n_frequencies)))
    edge, idx = k[~interior], k[interior]
    blocks = [_windows(edge[i:i + block], n, half, shared=False) for i in range(0, edge.size, block)]
    blocks += [_windows(idx[i:i + block], n, half, shared=True) for i in range(0, idx.size, block)]

    c1, c2, B, F = (np.zeros(n) for _ in range(4))
    fit = np.zeros(n)
    cache = {}
    names = [i if win.offsets.shape[0] > 1 else "interior" for i, win in enumerate(blocks)]
    for sweep in range(max(1, sweeps)):
        for win, name in zip(blocks, names):
            fr = win.frames
            out = _fit_block(win, v, fit, freqs, fps, vmin[fr], vmax[fr], sweep > 0, cache, name)
            c1[fr], c2[fr], B[fr], F[fr] = out
        c1[skipped] = c2[skipped] = B[skipped] = F[skipped] = 0.0
        fit = c2 + B  # f_k(τ = 0): sin 0 = 0, cos 0 = 1

    amplitude = np.hypot(c1, c2)
    phase = np.mod(np.arctan2(c2, c1) / (2 * np.pi), 1.0)
    phase[(amplitude == 0) | (phase >= 1.0)] = 0.0
    # PAPER: the frequency is the fit's own (Sec. 4.1.4, and the original's); here the slope of the
    # phase track, as in sinusoid_fit_plain.py, which says why. Of the labels, only the amplitude's
    # window reads it.
    F = phase_slope_frequency(phase, F, ~skipped & (amplitude > 0), fps, phase_slope_seconds,
                              min_frequency, max_frequency)
    return SinusoidFit(amplitude, F, phase, B, fit, skipped)


def phase_slope_frequency(phase, window_frequency, valid, fps: float, seconds: float,
                          min_frequency: float, max_frequency: float) -> np.ndarray:
    """(F,) frequency in Hz = slope of the unwrapped phase (cycles) over ``seconds`` around each
    frame, by least squares, where all of those frames are ``valid`` and inside the signal; the
    per-window frequency ``window_frequency`` elsewhere. Clipped to the frequency bounds."""
    n = phase.size
    half = int(round(seconds * fps / 2))
    out = np.asarray(window_frequency, dtype=np.float64).copy()
    width = 2 * half + 1
    if half < 1 or n < width:
        return out
    cycles = np.unwrap(2 * np.pi * phase) / (2 * np.pi)
    t = np.arange(n) / fps
    ok = np.lib.stride_tricks.sliding_window_view(valid, width).all(axis=1)     # (n - 2 half,)
    tw = np.lib.stride_tricks.sliding_window_view(t, width)
    cw = np.lib.stride_tricks.sliding_window_view(cycles, width)
    tc = tw - tw.mean(axis=1, keepdims=True)
    slope = (tc * cw).sum(axis=1) / (tc * tc).sum(axis=1)
    centre = np.arange(half, n - half)
    out[centre[ok]] = np.clip(slope[ok], min_frequency, max_frequency)
    return out
