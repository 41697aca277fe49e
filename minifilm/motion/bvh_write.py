"""Write a Motion as a BVH file (the inverse of ``bvh.read_bvh``), atomically.

Each joint keeps its own channels and rotation order, lengths are divided by ``scale`` (metres ->
centimetres by default) and rotations written in degrees, so a file read and written back gives the
same motion.
"""
from __future__ import annotations

import os
import re
from typing import List, Sequence, Tuple, Union

import numpy as np

from minifilm.files import atomic_write_text
from minifilm.motion.kinematics import matrix_to_euler
from minifilm.motion.motion import Motion


def write_bvh(motion: Motion, path: Union[str, os.PathLike], scale: float = 0.01) -> None:
    """Write ``motion`` as BVH (lengths divided by ``scale``; radians -> degrees), atomically.

    Each joint keeps its own channels and rotation order. A joint whose rotation channels are not
    three distinct axes (rare) is written with its position channels plus ``Zrotation Xrotation
    Yrotation``. Joints without channels are written as ``End Site`` when they are named
    ``<Parent>Site`` and have no children, otherwise as ``JOINT`` with ``CHANNELS 0``.
    Raises ValueError when a joint without position channels has translations that differ from its
    offset (BVH could not represent them).
    """
    atomic_write_text(path, format_bvh(motion, scale))


def format_bvh(motion: Motion, scale: float = 0.01) -> str:
    """The BVH text ``write_bvh`` writes."""
    if not (np.isfinite(scale) and scale > 0):
        raise ValueError(f"write_bvh: scale must be positive, got {scale}")
    J, F = motion.n_joints, motion.n_frames
    if F < 1:
        raise ValueError(f"write_bvh({motion.source}): a BVH file needs at least one frame")
    children: List[List[int]] = [[] for _ in range(J)]
    for j, p in enumerate(motion.parents):
        if p >= 0:
            children[p].append(j)
    channels = [_writable_channels(motion.channels[j]) for j in range(J)]

    out = ["HIERARCHY"]

    def emit(j: int, depth: int) -> None:
        pad = "\t" * depth
        off = motion.offsets[j] / scale
        offset_line = f"{pad}\tOFFSET {off[0]:.6f} {off[1]:.6f} {off[2]:.6f}"
        p = motion.parents[j]
        is_site = (not channels[j] and not children[j] and p >= 0
                   and re.fullmatch(re.escape(motion.names[p]) + r"Site\d*", motion.names[j]) is not None)
        if is_site:
            out.extend([f"{pad}End Site", f"{pad}{{", offset_line, f"{pad}}}"])
            return
        out.append(f"{pad}{'ROOT' if p < 0 else 'JOINT'} {motion.names[j]}")
        out.extend([f"{pad}{{", offset_line,
                    f"{pad}\tCHANNELS {len(channels[j])}" + "".join(" " + c for c in channels[j])])
        for c in children[j]:
            emit(c, depth + 1)
        out.append(f"{pad}}}")

    # Recursion depth is the skeleton's depth (tens of joints at most in practice).
    for root in (j for j in range(J) if motion.parents[j] < 0):
        emit(root, 0)

    values = _frame_values(motion, channels, scale)
    out += ["MOTION", f"Frames: {F}", f"Frame Time: {motion.frame_time:.10g}"]
    if values.shape[1] == 0:
        raise ValueError(f"write_bvh({motion.source}): no joint has channels, nothing to write per frame")
    row = " ".join(["%.6f"] * values.shape[1])
    out.extend(row % tuple(v) for v in values)
    return "\n".join(out) + "\n"


def _writable_channels(chans: Sequence[str]) -> Tuple[str, ...]:
    rot = "".join(c[0] for c in chans if c.endswith("rotation"))
    if not rot or (len(rot) == 3 and len(set(rot)) == 3):
        return tuple(chans)
    return tuple(c for c in chans if c.endswith("position")) + ("Zrotation", "Xrotation", "Yrotation")


def _frame_values(motion: Motion, channels: List[Tuple[str, ...]], scale: float) -> np.ndarray:
    """(F, total channels) BVH values: positions / scale, rotations in degrees in each joint's order."""
    columns = []
    for j, chans in enumerate(channels):
        t = motion.translations[:, j] / scale
        has = {c[0] for c in chans if c.endswith("position")}
        fixed = [a for a in range(3) if "XYZ"[a] not in has]
        if fixed:
            drift = np.abs(motion.translations[:, j, fixed] - motion.offsets[j, fixed]).max()
            if drift > 1e-9 + 1e-9 * np.abs(motion.offsets[j]).max():
                raise ValueError(f"write_bvh({motion.source}): joint {motion.names[j]!r} has no "
                                 f"{'/'.join('XYZ'[a] for a in fixed)} position channel but its translation "
                                 f"moves away from its offset (by {drift:.3g} m); BVH can't represent that")
        order = "".join(c[0] for c in chans if c.endswith("rotation"))
        angles = np.degrees(matrix_to_euler(motion.rotations[:, j], order)) if order else None
        k = 0
        for c in chans:
            if c.endswith("position"):
                columns.append(t[:, "XYZ".index(c[0])])
            else:
                columns.append(angles[:, k])
                k += 1
    if not columns:
        return np.zeros((motion.n_frames, 0))
    return np.stack(columns, axis=1)
