"""Import matplotlib for drawing files (the Agg backend), or say which extra to install."""
from __future__ import annotations

from pathlib import Path

from minifilm.files import atomic_write


def pyplot():
    """``matplotlib.pyplot`` with the file-only Agg backend; ImportError naming the extra when
    matplotlib is missing."""
    try:
        import matplotlib  # optional extra (minifilm[viz]): imported only when drawing
    except ImportError:
        raise ImportError("drawing needs matplotlib: pip install 'minifilm[viz]'") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt   # after choosing the backend, which must come first
    return plt


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
