"""The one inference path: Ω and Φ in evaluation mode, laid out for speed (Sec. 4.4, Eq. 3-4).

Everything that drives a character runs through :meth:`RuntimeNetwork.predict`: a model trained
here (:meth:`RuntimeNetwork.from_model`), the authors' released network (``released.py`` loads it
into a model), and the comparison variants of Sec. 5 (``minifilm/baselines/runtime.py`` gives it
their own gate and hidden-layer modulation). Per frame, for a batch of B characters:

    x̂    = (x - x_mean) / x_std
    α    = gate(x̂, p)                        Ω: softmax of an MLP of p̂ = (p - p_mean) / p_std
    F(i) = Σ_k α_k (h(i-1) W_k + b_k)         h(0) = x̂; one (I, K·O) matrix product per layer
    h(i) = hidden(i, F(i), α, cond)           Eq. (3): ELU(γ(i) ∘ (F(i) - μ) / σ + β(i)) for FiLM
    z    = F(3) · z_std + z_mean

Each expert layer is stored as one matrix ``(I, K·O)`` (the K experts side by side), so a frame
costs one matrix product per layer and reads each weight once; blending the weights first, as
the original runtime does, computes the same sum but also writes and re-reads the blended matrix
(``benchmarks/runtime.py`` measures both). ``cond`` is the style condition, given per call: a
FiLM vector (4H,) or (B, 4H) for FiLM models, style ids for the one-hot and adapter variants.
"""
from __future__ import annotations

from typing import Callable, Optional, Sequence, Tuple

import numpy as np

from minifilm.dataset.stats import NormStats
from minifilm.model.motion_net import split_film
from minifilm.nn import functional as F


class GatingMLP:
    """Ω in evaluation mode (Sec. 4.1): p̂ -> dense, ELU -> dense, ELU -> dense, softmax = α,
    with p̂ = (p - p_mean) / p_std the normalised local phases (``stats``).

    layers: [(W (in, out), b (out,))] * 3.
    """

    def __init__(self, layers: Sequence[Tuple[np.ndarray, np.ndarray]], stats: NormStats, dtype=np.float32):
        dtype = np.dtype(dtype)
        self.layers = [(np.asarray(W, dtype), np.asarray(b, dtype)) for W, b in layers]
        if len(self.layers) != 3:
            raise ValueError(f"GatingMLP: need 3 layers, got {len(self.layers)}")
        self.p_mean = stats.p_mean.astype(dtype)
        self.p_inv = (1.0 / stats.p_std).astype(dtype)
        self.in_dim = self.layers[0][0].shape[0]

    def __call__(self, x_norm: np.ndarray, p_raw: np.ndarray) -> np.ndarray:
        """x̂ (B, x_dim) (unused: Ω reads the phases only), raw phases p (B, phase_dim)
        -> α (B, K), rows summing to 1."""
        h = (np.asarray(p_raw, self.p_mean.dtype) - self.p_mean) * self.p_inv
        for l, (W, b) in enumerate(self.layers):
            h = h @ W + b
            if l < 2:
                h = F.elu_forward(h)[0]
        return F.softmax_forward(h)[0]


class FilmHidden:
    """The LPN's hidden layer at inference, Eq. (3): h = ELU(γ ∘ LN(F) + β), with cond = the FiLM
    vector [γ1, β1, γ2, β2] (4H,) or (B, 4H). ``ln_unbiased, ln_eps``: the layer-norm convention
    (training: True, 1e-6; the released runtime: False, 0.0, docs/original-code.md §10.2)."""

    def __init__(self, hidden: int, ln_unbiased: bool, ln_eps: float):
        self.hidden, self.ln_unbiased, self.ln_eps = hidden, bool(ln_unbiased), float(ln_eps)

    def __call__(self, layer: int, f: np.ndarray, alpha: np.ndarray, film: np.ndarray) -> np.ndarray:
        gamma, beta = split_film(np.asarray(film, f.dtype), self.hidden)[layer]
        h = F.layer_norm_forward(f, unbiased=self.ln_unbiased, eps=self.ln_eps)[0]
        return F.elu_forward(gamma * h + beta)[0]


