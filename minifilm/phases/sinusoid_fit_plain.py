"""The sinusoid fit behind the local phases, one frame at a time (Sec. 4.1.4; docs/original-code.md §4.1-§4.4).

For every frame ``k`` of a preprocessed source signal ``v`` (F,) we fit

    f_k(t) = A sin(2π(F t − S)) + B

to the samples of a window around ``k`` and read the phase of frame ``k`` off the fitted curve;
Eq. (1) then turns phase and amplitude into the phase vector (minifilm/phases/local_phases.py).
This is the fit written plainly, frame by frame and frequency by frequency. The package runs the
same fit vectorised over all frames (minifilm/phases/sinusoid_fit.py::fit_sinusoids), tested
equal to this one in tests/phases/test_sinusoid_fit_plain.py.

The window, bounds, skip rule and neighbour-agreement ("connect") terms are the original's; the
optimiser is not. Where and why this departs from the original (the one place it is documented):

* **Local time.** Window ``k`` is written in ``τ = t − t_k``, i.e. ``f_k = A sin(2π(F τ − S')) + B``
  with ``S' = S − F t_k`` (the same curve). The phase of frame ``k`` is then ``(−S') mod 1``.
* **Linear for a fixed F** (the heart of it). ``A sin(2π(Fτ − S')) + B = c1 sin(2πFτ) + c2 cos(2πFτ) + B``
  with ``c1 = A cos 2πφ``, ``c2 = A sin 2πφ`` and ``φ = (−S') mod 1``. For a fixed frequency the
  weighted least-squares problem in (c1, c2, B) is a 3x3 linear system (:func:`normal_equations`).
  The original instead runs, per frame, a clock-seeded genetic algorithm (50 individuals, 10
  generations) whose results cannot be reproduced; we minimise the *same* loss deterministically.
* **Grid + refinement over F.** ``n_frequencies`` log-spaced frequencies in [0.25, 4] Hz; the best
  grid frequency is refined by a parabola through the loss at it and its two neighbours (in log F),
  re-solved there, and kept only if it lowers the loss (:func:`fit_window`).
* **Bounds (§4.2)**, with vmin/vmax taken over every sample the loss looks at (the data window
  plus the P connect frames each side, 1 s at 60 fps) instead of the 0.5 s data window alone. With
  the original's narrower range a noise-free 0.5 Hz sinusoid is not representable near its peaks
  (the window then holds a quarter cycle whose range is a fraction of A, and B lies below it),
  which biased F by 10-40 % in our tests. ``A >= 0`` holds by construction (A = |(c1, c2)|). If the
  optimal ``B`` leaves ``[vmin, vmax]`` it is clipped and (c1, c2) re-solved with B fixed; if ``A``
  then exceeds ``vmax − vmin`` it is scaled down to the bound (a projection, not the exact
  constrained optimum; the frequency search then prefers frequencies whose unconstrained fit is
  feasible). The original's bound on S is not needed: S' is only defined modulo 1.
* **Connect terms (§4.3), Jacobi style.** Sweep 0 fits the data alone (the original starts from
  ``Fit = 0``, which pulls every first-generation fit towards zero); each further sweep adds the
  weighted agreement with the neighbours' fitted values ``Fit[j] = f_j(t_j)`` from the previous
  sweep, as the original does between its 10 generations. 3 sweeps by default: more change the
  phases by far less than their noise.
* **Time in seconds.** The window is 0.5 s (2P+1 frames, P = round(0.25 fps)), so 30 and 120 fps
  data are fitted over the same duration as the original's 60 fps.
* **Frequency from the phase track.** A 0.5 s window pins the phase down (< 0.01 cycle median
  error at 5 % noise from 0.5 to 3 Hz) but not the frequency below 1 Hz, where it holds less than
  half a cycle (the Cramér-Rao bound of one 31-sample window is a relative std of 48 % at 0.5 Hz).
  So the reported frequency of frame k is the slope of the unwrapped fitted phase over the 1 s
  around k (a least-squares line through ``phase_slope_seconds`` of phases), where every frame of
  that second was fitted; elsewhere (ends, skipped stretches) the window's own F is kept. The
  phases and the fit are unchanged. The frequency sets the amplitude's speed window (§4.5).

Everything else follows the original: a window of ``2P+1`` frames (31 at 60 fps, 0.5 s) shifted, not
truncated, near the ends; connect terms ``i = 1..P`` frames outside each side with weights
``(1 − i/P)²``, left out beyond the signal; frames whose window has ``Σ|v| < 1e-3`` are skipped
(all parameters 0). The denominator of the original's loss only rescales it and is omitted.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["SinusoidFit", "Window", "apply_bounds", "fit_sinusoids_plain", "fit_window", "frame_window",
           "is_feasible", "normal_equations", "window_half_width"]


@dataclass
class SinusoidFit:
    """Per-frame sinusoid parameters, all (F,) float64, in local time τ = t − t_k.

    amplitude: A >= 0 (units of the signal).
    frequency: F in Hz; 0 for skipped frames.
    phase:     φ = (−S') mod 1 = (F t_k − S) mod 1, in [0, 1), cycles.
    offset:    B (units of the signal).
    fit:       f_k(t_k) = A sin 2πφ + B, the fitted curve's value at its own frame (the original's Fit).
    skipped:   bool, frames whose window was (almost) all zeros.
    """

    amplitude: np.ndarray
    frequency: np.ndarray
    phase: np.ndarray
    offset: np.ndarray
    fit: np.ndarray
    skipped: np.ndarray

    def curve(self, k: int, t_offset: np.ndarray) -> np.ndarray:
        """Frame k's fitted sinusoid at times ``t_k + t_offset`` (seconds)."""
        return self.amplitude[k] * np.sin(2 * np.pi * (self.frequency[k] * t_offset + self.phase[k])) + self.offset[k]


