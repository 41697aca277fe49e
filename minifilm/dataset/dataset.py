"""A built dataset: three splits of rows and style clips, the layout, styles, statistics, provenance.

Split holds the raw (unnormalised) rows of one split; :meth:`Dataset.train_data` hands a split to
the trainer normalised, as :class:`~minifilm.dataset.arrays.TrainData`. ``save`` / ``load`` use one
``.npz`` file (no pickle) whose file paths are stored relative to the file itself, so a cache or run
folder works from any working directory and can be moved as a whole.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Dict, List, Optional, Union

import numpy as np

from minifilm.dataset.arrays import TrainData
from minifilm.dataset.cache import CACHE_FORMAT
from minifilm.dataset.splits import SPLITS
from minifilm.dataset.stats import NormStats
from minifilm.errors import DataError
from minifilm.features.compute import trajectory_offsets, trajectory_sample_frames
from minifilm.features.layout import FeatureLayout
from minifilm.files import MAX_JSON_BYTES, Member, atomic_savez, parse_json, read_npz, read_npz_member
from minifilm.files.reading import memory_budget


@dataclass
class Split:
    """The rows of one split. x (N, x_dim), p (N, 8), z (N, z_dim) float32; style (N,) int;
    file (N,) index into ``Dataset.files``; frame (N,) current frame in that file (after its
    start/end crop); clips (M, T, 12 J)
    float32 with clip_style (M,) and clip_file (M,)."""
    x: np.ndarray
    p: np.ndarray
    z: np.ndarray
    style: np.ndarray
    file: np.ndarray
    frame: np.ndarray
    clips: np.ndarray
    clip_style: np.ndarray
    clip_file: np.ndarray

    def __len__(self) -> int:
        return int(self.x.shape[0])

    def runs(self):
        """(starts, stops) (R,) row bounds of the runs of consecutive frames of one file: a run's
        rows are frames f, f + 1, ... of its file (the split's other frames of it start a new run)."""
        if len(self) == 0:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        brk = np.r_[True, (np.diff(self.file) != 0) | (np.diff(self.frame) != 1)]
        starts = np.nonzero(brk)[0]
        return starts, np.r_[starts[1:], len(self)]


_SPLIT_ARRAYS = ("x", "p", "z", "style", "file", "frame", "clips", "clip_style", "clip_file")


@dataclass
class Dataset:
    """A built dataset: three splits, the layout, style names, normalisation and provenance.

    stats: normalisation statistics of the training rows.
    files: one dict per featurised source (a file, or its mirror) with path (absolute), style,
    gait, mirrored, n_frames and segments [(start, stop, split)].
    """
    layout: FeatureLayout
    styles: List[str]
    fps: float
    skeleton: str
    train: Split
    val: Split
    test: Split
    stats: NormStats
    files: List[dict]
    settings: dict
    cache_path: Optional[Path] = None
    build_seconds: float = 0.0
    cache_key: str = ""
    loaded: bool = False        # read from a cache (True) or built now

    def split(self, name: str) -> Split:
        if name not in SPLITS:
            raise KeyError(f"Dataset.split: {name!r} is not one of {SPLITS}")
        return getattr(self, name)

    def train_data(self, name: str, clip_split: Optional[str] = None, dtype=np.float32) -> TrainData:
        """Split ``name`` normalised with the training statistics, as the trainer takes it.

        Clips come from ``clip_split``; by default the split's own clips when every style with rows
        has one there, else the training clips (validation and test windows are usually shorter
        than a clip; the clip is the style condition y, not a target).
        """
        sp = self.split(name)
        if clip_split is None:
            have = set(sp.clip_style.tolist())
            clip_split = name if set(sp.style.tolist()) <= have else "train"
        cs = self.split(clip_split)
        n = self.stats
        return TrainData(x=n.normalize_x(sp.x).astype(dtype), p=n.normalize_p(sp.p).astype(dtype),
                         z=n.normalize_z(sp.z).astype(dtype), style=sp.style,
                         clips=n.normalize_clip(cs.clips, self.layout.x_joints).astype(dtype),
                         clip_style=cs.clip_style, style_names=list(self.styles))

    # ------------------------------------------------------------------ report
    def frame_counts(self) -> Dict[str, Dict[str, int]]:
        """{style: {split: rows}} (plus '<split> clips')."""
        out = {s: {} for s in self.styles}
        for name in SPLITS:
            sp = self.split(name)
            rows = np.bincount(sp.style, minlength=len(self.styles))
            clips = np.bincount(sp.clip_style, minlength=len(self.styles))
            for i, s in enumerate(self.styles):
                out[s][name] = int(rows[i])
                out[s][name + " clips"] = int(clips[i])
        return out

    def reflected_fraction(self) -> Dict[str, float]:
        """{split: fraction of the x trajectory samples that are point reflections} (a segment
        shorter than the trajectory window is mostly reflections; see split_unit='files')."""
        offsets = trajectory_offsets(self.fps, self.layout.trajectory_seconds)
        counts = {s: [0, 0] for s in SPLITS}
        for info in self.files:
            for a, b, split in info["segments"]:
                k = np.arange(a + 1, b - 1)
                if k.size:
                    _, pivot = trajectory_sample_frames(k, offsets, a, b)
                    counts[split][0] += int((pivot >= 0).sum())
                    counts[split][1] += pivot.size
        return {s: (r / n if n else 0.0) for s, (r, n) in counts.items()}

    def summary(self) -> str:
        """A table of rows (frames) and clips per style and split."""
        counts = self.frame_counts()
        w = max([5] + [len(s) for s in self.styles])
        head = f"{'style':<{w}} " + " ".join(f"{h:>9}" for h in ("train", "val", "test", "clips tr",
                                                                   "clips va", "clips te"))
        lines = [head, "-" * len(head)]
        total = np.zeros(6, dtype=np.int64)
        for s in self.styles:
            c = counts[s]
            row = [c["train"], c["val"], c["test"], c["train clips"], c["val clips"], c["test clips"]]
            total += row
            lines.append(f"{s:<{w}} " + " ".join(f"{v:>9d}" for v in row))
        lines.append("-" * len(head))
        lines.append(f"{'total':<{w}} " + " ".join(f"{v:>9d}" for v in total))
        n_src = len(self.files)
        n_mir = sum(1 for f in self.files if f["mirrored"])
        lines.append(f"{n_src} sources ({n_mir} mirrored), {self.fps:g} fps, skeleton {self.skeleton}, "
                     f"x {self.layout.x_dim}, z {self.layout.z_dim}, clip T={self.train.clips.shape[1]}"
                     f" x {self.layout.clip_dim}")
        refl = self.reflected_fraction()
        lines.append("trajectory samples that are reflections: " +
                     ", ".join(f"{s} {100 * refl[s]:.1f} %" for s in SPLITS))
        return "\n".join(lines)

    # ------------------------------------------------------------------ save / load
    def save(self, path: Union[str, Path]) -> Path:
        """Write one .npz (atomically). File paths are stored relative to ``path``'s folder."""
        arrays = {f"{name}/{key}": getattr(self.split(name), key)
                  for name in SPLITS for key in _SPLIT_ARRAYS}
        arrays.update(self.stats.to_arrays(prefix="norm/"))
        here = os.path.dirname(os.path.abspath(path))
        files = [{**f, "path": os.path.relpath(os.path.abspath(f["path"]), here)} for f in self.files]
        meta = {"layout": self.layout.to_dict(), "styles": self.styles, "fps": self.fps,
                "skeleton": self.skeleton, "files": files, "settings": self.settings,
                "format": CACHE_FORMAT, "build_seconds": self.build_seconds, "cache_key": self.cache_key}
        arrays["meta"] = np.array(json.dumps(meta))
        return atomic_savez(path, arrays)

    @classmethod
    def load(cls, path: Union[str, Path]) -> "Dataset":
        """Read a cache written by :meth:`save`. Its small 'meta' entry is read first; every array's
        header is then checked against the layout it describes (rows of x, p and z alike in each
        split, clips of one length) and their sum against half of this machine's memory, before
        any data is read: a padded or forged cache is a DataError, never a huge allocation."""
        meta = read_npz_member(path, "meta", "dataset cache", DataError, Member("U", ()), 4 * MAX_JSON_BYTES)
        if meta is None:
            raise DataError(f"dataset cache {path}: not a dataset cache (no 'meta' entry)")
        meta = parse_json(str(meta), f"dataset cache {path}: 'meta'", DataError)
        if not isinstance(meta, dict) or meta.get("format") != CACHE_FORMAT:
            raise DataError(f"dataset cache {path}: format {meta.get('format') if isinstance(meta, dict) else meta!r} "
                            f"is not {CACHE_FORMAT}")
        try:
            layout = FeatureLayout.from_dict(meta["layout"])
        except (KeyError, ValueError, TypeError, AttributeError) as e:
            raise DataError(f"dataset cache {path}: not a dataset cache ({type(e).__name__}: {e})") from None
        d = read_npz(path, "dataset cache", DataError, memory_budget(), cache_members(layout))
        try:
            splits = {name: Split(*(d[f"{name}/{key}"] for key in _SPLIT_ARRAYS)) for name in SPLITS}
            norm = NormStats.from_arrays(d, prefix="norm/")
            here = os.path.dirname(os.path.abspath(path))
            for f in meta["files"]:
                f["segments"] = [tuple(s) for s in f["segments"]]
                f["path"] = os.path.normpath(os.path.join(here, f["path"]))
            return cls(layout, list(meta["styles"]), float(meta["fps"]), meta["skeleton"], splits["train"],
                       splits["val"], splits["test"], norm, meta["files"], meta["settings"], Path(path),
                       float(meta.get("build_seconds", 0.0)), meta.get("cache_key", ""), loaded=True)
        except (KeyError, ValueError, TypeError, AttributeError) as e:
            raise DataError(f"dataset cache {path}: not a dataset cache ({type(e).__name__}: {e})") from None


def cache_members(layout: FeatureLayout) -> Dict[str, Member]:
    """What a dataset cache of ``layout`` holds: per split, N rows of x, p, z, style, file and frame
    and M clips of T frames with their style and file; the statistics; 'meta'."""
    members = {"meta": Member("U", ())}
    for name in SPLITS:
        rows, clips = f"{name} rows", f"{name} clips"
        members.update({f"{name}/x": Member("f", (rows, layout.x_dim)), f"{name}/p": Member("f", (rows, layout.phase_dim)),
                        f"{name}/z": Member("f", (rows, layout.z_dim)),
                        f"{name}/clips": Member("f", (clips, "T", layout.clip_dim))})
        members.update({f"{name}/{key}": Member("iu", (rows,)) for key in ("style", "file", "frame")})
        members.update({f"{name}/{key}": Member("iu", (clips,)) for key in ("clip_style", "clip_file")})
    for part, size in (("x", layout.x_dim), ("z", layout.z_dim), ("p", layout.phase_dim)):
        members.update({f"norm/{part}_{k}": Member("f", (size,)) for k in ("mean", "std")})
    return members
