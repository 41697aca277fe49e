"""Train / validation / test splits of motion files (docs/original-code.md §8.2, made leak-free).

Every file is cut into contiguous segments: one validation and one test window of ``floor(0.1 L)``
frames each, drawn with a seeded generator so that they never overlap, and train around them (the
original could overlap them, §12.17). ``gap_seconds`` can additionally drop that much at every
border between segments of different splits. For datasets of many short files (Bandai: ~5 s each,
so a 10 % window is shorter than the 2 s trajectory window) whole files can go to one split instead
(:func:`split_files`). Each file's windows depend on the seed and its name only, not on the other
files.
"""
from __future__ import annotations

import zlib
from pathlib import Path
from typing import Dict, List, Sequence, Tuple

import numpy as np

from minifilm.dataset.manifest import MotionFile

SPLITS = ("train", "val", "test")


def split_segments(n_frames: int, rng: np.random.Generator,
                   fractions: Sequence[float] = (0.8, 0.1, 0.1)) -> List[Tuple[int, int, str]]:
    """Cut ``[0, n_frames)`` into contiguous segments ``(start, stop, split)`` (docs/original-code.md §8.2).

    The validation and test windows are ``floor(f L)`` frames each; they never overlap, their
    order and positions are random (seeded by ``rng``); the rest, up to three pieces, is train.
    """
    L = int(n_frames)
    sizes = {"val": int(np.floor(fractions[1] * L)), "test": int(np.floor(fractions[2] * L))}
    free = L - sizes["val"] - sizes["test"]
    cuts = np.sort(rng.integers(0, free + 1, size=2))          # train pieces: [0,c0), ..., [c1, free)
    order = ["val", "test"] if rng.random() < 0.5 else ["test", "val"]
    pieces = [("train", int(cuts[0])), (order[0], sizes[order[0]]), ("train", int(cuts[1] - cuts[0])),
              (order[1], sizes[order[1]]), ("train", int(free - cuts[1]))]
    out, a = [], 0
    for split, size in pieces:
        if size > 0:
            out.append((a, a + size, split))
            a += size
    return out


def apply_gap(segments: List[Tuple[int, int, str]], gap: int) -> List[Tuple[int, int, str]]:
    """Shrink segments by ``gap`` frames at every border with a segment of another split."""
    out = []
    for i, (a, b, s) in enumerate(segments):
        if i > 0 and segments[i - 1][2] != s:
            a += gap
        if i + 1 < len(segments) and segments[i + 1][2] != s:
            b -= gap
        if b > a:
            out.append((a, b, s))
    return out


def split_files(files: Sequence[MotionFile], seed: int,
                fractions: Sequence[float] = (0.8, 0.1, 0.1)) -> Dict[Path, str]:
    """Whole-file splits: per style, the files in a seeded random order give ``round(f n)`` files
    to val and to test (at least one each once a style has 3 files), the rest to train."""
    by_style: Dict[str, List[MotionFile]] = {}
    for f in files:
        by_style.setdefault(f.style, []).append(f)
    out = {}
    for style, group in sorted(by_style.items()):
        group = sorted(group, key=lambda f: Path(f.path).name)
        rng = np.random.default_rng([int(seed), zlib.crc32(style.encode("utf-8"))])
        order = rng.permutation(len(group))
        n = len(group)
        n_val, n_test = (_file_count(fr, n) for fr in fractions[1:])
        for rank, i in enumerate(order):
            out[Path(group[i].path)] = "val" if rank < n_val else "test" if rank < n_val + n_test else "train"
    return out


def _file_count(fraction: float, n: int) -> int:
    """Files of a style for a split of ``fraction``: rounded, at least 1 once there are 3 files."""
    k = int(round(fraction * n))
    return max(1, k) if fraction > 0 and n >= 3 else k if n >= 3 else 0


def file_rng(seed: int, f: MotionFile) -> np.random.Generator:
    """A generator that depends on the seed and the file's name only (not on the other files)."""
    return np.random.default_rng([int(seed), zlib.crc32(Path(f.path).name.encode("utf-8"))])
