"""Which frame of each track an animation shows at each of its frames, and for how long.

Tracks may have different frame rates (30 fps Bandai next to 120 fps Xia) and lengths. The
animation has its own clock: output frame k is shown at time ``k / fps``, and each track shows
its frame nearest to t, ``floor(t * track.fps + 0.5)``, held on its last frame once it has ended.
(Nearest, not the frame started last: BVH frame times are rounded, "0.0083333" is 120.0048 fps,
and a floor would drop a frame whenever the rounded rates disagree by a hair.)
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np

from minifilm.viewer.tracks import Track

__all__ = ["Schedule", "schedule", "gif_durations_ms", "GIF_MAX_FPS"]

# Browsers show GIF frames shorter than 20 ms for 100 ms (a 60 fps GIF would play 6x too slowly),
# and GIF delays are whole centiseconds; 50 fps is the fastest rate that plays as written.
GIF_MAX_FPS = 50.0


@dataclass
class Schedule:
    """The frames of an animation.

    Attributes:
        fps:    output frames per second.
        frames: (N, T) int: the frame of each of the T tracks shown at output frame k.
    """

    fps: float
    frames: np.ndarray

    @property
    def n_frames(self) -> int:
        return int(self.frames.shape[0])

    @property
    def times(self) -> np.ndarray:
        """(N,) seconds at which each output frame is shown."""
        return np.arange(self.n_frames) / self.fps


def schedule(tracks: Sequence[Track], fps: Optional[float] = None, seconds: Optional[float] = None,
             every: Optional[int] = None, max_fps: Optional[float] = None) -> Schedule:
    """Output frames for ``tracks``.

    Args:
        fps:     output frame rate; default: the highest track frame rate divided by ``every``.
        seconds: duration; default: the longest track's duration.
        every:   keep every n-th frame of the fastest track (frame rate divided by n). Default 1,
                 or, when ``max_fps`` is given, the smallest n whose rate does not exceed it.
                 Give ``fps`` or ``every``, not both.
        max_fps: see ``every`` (GIFs use ``GIF_MAX_FPS``).
    The output has ``ceil(seconds * fps)`` frames: every source frame of a single track with
    ``every=1``, and frames 0, n, 2n, ... with ``every=n``.
    """
    if not tracks:
        raise ValueError("nothing to draw: no tracks given")
    top = max(t.fps for t in tracks)
    if fps is not None and every is not None:
        raise ValueError("give fps or every, not both")
    if fps is None:
        if every is None:
            every = 1 if max_fps is None else max(1, math.ceil(top / max_fps - 1e-9))
        if int(every) != every or every < 1:
            raise ValueError(f"every must be a positive whole number, got {every}")
        fps = top / int(every)
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be positive, got {fps}")
    if seconds is None:
        seconds = max(t.duration for t in tracks)
    if not (np.isfinite(seconds) and seconds > 0):
        raise ValueError(f"seconds must be positive, got {seconds}")
    n = max(1, math.ceil(seconds * fps - 1e-3))
    t = np.arange(n) / fps
    frames = np.stack([np.minimum(np.floor(t * tr.fps + 0.5).astype(np.int64), tr.n_frames - 1)
                       for tr in tracks], axis=1)
    return Schedule(fps=float(fps), frames=frames)


def gif_durations_ms(n: int, fps: float) -> list:
    """Per-frame GIF delays in ms, whole centiseconds whose running sum tracks ``k / fps``.

    A 30 fps GIF alternates 30 and 40 ms delays (30, 40, 30, 30, 40, ...) so that its total
    duration stays exact instead of drifting to 33 fps with a constant 30 ms.
    """
    edges = np.round(np.arange(n + 1) * 100.0 / fps).astype(np.int64)  # centiseconds
    return [int(10 * d) for d in np.maximum(np.diff(edges), 2)]
