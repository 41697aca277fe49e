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
  member's declared shape and dtype against what the file must hold (a :class:`Member` each) and
  its size against the file and a memory budget *before* allocating, never unpickles, refuses two
  members of one name, and turns every way an archive can be broken into one error naming the file.
"""
from __future__ import annotations

import json
import os
import stat
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO, Dict, Mapping, Optional, Tuple, Type, Union

import numpy as np

from minifilm.errors import InputError
from minifilm.files.names import few
from minifilm.files.output_targets import kind_of

#: The most a JSON file minifilm reads (run.json, a retarget map, a checkpoint's configuration)
#: may hold: they are a few kilobytes.
MAX_JSON_BYTES = 16 << 20

#: The most a single .npz archive may ask for when read: far above any minifilm file (the paper's
#: model and its Adam state are ~70 MB), far below a machine's memory.
MAX_NPZ_BYTES = 1 << 30


def memory_budget() -> int:
    """Half of this machine's memory, in bytes (4 GiB when the system does not say): the most a
    command lets one input ask for (a data set, a long motion)."""
    try:
        return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE") // 2
    except (ValueError, OSError, AttributeError):
        return 4 << 30


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


@dataclass(frozen=True)
class Member:
    """What one array of an archive must be, checked from its ``.npy`` header before any data is read.

    kinds: the dtype kinds it may have (NumPy's ``dtype.kind``: "f" floats, "U" text, "iu" whole
    numbers); shape: one entry per axis, a whole number (that size), None (any size) or a word
    naming a size that must be the same wherever the word appears in the archive (``names`` ("S",)
    and ``films`` ("S", 2048): one name per vector, each of 2048 numbers), or None for any shape
    at all; optional: whether the archive may lack it."""
    kinds: str
    shape: Optional[Tuple[Union[int, str, None], ...]]
    optional: bool = False
    why: str = ""          # said after a wrong shape: why it must be so ("the network needs 2048 numbers")


#: what a member's header says: (shape, dtype)
Header = Tuple[Tuple[int, ...], np.dtype]


def read_npz(path, what: str = "archive", error: Type[InputError] = InputError,
             max_bytes: Optional[int] = MAX_NPZ_BYTES, members: Optional[Mapping[str, Member]] = None
             ) -> Dict[str, np.ndarray]:
    """Every array of the ``.npz`` at ``path`` -> {name: array}, or ``error`` naming ``what`` and the file.

    Before any data is read, each member's ``.npy`` header is checked: no object dtype (that would
    be a pickle); the size it declares must fit in the member and, summed, in ``max_bytes`` (None:
    no budget); and, given ``members`` (name -> :class:`Member`; a name ending in ``*`` stands for
    every name that starts with the rest), the archive must hold those arrays and no others, each of
    its kinds and shape. So a truncated, forged or padded archive is an error, never a huge
    allocation or a half-read array. FileNotFoundError when there is no file at all (the caller
    knows better what that means).
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{what} {path}: no such file")
    where = f"{what} {path}"
    try:
        with open_regular(path, what, error=error) as f:
            with zipfile.ZipFile(f) as archive:
                _check_unique_members(archive, where, error)
                headers = {info.filename[:-4]: _member_header(archive, info, where, error)
                           for info in _npy_members(archive, where, error)}
                if members is not None:
                    check_members(headers, members, where, error)
                total = sum(_nbytes(*h) for h in headers.values())
                if max_bytes is not None and total > max_bytes:
                    raise error(f"{where}: its arrays would take {total / 2**30:.3g} GiB of memory, more than the "
                                f"{max_bytes / 2**30:.3g} GiB such a file may")
                f.seek(0)
                with np.load(f, allow_pickle=False) as z:
                    return {name: z[name] for name in z.files}
    except error:
        raise
    except (zipfile.BadZipFile, zipfile.LargeZipFile, ValueError, OSError, EOFError, KeyError, MemoryError,
            zlib.error, NotImplementedError) as e:
        raise error(f"{where}: not a readable .npz archive ({type(e).__name__}: {e})") from None


