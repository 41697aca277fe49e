"""Measuring style so that it cannot be gamed : a distribution distance beside the classifier.

A classifier can be fooled: a motion that holds one telling pose for a window is "recognised"
though it moves like nothing in the data, and a different seed of the same classifier may disagree
(``studies/new_style_ceiling.py`` searched classifier settings and found both). So a style
counts as *reproduced* only when two different measures agree:

1. the **Fréchet distance** between the distribution of windowed, root-relative pose and velocity
   features of the generated motion and that of the real frames of each style, and the **rank**
   of the target style among all styles by that distance (1 = nearest);
2. the **classifier's recognition** (the share of windows it gives the target style), over several
   classifier seeds: the minimum and the mean.

Features: each window (``window`` frames, every ``stride``) of per-frame clip features (every joint's
position, forward, up and velocity relative to that frame's root, normalised with the training
statistics; :func:`~minifilm.evaluation.style_classifier.rollout_blocks`) is summarised by its mean
and standard deviation over time, as the classifier reads it. Those summaries (2 x 12 J = 552
numbers for 23 joints) are standardised and projected on the first ``dims`` principal components
of the real windows of all styles, so each style's covariance is estimated from enough windows.

Fréchet distance between Gaussians fitted to two sets of vectors (as FID, Heusel et al. 2017):

    d² = |μ₁ − μ₂|² + tr(Σ₁ + Σ₂ − 2 (Σ₁ Σ₂)^½),   tr (Σ₁ Σ₂)^½ = Σ √λ(Σ₁^½ Σ₂ Σ₁^½)

computed with symmetric eigendecompositions only (the matrix in the last form is symmetric PSD).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, Mapping, Optional, Sequence

import numpy as np

from minifilm.evaluation.style_classifier import window_summary


def _sqrt_psd(S: np.ndarray) -> np.ndarray:
    """The symmetric square root of a symmetric positive semi-definite matrix (negative rounding
    errors in the eigenvalues clipped to 0)."""
    w, V = np.linalg.eigh((S + S.T) / 2)
    return (V * np.sqrt(np.clip(w, 0.0, None))) @ V.T


def frechet_distance(mu1: np.ndarray, cov1: np.ndarray, mu2: np.ndarray, cov2: np.ndarray) -> float:
    """Squared Fréchet (2-Wasserstein) distance between N(mu1, cov1) and N(mu2, cov2); mu (D,), cov (D, D)."""
    mu1, mu2 = np.asarray(mu1, np.float64), np.asarray(mu2, np.float64)
    cov1, cov2 = np.asarray(cov1, np.float64), np.asarray(cov2, np.float64)
    D = len(mu1)
    if mu2.shape != (D,) or cov1.shape != (D, D) or cov2.shape != (D, D):
        raise ValueError(f"frechet_distance: means {mu1.shape}, {mu2.shape} and covariances {cov1.shape}, "
                         f"{cov2.shape} must be (D,) and (D, D)")
    A = _sqrt_psd(cov1)
    lam = np.linalg.eigvalsh(A @ cov2 @ A)
    cross = np.sum(np.sqrt(np.clip(lam, 0.0, None)))
    d = float(np.sum((mu1 - mu2) ** 2) + np.trace(cov1) + np.trace(cov2) - 2.0 * cross)
    return max(d, 0.0)


def gaussian(features: np.ndarray):
    """(N, D) -> (mean (D,), covariance (D, D)) with the 1/N convention (N >= 2)."""
    X = np.asarray(features, np.float64)
    if X.ndim != 2 or len(X) < 2:
        raise ValueError(f"gaussian: need (N >= 2, D) features, got {X.shape}")
    mu = X.mean(axis=0)
    Xc = X - mu
    return mu, Xc.T @ Xc / len(X)


@dataclass
class StyleSpace:
    """Real windows of every style, summarised, standardised and projected on ``dims`` principal
    components; one Gaussian per style. Build with :meth:`fit`."""

    names: list
    mean: np.ndarray            # (2C,) summary mean of all real windows
    std: np.ndarray             # (2C,)
    basis: np.ndarray           # (2C, dims) principal directions
    gaussians: Dict[str, tuple]  # name -> (mu (dims,), cov (dims, dims))

    @classmethod
    def fit(cls, windows: Mapping[str, np.ndarray], dims: int = 32, summarised: bool = False) -> "StyleSpace":
        """windows: style name -> (M, T, C) real windows (normalised clip features), M >= 2 each, or
        with ``summarised`` their (M, 2C) summaries (:func:`window_summary`: far less memory)."""
        names = list(windows)
        if len(names) < 1:
            raise ValueError("StyleSpace.fit: no styles")
        summ = {n: np.asarray(windows[n], np.float64) if summarised else window_summary(windows[n]) for n in names}
        for n, s in summ.items():
            if len(s) < 2:
                raise ValueError(f"StyleSpace.fit: style {n!r} has {len(s)} windows; need at least 2")
        allw = np.concatenate(list(summ.values()))
        mean = allw.mean(axis=0)
        std = np.where(allw.std(axis=0) > 1e-8, allw.std(axis=0), 1.0)
        Z = (allw - mean) / std
        # principal directions of the standardised summaries (SVD; signs do not matter for distances)
        _, _, Vt = np.linalg.svd(Z - Z.mean(axis=0), full_matrices=False)
        basis = Vt[:min(dims, Vt.shape[0])].T
        space = cls(names, mean, std, basis, {})
        space.gaussians = {n: gaussian(space.project(summ[n], summarised=True)) for n in names}
        return space

    def project(self, windows: np.ndarray, summarised: bool = False) -> np.ndarray:
        """(M, T, C) windows (or (M, 2C) summaries with ``summarised``) -> (M, dims)."""
        s = np.asarray(windows, np.float64) if summarised else window_summary(windows)
        return ((s - self.mean) / self.std) @ self.basis

    def distances(self, windows: np.ndarray, summarised: bool = False) -> Dict[str, float]:
        """Squared Fréchet distance from generated windows (M >= 2, T, C), or their (M, 2C)
        summaries with ``summarised``, to every style."""
        mu, cov = gaussian(self.project(windows, summarised))
        return {n: frechet_distance(mu, cov, *g) for n, g in self.gaussians.items()}

    def rank(self, windows: np.ndarray, target: str, summarised: bool = False) -> int:
        """The target style's place among all styles by distance (1 = nearest; ties count against it)."""
        if target not in self.gaussians:
            raise KeyError(f"StyleSpace.rank: no style {target!r}; styles: {self.names}")
        d = self.distances(windows, summarised)
        return 1 + sum(v <= d[target] for n, v in d.items() if n != target)


