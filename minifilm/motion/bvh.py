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
expected. The motion block is parsed with one split per line and a single bulk float conversion.
"""
from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Dict, List, Optional, Tuple, Union

import numpy as np

from minifilm.errors import MAX_FPS, MIN_FPS, InputError
from minifilm.motion.kinematics import axis_rotation, euler_to_matrix
from minifilm.motion.motion import Motion

__all__ = ["BVHError", "read_bvh", "parse_bvh", "bvh_duration"]

CHANNEL_NAMES = {f"{axis}{kind}".lower(): f"{axis}{kind}"
                 for axis in "XYZ" for kind in ("position", "rotation")}


class BVHError(InputError):
    """A malformed BVH file. The message names the file, the line number and what was expected."""

    def __init__(self, source: str, line: Optional[int], message: str):
        self.source = source
        self.line = line
        where = f"{source}, line {line}" if line is not None else source
        super().__init__(f"{where}: {message}")


# ----------------------------------------------------------------------------------------------
# Reading
# ----------------------------------------------------------------------------------------------

def read_bvh(path: Union[str, os.PathLike], scale: float = 0.01) -> Motion:
    """Read a BVH file into a ``Motion`` (metres = BVH units * ``scale``, radians).

    Raises ``BVHError`` (a ValueError) for malformed files and OSError when the file can't be read.
    """
    raw = Path(path).read_bytes()
    return parse_bvh(raw.decode("utf-8", errors="replace"), source=str(path), scale=scale)


def bvh_duration(path: Union[str, os.PathLike]) -> float:
    """Seconds of motion in a BVH file (frames x frame time), read from its MOTION header alone,
    without parsing the frames. BVHError when the header is missing or malformed."""
    n_frames, frame_time = bvh_timing(path)
    return n_frames * frame_time


def bvh_timing(path: Union[str, os.PathLike]) -> Tuple[int, float]:
    """(frames, seconds per frame) of a BVH file from its MOTION header alone (a fast survey of
    many files before any is parsed). BVHError when the header is missing or malformed."""
    lines: List[str] = []
    motion_line, after = None, 0
    with open(path, "r", encoding="utf-8", errors="replace") as f:
        for line in f:                        # stop two non-empty lines after MOTION
            lines.append(line.rstrip("\r\n"))
            if motion_line is None and lines[-1].strip().upper() == "MOTION":
                motion_line = len(lines) - 1
            elif motion_line is not None and lines[-1].strip():
                after += 1
                if after == 2:
                    break
    if motion_line is None:
        raise BVHError(str(path), None, "no MOTION section")
    n_frames, frame_time, _ = _parse_motion_header(lines, motion_line, str(path))
    return n_frames, frame_time


def parse_bvh(text: str, source: str = "<string>", scale: float = 0.01) -> Motion:
    """Parse BVH ``text`` (the contents of a file); ``source`` names it in error messages."""
    if not (np.isfinite(scale) and scale > 0):
        raise ValueError(f"parse_bvh({source}): scale must be positive, got {scale}")
    lines = _LINE_END.split(text.lstrip("\ufeff"))            # \n, \r\n and old Mac \r alike
    header = _Hierarchy(lines, source)
    motion_line = header.parse()
    n_frames, frame_time, first_data_line = _parse_motion_header(lines, motion_line, source)
    n_channels = sum(len(c) for c in header.channels)
    values = _parse_frames(lines, first_data_line, n_frames, n_channels, source)
    return _build_motion(header, values, frame_time, scale, source)


_TOKEN = re.compile(r"[{}]|[^\s{}]+")
_LINE_END = re.compile(r"\r\n|\r|\n")
#: the largest channel value or offset accepted, in the file's units (10 km in centimetres,
#: 2,800 turns in degrees): beyond it a file is broken and its numbers would overflow later
MAX_VALUE = 1e6


class _Hierarchy:
    """The HIERARCHY section: a small recursive-descent parser over (token, line) pairs.

    Nesting is tracked with an explicit stack, so garbage with thousands of braces can't overflow
    Python's recursion limit.
    """

    def __init__(self, lines: List[str], source: str):
        self.lines = lines
        self.source = source
        self.names: List[str] = []
        self.parents: List[int] = []
        self.offsets: List[Tuple[float, float, float]] = []
        self.channels: List[Tuple[str, ...]] = []
        self.tokens: List[Tuple[str, int]] = []
        self.pos = 0

    def error(self, line: Optional[int], message: str) -> BVHError:
        return BVHError(self.source, line, message)

    def parse(self) -> int:
        """Parse up to MOTION; returns the 0-based index of the MOTION line."""
        motion_line = None
        for i, line in enumerate(self.lines):
            toks = _TOKEN.findall(line)
            if toks and toks[0].upper() == "MOTION":
                if len(toks) > 1:
                    raise self.error(i + 1, f"expected 'MOTION' alone on its line, found {_clip(line)!r}")
                motion_line = i
                break
            self.tokens.extend((t, i + 1) for t in toks)
        end_line = (motion_line + 1) if motion_line is not None else len(self.lines)
        self.tokens.append(("<end of hierarchy>", end_line))

        tok, line = self.next()
        if tok == "<end of hierarchy>":
            raise self.error(line, "expected 'HIERARCHY' at the start of the file, found no text")
        if tok.upper() != "HIERARCHY":
            raise self.error(line, f"expected 'HIERARCHY' at the start of the file, found {tok!r}")
        tok, line = self.peek()
        if tok.upper() != "ROOT":
            raise self.error(line, f"expected 'ROOT' after HIERARCHY, found {tok!r}")
        while self.peek()[0].upper() == "ROOT":
            self.parse_joint_tree()
        tok, line = self.peek()
        if tok == "}":
            raise self.error(line, "unbalanced braces: '}' closes a block that was never opened")
        if motion_line is None or tok != "<end of hierarchy>":
            raise self.error(line, f"expected 'MOTION' after the hierarchy, found {tok!r}")
        return motion_line

    def peek(self) -> Tuple[str, int]:
        return self.tokens[self.pos]

    def next(self) -> Tuple[str, int]:
        tok = self.tokens[self.pos]
        if self.pos < len(self.tokens) - 1:
            self.pos += 1
        return tok

    def expect(self, want: str) -> int:
        tok, line = self.next()
        if tok != want:
            hint = " (unbalanced braces?)" if want in "{}" or tok in "{}" else ""
            raise self.error(line, f"expected {want!r}, found {tok!r}{hint}")
        return line

    def parse_joint_tree(self) -> None:
        """One ROOT block with all its descendants."""
        stack: List[int] = []           # open joints (indices), innermost last
        site_count: Dict[int, int] = {}
        while True:
            tok, line = self.next()
            key = tok.upper()
            parent = stack[-1] if stack else -1
            if key in ("ROOT", "JOINT") and (key == "ROOT") == (not stack):
                name = self.joint_name(line)
                stack.append(self.add_joint(name, parent, line, end_site=False))
            elif key == "END" and stack:
                site_tok, site_line = self.next()
                if site_tok.upper() != "SITE":
                    raise self.error(site_line, f"expected 'Site' after 'End', found {site_tok!r}")
                site_count[parent] = site_count.get(parent, 0) + 1
                n = site_count[parent]
                name = self.names[parent] + "Site" + (str(n) if n > 1 else "")
                self.add_joint(name, parent, line, end_site=True)
            elif tok == "}" and stack:
                stack.pop()
                if not stack:
                    return
            elif tok == "<end of hierarchy>":
                raise self.error(line, f"unbalanced braces: {len(stack)} block(s) still open "
                                       f"(innermost {self.names[stack[-1]]!r}) where the hierarchy ends")
            else:
                inside = f" inside {self.names[parent]!r}" if stack else ""
                raise self.error(line, f"expected 'JOINT', 'End Site' or '}}'{inside}, found {tok!r}")

    def joint_name(self, line: int) -> str:
        """The joint name: every token after ROOT/JOINT on the same line, up to a '{'."""
        parts = []
        while self.peek()[1] == line and self.peek()[0] not in "{}" and self.peek()[0] != "<end of hierarchy>":
            parts.append(self.next()[0])
        if not parts:
            raise self.error(line, "expected a joint name after ROOT/JOINT")
        name = " ".join(parts)
        if name in self.names:
            raise self.error(line, f"duplicate joint name {name!r}: joint names must be unique")
        return name

    def add_joint(self, name: str, parent: int, line: int, end_site: bool) -> int:
        self.expect("{")
        offset = None
        channels: Optional[Tuple[str, ...]] = None
        while True:  # OFFSET and CHANNELS, each once, in either order (End Sites: OFFSET only)
            tok, tline = self.peek()
            key = tok.upper()
            if key == "OFFSET" and offset is None:
                self.next()
                offset = tuple(self.number(f"OFFSET of {name!r}") for _ in range(3))
            elif key == "CHANNELS" and channels is None and not end_site:
                channels = self.channel_list(name)
            else:
                break
        if offset is None:
            raise self.error(tline, f"expected 'OFFSET' in {name!r}, found {tok!r}")
        channels = channels or ()
        index = len(self.names)
        self.names.append(name)
        self.parents.append(parent)
        self.offsets.append(offset)          # type: ignore[arg-type]
        self.channels.append(channels)
        if end_site:
            self.expect("}")
        return index

    def number(self, what: str) -> float:
        tok, line = self.next()
        try:
            value = float(tok)
        except ValueError:
            raise self.error(line, f"expected a number in the {what}, found {tok!r}") from None
        if not abs(value) <= MAX_VALUE:           # also refuses nan and inf
            raise self.error(line, f"expected a finite number of magnitude at most {MAX_VALUE:g} in the {what}, "
                                   f"found {_clip(tok)!r}")
        return value

    def channel_list(self, name: str) -> Tuple[str, ...]:
        _, line = self.next()  # CHANNELS
        tok, nline = self.next()
        if not re.fullmatch(r"\d+", tok):
            raise self.error(nline, f"expected the channel count after CHANNELS in {name!r}, found {tok!r}")
        count = int(tok)
        channels = []
        for k in range(count):
            tok, cline = self.next()
            if cline != line:
                raise self.error(line, f"CHANNELS {count} for {name!r} lists only {k} channel names on "
                                       f"its line (expected {count})")
            canonical = CHANNEL_NAMES.get(tok.lower())
            if canonical is None:
                raise self.error(cline, f"expected channel {k + 1} of {count} for {name!r} (one of "
                                        f"Xposition ... Zrotation), found {tok!r}")
            channels.append(canonical)
        positions = [c for c in channels if c.endswith("position")]
        if len(set(positions)) != len(positions):
            raise self.error(line, f"joint {name!r} lists a position channel twice: {channels}")
        nxt, nline = self.peek()
        if nline == line and CHANNEL_NAMES.get(nxt.lower()):
            raise self.error(line, f"CHANNELS {count} for {name!r} is followed by more channel names "
                                   f"than it declares")
        return tuple(channels)


def _parse_motion_header(lines: List[str], motion_line: int, source: str) -> Tuple[int, float, int]:
    """'Frames: N' and 'Frame Time: t' after MOTION; returns (N, t, index of the first data line)."""
    i = motion_line + 1
    found = {}
    for key, pattern in (("frames", r"frames\s*:\s*(.*)"), ("time", r"frame\s+time\s*:\s*(.*)")):
        while i < len(lines) and not lines[i].strip():
            i += 1
        if i >= len(lines):
            raise BVHError(source, i, f"expected {'Frames: <count>' if key == 'frames' else 'Frame Time: <seconds>'}"
                                      f" after MOTION, reached the end of the file")
        m = re.fullmatch(pattern, lines[i].strip(), flags=re.IGNORECASE)
        value = m.group(1).strip() if m else None
        if key == "frames":
            if value is None or not re.fullmatch(r"\d+", value):
                raise BVHError(source, i + 1, f"expected 'Frames: <count>', found {_clip(lines[i])!r}")
            found[key] = int(value)
            if found[key] == 0:
                raise BVHError(source, i + 1, "expected at least one frame, the file declares 'Frames: 0'")
        else:
            try:
                t = float(value) if value is not None else float("nan")
            except ValueError:
                t = float("nan")
            if not (np.isfinite(t) and t > 0):
                raise BVHError(source, i + 1, f"expected 'Frame Time: <positive seconds>', found {_clip(lines[i])!r}")
            if not MIN_FPS <= 1.0 / t <= MAX_FPS:
                raise BVHError(source, i + 1, f"'Frame Time: {t:g}' is {1.0 / t:g} frames per second; expected "
                                              f"{MIN_FPS:g} to {MAX_FPS:g} (a frame time of {1 / MAX_FPS:g} to {1 / MIN_FPS:g} s)")
            found[key] = t
        i += 1
    return found["frames"], found["time"], i


def _clip(line: str, n: int = 40) -> str:
    """A line shortened for an error message."""
    line = line.strip()
    return line if len(line) <= n else line[:n] + "..."


def _parse_frames(lines: List[str], first: int, n_frames: int, n_channels: int, source: str) -> np.ndarray:
    """(n_frames, n_channels) float array from the data lines, checking each line's count."""
    tokens: List[str] = []
    line_numbers: List[int] = []
    for i in range(first, len(lines)):
        parts = lines[i].split()
        if not parts:
            continue
        if len(line_numbers) == n_frames:
            raise BVHError(source, i + 1, f"expected {n_frames} frames as declared by 'Frames:', "
                                          f"found more data")
        if len(parts) != n_channels:
            raise BVHError(source, i + 1, f"expected {n_channels} values in frame {len(line_numbers) + 1}, "
                                          f"found {len(parts)}")
        tokens.extend(parts)
        line_numbers.append(i + 1)
    if len(line_numbers) < n_frames:
        raise BVHError(source, len(lines), f"expected {n_frames} frames as declared by 'Frames:', "
                                           f"the file ends after {len(line_numbers)}")
    try:
        values = np.fromiter(map(float, tokens), dtype=np.float64, count=len(tokens))
    except ValueError:
        values = None
    if values is None or not np.all(np.abs(values) <= MAX_VALUE):      # also catches nan and inf
        _raise_bad_value(tokens, line_numbers, n_channels, source)
    return values.reshape(n_frames, n_channels)


def _raise_bad_value(tokens: List[str], line_numbers: List[int], n_channels: int, source: str) -> None:
    """Slow path: find the first non-numeric or non-finite value and name its line."""
    for k, tok in enumerate(tokens):
        try:
            ok = abs(float(tok)) <= MAX_VALUE
        except ValueError:
            ok = False
        if not ok:
            raise BVHError(source, line_numbers[k // n_channels],
                           f"expected a finite number of magnitude at most {MAX_VALUE:g} as value {k % n_channels + 1}, "
                           f"found {_clip(tok)!r}")
    raise AssertionError("unreachable: a bad value was detected but not found")


def _build_motion(h: _Hierarchy, values: np.ndarray, frame_time: float, scale: float, source: str) -> Motion:
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
