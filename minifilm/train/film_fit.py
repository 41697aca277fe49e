"""Fit one style's FiLM vector through a frozen Ω and Φ (a network shipped without Ψ).

The released network has no FiLM generator: a style is nothing but its 2,048 numbers
{γ1, β1, γ2, β2} (Eq. 2). A new style is then taught by fitting those numbers directly, with
Ω and Φ frozen, so that Φ(x; Ω(p), film) predicts the clip's next frames (Eq. 4):

    film = μ + U (s ∘ c) + τ r                                          the parametrisation
    loss = mean_rows,outputs (z_pred − z)^2 + λ (|c|^2 + |r|^2) / D       data term + prior

μ, U, s: mean, principal directions and their standard deviations of the known styles' vectors
(a Gaussian prior N(μ, U S² Uᵀ + τ² I) written in whitened coordinates c, r), D = 4H. The
prior keeps the fit near the styles the network was trained with: 2,048 free numbers fitted
teacher-forced to a few thousand rows overfit (a lower loss than the true vector, rollouts
that stop stepping). τ lets the fit leave the known styles' span (a held-out style lies 45 %
outside the span of the other 99 released ones).

Ω(p) and Φ's first expert layer up to its layer norm do not depend on the FiLM vector, so they
are computed once for all rows (:class:`FrozenRows`); each step runs only the rest of Φ. The
backward pass chains the kit's gradient-checked pairs (minifilm.nn.functional); the whole
loss -> (c, r) gradient is checked in tests/train/test_film_fit.py.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import List, Optional

import numpy as np

from minifilm.model.motion_net import split_film
from minifilm.nn import functional as F
from minifilm.nn.optim import Adam
from minifilm.nn.params import Parameters


@dataclass
class StylePrior:
    """Gaussian prior over FiLM vectors from known styles: mean (D,), directions (k, D) orthonormal
    rows, scales (k,) standard deviation along each, tau: standard deviation off their span."""
    mean: np.ndarray
    directions: np.ndarray
    scales: np.ndarray
    tau: float

    @classmethod
    def from_vectors(cls, vectors: np.ndarray, tau: Optional[float] = None, share: float = 0.999) -> "StylePrior":
        """vectors (S, D) known styles' FiLM vectors -> prior. The directions keep ``share`` of the
        variance; tau defaults to the per-number spread the leave-one-out study measured
        (a style's distance from the others' span / sqrt(D), about 0.25 for the released net),
        estimated here as that of the last kept direction when there are few styles."""
        V = np.asarray(vectors, np.float64)
        if V.ndim != 2 or len(V) < 2:
            raise ValueError(f"StylePrior: need (S >= 2, D) style vectors, got {V.shape}")
        mu = V.mean(axis=0)
        _, s, Wt = np.linalg.svd(V - mu, full_matrices=False)
        scales = s / np.sqrt(len(V) - 1)
        k = int(np.searchsorted(np.cumsum(s ** 2) / np.sum(s ** 2), share) + 1)
        k = max(1, min(k, len(s)))
        if tau is None:
            # what is left off the span, spread over the D numbers: the held-out residual of a
            # typical style is about the size of the sum of the smallest directions
            tail = np.sqrt(np.sum(scales[k // 2:] ** 2) / V.shape[1])
            tau = float(max(tail, 1e-3 * np.sqrt(np.mean(scales[:k] ** 2))))
        return cls(mu, Wt[:k].copy(), scales[:k].copy(), float(tau))

    @property
    def dim(self) -> int:
        return len(self.mean)

    def film(self, c: np.ndarray, r: np.ndarray) -> np.ndarray:
        """Whitened coordinates c (k,), r (D,) -> FiLM vector (D,)."""
        return self.mean + (c * self.scales) @ self.directions + self.tau * r

    def coordinates(self, film: np.ndarray):
        """FiLM vector (D,) -> (c, r) with film(c, r) == film (the inverse of :meth:`film`)."""
        d = np.asarray(film, np.float64) - self.mean
        inside = d @ self.directions.T
        r = (d - inside @ self.directions) / self.tau
        return inside / self.scales, r

    def film_backward(self, dfilm: np.ndarray):
        """dL/dfilm (D,) -> dL/dc (k,), dL/dr (D,)."""
        return (self.directions @ dfilm) * self.scales, self.tau * dfilm


class FrozenRows:
    """Rows (x, p, z normalised) with everything that does not depend on the FiLM vector done once.

    x (N, x_dim), p (N, 8), z (N, z_dim), all normalised with the network's statistics; weights
    of the gating network Ω and Φ's expert stacks are read from ``model`` (a StyleModel).
    ln_unbiased / ln_eps: the layer norm's convention (the released runtime: False, 0.0).
    """

    def __init__(self, model, x, p, z, ln_unbiased: bool = False, ln_eps: float = 0.0, dtype=np.float32):
        P = model.motion.params.params
        self.dtype = np.dtype(dtype)
        self.hidden = model.config.hidden
        self.ln = (ln_unbiased, ln_eps)
        self.W1, self.b1 = P["W1"].astype(dtype), P["b1"].astype(dtype)
        self.W2, self.b2 = P["W2"].astype(dtype), P["b2"].astype(dtype)
        x, p, self.z = (np.asarray(a, dtype) for a in (x, p, z))
        self.alpha = model.gating.forward(p.astype(model.dtype)).astype(dtype)        # Ω(p), (N, K)
        f1, _ = F.expert_linear_forward(x, self.alpha, P["W0"].astype(dtype), P["b0"].astype(dtype))
        self.n1, _ = F.layer_norm_forward(f1, unbiased=ln_unbiased, eps=ln_eps)      # (N, H)

    def __len__(self) -> int:
        return len(self.z)

    def predict(self, film: np.ndarray, rows=None) -> np.ndarray:
        """z of the rows (all or the index array ``rows``) under one FiLM vector (4H,)."""
        return self._forward(film, rows)[0]

    def _forward(self, film, rows):
        sel = slice(None) if rows is None else rows
        (g1, b1), (g2, b2) = split_film(np.asarray(film, self.dtype), self.hidden)
        alpha = self.alpha[sel]
        m1, c_film1 = F.film_forward(self.n1[sel], g1, b1)
        h1, c_elu1 = F.elu_forward(m1)
        f2, c_exp2 = F.expert_linear_forward(h1, alpha, self.W1, self.b1)
        n2, c_norm2 = F.layer_norm_forward(f2, unbiased=self.ln[0], eps=self.ln[1])
        m2, c_film2 = F.film_forward(n2, g2, b2)
        h2, c_elu2 = F.elu_forward(m2)
        z, c_exp3 = F.expert_linear_forward(h2, alpha, self.W2, self.b2)
        return z, (c_film1, c_elu1, c_exp2, c_norm2, c_film2, c_elu2, c_exp3)

    def loss(self, film: np.ndarray, rows=None) -> float:
        """Mean squared error over the rows' normalised outputs."""
        z = self.z if rows is None else self.z[rows]
        return float(np.mean((self.predict(film, rows) - z) ** 2, dtype=np.float64))

    def loss_and_grad(self, film: np.ndarray, rows=None):
        """(mean squared error, dL/dfilm (4H,)) over the rows (all, or the index array ``rows``)."""
        z_true = self.z if rows is None else self.z[rows]
        z, (c_film1, c_elu1, c_exp2, c_norm2, c_film2, c_elu2, c_exp3) = self._forward(film, rows)
        diff = z - z_true
        loss = float(np.mean(diff.astype(np.float64) ** 2))
        dz = (2.0 / diff.size) * diff
        # the kit's pairs in reverse; only the FiLM gradients are wanted (expert weights frozen)
        dh2 = F.expert_linear_backward(dz, c_exp3, weights=False)[0]
        dn2, dg2, db2 = F.film_backward(F.elu_backward(dh2, c_elu2), c_film2)
        dh1 = F.expert_linear_backward(F.layer_norm_backward(dn2, c_norm2), c_exp2, weights=False)[0]
        _, dg1, db1 = F.film_backward(F.elu_backward(dh1, c_elu1), c_film1)
        return loss, np.concatenate([dg1, db1, dg2, db2]).astype(np.float64)


