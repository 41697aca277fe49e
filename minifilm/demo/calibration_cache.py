"""Speed calibrations kept between runs of the demo, so a restart starts in a second.

A style's calibration depends on the network (its weights and normalisation), how it is driven
(frame rate, feature layout, the Controller's options, the commands and directions measured) and
the style itself (its FiLM vector and start frame). The first group makes the key
(:func:`calibration_key`), which names one JSON file per network in the user's cache folder
(``$XDG_CACHE_HOME/minifilm``, else ``~/.cache/minifilm``; ``MINIFILM_CACHE`` overrides it); each
entry keeps the digest of its style (:func:`style_digest`) and is used only while the style's
vector and start frame are the same (a style re-taught under the same name is measured again).
Another network, a changed option or a changed measurement (``CALIBRATION_VERSION``) never reads
an old entry, whatever the files are called or what else their folder holds.

The package ships the released network's calibrations, all 100 styles
(``shipped_calibrations/``, written by ``scripts/released_calibrations.py``): a file there whose
name is the key is read first, so the authors' network starts calibrated on a new machine and
its demo measures nothing (a test measures styles again and compares, so a change to the runtime
cannot leave a stale table behind).

Written atomically (``minifilm/files/atomic.py``) after each style is measured; a file that
cannot be read (corrupt, truncated, wrong shapes, not a regular file) is ignored with one warning
and rewritten. Nothing in it is trusted that the measurement could not have written: the commands
and directions must be exactly those measured, the speeds finite, at most ``MAX_PLAUSIBLE_SPEED``
and not all zero. A file that fails (zeros, 1e300, reordered commands) is refused with one warning
and every style in it measured again.
"""
from __future__ import annotations

import dataclasses
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
from minifilm.runtime.calibration import CALIBRATION_DIRECTIONS, SpeedCalibration

#: Changes whenever what a calibration measures changes (commands, directions, seconds, runtime).
CALIBRATION_VERSION = "speed-calibration-4"
#: m/s: no character measured goes faster (a sprinter's 10 m/s, and some); more is not a measurement
MAX_PLAUSIBLE_SPEED = 12.0
#: m/s: a style whose fastest forward speed is below this did not move: not a measurement either
MIN_TOP_SPEED = 0.05
#: A cache file larger than this is not read (100 styles take about 60 KB).
MAX_CACHE_BYTES = 8 * 1024 * 1024
#: The calibrations that come with the package (the released network's), one file per key.
SHIPPED = Path(__file__).resolve().parent / "shipped_calibrations"


def cache_folder() -> Path:
    """Where the demo keeps its calibrations."""
    if os.environ.get("MINIFILM_CACHE"):
        return Path(os.environ["MINIFILM_CACHE"])
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "minifilm"


