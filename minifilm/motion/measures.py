"""Measures of a motion's quality, from joint positions alone: bone-length variation, foot sliding.

Real motion capture has rigid bones and planted feet; a network that predicts every joint
independently may stretch its bones and slide its feet. These two numbers say how much, and are
read by the runtime's rollout checks and by the comparison of Sec. 5.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np


def bone_length_cv(positions: np.ndarray, parents: Sequence[int]) -> np.ndarray:
    """Coefficient of variation (std / mean over frames) of every bone's length, per joint.

    positions (F, J, 3) world joint positions (any float dtype; computed in float64); parents (J,)
    with -1 for roots. Returns (J,): entry j is the cv of the bone parent(j) -> j, 0 for roots,
    so ``argmax`` names the worst bone's child joint.
    """
    P = np.asarray(positions, dtype=np.float64)
    parents = np.asarray(parents)
    if P.ndim != 3 or P.shape[1] != len(parents) or P.shape[2] != 3:
        raise ValueError(f"bone_length_cv: positions {P.shape} must be (F, {len(parents)}, 3)")
    child = np.nonzero(parents >= 0)[0]
    lengths = np.linalg.norm(P[:, child] - P[:, parents[child]], axis=-1)        # (F, bones)
    cv = np.zeros(len(parents))
    cv[child] = lengths.std(axis=0) / np.maximum(lengths.mean(axis=0), 1e-9)
    return cv


def foot_sliding(positions: np.ndarray, contacts: np.ndarray, toes: Sequence[int], fps: float,
                 threshold: float = 0.5) -> float:
    """Mean horizontal toe speed (m/s) over frames where the foot's predicted contact > threshold.

    positions (F, J, 3), contacts (F, feet), toes: joint index per foot (same order as contacts).
    """
    toes = list(toes)
    v = np.linalg.norm(np.diff(positions[:, toes][..., [0, 2]], axis=0), axis=-1) * fps  # (F-1, feet)
    on = np.asarray(contacts)[1:] > threshold
    return float(v[on].mean()) if np.any(on) else 0.0
