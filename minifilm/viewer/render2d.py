"""Draws tracks side by side into RGB frames with matplotlib (Agg): the renderer behind GIF and MP4.

One panel per character, in a grid of ``columns``. Panels rather than one shared scene because
each character gets its own camera following its own root: characters that walk in different
directions or at different speeds stay centred and never overlap, which no fixed sideways offset
in a shared scene guarantees.

Speed: the figure is built once; each frame only replaces the data of a few artists (a
``LineCollection`` of bones, one of grid lines, a trail line, contact markers, a text), then the
canvas is drawn once. Points are projected by ``projection.project`` in NumPy, so matplotlib only
draws 2-D lines. The numbers drawn are kept (``drawn``, ``pixels``, ``cameras``) for tests.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import List, Sequence, Tuple

import numpy as np

from minifilm.viewer.deps import require
from minifilm.viewer.projection import Camera, depth_of, follow_cameras, grid_step, heading_of, project
from minifilm.viewer.timeline import Schedule
from minifilm.viewer.titles import fit_title
from minifilm.viewer.tracks import Track

__all__ = ["PanelRenderer", "Rendering", "COLOURS"]

# Tableau colours without the grey and olive that vanish on a grey grid; one per character.
COLOURS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf", "#8c564b", "#e377c2"]
CONTACT_FACE, CONTACT_EDGE = "#ffd000", "#222222"
GRID_COLOUR = "#c8c8c8"
# Bones further from the camera are blended towards white by up to this much (a depth cue that
# tells the near leg from the far one in a single-colour skeleton).
FAR_FADE = 0.55
#: a title may use this fraction of its panel's width (the rest is margin from its neighbours)
TITLE_WIDTH = 0.94
GRID_RADIUS = 2.2  # floor drawn within this many body sizes of the camera target


@dataclass
class Rendering:
    """What a GIF / MP4 writer drew, returned to the caller (and checked by the tests).

    Attributes:
        path:    the written file.
        size:    (width, height) of the frames, pixels.
        fps:     output frames per second.
        frames:  (N, T) int: frame of each track shown at each output frame.
        drawn:   per track, (N, J, 2) screen points of the joints (``project(positions, camera)``).
        pixels:  per track, (N, J, 2) the same points in image pixels (x right, y down).
        cameras: per track, N ``Camera`` objects.
        titles:  per track, (shown title, (x0, y0, x1, y1) its drawn box in image pixels, y down).
    """

    path: Path
    size: Tuple[int, int]
    fps: float
    frames: np.ndarray
    drawn: List[np.ndarray]
    pixels: List[np.ndarray]
    cameras: List[List[Camera]]
    titles: List[Tuple[str, Tuple[float, float, float, float]]] = field(default_factory=list)

    @property
    def n_frames(self) -> int:
        return int(self.frames.shape[0])


def _rgb(hex_colour: str) -> np.ndarray:
    return np.array([int(hex_colour[i:i + 2], 16) / 255.0 for i in (1, 3, 5)])


class PanelRenderer:
    """Renders output frame ``k`` of ``schedule`` for ``tracks`` into an (H, W, 3) uint8 image.

    Args:
        tracks:   the characters.
        schedule: which frame of each track to show at each output frame.
        size:     (width, height) of one panel, pixels; the image is
                  ``(columns * width, rows * height)``.
        columns:  panels per row; default ``min(len(tracks), 4)``.
        contacts: highlight contact joints when in contact.
        trail:    draw each root's path on the floor.

    After ``render(k)``, ``drawn[i][k]`` is the (J, 2) screen points of track i's joints,
    ``pixels[i][k]`` the same points in image pixels (x right, y down, pixel (r, c) covers
    [c, c+1) x [r, r+1)) and ``cameras[i][k]`` the ``Camera`` used.
    """

    def __init__(self, tracks: Sequence[Track], schedule: Schedule, size: Tuple[int, int] = (240, 300),
                 columns: int = None, contacts: bool = True, trail: bool = True, dpi: int = 100):
        # matplotlib is an optional extra: imported here, not at module import.
        require("matplotlib", "drawing a GIF or MP4")
        from matplotlib.backends.backend_agg import FigureCanvasAgg   # (the optional extra, see above)
        from matplotlib.figure import Figure

        self.tracks = list(tracks)
        self.schedule = schedule
        self.show_contacts, self.show_trail = contacts, trail
        w, h = (int(v) for v in size)
        if w < 32 or h < 32:
            raise ValueError(f"panel size must be at least 32 x 32 pixels, got {size}")
        n = len(self.tracks)
        self.columns = int(columns) if columns else min(n, 4)
        if self.columns < 1:
            raise ValueError(f"columns must be at least 1, got {columns}")
        self.rows = math.ceil(n / self.columns)
        self.width, self.height = self.columns * w, self.rows * h
        self.figure = Figure(figsize=(self.width / dpi, self.height / dpi), dpi=dpi, facecolor="white")
        self.canvas = FigureCanvasAgg(self.figure)
        # One body size for all panels, so characters keep their relative sizes.
        self.size = max(t.body_size() for t in self.tracks)
        self.step = grid_step(self.size)
        self.aspect = w / h
        self.panels = [self._panel(i, w, h) for i in range(n)]
        self._separators(w, h)
        self.drawn: List[List[np.ndarray]] = [[None] * schedule.n_frames for _ in self.tracks]
        self.pixels: List[List[np.ndarray]] = [[None] * schedule.n_frames for _ in self.tracks]
        self.cameras: List[List[Camera]] = []
        for i, t in enumerate(self.tracks):
            root_xz = t.positions[schedule.frames[:, i], t.root][:, [0, 2]]
            self.cameras.append(follow_cameras(root_xz, schedule.fps, self.size, heading_of(t.trail)))

    def rendering(self, path) -> Rendering:
        """The record of everything drawn so far (call after rendering every frame)."""
        return Rendering(path=Path(path), size=(self.width, self.height), fps=self.schedule.fps,
                         frames=self.schedule.frames.copy(),
                         drawn=[np.stack(d) for d in self.drawn], pixels=[np.stack(p) for p in self.pixels],
                         cameras=self.cameras, titles=[self._title_box(p["title"]) for p in self.panels])

    # -- figure construction --------------------------------------------------------------------

    def _panel(self, i: int, w: int, h: int) -> dict:
        # matplotlib is an optional extra (loaded by __init__ through require)
        from matplotlib.collections import LineCollection
        from matplotlib.lines import Line2D

        r, c = divmod(i, self.columns)
        ax = self.figure.add_axes([c * w / self.width, 1 - (r + 1) * h / self.height,
                                   w / self.width, h / self.height])
        ax.set_axis_off()
        ax.set_xlim(-self.aspect, self.aspect)
        ax.set_ylim(-1.0, 1.0)
        colour = COLOURS[i % len(COLOURS)]
        grid = LineCollection([], colors=GRID_COLOUR, linewidths=0.8, zorder=1)
        trail = Line2D([], [], color=colour, alpha=0.55, linewidth=1.6, zorder=2)
        bones = LineCollection([], linewidths=3.0, capstyle="round", zorder=3)
        marks = Line2D([], [], linestyle="none", marker="o", markersize=7, markerfacecolor=CONTACT_FACE,
                       markeredgecolor=CONTACT_EDGE, markeredgewidth=1.0, zorder=4)
        for artist in (grid, trail, bones, marks):
            ax.add_artist(artist) if isinstance(artist, Line2D) else ax.add_collection(artist)
        title = ax.text(0.5, 0.975, self.tracks[i].name, transform=ax.transAxes, ha="center", va="top",
                        fontsize=11, fontweight="bold", color=colour, zorder=5)
        fit_title(title, self.canvas.get_renderer(), max_width=TITLE_WIDTH * w)
        label = ax.text(0.03, 0.02, "", transform=ax.transAxes, ha="left", va="bottom",
                        fontsize=7.5, color="#555555", zorder=5)
        return dict(ax=ax, grid=grid, trail=trail, bones=bones, marks=marks, label=label, title=title,
                    rgb=_rgb(colour))

    def _separators(self, w: int, h: int) -> None:
        from matplotlib.lines import Line2D   # optional extra, loaded by __init__ through require

        for c in range(1, self.columns):
            x = c * w / self.width
            self.figure.add_artist(Line2D([x, x], [0, 1], color="#dddddd", linewidth=1.0))
        for r in range(1, self.rows):
            y = r * h / self.height
            self.figure.add_artist(Line2D([0, 1], [y, y], color="#dddddd", linewidth=1.0))

    # -- per frame ---------------------------------------------------------------------------------

    def render(self, k: int) -> np.ndarray:
        """Draw output frame ``k``; returns a new (H, W, 3) uint8 RGB array."""
        self.update(k)
        self.canvas.draw()
        return np.array(self.canvas.buffer_rgba())[:, :, :3]

    def update(self, k: int) -> None:
        """Set every artist's data for output frame ``k`` (without drawing the canvas)."""
        for i, (track, panel) in enumerate(zip(self.tracks, self.panels)):
            f = int(self.schedule.frames[k, i])
            camera = self.cameras[i][k]
            joints = track.positions[f]  # (J, 3)
            xy = project(joints, camera)  # (J, 2)
            self.drawn[i][k] = xy
            self.pixels[i][k] = self._to_pixels(panel["ax"], xy)
            panel["grid"].set_segments(self._grid_segments(camera))
            self._draw_bones(panel, track, xy, depth_of(joints, camera), camera)
            self._draw_trail(panel, track, f, camera)
            self._draw_contacts(panel, track, f, xy)
            # The output clock makes every frame differ, even once all tracks hold their last frame:
            # Pillow merges identical GIF frames, which would change the frame count.
            panel["label"].set_text(f"{k / self.schedule.fps:5.2f} s   frame {f + 1}/{track.n_frames}")

    def _title_box(self, title) -> Tuple[str, Tuple[float, float, float, float]]:
        box = title.get_window_extent(renderer=self.canvas.get_renderer())
        return title.get_text(), (float(box.x0), self.height - float(box.y1), float(box.x1), self.height - float(box.y0))

    def _to_pixels(self, ax, xy: np.ndarray) -> np.ndarray:
        disp = ax.transData.transform(xy)  # display units: pixels from the bottom-left corner
        return np.stack([disp[:, 0], self.height - disp[:, 1]], axis=1)

    def _grid_segments(self, camera: Camera) -> np.ndarray:
        """(L, 2, 2) screen segments of world-aligned floor lines around the camera target."""
        tx, _, tz = camera.target
        R, s = GRID_RADIUS * self.size, self.step
        xs = s * np.arange(math.ceil((tx - R) / s), math.floor((tx + R) / s) + 1)
        zs = s * np.arange(math.ceil((tz - R) / s), math.floor((tz + R) / s) + 1)
        ends = [np.array([[x, 0.0, tz - R], [x, 0.0, tz + R]]) for x in xs]
        ends += [np.array([[tx - R, 0.0, z], [tx + R, 0.0, z]]) for z in zs]
        return project(np.stack(ends), camera) if ends else np.zeros((0, 2, 2))

    def _draw_bones(self, panel: dict, track: Track, xy: np.ndarray, depth: np.ndarray, camera: Camera) -> None:
        bones = track.bones  # (B, 2) joint, parent
        mid = 0.5 * (depth[bones[:, 0]] + depth[bones[:, 1]])
        order = np.argsort(-mid)  # far bones first: near bones are drawn over them
        far = np.clip((mid[order] - camera.distance) / (0.6 * self.size) + 0.5, 0.0, 1.0)
        colours = panel["rgb"] + (1.0 - panel["rgb"]) * (FAR_FADE * far)[:, None]
        panel["bones"].set_segments(xy[bones[order]])
        panel["bones"].set_color(colours)

    def _draw_trail(self, panel: dict, track: Track, f: int, camera: Camera) -> None:
        if not self.show_trail:
            panel["trail"].set_data([], [])
            return
        path = track.trail[: f + 1]  # (f+1, 3)
        xy = project(path, camera)
        # Only the part on the drawn floor: far-away trail points would sprawl across the panel.
        away = np.hypot(path[:, 0] - camera.target[0], path[:, 2] - camera.target[2]) > GRID_RADIUS * self.size
        xy[away] = np.nan
        panel["trail"].set_data(xy[:, 0], xy[:, 1])

    def _draw_contacts(self, panel: dict, track: Track, f: int, xy: np.ndarray) -> None:
        if not self.show_contacts or track.contacts is None:
            panel["marks"].set_data([], [])
            return
        on = track.contact_joints[track.in_contact()[f]]
        panel["marks"].set_data(xy[on, 0], xy[on, 1])
