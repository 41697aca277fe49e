"""Animated GIF of one or more characters side by side (matplotlib Agg + Pillow, no ffmpeg).

    write_gif(["walk.bvh", "run.bvh"], "styles.gif")

Frames are drawn by ``render2d.PanelRenderer`` and quantised to one global 8-bit palette (built
from the first frame plus a swatch of every colour the renderer can use), so colours do not
flicker between frames and Pillow can store each frame as the small rectangle that changed.
"""
from __future__ import annotations

import os
from typing import Optional, Tuple, Union

import numpy as np

from minifilm.viewer.deps import require
from minifilm.files import atomic_path
from minifilm.viewer.render2d import COLOURS, CONTACT_EDGE, CONTACT_FACE, FAR_FADE, GRID_COLOUR, PanelRenderer, Rendering
from minifilm.viewer.timeline import GIF_MAX_FPS, gif_durations_ms, schedule
from minifilm.viewer.tracks import as_tracks

__all__ = ["write_gif"]


def write_gif(tracks, path: Union[str, os.PathLike], fps: Optional[float] = None,
              seconds: Optional[float] = None, every: Optional[int] = None,
              size: Tuple[int, int] = (240, 300), columns: Optional[int] = None,
              contacts: bool = True, trail: bool = True, colours: int = 128) -> Rendering:
    """Write an animated GIF of ``tracks`` side by side; returns what was drawn.

    Args:
        tracks:   a ``Track``, ``Motion`` or BVH path, or a sequence of them (one panel each).
        path:     the ``.gif`` to write (atomically: a failure leaves no file behind).
        fps:      output frame rate; default the source rate (the highest, for mixed rates)
                  divided by ``every``.
        seconds:  duration; default the longest track's. Tracks that end early hold their last frame.
        every:    keep every n-th source frame. Default: 1, or the smallest n that keeps the GIF at
                  or below 50 fps (120 fps becomes 40 fps): browsers play GIF frames shorter than
                  20 ms at 100 ms, so a faster GIF would play in slow motion.
        size:     (width, height) of one character's panel, pixels.
        columns:  panels per row (default up to 4; 8 characters make 2 rows).
        contacts: mark contact joints in contact (tracks with ``contacts`` only).
        trail:    draw the root's path on the floor.
        colours:  size of the palette, 2-256 (fewer colours make a smaller file: 16 take about a
                  fifth less than 128, with coarser anti-aliasing).
    Raises:
        OutputPathError (an OSError) naming ``path`` when it cannot be written, before rendering;
        ValueError for bad tracks or arguments; ImportError when matplotlib or Pillow is missing.
    """
    if not (isinstance(colours, (int, np.integer)) and 2 <= colours <= 256):
        raise ValueError(f"colours must be an integer from 2 to 256, got {colours!r}")
    with atomic_path(path, "GIF") as tmp:
        Image = require("PIL.Image", "writing a GIF")  # Pillow is an optional extra
        items = as_tracks(tracks)
        sched = schedule(items, fps=fps, seconds=seconds, every=every,
                         max_fps=None if fps is not None else GIF_MAX_FPS)
        renderer = PanelRenderer(items, sched, size=size, columns=columns, contacts=contacts, trail=trail)
        first = renderer.render(0)
        palette = _palette(Image, first, len(items), colours)

        def to_p(rgb: np.ndarray):
            return Image.fromarray(rgb).quantize(palette=palette, dither=Image.Dither.NONE)

        rest = (to_p(renderer.render(k)) for k in range(1, sched.n_frames))
        to_p(first).save(tmp, format="GIF", save_all=True, append_images=rest,
                         duration=gif_durations_ms(sched.n_frames, sched.fps), loop=0)
    return renderer.rendering(path)


def _palette(Image, first: np.ndarray, n_tracks: int, colours: int = 128):
    """A P-mode image whose palette (``colours`` <= 256 entries) covers ``first`` and every renderer colour.

    The swatch holds each character colour at every depth fade, the trail blend, the contact
    marker and the grid, so colours first seen later in the clip still map to themselves.
    """
    def rgb(h):
        return np.array([int(h[i:i + 2], 16) for i in (1, 3, 5)], dtype=np.float64)

    white = np.full(3, 255.0)
    swatch = [rgb(CONTACT_FACE), rgb(CONTACT_EDGE), rgb(GRID_COLOUR), np.zeros(3), white]
    for h in COLOURS[:max(n_tracks, 1)]:
        c = rgb(h)
        swatch += [c + (white - c) * a for a in np.linspace(0.0, FAR_FADE, 6)]
        swatch.append(0.55 * c + 0.45 * white)  # the trail, drawn with alpha 0.55
    block = np.repeat(np.array(swatch, dtype=np.uint8)[None], 8, axis=0)  # (8, S, 3)
    block = np.repeat(block, max(1, first.shape[1] // len(swatch)), axis=1)[:, : first.shape[1]]
    pad = np.full((8, first.shape[1], 3), 255, dtype=np.uint8)
    pad[:, : block.shape[1]] = block
    sample = np.concatenate([first, pad], axis=0)
    return Image.fromarray(sample).quantize(colors=colours, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
