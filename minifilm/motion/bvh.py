"""Read and write BVH motion capture files (docs/original-code.md §1.1).

Reading, in the original's terms:

- Bones are listed in file order, ``End Site`` included; an End Site is named after its parent with
  ``"Site"`` appended (``LeftWrist`` -> ``LeftWristSite``; a second End Site under the same parent
  becomes ``...Site2``). End Sites have no channels and an identity rotation.
- A joint's local translation is its OFFSET, with each position channel it has replacing the
  matching component (any joint may have position channels: the Bandai files put six channels on
  every joint). The original has a quirk: when all three position channels read exactly 0 it uses
  the OFFSET instead. We do not copy it: a root passing exactly through the origin would jump to its
  offset, and no file in the shared data relies on it (the Bandai ``joint_Root`` has both zero
  channels and a zero offset).
- A joint's local rotation is the product of one axis rotation per rotation channel, in the order
  listed: ``Yrotation Xrotation Zrotation`` gives ``Ry @ Rx @ Rz`` (see ``kinematics.euler_to_matrix``).
- Lengths are multiplied by ``scale`` (0.01: centimetres -> metres); degrees become radians.

The format is parsed leniently where files in the wild differ (tabs or spaces, CRLF line ends,
``Frame Time: .0083333``, keywords in any case, blank lines) and strictly where a mistake would give
a silently wrong motion: every problem raises ``BVHError`` naming the file, the line and what was
expected (the text's syntax is :mod:`minifilm.motion.bvh_syntax`). The motion block is parsed with
one split per line and a bulk float conversion per block of frames.
"""
from __future__ import annotations

import os
from typing import Dict, List, Tuple, Union

import numpy as np

from minifilm.files import open_regular, read_regular_bytes
from minifilm.files.reading import memory_budget
from minifilm.motion.bvh_syntax import (LINE_END, MAX_VALUE, NUMBER, BVHError, Hierarchy, clip,
                                        parse_motion_header)
from minifilm.motion.kinematics import axis_rotation, euler_to_matrix
from minifilm.motion.motion import Motion

__all__ = ["BVHError", "read_bvh", "parse_bvh", "bvh_duration", "bvh_timing", "bvh_header", "bvh_header_names",
           "decode_bvh"]


#: the largest BVH file read (100STYLE's longest take is about 20 MB)
MAX_BVH_BYTES = 1 << 30


def read_bvh(path: Union[str, os.PathLike], scale: float = 0.01) -> Motion:
    """Read a BVH file into a ``Motion`` (metres = BVH units * ``scale``, radians).

    Raises ``BVHError`` (a ValueError) for malformed files, for anything but a regular file (a
    FIFO, a device), for files over :data:`MAX_BVH_BYTES`, and for files whose header alone shows
    that reading them would take more memory than allowed (:func:`check_motion_size`, said with the
    estimate before the file is read); OSError when the file can't be read.
    """
    header, n_frames, _ = _header(path)
    check_motion_size(len(header.names), n_frames, sum(len(c) for c in header.channels), os.path.getsize(path),
                      str(path))
    text = decode_bvh(read_regular_bytes(path, "BVH file", MAX_BVH_BYTES, error=BVHError.about_file), str(path))
    return parse_bvh(text, source=str(path), scale=scale)


def bvh_duration(path: Union[str, os.PathLike]) -> float:
    """Seconds of motion in a BVH file (frames x frame time), read from its MOTION header alone,
    without parsing the frames. BVHError when the header is missing or malformed."""
    n_frames, frame_time = bvh_timing(path)
    return n_frames * frame_time


def bvh_timing(path: Union[str, os.PathLike]) -> Tuple[int, float]:
    """(frames, seconds per frame) of a BVH file from its MOTION header alone (a fast survey of
    many files before any is parsed). BVHError when the header is missing or malformed."""
    n_frames, frame_time, _ = bvh_header(path)
    return n_frames, frame_time