@dataclass
class FitSettings:
    """steps: Adam steps at most; batch: rows per step; lr: Adam's step on the whitened
    coordinates; prior_weight: λ; holdout: share of the rows (the clip's last part) kept out to
    stop early; patience: evaluations without a better held-out loss before stopping; every:
    steps between evaluations; seed."""
    steps: int = 300
    batch: int = 256
    lr: float = 0.05
    prior_weight: float = 1.0
    holdout: float = 0.2
    patience: int = 4
    every: int = 20
    seed: int = 0


@dataclass
class FitResult:
    film: np.ndarray                  # (D,) the chosen vector (best held-out loss)
    start_loss: float                 # loss of all rows at the start vector
    loss: float                       # ... at the chosen vector
    holdout_loss: float               # held-out rows at the chosen vector
    steps: int                        # steps run (early stopping may end it sooner)
    best_step: int
    history: List[tuple] = field(default_factory=list)   # (step, train-batch loss, held-out loss)
    snapshots: List[np.ndarray] = field(default_factory=list)   # vectors at each evaluation


def prior_loss_and_grad(prior_weight: float, c: np.ndarray, r: np.ndarray, D: int):
    """λ (|c|² + |r|²) / D and its gradients with respect to c and r."""
    w = prior_weight / D
    return w * float(c @ c + r @ r), 2 * w * c, 2 * w * r


