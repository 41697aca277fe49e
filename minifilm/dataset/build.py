"""Datasets: BVH files -> training pairs (x, p, z), style clips y, splits, normalisation (Sec. 3.2, 4.3).

    files (manifest.py) -> per file: read, contacts, local phases, train/val/test segments
                        -> per segment (and its mirror): x, p, z rows and style clips (features.py)
                        -> normalisation statistics from the training rows
                        -> cached .npz

Splits (original-pipeline.md §8.2, made leak-free). Every file is cut into contiguous segments:
one validation and one test window of ``floor(0.1 L)`` frames each, drawn with a seeded generator
so that they never overlap, and train around them (the original could overlap them, §12.17).
Each segment is featurised as if it were its own clip (features.py): trajectory samples that fall
outside it are point-reflected at its ends and the first / last frame are never "current", so no
validation or test row contains a number computed from a training frame, and vice versa.
``gap_seconds`` can additionally drop that much at every border between segments of different
splits (default 0: the nearest train and test current frames are then 3 frames apart). Phases and
contacts are labels of the whole file (the phase fit needs ~1 s of context), which is the one place
where a row's numbers depend on its neighbours. A mirrored copy uses the same segments as its
original. Transition files (gait ``TR*``) are all train unless ``split_transitions`` (§8.2).
For datasets of many short files (Bandai: ~5 s each, so a 10 % window is shorter than the 2 s
trajectory window and most of its samples are reflections) ``split_unit='files'`` sends whole
files to train / val / test instead, per style.

Normalisation (§8.5): per-column mean and biased std of the training rows, in float64; a std below
``min_std`` (zero up to rounding, e.g. trajectory sample 6, the hips' x and z) becomes 1. Clips are
normalised with the x joint-block statistics (§9). Saved as .npz, no pickle.

Style-balanced minibatches (Sec. 4.3) are the trainer's job (``minifilm.train.trainer.epoch_batches``);
:meth:`Dataset.train_data` hands it each split as a normalised :class:`~minifilm.dataset.arrays.TrainData`,
and the bone-length loss takes ``layout.joint_columns('z', 'position')`` and ``layout.parents``.
"""
from __future__ import annotations

import hashlib
import json
import os
import sys
import time
import zlib
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from minifilm.dataset.manifest import MotionFile, read_manifest, scan_100style
from minifilm.features.layout import FeatureLayout
from minifilm.dataset.arrays import NormStats, TrainData

SPLITS = ("train", "val", "test")
#: Bump when the meaning of the cached arrays changes without any source file changing.
CACHE_FORMAT = 1


# =========================================================================== settings
@dataclass(frozen=True)
class DatasetSettings:
    """Everything that decides the content of a dataset (and so its cache key).

    fps:              resample every file to this rate; None = use the files' rate (all equal).
    skeleton:         a built-in skeleton name ('100style', 'bandai', 'cmu', ...); None = detect.
    split_fractions:  (train, val, test) fractions of every file, default 80/10/10.
    seed:             seeds the per-file split windows (each file from ``seed`` and its name).
    gap_seconds:      frames dropped at each border between segments of different splits.
    mirror_styles:    styles that also get a mirrored copy; ('*',) = all styles. A manifest's
                      ``mirror`` column overrides this per file.
    idle_gaits:       gaits that are skipped (100STYLE 'ID').
    clip_gaits:       gaits whose files give style clips (100STYLE forward walk 'FW', Bandai 'walk').
    clip_fallback:    a style whose clip-gait files give no training clip (none exist, or their
                      training segments are shorter than a clip) takes its clips from its other
                      files.
    clip_seconds, clip_stride_seconds: clip length and stride (paper: 240 frames at 60 fps, half).
    split_transitions: split TR* files too (the original puts them all in train).
    split_unit:       'segments' (default, the original: every file is cut 80/10/10) or 'files'
                      (whole files go to train / val / test, per style, seeded): for datasets of
                      many short files, where 10 % windows are shorter than the 2 s trajectory.
    min_std:          std below this becomes 1 in the normalisation.
    """
    fps: Optional[float] = None
    skeleton: Optional[str] = None
    split_fractions: Tuple[float, float, float] = (0.8, 0.1, 0.1)
    seed: int = 0
    gap_seconds: float = 0.0
    mirror_styles: Tuple[str, ...] = ()
    idle_gaits: Tuple[str, ...] = ("ID", "idle")
    clip_gaits: Tuple[str, ...] = ("FW", "walk")
    clip_fallback: bool = True
    clip_seconds: float = 4.0
    clip_stride_seconds: float = 2.0
    split_transitions: bool = False
    split_unit: str = "segments"
    min_std: float = 1e-6

    def __post_init__(self) -> None:
        for name in ("split_fractions", "mirror_styles", "idle_gaits", "clip_gaits"):
            value = getattr(self, name)
            object.__setattr__(self, name, (value,) if isinstance(value, str) else tuple(value))
        fr = self.split_fractions
        if len(fr) != 3 or min(fr) < 0 or not np.isclose(sum(fr), 1.0):
            raise ValueError(f"DatasetSettings: split_fractions must be 3 non-negative numbers summing "
                             f"to 1, got {fr}")
        if self.split_unit not in ("segments", "files"):
            raise ValueError(f"DatasetSettings: split_unit must be 'segments' or 'files', got {self.split_unit!r}")
        if self.gap_seconds < 0:
            raise ValueError(f"DatasetSettings: gap_seconds must be >= 0, got {self.gap_seconds}")

    def mirrors(self, f: MotionFile) -> bool:
        if f.mirror is not None:
            return f.mirror
        return "*" in self.mirror_styles or f.style in self.mirror_styles

    def to_dict(self) -> dict:
        return asdict(self)