def window_half_width(seconds: float, fps: float) -> int:
    """Half width P in frames of a window of ``seconds`` (2P+1 frames; 0.5 s at 60 fps -> 15)."""
    return max(1, int(np.floor(seconds * fps / 2 + 0.5)))


@dataclass
class Window:
    """The samples the loss of frame k looks at: its data window and P connect frames each side.

    index:   (E,) frame j of each sample (clipped into the signal; weight 0 where it was outside).
    offset:  (E,) τ = j − k in frames.
    data:    (E,) 1 on the data window, 0 on the connect frames.
    connect: (E,) (1 − i/P)² on the connect frame i outside the data window, 0 on the data window
             and beyond the signal.
    vmin, vmax: the range of the signal over these samples (the bounds, §4.2).
    skipped: the data window is (almost) all zeros.
    """

    index: np.ndarray
    offset: np.ndarray
    data: np.ndarray
    connect: np.ndarray
    vmin: float
    vmax: float
    skipped: bool


def frame_window(v: np.ndarray, k: int, half: int, skip_threshold: float) -> Window:
    """Frame k's window: 2P+1 data frames centred on k, shifted (not cut) inwards near the ends,
    plus the P frames beyond each side for the connect terms (§4.1-§4.3)."""
    n = v.size
    length = min(2 * half + 1, n)
    lo = min(max(k - half, 0), n - length)                # first data frame
    j = np.arange(lo - half, lo + length + half)          # every sample, data and connect
    inside = (j >= 0) & (j < n)
    data = ((j >= lo) & (j < lo + length)).astype(float)
    i = np.where(j < lo, lo - j, j - (lo + length - 1))   # connect distance 1..P (0 on the data)
    connect = np.where(data > 0, 0.0, (1.0 - i / half) ** 2) * inside
    seen = v[j[inside]]
    return Window(np.clip(j, 0, n - 1), (j - k).astype(float), data, connect, float(seen.min()),
                  float(seen.max()), bool(np.abs(v[lo: lo + length]).sum() < skip_threshold))


