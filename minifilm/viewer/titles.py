"""Panel titles that fit their panel: a smaller font, then an ellipsis in the middle.

Side by side, file names such as ``dataset-2_walk-turn-left_feminine_001`` are wider than a 240
pixel panel at the title's 11 points: they ran into each other and the last one was cut at the
image's edge. ``fit_title`` measures the drawn text (matplotlib's renderer, in pixels) and first
shrinks the font down to ``min_size``, then drops characters from the middle — the start and the
end of a name are what tell files apart (``dataset-2_wal…eminine_001``) — until it fits.
"""
from __future__ import annotations

__all__ = ["fit_title", "text_width"]

ELLIPSIS = "\u2026"


def text_width(text_artist, renderer) -> float:
    """Width in pixels of a matplotlib ``Text`` as drawn by ``renderer``."""
    return float(text_artist.get_window_extent(renderer=renderer).width)


def fit_title(text_artist, renderer, max_width: float, min_size: float = 8.0) -> str:
    """Shrink ``text_artist`` (a matplotlib Text) to at most ``max_width`` pixels; returns the shown text.

    The font size goes down by half points to ``min_size``; if the text is still too wide,
    characters are removed from its middle and replaced by an ellipsis (at least one character is
    kept on each side; a single character is shown as is)."""
    full = text_artist.get_text()
    size = float(text_artist.get_fontsize())
    while text_width(text_artist, renderer) > max_width and size > min_size:
        size = max(min_size, size - 0.5)
        text_artist.set_fontsize(size)
    keep = len(full)
    while text_width(text_artist, renderer) > max_width and keep > 2:
        keep -= 1
        head = (keep + 1) // 2
        text_artist.set_text(full[:head] + ELLIPSIS + full[len(full) - (keep - head):])
    return text_artist.get_text()
