"""The BVH text format: its tokens, its numbers and the HIERARCHY section, parsed strictly.

:class:`Hierarchy` reads the joint tree (names, parents, offsets, channels) from the lines before
MOTION; :func:`parse_motion_header` reads ``Frames:`` and ``Frame Time:``. Every problem is a
:class:`BVHError` naming the file, the line and what was expected. What the numbers mean (units,
rotation orders) is :mod:`minifilm.motion.bvh`'s business.
"""
from __future__ import annotations

import re
from typing import Dict, List, Optional, Tuple

import numpy as np

from minifilm.errors import MAX_FPS, MIN_FPS, InputError

CHANNEL_NAMES = {f"{axis}{kind}".lower(): f"{axis}{kind}"
                 for axis in "XYZ" for kind in ("position", "rotation")}


class BVHError(InputError):
    """A malformed BVH file. The message names the file, the line number and what was expected."""

    def __init__(self, source: str, line: Optional[int], message: str):
        self.source = source
        self.line = line
        where = f"{source}, line {line}" if line is not None else source
        super().__init__(f"{where}: {message}")

    @classmethod
    def about_file(cls, message: str) -> "BVHError":
        """A problem with the file as a whole (a FIFO, too large), worded with its path already."""
        error = cls.__new__(cls)
        InputError.__init__(error, message)
        error.source, error.line = None, None
        return error

    def __reduce__(self):
        """Pickled as it is (a worker process's error travels so): its message as worded, then its
        file, line and notes; not through __init__, which words the message."""
        return type(self).about_file, (str(self.args[0]),), self.__dict__


_TOKEN = re.compile(r"[{}]|[^\s{}]+")
#: a number as BVH files write it: ASCII digits, an optional sign, point and exponent (Python's
#: float() would also take "1_0", digits of other scripts, "nan" and "inf")
NUMBER = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
LINE_END = re.compile(r"\r\n|\r|\n")
#: the largest channel value or offset accepted, in the file's units (10 km in centimetres,
#: 2,800 turns in degrees): beyond it a file is broken and its numbers would overflow later
MAX_VALUE = 1e6
#: the longest joint name accepted (real rigs: under 40 characters)
MAX_JOINT_NAME = 256


class Hierarchy:
    """The HIERARCHY section: a small recursive-descent parser over (token, line) pairs.

    Nesting is tracked with an explicit stack, so garbage with thousands of braces can't overflow
    Python's recursion limit.
    """

    def __init__(self, lines: List[str], source: str):
        self.lines = lines
        self.source = source
        self.names: List[str] = []
        self.name_set: set = set()              # the same names, for a duplicate check in O(1)
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
                    raise self.error(i + 1, f"expected 'MOTION' alone on its line, found {clip(line)!r}")
                motion_line = i
                break
            self.tokens.extend((t, i + 1) for t in toks)
        end_line = (motion_line + 1) if motion_line is not None else len(self.lines)
        self.tokens.append(("<end of hierarchy>", end_line))

        tok, line = self.next()
        if tok == "<end of hierarchy>" and motion_line is not None:
            raise self.error(line, "the file starts with MOTION: it has no HIERARCHY section (the skeleton "
                                   "must come first, 'HIERARCHY' then 'ROOT ...')")
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
        if not name.isprintable() or len(name) > MAX_JOINT_NAME:
            raise self.error(line, f"joint name {clip(name)!r}: expected at most {MAX_JOINT_NAME} printable "
                                   "characters (no control characters)")
        if name in self.name_set:
            raise self.error(line, f"duplicate joint name {clip(name)!r}: joint names must be unique")
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
        self.name_set.add(name)
        self.parents.append(parent)
        self.offsets.append(offset)          # type: ignore[arg-type]
        self.channels.append(channels)
        if end_site:
            self.expect("}")
        return index

    def number(self, what: str) -> float:
        tok, line = self.next()
        if not NUMBER.fullmatch(tok):
            raise self.error(line, f"expected a number in the {what}, found {clip(tok)!r}")
        value = float(tok)
        if not abs(value) <= MAX_VALUE:           # also refuses nan and inf
            raise self.error(line, f"expected a finite number of magnitude at most {MAX_VALUE:g} in the {what}, "
                                   f"found {clip(tok)!r}")
        return value

    def channel_list(self, name: str) -> Tuple[str, ...]:
        _, line = self.next()  # CHANNELS
        tok, nline = self.next()
        if not re.fullmatch(r"[0-9]{1,3}", tok):
            raise self.error(nline, f"expected the channel count (0-999) after CHANNELS in {name!r}, "
                                    f"found {clip(tok)!r}")
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


def parse_motion_header(lines: List[str], motion_line: int, source: str) -> Tuple[int, float, int]:
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
            if value is None or not re.fullmatch(r"[0-9]+", value):
                raise BVHError(source, i + 1, f"expected 'Frames: <count>', found {clip(lines[i])!r}")
            if len(value.lstrip("0")) > 9:
                raise BVHError(source, i + 1, f"'Frames: {clip(value, 12)}' declares more than 999,999,999 frames")
            found[key] = int(value)
            if found[key] == 0:
                raise BVHError(source, i + 1, "expected at least one frame, the file declares 'Frames: 0'")
        else:
            # the same spelling as the motion's numbers: float() alone would take "0.01_6" or
            # Arabic-Indic digits, which no BVH writer produces and the frames would refuse
            t = float(value) if value is not None and NUMBER.fullmatch(value) else float("nan")
            if not (np.isfinite(t) and t > 0):
                raise BVHError(source, i + 1, f"expected 'Frame Time: <positive seconds>', found {clip(lines[i])!r}")
            if not MIN_FPS <= 1.0 / t <= MAX_FPS:
                raise BVHError(source, i + 1, f"'Frame Time: {t:g}' is {1.0 / t:g} frames per second; expected "
                                              f"{MIN_FPS:g} to {MAX_FPS:g} (a frame time of {1 / MAX_FPS:g} to {1 / MIN_FPS:g} s)")
            found[key] = t
        i += 1
    return found["frames"], found["time"], i


def clip(line: str, n: int = 40) -> str:
    """A line shortened for an error message."""
    line = line.strip()
    return line if len(line) <= n else line[:n] + "..."