# =========================================================================== splits
def split_segments(n_frames: int, rng: np.random.Generator,
                   fractions: Sequence[float] = (0.8, 0.1, 0.1)) -> List[Tuple[int, int, str]]:
    """Cut ``[0, n_frames)`` into contiguous segments ``(start, stop, split)`` (original §8.2).

    The validation and test windows are ``floor(f L)`` frames each; they never overlap, their
    order and positions are random (seeded by ``rng``); the rest, up to three pieces, is train.
    """
    L = int(n_frames)
    sizes = {"val": int(np.floor(fractions[1] * L)), "test": int(np.floor(fractions[2] * L))}
    free = L - sizes["val"] - sizes["test"]
    cuts = np.sort(rng.integers(0, free + 1, size=2))          # train pieces: [0,c0), ..., [c1, free)
    order = ["val", "test"] if rng.random() < 0.5 else ["test", "val"]
    pieces = [("train", int(cuts[0])), (order[0], sizes[order[0]]), ("train", int(cuts[1] - cuts[0])),
              (order[1], sizes[order[1]]), ("train", int(free - cuts[1]))]
    out, a = [], 0
    for split, size in pieces:
        if size > 0:
            out.append((a, a + size, split))
            a += size
    return out


def apply_gap(segments: List[Tuple[int, int, str]], gap: int) -> List[Tuple[int, int, str]]:
    """Shrink segments by ``gap`` frames at every border with a segment of another split."""
    out = []
    for i, (a, b, s) in enumerate(segments):
        if i > 0 and segments[i - 1][2] != s:
            a += gap
        if i + 1 < len(segments) and segments[i + 1][2] != s:
            b -= gap
        if b > a:
            out.append((a, b, s))
    return out


def split_files(files: Sequence[MotionFile], seed: int,
                fractions: Sequence[float] = (0.8, 0.1, 0.1)) -> Dict[Path, str]:
    """Whole-file splits: per style, the files in a seeded random order give ``round(f n)`` files
    to val and to test (at least one each once a style has 3 files), the rest to train."""
    by_style: Dict[str, List[MotionFile]] = {}
    for f in files:
        by_style.setdefault(f.style, []).append(f)
    out = {}
    for style, group in sorted(by_style.items()):
        group = sorted(group, key=lambda f: Path(f.path).name)
        rng = np.random.default_rng([int(seed), zlib.crc32(style.encode("utf-8"))])
        order = rng.permutation(len(group))
        n = len(group)
        n_val, n_test = (_file_count(fr, n) for fr in fractions[1:])
        for rank, i in enumerate(order):
            out[Path(group[i].path)] = "val" if rank < n_val else "test" if rank < n_val + n_test else "train"
    return out


def _file_count(fraction: float, n: int) -> int:
    """Files of a style for a split of ``fraction``: rounded, at least 1 once there are 3 files."""
    k = int(round(fraction * n))
    return max(1, k) if fraction > 0 and n >= 3 else k if n >= 3 else 0


def file_rng(seed: int, f: MotionFile) -> np.random.Generator:
    """A generator that depends on the seed and the file's name only (not on the other files)."""
    return np.random.default_rng([int(seed), zlib.crc32(Path(f.path).name.encode("utf-8"))])