def _plain(value):
    """An option's value as JSON (a dataclass by its fields; anything else by its type's name)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {type(value).__name__: dataclasses.asdict(value)}
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    return type(value).__name__


def calibration_key(source) -> Optional[str]:
    """20 hex digits: the network's arrays (names, dtypes, shapes, bits) and how it is driven
    (``CALIBRATION_VERSION``, frame rate, layout, the Controller's options, commands and directions)
    of a :class:`~minifilm.demo.source.DemoSource`; None for a network that cannot be written
    as arrays (nothing is cached for it)."""
    try:
        arrays = source.network.to_arrays()
    except TypeError:
        return None
    h = hashlib.sha256(CALIBRATION_VERSION.encode())
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}:{a.dtype.str}:{a.shape}\0".encode())
        h.update(a.tobytes())
    layout = source.layout
    driven = {"fps": float(source.fps), "joints": list(layout.joint_names), "parents": list(layout.parents),
              "trajectory": list(layout.trajectory_seconds),
              "commands": [float(c) for c in source.calibration_commands],
              "directions": list(CALIBRATION_DIRECTIONS),
              "options": {k: _plain(v) for k, v in sorted(source.options.items())}}
    h.update(json.dumps(driven, sort_keys=True).encode())
    return h.hexdigest()[:20]


def style_digest(source, name: str) -> str:
    """16 hex digits: the bits of style ``name``'s FiLM vector and of its start frame (x, p), if any."""
    h = hashlib.blake2b(digest_size=8)
    own = getattr(source.library, "calibration_bits", None)     # a library with adapters (runtime/adapted.py)
    h.update(own(name) if own else np.ascontiguousarray(source.library[name], np.float64).tobytes())
    for part in source.starts.get(name, ()):
        h.update(b"\0" + np.ascontiguousarray(part, np.float64).tobytes())
    return h.hexdigest()


def _to_json(cal: SpeedCalibration, style: str) -> dict:
    return {"style": style, "commanded": cal.commanded[1:].tolist(),
            "achieved": np.round(cal.achieved[:, 1:], 6).tolist(),
            "directions": [float(d) for d in cal.directions]}


def _from_json(entry, commands) -> SpeedCalibration:
    """The SpeedCalibration of a file's entry, measured at ``commands`` (m/s) and
    ``CALIBRATION_DIRECTIONS``; ValueError naming what does not hold."""
    if not isinstance(entry, dict) or set(entry) != {"style", "commanded", "achieved", "directions"}:
        raise ValueError("an entry must have exactly style, commanded, achieved and directions")
    if not isinstance(entry["style"], str):
        raise ValueError("an entry's style must be a digest (a string)")
    c = np.asarray(entry["commanded"], dtype=np.float64)
    a = np.asarray(entry["achieved"], dtype=np.float64)
    d = np.asarray(entry["directions"], dtype=np.float64)
    if c.ndim != 1 or not 1 <= len(c) <= 64 or d.ndim != 1 or not 1 <= len(d) <= 16 or a.shape != (len(d), len(c)):
        raise ValueError(f"shapes commanded {c.shape}, achieved {a.shape}, directions {d.shape} do not fit")
    if not (np.all(np.isfinite(c)) and np.all(np.isfinite(a)) and np.all(np.isfinite(d))):
        raise ValueError("numbers must be finite")
    if c.tolist() != [float(v) for v in commands] or d.tolist() != list(CALIBRATION_DIRECTIONS):
        raise ValueError(f"commands {c.tolist()[:12]} and directions {d.tolist()} are not the measured "
                         f"{[float(v) for v in commands]} and {list(CALIBRATION_DIRECTIONS)}")
    if np.any(a < 0) or np.any(a > MAX_PLAUSIBLE_SPEED):
        raise ValueError(f"achieved speeds must be within 0-{MAX_PLAUSIBLE_SPEED:g} m/s, found "
                         f"{a.min():.3g}..{a.max():.3g}")
    if a[0].max() < MIN_TOP_SPEED:
        raise ValueError(f"the forward speeds are all under {MIN_TOP_SPEED} m/s: the character never moved")
    return SpeedCalibration(c, a, tuple(d.tolist()))


def file_text(entries: Dict[str, dict]) -> str:
    """A calibration file's JSON, one style a line (the package's file reads well in a diff)."""
    lines = [f"  {json.dumps(name)}: {json.dumps(entry, allow_nan=False)}" for name, entry in entries.items()]
    return f'{{"version": {json.dumps(CALIBRATION_VERSION)}, "styles": {{\n' + ",\n".join(lines) + "\n}}\n"


class CalibrationCache:
    """The cached calibrations of one DemoSource's styles; ``load()`` then ``put()`` as styles are
    measured. ``where``: the cache folder (default :func:`cache_folder`); ``shipped``: the folder of
    the package's own calibrations (None: not read); ``ignore_cached``: the cache file's entries
    are not used, only kept for the styles not measured again (``minifilm demo --recalibrate``)."""

    def __init__(self, source, where: Optional[Path] = None, shipped: Optional[Path] = SHIPPED,
                 ignore_cached: bool = False):
        self.source, self.ignore_cached = source, ignore_cached
        self.where = None if where is None else Path(where)
        self.shipped = None if shipped is None else Path(shipped)
        self._key: Optional[str] = None
        self._keyed = False
        self.entries: Dict[str, dict] = {}

    @property
    def key(self) -> Optional[str]:
        """:func:`calibration_key`, computed on first use (about a tenth of a second for the
        released network's 20 MB, off the start-up's way)."""
        if not self._keyed:
            self._key, self._keyed = calibration_key(self.source), True
        return self._key

    @property
    def path(self) -> Optional[Path]:
        """The cache file, named by the key; None when nothing can be cached."""
        return None if self.key is None else (self.where or cache_folder()) / f"calibration-{self.key}.json"

    def _read(self, path: Path, what: str) -> Dict[str, tuple]:
        """The entries of one file, name -> (entry, SpeedCalibration); {} and one warning when
        the file cannot be used."""
        try:
            obj = json.loads(read_regular_bytes(path, what, max_bytes=MAX_CACHE_BYTES), **JSON_NUMBERS)
            if not isinstance(obj, dict) or obj.get("version") != CALIBRATION_VERSION \
                    or not isinstance(obj.get("styles"), dict):
                raise ValueError(f"not a {CALIBRATION_VERSION} file")
            entries = {str(name): (entry, _from_json(entry, self.source.calibration_commands))
                       for name, entry in obj["styles"].items()}
        except (OSError, ValueError, RecursionError, TypeError, InputError) as e:
            print(f"warning: ignoring the {what} {path} ({str(e)[:200]}); it will be measured again", file=sys.stderr)
            return {}
        return entries

    def load(self) -> Dict[str, SpeedCalibration]:
        """The calibrations known for this source's styles: the shipped ones, then the cache
        file's ({} when there are none)."""
        if self.key is None:
            return {}
        found = {}
        shipped = None if self.shipped is None else self.shipped / f"calibration-{self.key}.json"
        if shipped is not None and shipped.is_file():
            found.update(self._read(shipped, "shipped speed calibrations"))
        if os.path.lexists(self.path):
            cached = self._read(self.path, "speed calibration cache")
            self.entries.update({name: entry for name, (entry, _) in cached.items()})   # kept when rewritten
            if not self.ignore_cached:
                found.update(cached)
        # a style re-taught under an old name (another pack, a run fine-tuned again) is not the one measured
        return {name: cal for name, (entry, cal) in found.items()
                if name in self.source.library and entry["style"] == style_digest(self.source, name)}

    def put(self, name: str, cal: SpeedCalibration) -> None:
        """Add a style's calibration and rewrite the file (atomically); a cache that cannot be
        written is a warning, never an error (the demo works without it)."""
        if self.path is None:
            return
        self.entries[name] = _to_json(cal, style_digest(self.source, name))
        text = file_text(self.entries)
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
