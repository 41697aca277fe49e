"""Source functions for the local phases and their preprocessing (Sec. 4.1.2-4.1.4;
docs/original-code.md §3.3-§3.7).

A source function G(t) is a 1-D signal per end effector whose cycles are the bone's cycles:

* contact-based (feet): the 0/1 foot contact signal (Sec. 4.1.2);
* contact-free (hands, and the lifted foot in hopping styles): the bone position in the hips'
  frame, centred, projected on its first principal component, the component directed along the
  character's forward axis (Sec. 4.1.3).

Before the sinusoid fit each source is normalised in a 1 s window, low-passed by a 2nd-order 4 Hz
Butterworth filter run forwards and backwards, and values below 1e-3 are set to 0 (Sec. 4.1.4).

Decisions (docs/original-code.md §12):
* §12.3 contact lag: the original feeds frame k the contact of frame k−1 (an indexing slip). We do
  **not** replicate it: the contact source of frame k is the contact of frame k.
* §12.8 Butterworth edges: we use ``scipy.signal.sosfiltfilt`` with constant (edge-value) padding
  instead of the original's hand-made edges. On a normalised contact signal the result agrees with
  the original's recursion to about 1e-7 except in the last ~0.5 s, where the original leaves the
  last sample unfiltered and starts its backward pass from it (differences up to ~0.05 there; we
  filter the last sample like every other). tests/phases/test_phases.py compares the two.
* The original computes sources only inside a per-file frame range (Frame_Cuts.csv, 100STYLE
  specific) and sets them to 0 outside; here the caller passes the frames to use (slice the motion).
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

__all__ = ["contact_source", "pca_source", "principal_direction", "window_normalise", "butterworth",
           "preprocess_source"]


def contact_source(contacts) -> np.ndarray:
    """(F,) 0/1 contact signal of one foot -> (F,) float source (no one-frame lag, see module doc)."""
    c = np.asarray(contacts, dtype=np.float64)
    if c.ndim != 1:
        raise ValueError(f"contact_source: expected one foot's contacts (F,), got shape {c.shape}")
    return c.copy()


def principal_direction(local_positions, forward_axis: Sequence[float] = (0.0, 0.0, 1.0)):
    """First principal component of hips-local positions, directed along ``forward_axis``.

    Args:
        local_positions: (F, 3) bone positions in the hips' own frame, metres.
        forward_axis: (3,) unit hips-local axis pointing to the character's front.
    Returns:
        (mean (3,), direction (3,) unit vector with direction · forward_axis >= 0).
    """
    q = np.asarray(local_positions, dtype=np.float64)
    if q.ndim != 2 or q.shape[1] != 3 or q.shape[0] < 2:
        raise ValueError(f"principal_direction: need positions (F >= 2, 3), got shape {q.shape}")
    mean = q.mean(axis=0)
    c = q - mean
    cov = c.T @ c / (q.shape[0] - 1)
    _, vecs = np.linalg.eigh(cov)      # eigenvalues ascending
    pc1 = vecs[:, -1]
    fwd = np.asarray(forward_axis, dtype=np.float64)
    along = float(pc1 @ fwd)
    # Direct the component (Sec. 4.1.3): positive along forward. An exact tie (a component
    # perpendicular to forward) falls back to the original's rule on the first axis.
    if along < 0 or (along == 0 and pc1[0] <= 0):
        pc1 = -pc1
    return mean, pc1


def pca_source(local_positions, forward_axis: Sequence[float] = (0.0, 0.0, 1.0)) -> np.ndarray:
    """Contact-free source (Sec. 4.1.3): centred hips-local positions projected on the directed PC1.

    local_positions (F, 3) metres -> (F,) metres. Compute it per file (one style and gait), as the
    paper does: the mean and the component are those of the frames given.
    """
    q = np.asarray(local_positions, dtype=np.float64)
    mean, pc1 = principal_direction(q, forward_axis)
    return (q - mean) @ pc1


def window_normalise(signal, fps: float, window_seconds: float = 1.0, min_std: float = 1e-6) -> np.ndarray:
    """Normalise each frame by the mean and population std of a window centred on it (§3.5).

    The window holds round(window_seconds*fps)+1 frames (61 at 60 fps); samples beyond the ends
    repeat the end values. A window whose std is below ``min_std`` (a constant signal, up to
    rounding) uses std = 1, so a still signal becomes 0 rather than amplified rounding noise.

    signal (F,) -> (F,).
    """
    x = np.asarray(signal, dtype=np.float64)
    n = x.size
    half = int(np.floor(window_seconds * fps / 2 + 0.5))
    padded = np.concatenate([np.full(half, x[0]), x, np.full(half, x[-1])])
    shift = padded.mean()  # centring first keeps the running sums accurate
    y = padded - shift
    cs = np.concatenate([[0.0], np.cumsum(y)])
    cs2 = np.concatenate([[0.0], np.cumsum(y * y)])
    m = 2 * half + 1
    s1 = cs[m:m + n] - cs[:n]
    s2 = cs2[m:m + n] - cs2[:n]
    mean = s1 / m
    var = np.maximum(s2 / m - mean * mean, 0.0)
    std = np.sqrt(var)
    std = np.where(std < min_std, 1.0, std)
    return (x - shift - mean) / std


def butterworth(signal, fps: float, cutoff: float = 4.0, order: int = 2) -> np.ndarray:
    """Zero-phase low-pass: a Butterworth filter run forwards and backwards (§3.6).

    ``sosfiltfilt`` with constant (edge-value) padding; see the module doc for the edge deviation.
    signal (F, ...) filtered along axis 0.
    """
    x = np.asarray(signal, dtype=np.float64)
    nyquist = fps / 2.0
    if not (0 < cutoff < nyquist):
        raise ValueError(f"butterworth: cutoff {cutoff} Hz must lie in (0, fps/2 = {nyquist}) Hz")
    if x.shape[0] < 2:
        return x.copy()
    # imported here: scipy.signal is ~85 % of the package's import time, for this one filter
    from scipy.signal import butter, sosfiltfilt
    sos = butter(order, cutoff / nyquist, output="sos")
    padlen = min(3 * (2 * len(sos) + 1), x.shape[0] - 1)
    return sosfiltfilt(sos, x, axis=0, padtype="constant", padlen=padlen)


def usable_cutoff(cutoff: float, fps: float) -> float:
    """``cutoff`` (Hz), or 80 % of the Nyquist rate when the data cannot carry it: below 10 fps
    the paper's 4 Hz lies at or above fps/2, so the low-pass keeps what the frames can hold."""
    return min(float(cutoff), 0.4 * float(fps))


def preprocess_source(signal, fps: float, normalise_seconds: float = 1.0, cutoff: float = 4.0,
                      zero_below: float = 1e-3) -> np.ndarray:
    """Sec. 4.1.4 / §3.7: window normalisation, Butterworth, |v| < 1e-3 -> 0. (F,) -> (F,).
    At low frame rates the cutoff is lowered to what the frames can carry (:func:`usable_cutoff`)."""
    v = butterworth(window_normalise(signal, fps, normalise_seconds), fps, usable_cutoff(cutoff, fps))
    v[np.abs(v) < zero_below] = 0.0
    return v