# =========================================================================== normalisation
class Normalizer(NormStats):
    """Mean / std of x, p and z (float64) from the training rows (original-pipeline §8.5).

    A :class:`minifilm.dataset.arrays.NormStats` (what the trainer and the runtime read) plus fitting,
    clip normalisation and .npz files. Clips use the x joint-block statistics
    (``x_mean[layout.x_joints]``), as in §9.
    """

    @classmethod
    def fit(cls, x: np.ndarray, p: np.ndarray, z: np.ndarray, min_std: float = 1e-6) -> "Normalizer":
        """Statistics of training rows x (N, x_dim), p (N, 8), z (N, z_dim); std < min_std -> 1."""
        if len(x) == 0:
            raise ValueError("Normalizer.fit: no training rows")
        stats = {}
        for name, a in (("x", x), ("p", p), ("z", z)):
            mean, std = _mean_std(a)
            std[std < min_std] = 1.0
            stats[f"{name}_mean"], stats[f"{name}_std"] = mean, std
        return cls(**stats)

    def normalize_clip(self, clip, layout: FeatureLayout):
        """(..., T, 12 J) clips with the x joint-block statistics (§9)."""
        s = layout.x_joints
        return (clip - self.x_mean[s]) / self.x_std[s]

    def state_dict(self) -> Dict[str, np.ndarray]:
        return self.to_arrays(prefix="")

    @classmethod
    def from_state_dict(cls, d) -> "Normalizer":
        return cls(**NormStats.from_arrays(d, prefix="").__dict__)

    def save(self, path: Union[str, Path]) -> Path:
        return _save_npz(path, self.state_dict())

    @classmethod
    def load(cls, path: Union[str, Path]) -> "Normalizer":
        with np.load(path, allow_pickle=False) as d:
            return cls.from_state_dict({k: d[k] for k in d.files})


def _mean_std(a: np.ndarray, chunk: int = 1 << 15) -> Tuple[np.ndarray, np.ndarray]:
    """Column mean and biased std (as the original) in float64, two passes over row chunks so a
    large float32 array is never copied whole into float64."""
    n = a.shape[0]
    total = np.zeros(a.shape[1])
    for i in range(0, n, chunk):
        total += a[i:i + chunk].sum(axis=0, dtype=np.float64)
    mean = total / n
    sq = np.zeros(a.shape[1])
    for i in range(0, n, chunk):
        sq += ((a[i:i + chunk].astype(np.float64) - mean) ** 2).sum(axis=0)
    return mean, np.sqrt(sq / n)


