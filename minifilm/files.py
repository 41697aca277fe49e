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
* :func:`check_writable` says, before any long computation, whether a path can be written;
* :func:`read_npz` is the one reader of the ``.npz`` archives minifilm writes: it checks every
  member's declared size against the file and a memory budget *before* allocating, never unpickles,
  and turns every way an archive can be broken into one error naming the file.

A writer killed midway (power cut, SIGKILL) cannot clean up after itself; its temporary file carries
its process id, and the next writer of the same target removes temporaries whose process is gone.

Files get the permissions a plain ``open(path, "w")`` would give (0666 less the umask): the
temporary files of ``tempfile`` are created 0600, which would make outputs private by accident.

This module imports nothing of minifilm but its errors, so every layer may use it.
"""
from __future__ import annotations

import contextlib
import os
import re
import shutil
import tempfile
import zipfile
import zlib
from pathlib import Path
from typing import BinaryIO, Callable, Dict, Iterator, Optional, Type, Union

import numpy as np

from minifilm.errors import InputError, OutputPathError

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


def remove_stale_temporaries(target: PathLike) -> int:
    """Delete temporary siblings of ``target`` left by writers that were killed (their process no
    longer exists); returns how many were removed. Temporaries of live writers are left alone."""
    target = Path(target)
    pattern = re.compile(r"^\." + re.escape(target.name) + r"\.(\d+)\..*\.(tmp|part|old)$")
    removed = 0
    try:
        siblings = list(target.parent.iterdir())
    except OSError:
        return 0
    for p in siblings:
        m = pattern.match(p.name)
        if m and int(m.group(1)) != os.getpid() and not _process_alive(int(m.group(1))):
            with contextlib.suppress(OSError):
                shutil.rmtree(p) if p.is_dir() and not p.is_symlink() else p.unlink()
                removed += 1
    return removed


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
    _check_name_lengths(path, existing, what)
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


@contextlib.contextmanager
def atomic_path(path: PathLike, what: str = "output") -> Iterator[str]:
    """``with atomic_path(out, "GIF") as tmp:`` write the file named ``tmp``; on success it
    replaces ``out``. For writers that want a file name rather than a file object (Pillow,
    matplotlib's movie writers). A missing parent folder is created, as by :func:`atomic_write`.
    The temporary file is created at once beside ``out``, so a path that cannot be written raises
    OutputPathError before the body's work; on any failure the temporary file is removed and
    ``out`` is left as it was."""
    target = Path(path)
    if target.is_dir():
        raise OutputPathError(f"cannot write {what} to {target}: it is a folder, give a file name")
    folder = target.parent
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        raise OutputPathError(f"cannot write {what} to {target}: folder {folder} cannot be made "
                              "(a file is in the way, or its parent is not writable)") from None
    try:
        remove_stale_temporaries(target)
        fd, tmp = tempfile.mkstemp(prefix=_temp_prefix(target), suffix=".part", dir=folder)
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
    remove_stale_temporaries(path)
    fd, tmp = tempfile.mkstemp(prefix=_temp_prefix(path), suffix=".tmp", dir=path.parent)
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
    remove_stale_temporaries(path)
    tmp = Path(tempfile.mkdtemp(prefix=_temp_prefix(path), suffix=".tmp", dir=path.parent))
    try:
        os.chmod(tmp, 0o777 & ~_umask())
        yield tmp
        old = None
        if path.exists():
            old = Path(tempfile.mkdtemp(prefix=_temp_prefix(path), suffix=".old", dir=path.parent))
            os.replace(path, old / "folder")
        os.replace(tmp, path)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


#: The most a single .npz archive may ask for when read: far above any minifilm file (the paper's
#: model and its Adam state are ~70 MB), far below a machine's memory.
MAX_NPZ_BYTES = 1 << 30


def read_npz(path: PathLike, what: str = "archive", error: Type[InputError] = InputError,
             max_bytes: Optional[int] = MAX_NPZ_BYTES) -> Dict[str, np.ndarray]:
    """Every array of the ``.npz`` at ``path`` -> {name: array}, or ``error`` naming ``what`` and the file.

    Before reading, each member's ``.npy`` header is checked: no object dtype (that would be a
    pickle), and the size it declares must fit in the member and, summed, in ``max_bytes`` (None: no
    budget, for dataset caches, which hold whatever data the user has). So a
    truncated or forged archive is an error, never a huge allocation or a half-read array.
    FileNotFoundError when there is no file at all (the caller knows better what that means).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{what} {path}: no such file")
    where = f"{what} {path}"
    try:
        with zipfile.ZipFile(path) as archive:
            total = 0
            for info in archive.infolist():
                if not info.filename.endswith(".npy"):
                    raise error(f"{where}: member {info.filename!r} is not a .npy array")
                with archive.open(info) as member:
                    version = np.lib.format.read_magic(member)
                    header = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                              else np.lib.format.read_array_header_2_0)
                    shape, _, dtype = header(member)
                if dtype.hasobject:
                    raise error(f"{where}: array {info.filename[:-4]!r} holds Python objects (refused: never unpickled)")
                nbytes = int(np.prod(shape, dtype=np.float64)) * dtype.itemsize
                if nbytes > info.file_size:
                    raise error(f"{where}: array {info.filename[:-4]!r} declares {nbytes:,} bytes but holds "
                                f"{info.file_size:,} (truncated or forged)")
                total += nbytes
                if max_bytes is not None and total > max_bytes:
                    raise error(f"{where}: its arrays would take more than {max_bytes / 2**30:g} GiB of memory")
        with np.load(path, allow_pickle=False) as z:
            return {name: z[name] for name in z.files}
    except error:
        raise
    except (zipfile.BadZipFile, zipfile.LargeZipFile, ValueError, OSError, EOFError, KeyError, MemoryError,
            zlib.error, NotImplementedError) as e:
        raise error(f"{where}: not a readable .npz archive ({type(e).__name__}: {e})") from None
