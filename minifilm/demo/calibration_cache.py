"""Speed calibrations kept between runs of the demo, per network, so a restart starts in a second.

One JSON file per network in the user's cache folder (``$XDG_CACHE_HOME/minifilm``, else
``~/.cache/minifilm``; ``MINIFILM_CACHE`` overrides it), named by a hash of the network's files
(their names, sizes and contents) and of how calibrations are measured (``CALIBRATION_VERSION``):
another network, a changed file or a changed measurement never reads an old entry. Written
atomically (``minifilm/files/atomic.py``) after each style is measured; a file that cannot be read
(corrupt, truncated, wrong shapes, not a regular file) is ignored with one warning and rewritten.
Nothing in it is trusted that the measurement could not have written: the commands and
directions must be exactly those measured (``CALIBRATION_COMMANDS``, ``CALIBRATION_DIRECTIONS``),
the speeds finite, at most ``MAX_PLAUSIBLE_SPEED`` and not all zero. A file that fails (zeros,
1e300, reordered commands) is refused with one warning and every style in it measured again.
"""
from __future__ import annotations

import hashlib
import json
import os
import sys
from pathlib import Path
from typing import Dict, Optional

import numpy as np

from minifilm.errors import InputError
from minifilm.files.atomic import atomic_write_text
from minifilm.files.state import owned_writes
from minifilm.files.reading import JSON_NUMBERS, read_regular_bytes
from minifilm.runtime.calibration import CALIBRATION_COMMANDS, CALIBRATION_DIRECTIONS, SpeedCalibration

#: Changes whenever what a calibration measures changes (commands, directions, seconds, runtime).
CALIBRATION_VERSION = "speed-calibration-3"
#: m/s: no character measured goes faster (a sprinter's 10 m/s, and some); more is not a measurement
MAX_PLAUSIBLE_SPEED = 12.0
#: m/s: a style whose fastest forward speed is below this did not move: not a measurement either
MIN_TOP_SPEED = 0.05
#: A cache file larger than this is not read (100 styles take about 60 KB).
MAX_CACHE_BYTES = 8 * 1024 * 1024


def cache_folder() -> Path:
    """Where the demo keeps its calibrations."""
    if os.environ.get("MINIFILM_CACHE"):
        return Path(os.environ["MINIFILM_CACHE"])
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "minifilm"


def network_key(folder) -> str:
    """A hash of every regular file in the network's folder (names, sizes, contents) and of
    ``CALIBRATION_VERSION``: 20 hex digits."""
    h = hashlib.sha256(CALIBRATION_VERSION.encode())
    folder = Path(folder)
    for path in sorted(p for p in folder.iterdir() if p.is_file()):
        h.update(path.name.encode("utf-8", "surrogateescape") + b"\0")
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
        h.update(b"\0")
    return h.hexdigest()[:20]


def _to_json(cal: SpeedCalibration) -> dict:
    return {"commanded": cal.commanded[1:].tolist(), "achieved": cal.achieved[:, 1:].tolist(),
            "directions": [float(d) for d in cal.directions]}


