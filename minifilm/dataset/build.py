"""Build a dataset: BVH files -> training rows (x, p, z), style clips y, splits, statistics (Sec. 3.2, 4.3).

    files (manifest.py) -> per file: read, label (contacts, local phases), split into segments
                        -> per segment (and its mirror): x, p, z rows and style clips (features/)
                        -> normalisation statistics from the training rows (stats.py)
                        -> cached .npz (cache.py, dataset.py)

Each segment is featurised as if it were its own clip (features/compute.py): trajectory samples
that fall outside it are point-reflected at its ends and the first / last frame are never
"current", so no validation or test row contains a number computed from a training frame, and vice
versa. Phases and contacts are labels of the whole file (the phase fit needs ~1 s of context),
which is the one place where a row's numbers depend on its neighbours. A mirrored copy uses the
same segments as its original. Transition files (gait ``TR*``) are all train unless
``split_transitions`` (§8.2).

Style-balanced minibatches (Sec. 4.3) are the trainer's job (``minifilm.train.batches``).
"""
from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from minifilm.dataset.cache import cached_key, dataset_cache_key
from minifilm.dataset.dataset import Dataset, Split
from minifilm.dataset.manifest import MotionFile, read_manifest, scan_folder
from minifilm.dataset.progress import Progress
from minifilm.dataset.settings import DatasetSettings
from minifilm.dataset.splits import SPLITS, apply_gap, file_rng, split_files, split_segments
from minifilm.dataset.stats import NormStats
from minifilm.dataset.survey import check_memory, check_one_rig, most_common_rig, survey
from minifilm.dataset.validate import check_every_style_trains, check_finite
from minifilm.errors import DataError
from minifilm.files import check_name, note_input, owned_writes
from minifilm.features.compute import clip_features_from_arrays, frame_features_from_arrays, motion_arrays
from minifilm.features.layout import FeatureLayout
from minifilm.motion.bvh import read_bvh
from minifilm.motion.editing import mirror, resample
from minifilm.motion.skeletons import builtin_skeleton, detect_skeleton
from minifilm.phases.label import label


def resolve_files(source: Union[str, Path, Sequence[MotionFile]]) -> List[MotionFile]:
    """A folder (100STYLE or Bandai Namco naming), a .csv manifest, or a list of MotionFile."""
    if isinstance(source, (str, Path)):
        p = Path(source)
        files = read_manifest(p) if p.suffix.lower() == ".csv" else scan_folder(p)
        note_input(p)
    else:
        files = list(source)
        if not files or not all(isinstance(f, MotionFile) for f in files):
            raise TypeError("build_dataset: source must be a folder, a .csv manifest or a non-empty list "
                            "of minifilm.dataset.manifest.MotionFile")
    for f in files:             # names from data become file names: one rule (minifilm/files/names.py)
        check_name(f.style, f"{f.path}: style")
        check_name(f.gait, f"{f.path}: gait")
        note_input(f.path)      # no output of this command may replace a file it learns from
    return files


def _load_motion(f: MotionFile, skeleton, fps: Optional[float]):
    """One manifest entry as a Motion: read, cropped to its frame range, resampled to ``fps``."""
    motion = read_bvh(f.path, scale=skeleton.bvh_scale)
    if f.start is not None or f.end is not None:
        a = 0 if f.start is None else f.start
        b = motion.n_frames if f.end is None else f.end
        if b > motion.n_frames or a >= b:
            raise ValueError(f"{f.path}: frame range [{a}, {b}) does not fit its {motion.n_frames} frames")
        motion = motion.slice(a, b)
    if fps is not None and abs(motion.fps - fps) > 1e-3 * fps:
        motion = resample(motion, fps)
    return motion


def _featurise(motion, skeleton, contacts, phases, segments, fps, want_clips, settings, dtype):
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


def _pick_skeleton(settings: DatasetSettings, surveyed):
    """The skeleton named in the settings, else the built-in one the joints of most files match
    (read off their headers by the survey)."""
    if settings.skeleton is not None:
        try:
            return builtin_skeleton(settings.skeleton)
        except ValueError as e:
            raise ValueError(f"DatasetSettings.skeleton: {e}") from None
    return detect_skeleton(most_common_rig(surveyed))


