"""Whole-motion edits that build a new ``Motion``: left/right mirroring and resampling.

Mirroring follows original-pipeline.md §1.3 (joint names decide the partners); resampling uses
slerp for rotations and linear interpolation for translations, so data at 30, 60 and 120 fps can
be brought to one rate.
"""
from __future__ import annotations

import re
from typing import Sequence

import numpy as np

from minifilm.motion.kinematics import matrix_to_quat, quat_to_matrix, slerp
from minifilm.motion.motion import Motion

# ----------------------------------------------------------------------------------------------
# Mirroring (original-pipeline.md §1.3)
# ----------------------------------------------------------------------------------------------

_SUFFIX_LR = re.compile(r"_([LR])(?=$|_|Site$)")


def mirror_name(name: str) -> str:
    """The name of the joint on the other side, or ``name`` itself when it has no side.

    Rules, tried in turn: the substrings ``Left`` <-> ``Right`` (also lower case ``left``/``right``),
    as the original does (MD l.196-234); a leading ``L``/``R`` followed by a capital (``LHipJoint``);
    and, beyond the original, a leading ``l``/``r`` followed by a capital (CMU ``rCollar``) and a
    ``_L``/``_R`` suffix as in the Bandai files (``Hand_L``, ``Hand_LSite``).
    """
    for a, b in (("Left", "Right"), ("left", "right")):
        if a in name or b in name:
            return b.join(part.replace(b, a) for part in name.split(a))
    if len(name) >= 2 and name[0] in "LRlr" and name[1].isupper():
        return {"L": "R", "R": "L", "l": "r", "r": "l"}[name[0]] + name[1:]
    m = _SUFFIX_LR.search(name)
    if m:
        side = "R" if m.group(1) == "L" else "L"
        return name[:m.start(1)] + side + name[m.end(1):]
    return name


def mirror_pairs(names: Sequence[str]) -> np.ndarray:
    """(J,) index of each joint's mirror partner; joints without a partner map to themselves."""
    index = {n: i for i, n in enumerate(names)}
    return np.array([index.get(mirror_name(n), i) for i, n in enumerate(names)], dtype=np.int64)


def mirror(motion):
    """Mirror a motion across the character's left/right, about the world x axis (§1.3).

    In world space ``mirrored World_j = M World_sym(j) M`` with ``M = diag(-1, 1, 1)``. When the
    hierarchy is symmetric (``sym(parent(j)) == parent(sym(j))``) this is the same as mirroring the
    local transforms, ``R'_j = M R_sym(j) M`` and ``t'_j = M t_sym(j)``, so the result is again a
    ``Motion`` with the same joints and channels: world positions become ``(-x, y, z)`` of the
    partner joint's. Raises ValueError when the hierarchy is not symmetric.
    """
    sym = mirror_pairs(motion.names)
    parents = motion.parents
    for j in range(motion.n_joints):
        p, ps = parents[j], parents[sym[j]]
        if (p < 0) != (ps < 0) or (p >= 0 and sym[p] != ps):
            raise ValueError(f"mirror({motion.source}): hierarchy is not left/right symmetric at joint "
                             f"{motion.names[j]!r} (partner {motion.names[sym[j]]!r})")
    M = np.diag([-1.0, 1.0, 1.0])
    rotations = M @ motion.rotations[:, sym] @ M
    translations = motion.translations[:, sym] * np.array([-1.0, 1.0, 1.0])
    offsets = motion.offsets[sym] * np.array([-1.0, 1.0, 1.0])
    return Motion(list(motion.names), parents.copy(), offsets, list(motion.channels), rotations,
                  translations, motion.frame_time, f"mirror({motion.source})")


# ----------------------------------------------------------------------------------------------
# Resampling
# ----------------------------------------------------------------------------------------------

def resample(motion, fps: float):
    """The same motion at another frame rate: slerp for rotations, linear for translations.

    New frame ``k`` sits at time ``k / fps``; frames run while that time is within the original
    duration ``(F - 1) * frame_time`` (plus a 1e-6 frame tolerance), so the first frame is kept and
    the last new frame is at or before the last old one. Returns a new ``Motion``.

    BVH files store rounded frame times (1/60 s as 0.016667), so a source rate within 0.01 % of a
    whole number of frames per second is taken to be that number, as the original importer does
    (``round(1 / FrameTime)``, BVH l.300). That makes 60 -> 30 fps keep exactly every second frame.
    """
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"resample: fps must be positive, got {fps}")
    F = motion.n_frames
    source_fps = motion.fps
    if abs(source_fps - round(source_fps)) < 1e-4 * source_fps:
        source_fps = float(round(source_fps))
    step = source_fps / fps                            # old frames per new frame
    n_new = int(np.floor((F - 1) / step + 1e-6)) + 1
    u = np.arange(n_new) * step                        # fractional old-frame index per new frame
    i0 = np.clip(np.floor(u + 1e-9).astype(np.int64), 0, F - 1)
    i1 = np.minimum(i0 + 1, F - 1)
    a = np.clip(u - i0, 0.0, 1.0)
    q = matrix_to_quat(motion.rotations)               # (F, J, 4)
    q_new = slerp(q[i0], q[i1], np.broadcast_to(a[:, None], (n_new, motion.n_joints)))
    rotations = quat_to_matrix(q_new)
    t0, t1 = motion.translations[i0], motion.translations[i1]
    translations = t0 + a[:, None, None] * (t1 - t0)
    return Motion(list(motion.names), motion.parents.copy(), motion.offsets.copy(), list(motion.channels),
                  rotations, translations, 1.0 / fps, f"resample({motion.source}, {fps:g} fps)")
