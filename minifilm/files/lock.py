"""One writer at a time: a lock on a folder that a command writes (a run folder).

``with folder_lock(run):`` holds an exclusive lock on the file ``.<run>.lock`` beside the folder
(beside, not inside: the folder itself is replaced whole when a run is written again). A second
writer of the same folder gets :class:`FolderInUseError` at once, naming the process that holds it,
instead of two trainings mixing their files. The operating system releases the lock when its
process ends in any way, SIGKILL included, so a killed writer never leaves the folder locked. The
lock file stays (it is empty but for the holder's process id): removing it would let a third
writer lock a new file while a second still waits on the old one.
"""
from __future__ import annotations

import contextlib
import os
from pathlib import Path
from typing import Iterator

from minifilm.errors import OutputPathError

try:                                    # POSIX
    import fcntl
except ImportError:                     # Windows
    fcntl = None
    import msvcrt  # Windows has no fcntl; its own byte-range lock instead


class FolderInUseError(OutputPathError):
    """Another process is writing the folder."""


def lock_path(folder) -> Path:
    folder = Path(os.path.abspath(folder))
    return folder.parent / f".{folder.name}.lock"


def _try_lock(fd: int) -> bool:
    try:
        if fcntl is not None:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        else:
            msvcrt.locking(fd, msvcrt.LK_NBLCK, 1)
        return True
    except OSError:
        return False


@contextlib.contextmanager
def folder_lock(folder, what: str = "run folder") -> Iterator[None]:
    """Hold the lock of ``folder`` for the block (see the module docstring)."""
    path = lock_path(folder)
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0), 0o666)
    except OSError as e:
        raise OutputPathError(f"cannot lock {what} {folder}: {path}: {e.strerror or e}") from None
    try:
        if not _try_lock(fd):
            holder = os.pread(fd, 32, 0).decode("ascii", "replace").strip() if hasattr(os, "pread") else ""
            who = f"process {holder}" if holder.isdigit() else "another process"
            raise FolderInUseError(f"{what} {folder} is in use by {who} (another minifilm command writing "
                                   "it); wait for it to finish or choose another folder")
        os.ftruncate(fd, 0)
        os.pwrite(fd, str(os.getpid()).encode(), 0) if hasattr(os, "pwrite") else os.write(fd, str(os.getpid()).encode())
        yield
    finally:
        os.close(fd)                    # releases the lock
