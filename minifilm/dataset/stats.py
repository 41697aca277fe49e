"""Normalisation statistics: the one class every stage reads them from (docs/original-code.md §8.5).

    x̂ = (x - x_mean) / x_std      network input (Sec. 3.2)
    p̂ = (p - p_mean) / p_std      local phases fed to the gating network Ω (the released GT_X stats)
    ẑ = (z - z_mean) / z_std      network output; the bone-length loss and the runtime map back
    ŷ = (y - x_mean[J]) / x_std[J] style clips, with the x joint-block statistics (§9)

Fitted on the training rows in float64 (per-column mean and biased std, as the original), stored in
checkpoints (``stats.<name>`` arrays), dataset caches and the released network's ``.bin`` files.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Dict, Tuple, Union

import numpy as np

from minifilm.errors import InputError
from minifilm.files import Member, atomic_savez, read_npz

FIELDS = ("x_mean", "x_std", "z_mean", "z_std", "p_mean", "p_std")


@dataclass
class NormStats:
    """Per-column mean and std of x (x_dim,), z (z_dim,) and p (phase_dim,), float64.

    Every std is finite and > 0 and every mean finite, checked on construction, so a corrupt
    checkpoint or cache fails here, naming the field, and never reaches a network as NaN.
    """

    x_mean: np.ndarray
    x_std: np.ndarray
    z_mean: np.ndarray
    z_std: np.ndarray
    p_mean: np.ndarray
    p_std: np.ndarray

    def __post_init__(self):
        for name in ("x", "z", "p"):
            m = np.asarray(getattr(self, f"{name}_mean"), dtype=np.float64)
            s = np.asarray(getattr(self, f"{name}_std"), dtype=np.float64)
            if m.ndim != 1 or m.shape != s.shape:
                raise ValueError(f"NormStats: {name}_mean {m.shape} and {name}_std {s.shape} must be equal 1-D")
            if not np.all(np.isfinite(m)):
                bad = np.flatnonzero(~np.isfinite(m))[:5]
                raise ValueError(f"NormStats: {name}_mean has non-finite values (at {bad.tolist()})")
            if not (np.all(np.isfinite(s)) and np.all(s > 0)):
                bad = np.flatnonzero(~(np.isfinite(s) & (s > 0)))[:5]
                raise ValueError(f"NormStats: {name}_std must be finite and > 0 (bad indices {bad.tolist()})")
            setattr(self, f"{name}_mean", m)
            setattr(self, f"{name}_std", s)

    # ---- fitting --------------------------------------------------------------------------
    @classmethod
    def fit(cls, x: np.ndarray, p: np.ndarray, z: np.ndarray, min_std: float = 1e-6) -> "NormStats":
        """Statistics of training rows x (N, x_dim), p (N, 8), z (N, z_dim); a std below
        ``min_std`` (a constant column, e.g. the current trajectory sample) becomes 1."""
        if len(x) == 0:
            raise ValueError("NormStats.fit: no training rows")
        stats = {}
        for name, a in (("x", x), ("p", p), ("z", z)):
            mean, std = _mean_std(a)
            std[std < min_std] = 1.0
            stats[f"{name}_mean"], stats[f"{name}_std"] = mean, std
        return cls(**stats)

    @classmethod
    def identity(cls, x_dim: int, z_dim: int, phase_dim: int = 8) -> "NormStats":
        """Mean 0, std 1 everywhere (data that is already normalised)."""
        return cls(np.zeros(x_dim), np.ones(x_dim), np.zeros(z_dim), np.ones(z_dim),
                   np.zeros(phase_dim), np.ones(phase_dim))

    # ---- applying -------------------------------------------------------------------------
    def normalize_x(self, x):
        return (x - self.x_mean) / self.x_std

    def normalize_p(self, p):
        return (p - self.p_mean) / self.p_std

    def normalize_z(self, z):
        return (z - self.z_mean) / self.z_std

    def denormalize_z(self, z_hat):
        return z_hat * self.z_std + self.z_mean

    def normalize_clip(self, clip, joints: slice):
        """(..., T, 12 J) style clips with the statistics of x's joint block ``joints``
        (``layout.x_joints``), as the original normalises its style clips (§9)."""
        return (clip - self.x_mean[joints]) / self.x_std[joints]

    # ---- files ----------------------------------------------------------------------------
    def to_arrays(self, prefix: str = "stats.") -> Dict[str, np.ndarray]:
        """``{prefix + field: array}`` for an ``.npz`` archive."""
        return {prefix + k: getattr(self, k) for k in FIELDS}

    @classmethod
    def from_arrays(cls, arrays, prefix: str = "stats.") -> "NormStats":
        """Inverse of :meth:`to_arrays`; KeyError naming the missing entries."""
        missing = [prefix + k for k in FIELDS if prefix + k not in arrays]
        if missing:
            raise KeyError(f"NormStats.from_arrays: missing {missing}")
        not_float = [prefix + k for k in FIELDS if np.asarray(arrays[prefix + k]).dtype.kind != "f"]
        if not_float:
            raise ValueError(f"NormStats.from_arrays: {not_float} must hold floating-point numbers")
        return cls(**{k: np.asarray(arrays[prefix + k]) for k in FIELDS})

    def save(self, path: Union[str, Path]) -> Path:
        return atomic_savez(path, self.to_arrays(prefix=""))

    @classmethod
    def load(cls, path: Union[str, Path]) -> "NormStats":
        members = {k: Member("f", (k[0],)) for k in FIELDS}     # x_mean and x_std of one size, ...
        arrays = read_npz(path, "statistics", InputError, members=members)
        try:
            return cls.from_arrays(arrays, prefix="")
        except (KeyError, ValueError) as e:
            raise InputError(f"statistics {path}: {e}") from None


def _mean_std(a: np.ndarray, chunk: int = 1 << 15) -> Tuple[np.ndarray, np.ndarray]:
    """Column mean and biased std (as the original) in float64, two passes over row chunks so a
    large float32 array is never copied whole into float64."""
    n = a.shape[0]
    total = np.zeros(a.shape[1])
    for i in range(0, n, chunk):
        total += a[i:i + chunk].sum(axis=0, dtype=np.float64)
    mean = total / n
    sq = np.zeros(a.shape[1])
    for i in range(0, n, chunk):
        sq += ((a[i:i + chunk].astype(np.float64) - mean) ** 2).sum(axis=0)
    return mean, np.sqrt(sq / n)
