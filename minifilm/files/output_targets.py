"""What an output may replace, and the inputs of the running command, which it may not.

The rule every writer follows (:func:`output_target`):

* a new path is created (its folder too);
* an existing **regular file** is replaced whole and keeps its permission bits;
* a **symbolic link** is followed: the file it leads to is replaced and the link stays a link
  (what a shell's ``>`` does), under the same rules; but a link where one of minifilm's state
  files belongs (a run folder's ``styles.npz``, ``starts.npz``, ``model-<NAME>.npz``, a cache) is
  refused: a run's own files are never written through a link;
* a **read-only** file is refused: minifilm never replaces what somebody protected (``chmod u+w``
  it or remove it first). Root ignores permissions, so the file's mode bits are read, not access().
  The same rule holds for folders: nothing is written into a read-only folder, and a read-only
  folder is not replaced;
* a **folder, device, FIFO or socket** is refused: replacing ``/dev/null`` with a regular file (as
  a rename over it would, for root) or hanging on a FIFO is never what an output meant;
* a file that the **running command reads** is refused (``generate --skeleton-bvh a.bvh --out a.bvh``), and so is a
  folder that holds one (``train --data runs/x/data --out runs/x``);
* a **state file** minifilm keeps (a run folder's ``styles.npz``, ``model.npz``, ..., a data set
  cache) is refused unless the code writing it owns it (:mod:`minifilm.files.state`), whatever the
  option that named it.

:func:`output_target` is the one place these rules are applied: every atomic writer asks it, and
so does :func:`minifilm.files.atomic.check_writable`, which each command calls for each of its
outputs before the work.

The last rule needs to know the command's inputs: the files and folders a user named for it to
read. Inside :func:`command_inputs` (the ``minifilm`` command opens one around each subcommand)
they are recorded where they enter: the command line's input arguments (``minifilm/cli/args.py``)
and the files a data folder or manifest lists. A command's own state that it reads and writes
again (a run's ``styles.npz`` when a style is added) is not an input: it is state, which the
rule of :mod:`minifilm.files.state` protects from every other writer. Outside such a block nothing
is recorded: a Python user may read a file, edit the motion and write it back in place.
"""
from __future__ import annotations

import contextlib
import os
import stat
import threading
from pathlib import Path
from typing import Dict, Iterator, Optional, Tuple

from minifilm.errors import OutputPathError
from minifilm.files.state import is_owned, state_of

_lock = threading.Lock()
_depth = 0
#: (device, inode) -> the path as the command named it, while a command_inputs() block is open
_inputs: Dict[Tuple[int, int], str] = {}
#: the real paths of the same inputs, for "does this folder hold an input?"
_input_paths: Dict[str, str] = {}


