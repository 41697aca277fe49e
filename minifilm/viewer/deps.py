"""Optional dependencies of the viewer, imported only when a function needs them.

matplotlib and Pillow (GIF / MP4) and playwright (browser tests) are extras, never core
dependencies of minifilm: ``pip install 'minifilm[viz]'`` installs the drawing ones.
"""
from __future__ import annotations

import importlib

__all__ = ["require"]

_PIP_NAME = {"matplotlib": "matplotlib", "PIL": "Pillow"}


def require(module: str, purpose: str):
    """Import and return ``module``; a clear ImportError naming the extra when it is missing."""
    try:
        return importlib.import_module(module)
    except ImportError as e:
        top = module.split(".")[0]
        raise ImportError(f"{purpose} needs {_PIP_NAME.get(top, top)}, which is not installed: "
                          f"pip install 'minifilm[viz]' ({e})") from None
