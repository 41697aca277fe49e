"""Style modulation other than FiLM (Sec. 5): a one-hot style input and residual adapters.

Both add a style-dependent term to ONE hidden layer of the synthesis network (the paper, Sec.
5.1.2), unlike FiLM, which scales and shifts both hidden layers. Each class owns a `Parameters`
set (the "style modulation network" of Table 2, S.M.N.) and has explicit forward / backward.

OneHotShift (PFNN one-hot, Holden et al. 2017; LPN one-hot)
    A one-hot style vector e_s appended to the input x of the first layer adds, per expert or
    control point k, the row E[k, s] of that layer's weights:  Σ_k α_k (W_k [x; e_s] + b_k)
    = Σ_k α_k (W_k x + b_k) + Σ_k α_k E[k, s].  Stored as E (K, S, H) without bias.
    Per style at run time: K × H numbers (PFNN 4 × 512 = 2048, LPN 8 × 512 = 4096).

ResidualAdapter (LPN Resad; Rebuffi et al. 2017)
    h ← h + h A_s + a_s on a hidden layer, A (S, H, H), a (S, H): H² + H per style (262,656).

CPResidualAdapter (PFNN Resad; Mason et al. 2018)
    A phase-dependent adapter whose weight tensor over the 4 phase control points (4, H, H) is
    CP-decomposed with rank R:  A_s(φ) = Σ_r c_sr(φ) u_sr v_srᵀ, the c_sr(φ) a Catmull-Rom spline
    over 4 control values C_s (4, R). So h ← h + ((h U_s) ∘ (w(φ) C_s)) V_s + a_s with U (S, H, R),
    V (S, R, H), C (S, 4, R), a (S, H): 2 H R + 4 R + H per style (R = 30, H = 512: 31,352).

Style ids are (B,) ints; a batch may mix styles (handled one style at a time). Adapters start
as the identity (A, C, a zero), as residual adapters are meant to; U, V start Glorot-uniform so
that C gets a gradient from the first step.
"""
from __future__ import annotations

import numpy as np

from minifilm.model.init import glorot_uniform
from minifilm.nn.params import Parameters


def _check_styles(style, n_styles, B, who):
    if style is None:
        raise ValueError(f"{who}: needs style ids (B,) (forward(..., style=ids))")
    style = np.asarray(style)
    if style.shape != (B,) or not np.issubdtype(style.dtype, np.integer):
        raise ValueError(f"{who}: style must be ({B},) ints, got {style.shape} {style.dtype}")
    if style.size and (style.min() < 0 or style.max() >= n_styles):
        raise ValueError(f"{who}: style ids must be in 0..{n_styles - 1}, got {style.min()}..{style.max()}")
    return style


def _groups(style):
    """(style id, row indices) for every style present in the batch."""
    for s in np.unique(style):
        yield int(s), np.nonzero(style == s)[0]


# ---- one-hot ---------------------------------------------------------------------------------
def onehot_shapes(n_blend: int, n_styles: int, hidden: int) -> dict:
    return {"E": (n_blend, n_styles, hidden)}


class OneHotShift:
    """Σ_k α_bk E[k, s_b]: the first layer's response to a one-hot style input. -> (B, H)."""

    per_style_fields = ("E",)

    def __init__(self, n_blend, n_styles, hidden, fan_in, rng, dtype=np.float32):
        self.n_styles = n_styles
        self.params = Parameters(onehot_shapes(n_blend, n_styles, hidden), dtype=dtype)
        # the one-hot rows are rows of the first layer: same initialisation as that layer
        self.params.params["E"][...] = glorot_uniform(rng, (n_blend, n_styles, hidden), fan_in, hidden, dtype)
        self._cache = None

    def forward(self, style, alpha):
        """style (B,) ints, or (B, S) weights of a blended one-hot vector (style interpolation:
        the term is linear in the vector, so it blends the style rows); alpha (B, K) -> shift (B, H)."""
        E = self.params.params["E"]
        if np.ndim(style) == 2:
            weights = np.asarray(style, dtype=E.dtype)
            if weights.shape != (alpha.shape[0], self.n_styles):
                raise ValueError(f"OneHotShift: style weights must be ({alpha.shape[0]}, {self.n_styles}), "
                                 f"got {weights.shape}")
            self._cache = ("weights", weights, alpha)
            return np.einsum("bk,bs,ksh->bh", alpha, weights, E)
        style = _check_styles(style, self.n_styles, alpha.shape[0], "OneHotShift")
        rows = E[:, style, :]                                       # (K, B, H)
        self._cache = ("ids", style, alpha, rows)
        return np.einsum("bk,kbh->bh", alpha, rows)

    def backward(self, dshift):
        """dshift (B, H) -> dalpha (B, K); adds dE."""
        if self._cache[0] == "weights":
            _, weights, alpha = self._cache
            E = self.params.params["E"]
            self.params.grads["E"] += np.einsum("bk,bs,bh->ksh", alpha, weights, dshift)
            return np.einsum("bh,bs,ksh->bk", dshift, weights, E)
        _, style, alpha, rows = self._cache
        dE = np.einsum("bk,bh->kbh", alpha, dshift)                 # (K, B, H)
        np.add.at(self.params.grads["E"], (slice(None), style), dE)
        return np.einsum("bh,kbh->bk", dshift, rows)