def normal_equations(freqs, offset, weight, y, fps):
    """The 3x3 weighted least-squares system of one window, for each frequency (the method's core).

    Minimise ``Σ w (c1 sin 2πFτ + c2 cos 2πFτ + B − y)²`` over c = (c1, c2, B): for a fixed F
    it is linear, and with the basis b(τ) = (sin 2πFτ, cos 2πFτ, 1) its normal equations are
    G c = r, G = Σ w b bᵀ, r = Σ w y b. A ridge of 1e-10 trace(G) keeps degenerate windows
    (1-2 frames) finite. freqs (G,) Hz, offset τ (E,) frames, weight and y (E,).
    Returns G (G, 3, 3), r (G, 3) and Σ w y² (the error of c = 0).
    """
    angle = (2 * np.pi / fps) * freqs[:, None] * offset[None, :]              # (G, E)
    basis = np.stack([np.sin(angle), np.cos(angle), np.ones_like(angle)], axis=-1)   # (G, E, 3)
    weighted = weight[None, :, None] * basis
    G = basis.transpose(0, 2, 1) @ weighted
    r = weighted.transpose(0, 2, 1) @ y
    G += (1e-10 * np.trace(G, axis1=1, axis2=2) + 1e-300)[:, None, None] * np.eye(3)
    return G, r, float(np.sum(weight * y * y))


def is_feasible(c, vmin: float, vmax: float) -> bool:
    """The §4.2 bounds: the offset B in [vmin, vmax] and the amplitude |(c1, c2)| <= vmax − vmin."""
    return bool(vmin <= c[2] <= vmax and c[0] ** 2 + c[1] ** 2 <= (vmax - vmin) ** 2)


def apply_bounds(G, r, yy: float, c, vmin: float, vmax: float):
    """One frequency's solution c brought inside the bounds: B clipped (and (c1, c2) re-solved
    for that B, a 2x2 system), then the amplitude scaled down to vmax − vmin if it is above.
    Returns the new c and its weighted squared error yy − 2 cᵀr + cᵀGc."""
    c = c.copy()
    B = min(max(c[2], vmin), vmax)
    if B != c[2]:
        c[:2] = np.linalg.solve(G[:2, :2], r[:2] - G[:2, 2] * B)
        c[2] = B
    amplitude = np.hypot(c[0], c[1])
    if amplitude > vmax - vmin:
        c[:2] *= (vmax - vmin) / max(amplitude, 1e-300)
    return c, yy - 2 * c @ r + c @ G @ c


def fit_window(win: Window, weight, y, freqs, fps):
    """Best (c1, c2, B) and F of one window: every grid frequency, then a parabolic refinement.

    For each grid frequency the 3x3 system is solved; where the solution breaks a bound it is
    brought inside (:func:`apply_bounds`). A bound can only raise the error, so a frequency whose
    unbounded fit is infeasible and already worse than the best feasible one cannot win: it is
    left as it is, with its unbounded error (a lower bound) in the list the parabola reads. (The
    vectorised fit prunes the same way; there it saves most of the work.)
    """
    G, r, yy = normal_equations(freqs, win.offset, weight, y, fps)
    coef = np.linalg.solve(G, r[..., None])[..., 0]                 # (G, 3): one 3x3 system per F
    error = yy - np.sum(coef * r, axis=1)                            # at the optimum cᵀGc = cᵀr
    feasible = np.array([is_feasible(c, win.vmin, win.vmax) for c in coef])
    best_feasible = np.min(error[feasible], initial=np.inf)
    for g in np.nonzero(~feasible & (error < best_feasible))[0]:
        coef[g], error[g] = apply_bounds(G[g], r[g], yy, coef[g], win.vmin, win.vmax)
    best = int(np.argmin(error))
    # parabola through (log F, error) at best - 1, best, best + 1: its vertex, at most one step away
    logf = np.log(freqs)
    shift = 0.0
    if 0 < best < len(freqs) - 1:
        l0, l1, l2 = error[best - 1], error[best], error[best + 1]
        if l0 - 2 * l1 + l2 > 0:
            shift = float(np.clip(0.5 * (l0 - l2) / (l0 - 2 * l1 + l2), -1, 1))
    step = logf[1] - logf[0] if len(freqs) > 1 else 0.0
    f_refined = np.exp(logf[best] + shift * step)
    G1, r1, _ = normal_equations(np.array([f_refined]), win.offset, weight, y, fps)
    c = np.linalg.solve(G1[0], r1[0])
    sse = yy - c @ r1[0]
    if not is_feasible(c, win.vmin, win.vmax):
        c, sse = apply_bounds(G1[0], r1[0], yy, c, win.vmin, win.vmax)
    if sse < error[best]:
        return c, f_refined
    return coef[best], freqs[best]


