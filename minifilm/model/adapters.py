"""A style's own capacity in Φ: per-style adapters beside its FiLM vector.

PAPER: the paper teaches a style through Ψ and FiLM alone (Sec. 4.4, 5.3.2); its comparison
(Sec. 5, "Resad", after Mason et al. 2018) gives each style a residual adapter instead. Here an
adapter is added to a style taught from a clip that lies outside what FiLM vectors of the network
reach (docs/teaching-released.md), and it acts only on the rows whose style mix holds that style:
every row carries a share s in [0, 1], the style's weight in the mix of the moment, and s = 0 is
Φ exactly as it is. Two kinds:

residual   after the ELU of hidden layer i of Eq. (3), i = 1, 2:
               h(i) <- h(i) + s (h(i) A_i + a_i)            A_i (H, H), a_i (H,), zero at the start
           (the comparison's LPN Resad, minifilm/baselines/style_modulation.py, on both layers)
lowrank    inside every gated-expert layer l = 0, 1, 2 (LoRA, Hu et al. 2021, one update per expert):
               F(l) <- F(l) + s Σ_k α_k (h(l-1) P_lk) Q_lk   P_lk (I, r), Q_lk (r, O), r = 4-8
           P Glorot-uniform, Q zero at the start, so the update starts at zero and P gets a
           gradient from the first step. Σ_k α_k P_lk Q_lk is a change of the blended expert
           weight of rank at most K r, different at every phase, as the experts are.

Both start as the identity. The pairs below are the layers (forward, hand-written backward,
gradient-checked in minifilm/evaluation/gradcheck_adapters.py); :class:`StyleAdapter` holds one
style's arrays and is what the runtime network applies (minifilm/runtime/adapted.py).
Shapes: x, h (B, I); α (B, K); s (B,); experts W (K, I, O).
"""
from __future__ import annotations

from typing import Dict

import numpy as np

from minifilm.model.init import glorot_uniform
from minifilm.nn.checks import require, require_grad_shape
from minifilm.nn.params import Parameters

KINDS = ("residual", "lowrank")
RANKS = (1, 64)                    # the low-rank update's rank may be set in this range


# ---- residual adapter: h + s (h A + a) ----------------------------------------------------------
def residual_adapter_forward(h: np.ndarray, A: np.ndarray, a: np.ndarray, share: np.ndarray):
    """h (B, H), A (H, H), a (H,), share (B,) -> h + s (h A + a) (B, H)."""
    require(A.shape == (h.shape[1],) * 2 and a.shape == (h.shape[1],) and share.shape == (h.shape[0],),
            f"residual_adapter_forward: h {h.shape}, A {A.shape}, a {a.shape}, share {share.shape}")
    change = h @ A + a                                          # (B, H)
    return h + share[:, None] * change, (h, A, share, change)


def residual_adapter_backward(dout: np.ndarray, cache):
    """-> dh (B, H), dA (H, H), da (H,), dshare (B,)."""
    h, A, share, change = cache
    require_grad_shape("residual_adapter_backward", dout, h.shape)
    ds = share[:, None] * dout                                  # gradient reaching the change
    return dout + ds @ A.T, h.T @ ds, ds.sum(axis=0), np.sum(dout * change, axis=1)


# ---- low-rank expert update: s Σ_k α_k (x P_k) Q_k ----------------------------------------------
def lowrank_experts_forward(x: np.ndarray, alpha: np.ndarray, P: np.ndarray, Q: np.ndarray, share: np.ndarray):
    """The change of a gated-expert layer's output: x (B, I), α (B, K), P (K, I, r), Q (K, r, O),
    share (B,) -> s Σ_k α_k (x P_k) Q_k (B, O). As the experts' fast form (nn/functional.py), one
    product per factor: T = x [P_1 .. P_K] (B, K, r), then (α ∘ T) flattened times Q (K r, O)."""
    K, I, r = P.shape
    require(x.ndim == 2 and x.shape[1] == I and alpha.shape == (x.shape[0], K) and Q.shape[:2] == (K, r)
            and share.shape == (x.shape[0],),
            f"lowrank_experts_forward: x {x.shape}, alpha {alpha.shape}, P {P.shape}, Q {Q.shape}, share {share.shape}")
    B = x.shape[0]
    T = (x @ P.transpose(1, 0, 2).reshape(I, K * r)).reshape(B, K, r)      # x P_k for every k
    U = (alpha[:, :, None] * T).reshape(B, K * r)                           # α_k x P_k
    inner = U @ Q.reshape(K * r, -1)                                        # Σ_k α_k x P_k Q_k
    return share[:, None] * inner, (x, alpha, P, Q, share, T, U, inner)


