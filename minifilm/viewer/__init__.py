"""See the motion: animated GIF / MP4 and a self-contained three.js HTML player (optional extras).

    from minifilm.viewer import track_from_bvh, write_gif, write_html
    tracks = [track_from_bvh(p) for p in ["walk.bvh", "run.bvh"]]
    write_gif(tracks, "styles.gif")      # matplotlib + Pillow, no ffmpeg
    write_html(tracks, "index.html")     # one file, opens offline from disk

Files: ``tracks`` (what is drawn), ``timeline`` (which frame when), ``projection`` (the 2-D camera
of the GIF), ``render2d`` (matplotlib panels), ``gif`` / ``mp4`` (animated files), ``encode`` and
``html`` (the browser player, with ``assets/`` and the vendored three.js in ``vendor/``),
``output`` (atomic writes), ``deps`` (optional imports).
"""
from .gif import write_gif
from .html import write_html
from .mp4 import write_mp4
from .output import OutputPathError
from .projection import Camera, project
from .render2d import Rendering
from .tracks import Track, as_tracks, track_from_bvh, track_from_motion

__all__ = ["Track", "track_from_motion", "track_from_bvh", "as_tracks", "write_gif", "write_mp4",
           "write_html", "Camera", "project", "Rendering", "OutputPathError"]
