"""Ω, the gating network (Sec. 4.1): local phases -> expert blend weights α.

    p (B, phase_dim) -> dropout -> linear -> ELU -> dropout -> linear -> ELU
                     -> dropout -> linear -> softmax = α (B, K)

p is the normalised local-phase vector of Eq. (1) (4 end effectors x amplitude-scaled
(sin, cos)). Weights are stored (in, out).
"""
from __future__ import annotations

import numpy as np

from minifilm.model.config import ModelConfig
from minifilm.model.dropout import dropout_site, dropout_site_backward
from minifilm.model.init import init_dense_stack
from minifilm.nn import functional as F
from minifilm.nn.params import Parameters


def gating_shapes(config: ModelConfig) -> dict:
    """Parameter shapes of Ω: W{l} (in, out), b{l} (out,) for l = 0, 1, 2."""
    sizes = [config.phase_dim, config.gating_hidden, config.gating_hidden, config.n_experts]
    shapes = {}
    for l in range(3):
        shapes[f"W{l}"] = (sizes[l], sizes[l + 1])
        shapes[f"b{l}"] = (sizes[l + 1],)
    return shapes


class GatingNetwork:
    """Ω: phases (B, phase_dim) -> α (B, K). Parameters W0 b0 W1 b1 W2 b2 in one flat buffer."""

    def __init__(self, config: ModelConfig, rng: np.random.Generator, dtype=np.float32):
        self.config = config
        sizes = [config.phase_dim, config.gating_hidden, config.gating_hidden, config.n_experts]
        shapes = gating_shapes(config)
        self.params = Parameters(shapes, dtype=dtype)
        init_dense_stack(self.params, sizes, rng, dtype)
        self.used_masks: dict = {}
        self._caches = None

    def forward(self, p, train=False, rng=None, masks=None):
        """p (B, phase_dim) -> α (B, K); rows of α sum to 1."""
        P, q, self.used_masks = self.params.params, self.config.dropout, {}
        caches = []
        h = p
        for l in range(3):
            h, c_drop = dropout_site(h, q, f"gating{l}", train, rng, masks, self.used_masks)
            h, c_lin = F.linear_forward(h, P[f"W{l}"], P[f"b{l}"])
            if l < 2:
                h, c_act = F.elu_forward(h)
            else:
                h, c_act = F.softmax_forward(h)
            caches.append((c_drop, c_lin, c_act))
        self._caches = caches
        return h

    def backward(self, dalpha):
        """dalpha (B, K) -> dp (B, phase_dim); adds parameter gradients into .params.grads."""
        if self._caches is None:
            raise RuntimeError("GatingNetwork.backward called before forward")
        G = self.params.grads
        dh = dalpha
        for l in reversed(range(3)):
            c_drop, c_lin, c_act = self._caches[l]
            dh = F.softmax_backward(dh, c_act) if l == 2 else F.elu_backward(dh, c_act)
            dh, dW, db = F.linear_backward(dh, c_lin)
            G[f"W{l}"] += dW
            G[f"b{l}"] += db
            dh = dropout_site_backward(dh, c_drop)
        return dh
