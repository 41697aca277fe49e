"""One writer at a time: a lock on a folder that a command writes (a run folder, a style pack).

``with folder_lock(run):`` holds an exclusive lock on the file ``.<name>.lock`` beside the folder.
A second writer of the same folder gets :class:`FolderInUseError` at once, naming the process that
holds it, instead of two commands mixing (or losing) each other's files. The operating system
releases the lock when its process ends in any way, SIGKILL included, so a killed writer never
leaves the folder locked.

The lock belongs to the folder, not to the words that name it: its file sits beside the folder
that the path leads to once every symbolic link is followed, so ``runA``, ``./runA`` and a link
``alias -> runA`` all take one lock. It is beside the folder rather than inside it, and keyed by
the folder's path rather than by the folder itself (its inode), because a run is written anew by
building a new folder and renaming it into place (:func:`minifilm.files.atomic.atomic_directory`):
a lock inside the old folder, or on it, would go away with it while its writer still works, and a
second writer would lock the new one. The path stays while the folders behind it are exchanged.

The holder removes the lock file when it is done. A writer that opened the file just before it was
removed, and then gets the lock, finds the path no longer leads to the file it locked and starts
over, so two writers never hold two different lock files of one folder. A lock file left by a
killed process is unlocked, and used and removed by the next writer.

The lock may be taken again by the thread that holds it (a command that reads a style pack, teaches
and writes it holds the pack's lock, and the writer of the folder takes it again); any other thread
or process is refused.
"""
from __future__ import annotations

import contextlib
import os
import threading
from pathlib import Path
from typing import Dict, Iterator, Tuple

from minifilm.errors import OutputPathError

try:                                    # POSIX
    import fcntl
except ImportError:                     # Windows
    fcntl = None
    import msvcrt  # Windows has no fcntl; its own byte-range lock instead


class FolderInUseError(OutputPathError):
    """Another process is writing the folder."""


def lock_path(folder) -> Path:
    """The lock file of ``folder``: ``.<name>.lock`` beside the folder its links lead to."""
    folder = Path(os.path.realpath(folder))
    return folder.parent / f".{folder.name}.lock"


#: lock file -> (thread holding it, how many blocks of that thread hold it) in this process
_held: Dict[Path, Tuple[int, int]] = {}
_held_lock = threading.Lock()


def _try_lock(fd: int) -> bool:
    try:
        if fcntl is not None:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        else:
            msvcrt.locking(fd, msvcrt.LK_NBLCK, 1)
        return True
    except OSError:
        return False


def _still_there(fd: int, path: Path) -> bool:
    """Whether ``path`` is still the file open as ``fd`` (its holder may have removed it)."""
    try:
        st, now = os.fstat(fd), os.stat(path, follow_symlinks=False)
    except OSError:
        return False
    return (st.st_dev, st.st_ino) == (now.st_dev, now.st_ino)


def _open_locked(path: Path, folder, what: str) -> int:
    """A descriptor of the lock file ``path``, locked; FolderInUseError naming the holder."""
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0),
                         0o666)
        except OSError as e:
            raise OutputPathError(f"cannot lock {what} {folder}: {path}: {e.strerror or e}") from None
        if not _try_lock(fd):
            holder = os.pread(fd, 32, 0).decode("ascii", "replace").strip() if hasattr(os, "pread") else ""
            os.close(fd)
            who = f"process {holder}" if holder.isdigit() else "another process"
            shown = folder if Path(os.path.realpath(folder)) == Path(os.path.abspath(folder)) \
                else f"{folder} (the folder {os.path.realpath(folder)})"
            raise FolderInUseError(f"{what} {shown} is in use by {who} (another minifilm command writing "
                                   "it); wait for it to finish or choose another folder")
        if _still_there(fd, path):
            return fd
        os.close(fd)                     # locked a file its holder had just removed: start over


@contextlib.contextmanager
def folder_lock(folder, what: str = "run folder") -> Iterator[None]:
    """Hold the lock of ``folder`` for the block (see the module docstring)."""
    path = lock_path(folder)
    me = threading.get_ident()
    with _held_lock:
        holder, depth = _held.get(path, (None, 0))
        again = holder == me
        if again:
            _held[path] = (me, depth + 1)
    if again:
        try:
            yield
        finally:
            with _held_lock:
                _held[path] = (me, _held[path][1] - 1)
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    fd = _open_locked(path, folder, what)
    try:
        os.ftruncate(fd, 0)
        os.pwrite(fd, str(os.getpid()).encode(), 0) if hasattr(os, "pwrite") else os.write(fd, str(os.getpid()).encode())
        with _held_lock:
            _held[path] = (me, 1)
        yield
    finally:
        with _held_lock:
            _held.pop(path, None)
        with contextlib.suppress(OSError):
            if _still_there(fd, path):
                os.unlink(path)          # while still locked: see the module docstring
        os.close(fd)                     # releases the lock
