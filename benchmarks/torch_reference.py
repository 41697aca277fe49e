"""The same style model written with torch.nn, for side-by-side timing (benchmarks only).

PyTorch is NOT a dependency of minifilm: only the benchmark scripts import this file, and
``load_torch()`` returns None when torch is not installed, so they skip the PyTorch column.

The PyTorch model computes exactly what minifilm.model.style_model.StyleModel computes (``from_numpy``
copies a NumPy model's weights, and the benchmarks print the largest difference of outputs
and gradients as a check):

    Ω  p -> dropout -> Linear(8, 32) -> ELU -> dropout -> Linear(32, 32) -> ELU -> dropout
         -> Linear(32, K) -> softmax = α
    Φ  3 gated-expert layers 348 -> 512 -> 512 -> 342, K = 8; after each hidden layer the layer
       norm of the original ((h - μ) / (σ_unbiased + 1e-6), no affine), FiLM and ELU;
       dropout before every layer
    Ψ  Conv1d(300, 256, 25, 'same') -> ReLU -> MaxPool(2) -> Conv1d(256, 256, 25) -> ReLU
       -> MaxPool(2) -> flatten -> Linear(15360, 2048) -> ReLU -> dropout -> Linear(2048, 2048)

Choices that favour PyTorch, so the comparison is not flattering to NumPy:
  * the gated experts use the same fast formulation as minifilm (one matmul on the (B, K*I)
    outer product), which is faster in PyTorch too than building per-sample weights;
  * Ψ takes its clip channels-first (B, C, T), PyTorch's native Conv1d layout, prepared once
    outside the timed step; the flatten order difference is absorbed into the copied weights;
  * inference runs under ``torch.inference_mode()``.
"""
from __future__ import annotations

import numpy as np


def load_torch(threads: int):
    """Import torch with ``threads`` intra-op threads; None if torch is not installed."""
    try:
        import torch
    except ImportError:
        return None
    torch.set_num_threads(threads)
    return torch


def build(torch):
    """Define the module classes (torch is imported lazily, so this is a factory)."""
    nn = torch.nn
    Fn = torch.nn.functional

    class Gating(nn.Module):
        def __init__(self, cfg):
            super().__init__()
            sizes = [cfg.phase_dim, cfg.gating_hidden, cfg.gating_hidden, cfg.n_experts]
            self.layers = nn.ModuleList(nn.Linear(sizes[i], sizes[i + 1]) for i in range(3))
            self.drop = nn.Dropout(cfg.dropout)

        def forward(self, p):
            h = p
            for i, layer in enumerate(self.layers):
                h = layer(self.drop(h))
                h = Fn.elu(h) if i < 2 else torch.softmax(h, dim=-1)
            return h

    class Experts(nn.Module):
        """K expert linear layers blended per sample: y = (α ⊗ x) @ W.reshape(K*I, O) + α @ b."""

        def __init__(self, K, I, O):
            super().__init__()
            self.K, self.I, self.O = K, I, O
            self.W = nn.Parameter(torch.empty(K, I, O))
            self.b = nn.Parameter(torch.empty(K, O))

        def forward(self, x, alpha):
            Z = (alpha[:, :, None] * x[:, None, :]).reshape(x.shape[0], self.K * self.I)
            return Z @ self.W.reshape(self.K * self.I, self.O) + alpha @ self.b

    class Motion(nn.Module):
        def __init__(self, cfg):
            super().__init__()
            sizes = [cfg.x_dim, cfg.hidden, cfg.hidden, cfg.z_dim]
            self.layers = nn.ModuleList(Experts(cfg.n_experts, sizes[i], sizes[i + 1]) for i in range(3))
            self.drop = nn.Dropout(cfg.dropout)
            self.H, self.eps = cfg.hidden, cfg.ln_eps

        def forward(self, x, alpha, film):
            H = self.H
            h = x
            for i, layer in enumerate(self.layers):
                h = layer(self.drop(h), alpha)
                if i < 2:
                    gamma, beta = film[:, 2 * i * H:(2 * i + 1) * H], film[:, (2 * i + 1) * H:(2 * i + 2) * H]
                    h = (h - h.mean(-1, keepdim=True)) / (h.std(-1, keepdim=True) + self.eps)
                    h = Fn.elu(gamma * h + beta)
            return h

    class Film(nn.Module):
        def __init__(self, cfg):
            super().__init__()
            k = cfg.conv_kernel
            self.conv0 = nn.Conv1d(cfg.clip_channels, cfg.conv_filters, k, padding=k // 2)
            self.conv1 = nn.Conv1d(cfg.conv_filters, cfg.conv_filters, k, padding=k // 2)
            self.dense0 = nn.Linear(cfg.flat_dim, cfg.film_dense)
            self.dense1 = nn.Linear(cfg.film_dense, cfg.film_dim)
            self.drop = nn.Dropout(cfg.dropout)

        def forward(self, clip_bct):
            h = Fn.max_pool1d(torch.relu(self.conv0(clip_bct)), 2)
            h = Fn.max_pool1d(torch.relu(self.conv1(h)), 2)
            h = self.drop(torch.relu(self.dense0(h.flatten(1))))
            return self.dense1(h)

    class StyleModel(nn.Module):
        def __init__(self, cfg, with_film_generator=True):
            super().__init__()
            self.gating = Gating(cfg)
            self.motion = Motion(cfg)
            self.film = Film(cfg) if with_film_generator else None

        def forward_with_film(self, x, p, film):
            return self.motion(x, self.gating(p), film)

        def forward(self, x, p, clip_bct):
            return self.forward_with_film(x, p, self.film(clip_bct))

    return StyleModel


def from_numpy(torch, np_model):
    """A torch StyleModel holding a copy of ``np_model``'s weights (float32)."""
    cfg = np_model.config
    model = build(torch)(cfg, with_film_generator=np_model.film is not None)
    t = lambda a: torch.from_numpy(np.ascontiguousarray(a, dtype=np.float32))  # noqa: E731
    with torch.no_grad():
        G = np_model.gating.params.params
        for i, layer in enumerate(model.gating.layers):
            layer.weight.copy_(t(G[f"W{i}"].T))          # torch Linear stores (out, in)
            layer.bias.copy_(t(G[f"b{i}"]))
        M = np_model.motion.params.params
        for i, layer in enumerate(model.motion.layers):
            layer.W.copy_(t(M[f"W{i}"]))                # both (K, in, out)
            layer.b.copy_(t(M[f"b{i}"]))
        if model.film is not None:
            P = np_model.film.params.params
            model.film.conv0.weight.copy_(t(P["conv0_W"].transpose(2, 1, 0)))   # (k,C,F) -> (F,C,k)
            model.film.conv0.bias.copy_(t(P["conv0_b"]))
            model.film.conv1.weight.copy_(t(P["conv1_W"].transpose(2, 1, 0)))
            model.film.conv1.bias.copy_(t(P["conv1_b"]))
            # minifilm flattens (T', F) time-major, torch flattens (F, T') filter-major
            Tq, Fc = cfg.pooled_frames, cfg.conv_filters
            W0 = P["dense0_W"].reshape(Tq, Fc, -1).transpose(1, 0, 2).reshape(Tq * Fc, -1)
            model.film.dense0.weight.copy_(t(W0.T))
            model.film.dense0.bias.copy_(t(P["dense0_b"]))
            model.film.dense1.weight.copy_(t(P["dense1_W"].T))
            model.film.dense1.bias.copy_(t(P["dense1_b"]))
    return model
