"""Writing files and folders so that a reader never sees half of one: the one home for atomic writes.

Every writer in minifilm (BVH files, dataset caches, checkpoints, style libraries, the released
network's folder, pictures) goes through here:

* :func:`atomic_write` writes a file into a temporary sibling, flushes it to disk and renames it
  over the target (``os.replace`` is atomic on one file system), so a crash or a kill leaves either
  the old file or the new one, never a mix, and no temporary debris;
* :func:`atomic_directory` does the same for a whole folder: the caller fills a temporary sibling
  folder, which then replaces the target (an old folder of that name is moved aside first and
  removed after the swap, so nothing of it survives in the new one);
* :func:`atomic_path` is the same for writers that want a file name (Pillow, matplotlib);
* :func:`check_writable` says, before any long computation, whether a path can be written.

Files get the permissions a plain ``open(path, "w")`` would give (0666 less the umask): the
temporary files of ``tempfile`` are created 0600, which would make outputs private by accident.

This module imports nothing from minifilm, so every layer may use it.
"""
from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from pathlib import Path
from typing import BinaryIO, Callable, Iterator, Union

PathLike = Union[str, os.PathLike]


class OutputPathError(OSError):
    """An output path cannot be written (a missing or read-only folder, a folder given as a file
    name); the message names the path and says why."""


def _umask() -> int:
    """The process's umask (reading it means setting it, so set it straight back)."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


def check_writable(path: PathLike, what: str = "output") -> Path:
    """Raise OutputPathError unless a file can be written at ``path``: its folder exists (or can
    be made inside an existing, writable folder), and ``path`` is not itself a folder. Call it
    before the work that produces the file, so a typo costs nothing."""
    path = Path(path)
    if path.is_dir():
        raise OutputPathError(f"{what} {path}: is a folder, expected a file name")
    folder = path.parent if str(path.parent) else Path(".")
    existing = folder
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise OutputPathError(f"{what} {path}: {existing} is a file, not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise OutputPathError(f"{what} {path}: folder {existing} is not writable")
    return path


@contextlib.contextmanager
def atomic_path(path: PathLike, what: str = "output") -> Iterator[str]:
    """``with atomic_path(out, "GIF") as tmp:`` write the file named ``tmp``; on success it
    replaces ``out``. For writers that want a file name rather than a file object (Pillow,
    matplotlib's movie writers). The temporary file is created at once beside ``out``, so a path
    that cannot be written raises OutputPathError before the body's work; on any failure the
    temporary file is removed and ``out`` is left as it was."""
    target = Path(path)
    if target.is_dir():
        raise OutputPathError(f"cannot write {what} to {target}: it is a folder, give a file name")
    folder = target.parent
    if not folder.is_dir():
        reason = "does not exist" if not folder.exists() else "is not a folder"
        raise OutputPathError(f"cannot write {what} to {target}: folder {folder} {reason}")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".part", dir=folder)
    except OSError as e:
        raise OutputPathError(f"cannot write {what} to {target}: {e.strerror or e}") from None
    os.close(fd)
    try:
        yield tmp
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            os.remove(tmp)
        raise


def atomic_write(path: PathLike, write: Callable[[BinaryIO], None]) -> Path:
    """Create or replace the file ``path`` with what ``write(f)`` writes to a binary file ``f``.

    The parent folder is created when missing. On any error (or KeyboardInterrupt) the temporary
    file is removed and the old file, if any, is left as it was.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
    return path


def atomic_write_text(path: PathLike, text: str) -> Path:
    """:func:`atomic_write` of a UTF-8 text with ``\\n`` line ends."""
    return atomic_write(path, lambda f: f.write(text.encode("utf-8")))


def atomic_savez(path: PathLike, arrays: dict) -> Path:
    """:func:`atomic_write` of an uncompressed ``.npz`` archive of ``arrays`` (name -> array).

    Nothing is pickled: object arrays are refused here, so every archive minifilm writes loads
    with ``allow_pickle=False``.
    """
    # numpy here, not at the top: the command line imports this module before it sets the BLAS
    # thread count of its batch-1 commands (minifilm/cli/__init__.py), and OpenBLAS reads it once,
    # when numpy is first imported
    import numpy as np
    for name, a in arrays.items():
        if np.asarray(a).dtype == object:
            raise TypeError(f"atomic_savez({path}): array {name!r} has dtype object (would be pickled)")
    return atomic_write(path, lambda f: np.savez(f, **arrays))


@contextlib.contextmanager
def atomic_directory(path: PathLike) -> Iterator[Path]:
    """``with atomic_directory(folder) as tmp:`` fill ``tmp``; on success it becomes ``folder``.

    ``tmp`` is a new empty sibling of ``folder``. When the block ends normally, an existing
    ``folder`` is renamed aside, ``tmp`` is renamed to ``folder`` and the old one is deleted, so
    a reader sees either the complete old folder or the complete new one (for the instant between
    the two renames, none). When the block raises, ``tmp`` is deleted and ``folder`` is untouched.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.exists() and not path.is_dir():
        raise NotADirectoryError(f"{path}: exists and is not a folder")
    tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent))
    try:
        os.chmod(tmp, 0o777 & ~_umask())
        yield tmp
        old = None
        if path.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".old", dir=path.parent))
            os.replace(path, old / "folder")
        os.replace(tmp, path)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