def lowrank_experts_backward(dout: np.ndarray, cache):
    """-> dx (B, I), dα (B, K), dP (K, I, r), dQ (K, r, O), dshare (B,)."""
    x, alpha, P, Q, share, T, U, inner = cache
    K, I, r = P.shape
    require_grad_shape("lowrank_experts_backward", dout, inner.shape)
    B = x.shape[0]
    dshare = np.sum(dout * inner, axis=1)
    dinner = share[:, None] * dout                                          # (B, O)
    dQ = (U.T @ dinner).reshape(Q.shape)
    dU = (dinner @ Q.reshape(K * r, -1).T).reshape(B, K, r)
    dalpha = np.sum(dU * T, axis=2)
    dT = (alpha[:, :, None] * dU).reshape(B, K * r)
    dP = (x.T @ dT).reshape(I, K, r).transpose(1, 0, 2)
    dx = dT @ P.transpose(1, 0, 2).reshape(I, K * r).T
    return dx, dalpha, dP, dQ, dshare


# ---- one style's adapter ------------------------------------------------------------------------
def adapter_shapes(kind: str, sizes, n_experts: int, rank: int = 0) -> Dict[str, tuple]:
    """The arrays of one adapter of Φ with layer sizes ``sizes`` = [x_dim, H, H, z_dim]:
    residual: A0, A1 (H, H), a0, a1 (H,); lowrank: P{l} (K, in, r), Q{l} (K, r, out), l = 0, 1, 2."""
    if kind == "residual":
        H = sizes[1]
        return {"A0": (H, H), "a0": (H,), "A1": (H, H), "a1": (H,)}
    if kind == "lowrank":
        require(RANKS[0] <= rank <= RANKS[1], f"adapter_shapes: rank {rank} outside {RANKS[0]}-{RANKS[1]}")
        shapes = {}
        for l in range(3):
            shapes[f"P{l}"] = (n_experts, sizes[l], rank)
            shapes[f"Q{l}"] = (n_experts, rank, sizes[l + 1])
        return shapes
    raise ValueError(f"adapter kind {kind!r}: expected one of {', '.join(KINDS)}")


class StyleAdapter:
    """One style's adapter: ``kind`` ('residual' or 'lowrank'), ``rank`` (lowrank; 0 for residual),
    Φ's layer sizes [x_dim, H, H, z_dim] and expert count, its arrays in one Parameters buffer."""

    def __init__(self, kind: str, sizes, n_experts: int, rank: int = 0, dtype=np.float32,
                 rng: np.random.Generator = None):
        self.kind, self.rank = kind, int(rank) if kind == "lowrank" else 0
        self.sizes, self.n_experts = [int(n) for n in sizes], int(n_experts)
        self.params = Parameters(adapter_shapes(kind, self.sizes, self.n_experts, self.rank), dtype=dtype)
        if kind == "lowrank" and rng is not None:
            for l in range(3):
                P = self.params.params[f"P{l}"]
                P[...] = glorot_uniform(rng, P.shape, self.sizes[l], self.rank, dtype)

    @property
    def dtype(self):
        return self.params.dtype

    def experts_change(self, layer: int, x: np.ndarray, alpha: np.ndarray, share: np.ndarray) -> np.ndarray:
        """The change of gated-expert layer ``layer``'s output (B, O) for its input x (B, I): the
        low-rank update (lowrank), else 0."""
        if self.kind != "lowrank":
            return 0.0
        p = self.params.params
        return lowrank_experts_forward(x, alpha, p[f"P{layer}"], p[f"Q{layer}"], share)[0]

    def hidden_change(self, layer: int, h: np.ndarray, share: np.ndarray) -> np.ndarray:
        """The change of hidden layer ``layer``'s output h (B, H) (after its ELU): s (h A + a)
        (residual), else 0."""
        if self.kind != "residual":
            return 0.0
        p = self.params.params
        return share[:, None] * (h @ p[f"A{layer}"] + p[f"a{layer}"])

    def astype(self, dtype) -> "StyleAdapter":
        """A copy computing in ``dtype``."""
        return StyleAdapter.from_arrays({**self.description(), "dtype": np.dtype(dtype).name}, self.to_arrays())

    def to_arrays(self) -> Dict[str, np.ndarray]:
        return {k: v.copy() for k, v in self.params.params.items()}

    def description(self) -> dict:
        """What a file needs to say to make this adapter again (minifilm/runtime/adapter_file.py)."""
        return {"kind": self.kind, "rank": self.rank, "sizes": list(self.sizes), "experts": self.n_experts,
                "dtype": self.dtype.name}

    @classmethod
    def from_arrays(cls, description: dict, arrays: Dict[str, np.ndarray]) -> "StyleAdapter":
        """The adapter :meth:`description` and :meth:`to_arrays` describe (shapes already checked)."""
        a = cls(description["kind"], description["sizes"], description["experts"], description["rank"],
                dtype=description["dtype"])
        for k, v in arrays.items():
            a.params.params[k][...] = v
        return a