def fit_sinusoids_plain(signal, fps: float, window_seconds: float = 0.5, min_frequency: float = 0.25,
                        max_frequency: float = 4.0, n_frequencies: int = 48, sweeps: int = 3,
                        skip_threshold: float = 1e-3, phase_slope_seconds: float = 1.0) -> SinusoidFit:
    """Fit ``A sin(2π(F t − S)) + B`` around every frame of ``signal``, one frame at a time.

    Args and result as :func:`minifilm.phases.sinusoid_fit.fit_sinusoids` (which computes the
    same, vectorised): signal (F,) preprocessed source, fps, the 0.5 s window, the frequency
    bounds and grid, the Jacobi sweeps of the connect terms, the skip threshold, and the span of
    the phase track whose slope is the reported frequency. Returns a SinusoidFit of (F,) arrays.
    """
    v = np.asarray(signal, dtype=np.float64)
    if v.ndim != 1 or v.size == 0:
        raise ValueError(f"fit_sinusoids_plain: signal must be a non-empty 1-D array, got shape {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError("fit_sinusoids_plain: signal contains NaN or inf")
    if not (fps > 0 and 0 < min_frequency < max_frequency):
        raise ValueError(f"fit_sinusoids_plain: need fps > 0 and 0 < min_frequency < max_frequency, "
                         f"got fps={fps}, frequencies=({min_frequency}, {max_frequency})")
    n = v.size
    half = window_half_width(window_seconds, fps)
    freqs = np.geomspace(min_frequency, max_frequency, n_frequencies)
    windows = [frame_window(v, k, half, skip_threshold) for k in range(n)]

    coef, F = np.zeros((n, 3)), np.zeros(n)               # (c1, c2, B) and F of every frame
    fit = np.zeros(n)                                     # each frame's curve at its own frame
    for sweep in range(max(1, sweeps)):
        new_coef, new_F = np.zeros((n, 3)), np.zeros(n)
        for k, win in enumerate(windows):
            if win.skipped:
                continue                                  # all parameters 0
            if sweep == 0:                                # the data alone
                weight, y = win.data, np.where(win.data > 0, v[win.index], 0.0)
            else:                                         # plus the neighbours' last fits
                weight, y = win.data + win.connect, np.where(win.data > 0, v[win.index], fit[win.index])
            new_coef[k], new_F[k] = fit_window(win, weight, y, freqs, fps)
        coef, F = new_coef, new_F
        fit = coef[:, 1] + coef[:, 2]                     # f_k(τ = 0): sin 0 = 0, cos 0 = 1

    c1, c2, B = coef.T
    amplitude = np.hypot(c1, c2)
    phase = np.mod(np.arctan2(c2, c1) / (2 * np.pi), 1.0)
    phase[(amplitude == 0) | (phase >= 1.0)] = 0.0
    skipped = np.array([w.skipped for w in windows])
    valid = ~skipped & (amplitude > 0)
    # PAPER: the paper's (and the original's) frequency is the fit's F. Here it is the slope of the
    # unwrapped phase over the second around k, where all of it was fitted (see the module
    # docstring); the window's own F elsewhere.
    slope_half = int(round(phase_slope_seconds * fps / 2))
    cycles = np.unwrap(2 * np.pi * phase) / (2 * np.pi)
    t = np.arange(n) / fps
    frequency = F.copy()
    if slope_half >= 1:
        for k in range(slope_half, n - slope_half):
            s = slice(k - slope_half, k + slope_half + 1)
            if np.all(valid[s]):
                tc = t[s] - t[s].mean()
                frequency[k] = np.clip(np.sum(tc * cycles[s]) / np.sum(tc * tc), min_frequency, max_frequency)
    return SinusoidFit(amplitude, frequency, phase, B.copy(), fit, skipped)