def bvh_header(path: Union[str, os.PathLike]) -> Tuple[int, float, int]:
    """(frames, seconds per frame, joints with End Sites) of a BVH file, read from its header
    alone: what parsing it would allocate, known before it is parsed."""
    names, n_frames, frame_time = bvh_header_names(path)
    return n_frames, frame_time, len(names)


def bvh_header_names(path: Union[str, os.PathLike]) -> Tuple[List[str], int, float]:
    """(joint names with End Sites, frames, seconds per frame) of a BVH file, from its header alone.

    The hierarchy is read by the same parser as the whole file (so a hierarchy written on one line
    counts its joints, and names are those ``read_bvh`` gives); the frames are not read."""
    header, n_frames, frame_time = _header(path)
    return list(header.names), n_frames, frame_time


def _header(path: Union[str, os.PathLike]) -> Tuple[Hierarchy, int, float]:
    """(parsed hierarchy, frames, seconds per frame) of a BVH file: its text up to the frames."""
    chunks: List[bytes] = []
    motion_line, after = None, 0
    with open_regular(path, "BVH file", MAX_BVH_BYTES, error=BVHError.about_file) as raw:
        for i, line in enumerate(raw):        # stop two non-empty lines after MOTION
            chunks.append(line)
            text = line.strip()
            first = text.split(None, 1)[0].upper() if text else b""
            if motion_line is None and first == b"MOTION":
                motion_line = i
            elif motion_line is not None and text:
                after += 1
                if after == 2:
                    break
    lines = LINE_END.split(decode_bvh(b"".join(chunks), str(path)).lstrip("\ufeff"))
    header = Hierarchy(lines, str(path))
    motion_line = header.parse()
    n_frames, frame_time, _ = parse_motion_header(lines, motion_line, str(path))
    return header, n_frames, frame_time


def decode_bvh(raw: bytes, source: str) -> str:
    """The text of a BVH file: UTF-8 (ASCII included), else Windows-1252, the encoding of files
    written on Windows (joint names such as ``Hüfte``); BVHError naming the first byte neither
    reads (instead of names that silently end in a replacement character)."""
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        pass
    if b"\0" in raw[:4096]:         # no text file holds a NUL: an archive, a picture, a checkpoint
        raise BVHError(source, 1, "not a BVH file: it holds binary data, not text")
    try:
        return raw.decode("cp1252")
    except UnicodeDecodeError as e:
        line = raw[:e.start].count(b"\n") + 1
        raise BVHError(source, line, f"byte 0x{raw[e.start]:02X} is neither UTF-8 nor Windows-1252 text; "
                                     "save the file as UTF-8") from None


def parse_bvh(text: str, source: str = "<string>", scale: float = 0.01) -> Motion:
    """Parse BVH ``text`` (the contents of a file); ``source`` names it in error messages."""
    if not (np.isfinite(scale) and scale > 0):
        raise ValueError(f"parse_bvh({source}): scale must be positive, got {scale}")
    lines = LINE_END.split(text.lstrip("\ufeff"))            # \n, \r\n and old Mac \r alike
    header = Hierarchy(lines, source)
    motion_line = header.parse()
    n_frames, frame_time, first_data_line = parse_motion_header(lines, motion_line, source)
    n_channels = sum(len(c) for c in header.channels)
    check_motion_size(len(header.names), n_frames, n_channels, len(text), source)
    values = _parse_frames(lines, first_data_line, n_frames, n_channels, source)
    return _build_motion(header, values, frame_time, scale, source)


