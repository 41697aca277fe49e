"""TrainData: the plain arrays a training run reads (the interface between dataset/ and train/).

Everything here is already normalised and aligned; the trainer never sees BVH files or feature
layouts. :meth:`minifilm.dataset.dataset.Dataset.train_data` produces these; tests build them from
random arrays.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from minifilm.errors import DataError


@dataclass
class TrainData:
    """One split (train, val or test) of normalised frames and style clips.

    x (N, x_dim), p (N, phase_dim), z (N, z_dim)   frame pairs: input, local phases, next-frame output
    style (N,) int                                 style id of each frame, 0 .. S-1
    clips (M, T, C)                                style clips for Ψ (normalised)
    clip_style (M,) int                            style id of each clip
    style_names                                    optional names, indexed by style id

    Every style that has frames must have at least one clip: each training sample is paired
    with a clip of its own style drawn at random (minifilm/train/batches.py).
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
            names = [self.style_names[i] if i < len(self.style_names) else i for i in missing]
            raise DataError(f"TrainData: style(s) {names} have training frames but no style clip: every stretch "
                            "of their training frames is shorter than a clip; give longer files or shorter "
                            "clips (clip_seconds, --clip-seconds)")
        for name in ("x", "p", "z", "clips"):
            a = getattr(self, name)
            if a.dtype.kind != "f":
                raise DataError(f"TrainData: {name} must hold floating-point numbers, got {a.dtype}")
            if not np.all(np.isfinite(a)):       # checked here so a training run never starts on them
                where = tuple(int(i) for i in np.argwhere(~np.isfinite(a))[0])
                raise DataError(f"TrainData: {name}{list(where)} is {a[where]} (non-finite)")
        if len(self.style) and (self.style.min() < 0 or self.clip_style.min(initial=0) < 0):
            raise DataError("TrainData: style ids must be >= 0")

    @property
    def styles(self) -> np.ndarray:
        """Sorted style ids present in the frames."""
        return np.unique(self.style)

    def __len__(self):
        return self.x.shape[0]
