"""Checks of built rows: every number finite, and every style with something to train on.

Both name what is wrong in the user's terms (the file, frame and feature column; the style and its
files) so bad data fails while the dataset is built, not as "loss is not finite" an hour later or
as a style that silently never trains.
"""
from __future__ import annotations

from pathlib import Path
from typing import List, Sequence

import numpy as np

from minifilm.errors import DataError


def check_finite(a: np.ndarray, which: str, layout, where: str, frames: np.ndarray) -> None:
    """DataError naming the first non-finite entry of rows ``a`` (N, D) of ``which`` ('x', 'z',
    'p'): its frame (``frames`` (N,) of the file ``where``) and the column's meaning."""
    finite = np.isfinite(a)
    if finite.all():
        return
    row, col = np.argwhere(~finite)[0]
    column = layout.describe(which)[col]
    raise DataError(f"{where}: frame {int(frames[row])}: {which}[{col}] ({column.joint}, {column.quantity}) is "
                    f"{a[row, col]} ({int((~finite).sum())} non-finite numbers in all)")


def _style_files(sources: Sequence[dict], style: str) -> List[dict]:
    return [s for s in sources if s["style"] == style and not s["mirrored"]]


def _listing(files: Sequence[dict], fps: float, limit: int = 4) -> str:
    shown = ", ".join(f"{Path(s['path']).name} ({s['n_frames'] / fps:.1f} s)" for s in files[:limit])
    return shown + (f" and {len(files) - limit} more" if len(files) > limit else "")


def check_every_style_trains(train, styles: Sequence[str], sources: Sequence[dict], settings, fps: float) -> None:
    """DataError when a style has no training row, or no training style clip while others have
    some (a dataset built without clips, for a model without Ψ, is fine), saying why: its files are
    too short, all went to validation / test, or none is long enough for a clip."""
    rows = np.bincount(train.style, minlength=len(styles))
    clips = np.bincount(train.clip_style, minlength=len(styles))
    clip_seconds = settings["clip_seconds"] if isinstance(settings, dict) else settings.clip_seconds
    for sid, style in enumerate(styles):
        files = _style_files(sources, style)
        in_train = [s for s in files if any(seg[2] == "train" for seg in s["segments"])]
        if rows[sid] == 0:
            if not in_train:
                raise DataError(f"style {style!r} has no training rows: all {len(files)} of its files went to "
                                f"validation or test ({_listing(files, fps)}); give it more files, or split "
                                "every file into segments (--split segments)")
            raise DataError(f"style {style!r} has no training rows: its training files are too short "
                            f"({_listing(in_train, fps)})")
        if clips[sid] == 0 and clips.any():
            # what a clip must fit in is a training segment, not the whole file (files are split
            # into train / validation / test parts, and a clip may not cross into the others)
            longest = max(b - a for f in in_train for a, b, split in f["segments"] if split == "train") / fps
            raise DataError(f"style {style!r} has no training style clip: a clip lasts {clip_seconds:g} s and its "
                            f"longest stretch of training frames {longest:.2f} s (files: {_listing(in_train, fps)}); "
                            "give it longer files or use shorter clips (--clip-seconds)")