#: the most memory reading one motion may take (also bounded by half of this machine's memory), and
#: per character of its file: a real take's rotations and translations (96 bytes per joint and
#: frame) need a few times its file's size; a header that declares thousands of joints without
#: channels, or frames the file does not hold, asks for more
MAX_MOTION_BYTES, MAX_BYTES_PER_CHARACTER, ALWAYS_ALLOWED_BYTES = 4 << 30, 64, 256 << 20
#: what reading a file takes, per character of it (its bytes, text and lines) and per joint and frame
#: (the channels, the rotations and translations, their temporaries): the peak traced memory of
#: read_bvh on Bandai and CMU takes of 20,000 and 60,000 frames (27 and 57 joints) was 3.6 x the file's
#: size + 257 bytes per joint and frame, rounded up (so the estimate is 5-20 % above the peak)
READ_BYTES_PER_CHARACTER, READ_BYTES_PER_JOINT_FRAME = 4, 280


def check_motion_size(n_joints: int, n_frames: int, n_channels: int, n_characters: int, source: str) -> None:
    """BVHError, before anything is allocated, when a header of ``n_joints`` joints, ``n_frames``
    frames and ``n_channels`` values per frame cannot be read from a text of ``n_characters``:

    * it declares frames the text cannot hold (each value takes a digit and a separator), or
      motion arrays far larger than a text of this size justifies (see MAX_BYTES_PER_CHARACTER):
      a broken or hostile header;
    * reading it would take more memory than :data:`MAX_MOTION_BYTES` or half of this machine's:
      an honest file too large, refused with the estimate (cut it into shorter files).
    """
    if n_frames * max(2 * n_channels, 1) > n_characters:
        raise BVHError(source, None, f"its header declares {n_frames:,} frames of {n_channels} values, more than its "
                                     f"{n_characters:,} characters can hold (a broken or hostile header)")
    arrays = n_frames * (n_joints * 12 + n_channels) * 8
    justified = max(ALWAYS_ALLOWED_BYTES, MAX_BYTES_PER_CHARACTER * n_characters)
    if arrays > justified:
        raise BVHError(source, None, f"its header declares {n_joints:,} joints and {n_frames:,} frames, "
                                     f"{arrays / 2**30:.2f} GiB of memory; a file of {n_characters:,} characters "
                                     f"may ask for at most {justified / 2**30:.2f} GiB (a broken or hostile header)")
    need = READ_BYTES_PER_CHARACTER * n_characters + READ_BYTES_PER_JOINT_FRAME * n_joints * n_frames
    budget = memory_budget()
    limit = min(MAX_MOTION_BYTES, budget)
    if need > limit:
        whose = "half of this machine's memory" if budget < MAX_MOTION_BYTES else "the most minifilm reads as one motion"
        raise BVHError(source, None, f"{n_frames:,} frames of {n_joints} joints ({_size(n_characters)}): reading it "
                                     f"would need about {_size(need)} of memory, more than {_size(limit)} ({whose}); "
                                     "cut it into shorter files")


def _size(n: float) -> str:
    return f"{n / 2**30:.1f} GiB" if n >= 2**30 else f"{n / 2**20:.0f} MiB"


def _parse_frames(lines: List[str], first: int, n_frames: int, n_channels: int, source: str) -> np.ndarray:
    """(n_frames, n_channels) float array from the data lines, checking each line's count. The
    lines are converted a block at a time into the preallocated array, so the strings of at most
    one block are alive at once."""
    values = np.empty((n_frames, n_channels), dtype=np.float64)
    tokens: List[str] = []
    line_numbers: List[int] = []
    done = 0                                          # frames converted into ``values``
    for i in range(first, len(lines)):
        parts = lines[i].split()
        if not parts:
            continue
        if done + len(line_numbers) == n_frames:
            raise BVHError(source, i + 1, f"expected {n_frames} frames as declared by 'Frames:', "
                                          f"found more data")
        if len(parts) != n_channels:
            raise BVHError(source, i + 1, f"expected {n_channels} values in frame {done + len(line_numbers) + 1}, "
                                          f"found {len(parts)}")
        tokens.extend(parts)
        line_numbers.append(i + 1)
        if len(line_numbers) == _BLOCK_FRAMES:
            _convert(tokens, line_numbers, values[done:done + len(line_numbers)], source)
            done += len(line_numbers)
            tokens, line_numbers = [], []
    if done + len(line_numbers) < n_frames:
        raise BVHError(source, len(lines), f"expected {n_frames} frames as declared by 'Frames:', "
                                           f"the file ends after {done + len(line_numbers)}")
    _convert(tokens, line_numbers, values[done:], source)
    return values


