"""Style metrics for the comparison of Sec. 5 (Figure 8, 10, 11): numbers computed from rollouts,
style scores and FiLM vectors. Plain NumPy, no model code.

- foot sliding, bone-length variation and path following of generated motion (quality of rollouts);
- smoothness of a style score along an interpolation weight (Figure 8: FiLM blends smoothly);
- a 2-D PCA embedding and the silhouette score of FiLM vectors grouped by style (Figure 11).
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from minifilm.evaluation import field_metrics
from minifilm.motion.measures import bone_length_cv, foot_sliding


# ---------------------------------------------------------------------------- rollouts
def bone_length_variation(positions: np.ndarray, parents: Sequence[int]) -> dict:
    """:func:`bone_length_cv` summarised: {'mean': mean cv over bones, 'max': worst bone}.

    The network predicts joint positions independently, so nothing forces bone lengths to stay
    fixed; real motion has cv 0.
    """
    cv = bone_length_cv(positions, parents)
    bones = np.asarray(parents) >= 0
    return {"mean": float(cv[bones].mean()), "max": float(cv.max())}


def commanded_path(rollout, b: int) -> np.ndarray:
    """(F, 2) where character ``b`` would be if it moved exactly at its commanded velocities from
    where it started: the path a trajectory error is measured against."""
    steps = rollout.targets[b, :-1] / rollout.fps
    return rollout.root_positions[b, 0] + np.concatenate([np.zeros((1, 2)), np.cumsum(steps, axis=0)])


def rollout_quality(rollout, parents: Sequence[int], toes: Sequence[int], warmup_seconds: float = 1.0,
                    contact_threshold: float = 0.5) -> dict:
    """Foot sliding, bone-length variation and path following of a
    :class:`minifilm.runtime.controller.Rollout`, averaged over its characters, after
    ``warmup_seconds`` (the start pose is the mean pose).

    toes: joint index of the toe for each contact column (the Rollout's order [right, left]).
    Keys: foot_sliding (m/s, toes while the network's own contact label is on), foot_sliding_cm_s
    (cm/s, toes while within 1 cm of the floor: the field's height-based definition,
    :func:`~minifilm.evaluation.field_metrics.foot_sliding`), bone_cv_mean / bone_cv_max,
    path_error (m, mean distance of the root from the commanded path), direction_error (degrees,
    direction of travel against the command's) and stalled (share of moving commands on which the
    root stood), all from the first frame.
    """
    k0 = min(int(round(warmup_seconds * rollout.fps)), rollout.positions.shape[1] - 2)
    slide, slide_cm, cv_mean, cv_max, path, direction, stalled = [], [], [], [], [], [], []
    for b in range(rollout.positions.shape[0]):
        P = rollout.positions[b, k0:]
        slide.append(foot_sliding(P, rollout.contacts[b, k0:], toes, rollout.fps, contact_threshold))
        slide_cm.append(field_metrics.foot_sliding(P, toes, rollout.fps)["speed_cm_s"])
        v = bone_length_variation(P, parents)
        cv_mean.append(v["mean"])
        cv_max.append(v["max"])
        e = field_metrics.trajectory_errors(rollout.root_positions[b], commanded_path(rollout, b), fps=rollout.fps)
        path.append(e["position_mean"])
        direction.append(e["direction_mean"])
        stalled.append(e["stalled"])
    return {"foot_sliding": float(np.mean(slide)), "foot_sliding_cm_s": float(np.mean(slide_cm)),
            "bone_cv_mean": float(np.mean(cv_mean)), "bone_cv_max": float(np.max(cv_max)),
            "path_error": float(np.mean(path)), "direction_error": float(np.mean(direction)),
            "stalled": float(np.mean(stalled))}


# ---------------------------------------------------------------------------- interpolation
def interpolation_smoothness(weights: np.ndarray, scores: np.ndarray) -> dict:
    """How smoothly a style score s(w) (e.g. the classifier's probability of style B) follows the
    blend weight w from style A (w = 0) to style B (w = 1) (Figure 8).

    weights (n,) increasing, scores (n,). Returns
      change:       s(1) - s(0)  (how far the score moves at all);
      monotonicity: |s(1) - s(0)| / sum |s_{k+1} - s_k|  (1 = monotone, less = back and forth);
      max_step:     max |s_{k+1} - s_k| / max(|s(1) - s(0)|, 1e-9)  (1/(n-1) for a linear score on
                    an even grid, 1 for a step: how much of the change happens between two weights);
      linear_rmse:  RMS distance of s(w) from the straight line between its end points.
    """
    w = np.asarray(weights, dtype=np.float64)
    s = np.asarray(scores, dtype=np.float64)
    if w.ndim != 1 or w.shape != s.shape or len(w) < 2:
        raise ValueError(f"interpolation_smoothness: weights {w.shape} and scores {s.shape} must be "
                         f"equal 1-D arrays of length >= 2")
    if np.any(np.diff(w) <= 0):
        raise ValueError("interpolation_smoothness: weights must be strictly increasing")
    steps = np.abs(np.diff(s))
    change = s[-1] - s[0]
    total = steps.sum()
    line = s[0] + (w - w[0]) / (w[-1] - w[0]) * change
    return {"change": float(change),
            "monotonicity": float(abs(change) / total) if total > 0 else 1.0,
            "max_step": float(steps.max() / max(abs(change), 1e-9)),
            "linear_rmse": float(np.sqrt(np.mean((s - line) ** 2)))}


# ---------------------------------------------------------------------------- FiLM codes
def pca_2d(X: np.ndarray, basis_from: np.ndarray | None = None):
    """Project rows of X (N, D) onto the first two principal axes.

    basis_from (M, D): rows that define the mean and the axes (default X itself), so codes before
    and after fine-tuning can be drawn in one frame. Returns (Y (N, 2), explained variance ratio (2,)).
    """
    X = np.asarray(X, dtype=np.float64)
    B = X if basis_from is None else np.asarray(basis_from, dtype=np.float64)
    mean = B.mean(axis=0)
    _, sv, Vt = np.linalg.svd(B - mean, full_matrices=False)
    var = sv ** 2
    ratio = var[:2] / max(var.sum(), 1e-300)
    if len(ratio) < 2:                         # one row or one column: pad the missing axis
        Vt = np.vstack([Vt, np.zeros((2 - len(Vt), X.shape[1]))])
        ratio = np.pad(ratio, (0, 2 - len(ratio)))
    return (X - mean) @ Vt[:2].T, ratio


def silhouette_score(X: np.ndarray, labels: np.ndarray) -> float:
    """Mean silhouette (Rousseeuw 1987) of points X (N, D) with labels (N,); see silhouette_samples."""
    return float(silhouette_samples(X, labels).mean())


def silhouette_samples(X: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """Silhouette (Rousseeuw 1987) of every point of X (N, D) with cluster labels (N,), Euclidean.

    For point i: a = mean distance to the other points of its cluster, b = the smallest mean
    distance to the points of another cluster, s = (b - a) / max(a, b); s = 0 for a point alone in
    its cluster. In [-1, 1]; near 1 = compact, well separated clusters. Needs >= 2 clusters.
    """
    X = np.asarray(X, dtype=np.float64)
    labels = np.asarray(labels)
    if X.ndim != 2 or labels.shape != (len(X),):
        raise ValueError(f"silhouette_score: X {X.shape} must be (N, D) with labels (N,), got {labels.shape}")
    names, lab = np.unique(labels, return_inverse=True)
    if len(names) < 2:
        raise ValueError("silhouette_score: needs at least 2 clusters")
    sq = (X * X).sum(axis=1)
    D = np.sqrt(np.maximum(sq[:, None] + sq[None, :] - 2 * X @ X.T, 0.0))         # (N, N)
    onehot = np.eye(len(names))[lab]                                              # (N, K)
    counts = onehot.sum(axis=0)                                                    # (K,)
    sums = D @ onehot                                                              # (N, K)
    own = counts[lab]
    a = sums[np.arange(len(X)), lab] / np.maximum(own - 1, 1)                      # self-distance is 0
    other = sums / counts
    other[np.arange(len(X)), lab] = np.inf
    b = other.min(axis=1)
    return np.where(own > 1, (b - a) / np.maximum(np.maximum(a, b), 1e-300), 0.0)
