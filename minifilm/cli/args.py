"""Argument types for the command line: each checks its value when the arguments are parsed, so a
bad value is one clear line before any work starts (argparse prints it and exits 2)."""
from __future__ import annotations

import argparse
import math
import os
from pathlib import Path

from minifilm.files import note_input


def _number(text: str, kind=float):
    try:
        value = kind(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a {'whole ' if kind is int else ''}number") from None
    if kind is float and not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
    return value


def in_range(low=None, high=None, kind=float, low_open=False):
    """A number in [low, high] (``low_open``: low excluded)."""
    def check(text: str):
        v = _number(text, kind)
        if low is not None and (v < low or (low_open and v == low)):
            raise argparse.ArgumentTypeError(f"{v} must be {'>' if low_open else '>='} {low}")
        if high is not None and v > high:
            raise argparse.ArgumentTypeError(f"{v} must be <= {high}")
        return v
    return check


def seconds_at_least(low: float):
    return in_range(low, 24 * 3600.0)


def positive(kind=float, high=None):
    return in_range(0, high, kind, low_open=True)


def png_path(text: str) -> Path:
    """An output picture path; '.png' is added when it has no suffix (matplotlib would add it).
    A folder is refused rather than quietly becoming 'folder.png' beside it."""
    p = Path(text)
    if p.is_dir():
        raise argparse.ArgumentTypeError(f"{text} is a folder; give a file name (e.g. {p / 'phases.png'})")
    if p.suffix and p.suffix.lower() != ".png":     # found now, not when the drawing is saved
        raise argparse.ArgumentTypeError(f"{text}: a PNG picture is written here; give a name ending in .png")
    return p if p.suffix else p.with_suffix(".png")


def output_folder(text: str) -> Path:
    """A folder to write into: it may not exist yet, but it may not be a file, and the nearest
    existing folder above it must be writable."""
    p = Path(text)
    if p.exists() and not p.is_dir():
        raise argparse.ArgumentTypeError(f"{text} is a file, expected a folder")
    existing = p
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise argparse.ArgumentTypeError(f"{text}: {existing} is a file, not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise argparse.ArgumentTypeError(f"{text}: folder {existing} is not writable")
    return p


def input_path(text: str) -> Path:
    """A file or folder the command reads. It is recorded as an input (minifilm/files/output_targets.py),
    so that no output of the same command may replace it: ``view a.bvh --html a.bvh`` is refused
    before any work."""
    p = Path(text)
    note_input(p)
    return p