# ---- full residual adapter (LPN Resad) -------------------------------------------------------
def adapter_shapes(n_styles: int, hidden: int) -> dict:
    return {"A": (n_styles, hidden, hidden), "a": (n_styles, hidden)}


class ResidualAdapter:
    """h (B, H) -> h + h A_s + a_s per sample's style s."""

    def __init__(self, n_styles, hidden, rng, dtype=np.float32):
        self.n_styles = n_styles
        self.params = Parameters(adapter_shapes(n_styles, hidden), dtype=dtype)   # zeros: identity
        self._cache = None

    def forward(self, h, style, phase_weights=None):
        style = _check_styles(style, self.n_styles, h.shape[0], "ResidualAdapter")
        P = self.params.params
        out = h.copy()
        for s, idx in _groups(style):
            out[idx] += h[idx] @ P["A"][s] + P["a"][s]
        self._cache = (h, style)
        return out

    def backward(self, dout):
        h, style = self._cache
        P, G = self.params.params, self.params.grads
        dh = dout.copy()
        for s, idx in _groups(style):
            G["A"][s] += h[idx].T @ dout[idx]
            G["a"][s] += dout[idx].sum(axis=0)
            dh[idx] += dout[idx] @ P["A"][s].T
        return dh



# ---- CP-decomposed phase-dependent adapter (PFNN Resad) ------------------------------------
def cp_adapter_shapes(n_styles: int, hidden: int, rank: int, n_points: int = 4) -> dict:
    return {"U": (n_styles, hidden, rank), "V": (n_styles, rank, hidden),
            "C": (n_styles, n_points, rank), "a": (n_styles, hidden)}


class CPResidualAdapter:
    """h (B, H), phase weights w (B, 4) -> h + ((h U_s) ∘ (w C_s)) V_s + a_s."""

    def __init__(self, n_styles, hidden, rank, rng, n_points=4, dtype=np.float32):
        self.n_styles = n_styles
        shapes = cp_adapter_shapes(n_styles, hidden, rank, n_points)
        self.params = Parameters(shapes, dtype=dtype)
        P = self.params.params
        P["U"][...] = glorot_uniform(rng, shapes["U"], hidden, rank, dtype)
        P["V"][...] = glorot_uniform(rng, shapes["V"], rank, hidden, dtype)
        self._cache = None                                   # C and a zero: the adapter starts as identity

    def forward(self, h, style, phase_weights):
        style = _check_styles(style, self.n_styles, h.shape[0], "CPResidualAdapter")
        P = self.params.params
        out = h.copy()
        parts = []
        for s, idx in _groups(style):
            t = h[idx] @ P["U"][s]                             # (b, R) projections
            g = phase_weights[idx] @ P["C"][s]                 # (b, R) phase-dependent CP weights
            out[idx] += (t * g) @ P["V"][s] + P["a"][s]
            parts.append((s, idx, t, g))
        self._cache = (h, phase_weights, parts)
        return out

    def backward(self, dout):
        h, w, parts = self._cache
        P, G = self.params.params, self.params.grads
        dh = dout.copy()
        for s, idx, t, g in parts:
            d = dout[idx]
            dm = d @ P["V"][s].T                                # (b, R)
            G["V"][s] += (t * g).T @ d
            G["a"][s] += d.sum(axis=0)
            G["C"][s] += w[idx].T @ (dm * t)
            dt = dm * g
            G["U"][s] += h[idx].T @ dt
            dh[idx] += dt @ P["U"][s].T
        return dh