def build_dataset(source: Union[str, Path, Sequence[MotionFile]],
                  settings: Optional[DatasetSettings] = None, cache_dir: Union[str, Path, None] = None,
                  progress: bool = True, skeleton=None, dtype=np.float32, **overrides) -> Dataset:
    """Build (or load from cache) the dataset of a 100STYLE-named folder, a CSV manifest or a list
    of :class:`~minifilm.dataset.manifest.MotionFile`.

    Args:
        settings: a :class:`DatasetSettings`; keyword ``overrides`` replace single fields.
        cache_dir: where ``dataset-<name hash>.npz`` lives; None disables caching. A cache whose
            files, code or settings changed is rebuilt and overwritten.
        progress: a status line on stderr.
        skeleton: a :class:`~minifilm.motion.skeletons.Skeleton` object for a custom skeleton
            (overrides ``settings.skeleton``; its repr enters the cache key).
    """
    settings = settings or DatasetSettings()
    if overrides:
        settings = DatasetSettings(**{**settings.to_dict(), **overrides})
    files = [f for f in resolve_files(source) if f.gait not in settings.idle_gaits]
    if not files:
        raise ValueError("build_dataset: every file is idle (see DatasetSettings.idle_gaits)")
    cache_path, key = None, ""
    if cache_dir is not None:
        name, key = dataset_cache_key(files, settings, skeleton)
        cache_path = Path(cache_dir) / f"dataset-{name}.npz"
        if cache_path.is_file() and cached_key(cache_path) == key:
            return Dataset.load(cache_path)
    t0 = time.perf_counter()
    surveyed = survey(files, settings.fps)                # headers only: rates, lengths, joints
    skeleton = skeleton or _pick_skeleton(settings, surveyed)
    check_one_rig(surveyed, skeleton)                     # a foreign file named before any is read
    fps = settings.fps or next(iter(surveyed.values())).fps
    check_memory(surveyed, [settings.mirrors(f) for f in files], FeatureLayout.for_skeleton(skeleton),
                 int(round(settings.clip_seconds * fps)), int(round(settings.clip_stride_seconds * fps)),
                 np.dtype(dtype).itemsize)
    ds = _build(files, settings, skeleton, progress, dtype)
    ds.build_seconds = time.perf_counter() - t0
    ds.cache_key = key
    if cache_path is not None:     # overwrites a stale cache of the same dataset
        with owned_writes(cache_path):       # the builder owns its caches (minifilm/files/state.py)
            ds.save(cache_path)
        ds.cache_path = cache_path
    return ds


def _build(files: List[MotionFile], settings: DatasetSettings, skeleton, progress: bool, dtype) -> Dataset:
    builder = _Builder(files, settings, skeleton, dtype)
    bar = Progress(len(files), "dataset", progress)
    for i, f in enumerate(files):
        try:
            builder.add(f)
        except DataError:
            raise                       # names its file already
        except Exception as e:          # say which file, whatever went wrong inside
            e.add_note(f"(while building the dataset from {f.path})")
            raise
        bar.update(i + 1, Path(f.path).name)
    return builder.finish()


