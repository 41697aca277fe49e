"""See the motion: animated GIF / MP4, a self-contained three.js HTML player, and still pictures.

    from minifilm.viewer import track_from_bvh, write_gif, write_html
    tracks = [track_from_bvh(p) for p in ["walk.bvh", "run.bvh"]]
    write_gif(tracks, "styles.gif")      # matplotlib + Pillow, no ffmpeg
    write_html(tracks, "index.html")     # one file, opens offline from disk
    # a runtime Rollout (B characters) carries no skeleton: give the layout's parents and names
    write_gif(tracks_from_rollout(rollout, layout.parents, ["Old", "Zombie"], layout.joint_names), "two.gif")

Files: ``tracks`` (what is drawn), ``timeline`` (which frame when), ``projection`` (the 2-D camera
of the GIF), ``render2d`` (matplotlib panels), ``gif`` / ``mp4`` (animated files), ``encode`` and
``html`` (the browser player, with ``assets/`` and the vendored three.js in ``vendor/``),
``phase_plot`` (the paper's Figure 4), ``strip`` (side-view stick figures of a rollout), ``deps``
(the optional imports: matplotlib, Pillow). Importing this package loads none of them.
"""
from minifilm.errors import MissingDependencyError, OutputPathError
from minifilm.viewer.builders import track_with_contacts, tracks_from_rollout
from minifilm.viewer.deps import FFmpegMissingError
from minifilm.viewer.gif import write_gif
from minifilm.viewer.html import write_html
from minifilm.viewer.mp4 import write_mp4
from minifilm.viewer.projection import Camera, project
from minifilm.viewer.render2d import Rendering
from minifilm.viewer.tracks import Track, as_tracks, track_from_bvh, track_from_motion

__all__ = ["Track", "track_from_motion", "track_from_bvh", "track_with_contacts", "tracks_from_rollout",
           "as_tracks", "write_gif", "write_mp4", "write_html", "Camera", "project", "Rendering",
           "OutputPathError", "MissingDependencyError", "FFmpegMissingError"]
