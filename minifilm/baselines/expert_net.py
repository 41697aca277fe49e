"""Φ without FiLM: the synthesis network of the one-hot and residual-adapter variants (Sec. 5).

Three blended-expert layers (experts = PFNN control points or MANN/LPN experts, blended by α):

    a(1) = Σ_k α_k (W_k x + b_k) + shift          shift: the one-hot style term (or 0)
    h(1) = ELU(a(1));  h(1) ← adapter(h(1))        adapter: residual adapter (or identity)
    h(2) = ELU(Σ_k α_k (W_k h(1) + b_k))
    z    = Σ_k α_k (W_k h(2) + b_k)

as in the PFNN / MANN (ELU, no layer norm; the LPN's layer norm exists to be modulated by FiLM,
Eq. 3). Dropout (rate config.dropout) on the input of every layer in training, with named sites
("motion0..2") so a gradient check can replay the masks. Parameters have the same names and
shapes as MotionNetwork's (motion_shapes), W{l} (K, in, out), b{l} (K, out).
"""
from __future__ import annotations

import numpy as np

from minifilm.model.blocks import expert_backward, expert_forward
from minifilm.model.config import ModelConfig
from minifilm.model.dropout import Dropout
from minifilm.model.init import init_dense_stack
from minifilm.model.motion_net import motion_shapes
from minifilm.nn import functional as F
from minifilm.nn.params import Parameters


class ExpertNetwork:
    """x (B, x_dim), α (B, K) [, shift (B, H), adapter] -> z (B, z_dim)."""

    def __init__(self, config: ModelConfig, rng: np.random.Generator, dtype=np.float32):
        self.config = config
        sizes = [config.x_dim, config.hidden, config.hidden, config.z_dim]
        shapes = motion_shapes(config)
        self.params = Parameters(shapes, dtype=dtype)
        init_dense_stack(self.params, sizes, rng, dtype)
        self.used_masks: dict = {}
        self._caches = None

    def forward(self, x, alpha, train=False, rng=None, masks=None, shift=None, adapter=None):
        """shift (B, H) is added before the first activation; adapter(h) -> h acts on h(1)."""
        P = self.params.params
        drop = Dropout(self.config.dropout, train, rng, masks)
        self.used_masks = drop.used
        self._caches = []
        h = x
        for l in range(3):
            h, c_exp = expert_forward(h, alpha, P[f"W{l}"], P[f"b{l}"], drop, f"motion{l}")
            c_act = None
            if l == 0 and shift is not None:
                h = h + shift
            if l < 2:
                h, c_act = F.elu_forward(h)
            if l == 0 and adapter is not None:
                h = adapter(h)
            self._caches.append((c_exp, c_act))
        return h

    def backward(self, dz, adapter_backward=None):
        """dz (B, z_dim) -> dx (B, x_dim), dα (B, K), dshift (B, H); parameter grads are added."""
        if self._caches is None:
            raise RuntimeError("ExpertNetwork.backward called before forward")
        G = self.params.grads
        dalpha, dshift, dh = 0.0, None, dz
        for l in reversed(range(3)):
            c_exp, c_act = self._caches[l]
            if l == 0 and adapter_backward is not None:
                dh = adapter_backward(dh)
            if l < 2:
                dh = F.elu_backward(dh, c_act)
            if l == 0:
                dshift = dh
            dh, da, dW, db = expert_backward(dh, c_exp)
            G[f"W{l}"] += dW
            G[f"b{l}"] += db
            dalpha = dalpha + da
        return dh, dalpha, dshift
