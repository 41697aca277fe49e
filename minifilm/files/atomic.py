"""Writing files and folders so that a reader never sees half of one.

* :func:`atomic_write` writes a file into a temporary sibling, flushes it to disk and renames it
  over the target (``os.replace`` is atomic on one file system), so a crash or a kill leaves either
  the old file or the new one, never a mix;
* :func:`atomic_path` is the same for writers that want a file name (Pillow, matplotlib);
* :func:`atomic_directory` does it for a whole folder: the caller fills a temporary sibling folder,
  which is then exchanged with the target in one step (Linux's ``renameat2(RENAME_EXCHANGE)``;
  elsewhere two renames, undone by the next writer if a kill falls between them);
* :func:`check_writable` says, before any long computation, whether a path can be written.

What a target may be (a new path, a regular file, a link to one; never a device, FIFO, socket,
read-only file or an input of the running command) is decided in :mod:`minifilm.files.output_targets`,
and every writer here asks it first. A replaced file keeps its permission bits; a new one gets
what a plain ``open(path, "w")`` would give (0666 less the umask), not the 0600 of ``tempfile``.

A writer killed midway (power cut, SIGKILL) cannot clean up after itself; its temporary carries its
process id, and the next writer into the same folder removes temporaries whose process is gone,
whatever target they were for.
An error while writing (a full disk) is an OutputPathError naming the target.
"""
from __future__ import annotations

import contextlib
import ctypes
import errno
import os
import re
import shutil
import stat
import tempfile
from pathlib import Path
from typing import BinaryIO, Callable, Iterator, Optional, Union

import numpy as np

from minifilm.errors import OutputPathError
from minifilm.files.lock import folder_lock
from minifilm.files.output_targets import folder_target, output_target

PathLike = Union[str, os.PathLike]


def _umask() -> int:
    """The process's umask (reading it means setting it, so set it straight back)."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _temp_prefix(target: Path) -> str:
    """Temporary siblings of ``target`` are named ``.<name>.<pid>.<random><suffix>``."""
    return f".{target.name}.{os.getpid()}."


def _process_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:         # somebody else's process
        return True
    return True


#: a temporary of an atomic writer: ``.<target name>.<process id>.<8 random characters><suffix>``
_TEMPORARY = re.compile(r"^\.(?P<name>.+)\.(?P<pid>\d+)\.[a-z0-9_]{8}\.(?P<kind>tmp|part|old)$", re.DOTALL)


def remove_stale_temporaries(target: PathLike) -> int:
    """Delete the temporaries that writers killed midway (their process no longer exists) left in
    the folder of ``target``, for any target there (a killed ``train --out runA`` would otherwise
    leave its temporary folder for good when the user then picks another name); returns how many
    were removed. Temporaries of live writers are left alone. A folder moved aside by a writer
    killed between its two renames is put back first, when its place is empty."""
    target = Path(target)
    removed = 0
    try:
        entries = [e.name for e in os.scandir(target.parent) if e.name.startswith(".")]
    except OSError:
        return 0
    for name in entries:
        m = _TEMPORARY.match(name)
        if not m:
            continue
        pid, p = int(m["pid"]), target.parent / name
        if pid == os.getpid() or _process_alive(pid):
            continue
        own = target.parent / m["name"]
        if m["kind"] == "old" and not os.path.lexists(own) and (p / "folder").is_dir():
            with contextlib.suppress(OSError):
                os.replace(p / "folder", own)
        with contextlib.suppress(OSError):
            shutil.rmtree(p) if p.is_dir() and not p.is_symlink() else p.unlink()
            removed += 1
    return removed


def check_writable(path: PathLike, what: str = "output") -> Path:
    """Raise OutputPathError unless a file can be written at ``path``: what is there may be
    replaced (:func:`minifilm.files.output_targets.output_target`), and its folder exists (or can be made
    inside an existing, writable folder). Call it before the work that produces the file, so a
    typo costs nothing."""
    path = Path(path)
    target = output_target(path, what)
    folder = target.parent if str(target.parent) else Path(".")
    existing = folder
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise OutputPathError(f"{what} {path}: {existing} is a file, not a folder")
    if not os.access(existing, os.W_OK | os.X_OK) or not os.stat(existing).st_mode & 0o222:   # root: the mode bits
        raise OutputPathError(f"{what} {path}: folder {existing} is not writable")
    _check_name_lengths(target, existing, what)
    return path


#: Bytes a temporary file's name adds to its target's (".name.<pid>.<random>.tmp").
_TEMP_NAME_EXTRA = 32


def _check_name_lengths(path: Path, existing: Path, what: str) -> None:
    """OutputPathError when a name in ``path`` below ``existing`` is too long for the file system
    (found now rather than after the work, when the temporary file is made)."""
    try:
        name_max = os.pathconf(existing, "PC_NAME_MAX")
    except (OSError, ValueError):
        name_max = 255
    for part in path.relative_to(existing).parts if path.is_relative_to(existing) else (path.name,):
        extra = _TEMP_NAME_EXTRA if part == path.name else 0
        if len(os.fsencode(part)) + extra > name_max:
            raise OutputPathError(f"{what} {path}: the name {part[:40]}... is too long for this file system "
                                  f"({len(os.fsencode(part))} bytes; at most {name_max - extra} here)")


def _new_file_mode(target: Path) -> int:
    """The permission bits the written file gets: the replaced file's, else 0666 less the umask."""
    try:
        return stat.S_IMODE(os.stat(target).st_mode)
    except OSError:
        return 0o666 & ~_umask()


