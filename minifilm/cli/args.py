"""Argument types for the command line: each checks its value when the arguments are parsed, so a
bad value is one clear line before any work starts (argparse prints it and exits 2)."""
from __future__ import annotations

import argparse
import math
import os
from pathlib import Path

from minifilm.errors import OutputPathError
from minifilm.files import check_not_state, note_input


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


#: what an output of each format is called, for the messages
FORMATS = {".png": "a PNG picture", ".gif": "an animated GIF", ".bvh": "a BVH file", ".html": "an HTML page",
           ".htm": "an HTML page", ".mp4": "an MP4 video", ".md": "a markdown text", ".txt": "a text"}


def output_file(*suffixes: str, add: bool = False):
    """The type of an option that writes one file in a format named by ``suffixes``: another
    suffix is refused when the arguments are parsed (``--gif x.png`` would hold a GIF under a
    PNG's name), and so is a folder, rather than quietly becoming 'folder.gif' beside it. A name
    without a suffix is kept as it is (``--out /dev/null`` stays /dev/null, and is refused as a
    device), except that ``add`` adds the first suffix to a new one (matplotlib adds '.png'
    itself). The function carries ``output = "file"`` and ``suffixes``: tests find every writing
    option of every command by them."""
    def check(text: str) -> Path:
        p = Path(text)
        if not text or not p.name:
            raise argparse.ArgumentTypeError(f"{text!r}: give a file name ending in {suffixes[0]}")
        if p.is_dir():
            raise argparse.ArgumentTypeError(f"{text} is a folder; give a file name (e.g. {p / ('out' + suffixes[0])})")
        if p.suffix and p.suffix.lower() not in suffixes:
            raise argparse.ArgumentTypeError(
                f"{text}: {FORMATS.get(suffixes[0], 'a ' + suffixes[0] + ' file')} is written here; give a name "
                f"ending in {' or '.join(suffixes)}, not {p.suffix}")
        return p.with_suffix(suffixes[0]) if add and not p.suffix and not os.path.lexists(p) else p
    check.output, check.suffixes = "file", tuple(suffixes)
    check.__name__ = f"output_file{suffixes}"
    return check


#: an output picture path; '.png' is added when it has no suffix
png_path = output_file(".png", add=True)
gif_path = output_file(".gif")
html_path = output_file(".html", ".htm")
bvh_path = output_file(".bvh")
mp4_path = output_file(".mp4")
markdown_path = output_file(".md", ".txt")


def non_empty(flag: str):
    """Text that must say something: ``--to ''`` would otherwise name the current folder."""
    def check(text: str) -> str:
        if not text.strip():
            raise argparse.ArgumentTypeError(f"{text!r} is empty; give a name or a path")
        return text
    return check


def output_folder(text: str) -> Path:
    """A folder to write into: it may not exist yet, but it may not be a file, and the nearest
    existing folder above it must be writable. An empty name is refused (Path('') is the current
    folder, which nobody means by it)."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f"{text!r}: give a folder name")
    p = Path(text)
    if p.exists() and not p.is_dir():
        raise argparse.ArgumentTypeError(f"{text} is a file, expected a folder")
    existing = p
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise argparse.ArgumentTypeError(f"{text}: {existing} is a file, not a folder")
    if not os.access(existing, os.W_OK | os.X_OK) or not os.stat(existing).st_mode & 0o222:   # root: the mode bits
        raise argparse.ArgumentTypeError(f"{text}: folder {existing} is not writable")
    try:                  # a run's data/, cache/ or generated/ is no folder to write into
        check_not_state(p)
    except OutputPathError as e:
        raise argparse.ArgumentTypeError(str(e)) from None
    return p


output_folder.output = "folder"


def input_path(text: str) -> Path:
    """A file or folder the command reads. It is recorded as an input (minifilm/files/output_targets.py),
    so that no output of the same command may replace it: ``generate --skeleton-bvh a.bvh --out a.bvh``
    is refused
    before any work."""
    p = Path(text)
    note_input(p)
    return p


def add_network_source(ap) -> None:
    """The network a command drives, one of two: --params (the authors' released network, with
    --styles PACK beside its own styles) or --run (a run folder written by minifilm train)."""
    src = ap.add_mutually_exclusive_group(required=True)
    src.add_argument("--params", type=input_path, help="the released network's parameter folder")
    src.add_argument("--run", type=input_path, help="a run folder written by minifilm train")
    ap.add_argument("--styles", type=input_path,
                    help="with --params: a style pack folder (minifilm finetune --params ... --out PACK) whose "
                         "styles join the network's own")
