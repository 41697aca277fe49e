"""MP4 of the same side-by-side animation as the GIF, through matplotlib's ffmpeg writer.

ffmpeg is not a Python package and often missing; when it is, ``write_mp4`` says so in one line
(and that a GIF needs no ffmpeg) before doing any work, instead of the classic matplotlib
failure deep inside an animation save.
"""
from __future__ import annotations

import os
from typing import Optional, Tuple, Union

from minifilm.files import atomic_path
from minifilm.viewer.deps import FFmpegMissingError, require_ffmpeg
from minifilm.viewer.render2d import PanelRenderer, Rendering
from minifilm.viewer.timeline import schedule
from minifilm.viewer.tracks import as_tracks

__all__ = ["write_mp4", "FFmpegMissingError"]  # the error lives in deps; re-exported here


def write_mp4(tracks, path: Union[str, os.PathLike], fps: Optional[float] = None,
              seconds: Optional[float] = None, every: Optional[int] = None,
              size: Tuple[int, int] = (240, 300), columns: Optional[int] = None,
              contacts: bool = True, trail: bool = True) -> Rendering:
    """Write an H.264 MP4 of ``tracks`` side by side; arguments as ``write_gif``.

    The frame rate is not capped as for GIFs (video players show 60 or 120 fps as written).
    Raises ``FFmpegMissingError`` when ffmpeg is not found, ``OutputPathError`` when ``path``
    cannot be written (both before rendering), ImportError without matplotlib.
    """
    require_ffmpeg(path)
    from matplotlib.animation import FFMpegWriter  # optional extra, checked by require_ffmpeg
    with atomic_path(path, "MP4") as tmp:
        items = as_tracks(tracks)
        sched = schedule(items, fps=fps, seconds=seconds, every=every)
        renderer = PanelRenderer(items, sched, size=size, columns=columns, contacts=contacts, trail=trail)
        # yuv420p (what every player decodes) needs even sizes; "-f mp4" because the temporary
        # file's name does not end in .mp4.
        writer = FFMpegWriter(fps=sched.fps, codec="libx264",
                              extra_args=["-pix_fmt", "yuv420p", "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2",
                                          "-f", "mp4"])
        with writer.saving(renderer.figure, tmp, dpi=renderer.figure.dpi):
            for k in range(sched.n_frames):
                renderer.update(k)
                writer.grab_frame()
    return renderer.rendering(path)