def _make_temporary(path: Path, what: str, suffix: str):
    """(target, fd, temporary name): the checked target of ``path`` and a new temporary beside it."""
    target = output_target(path, what)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
    except OSError:
        raise OutputPathError(f"cannot write {what} to {path}: folder {target.parent} cannot be made "
                              "(a file is in the way, or its parent is not writable)") from None
    try:
        remove_stale_temporaries(target)
        fd, tmp = tempfile.mkstemp(prefix=_temp_prefix(target), suffix=suffix, dir=target.parent)
    except OSError as e:
        raise OutputPathError(f"cannot write {what} to {path}: {e.strerror or e}") from None
    return target, fd, tmp


def _finish(tmp: str, target: Path, path: Path, what: str) -> None:
    """Give the temporary its permissions and rename it over the target, which is checked again
    (it may have changed while the work ran)."""
    mode = _new_file_mode(target)
    if output_target(path, what) != target:
        raise OutputPathError(f"cannot write {what} to {path}: it changed while the output was being made")
    os.chmod(tmp, mode)
    os.replace(tmp, target)


@contextlib.contextmanager
def atomic_path(path: PathLike, what: str = "output") -> Iterator[str]:
    """``with atomic_path(out, "GIF") as tmp:`` write the file named ``tmp``; on success it
    replaces ``out``. For writers that want a file name rather than a file object (Pillow,
    matplotlib's movie writers). A missing parent folder is created, as by :func:`atomic_write`.
    The target is checked and the temporary file created at once, so a path that cannot be
    written raises OutputPathError before the body's work; on any failure the temporary file is
    removed and ``out`` is left as it was."""
    path = Path(path)
    target, fd, tmp = _make_temporary(path, what, ".part")
    os.close(fd)
    try:
        try:
            yield tmp
        except OSError as e:
            if isinstance(e, OutputPathError) or not (e.errno in _WRITE_ERRNOS or e.filename == tmp):
                raise
            raise OutputPathError(f"cannot write {what} to {path}: {e.strerror or e}") from None
        _finish(tmp, target, path, what)
    except BaseException:
        with contextlib.suppress(OSError):
            os.remove(tmp)
        raise


#: errors of writing a file (rather than of reading another one): no space, quota, too large, I/O
_WRITE_ERRNOS = {errno.ENOSPC, errno.EFBIG, errno.EIO, errno.EROFS, getattr(errno, "EDQUOT", errno.ENOSPC)}


def atomic_write(path: PathLike, write: Callable[[BinaryIO], None], what: str = "output") -> Path:
    """Create or replace the file ``path`` with what ``write(f)`` writes to a binary file ``f``.

    The parent folder is created when missing. On any error (or KeyboardInterrupt) the temporary
    file is removed and the old file, if any, is left as it was; an OSError while writing (no
    space left) becomes an OutputPathError naming ``path``.
    """
    path = Path(path)
    target, fd, tmp = _make_temporary(path, what, ".tmp")
    try:
        try:
            with os.fdopen(fd, "wb") as f:
                write(f)
                f.flush()
                os.fsync(f.fileno())
        except OutputPathError:
            raise
        except OSError as e:
            raise OutputPathError(f"cannot write {what} to {path}: {e.strerror or e}") from None
        _finish(tmp, target, path, what)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
    return path


def atomic_write_text(path: PathLike, text: str, what: str = "output") -> Path:
    """:func:`atomic_write` of a UTF-8 text with ``\\n`` line ends."""
    return atomic_write(path, lambda f: f.write(text.encode("utf-8")), what)