def _from_json(entry) -> SpeedCalibration:
    if not isinstance(entry, dict) or set(entry) != {"commanded", "achieved", "directions"}:
        raise ValueError("an entry must have exactly commanded, achieved and directions")
    c = np.asarray(entry["commanded"], dtype=np.float64)
    a = np.asarray(entry["achieved"], dtype=np.float64)
    d = np.asarray(entry["directions"], dtype=np.float64)
    if c.ndim != 1 or not 1 <= len(c) <= 64 or d.ndim != 1 or not 1 <= len(d) <= 16 or a.shape != (len(d), len(c)):
        raise ValueError(f"shapes commanded {c.shape}, achieved {a.shape}, directions {d.shape} do not fit")
    if not (np.all(np.isfinite(c)) and np.all(np.isfinite(a)) and np.all(np.isfinite(d))):
        raise ValueError("numbers must be finite")
    if c.tolist() != list(CALIBRATION_COMMANDS) or d.tolist() != list(CALIBRATION_DIRECTIONS):
        raise ValueError(f"commands {c.tolist()[:12]} and directions {d.tolist()} are not the measured "
                         f"{list(CALIBRATION_COMMANDS)} and {list(CALIBRATION_DIRECTIONS)}")
    if np.any(a < 0) or np.any(a > MAX_PLAUSIBLE_SPEED):
        raise ValueError(f"achieved speeds must be within 0-{MAX_PLAUSIBLE_SPEED:g} m/s, found "
                         f"{a.min():.3g}..{a.max():.3g}")
    if a[0].max() < MIN_TOP_SPEED:
        raise ValueError(f"the forward speeds are all under {MIN_TOP_SPEED} m/s: the character never moved")
    return SpeedCalibration(c, a, tuple(d.tolist()))


class CalibrationCache:
    """The cached calibrations of one network (``folder``); ``load()`` then ``put()`` as styles
    are measured. ``path`` is None when there is no folder to key by (a trained run: nothing cached)."""

    def __init__(self, folder, where: Optional[Path] = None):
        self.folder, self.where = folder, where
        self._path: Optional[Path] = None
        self.entries: Dict[str, dict] = {}

    @property
    def path(self) -> Optional[Path]:
        """The cache file (its name hashes the network's files: computed on first use, a quarter
        of a second for the released network's 20 MB, off the start-up's way)."""
        if self._path is None and self.folder is not None:
            self._path = (self.where or cache_folder()) / f"calibration-{network_key(self.folder)}.json"
        return self._path

    def load(self) -> Dict[str, SpeedCalibration]:
        """The calibrations in the cache file ({} when there is none, or it is unreadable: then
        one warning on stderr)."""
        if self.path is None or not os.path.lexists(self.path):
            return {}
        try:
            obj = json.loads(read_regular_bytes(self.path, "calibration cache", max_bytes=MAX_CACHE_BYTES), **JSON_NUMBERS)
            if not isinstance(obj, dict) or obj.get("version") != CALIBRATION_VERSION \
                    or not isinstance(obj.get("styles"), dict):
                raise ValueError(f"not a {CALIBRATION_VERSION} file")
            out = {}
            for name, entry in obj["styles"].items():
                out[str(name)] = _from_json(entry)
                self.entries[str(name)] = entry
            return out
        except (OSError, ValueError, RecursionError, TypeError, InputError) as e:
            print(f"warning: ignoring the speed calibration cache {self.path} ({str(e)[:200]}); "
                  "it will be measured again", file=sys.stderr)
            self.entries = {}
            return {}

    def put(self, name: str, cal: SpeedCalibration) -> None:
        """Add a style's calibration and rewrite the file (atomically); a cache that cannot be
        written is a warning, never an error (the demo works without it)."""
        if self.path is None:
            return
        self.entries[name] = _to_json(cal)
        text = json.dumps({"version": CALIBRATION_VERSION, "styles": self.entries}, allow_nan=False)
        try:
            with owned_writes(self.path):    # the demo owns its cache (minifilm/files/state.py)
                atomic_write_text(self.path, text, "calibration cache")
        except Exception as e:  # noqa: BLE001 - a read-only or full cache folder must not stop the demo
            print(f"warning: could not write the speed calibration cache {self.path} ({str(e)[:200]})",
                  file=sys.stderr)


def max_speed(cal: SpeedCalibration, direction: float = 0.0) -> float:
    """The highest speed (m/s) the calibration measured in ``direction`` (degrees from the
    facing; interpolated between the measured directions)."""
    tops = cal.achieved.max(axis=1)
    if len(cal.directions) == 1:
        return float(tops[0])
    return float(np.interp(min(abs(direction), 180.0), np.asarray(cal.directions, dtype=np.float64), tops))
