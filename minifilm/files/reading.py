"""Reading a user's files so that no file can hang the command or exhaust the machine.

* :func:`open_regular` opens only **regular files**: a FIFO would block the reader forever,
  ``/dev/zero`` or ``/dev/urandom`` would grow without end, a folder or socket is a mistake. The
  path is checked with ``stat`` before it is opened (opening some devices does something), then
  opened non-blocking and checked again on the open descriptor, so a file swapped in between is
  caught too;
* :func:`read_regular_bytes` reads such a file whole, up to a size limit;
* :func:`parse_json` / :func:`read_json` turn every way a JSON text can be bad (syntax, nesting
  deep enough to exhaust Python's recursion, a file over its limit) into one error naming the file;
* :func:`read_npz` is the one reader of the ``.npz`` archives minifilm writes: it checks every
  member's declared size against the file and a memory budget *before* allocating, never
  unpickles, refuses two members of one name, and turns every way an archive can be broken into one error naming the file.
"""
from __future__ import annotations

import json
import os
import stat
import zipfile
import zlib
from pathlib import Path
from typing import Any, BinaryIO, Dict, Optional, Type

import numpy as np

from minifilm.errors import InputError
from minifilm.files.output_targets import kind_of

#: The most a JSON file minifilm reads (run.json, a retarget map, a checkpoint's configuration)
#: may hold: they are a few kilobytes.
MAX_JSON_BYTES = 16 << 20

#: The most a single .npz archive may ask for when read: far above any minifilm file (the paper's
#: model and its Adam state are ~70 MB), far below a machine's memory.
MAX_NPZ_BYTES = 1 << 30


def check_regular(path, what: str = "file", error: Type[Exception] = InputError) -> os.stat_result:
    """``os.stat(path)`` when ``path`` is a regular file (or a link to one); ``error`` naming what
    it is otherwise. FileNotFoundError when there is nothing there."""
    st = os.stat(path)
    if not stat.S_ISREG(st.st_mode):
        raise error(f"{what} {path}: is {kind_of(st.st_mode)}, not a regular file (minifilm reads only "
                    "regular files)")
    return st


def open_regular(path, what: str = "file", max_bytes: Optional[int] = None,
                 error: Type[Exception] = InputError) -> BinaryIO:
    """A binary file object of the regular file ``path`` (see the module docstring); ``error``
    when it is not one, or holds more than ``max_bytes``."""
    check_regular(path, what, error)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0) | getattr(os, "O_BINARY", 0)
    fd = os.open(path, flags)
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):           # swapped for something else since the stat
            raise error(f"{what} {path}: is {kind_of(st.st_mode)}, not a regular file")
        if max_bytes is not None and st.st_size > max_bytes:
            raise error(f"{what} {path}: {st.st_size:,} bytes, more than the {max_bytes:,} such a file may hold")
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def read_regular_bytes(path, what: str = "file", max_bytes: Optional[int] = None,
                       error: Type[Exception] = InputError) -> bytes:
    """The contents of the regular file ``path``, at most ``max_bytes`` (also when it grows while
    being read)."""
    with open_regular(path, what, max_bytes, error) as f:
        if max_bytes is None:
            return f.read()
        # in pieces rather than read(max_bytes + 1), which would allocate the whole limit at once;
        # the size may grow while reading (or be 0, as /proc's files say)
        chunks, total = [], 0
        piece = os.fstat(f.fileno()).st_size + 1          # all of it at once, as a rule
        while total <= max_bytes:
            chunk = f.read(min(piece, max_bytes + 1 - total))
            piece = 1 << 20
            if not chunk:
                break
            chunks.append(chunk)
            total += len(chunk)
        data = b"".join(chunks)
    if max_bytes is not None and len(data) > max_bytes:
        raise error(f"{what} {path}: more than the {max_bytes:,} bytes such a file may hold")
    return data


#: the most digits a whole number in a JSON file minifilm reads may have: far more than any count
#: or seed, far fewer than Python's own limit (4300), whose message points at an interpreter setting
MAX_JSON_DIGITS = 100


def bounded_int(text: str) -> int:
    """A JSON whole number, at most MAX_JSON_DIGITS digits (``json.loads(parse_int=...)``)."""
    digits = len(text.lstrip("-"))
    if digits > MAX_JSON_DIGITS:
        raise ValueError(f"a whole number of {digits:,} digits ({text[:12]}...), more than the "
                         f"{MAX_JSON_DIGITS} minifilm reads")
    return int(text)


def finite_float(text: str) -> float:
    """A JSON number with a fraction or exponent, finite (``1e999`` would become infinity)."""
    value = float(text)
    if value in (float("inf"), float("-inf")):
        raise ValueError(f"the number {text[:40]} is too large for a float")
    return value


