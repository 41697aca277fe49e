"""Φ, the motion synthesis network (Sec. 4.2, Eq. 3): three gated-expert layers.

For layer i in {1, 2} (the hidden layers), with expert weights blended by α = Ω(p):

    F(i) = Σ_k α_k (W_k h(i-1) + b_k)                          gated experts (fast form, DESIGN.md)
    h(i) = ELU( γ(i) ∘ (F(i) − μ) / σ + β(i) )                   Eq. (3): layer norm, FiLM, ELU

and the output layer z = Σ_k α_k (W_k h(2) + b_k) is linear. Dropout (rate config.dropout) is
applied to the input of every layer during training. Layer norm has no affine parameters of its
own (FiLM plays that role); training uses the unbiased σ with eps 1e-6 added to σ, the released
runtime the biased σ without eps (original-pipeline §10.2) — both are options.

Expert weights are stored W{l} (K, in, out), b{l} (K, out).
"""
from __future__ import annotations

import numpy as np

from minifilm.model.config import ModelConfig
from minifilm.model.dropout import dropout_site, dropout_site_backward
from minifilm.model.init import init_dense_stack
from minifilm.nn import functional as F
from minifilm.nn.params import Parameters


def split_film(film, hidden):
    """film (..., 4H) -> [(γ1, β1), (γ2, β2)], views in the order of Eq. (2)."""
    return [(film[..., 0:hidden], film[..., hidden:2 * hidden]),
            (film[..., 2 * hidden:3 * hidden], film[..., 3 * hidden:4 * hidden])]


def motion_shapes(config: ModelConfig) -> dict:
    """Parameter shapes of Φ: W{l} (K, in, out), b{l} (K, out) for l = 0, 1, 2."""
    K = config.n_experts
    sizes = [config.x_dim, config.hidden, config.hidden, config.z_dim]
    shapes = {}
    for l in range(3):
        shapes[f"W{l}"] = (K, sizes[l], sizes[l + 1])
        shapes[f"b{l}"] = (K, sizes[l + 1])
    return shapes


class MotionNetwork:
    """Φ: x (B, x_dim), α (B, K), FiLM (B, 4H) -> z (B, z_dim)."""

    def __init__(self, config: ModelConfig, rng: np.random.Generator, dtype=np.float32):
        self.config = config
        self.sizes = [config.x_dim, config.hidden, config.hidden, config.z_dim]
        shapes = motion_shapes(config)
        self.params = Parameters(shapes, dtype=dtype)
        init_dense_stack(self.params, self.sizes, rng, dtype)
        self.used_masks: dict = {}
        self._caches = None

    def _ln_options(self, unbiased, eps):
        return (self.config.ln_unbiased if unbiased is None else unbiased,
                self.config.ln_eps if eps is None else eps)

    def forward(self, x, alpha, film, train=False, rng=None, masks=None, ln_unbiased=None, ln_eps=None):
        """x (B, x_dim), α (B, K), film (B, 4H) = [γ1, β1, γ2, β2] -> z (B, z_dim)."""
        P, q, self.used_masks = self.params.params, self.config.dropout, {}
        unbiased, eps = self._ln_options(ln_unbiased, ln_eps)
        films = split_film(film, self.config.hidden)
        caches = []
        h = x
        for l in range(3):
            h, c_drop = dropout_site(h, q, f"motion{l}", train, rng, masks, self.used_masks)
            h, c_exp = F.expert_linear_forward(h, alpha, P[f"W{l}"], P[f"b{l}"])     # F(i)  (B, H)
            if l < 2:
                gamma, beta = films[l]
                h, c_ln = F.layer_norm_forward(h, unbiased=unbiased, eps=eps)   # (F − μ)/σ
                h, c_film = F.film_forward(h, gamma, beta)                     # γ ∘ · + β
                h, c_act = F.elu_forward(h)                                   # h(i)
                caches.append((c_drop, c_exp, c_ln, c_film, c_act))
            else:
                caches.append((c_drop, c_exp))
        self._caches = caches
        return h

    def backward(self, dz):
        """dz (B, z_dim) -> dx (B, x_dim), dα (B, K), dfilm (B, 4H); parameter grads are added."""
        if self._caches is None:
            raise RuntimeError("MotionNetwork.backward called before forward")
        G, H = self.params.grads, self.config.hidden
        dfilm = np.zeros(dz.shape[:1] + (4 * H,), dtype=dz.dtype)
        dfilms = split_film(dfilm, H)
        dalpha = 0.0
        dh = dz
        for l in reversed(range(3)):
            if l < 2:
                c_drop, c_exp, c_ln, c_film, c_act = self._caches[l]
                dh = F.elu_backward(dh, c_act)
                dh, dgamma, dbeta = F.film_backward(dh, c_film)
                dfilms[l][0][...] = dgamma
                dfilms[l][1][...] = dbeta
                dh = F.layer_norm_backward(dh, c_ln)
            else:
                c_drop, c_exp = self._caches[l]
            dh, da, dW, db = F.expert_linear_backward(dh, c_exp)
            G[f"W{l}"] += dW
            G[f"b{l}"] += db
            dalpha = dalpha + da
            dh = dropout_site_backward(dh, c_drop)
        return dh, dalpha, dfilm

    def predict_single(self, x, alpha, film, ln_unbiased=None, ln_eps=None):
        """Batch-1 inference (Sec. 4.4, original-pipeline §10.2): Σ_k α_k (h W_k + b_k) per layer.

        The original blends the expert weights with α first, then multiplies; the same sum is
        computed here as one matrix-vector product over outer(α, h) (F.expert_linear_single),
        which reads each expert weight once and writes no blended matrix (batch 1 is limited by
        reading the 19.7 MB of expert weights).

        x (x_dim,), α (K,), film (4H,) -> z (z_dim,). No dropout.
        """
        P = self.params.params
        unbiased, eps = self._ln_options(ln_unbiased, ln_eps)
        films = split_film(film, self.config.hidden)
        h = x
        for l in range(3):
            h = F.expert_linear_single(h, alpha, P[f"W{l}"], P[f"b{l}"])   # (O,)
            if l < 2:
                gamma, beta = films[l]
                h, _ = F.layer_norm_forward(h[None, :], unbiased=unbiased, eps=eps)
                h = F.elu_forward(gamma * h[0] + beta)[0]
        return h
