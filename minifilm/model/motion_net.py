"""Φ, the motion synthesis network (Sec. 4.2, Eq. 3): three gated-expert layers.

For layer i in {1, 2} (the hidden layers), with expert weights blended by α = Ω(p):

    F(i) = Σ_k α_k (W_k h(i-1) + b_k)                          gated experts (fast form: nn/functional.py::expert_linear_forward)
    h(i) = ELU( γ(i) ∘ (F(i) − μ) / σ + β(i) )                   Eq. (3): layer norm, FiLM, ELU

and the output layer z = Σ_k α_k (W_k h(2) + b_k) is linear. Dropout (rate config.dropout) is
applied to the input of every layer during training. Layer norm has no affine parameters of its
own (FiLM plays that role); training uses the unbiased σ with eps 1e-6 added to σ, the released
runtime the biased σ without eps (docs/original-code.md §10.2) — both are options. Each hidden layer
is one :func:`~minifilm.model.blocks.film_block_forward`.

Expert weights are stored W{l} (K, in, out), b{l} (K, out). Inference at run time goes through
:class:`minifilm.runtime.network.RuntimeNetwork`, which computes the same thing laid out for speed.
"""
from __future__ import annotations

import numpy as np

from minifilm.model.blocks import expert_backward, expert_forward, film_block_backward, film_block_forward
from minifilm.model.config import ModelConfig
from minifilm.model.dropout import Dropout
from minifilm.model.init import init_dense_stack
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
        self.params = Parameters(motion_shapes(config), dtype=dtype)
        init_dense_stack(self.params, self.sizes, rng, dtype)
        self.used_masks: dict = {}
        self._caches = None

    def forward(self, x, alpha, film, train=False, rng=None, masks=None, ln_unbiased=None, ln_eps=None):
        """x (B, x_dim), α (B, K), film (B, 4H) = [γ1, β1, γ2, β2] -> z (B, z_dim)."""
        P, c = self.params.params, self.config
        unbiased = c.ln_unbiased if ln_unbiased is None else ln_unbiased
        eps = c.ln_eps if ln_eps is None else ln_eps
        drop = Dropout(c.dropout, train, rng, masks)
        self.used_masks = drop.used
        (g1, b1), (g2, b2) = split_film(film, c.hidden)
        h1, c1 = film_block_forward(x, alpha, P["W0"], P["b0"], g1, b1, drop, "motion0", unbiased, eps)
        h2, c2 = film_block_forward(h1, alpha, P["W1"], P["b1"], g2, b2, drop, "motion1", unbiased, eps)
        z, c3 = expert_forward(h2, alpha, P["W2"], P["b2"], drop, "motion2")
        self._caches = (c1, c2, c3)
        return z

    def backward(self, dz):
        """dz (B, z_dim) -> dx (B, x_dim), dα (B, K), dfilm (B, 4H); parameter grads are added."""
        if self._caches is None:
            raise RuntimeError("MotionNetwork.backward called before forward")
        G, (c1, c2, c3) = self.params.grads, self._caches
        dfilm = np.zeros(dz.shape[:1] + (4 * self.config.hidden,), dtype=dz.dtype)
        dfilms = split_film(dfilm, self.config.hidden)            # views: [(dγ1, dβ1), (dγ2, dβ2)]
        dh2, da3, dW, db = expert_backward(dz, c3)
        G["W2"] += dW
        G["b2"] += db
        dh1, da2, dW, db, dgamma, dbeta = film_block_backward(dh2, c2)
        G["W1"] += dW
        G["b1"] += db
        dfilms[1][0][...], dfilms[1][1][...] = dgamma, dbeta
        dx, da1, dW, db, dgamma, dbeta = film_block_backward(dh1, c1)
        G["W0"] += dW
        G["b0"] += db
        dfilms[0][0][...], dfilms[0][1][...] = dgamma, dbeta
        return dx, da3 + da2 + da1, dfilm
