"""Optional dependencies of the viewer, imported only when a function needs them.

matplotlib and Pillow (GIF / MP4) and playwright (browser tests) are extras, never core
dependencies of minifilm: ``pip install 'minifilm[viz]'`` installs the drawing ones.
"""
from __future__ import annotations

import importlib
import warnings
from pathlib import Path

from minifilm.errors import MissingDependencyError
from minifilm.files import atomic_write

__all__ = ["require", "pyplot", "save_figure", "check_output_tools", "FFmpegMissingError", "MissingDependencyError"]

_PIP_NAME = {"matplotlib": "matplotlib", "PIL": "Pillow"}


class FFmpegMissingError(MissingDependencyError):
    """ffmpeg is not on the PATH (matplotlib's ``animation.ffmpeg_path``)."""


def require(module: str, purpose: str):
    """Import and return ``module``; MissingDependencyError (an ImportError) naming the extra when
    it is missing."""
    try:
        imported = importlib.import_module(module)
    except ImportError as e:
        # the package that is missing, which may be one ``module`` needs (matplotlib needs Pillow)
        top = (getattr(e, "name", None) or module).split(".")[0]
        raise MissingDependencyError(f"{purpose} needs {_PIP_NAME.get(top, top)}, which is not installed: "
                                     f"pip install 'minifilm[viz]' ({e})") from None
    if module == "matplotlib":
        # a style named in a script the font lacks (疲れた) is drawn with boxes; matplotlib's warning
        # for each glyph (three lines, naming its own source file) says nothing the picture does not
        warnings.filterwarnings("ignore", message=r"Glyph \d+ .* missing from font", category=UserWarning)
    return imported


def pyplot():
    """``matplotlib.pyplot`` with the file-only Agg backend; MissingDependencyError naming the
    extra when matplotlib is missing."""
    matplotlib = require("matplotlib", "drawing")  # optional extra (minifilm[viz]): imported only when drawing
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # after choosing the backend, which must come first
    return plt


def require_ffmpeg(path) -> None:
    """FFmpegMissingError naming ``path`` unless matplotlib finds ffmpeg."""
    require("matplotlib", "writing an MP4")
    from matplotlib.animation import FFMpegWriter  # optional extra, checked just above

    if not FFMpegWriter.isAvailable():
        raise FFmpegMissingError(f"cannot write MP4 {path}: ffmpeg was not found on the PATH; install it "
                                 "(e.g. apt-get install ffmpeg) or write a GIF instead, which needs no ffmpeg "
                                 "(--gif on the command line, write_gif in Python)")


def check_output_tools(path, kind: str) -> None:
    """Before any work: MissingDependencyError unless what writing ``path`` as ``kind`` needs is
    installed. ``kind``: "gif" (matplotlib, Pillow), "mp4" (matplotlib, ffmpeg), "png"
    (matplotlib) or "html" (nothing: three.js is vendored)."""
    if kind == "gif":
        require("matplotlib", f"writing the GIF {path}")
        require("PIL.Image", f"writing the GIF {path}")
    elif kind == "mp4":
        require_ffmpeg(path)
    elif kind == "png":
        require("matplotlib", f"writing the picture {path}")
    elif kind != "html":
        raise ValueError(f"check_output_tools: unknown kind {kind!r}")


def save_figure(fig, path, dpi: int = 100):
    """Save a matplotlib figure to ``path`` atomically (format from the suffix, PNG without one)
    and close it; returns the path written."""
    path = Path(path)
    fmt = path.suffix[1:].lower() or "png"
    try:
        atomic_write(path, lambda f: fig.savefig(f, format=fmt, dpi=dpi))
    finally:
        pyplot().close(fig)
    return path