def _save_npz(path: Union[str, Path], arrays: dict) -> Path:
    """Write to a temporary file and rename, so a crash never leaves half a file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + f".tmp{os.getpid()}.npz")
    np.savez(tmp, **arrays)
    os.replace(tmp, path)
    return path


# =========================================================================== the dataset
@dataclass
class Split:
    """The rows of one split. x (N, x_dim), p (N, 8), z (N, z_dim) float32; style (N,) int;
    file (N,) index into ``Dataset.files``; frame (N,) current frame in that file (after its
    start/end crop); clips (M, T, 12 J)
    float32 with clip_style (M,) and clip_file (M,)."""
    x: np.ndarray
    p: np.ndarray
    z: np.ndarray
    style: np.ndarray
    file: np.ndarray
    frame: np.ndarray
    clips: np.ndarray
    clip_style: np.ndarray
    clip_file: np.ndarray

    def __len__(self) -> int:
        return int(self.x.shape[0])


_SPLIT_ARRAYS = ("x", "p", "z", "style", "file", "frame", "clips", "clip_style", "clip_file")


@dataclass
class Dataset:
    """A built dataset: three splits, the layout, style names, normalisation and provenance.

    files: one dict per featurised source (a file, or its mirror) with path, style, gait, mirrored,
    n_frames and segments [(start, stop, split)].
    """
    layout: FeatureLayout
    styles: List[str]
    fps: float
    skeleton: str
    train: Split
    val: Split
    test: Split
    normalizer: Normalizer
    files: List[dict]
    settings: dict
    cache_path: Optional[Path] = None
    build_seconds: float = 0.0
    cache_key: str = ""

    def split(self, name: str) -> Split:
        if name not in SPLITS:
            raise KeyError(f"Dataset.split: {name!r} is not one of {SPLITS}")
        return getattr(self, name)

    def train_data(self, name: str, clip_split: Optional[str] = None, dtype=np.float32) -> TrainData:
        """Split ``name`` normalised with the training statistics, as the trainer takes it.

        Clips come from ``clip_split``; by default the split's own clips when every style with rows
        has one there, else the training clips (validation and test windows are usually shorter
        than a clip; the clip is the style condition y, not a target).
        """
        sp = self.split(name)
        if clip_split is None:
            have = set(sp.clip_style.tolist())
            clip_split = name if set(sp.style.tolist()) <= have else "train"
        cs = self.split(clip_split)
        n = self.normalizer
        return TrainData(x=n.normalize_x(sp.x).astype(dtype), p=n.normalize_p(sp.p).astype(dtype),
                         z=n.normalize_z(sp.z).astype(dtype), style=sp.style,
                         clips=n.normalize_clip(cs.clips, self.layout).astype(dtype),
                         clip_style=cs.clip_style, style_names=list(self.styles))

    # ------------------------------------------------------------------ report
    def frame_counts(self) -> Dict[str, Dict[str, int]]:
        """{style: {split: rows}} (plus '<split> clips')."""
        out = {s: {} for s in self.styles}
        for name in SPLITS:
            sp = self.split(name)
            rows = np.bincount(sp.style, minlength=len(self.styles))
            clips = np.bincount(sp.clip_style, minlength=len(self.styles))
            for i, s in enumerate(self.styles):
                out[s][name] = int(rows[i])
                out[s][name + " clips"] = int(clips[i])
        return out

    def reflected_fraction(self) -> Dict[str, float]:
        """{split: fraction of the x trajectory samples that are point reflections} (a segment
        shorter than the trajectory window is mostly reflections; see split_unit='files')."""
        from minifilm.features.compute import trajectory_offsets, trajectory_sample_frames

        offsets = trajectory_offsets(self.fps, self.layout.trajectory_seconds)
        counts = {s: [0, 0] for s in SPLITS}
        for info in self.files:
            for a, b, split in info["segments"]:
                k = np.arange(a + 1, b - 1)
                if k.size:
                    _, pivot = trajectory_sample_frames(k, offsets, a, b)
                    counts[split][0] += int((pivot >= 0).sum())
                    counts[split][1] += pivot.size
        return {s: (r / n if n else 0.0) for s, (r, n) in counts.items()}

    def summary(self) -> str:
        """A table of rows (frames) and clips per style and split."""
        counts = self.frame_counts()
        w = max([5] + [len(s) for s in self.styles])
        head = f"{'style':<{w}} " + " ".join(f"{h:>9}" for h in ("train", "val", "test", "clips tr",
                                                                   "clips va", "clips te"))
        lines = [head, "-" * len(head)]
        total = np.zeros(6, dtype=np.int64)
        for s in self.styles:
            c = counts[s]
            row = [c["train"], c["val"], c["test"], c["train clips"], c["val clips"], c["test clips"]]
            total += row
            lines.append(f"{s:<{w}} " + " ".join(f"{v:>9d}" for v in row))
        lines.append("-" * len(head))
        lines.append(f"{'total':<{w}} " + " ".join(f"{v:>9d}" for v in total))
        n_src = len(self.files)
        n_mir = sum(1 for f in self.files if f["mirrored"])
        lines.append(f"{n_src} sources ({n_mir} mirrored), {self.fps:g} fps, skeleton {self.skeleton}, "
                     f"x {self.layout.x_dim}, z {self.layout.z_dim}, clip T={self.train.clips.shape[1]}"
                     f" x {self.layout.clip_dim}")
        refl = self.reflected_fraction()
        lines.append("trajectory samples that are reflections: " +
                     ", ".join(f"{s} {100 * refl[s]:.1f} %" for s in SPLITS))
        return "\n".join(lines)

    # ------------------------------------------------------------------ save / load
    def save(self, path: Union[str, Path]) -> Path:
        arrays = {f"{name}/{key}": getattr(self.split(name), key)
                  for name in SPLITS for key in _SPLIT_ARRAYS}
        arrays.update({f"norm/{k}": v for k, v in self.normalizer.state_dict().items()})
        meta = {"layout": self.layout.to_dict(), "styles": self.styles, "fps": self.fps,
                "skeleton": self.skeleton, "files": self.files, "settings": self.settings,
                "format": CACHE_FORMAT, "build_seconds": self.build_seconds, "cache_key": self.cache_key}
        arrays["meta"] = np.array(json.dumps(meta))
        return _save_npz(path, arrays)

    @classmethod
    def load(cls, path: Union[str, Path]) -> "Dataset":
        with np.load(path, allow_pickle=False) as d:
            meta = json.loads(str(d["meta"]))
            splits = {name: Split(*(d[f"{name}/{key}"] for key in _SPLIT_ARRAYS)) for name in SPLITS}
            norm = Normalizer.from_state_dict({k[5:]: d[k] for k in d.files if k.startswith("norm/")})
        if meta.get("format") != CACHE_FORMAT:
            raise ValueError(f"{path}: dataset format {meta.get('format')} is not {CACHE_FORMAT}")
        for f in meta["files"]:
            f["segments"] = [tuple(s) for s in f["segments"]]
        return cls(FeatureLayout.from_dict(meta["layout"]), list(meta["styles"]), float(meta["fps"]),
                   meta["skeleton"], splits["train"], splits["val"], splits["test"], norm,
                   meta["files"], meta["settings"], Path(path), float(meta.get("build_seconds", 0.0)),
                   meta.get("cache_key", ""))


# =========================================================================== building
class _Progress:
    """One status line on stderr, rewritten in place on a terminal, every ~10 % otherwise."""

    def __init__(self, total: int, label: str, enabled: bool = True):
        self.total, self.label, self.enabled = total, label, enabled
        self.t0 = time.perf_counter()
        self.tty = enabled and sys.stderr.isatty()
        self.next_print = 0.0

    def update(self, done: int, note: str = "") -> None:
        if not self.enabled or self.total == 0:
            return
        frac = done / self.total
        if not self.tty and frac < self.next_print and done != self.total:
            return
        self.next_print = frac + 0.1
        el = time.perf_counter() - self.t0
        eta = el / done * (self.total - done) if done else float("nan")
        msg = f"[{self.label}] {done}/{self.total} files, {el:5.1f} s, eta {eta:5.1f} s {note}"
        if self.tty:
            sys.stderr.write("\r" + msg[:120].ljust(120) + ("\n" if done == self.total else ""))
        else:
            sys.stderr.write(msg + "\n")
        sys.stderr.flush()


def resolve_files(source: Union[str, Path, Sequence[MotionFile]]) -> List[MotionFile]:
    """A folder (100STYLE naming), a .csv manifest, or a list of MotionFile."""
    if isinstance(source, (str, Path)):
        p = Path(source)
        if p.suffix.lower() == ".csv":
            return read_manifest(p)
        return scan_100style(p)
    files = list(source)
    if not files or not all(isinstance(f, MotionFile) for f in files):
        raise TypeError("build_dataset: source must be a folder, a .csv manifest or a non-empty list "
                        "of minifilm.dataset.manifest.MotionFile")
    return files


def _source_fingerprint() -> str:
    """Hash of the code that computes the cached arrays: a code change invalidates old caches.

    That code is every module of the packages that read, label and featurise motion."""
    h = hashlib.sha256()
    package = Path(__file__).resolve().parents[1]
    for folder in ("motion", "phases", "features", "dataset"):
        for p in sorted((package / folder).glob("*.py")):
            h.update(f"{folder}/{p.name}".encode())
            h.update(p.read_bytes())
    return h.hexdigest()


def dataset_cache_key(files: Sequence[MotionFile], settings: DatasetSettings, skeleton=None) -> Tuple[str, str]:
    """(name, key): ``name`` hashes what the dataset is (file paths and labels, settings, custom
    skeleton) and names the cache file, so a dataset has one cache file; ``key`` adds every file's
    size and mtime and the code, and must match the stored one for the cache to be used."""
    what, state = [], []
    for f in files:
        st = Path(f.path).stat()
        what.append([str(Path(f.path).resolve()), f.style, f.gait, f.start, f.end, f.mirror])
        state.append([st.st_size, st.st_mtime_ns])
    name = json.dumps({"files": what, "settings": settings.to_dict(),
                       "skeleton": None if skeleton is None else repr(skeleton)}, sort_keys=True)
    key = json.dumps({"name": name, "state": state, "format": CACHE_FORMAT,
                      "code": _source_fingerprint()}, sort_keys=True)
    return hashlib.sha256(name.encode()).hexdigest()[:20], hashlib.sha256(key.encode()).hexdigest()


def _cached_key(path: Path) -> Optional[str]:
    """The key stored in a cache file (reads only its small 'meta' entry); None if unreadable."""
    try:
        with np.load(path, allow_pickle=False) as d:
            return json.loads(str(d["meta"])).get("cache_key")
    except (OSError, ValueError, KeyError):
        return None


def _load_motion(f: MotionFile, skeleton, fps: Optional[float]):
    from minifilm.motion.bvh import read_bvh
    from minifilm.motion.kinematics import resample

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


def _labels(motion, skeleton, style: str):
    """Foot contacts (F, 2) [right, left] and phase vectors (F, 8) of one file (Sec. 4.1)."""
    from minifilm.phases.contacts import foot_contacts
    from minifilm.phases.local_phases import default_sources, extract_local_phases

    positions, _ = motion.world()
    contacts = foot_contacts(positions[:, skeleton.contact_indices(motion)], motion.fps)
    phases = extract_local_phases(motion, skeleton, contacts, default_sources(style)).vectors()
    return contacts, phases


def mirror_labels(contacts: np.ndarray, phases: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Labels of the mirrored motion: left and right swap (original-pipeline §1.3, §4.6).

    contacts [right, left] -> [left, right]; phase slots [LH, RH, LF, RF] -> [RH, LH, RF, LF].
    """
    p = phases.reshape(phases.shape[0], 4, 2)[:, [1, 0, 3, 2]]
    return contacts[:, ::-1].copy(), p.reshape(phases.shape[0], 8).copy()


