"""Writing an output file atomically, with the path checked before any rendering work.

``atomic_output(path, "GIF")`` creates a temporary file beside the target at once (so a missing
folder, a folder given as the file name or a read-only place fails before minutes of rendering,
with one error naming the path), hands its name to the renderer, and renames it onto the target
only when the renderer finished. On any failure the temporary file is removed: a half-written
GIF or HTML file never appears under the target name.
"""
from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path
from typing import Iterator, Union

__all__ = ["OutputPathError", "atomic_output"]


class OutputPathError(OSError):
    """The output path cannot be written; the message names it and says why."""


@contextlib.contextmanager
def atomic_output(path: Union[str, os.PathLike], what: str) -> Iterator[str]:
    """Context manager yielding a temporary file name to write ``what`` (e.g. "GIF") into.

    Raises ``OutputPathError`` before the body runs when ``path`` cannot be written.
    """
    target = Path(path)
    folder = target.parent
    if target.is_dir():
        raise OutputPathError(f"cannot write {what} to {target}: it is a folder, give a file name")
    if not folder.exists():
        raise OutputPathError(f"cannot write {what} to {target}: folder {folder} does not exist")
    if not folder.is_dir():
        raise OutputPathError(f"cannot write {what} to {target}: {folder} is not a folder")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".part", dir=folder)
    except OSError as e:
        raise OutputPathError(f"cannot write {what} to {target}: {e.strerror or e}") from None
    os.close(fd)
    try:
        yield tmp
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            os.remove(tmp)
        raise
