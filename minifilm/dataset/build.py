"""Build a dataset: BVH files -> training rows (x, p, z), style clips y, splits, statistics (Sec. 3.2, 4.3).

    files (manifest.py) -> per file (file_rows.py): read, label (contacts, local phases), split
                           into segments; per segment (and its mirror): x, p, z rows and style
                           clips (features/) -- file after file here, or in worker processes
                           (minifilm/parallel.py) and collected in the same order
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

import functools
import os
import sys
import time
from concurrent.futures import Executor
from pathlib import Path
from typing import Dict, List, Optional, Sequence, Union

import numpy as np

from minifilm.dataset.cache import cached_key, dataset_cache_key
from minifilm.dataset.dataset import Dataset, Split
from minifilm.dataset.file_rows import FileRows, label_file
from minifilm.dataset.manifest import MotionFile, read_manifest, scan_folder
from minifilm.dataset.progress import Progress
from minifilm.dataset.settings import DatasetSettings
from minifilm.dataset.splits import SPLITS, split_files
from minifilm.dataset.stats import NormStats
from minifilm.dataset.survey import check_memory, check_one_rig, most_common_rig, survey
from minifilm.dataset.validate import check_every_style_trains
from minifilm.errors import DataError
from minifilm.files import check_name, note_input, owned_writes
from minifilm.features.layout import FeatureLayout
from minifilm.body.rig import detect_skeleton
from minifilm.motion.skeletons import builtin_skeleton
from minifilm.parallel import map_in_order, worker_count

#: frames of motion (mirrored copies counted) per worker by default: a worker's start -- a fresh
#: interpreter importing numpy, scipy.signal and the labelling code -- costs about a second of
#: CPU, about what labelling 1,000-2,000 frames costs (Bandai files, 30 fps); with less work than
#: this per worker, two workers took longer than one process (4 Bandai files, 278 frames, on a
#: busy 2-core machine: 2.2 s, against 0.8 s in one process)
FRAMES_PER_WORKER = 2000


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
                  progress: bool = True, skeleton=None, dtype=np.float32,
                  workers: Union[int, Executor, None] = None,
                  **overrides) -> Dataset:
    """Build (or load from cache) the dataset of a 100STYLE-named folder, a CSV manifest or a list
    of :class:`~minifilm.dataset.manifest.MotionFile`.

    Args:
        settings: a :class:`DatasetSettings`; keyword ``overrides`` replace single fields.
        cache_dir: where ``dataset-<name hash>.npz`` lives; None disables caching. A cache whose
            files, code or settings changed is rebuilt and overwritten.
        progress: a status line on stderr.
        skeleton: a :class:`~minifilm.motion.skeletons.Skeleton` object for a custom skeleton
            (overrides ``settings.skeleton``; its repr enters the cache key).
        workers: processes labelling the files at once (minifilm/parallel.py), default the cores
            this process may use, at most one per file and per FRAMES_PER_WORKER frames; 1 = one
            file after another in this process; or a concurrent.futures Executor to label them
            with. Each file is labelled by the same code wherever it runs and the results are
            collected in the files' order, so the dataset is the same for any number (it is not in
            the cache key).
    """
    settings = settings or DatasetSettings()
    if not isinstance(workers, Executor):
        try:
            worker_count(workers, 1)        # a count that is not one: refused before any work
        except ValueError as e:
            raise ValueError(f"build_dataset: {e}") from None
    if overrides:
        settings = DatasetSettings(**{**settings.to_dict(), **overrides})
    files = [f for f in resolve_files(source) if f.gait not in settings.idle_gaits]
    if not files:
        raise ValueError("build_dataset: every file is idle (see DatasetSettings.idle_gaits)")
    cache_path, key = None, ""
    if cache_dir is not None:
        name, key = dataset_cache_key(files, settings, skeleton)
        cache_path = Path(cache_dir) / f"dataset-{name}.npz"
        if cache_path.is_file() and cached_key(cache_path) == key:       # the key, before any array is read
            try:
                return Dataset.load(cache_path)
            except DataError as e:           # damaged or padded under a matching key: built and written anew
                warn(f"the data set cache {cache_path} cannot be used ({str(e)[:300]}); building the data set again")
    t0 = time.perf_counter()
    surveyed = survey(files, settings.fps)                # headers only: rates, lengths, joints
    skeleton = skeleton or _pick_skeleton(settings, surveyed)
    check_one_rig(surveyed, skeleton)                     # a foreign file named before any is read
    fps = settings.fps or next(iter(surveyed.values())).fps
    check_memory(surveyed, [settings.mirrors(f) for f in files], FeatureLayout.for_skeleton(skeleton),
                 int(round(settings.clip_seconds * fps)), int(round(settings.clip_stride_seconds * fps)),
                 np.dtype(dtype).itemsize)
    if workers is None:     # every core, but a worker only for enough motion to pay for its start
        frames = sum(surveyed[Path(f.path)].n_frames * (2 if settings.mirrors(f) else 1) for f in files)
        workers = worker_count(None, min(len(files), frames // FRAMES_PER_WORKER))
    ds = _build(files, settings, skeleton, progress, dtype, workers, fps)
    ds.build_seconds = time.perf_counter() - t0
    ds.cache_key = key
    if cache_path is not None:     # overwrites a stale cache of the same dataset
        try:
            with owned_writes(cache_path):       # the builder owns its caches (minifilm/files/state.py)
                ds.save(cache_path)
            ds.cache_path = cache_path
        except OSError as e:            # a full disk or a read-only folder costs the cache, not the data set
            warn(f"the data set is built, but its cache could not be written ({str(e)[:300]}); the next run "
                 "builds it again")
    return ds


def warn(text: str) -> None:
    """One line on stderr that says what went wrong and what happens instead; the work goes on."""
    print(f"warning: {text}", file=sys.stderr)


def _build(files: List[MotionFile], settings: DatasetSettings, skeleton, progress: bool, dtype,
           workers: Union[int, Executor] = 1, fps: Optional[float] = None) -> Dataset:
    """The dataset of ``files``, labelled by ``workers`` (minifilm/parallel.py: one after another
    here, or in worker processes) and collected in the files' order. ``fps``: the dataset's frame
    rate (the settings', else the first file's), which a worker needs before any file is read."""
    builder = _Builder(files, settings, skeleton, dtype)
    bar = Progress(len(files), "dataset", progress)
    if isinstance(workers, int) and min(workers, len(files)) > 1:
        bar.note(f"{len(files)} files in {min(workers, len(files))} worker processes")

    def collect(i: int, rows: FileRows) -> None:
        builder.collect(files[i], rows)
        bar.update(i + 1, Path(files[i].path).name)
    label = functools.partial(_label, settings=settings, skeleton=skeleton, fps=fps, dtype=dtype)
    map_in_order(label, [(f, builder.whole_split(f)) for f in files], workers, doing="building the dataset from",
                 name=lambda job: str(job[0].path), done=collect)
    return builder.finish()


def _label(job, settings: DatasetSettings, skeleton, fps: Optional[float], dtype) -> FileRows:
    """One file's rows (file_rows.label_file) for ``job`` = (file, its whole-file split or None),
    wherever it runs: with clips whenever the file may give them (the builder drops those a style
    does not need, which depends on the files before it: _Builder.collect)."""
    f, split = job
    return label_file(f, settings, skeleton, fps, split, f.gait in settings.clip_gaits or settings.clip_fallback, dtype)


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

    def whole_split(self, f: MotionFile) -> Optional[str]:
        """The split of a file that goes to one split whole (split_unit 'files'), else None."""
        if self.whole_files is None or (f.gait.startswith("TR") and not self.settings.split_transitions):
            return None
        return self.whole_files[Path(f.path)]

    def wants_clips(self, f: MotionFile) -> bool:
        """Clips of ``f``: a clip-gait file always gives them; another file only for a style that has
        none from a clip-gait file yet (clip_fallback) -- which depends on the files before it."""
        st = self.settings
        return f.gait in st.clip_gaits or (st.clip_fallback and f.style not in self.has_primary_clips)

    def collect(self, f: MotionFile, labelled: FileRows) -> None:
        """Keep the rows and clips of ``f`` (:func:`_label` made clips wherever they may be needed:
        those this file does not give, after the files before it, are dropped here)."""
        if self.fps is None:
            self.fps = labelled.fps
        primary = f.gait in self.settings.clip_gaits
        keep_clips = self.wants_clips(f)         # decided before this file's clips count
        sid = self.style_id[f.style]
        for v in labelled.variants:
            src = len(self.sources)
            self.sources.append({"path": os.path.abspath(f.path), "style": f.style, "gait": f.gait,
                                 "mirrored": v.mirrored, "n_frames": v.n_frames, "start": f.start,
                                 "end": f.end, "segments": labelled.segments})
            for split, ff in v.rows:
                self.parts[split]["rows"].append((src, sid, ff))
            for split, y in (v.clips if keep_clips else []):
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
