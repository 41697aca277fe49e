"""Pictures of a taught style beside the clip it was taught from (benchmarks/teach_real_clips.py).

    clip.bvh, taught.bvh -> <tag>.gif (both side by side, a few seconds) and <tag>.png (a contact
    sheet: the clip at a few moments in the top row, the taught style at the same moments below)

Drawn with the viewer's GIF renderer (minifilm/viewer/gif.py, render2d.py): each character at its
true size, the foot contacts marked, the path on the floor. matplotlib and Pillow are optional
extras of the viewer, needed here only; without them no picture is written and the reason is said.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

SECONDS, FPS, SIZE, COLOURS = 4.0, 15.0, (200, 250), 32


def clip_and_result(clip_bvh: Path, taught_bvh: Path, out: Path, tag: str, titles=("clip", "taught"),
                    moments=(0.5, 1.5, 2.5, 3.5), log=print) -> list:
    """Write ``out/<tag>.gif`` and ``out/<tag>.png``; -> the paths written (none without the extras)."""
    try:
        from minifilm.viewer.builders import track_with_contacts
        from minifilm.viewer.gif import write_gif
        from minifilm.viewer.render2d import PanelRenderer
        from minifilm.viewer.timeline import schedule
        from minifilm.viewer.deps import require
        Image = require("PIL.Image", "a contact sheet")
    except ImportError as e:
        log(f"    no pictures: {e}")
        return []
    tracks = [track_with_contacts(clip_bvh, name=titles[0]), track_with_contacts(taught_bvh, name=titles[1])]
    seconds = min(SECONDS, min(t.duration for t in tracks))
    gif = out / f"{tag}.gif"
    write_gif(tracks, gif, seconds=seconds, fps=FPS, size=SIZE, colours=COLOURS)
    sched = schedule(tracks, fps=FPS, seconds=seconds)
    renderer = PanelRenderer(tracks, sched, size=SIZE)
    frames = [renderer.render(min(sched.n_frames - 1, int(round(t * FPS)))) for t in moments if t <= seconds]
    w = SIZE[0]                      # each frame is [clip | taught]: the clip's row above, the result's below
    sheet = np.concatenate([np.concatenate([f[:, :w] for f in frames], axis=1),
                            np.concatenate([f[:, w:2 * w] for f in frames], axis=1)], axis=0)
    png = out / f"{tag}.png"
    Image.fromarray(np.ascontiguousarray(sheet)).quantize(colors=COLOURS).save(png, optimize=True)
    return [gif, png]