#: frames converted to numbers at a time (a few MB of strings for the widest rigs)
_BLOCK_FRAMES = 2048


def _convert(tokens: List[str], line_numbers: List[int], out: np.ndarray, source: str) -> None:
    """Fill ``out`` (frames, channels) with the numbers ``tokens`` spell. Python's float() also
    reads ``1_0`` and digits of other scripts; a BVH number is ASCII without underscores."""
    if not tokens:
        return
    try:
        ok = all(t.isascii() and "_" not in t for t in tokens)
        flat = np.fromiter(map(float, tokens), dtype=np.float64, count=len(tokens)) if ok else None
    except ValueError:
        flat = None
    if flat is None or not np.all(np.abs(flat) <= MAX_VALUE):      # also catches nan and inf
        _raise_bad_value(tokens, line_numbers, out.shape[1], source)
    out[...] = flat.reshape(out.shape)


def _raise_bad_value(tokens: List[str], line_numbers: List[int], n_channels: int, source: str) -> None:
    """Slow path: find the first non-numeric or non-finite value and name its line."""
    for k, tok in enumerate(tokens):
        try:
            ok = NUMBER.fullmatch(tok) is not None and abs(float(tok)) <= MAX_VALUE
        except ValueError:
            ok = False
        if not ok:
            raise BVHError(source, line_numbers[k // n_channels],
                           f"expected a finite number of magnitude at most {MAX_VALUE:g} as value {k % n_channels + 1}, "
                           f"found {clip(tok)!r}")
    raise AssertionError("unreachable: a bad value was detected but not found")


def _build_motion(h: Hierarchy, values: np.ndarray, frame_time: float, scale: float, source: str) -> Motion:
    """Local rotations (radians) and translations (metres) per joint from the channel values."""
    F, J = values.shape[0], len(h.names)
    offsets = np.asarray(h.offsets, dtype=np.float64).reshape(J, 3) * scale
    translations = np.broadcast_to(offsets, (F, J, 3)).copy()
    rotations = np.broadcast_to(np.eye(3), (F, J, 3, 3)).copy()
    # Group joints by rotation order so each distinct order costs one vectorised call.
    by_order: Dict[str, Tuple[List[int], List[List[int]]]] = {}
    column = 0
    for j, chans in enumerate(h.channels):
        rot_cols, rot_axes = [], ""
        for k, c in enumerate(chans):
            if c.endswith("position"):
                translations[:, j, "XYZ".index(c[0])] = values[:, column + k] * scale
            else:
                rot_cols.append(column + k)
                rot_axes += c[0]
        if len(rot_axes) == 3 and len(set(rot_axes)) == 3:
            joints, cols = by_order.setdefault(rot_axes, ([], []))
            joints.append(j)
            cols.append(rot_cols)
        elif rot_axes:  # unusual: 1, 2 or repeated rotation channels -> multiply them one by one
            R = np.broadcast_to(np.eye(3), (F, 3, 3))
            for col, axis in zip(rot_cols, rot_axes):
                R = R @ axis_rotation(axis, np.radians(values[:, col]))
            rotations[:, j] = R
        column += len(chans)
    for order, (joints, cols) in by_order.items():
        rotations[:, joints] = euler_to_matrix(np.radians(values[:, np.array(cols)]), order)
    return Motion(list(h.names), np.array(h.parents, dtype=np.int64), offsets, list(h.channels),
                  rotations, translations, float(frame_time), source)