def _featurise(motion, skeleton, contacts, phases, segments, fps, want_clips, settings, dtype):
    """Rows and clips of every segment of one (possibly mirrored) motion."""
    from minifilm.features.compute import clip_features_from_arrays, frame_features_from_arrays, motion_arrays

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


def _pick_skeleton(settings: DatasetSettings, first: MotionFile):
    from minifilm.motion import skeletons

    if settings.skeleton is not None:
        try:
            return skeletons.builtin_skeleton(settings.skeleton)
        except ValueError as e:
            raise ValueError(f"DatasetSettings.skeleton: {e}") from None
    from minifilm.motion.bvh import read_bvh

    return skeletons.detect_skeleton(read_bvh(first.path))


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
        if cache_path.is_file() and _cached_key(cache_path) == key:
            return Dataset.load(cache_path)
    t0 = time.perf_counter()
    skeleton = skeleton or _pick_skeleton(settings, files[0])
    ds = _build(files, settings, skeleton, progress, dtype)
    ds.build_seconds = time.perf_counter() - t0
    ds.cache_key = key
    if cache_path is not None:     # overwrites a stale cache of the same dataset
        ds.save(cache_path)
        ds.cache_path = cache_path
    return ds


def _build(files: List[MotionFile], settings: DatasetSettings, skeleton, progress: bool, dtype) -> Dataset:
    builder = _Builder(files, settings, skeleton, dtype)
    bar = _Progress(len(files), "dataset", progress)
    for i, f in enumerate(files):
        try:
            builder.add(f)
        except Exception as e:          # say which file, whatever went wrong inside
            if hasattr(e, "add_note"):
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
        elif abs(motion.fps - self.fps) > 1e-3 * self.fps:
            raise ValueError(f"{f.path}: {motion.fps:g} fps differs from the other files' {self.fps:g} fps; "
                             f"set DatasetSettings(fps=...) to resample")
        contacts, phases = _labels(motion, sk, f.style)
        segments = self.segments(f, motion.n_frames)
        primary = f.gait in st.clip_gaits
        want_clips = primary or (st.clip_fallback and f.style not in self.has_primary_clips)
        variants = [(False, motion, contacts, phases)]
        if st.mirrors(f):
            from minifilm.motion.kinematics import mirror

            variants.append((True, mirror(motion), *mirror_labels(contacts, phases)))
        sid = self.style_id[f.style]
        for mirrored, m, c, p in variants:
            src = len(self.sources)
            self.sources.append({"path": str(f.path), "style": f.style, "gait": f.gait,
                                 "mirrored": mirrored, "n_frames": m.n_frames, "start": f.start,
                                 "end": f.end, "segments": segments})
            rows, clips = _featurise(m, sk, c, p, segments, self.fps, want_clips, st, self.dtype)
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
        normalizer = Normalizer.fit(tr.x, tr.p, tr.z, self.settings.min_std)
        return Dataset(self.layout, self.styles, float(self.fps), self.skeleton.name, splits["train"],
                       splits["val"], splits["test"], normalizer, self.sources, self.settings.to_dict())


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