def fit_film(rows: FrozenRows, prior: StylePrior, start: Optional[np.ndarray] = None,
             settings: FitSettings = FitSettings()) -> FitResult:
    """Fit a FiLM vector to ``rows`` under ``prior`` (module docstring), from ``start`` (default:
    the prior's mean), Adam on (c, r), minibatches from the first 1 − holdout of the rows, stopped
    when the held-out rows' loss has not improved for ``patience`` evaluations."""
    s = settings
    rng = np.random.default_rng(s.seed)
    n = len(rows)
    n_hold = int(round(s.holdout * n)) if n >= 10 else 0
    train_rows, hold_rows = np.arange(n - n_hold), np.arange(n - n_hold, n)
    if n_hold == 0:
        hold_rows = train_rows
    k, D = len(prior.scales), prior.dim
    params = Parameters({"c": (k,), "r": (D,)}, dtype=np.float64)
    c0, r0 = prior.coordinates(prior.mean if start is None else start)
    params.params["c"][...], params.params["r"][...] = c0, r0
    opt = Adam([params], lr=s.lr)
    film = prior.film(c0, r0)
    best = (rows.loss(film, hold_rows), 0, film)
    start_loss = rows.loss(film)
    history, snapshots, since_best, step = [(0, float("nan"), best[0])], [film], 0, 0
    for step in range(1, s.steps + 1):
        batch = rng.choice(train_rows, size=min(s.batch, len(train_rows)), replace=False)
        c, r = params.params["c"], params.params["r"]
        film = prior.film(c, r)
        loss, dfilm = rows.loss_and_grad(film, batch)
        _, dc_p, dr_p = prior_loss_and_grad(s.prior_weight, c, r, D)
        dc, dr = prior.film_backward(dfilm)
        params.zero_grad()
        params.grads["c"][...], params.grads["r"][...] = dc + dc_p, dr + dr_p
        opt.step()
        if step % s.every == 0 or step == s.steps:
            film = prior.film(params.params["c"], params.params["r"])
            held = rows.loss(film, hold_rows)
            history.append((step, loss, held))
            snapshots.append(film)
            if held < best[0]:
                best, since_best = (held, step, film), 0
            else:
                since_best += 1
                if since_best >= s.patience:
                    break
    return FitResult(best[2], start_loss, rows.loss(best[2]), best[0], step, best[1], history, snapshots)
