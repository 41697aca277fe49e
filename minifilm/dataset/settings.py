"""DatasetSettings: everything that decides the content of a dataset (and so its cache key)."""
from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Optional, Tuple

import numpy as np

from minifilm.dataset.manifest import MotionFile


@dataclass(frozen=True)
class DatasetSettings:
    """Everything that decides the content of a dataset (and so its cache key).

    fps:              resample every file to this rate; None = use the files' rate (all equal).
    skeleton:         a built-in skeleton name ('100style', 'bandai', 'cmu', ...); None = detect.
    split_fractions:  (train, val, test) fractions of every file, default 80/10/10.
    seed:             seeds the per-file split windows (each file from ``seed`` and its name).
    gap_seconds:      frames dropped at each border between segments of different splits.
    mirror_styles:    styles that also get a mirrored copy; ('*',) = all styles. A manifest's
                      ``mirror`` column overrides this per file.
    idle_gaits:       gaits that are skipped (100STYLE 'ID').
    clip_gaits:       gaits whose files give style clips (100STYLE forward walk 'FW', Bandai 'walk').
    clip_fallback:    a style whose clip-gait files give no training clip (none exist, or their
                      training segments are shorter than a clip) takes its clips from its other
                      files.
    clip_seconds, clip_stride_seconds: clip length and stride (paper: 240 frames at 60 fps, half).
    split_transitions: split TR* files too (the original puts them all in train).
    split_unit:       'segments' (default, the original: every file is cut 80/10/10) or 'files'
                      (whole files go to train / val / test, per style, seeded): for datasets of
                      many short files, where 10 % windows are shorter than the 2 s trajectory.
    min_std:          std below this becomes 1 in the normalisation.
    """
    fps: Optional[float] = None
    skeleton: Optional[str] = None
    split_fractions: Tuple[float, float, float] = (0.8, 0.1, 0.1)
    seed: int = 0
    gap_seconds: float = 0.0
    mirror_styles: Tuple[str, ...] = ()
    idle_gaits: Tuple[str, ...] = ("ID", "idle")
    clip_gaits: Tuple[str, ...] = ("FW", "walk")
    clip_fallback: bool = True
    clip_seconds: float = 4.0
    clip_stride_seconds: float = 2.0
    split_transitions: bool = False
    split_unit: str = "segments"
    min_std: float = 1e-6

    def __post_init__(self) -> None:
        for name in ("split_fractions", "mirror_styles", "idle_gaits", "clip_gaits"):
            value = getattr(self, name)
            object.__setattr__(self, name, (value,) if isinstance(value, str) else tuple(value))
        fr = self.split_fractions
        if len(fr) != 3 or min(fr) < 0 or not np.isclose(sum(fr), 1.0):
            raise ValueError(f"DatasetSettings: split_fractions must be 3 non-negative numbers summing "
                             f"to 1, got {fr}")
        if self.split_unit not in ("segments", "files"):
            raise ValueError(f"DatasetSettings: split_unit must be 'segments' or 'files', got {self.split_unit!r}")
        if self.gap_seconds < 0:
            raise ValueError(f"DatasetSettings: gap_seconds must be >= 0, got {self.gap_seconds}")

    def mirrors(self, f: MotionFile) -> bool:
        if f.mirror is not None:
            return f.mirror
        return "*" in self.mirror_styles or f.style in self.mirror_styles

    def to_dict(self) -> dict:
        return asdict(self)
