"""Optional dependencies of the viewer, imported only when a function needs them.

matplotlib and Pillow (GIF / MP4) and playwright (browser tests) are extras, never core
dependencies of minifilm: ``pip install 'minifilm[viz]'`` installs the drawing ones.
"""
from __future__ import annotations

import importlib
from pathlib import Path

from minifilm.files import atomic_write

__all__ = ["require", "pyplot", "save_figure"]

_PIP_NAME = {"matplotlib": "matplotlib", "PIL": "Pillow"}


def require(module: str, purpose: str):
    """Import and return ``module``; a clear ImportError naming the extra when it is missing."""
    try:
        return importlib.import_module(module)
    except ImportError as e:
        top = module.split(".")[0]
        raise ImportError(f"{purpose} needs {_PIP_NAME.get(top, top)}, which is not installed: "
                          f"pip install 'minifilm[viz]' ({e})") from None


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
