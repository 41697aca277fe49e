"""Ψ, the FiLM generator (Sec. 4.2, Eq. 2): a style clip -> {γ1, β1, γ2, β2}.

    y (B, T, C) -> conv1d(F filters, kernel k, 'same') -> ReLU -> max-pool 2     conv block
                -> conv1d(F, k)                       -> ReLU -> max-pool 2     conv block
                -> flatten (B, T//4 * F) -> dense(film_dense) -> ReLU         dense block
                -> dropout -> dense(4 * hidden) = [γ1, β1, γ2, β2]           dense block (Eq. 2)

PAPER: the paper applies dropout 0.3 "everywhere" (Sec. 4.3). Ψ's dropout sits after the hidden
dense layer only, as in the original code (its Conv1D_Dense class); the convolutions have none.
Flattening is time-major (frame, filter), like a TF reshape of (B, T, F).

Parameter count. With the paper's sizes (T 240, C 300, F 256, k 25, dense 2048, hidden 512) this
network has 1,920,256 + 1,638,656 + 31,459,328 + 4,196,352 = 39,214,592 parameters, which is what
the original code builds. The paper's Table 2 reports 35,668,530 (S.M.N.); no choice of the
architecture described in the paper gives that number, so we keep the architecture and report
39,214,592 (see tests/model/test_model_params.py).

Initialisation: Glorot-uniform weights, zero biases, except the output bias of the γ parts is 1,
so that at initialisation FiLM is close to the identity (γ ≈ 1, β ≈ 0). The original starts from
zero biases (γ ≈ 0); Eq. (2) is unchanged, only the starting point differs.
"""
from __future__ import annotations

import numpy as np

from minifilm.model.blocks import conv_block_backward, conv_block_forward, dense_backward, dense_forward
from minifilm.model.config import ModelConfig
from minifilm.model.dropout import Dropout
from minifilm.model.init import glorot_uniform
from minifilm.nn.params import Parameters


def film_shapes(config: ModelConfig) -> dict:
    """Parameter shapes of Ψ: conv weights (k, C_in, F), dense weights (in, out), biases (out,)."""
    c = config
    k, C, Fn = c.conv_kernel, c.clip_channels, c.conv_filters
    return {
        "conv0_W": (k, C, Fn), "conv0_b": (Fn,),
        "conv1_W": (k, Fn, Fn), "conv1_b": (Fn,),
        "dense0_W": (c.flat_dim, c.film_dense), "dense0_b": (c.film_dense,),
        "dense1_W": (c.film_dense, c.film_dim), "dense1_b": (c.film_dim,),
    }


class FilmGenerator:
    """Ψ: clip (B, T, C) -> FiLM parameters (B, 4*hidden)."""

    def __init__(self, config: ModelConfig, rng: np.random.Generator, dtype=np.float32):
        self.config = config
        c = config
        k, C, Fn = c.conv_kernel, c.clip_channels, c.conv_filters
        shapes = film_shapes(config)
        self.params = Parameters(shapes, dtype=dtype)
        P = self.params.params
        P["conv0_W"][...] = glorot_uniform(rng, shapes["conv0_W"], k * C, k * Fn, dtype)
        P["conv1_W"][...] = glorot_uniform(rng, shapes["conv1_W"], k * Fn, k * Fn, dtype)
        P["dense0_W"][...] = glorot_uniform(rng, shapes["dense0_W"], c.flat_dim, c.film_dense, dtype)
        P["dense1_W"][...] = glorot_uniform(rng, shapes["dense1_W"], c.film_dense, c.film_dim, dtype)
        for name in ("conv0_b", "conv1_b", "dense0_b", "dense1_b"):
            P[name][...] = 0.0
        H = c.hidden
        P["dense1_b"][0:H] = 1.0            # γ1
        P["dense1_b"][2 * H:3 * H] = 1.0    # γ2
        self.used_masks: dict = {}
        self._caches = None
        # one workspace per layer: the big im2col matrices and weight gradients are reused from
        # step to step instead of being mapped afresh (minifilm/nn/workspaces.py::scratch)
        self._work = {"conv0": {}, "conv1": {}, "dense0": {}, "dense1": {}}

    def forward(self, clip, train=False, rng=None, masks=None):
        """clip (B, T, C) -> film (B, 4*hidden)."""
        c, P, W = self.config, self.params.params, self._work
        drop = Dropout(c.dropout, train, rng, masks)
        self.used_masks = drop.used
        # Drop the previous pass's caches now, not when the new ones are complete, so that no
        # large array of the last step stays alive next to its successor.
        self._caches = None
        if clip.ndim != 3 or clip.shape[1:] != (c.clip_frames, c.clip_channels):
            raise ValueError(f"FilmGenerator: clip must be (B, {c.clip_frames}, {c.clip_channels}), "
                             f"got {clip.shape}")
        h, c0 = conv_block_forward(clip, P["conv0_W"], P["conv0_b"], W["conv0"])   # (B, T//2, F)
        h, c1 = conv_block_forward(h, P["conv1_W"], P["conv1_b"], W["conv1"])      # (B, T//4, F)
        pooled_shape = h.shape
        h = h.reshape(h.shape[0], -1)                                             # (B, T//4 * F)
        # PAPER: dropout "everywhere" (Sec. 4.3); only here, before the last layer, as the original
        h, c2 = dense_forward(h, P["dense0_W"], P["dense0_b"], "relu")           # (B, film_dense)
        film, c3 = dense_forward(h, P["dense1_W"], P["dense1_b"], None, drop, "film_dense")  # (B, 4H)
        self._caches = (c0, c1, pooled_shape, c2, c3)
        return film

    def backward(self, dfilm, need_input_grad=True):
        """dfilm (B, 4*hidden) -> dclip (B, T, C); parameter gradients are added.

        need_input_grad=False skips dclip and returns None: training never needs the gradient of
        the clip (it is data), and with the paper's sizes it costs as much as the first
        convolution's forward pass (about a quarter of a training step).
        """
        if self._caches is None:
            raise RuntimeError("FilmGenerator.backward called before forward")
        c0, c1, pooled_shape, c2, c3 = self._caches
        G, W = self.params.grads, self._work
        dh, dW, db = dense_backward(dfilm, c3, work=W["dense1"])
        G["dense1_W"] += dW
        G["dense1_b"] += db
        dh, dW, db = dense_backward(dh, c2, work=W["dense0"])
        G["dense0_W"] += dW
        G["dense0_b"] += db
        dh, dW, db = conv_block_backward(dh.reshape(pooled_shape), c1)
        G["conv1_W"] += dW
        G["conv1_b"] += db
        dclip, dW, db = conv_block_backward(dh, c0, need_dx=need_input_grad)
        G["conv0_W"] += dW
        G["conv0_b"] += db
        return dclip
