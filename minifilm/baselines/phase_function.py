"""The PFNN's phase function (Holden et al. 2017): network weights as a cyclic Catmull-Rom spline.

The PFNN keeps 4 control-point weight sets W_0..W_3 spaced evenly round the phase cycle and, for a
global phase φ in [0, 1), uses the cubic Catmull-Rom interpolation of the four (Holden et al.
2017, Eq. 2-3):

    t = 4 φ,   k1 = ⌊t⌋ mod 4,   μ = t − ⌊t⌋,   k0 = k1 − 1, k2 = k1 + 1, k3 = k1 + 2  (mod 4)
    W(φ) = W_k1 + μ (½W_k2 − ½W_k0) + μ² (W_k0 − 5/2 W_k1 + 2 W_k2 − ½W_k3)
                + μ³ (3/2 W_k1 − 3/2 W_k2 + ½W_k3 − ½W_k0)

W(φ) is *linear* in the control points: W(φ) = Σ_k w_k(φ) W_k with the four spline weights
w(φ) below (they sum to 1). So a PFNN layer is exactly a gated-expert layer whose "experts" are the
control points and whose blend weights come from the phase instead of a gating network, and the
gated-expert kernels (minifilm.nn.functional.expert_linear_*) compute it and its gradient with
respect to the control-point weights. The phase is input data: it gets no gradient.
"""
from __future__ import annotations

import numpy as np


def catmull_rom_weights(phase, n_points: int = 4) -> np.ndarray:
    """Blend weights of the cyclic Catmull-Rom spline over `n_points` control points.

    phase (B,) or (B, 1) in [0, 1) (values outside are wrapped) -> w (B, n_points), rows sum to 1,
    w[b] @ values = the spline through `values` (n_points, ...) at phase[b]. At φ = k / n_points
    the spline passes through control point k exactly (w = one-hot k).
    """
    phase = np.asarray(phase)
    if phase.ndim == 2 and phase.shape[1] == 1:
        phase = phase[:, 0]
    if phase.ndim != 1:
        raise ValueError(f"catmull_rom_weights: phase must be (B,) or (B, 1), got {phase.shape}")
    if n_points < 4:
        raise ValueError(f"catmull_rom_weights: a cubic spline needs >= 4 control points, got {n_points}")
    t = np.mod(phase.astype(np.float64), 1.0) * n_points
    k1 = np.floor(t).astype(np.int64) % n_points
    mu = t - np.floor(t)
    mu2, mu3 = mu * mu, mu * mu * mu
    coeff = np.stack([-0.5 * mu + mu2 - 0.5 * mu3,          # k0 = k1 - 1
                      1.0 - 2.5 * mu2 + 1.5 * mu3,          # k1
                      0.5 * mu + 2.0 * mu2 - 1.5 * mu3,     # k2 = k1 + 1
                      -0.5 * mu2 + 0.5 * mu3], axis=1)      # k3 = k1 + 2
    w = np.zeros((phase.shape[0], n_points), dtype=np.float64)
    rows = np.arange(phase.shape[0])
    for j, shift in enumerate((-1, 0, 1, 2)):
        np.add.at(w, (rows, (k1 + shift) % n_points), coeff[:, j])   # add: n_points=4 never repeats, >4 safe too
    return w.astype(phase.dtype if np.issubdtype(phase.dtype, np.floating) else np.float64)


class PhaseFunction:
    """The PFNN's "gate": global phase (B, 1) -> control-point blend weights (B, n_points).

    Has no parameters; backward returns None (the phase is data, never trained through).
    """

    def __init__(self, n_points: int = 4):
        self.n_points = n_points
        self.params = None

    def forward(self, p, train=False, rng=None, masks=None):
        return catmull_rom_weights(p, self.n_points)

    def backward(self, dalpha):
        return None