def recognition(probabilities: np.ndarray, target: int) -> float:
    """Share of windows whose most probable class is ``target``: probabilities (M, classes) or
    (B, M, classes) for B characters of the same target."""
    p = np.asarray(probabilities)
    return float(np.mean(np.argmax(p, axis=-1) == int(target)))


def classifier_spread(recognitions: Sequence[float]) -> Dict[str, float]:
    """Minimum and mean of one motion's recognition over several classifier seeds."""
    r = np.asarray(list(recognitions), np.float64)
    if r.size == 0:
        raise ValueError("classifier_spread: no classifier seeds")
    return dict(min=float(r.min()), mean=float(r.mean()), seeds=int(r.size))


def reproduced(rank: int, recognitions: Sequence[float], threshold: float = 0.8) -> bool:
    """A style is reproduced when both measures agree: rank 1 by Fréchet distance and recognised
    at least ``threshold`` by every classifier seed (the minimum, not the mean)."""
    return int(rank) == 1 and classifier_spread(recognitions)["min"] >= threshold


def style_report(space: StyleSpace, windows: np.ndarray, target: str, recognitions: Optional[Sequence[float]] = None,
                 threshold: float = 0.8, summarised: bool = False) -> dict:
    """Everything measured for one generated motion of style ``target``: distance to the target,
    the nearest style, the rank, and with ``recognitions`` the classifier spread and the verdict.
    windows: (M, T, C), or (M, 2C) summaries with ``summarised``."""
    d = space.distances(windows, summarised)
    nearest = min(d, key=d.get)
    rank = 1 + sum(v <= d[target] for n, v in d.items() if n != target)
    out = dict(target=target, distance=d[target], nearest=nearest, nearest_distance=d[nearest], rank=rank)
    if recognitions is not None:
        out.update(classifier=classifier_spread(recognitions), reproduced=reproduced(rank, recognitions, threshold))
    return out
