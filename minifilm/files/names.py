"""Names that come from data: one rule for every style name, and safe file names made from them.

A style's name enters from many places — a manifest's ``style`` column, a file name
(``<Style>_<Gait>.bvh``), a run's ``styles.npz`` and ``starts.npz``, ``finetune --name``, the
released network's ``styles.txt`` — and leaves as terminal output and as file names
(``generated/<Style>.bvh``, ``model-<NAME>.npz``). So every such name is checked where it enters
(:func:`check_name`): printable text (no escape sequences can reach a terminal, no invisible
characters), no path separators, no ``..``, no spaces at either end, at most
:data:`MAX_NAME_LENGTH` characters. A file named after it is made by :func:`file_name` and placed
by :func:`child_path`, which cannot leave its folder whatever the name holds.
"""
from __future__ import annotations

import re
import unicodedata
from pathlib import Path
from typing import Dict, Iterable, Type

from minifilm.errors import InputError

#: the longest style name (100STYLE's longest is 13 characters)
MAX_NAME_LENGTH = 64
#: characters a file name made from a name keeps as they are (letters and digits of any script)
_UNSAFE = re.compile(r"[^\w .+\-]")
_WINDOWS_RESERVED = {"CON", "PRN", "AUX", "NUL", *(f"COM{i}" for i in range(10)), *(f"LPT{i}" for i in range(10))}


def name_problem(name) -> str:
    """Why ``name`` may not name a style, or '' when it may."""
    if not isinstance(name, str):
        return f"is a {type(name).__name__}, not text"
    if not name.strip():
        return "is empty or blank"
    if len(name) > MAX_NAME_LENGTH:
        return f"has {len(name)} characters, more than {MAX_NAME_LENGTH}"
    if not name.isprintable():
        bad = next(c for c in name if not c.isprintable())
        return f"holds the control or invisible character {bad!r}"
    if "/" in name or "\\" in name:
        return "holds a path separator (/ or \\)"
    if ".." in name or name == ".":
        return "holds '..' (or is '.')"
    if name != name.strip():
        return "begins or ends with a space"
    return ""


def check_name(name, where: str, error: Type[Exception] = InputError) -> str:
    """``name`` when it may name a style (see the module docstring); ``error`` naming ``where``
    (the file and line, the argument) otherwise. The name is shown escaped, never raw."""
    problem = name_problem(name)
    if problem:
        shown = repr(name[:MAX_NAME_LENGTH]) + ("..." if len(name) > MAX_NAME_LENGTH else "") \
            if isinstance(name, str) else repr(name)
        raise error(f"{where}: the name {shown} {problem}; a name is 1-{MAX_NAME_LENGTH} printable "
                    "characters without / \\ or '..'")
    return name


def file_name(name: str) -> str:
    """A file name (without suffix) for ``name`` that is safe on every common file system:
    characters other than letters, digits, space and ``_ . + -`` become ``_``, a leading dot or
    space becomes ``_`` (no hidden files), and Windows' reserved device names get a ``_`` prefix."""
    safe = _UNSAFE.sub("_", name)[:MAX_NAME_LENGTH * 2] or "_"
    if safe[0] in ". ":
        safe = "_" + safe[1:]
    if safe.rstrip(" .") != safe:
        safe = safe.rstrip(" .") + "_"
    if safe.split(".")[0].upper() in _WINDOWS_RESERVED:
        safe = "_" + safe
    return safe


def same_file_key(file: str) -> str:
    """What two file names share when a case-folding, normalising disk (macOS, Windows) takes them
    for one file: minifilm compares the names it makes this way on every system, so a folder
    written on Linux copies to a Mac whole (``Neutral_FW.bvh`` and ``neutral_FW.bvh`` collide)."""
    return unicodedata.normalize("NFC", file).casefold()


def file_names(names: Iterable[str]) -> Dict[str, str]:
    """name -> a file name (:func:`file_name`) for each of ``names``, distinct even where two
    names would give the same file name or differ only in case (macOS and Windows fold case):
    a later one gets ``-2``, ``-3``, ... (also where they differ only in Unicode normalisation)."""
    key = same_file_key
    taken, result = set(), {}
    for name in names:
        base = candidate = file_name(name)
        n = 1
        while key(candidate) in taken:
            n += 1
            candidate = f"{base}-{n}"
        taken.add(key(candidate))
        result[name] = candidate
    return result


def child_path(folder, name: str, suffix: str = "") -> Path:
    """``folder / (file_name(name) + suffix)``: always a direct child of ``folder``."""
    folder = Path(folder)
    path = folder / (file_name(name) + suffix)
    if path.parent != folder or path.name in ("", ".", ".."):      # cannot happen; kept as the guarantee
        raise InputError(f"{name!r}: would not name a file inside {folder}")
    return path
