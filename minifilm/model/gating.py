"""Ω, the gating network (Sec. 4.1): local phases -> expert blend weights α.

    p (B, phase_dim) -> dropout -> dense -> ELU -> dropout -> dense -> ELU
                     -> dropout -> dense -> softmax = α (B, K)

p is the normalised local-phase vector of Eq. (1) (4 end effectors x amplitude-scaled
(sin, cos)). Weights are stored (in, out).
"""
from __future__ import annotations

import numpy as np

from minifilm.model.blocks import dense_backward, dense_forward
from minifilm.model.config import ModelConfig
from minifilm.model.dropout import Dropout
from minifilm.model.init import init_dense_stack
from minifilm.nn.params import Parameters

ACTIVATIONS = ("elu", "elu", "softmax")


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
        self.params = Parameters(gating_shapes(config), dtype=dtype)
        init_dense_stack(self.params, sizes, rng, dtype)
        self.used_masks: dict = {}
        self._caches = None

    def forward(self, p, train=False, rng=None, masks=None):
        """p (B, phase_dim) -> α (B, K); rows of α sum to 1."""
        P = self.params.params
        drop = Dropout(self.config.dropout, train, rng, masks)
        self.used_masks = drop.used
        h, self._caches = p, []
        for l, activation in enumerate(ACTIVATIONS):
            h, cache = dense_forward(h, P[f"W{l}"], P[f"b{l}"], activation, drop, f"gating{l}")
            self._caches.append(cache)
        return h

    def backward(self, dalpha):
        """dalpha (B, K) -> dp (B, phase_dim); adds parameter gradients into .params.grads."""
        if self._caches is None:
            raise RuntimeError("GatingNetwork.backward called before forward")
        G = self.params.grads
        dh = dalpha
        for l in reversed(range(3)):
            dh, dW, db = dense_backward(dh, self._caches[l])
            G[f"W{l}"] += dW
            G[f"b{l}"] += db
        return dh