class _Builder:
    """Collects the rows and clips of every file, then stacks them into a Dataset."""

    def __init__(self, files: List[MotionFile], settings: DatasetSettings, skeleton, dtype):
        self.settings, self.skeleton, self.dtype = settings, skeleton, dtype
        self.styles = sorted({f.style for f in files})
        self.style_id = {s: i for i, s in enumerate(self.styles)}
        self.layout = FeatureLayout.for_skeleton(skeleton)
        self.parts = {s: {"rows": [], "clips": []} for s in SPLITS}
        self.sources: List[dict] = []
        self.fps = settings.fps
        self.has_primary_clips: set = set()   # styles with a training clip from a clip-gait file
        self.fallback: Dict[str, list] = {}   # other files' clips, kept while a style has none
        self.whole_files = None
        if settings.split_unit == "files":
            splittable = [f for f in files if settings.split_transitions or not f.gait.startswith("TR")]
            self.whole_files = split_files(splittable, settings.seed, settings.split_fractions)

    def segments(self, f: MotionFile, n_frames: int) -> List[Tuple[int, int, str]]:
        st = self.settings
        if f.gait.startswith("TR") and not st.split_transitions:
            return [(0, n_frames, "train")]
        if self.whole_files is not None:
            return [(0, n_frames, self.whole_files[Path(f.path)])]
        segs = split_segments(n_frames, file_rng(st.seed, f), st.split_fractions)
        return apply_gap(segs, int(round(st.gap_seconds * self.fps)))

    def add(self, f: MotionFile) -> None:
        st, sk = self.settings, self.skeleton
        motion = _load_motion(f, sk, st.fps)
        if self.fps is None:
            self.fps = motion.fps
        elif abs(motion.fps - self.fps) > 1e-3 * self.fps:      # survey() refuses this up front
            raise DataError(f"{f.path}: {motion.fps:g} fps differs from the other files' {self.fps:g} fps; "
                            f"set DatasetSettings(fps=...) to resample")
        labels = label(motion, sk, f.style)
        segments = self.segments(f, motion.n_frames)
        primary = f.gait in st.clip_gaits
        want_clips = primary or (st.clip_fallback and f.style not in self.has_primary_clips)
        variants = [(False, motion, labels)]
        if st.mirrors(f):
            variants.append((True, mirror(motion), labels.mirrored()))
        sid = self.style_id[f.style]
        for mirrored, m, lab in variants:
            src = len(self.sources)
            self.sources.append({"path": os.path.abspath(f.path), "style": f.style, "gait": f.gait,
                                 "mirrored": mirrored, "n_frames": m.n_frames, "start": f.start,
                                 "end": f.end, "segments": segments})
            rows, clips = _featurise(m, sk, lab.contacts, lab.vectors, segments, self.fps, want_clips, st,
                                     self.dtype)
            for _, ff in rows:
                for what, a in (("x", ff.x), ("z", ff.z), ("p", ff.p)):
                    check_finite(a, what, self.layout, f"{f.path}{' (mirrored)' if mirrored else ''}", ff.frames)
            for split, ff in rows:
                self.parts[split]["rows"].append((src, sid, ff))
            for split, y in clips:
                if primary:
                    self.parts[split]["clips"].append((src, sid, y))
                    if split == "train" and len(y):
                        self.has_primary_clips.add(f.style)
                        self.fallback.pop(f.style, None)
                elif f.style not in self.has_primary_clips:
                    self.fallback.setdefault(f.style, []).append((split, (src, sid, y)))

    def finish(self) -> Dataset:
        for style, items in self.fallback.items():   # styles without a training clip of a clip gait
            if style not in self.has_primary_clips:
                for split, item in items:
                    self.parts[split]["clips"].append(item)
        T = int(round(self.settings.clip_seconds * self.fps))
        splits = {name: _stack(self.parts[name], self.layout, T, self.dtype) for name in SPLITS}
        tr = splits["train"]
        check_every_style_trains(tr, self.styles, self.sources, self.settings, self.fps)
        stats = NormStats.fit(tr.x, tr.p, tr.z, self.settings.min_std)
        return Dataset(self.layout, self.styles, float(self.fps), self.skeleton.name, splits["train"],
                       splits["val"], splits["test"], stats, self.sources, self.settings.to_dict())


def _stack(part, layout: FeatureLayout, T: int, dtype) -> Split:
    rows, clips = part["rows"], part["clips"]
    cat = lambda arrs, shape, dt: np.concatenate(arrs) if arrs else np.empty(shape, dtype=dt)
    x = cat([r[2].x for r in rows], (0, layout.x_dim), dtype)
    p = cat([r[2].p for r in rows], (0, layout.phase_dim), dtype)
    z = cat([r[2].z for r in rows], (0, layout.z_dim), dtype)
    style = cat([np.full(len(r[2]), r[1], np.int32) for r in rows], (0,), np.int32)
    file = cat([np.full(len(r[2]), r[0], np.int32) for r in rows], (0,), np.int32)
    frame = cat([r[2].frames.astype(np.int32) for r in rows], (0,), np.int32)
    y = cat([c[2] for c in clips], (0, T, layout.clip_dim), dtype)
    clip_style = cat([np.full(len(c[2]), c[1], np.int32) for c in clips], (0,), np.int32)
    clip_file = cat([np.full(len(c[2]), c[0], np.int32) for c in clips], (0,), np.int32)
    return Split(x, p, z, style, file, frame, y, clip_style, clip_file)