class RuntimeNetwork:
    """Raw x, raw p and a style condition in, raw z out: the whole network for B characters.

    Args:
        gate: ``gate(x̂ (B, x_dim), p (B, phase_dim)) -> α (B, K)``, e.g. a :class:`GatingMLP`.
        experts: [(W (K, in, out), b (K, out))] * 3 of Φ.
        stats: normalisation statistics (x and z sizes must match the network).
        hidden: ``hidden(layer, F (B, H), α, cond) -> h (B, H)`` for layers 0 and 1, e.g. a
            :class:`FilmHidden`.
        dtype: computation dtype (float32 for speed; float64 for exact comparisons).
    """

    def __init__(self, gate: Callable, experts, stats: NormStats, hidden: Callable, dtype=np.float32):
        self.dtype = np.dtype(dtype)
        self.stats = stats
        self.gate, self.hidden = gate, hidden
        if len(experts) != 3:
            raise ValueError(f"RuntimeNetwork: need 3 expert layers, got {len(experts)}")
        self.n_experts = int(np.shape(experts[0][0])[0])
        self.layers = []
        for l, (W, b) in enumerate(experts):
            W = np.asarray(W, self.dtype)
            K, I, O = W.shape
            if K != self.n_experts or np.shape(b) != (K, O):
                raise ValueError(f"RuntimeNetwork: expert layer {l} has W {W.shape}, b {np.shape(b)}; "
                                 f"expected ({self.n_experts}, in, out) and ({self.n_experts}, out)")
            self.layers.append((np.ascontiguousarray(W.transpose(1, 0, 2).reshape(I, K * O)),
                                np.asarray(b, self.dtype), O))
        self.x_dim = self.layers[0][0].shape[0]
        self.z_dim = self.layers[2][2]
        if (len(stats.x_mean), len(stats.z_mean)) != (self.x_dim, self.z_dim):
            raise ValueError(f"RuntimeNetwork: statistics sizes x {len(stats.x_mean)}, z {len(stats.z_mean)} "
                             f"do not match the network ({self.x_dim}, {self.z_dim})")
        self._x_mean = stats.x_mean.astype(self.dtype)
        self._x_inv = (1.0 / stats.x_std).astype(self.dtype)
        self._z_mean, self._z_std = stats.z_mean.astype(self.dtype), stats.z_std.astype(self.dtype)

    @classmethod
    def from_model(cls, model, stats: NormStats, runtime_layer_norm: bool = False,
                   dtype=np.float32) -> "RuntimeNetwork":
        """From a :class:`~minifilm.model.style_model.StyleModel` (its Ω and Φ; Ψ is not needed:
        styles come in as FiLM vectors). ``runtime_layer_norm`` picks the released runtime's
        layer norm (biased σ, no eps) instead of the model's training convention."""
        g, m = model.gating.params.params, model.motion.params.params
        gate = GatingMLP([(g[f"W{l}"], g[f"b{l}"]) for l in range(3)], stats, dtype=dtype)
        experts = [(m[f"W{l}"], m[f"b{l}"]) for l in range(3)]
        cfg = model.config
        unbiased, eps = (False, 0.0) if runtime_layer_norm else (cfg.ln_unbiased, cfg.ln_eps)
        if gate.in_dim != len(stats.p_mean):
            raise ValueError(f"RuntimeNetwork: the gating network reads {gate.in_dim} phases, the "
                             f"statistics have {len(stats.p_mean)}")
        return cls(gate, experts, stats, FilmHidden(cfg.hidden, unbiased, eps), dtype)

    def to_arrays(self) -> dict:
        """A FiLM network with a :class:`GatingMLP` gate as named arrays (an ``.npz`` archive, or the
        fingerprint of a calibration: demo/calibration_cache.py); :meth:`from_arrays` makes the same network."""
        if not (isinstance(self.gate, GatingMLP) and isinstance(self.hidden, FilmHidden)):
            raise TypeError("RuntimeNetwork.to_arrays: only a FiLM network with a GatingMLP gate is written")
        h = self.hidden
        arrays = {**self.stats.to_arrays(), "film": np.array([h.hidden, h.ln_unbiased, h.ln_eps], np.float64)}
        for l, (W, b) in enumerate(self.gate.layers):
            arrays[f"gate.W{l}"], arrays[f"gate.b{l}"] = W, b
        for l, (Wc, b, O) in enumerate(self.layers):       # back to (K, in, out), as the constructor takes it
            arrays[f"expert.W{l}"] = Wc.reshape(len(Wc), self.n_experts, O).transpose(1, 0, 2)
            arrays[f"expert.b{l}"] = b
        return arrays

    @classmethod
    def from_arrays(cls, arrays) -> "RuntimeNetwork":
        """The network :meth:`to_arrays` wrote, in the dtype of its arrays."""
        stats = NormStats.from_arrays(arrays)
        dtype = np.asarray(arrays["expert.W0"]).dtype
        gate = GatingMLP([(arrays[f"gate.W{l}"], arrays[f"gate.b{l}"]) for l in range(3)], stats, dtype=dtype)
        hidden, unbiased, eps = np.asarray(arrays["film"], np.float64)
        experts = [(arrays[f"expert.W{l}"], arrays[f"expert.b{l}"]) for l in range(3)]
        return cls(gate, experts, stats, FilmHidden(int(hidden), bool(unbiased), float(eps)), dtype)

    @property
    def film_dim(self) -> Optional[int]:
        """The length of a FiLM style vector (4 * hidden) for a FiLM network; None for the other
        conditionings of the comparison variants."""
        return 4 * self.hidden.hidden if isinstance(self.hidden, FilmHidden) else None

    def predict(self, x_raw: np.ndarray, p_raw: np.ndarray, cond, change=None) -> np.ndarray:
        """Raw output z (B, z_dim) from raw x (B, x_dim), raw phases p (B, phase_dim) and the
        style condition (a FiLM vector (4H,) / (B, 4H) for FiLM models). ``change``: a style's own
        change of Φ for these rows (minifilm/runtime/adapted.py), applied after each gated-expert
        layer (``change.experts(l, F, input, α)``) and each hidden layer (``change.hidden(l, h)``);
        None: Φ as it is, the same operations as without the argument."""
        h = (np.asarray(x_raw, self.dtype) - self._x_mean) * self._x_inv
        alpha = self.gate(h, p_raw).astype(self.dtype, copy=False)      # (B, K)
        B = len(h)
        for l, (Wc, b, O) in enumerate(self.layers):
            if 1 < B < 5:   # BLAS is slower on a skinny matrix product than on a few vector products
                y = np.stack([row @ Wc for row in h]).reshape(B, self.n_experts, O)
            else:
                y = (h @ Wc).reshape(B, self.n_experts, O)              # every expert's output
            f = np.matmul(alpha[:, None, :], y)[:, 0] + alpha @ b       # Σ_k α_k (h W_k + b_k)
            if change is not None:
                f = change.experts(l, f, h, alpha)
            h = f
            if l < 2:
                h = self.hidden(l, h, alpha, cond)
                if change is not None:
                    h = change.hidden(l, h)
        return h * self._z_std + self._z_mean