def atomic_savez(path: PathLike, arrays: dict, what: str = "output") -> Path:
    """:func:`atomic_write` of an uncompressed ``.npz`` archive of ``arrays`` (name -> array).

    Nothing is pickled: object arrays are refused here, so every archive minifilm writes loads
    with ``allow_pickle=False``.
    """
    for name, a in arrays.items():
        if np.asarray(a).dtype == object:
            raise TypeError(f"atomic_savez({path}): array {name!r} has dtype object (would be pickled)")
    return atomic_write(path, lambda f: np.savez(f, **arrays), what)


def _check_replaceable(path: Path, what: str, replaceable: Optional[Callable[[str], bool]]) -> None:
    """OutputPathError when the existing folder ``path`` holds a name its writer does not make."""
    try:
        names = [n for n in os.listdir(path) if not n.startswith(".")]
    except FileNotFoundError:
        return
    except OSError as e:
        raise OutputPathError(f"cannot write {what} {path}: {e.strerror or e}") from None
    foreign = sorted(n for n in names if replaceable is None or not replaceable(n))
    if foreign:
        shown = ", ".join(foreign[:3]) + (f" and {len(foreign) - 3} more" if len(foreign) > 3 else "")
        raise OutputPathError(f"cannot write {what} {path}: the folder holds files that are not part of a "
                              f"{what} ({shown}), which writing it anew would delete; give a new or empty folder")


def _exchange(a: Path, b: Path) -> bool:
    """Swap the two existing paths in one step (Linux renameat2 RENAME_EXCHANGE); False where the
    system or the file system cannot."""
    try:
        renameat2 = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError):
        return False
    at_fdcwd, rename_exchange = -100, 2
    return renameat2(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), rename_exchange) == 0


@contextlib.contextmanager
def atomic_directory(path: PathLike, what: str = "output folder",
                     replaceable: Optional[Callable[[str], bool]] = None) -> Iterator[Path]:
    """``with atomic_directory(folder) as tmp:`` fill ``tmp``; on success it becomes ``folder``.

    ``tmp`` is a new empty sibling of ``folder``. When the block ends normally, the two are
    exchanged in one step where the system can (so a reader sees the complete old folder or the
    complete new one, never neither) and the old one is deleted; elsewhere the old folder is
    renamed aside first. When the block raises, ``tmp`` is deleted and ``folder`` is untouched.
    ``folder`` may not be a file, nor hold an input of the running command, and an existing
    folder is replaced only when it is empty or every name in it is one the writer makes
    (``replaceable(name)``): ``--out .`` must never delete a user's own files. The folder is
    locked meanwhile (:mod:`minifilm.files.lock`): a second writer of it is refused, naming this
    one. An error writing into ``tmp`` (a full disk) names ``folder``, the folder the user knows.
    """
    path = folder_target(path, what)
    _check_replaceable(path, what, replaceable)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError:
        raise OutputPathError(f"cannot write {what} {path}: its folder cannot be made") from None
    with folder_lock(path, what):
        remove_stale_temporaries(path)
        tmp = Path(tempfile.mkdtemp(prefix=_temp_prefix(path), suffix=".tmp", dir=path.parent))
        try:
            os.chmod(tmp, 0o777 & ~_umask())
            try:
                yield tmp
            except OSError as e:
                raise _named_after(e, tmp, path, what) from None
            folder_target(path, what)            # checked again: the work may have taken long
            _check_replaceable(path, what, replaceable)
            if path.is_dir() and _exchange(tmp, path):
                shutil.rmtree(tmp, ignore_errors=True)          # now the old folder
                return
            old: Optional[Path] = None
            if path.exists():
                old = Path(tempfile.mkdtemp(prefix=_temp_prefix(path), suffix=".old", dir=path.parent))
                os.replace(path, old / "folder")
            os.replace(tmp, path)
            if old is not None:
                shutil.rmtree(old, ignore_errors=True)
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise


def _named_after(e: OSError, tmp: Path, path: Path, what: str) -> OSError:
    """The error ``e`` raised while a folder was filled in ``tmp``, naming ``path`` instead of the
    hidden temporary, which is gone by the time the user reads the message."""
    if isinstance(e, OutputPathError) and str(tmp) in str(e):
        return OutputPathError(str(e).replace(str(tmp), str(path)))
    if not isinstance(e, OutputPathError) and e.errno in _WRITE_ERRNOS:
        inside = os.path.relpath(e.filename, tmp) if e.filename and str(e.filename).startswith(str(tmp)) else ""
        return OutputPathError(f"cannot write {what} {path / inside if inside else path}: {e.strerror or e}")
    return e
