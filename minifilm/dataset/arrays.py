"""The plain-array data interface between dataset building (data.py) and training (train.py).

Everything here is already normalised and aligned; the model package never sees BVH files or
feature layouts. ``data.py`` produces these; tests build them from random arrays.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class NormStats:
    """Per-feature normalisation statistics: v_hat = (v - mean) / std (original-pipeline §8.5).

    x_mean, x_std (x_dim,)   network input x
    z_mean, z_std (z_dim,)   network output z (the bone-length loss de-normalises with these)
    p_mean, p_std (phase_dim,) local phases fed to the gating network (the released GT_X stats)
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
            if not (np.all(np.isfinite(s)) and np.all(s > 0)):
                bad = np.nonzero(~(np.isfinite(s) & (s > 0)))[0][:5]
                raise ValueError(f"NormStats: {name}_std must be finite and > 0 (bad indices {bad.tolist()})")
            setattr(self, f"{name}_mean", m)
            setattr(self, f"{name}_std", s)

    def normalize_x(self, x):
        return (x - self.x_mean) / self.x_std

    def normalize_p(self, p):
        return (p - self.p_mean) / self.p_std

    def normalize_z(self, z):
        return (z - self.z_mean) / self.z_std

    def denormalize_z(self, z_hat):
        return z_hat * self.z_std + self.z_mean

    def to_arrays(self, prefix="stats.") -> dict:
        return {prefix + k: getattr(self, k) for k in ("x_mean", "x_std", "z_mean", "z_std", "p_mean", "p_std")}

    @classmethod
    def from_arrays(cls, arrays, prefix="stats.") -> "NormStats":
        keys = ("x_mean", "x_std", "z_mean", "z_std", "p_mean", "p_std")
        missing = [prefix + k for k in keys if prefix + k not in arrays]
        if missing:
            raise KeyError(f"NormStats.from_arrays: missing {missing}")
        return cls(**{k: np.asarray(arrays[prefix + k]) for k in keys})

    @classmethod
    def identity(cls, x_dim, z_dim, phase_dim=8) -> "NormStats":
        """Mean 0, std 1 everywhere (data that is already normalised)."""
        return cls(np.zeros(x_dim), np.ones(x_dim), np.zeros(z_dim), np.ones(z_dim),
                   np.zeros(phase_dim), np.ones(phase_dim))


@dataclass
class TrainData:
    """One split (train, val or test) of normalised frames and style clips.

    x (N, x_dim), p (N, phase_dim), z (N, z_dim)   frame pairs: input, local phases, next-frame output
    style (N,) int                                 style id of each frame, 0 .. S-1
    clips (M, T, C)                                style clips for Ψ (normalised)
    clip_style (M,) int                            style id of each clip
    style_names                                    optional names, indexed by style id

    Every style that has frames must have at least one clip: each training sample is paired
    with a clip of its own style drawn at random (the original draws clips per style).
    """

    x: np.ndarray
    p: np.ndarray
    z: np.ndarray
    style: np.ndarray
    clips: np.ndarray
    clip_style: np.ndarray
    style_names: list = field(default_factory=list)

    def __post_init__(self):
        self.style = np.asarray(self.style, dtype=np.int64)
        self.clip_style = np.asarray(self.clip_style, dtype=np.int64)
        N = self.x.shape[0]
        for name in ("p", "z", "style"):
            if getattr(self, name).shape[0] != N:
                raise ValueError(f"TrainData: {name} has {getattr(self, name).shape[0]} rows, x has {N}")
        if self.x.ndim != 2 or self.p.ndim != 2 or self.z.ndim != 2:
            raise ValueError("TrainData: x, p and z must be 2-D (N, features)")
        if self.clips.ndim != 3 or self.clip_style.shape != (self.clips.shape[0],):
            raise ValueError(f"TrainData: clips must be (M, T, C) with clip_style (M,), got "
                             f"{self.clips.shape} and {self.clip_style.shape}")
        missing = sorted(set(self.style.tolist()) - set(self.clip_style.tolist()))
        if missing:
            raise ValueError(f"TrainData: style(s) {missing} have frames but no clip")

    @property
    def styles(self) -> np.ndarray:
        """Sorted style ids present in the frames."""
        return np.unique(self.style)

    def __len__(self):
        return self.x.shape[0]
