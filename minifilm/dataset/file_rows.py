"""One file's share of a dataset: read it, label it (contacts, local phases), cut it into segments,
and compute the rows and style clips of every segment, for the file and its mirrored copy.

    MotionFile -> load_motion (crop, resample) -> label (phases/label.py) -> file_segments
               -> per variant (the file, its mirror): x, p, z rows and clips y per segment (features/)

:func:`label_file` depends on nothing but its arguments (not on the other files), so the builder
(build.py) may call it file after file in one process, or in worker processes (minifilm/parallel.py)
and get the same numbers.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import List, Optional, Tuple

import numpy as np

from minifilm.body.read import Body
from minifilm.dataset.manifest import MotionFile
from minifilm.dataset.settings import DatasetSettings
from minifilm.dataset.splits import apply_gap, file_rng, split_segments
from minifilm.dataset.validate import check_finite
from minifilm.errors import DataError
from minifilm.features.compute import (FrameFeatures, clip_features_from_arrays, frame_features_from_arrays,
                                       motion_arrays)
from minifilm.features.layout import FeatureLayout
from minifilm.motion.bvh import read_bvh
from minifilm.motion.editing import mirror, resample
from minifilm.phases.label import label

#: (first frame, end frame, split) of one segment of a file
Segment = Tuple[int, int, str]


@dataclass
class Variant:
    """The rows and clips of the file or of its mirrored copy.

    rows: [(split, FrameFeatures)] one per segment (x (N, x_dim), p (N, 8), z (N, z_dim), frames (N,));
    clips: [(split, y (M, T, clip_dim))] one per segment, or [] when no clips were asked for."""
    mirrored: bool
    n_frames: int
    rows: List[Tuple[str, FrameFeatures]]
    clips: List[Tuple[str, np.ndarray]]


@dataclass
class FileRows:
    """Everything the builder keeps of one file: the frame rate it was featurised at, its segments
    and its variants (the file, then its mirrored copy if the settings mirror it)."""
    fps: float
    segments: List[Segment]
    variants: List[Variant]


def load_motion(f: MotionFile, skeleton, fps: Optional[float]):
    """One manifest entry as a Motion: read in metres (in the skeleton's unit, or the one the
    body's legs give when it is saved in another: :meth:`~minifilm.body.read.Body.on_skeleton`),
    cropped to its frame range, resampled to ``fps``."""
    motion, _ = Body(read_bvh(f.path, scale=1.0)).on_skeleton(skeleton)
    if f.start is not None or f.end is not None:
        a = 0 if f.start is None else f.start
        b = motion.n_frames if f.end is None else f.end
        if b > motion.n_frames or a >= b:
            raise ValueError(f"{f.path}: frame range [{a}, {b}) does not fit its {motion.n_frames} frames")
        motion = motion.slice(a, b)
    if fps is not None and abs(motion.fps - fps) > 1e-3 * fps:
        motion = resample(motion, fps)
    return motion


def file_segments(f: MotionFile, n_frames: int, settings: DatasetSettings, fps: float,
                  whole_split: Optional[str]) -> List[Segment]:
    """The file's segments: a transition file is all train (unless ``split_transitions``), a file
    split whole goes to ``whole_split``, any other is cut 80/10/10 by its own seeded windows."""
    if f.gait.startswith("TR") and not settings.split_transitions:
        return [(0, n_frames, "train")]
    if whole_split is not None:
        return [(0, n_frames, whole_split)]
    segs = split_segments(n_frames, file_rng(settings.seed, f), settings.split_fractions)
    return apply_gap(segs, int(round(settings.gap_seconds * fps)))


def featurise(motion, skeleton, contacts, phases, segments, fps, want_clips, settings, dtype):
    """Rows and clips of every segment of one (possibly mirrored) motion."""
    arrays = motion_arrays(motion, skeleton, fps)
    rows, clips = [], []
    for a, b, split in segments:
        f = frame_features_from_arrays(*arrays, phases, contacts, fps, a, b, dtype)
        rows.append((split, f))
        if want_clips:
            y = clip_features_from_arrays(*arrays, fps, settings.clip_seconds,
                                          settings.clip_stride_seconds, a, b, dtype)
            clips.append((split, y))
    return rows, clips


def label_file(f: MotionFile, settings: DatasetSettings, skeleton, fps: Optional[float],
               whole_split: Optional[str], want_clips: bool, dtype) -> FileRows:
    """Read, label and featurise one file (and its mirror). ``fps``: the dataset's frame rate, or
    None for the first file read (its own rate becomes the dataset's); a file at another rate is a
    DataError. ``whole_split``: the split of a file split whole (settings.split_unit 'files')."""
    motion = load_motion(f, skeleton, settings.fps)
    if fps is None:
        fps = motion.fps
    elif abs(motion.fps - fps) > 1e-3 * fps:      # survey() refuses this up front
        raise DataError(f"{f.path}: {motion.fps:g} fps differs from the other files' {fps:g} fps; "
                        f"set DatasetSettings(fps=...) to resample")
    labels = label(motion, skeleton, f.style)
    segments = file_segments(f, motion.n_frames, settings, fps, whole_split)
    todo = [(False, motion, labels)]
    if settings.mirrors(f):
        todo.append((True, mirror(motion), labels.mirrored()))
    layout = FeatureLayout.for_skeleton(skeleton)
    variants = []
    for mirrored, m, lab in todo:
        rows, clips = featurise(m, skeleton, lab.contacts, lab.vectors, segments, fps, want_clips, settings, dtype)
        for _, ff in rows:
            for what, a in (("x", ff.x), ("z", ff.z), ("p", ff.p)):
                check_finite(a, what, layout, f"{f.path}{' (mirrored)' if mirrored else ''}", ff.frames)
        variants.append(Variant(mirrored, m.n_frames, rows, clips))
    return FileRows(fps, segments, variants)