def kind_of(mode: int) -> str:
    """'a folder', 'a FIFO (named pipe)', ... for an ``st_mode``."""
    for test, name in ((stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
                       (stat.S_ISSOCK, "a socket"), (stat.S_ISCHR, "a character device"),
                       (stat.S_ISBLK, "a block device"), (stat.S_ISREG, "a regular file")):
        if test(mode):
            return name
    return "not a regular file"


@contextlib.contextmanager
def command_inputs() -> Iterator[None]:
    """While open, files read through minifilm.files and paths given to :func:`note_input` are
    the running command's inputs, and no output may replace them. Blocks nest; the record is
    cleared when the outermost one closes."""
    global _depth
    with _lock:
        _depth += 1
    try:
        yield
    finally:
        with _lock:
            _depth -= 1
            if _depth == 0:
                _inputs.clear()
                _input_paths.clear()


def note_input(path):
    """Record ``path`` (a file or a folder of inputs) as an input of the running command, and
    return it; nothing is recorded outside :func:`command_inputs` or when the path does not exist."""
    if _depth == 0:
        return path
    try:
        st = os.stat(path)
        real = os.path.realpath(path)
    except (OSError, ValueError):
        return path
    with _lock:
        _inputs[(st.st_dev, st.st_ino)] = str(path)
        _input_paths[real] = str(path)
    return path


def input_named(st: os.stat_result) -> Optional[str]:
    """The path of the input that is the file ``st`` describes, or None."""
    return _inputs.get((st.st_dev, st.st_ino)) if _depth else None


def input_inside(folder) -> Optional[str]:
    """An input of the running command that lies in ``folder`` (or is it), or None."""
    if not _depth:
        return None
    real = os.path.realpath(folder)
    prefix = real.rstrip(os.sep) + os.sep
    for path, named in list(_input_paths.items()):
        if path == real or path.startswith(prefix):
            return named
    return None


def output_target(path, what: str = "output") -> Path:
    """The file a writer of ``path`` creates or replaces (``path`` itself, or where its symbolic
    links lead), after the checks of the module docstring; OutputPathError naming ``path`` and
    the reason otherwise."""
    path = Path(path)
    _check_state_not_linked(path, what)
    try:
        st = os.stat(path)                   # follows links, /proc's magic ones included
    except (FileNotFoundError, NotADirectoryError):   # a new file, or a folder in the way (said later)
        st = None
    except OSError as e:
        raise OutputPathError(f"cannot write {what} to {path}: {e.strerror or e}") from None
    _check_folder_not_protected(Path(os.path.realpath(path)).parent, f"cannot write {what} to {path}")
    if st is None:
        # a new file (a dangling link is followed to where it points, as a shell would)
        _check_not_state(path, what)
        return Path(os.path.realpath(path))
    if not stat.S_ISREG(st.st_mode):
        hint = ", give a file name" if stat.S_ISDIR(st.st_mode) else "; give the path of a new or regular file"
        raise OutputPathError(f"cannot write {what} to {path}: it is {kind_of(st.st_mode)}{hint}")
    if not st.st_mode & 0o222 or not os.access(path, os.W_OK):
        raise OutputPathError(f"cannot write {what} to {path}: the file is read-only (minifilm does not "
                              "replace a protected file; make it writable or remove it first)")
    named = input_named(st)
    if named is not None:
        raise OutputPathError(f"cannot write {what} to {path}: it is also an input of this command "
                              f"({named}); choose another output path")
    _check_not_state(path, what)
    real = Path(os.path.realpath(path))
    try:
        same = os.stat(real)
    except OSError:
        same = None
    if same is None or (same.st_dev, same.st_ino) != (st.st_dev, st.st_ino):
        raise OutputPathError(f"cannot write {what} to {path}: it is not a file that can be replaced by name "
                              "(a link into /proc or a moving target)")
    return real


def _check_folder_not_protected(folder: Path, lead: str) -> None:
    """OutputPathError when the existing ``folder`` is read-only, by its mode bits as a file is
    (root could write into it, but somebody protected it)."""
    try:
        st = os.stat(folder)
    except OSError:
        return                                   # not there yet: made, in a folder checked in its turn
    if stat.S_ISDIR(st.st_mode) and (not st.st_mode & 0o222 or not os.access(folder, os.W_OK | os.X_OK)):
        raise OutputPathError(f"{lead}: the folder {folder} is read-only (minifilm does not write into a protected "
                              "folder; make it writable or choose another)")


def _check_state_not_linked(path: Path, what: str) -> None:
    """OutputPathError when ``path`` is a symbolic link where one of minifilm's state files belongs
    (a run folder's ``styles.npz``, a checkpoint, a cache): a run's own files are written where
    they are, never through a link, which may lead anywhere (a run unpacked from an archive can
    hold links to files elsewhere, dangling ones included)."""
    if not os.path.islink(path):
        return
    why = state_of(path)
    if why:
        raise OutputPathError(f"cannot write {what} to {path}: it is a symbolic link (to {os.readlink(path)}) where "
                              f"{why} belongs; minifilm never writes a run's own files through a link "
                              "(it may lead outside the folder): put the file itself there, or remove the link")


def folder_target(path, what: str = "output folder") -> Path:
    """The folder a whole-folder writer creates or replaces: ``path``, or where its link leads.
    OutputPathError when it exists and is not a folder, is read-only or holds an input of the running
    command, or when the folder it is made in is read-only."""
    path = Path(path)
    _check_folder_not_protected(Path(os.path.realpath(path)).parent, f"cannot write {what} {path}")
    try:
        st = os.stat(path)
    except (FileNotFoundError, NotADirectoryError):
        _check_not_state(path, what)
        return Path(os.path.realpath(path))
    except OSError as e:
        raise OutputPathError(f"cannot write {what} {path}: {e.strerror or e}") from None
    if not stat.S_ISDIR(st.st_mode):
        raise OutputPathError(f"cannot write {what} {path}: it is {kind_of(st.st_mode)}, expected a folder")
    _check_folder_not_protected(path, f"cannot write {what} {path}")
    named = input_inside(path)
    if named is not None:
        raise OutputPathError(f"cannot write {what} {path}: it holds an input of this command ({named}), "
                              "which writing the folder anew would remove; choose another folder")
    _check_not_state(path, what)
    return Path(os.path.realpath(path))


def check_not_state(path, what: str = "output") -> None:
    """OutputPathError when ``path`` (a file or a folder to write into) is state of minifilm's that
    the running code does not own: the rule of :mod:`minifilm.files.state`, for callers that
    check an output folder before anything is written into it."""
    _check_not_state(path, what, f"cannot write into {path}")


def _check_not_state(path, what: str, lead: str = "") -> None:
    """OutputPathError when ``path`` is one of minifilm's state files (minifilm/files/state.py)
    that the running command does not own; only while a command runs (see command_inputs)."""
    if not _depth or is_owned(path):
        return
    why = state_of(path)
    if why:
        raise OutputPathError(f"{lead or f'cannot write {what} to {path}'}: it is {why}; "
                              "choose another output path")
