"""Names that come from data: one rule for every style name, and safe file names made from them.

A style's name enters from many places — a manifest's ``style`` column, a file name
(``<Style>_<Gait>.bvh``), a run's ``styles.npz`` and ``starts.npz``, ``finetune --name``, the
released network's ``styles.txt`` — and leaves as terminal output and as file names
(``generated/<Style>.bvh``, ``model-<NAME>.npz``). So every such name is checked where it enters
(:func:`check_name`): printable text (no escape sequences can reach a terminal, no invisible
characters), no path separators, no ``..``, no spaces at either end, at most
:data:`MAX_NAME_LENGTH` characters. A file named after it is made by :func:`file_name` and placed
by :func:`child_path`, which cannot leave its folder whatever the name holds.

Two names may give one file name (``A:B`` and ``A_B``; ``Neutral`` and ``neutral`` on the
case-folding disks of macOS and Windows). minifilm compares the names it makes case-folded and
NFC-normalised (:func:`same_file_key`) on every system, so what it writes on Linux also copies
whole to a Mac: where the names a command makes must each be a file of their own (retargeted
files, a run's fine-tuned checkpoints, a made data set's files) it refuses such a pair before
writing anything (:func:`shared_file_names`); where any distinct name will do (a run's generated
motion) :func:`file_names` numbers the later ones.
"""
from __future__ import annotations

import re
import unicodedata
from pathlib import Path
from typing import Dict, Iterable, List, Tuple, Type

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
    space becomes ``_`` (no hidden files), and Windows' reserved device names get a ``_`` prefix.
    The name is NFC-composed first, so its two Unicode spellings make one file name."""
    # composed first: 'e' + a combining accent (as macOS stores names) is 'é', not 'e_'
    safe = _UNSAFE.sub("_", unicodedata.normalize("NFC", name))[:MAX_NAME_LENGTH * 2] or "_"
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


def shared_file_names(names: Iterable[str]) -> List[Tuple[str, List[str]]]:
    """The file names (:func:`file_name`) that more than one of ``names`` would be written to, each
    with those names: ``a:b``, ``a_b`` and ``a?b`` all become ``a_b``, ``Neutral`` and ``neutral`` one
    file on a case-folding disk (:func:`same_file_key`), and a name given twice meets itself.
    Empty when every name gets a file of its own. A writer that names files after inputs or styles checks this before writing any."""
    groups: Dict[str, List[str]] = {}
    first: Dict[str, str] = {}
    for name in names:
        made = file_name(name)
        key = same_file_key(made)
        first.setdefault(key, made)
        groups.setdefault(key, []).append(name)     # the same name twice: two writers of one file too
    return [(first[key], group) for key, group in groups.items() if len(group) > 1]


def file_names(names: Iterable[str]) -> Dict[str, str]:
    """name -> a file name (:func:`file_name`) for each of ``names``, distinct even where two
    names would give the same file name or differ only in case (macOS and Windows fold case):
    a later one gets ``-2``, ``-3``, ... (also where they differ only in Unicode normalisation),
    except that a name which is a safe file name already keeps it."""
    key = same_file_key
    names = list(dict.fromkeys(names))
    taken, made = set(), {}
    # a name that is a safe file name already keeps it: 'A_B' stays A_B and 'A:B' becomes A_B-2
    for name in sorted(names, key=lambda n: file_name(n) != n):
        base = candidate = file_name(name)
        n = 1
        while key(candidate) in taken:
            n += 1
            candidate = f"{base}-{n}"
        taken.add(key(candidate))
        made[name] = candidate
    return {name: made[name] for name in names}


def child_path(folder, name: str, suffix: str = "") -> Path:
    """``folder / (file_name(name) + suffix)``: always a direct child of ``folder``."""
    folder = Path(folder)
    path = folder / (file_name(name) + suffix)
    if path.parent != folder or path.name in ("", ".", ".."):      # cannot happen; kept as the guarantee
        raise InputError(f"{name!r}: would not name a file inside {folder}")
    return path


def few(names: Iterable, limit: int = 5) -> str:
    """The first ``limit`` of ``names`` (each escaped and cut to 60 characters) and how many more:
    an error message stays one short line whatever a file holds (300,000 unknown keys)."""
    names = list(names)
    shown = [r if len(r) <= 60 else r[:56] + "...'" for r in map(repr, names[:limit])]
    return ", ".join(shown) + (f" and {len(names) - limit:,} more" if len(names) > limit else "")

