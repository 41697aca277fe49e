"""Look at every file of a dataset before building it: frame rates, lengths, and the memory it needs.

Reading only each BVH header (:func:`minifilm.motion.bvh.bvh_header`), the survey refuses, with one
error naming the files at fault, what would otherwise fail late or blame the wrong file:

* files at different frame rates when no common rate is set (the minority is named, not whichever
  file happened to be read second);
* a frame range (manifest ``start, end``) outside its file, and files too short for a single row;
* a dataset whose arrays would not fit in memory (estimated before anything is allocated);
* files of another rig than the others (:func:`check_one_rig`: the skeleton's joints are read
  off every header, so one foreign file among hundreds is named before any file is labelled).
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace
from typing import Dict, List, Optional, Sequence, Tuple

from minifilm.dataset.manifest import MotionFile
from minifilm.errors import DataError
from minifilm.files.reading import memory_budget
from minifilm.motion.bvh import bvh_header_names

#: Frames a file needs for one training row (a current frame with a frame before and after it).
MIN_FRAMES = 3
#: Bytes of transient float64 work per joint and frame while one file is labelled and featurised
#: (rotations, world transforms, velocities, phase fits), measured on the Bandai files (~230) with room.
WORK_BYTES_PER_JOINT_FRAME = 400


@dataclass
class FileSurvey:
    path: Path
    n_frames: int           # frames used: the manifest's range, at the dataset's frame rate
    fps: float              # the file's own rate
    n_joints: int = 0       # joints in the file's hierarchy (End Sites included): what reading it allocates
    raw_frames: int = 0     # frames in the file, before cropping and resampling
    names: Tuple[str, ...] = ()   # its joints' names (End Sites included), from the header


def _round_rate(fps: float) -> float:
    return float(f"{fps:.4g}")


def survey(files: Sequence[MotionFile], fps: Optional[float]) -> Dict[Path, FileSurvey]:
    """Per file, its frame count (cropped and resampled as the build will) and rate; DataError
    for mixed rates without a common ``fps``, a range outside a file, or a file too short."""
    out: Dict[Path, FileSurvey] = {}
    for f in files:
        names, n, frame_time = bvh_header_names(f.path)
        n_joints = len(names)
        rate = 1.0 / frame_time
        a = 0 if f.start is None else f.start
        b = n if f.end is None else f.end
        if not (0 <= a < b <= n):
            raise DataError(f"{f.path}: frame range [{a}, {b}) does not fit its {n} frames")
        used = b - a if fps is None else int((b - a - 1) * fps / rate) + 1
        if used < MIN_FRAMES:
            raise DataError(f"{f.path}: {used} frame{'s' if used != 1 else ''} to use; a file needs at least "
                            f"{MIN_FRAMES} (one frame with a neighbour on each side)")
        out[Path(f.path)] = FileSurvey(Path(f.path), used, rate, n_joints, n, tuple(names))
    if fps is None:
        rates = Counter(_round_rate(s.fps) for s in out.values())
        if len(rates) > 1:
            common = rates.most_common(1)[0][0]
            odd = [s for s in out.values() if _round_rate(s.fps) != common]
            listed = ", ".join(f"{s.path.name} ({s.fps:g} fps)" for s in odd[:5])
            more = f" and {len(odd) - 5} more" if len(odd) > 5 else ""
            raise DataError(f"{len(odd)} of {len(out)} files are not at the others' {common:g} fps: {listed}{more}; "
                            "resample them all to one rate (--fps of minifilm train / dataset, "
                            "DatasetSettings(fps=...))")
    return out


def most_common_rig(surveyed: Dict[Path, FileSurvey]) -> SimpleNamespace:
    """The joint names most files share, as a stand-in motion (``names``, ``source``) for
    :func:`~minifilm.body.rig.detect_skeleton`: the data set's skeleton is the majority's,
    not whichever file comes first."""
    layouts = Counter(s.names for s in surveyed.values())
    names, count = layouts.most_common(1)[0]
    first = next(s.path for s in surveyed.values() if s.names == names)
    return SimpleNamespace(names=list(names), source=f"{first} (and the {count - 1} other files of its joints)")


def check_one_rig(surveyed: Dict[Path, FileSurvey], skeleton) -> None:
    """DataError naming the files that lack joints ``skeleton`` reads (files of another rig), from
    their headers alone, before any file is read in full."""
    odd = [(s, skeleton.missing_joints(SimpleNamespace(names=s.names))) for s in surveyed.values()]
    odd = [(s, missing) for s, missing in odd if missing]
    if not odd:
        return
    listed = "; ".join(f"{s.path.name} lacks {', '.join(missing[:4])}{' ...' if len(missing) > 4 else ''} "
                       f"(its {len(s.names)} joints start {', '.join(s.names[:3])})" for s, missing in odd[:3])
    more = f"; and {len(odd) - 3} more" if len(odd) > 3 else ""
    fitting = next((s.path for s in surveyed.values() if not skeleton.missing_joints(SimpleNamespace(names=s.names))),
                   None)
    how = (f"put them on the others' rig first (minifilm retarget FILES --to {fitting} --out DIR; "
           f"minifilm train --data ... --rig {fitting} retargets every file as it trains)"
           if fitting is not None else f"give files of the {skeleton.name!r} skeleton")
    raise DataError(f"{len(odd)} of {len(surveyed)} files are not of the {skeleton.name!r} skeleton the data set "
                    f"is read with: {listed}{more}. A data set is one rig: {how}, or leave them out")


def check_memory(surveyed: Dict[Path, FileSurvey], mirrored: List[bool], layout, clip_frames: int,
                 clip_stride_frames: int, itemsize: int, budget: Optional[int] = None) -> int:
    """Estimated peak bytes of building the dataset; DataError when it exceeds ``budget``.

    The stacked arrays: per frame x, z, p (``itemsize`` each) and three int32 indices, times two
    for a mirrored file, plus its style clips (one every ``clip_stride_frames``); and the largest
    file's transient work."""
    budget = memory_budget() if budget is None else budget
    row = (layout.x_dim + layout.z_dim + layout.phase_dim) * itemsize + 12
    clip_per_frame = clip_frames * layout.clip_dim * itemsize / max(1, clip_stride_frames)
    frames = sum(s.n_frames * (2 if m else 1) for s, m in zip(surveyed.values(), mirrored))
    arrays = frames * (row + clip_per_frame)
    # the file's own joints (a rig may have far more than the skeleton's exported ones), read at
    # its own rate before any resampling
    work = max(max(s.n_frames, s.raw_frames) * max(s.n_joints, layout.n_joints) for s in surveyed.values()) \
        * 2 * WORK_BYTES_PER_JOINT_FRAME
    total = int(arrays + work)
    if total > budget:
        raise DataError(f"the dataset would need about {total / 2**30:.1f} GiB ({frames:,} frames of "
                        f"{len(surveyed)} files), more than {budget / 2**30:.1f} GiB (half of this machine's "
                        "memory); use fewer or shorter files, or a lower frame rate")
    return total
