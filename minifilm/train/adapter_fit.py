"""Fit one style's adapter (minifilm/model/adapters.py) through the frozen Ω and Φ, with replay.

The style's FiLM vector is fitted first (film_fit.py); where no FiLM vector reaches the clip, the
adapter gives the style capacity of its own. Ω, Φ's experts and every FiLM vector stay frozen; the
adapter's arrays are fitted, teacher-forced, so that Φ predicts the clip's next frames:

    loss = mean over a minibatch of |Φ_adapted(x̂; Ω(p), film_row, s = 1) − ẑ|²     (normalised)
    minibatch = (1 − ρ) B rows of the clip, under the new style's vector
              +      ρ B *replay* rows: states the unmodified network visits walking in its own
                     styles, under their vectors, whose targets are what Φ without the adapter predicts

The replay is prior preservation (as LoRA-MDM and SMooDi keep a model's other motion while it
learns one new style): the adapter must leave the network's own motion as it was even while it is
on, so it learns what is particular to the clip, not a change of all motion. That matters where
the adapter is on beside another style (a blend, a switch) and in the new style's own walk, which
visits states the clip does not hold. The clip's last ``holdout`` share is kept out to stop early.

Ω(p) and the first expert layer's output before any adapter do not change, so they are computed
once for all rows (:class:`AdapterRows`). The backward pass chains the gradient-checked pairs;
the whole loss -> adapter gradient is checked in minifilm/evaluation/gradcheck_adapters.py.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import List, Optional

import numpy as np

from minifilm.model.adapters import (StyleAdapter, lowrank_experts_backward, lowrank_experts_forward,
                                     residual_adapter_backward, residual_adapter_forward)
from minifilm.model.motion_net import split_film
from minifilm.nn import functional as F
from minifilm.nn.optim import Adam


@dataclass
class FrozenPhi:
    """Φ's expert layers [(W (K, I, O), b (K, O))] * 3, frozen, and its layer norm's convention
    (the released runtime's: biased σ, no ε)."""
    experts: list
    ln_unbiased: bool = False
    ln_eps: float = 0.0

    @classmethod
    def of(cls, model, dtype=np.float32, ln_unbiased: bool = False, ln_eps: float = 0.0) -> "FrozenPhi":
        P = model.motion.params.params
        return cls([(P[f"W{l}"].astype(dtype), P[f"b{l}"].astype(dtype)) for l in range(3)], ln_unbiased, ln_eps)

    @property
    def sizes(self) -> list:
        return [self.experts[0][0].shape[1]] + [W.shape[2] for W, _ in self.experts]

    @property
    def n_experts(self) -> int:
        return self.experts[0][0].shape[0]


@dataclass
class AdapterRows:
    """Rows with what does not depend on the adapter done once: x̂ (N, x_dim) normalised inputs,
    α (N, K) = Ω(p̂), f0 (N, H) the first expert layer's output, ẑ (N, z_dim) normalised targets,
    style (N,) each row's index into the table of FiLM vectors it is fitted under."""
    x: np.ndarray
    alpha: np.ndarray
    f0: np.ndarray
    z: np.ndarray
    style: np.ndarray

    @classmethod
    def make(cls, model, phi: FrozenPhi, x, p, z, style) -> "AdapterRows":
        """From normalised x, p, z rows of a StyleModel's Ω and Φ."""
        dtype = phi.experts[0][0].dtype
        x = np.asarray(x, dtype)
        alpha = model.gating.forward(np.asarray(p, model.dtype)).astype(dtype)
        f0 = F.expert_linear_forward(x, alpha, *phi.experts[0])[0]
        style = np.broadcast_to(np.asarray(style, np.int64), (len(x),)).copy()
        return cls(x, alpha, f0, np.asarray(z, dtype), style)

    def __len__(self) -> int:
        return len(self.z)

    def take(self, index) -> "AdapterRows":
        return AdapterRows(self.x[index], self.alpha[index], self.f0[index], self.z[index], self.style[index])

    @staticmethod
    def join(parts) -> "AdapterRows":
        return AdapterRows(*(np.concatenate([getattr(p, k) for p in parts]) for k in ("x", "alpha", "f0", "z", "style")))


def adapted_phi_forward(rows: AdapterRows, films: np.ndarray, phi: FrozenPhi, adapter: StyleAdapter,
                        share: np.ndarray):
    """Φ with ``adapter`` at ``share`` (B,) on ``rows`` (B of them), each under films[rows.style]
    -> ẑ (B, z_dim), caches. The layers of Eq. (3) with the adapter's changes where
    minifilm/runtime/network.py applies them."""
    A, H = adapter.params.params, phi.sizes[1]
    film = films[rows.style]                                            # (B, 4H)
    low, res = adapter.kind == "lowrank", adapter.kind == "residual"
    h, f, caches = rows.x, rows.f0, []
    for l in range(3):
        c = {}
        if l > 0:
            f, c["experts"] = F.expert_linear_forward(h, rows.alpha, *phi.experts[l])
        if low:
            d, c["low"] = lowrank_experts_forward(h, rows.alpha, A[f"P{l}"], A[f"Q{l}"], share)
            f = f + d
        if l < 2:
            gamma, beta = split_film(film, H)[l]
            n, c["norm"] = F.layer_norm_forward(f, unbiased=phi.ln_unbiased, eps=phi.ln_eps)
            m, c["film"] = F.film_forward(n, gamma, beta)
            h, c["elu"] = F.elu_forward(m)
            if res:
                h, c["res"] = residual_adapter_forward(h, A[f"A{l}"], A[f"a{l}"], share)
        caches.append(c)
    return f, caches


def adapted_phi_backward(dz: np.ndarray, caches, adapter: StyleAdapter) -> None:
    """Adds the gradients of the adapter's arrays (``adapter.params.grads``) for dL/dẑ (B, z_dim);
    the frozen layers pass the gradient through (no gradient of their weights is formed)."""
    G = adapter.params.grads
    df = dz
    for l in (2, 1, 0):
        c = caches[l]
        if l < 2:                       # back through hidden layer l (ELU, FiLM, layer norm)
            dh = df
            if "res" in c:
                dh, dA, da, _ = residual_adapter_backward(dh, c["res"])
                G[f"A{l}"] += dA
                G[f"a{l}"] += da
            dn = F.film_backward(F.elu_backward(dh, c["elu"]), c["film"])[0]
            df = F.layer_norm_backward(dn, c["norm"])
        dx = None
        if "low" in c:
            dx, _, dP, dQ, _ = lowrank_experts_backward(df, c["low"])
            G[f"P{l}"] += dP
            G[f"Q{l}"] += dQ
        if l > 0:                       # to the layer's input, the hidden layer below
            dh = F.expert_linear_backward(df, c["experts"], weights=False)[0]
            df = dh if dx is None else dh + dx


@dataclass
class AdapterSettings:
    """kind: 'residual' or 'lowrank'; rank: of the low-rank updates; steps: Adam steps at most;
    batch: rows per step; replay: the share ρ of each minibatch replaying the network's own motion;
    noise: σ of the Gaussian noise added to the clip rows' normalised inputs (their targets kept),
    in ``copies`` noisy copies of every row drawn once (0: the rows as they are); lr: Adam's step; decay: L2 pull of the arrays towards 0 (the identity); holdout: the clip's last
    share kept out to stop early; every / patience: steps between evaluations, evaluations
    without a better held-out loss before stopping; seed."""
    kind: str = "lowrank"
    rank: int = 8
    steps: int = 300
    batch: int = 256
    replay: float = 0.25
    noise: float = 0.3
    copies: int = 4
    lr: float = 1e-3
    decay: float = 0.0
    holdout: float = 0.2
    every: int = 25
    patience: int = 4
    seed: int = 0


@dataclass
class AdapterFit:
    adapter: StyleAdapter
    start_loss: float                 # held-out clip rows, the adapter off (the FiLM vector alone)
    holdout_loss: float               # ... with the adapter kept
    replay_start: float               # replay rows' loss, the adapter off (0: the network's own targets)
    replay_loss: float                # ... with the adapter on
    steps: int
    best_step: int
    history: List[tuple] = field(default_factory=list)   # (step, minibatch loss, held-out, replay)


def noisy_copies(rows: AdapterRows, phi: FrozenPhi, sigma: float, copies: int, rng) -> AdapterRows:
    """``copies`` copies of ``rows`` with N(0, σ²) added to every normalised input number, the
    targets unchanged: states a little off the clip, each with the clip's next frame as its answer.

    PAPER: not in the paper, which trains on the data's own rows. A walk the network generates
    reads back its own slightly wrong poses, phases and a trajectory blended with the user's
    command; teacher-forced on the clip alone, the adapter has only seen the clip's exact states
    and the walk drifts back to the network's own styles (exposure bias). Rows nudged off the
    clip and told to come back teach it to return (as DAgger's corrections do, without rollouts)."""
    parts = []
    for _ in range(copies):
        x = rows.x + (sigma * rng.standard_normal(rows.x.shape)).astype(rows.x.dtype)
        parts.append(AdapterRows(x, rows.alpha, F.expert_linear_forward(x, rows.alpha, *phi.experts[0])[0],
                                 rows.z, rows.style))
    return AdapterRows.join(parts)


def rows_loss(rows: AdapterRows, films, phi, adapter, share: float = 1.0, chunk: int = 2048) -> float:
    """Mean squared error of Φ with ``adapter`` at ``share`` over all ``rows``."""
    total, n = 0.0, 0
    for a in range(0, len(rows), chunk):
        part = rows.take(slice(a, a + chunk))
        z, _ = adapted_phi_forward(part, films, phi, adapter, np.full(len(part), share, part.z.dtype))
        total += float(np.sum((z - part.z).astype(np.float64) ** 2))
        n += part.z.size
    return total / max(n, 1)


def fit_adapter(phi: FrozenPhi, clip: AdapterRows, films: np.ndarray, replay: Optional[AdapterRows] = None,
                settings: AdapterSettings = AdapterSettings()) -> AdapterFit:
    """Fit an adapter of ``settings.kind`` on ``clip`` (module docstring), with ``replay`` rows making
    up ``settings.replay`` of every minibatch (None or a share of 0: no replay); the arrays of the
    evaluation with the lowest held-out loss are kept."""
    s = settings
    rng = np.random.default_rng(s.seed)
    dtype = clip.z.dtype
    adapter = StyleAdapter(s.kind, phi.sizes, phi.n_experts, s.rank, dtype=dtype, rng=rng)
    n = len(clip)
    n_hold = int(round(s.holdout * n)) if n >= 10 else 0
    train, hold = clip.take(slice(0, n - n_hold)), clip.take(slice(n - n_hold, n) if n_hold else slice(0, n))
    if s.noise > 0:
        train = noisy_copies(train, phi, s.noise, s.copies, rng)
    have_replay = replay is not None and len(replay) > 0
    n_replay = int(round(s.replay * s.batch)) if have_replay else 0
    n_clip = s.batch - n_replay
    # replay rows to measure the drift of the network's own motion on, also when none is trained on
    check = replay.take(rng.choice(len(replay), min(len(replay), 1024), replace=False)) if have_replay else None
    off = StyleAdapter(s.kind, phi.sizes, phi.n_experts, s.rank, dtype=dtype)    # all zero: Φ as it is
    start = rows_loss(hold, films, phi, off)
    replay_start = rows_loss(check, films, phi, off) if have_replay else 0.0
    opt = Adam([adapter.params], lr=s.lr)
    best = (start, 0, adapter.params.data.copy(), replay_start)
    history, since_best, step = [(0, float("nan"), start, replay_start)], 0, 0
    ones = np.ones(s.batch, dtype)
    for step in range(1, s.steps + 1):
        parts = [train.take(rng.choice(len(train), n_clip, replace=n_clip > len(train)))]
        if n_replay:
            parts.append(replay.take(rng.integers(0, len(replay), n_replay)))
        batch = AdapterRows.join(parts)
        z, caches = adapted_phi_forward(batch, films, phi, adapter, ones[:len(batch)])
        diff = z - batch.z
        loss = float(np.mean(diff.astype(np.float64) ** 2))
        adapter.params.zero_grad()
        adapted_phi_backward((2.0 / diff.size) * diff, caches, adapter)
        if s.decay:
            adapter.params.grad += s.decay * adapter.params.data
        opt.step()
        if step % s.every == 0 or step == s.steps:
            held = rows_loss(hold, films, phi, adapter)
            rep = rows_loss(check, films, phi, adapter) if have_replay else 0.0
            history.append((step, loss, held, rep))
            if held < best[0]:
                best, since_best = (held, step, adapter.params.data.copy(), rep), 0
            else:
                since_best += 1
                if since_best >= s.patience:
                    break
    adapter.params.data[...] = best[2]
    return AdapterFit(adapter, start, best[0], replay_start, best[3], step, best[1], history)
