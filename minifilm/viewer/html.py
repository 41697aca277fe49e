"""One self-contained HTML file that plays tracks in 3-D with three.js, offline, from disk.

The page is ``assets/player.html`` with five things inlined:

- three.js (``vendor/three.module.min.js``, one ES module) as the ``data:`` URL of an import map
  entry, so the player's inline ``<script type="module">`` can ``import * as THREE from "three"``
  on a page opened with ``file://``: no server, no CDN, no network request. (An inline module
  cannot import a file by name, and a ``file://`` page may not fetch its neighbours.)
- ``assets/scene.js`` (stage, floor, skeletons, labels, orbit camera; shared with the live demo
  of ``minifilm.demo``, which serves it as a file) the same way, as the entry ``"minifilm-scene"``,
  and ``assets/mannequin.js`` (the shaded body drawn over the skeleton, also shared with the demo)
  as ``"minifilm-mannequin"``.
- ``assets/player.js`` (the player) and ``assets/player.css``.
- The motion data as JSON (``encode.py``: float32 roots + int16 offsets in base64).

Characters are placed side by side in lanes across their overall direction of travel, each
starting at its lane's origin; the page exposes ``window.minifilmPlayer`` for tests and scripts
(see ``assets/player.js``).
"""
from __future__ import annotations

import base64
import json
import os
import re
from pathlib import Path
from typing import List, Union

import numpy as np

from minifilm.viewer.encode import encode_tracks
from minifilm.files import atomic_path
from minifilm.viewer.projection import grid_step
from minifilm.viewer.tracks import Track, as_tracks

__all__ = ["write_html", "page_html", "lane_offsets"]

HERE = Path(__file__).resolve().parent
THREE_JS = HERE / "vendor" / "three.module.min.js"
SCENE_JS = HERE / "assets" / "scene.js"
MANNEQUIN_JS = HERE / "assets" / "mannequin.js"
THREE_VERSION = "0.170.0"


def write_html(tracks, path: Union[str, os.PathLike], title: str = "minifilm motion") -> Path:
    """Write the player page for ``tracks`` (Track, Motion, BVH path, or a sequence of them).

    Written atomically; raises ``OutputPathError`` naming ``path`` before any work when it
    cannot be written, ValueError for bad tracks. Returns the path.
    """
    with atomic_path(path, "HTML") as tmp:
        text = page_html(as_tracks(tracks), title)
        Path(tmp).write_text(text, encoding="utf-8")
    return Path(path)


def page_html(tracks: List[Track], title: str = "minifilm motion") -> str:
    """The page text for ``tracks``."""
    size = max(t.body_size() for t in tracks)
    offsets = lane_offsets(tracks, size)
    data = {
        "title": str(title),
        "size": size,
        "grid": grid_step(size),
        "heading": _mean_heading(tracks),
        "lanes": lanes_width(tracks, offsets, size),
        "characters": encode_tracks(tracks, offsets),
    }
    parts = {
        "TITLE": _escape_text(str(title)),
        "CSS": _asset("player.css"),
        "THREE": base64.b64encode(THREE_JS.read_bytes()).decode("ascii"),
        "SCENE": base64.b64encode(SCENE_JS.read_bytes()).decode("ascii"),
        "MANNEQUIN": base64.b64encode(MANNEQUIN_JS.read_bytes()).decode("ascii"),
        "DATA": _json_for_script(data),
        "JS": _asset("player.js"),
        "THREE_VERSION": THREE_VERSION,
    }
    # One pass, so a title or joint name that happens to contain "{{JS}}" is not expanded.
    return re.sub(r"\{\{(\w+)\}\}", lambda m: parts[m.group(1)], _asset("player.html", inlined=False))


def lane_offsets(tracks: List[Track], size: float) -> np.ndarray:
    """(T, 3) offsets that move each track's start into its own lane.

    Lanes run across the tracks' combined direction of travel (along x when they mostly walk
    along z), so characters walking the same way stay side by side instead of in single file.
    Each lane is as wide as its character's path reaches across, plus ``size`` metres between
    neighbours: straight walkers end up ``size`` apart, and characters on curved paths (a
    figure-eight) never walk through each other's lanes.
    """
    across = _across_axis(tracks)
    reach = [(t.trail - t.trail[0]) @ across for t in tracks]          # (F,) across, from the start
    lo = np.array([min(0.0, r.min()) for r in reach])
    hi = np.array([max(0.0, r.max()) for r in reach])
    centre = np.zeros(len(tracks))                                    # each start, along ``across``
    for i in range(1, len(tracks)):
        centre[i] = centre[i - 1] + hi[i - 1] - lo[i] + size
    centre -= ((centre + lo).min() + (centre + hi).max()) / 2.0       # lanes centred on the origin
    starts = np.array([t.trail[0] * np.array([1.0, 0.0, 1.0]) for t in tracks])
    return centre[:, None] * across - starts


def lanes_width(tracks: List[Track], offsets: np.ndarray, size: float) -> float:
    """Metres across all lanes (paths included): what the player's first camera must frame."""
    across = _across_axis(tracks)
    reach = np.concatenate([(t.trail + o) @ across for t, o in zip(tracks, offsets)])
    return float(reach.max() - reach.min() + size)


def _across_axis(tracks: List[Track]) -> np.ndarray:
    travel = np.array([np.abs(t.trail[-1] - t.trail[0]) for t in tracks]).sum(axis=0)  # (3,)
    return np.array([1.0, 0.0, 0.0]) if travel[2] >= travel[0] else np.array([0.0, 0.0, 1.0])


def _mean_heading(tracks: List[Track]) -> float:
    """Mean direction of travel (radians about +y, 0 = +z), as a vector mean of unit headings."""
    v = np.zeros(2)
    for t in tracks:
        d = t.trail[-1] - t.trail[0]
        length = np.hypot(d[0], d[2])
        if length > 1e-6:
            v += np.array([d[0], d[2]]) / length
    return float(np.arctan2(v[0], v[1])) if np.hypot(*v) > 1e-6 else 0.0


def _asset(name: str, inlined: bool = True) -> str:
    text = (HERE / "assets" / name).read_text(encoding="utf-8")
    # Inlined into <script>/<style>: a closing tag inside would end the element early.
    if inlined and ("</script" in text.lower() or "</style" in text.lower()):
        raise RuntimeError(f"assets/{name} contains a closing </script> or </style> tag")
    return text


def _json_for_script(data) -> str:
    """JSON safe inside <script>: '<', '>' and '&' escaped (a joint named '</script>' stays data)."""
    text = json.dumps(data, separators=(",", ":"), allow_nan=False)
    return text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")


def _escape_text(text: str) -> str:
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;").replace('"', "&quot;")