def no_constant(name):
    """``json.loads(parse_constant=...)``: JSON has no NaN or Infinity."""
    raise ValueError(f"{name} is not a JSON number")


#: the number hooks of every JSON parse in minifilm: json.loads(text, **JSON_NUMBERS)
JSON_NUMBERS = dict(parse_constant=no_constant, parse_int=bounded_int, parse_float=finite_float)


def parse_json(text, where: str, error: Type[Exception] = InputError) -> Any:
    """``json.loads(text)``, or ``error`` naming ``where``: bad syntax, a constant JSON does not
    have (NaN, Infinity), a number too long or too large (:data:`JSON_NUMBERS`), or nesting deep
    enough to exhaust Python's recursion."""
    try:
        return json.loads(text, **JSON_NUMBERS)
    except RecursionError:
        raise error(f"{where}: nested too deeply to be a minifilm file") from None
    except (ValueError, TypeError) as e:        # JSONDecodeError and bad UTF-8 are ValueErrors
        raise error(f"{where}: not valid JSON ({e})") from None


def read_json(path, what: str = "file", error: Type[Exception] = InputError,
              max_bytes: int = MAX_JSON_BYTES) -> Any:
    """The JSON value of the regular file ``path`` (UTF-8, at most ``max_bytes``)."""
    data = read_regular_bytes(path, what, max_bytes, error)
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise error(f"{what} {path}: not UTF-8 text (byte {e.start})") from None
    return parse_json(text, f"{what} {path}", error)


def read_npz(path, what: str = "archive", error: Type[InputError] = InputError,
             max_bytes: Optional[int] = MAX_NPZ_BYTES) -> Dict[str, np.ndarray]:
    """Every array of the ``.npz`` at ``path`` -> {name: array}, or ``error`` naming ``what`` and the file.

    Before reading, each member's ``.npy`` header is checked: no object dtype (that would be a
    pickle), and the size it declares must fit in the member and, summed, in ``max_bytes`` (None: no
    budget, for dataset caches, which hold whatever data the user has). So a
    truncated or forged archive is an error, never a huge allocation or a half-read array.
    FileNotFoundError when there is no file at all (the caller knows better what that means).
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{what} {path}: no such file")
    where = f"{what} {path}"
    try:
        with open_regular(path, what, error=error) as f:
            with zipfile.ZipFile(f) as archive:
                _check_unique_members(archive, where, error)
                total = 0
                for info in archive.infolist():
                    total += _member_bytes(archive, info, where, error)
                    if max_bytes is not None and total > max_bytes:
                        raise error(f"{where}: its arrays would take more than {max_bytes / 2**30:g} GiB of memory")
                f.seek(0)
                with np.load(f, allow_pickle=False) as z:
                    return {name: z[name] for name in z.files}
    except error:
        raise
    except (zipfile.BadZipFile, zipfile.LargeZipFile, ValueError, OSError, EOFError, KeyError, MemoryError,
            zlib.error, NotImplementedError) as e:
        raise error(f"{where}: not a readable .npz archive ({type(e).__name__}: {e})") from None


def read_npz_member(path, name: str, what: str = "archive", error: Type[InputError] = InputError) -> Optional[np.ndarray]:
    """The one array ``name`` of the .npz at ``path`` (None when it has no such member), checked as
    :func:`read_npz` checks every member, without reading the others (a checkpoint's small
    meta.json beside its weights)."""
    where = f"{what} {path}"
    try:
        with open_regular(path, what, error=error) as f, zipfile.ZipFile(f) as archive:
            _check_unique_members(archive, where, error)
            try:
                info = archive.getinfo(name + ".npy")
            except KeyError:
                return None
            _member_bytes(archive, info, where, error)
            with archive.open(info) as member:
                return np.lib.format.read_array(member, allow_pickle=False)
    except error:
        raise
    except (zipfile.BadZipFile, zipfile.LargeZipFile, ValueError, OSError, EOFError, MemoryError, zlib.error,
            NotImplementedError) as e:
        raise error(f"{where}: not a readable .npz archive ({type(e).__name__}: {e})") from None


def _check_unique_members(archive: zipfile.ZipFile, where: str, error) -> None:
    """``error`` when two members share a name: a reader would silently take one of them (NumPy the
    last), so which array the archive holds would depend on the reader. An archive minifilm writes
    never has two."""
    seen = set()
    for name in archive.namelist():
        if name in seen:
            raise error(f"{where}: holds two members named {name!r} (a damaged or forged archive; "
                        "minifilm never writes one)")
        seen.add(name)


def _member_bytes(archive: zipfile.ZipFile, info: zipfile.ZipInfo, where: str, error) -> int:
    """The bytes one ``.npy`` member declares, after checking it may be read at all."""
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
    return nbytes
