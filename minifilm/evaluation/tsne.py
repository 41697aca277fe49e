"""t-SNE in NumPy (van der Maaten & Hinton 2008), for Figure 11's embedding of FiLM parameters.

The paper draws the FiLM vectors of many clips per style in 2-D with t-SNE (Sec. 5.3.2, Figure 11).
This is the exact O(N²) algorithm, small enough to read:

1. **Affinities.** For each point i a Gaussian over the others,
   p_{j|i} = exp(−β_i d_ij²) / Σ_k exp(−β_i d_ik²), with β_i found by binary search so that the
   perplexity 2^{H(P_i)} equals the one asked for (H in bits; here in nats: H = log(perplexity)).
   Symmetrised: P = (P_{j|i} + P_{i|j}) / 2N.
2. **Embedding.** Student-t similarities q_ij = w_ij / Σ_{k≠l} w_kl with w_ij = 1 / (1 + |y_i − y_j|²);
   cost C = KL(P ‖ Q) = Σ p_ij log(p_ij / q_ij), exact gradient
   ∂C/∂y_i = 4 Σ_j (p_ij − q_ij) w_ij (y_i − y_j).
3. **Optimisation** as in the authors' reference: gradient descent with momentum (0.5, then 0.8),
   per-coordinate adaptive gains, and early exaggeration (P × 12 for the first 250 iterations).
"""
from __future__ import annotations

from typing import Optional, Tuple

import numpy as np


def squared_distances(X: np.ndarray) -> np.ndarray:
    """(N, D) -> (N, N) squared Euclidean distances (diagonal 0, no negatives from rounding)."""
    X = np.asarray(X, np.float64)
    s = np.sum(X * X, axis=1)
    D = s[:, None] + s[None, :] - 2.0 * X @ X.T
    np.fill_diagonal(D, 0.0)
    return np.maximum(D, 0.0)


def conditional_affinities(D: np.ndarray, perplexity: float, tol: float = 1e-5,
                           max_iter: int = 100) -> Tuple[np.ndarray, np.ndarray]:
    """Rows p_{j|i} (N, N) of squared distances D (N, N) at the given perplexity, by binary search
    on the precision β_i per row; returns (P, β (N,)). The entropy of each row is within ``tol``
    nats of log(perplexity) unless ``max_iter`` halvings were not enough."""
    D = np.asarray(D, np.float64)
    N = len(D)
    if not 1.0 <= perplexity < N:
        raise ValueError(f"conditional_affinities: perplexity {perplexity} must be in [1, N-1 = {N - 1}]")
    target = np.log(perplexity)
    P = np.zeros((N, N))
    betas = np.ones(N)
    for i in range(N):
        d = np.delete(D[i], i)
        d = d - d.min()                       # shift for stability: p is unchanged
        lo, hi, beta = 0.0, np.inf, 1.0 / max(np.mean(d), 1e-12)
        for _ in range(max_iter):
            e = np.exp(-beta * d)
            s = e.sum()
            H = np.log(s) + beta * np.sum(d * e) / s        # entropy of p = e / s, nats
            if abs(H - target) < tol:
                break
            if H > target:                     # too flat: sharpen
                lo = beta
                beta = beta * 2 if hi == np.inf else (beta + hi) / 2
            else:
                hi = beta
                beta = (beta + lo) / 2
        P[i, np.arange(N) != i] = e / s
        betas[i] = beta
    return P, betas


def joint_affinities(X: np.ndarray, perplexity: float = 30.0) -> np.ndarray:
    """Symmetric P (N, N) summing to 1, from points X (N, D)."""
    P, _ = conditional_affinities(squared_distances(X), perplexity)
    P = (P + P.T) / (2.0 * len(P))
    return np.maximum(P, 1e-12 / len(P) ** 2) * (1 - np.eye(len(P)))


def kl_and_gradient(Y: np.ndarray, P: np.ndarray) -> Tuple[float, np.ndarray]:
    """C = KL(P ‖ Q) of an embedding Y (N, d) and its exact gradient (N, d) (step 2 of the docstring)."""
    Y = np.asarray(Y, np.float64)
    W = 1.0 / (1.0 + squared_distances(Y))
    np.fill_diagonal(W, 0.0)
    Q = W / W.sum()
    off = ~np.eye(len(Y), dtype=bool)
    Pm, Qm = P[off], np.maximum(Q[off], 1e-300)
    kl = float(np.sum(Pm * np.log(np.maximum(Pm, 1e-300) / Qm)))
    M = (P - Q) * W                                          # (N, N)
    grad = 4.0 * (M.sum(axis=1)[:, None] * Y - M @ Y)        # Σ_j M_ij (y_i − y_j)
    return kl, grad


def tsne(X: np.ndarray, dims: int = 2, perplexity: float = 30.0, iters: int = 1000,
         learning_rate: Optional[float] = None,
         exaggeration: float = 12.0, exaggeration_iters: int = 250, seed: int = 0,
         rng: Optional[np.random.Generator] = None) -> np.ndarray:
    """Embed X (N, D) in ``dims`` dimensions; returns Y (N, dims). Deterministic for a seed.

    ``learning_rate`` None: max(N / exaggeration / 4, 50) (Belkina et al. 2019, scikit-learn's
    'auto'); the reference's fixed 200 tears small sets (a few hundred points) apart."""
    X = np.asarray(X, np.float64)
    if X.ndim != 2 or len(X) < 3 or not np.all(np.isfinite(X)):
        raise ValueError(f"tsne: need (N >= 3, D) finite points, got {X.shape}")
    perplexity = min(perplexity, (len(X) - 1) / 3.0)          # small sets: keep the search feasible
    rng = rng or np.random.default_rng(seed)
    if learning_rate is None:
        learning_rate = max(len(X) / exaggeration / 4.0, 50.0)
    P = joint_affinities(X, max(perplexity, 1.0))
    Y = 1e-4 * rng.normal(size=(len(X), dims))
    update = np.zeros_like(Y)
    gains = np.ones_like(Y)
    for it in range(iters):
        ex = exaggeration if it < exaggeration_iters else 1.0
        _, grad = kl_and_gradient(Y, P * ex)
        momentum = 0.5 if it < 250 else 0.8
        same = np.sign(grad) == np.sign(update)
        gains = np.maximum(np.where(same, gains * 0.8, gains + 0.2), 0.01)
        update = momentum * update - learning_rate * gains * grad
        Y = Y + update
        Y = Y - Y.mean(axis=0)
    return Y