def read_npz_member(path, name: str, what: str = "archive", error: Type[InputError] = InputError,
                    member: Optional[Member] = None, max_bytes: Optional[int] = MAX_NPZ_BYTES) -> Optional[np.ndarray]:
    """The one array ``name`` of the .npz at ``path`` (None when it has no such member), checked as
    :func:`read_npz` checks every member (against ``member`` when given, and ``max_bytes``),
    without reading the others (a checkpoint's small meta.json beside its weights)."""
    where = f"{what} {path}"
    try:
        with open_regular(path, what, error=error) as f, zipfile.ZipFile(f) as archive:
            _check_unique_members(archive, where, error)
            try:
                info = archive.getinfo(name + ".npy")
            except KeyError:
                return None
            header = _member_header(archive, info, where, error)
            if member is not None:
                check_members({name: header}, {name: member}, where, error)
            if max_bytes is not None and _nbytes(*header) > max_bytes:
                raise error(f"{where}: array {name!r} would take {_nbytes(*header):,} bytes, more than the "
                            f"{max_bytes:,} it may")
            with archive.open(info) as opened:
                return np.lib.format.read_array(opened, allow_pickle=False)
    except error:
        raise
    except (zipfile.BadZipFile, zipfile.LargeZipFile, ValueError, OSError, EOFError, MemoryError, zlib.error,
            NotImplementedError) as e:
        raise error(f"{where}: not a readable .npz archive ({type(e).__name__}: {e})") from None


def check_members(headers: Mapping[str, Header], members: Mapping[str, Member], where: str,
                  error: Type[Exception] = InputError) -> None:
    """``error`` naming ``where`` unless the arrays ``headers`` (name -> (shape, dtype)) are what
    ``members`` asks for (see :func:`read_npz`)."""
    exact = {n: m for n, m in members.items() if not n.endswith("*")}
    prefixes = sorted(((n[:-1], m) for n, m in members.items() if n.endswith("*")), key=lambda p: -len(p[0]))
    unknown = [n for n in headers if n not in exact and not any(n.startswith(p) for p, _ in prefixes)]
    if unknown:
        raise error(f"{where}: holds {few(unknown)}, which such a file does not have (a damaged, forged or padded "
                    f"archive; such a file holds {few(sorted(exact))})")
    missing = [n for n, m in exact.items() if not m.optional and n not in headers]
    if missing:
        raise error(f"{where}: missing arrays {few(missing)} (not such a file, or a damaged one)")
    sizes: Dict[str, int] = {}
    for name, (shape, dtype) in headers.items():
        m = exact.get(name) or next(m for p, m in prefixes if name.startswith(p))
        if m.shape is None:
            if dtype.kind not in m.kinds:
                raise error(f"{where}: array {name!r} is {dtype}, expected {_KINDS.get(m.kinds, m.kinds)}")
            continue
        ok = dtype.kind in m.kinds and len(shape) == len(m.shape)
        for have, want in zip(shape, m.shape) if ok else ():
            if isinstance(want, str):
                ok = ok and sizes.setdefault(want, have) == have
            elif want is not None:
                ok = ok and have == want
        if not ok:
            want = "(" + ", ".join("any" if w is None else str(sizes.get(w, w)) if isinstance(w, str) else str(w)
                                   for w in m.shape) + ("," if len(m.shape) == 1 else "") + ")"
            raise error(f"{where}: array {name!r} is {dtype} of shape {shape}, expected {_KINDS.get(m.kinds, m.kinds)} "
                        f"of shape {want}" + (f" ({m.why})" if m.why else ""))


_KINDS = {"f": "floats", "U": "text", "iu": "whole numbers", "b": "booleans"}


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


def _npy_members(archive: zipfile.ZipFile, where: str, error):
    """The archive's members, every one of them a ``.npy`` array."""
    for info in archive.infolist():
        if not info.filename.endswith(".npy"):
            raise error(f"{where}: member {info.filename!r} is not a .npy array")
        yield info


def _member_header(archive: zipfile.ZipFile, info: zipfile.ZipInfo, where: str, error) -> Header:
    """(shape, dtype) one ``.npy`` member declares, after checking it may be read at all."""
    with archive.open(info) as member:
        version = np.lib.format.read_magic(member)
        header = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                  else np.lib.format.read_array_header_2_0)
        shape, _, dtype = header(member)
    if dtype.hasobject:
        raise error(f"{where}: array {info.filename[:-4]!r} holds Python objects (refused: never unpickled)")
    if _nbytes(shape, dtype) > info.file_size:
        raise error(f"{where}: array {info.filename[:-4]!r} declares {_nbytes(shape, dtype):,} bytes but holds "
                    f"{info.file_size:,} (truncated or forged)")
    return tuple(shape), dtype


def _nbytes(shape, dtype: np.dtype) -> int:
    return int(np.prod(shape, dtype=np.float64)) * dtype.itemsize
