"""A demo session recorded on the server side: the frames a character makes for scripted input.

The same :class:`~minifilm.demo.character.Character` the server steps, fed the messages a page
would send at given times (no network, no browser), so a recording shows exactly what the demo
does. ``minifilm demo --record FILE.gif`` writes one with :func:`minifilm.viewer.write_gif`
(the README's GIF).
"""
from __future__ import annotations

from pathlib import Path
from typing import Dict, List, Sequence, Tuple

import numpy as np

from minifilm.demo.calibrations import Calibrations
from minifilm.demo.character import Character, DemoSettings
from minifilm.demo.protocol import InputMessage, StyleMessage
from minifilm.demo.source import DemoSource
from minifilm.viewer import Track, write_gif


def tour(second_style: str) -> List[Tuple[float, object]]:
    """The GIF's script, (time s, message): W and E held (walk round in a circle to the right),
    and after 2.5 s a change to ``second_style`` (smoothly, over 1 s)."""
    return [(0.0, InputMessage((0.0, 1.0), 1.0, 0.0)), (2.5, StyleMessage(((second_style, 1.0),), 1.0))]


def second_style(source: DemoSource, first: str) -> str:
    """A style that looks unlike ``first``: Zombie for the released network, else the next one."""
    names = source.library.names
    if "Zombie" in names and first != "Zombie":
        return "Zombie"
    return names[(names.index(first) + 1) % len(names)]


def record_session(source: DemoSource, settings: DemoSettings, script: Sequence[Tuple[float, object]],
                   seconds: float, calibrations: Calibrations = None) -> Dict[str, np.ndarray]:
    """Step one character for ``seconds`` with the script's messages submitted at their times.

    Returns positions (F, J, 3), contacts (F, 2), roots (F, 2), facing (F, 2), speed (F,) (the
    measured m/s the page shows) and frames (the F frame messages, dicts)."""
    if calibrations is None:
        styles = [settings.style] + [n for _, m in script if isinstance(m, StyleMessage) for n, _ in m.weights]
        calibrations = Calibrations(source, first=list(dict.fromkeys(styles)), background=False)
    character = Character(0, source, calibrations, settings)
    n = int(round(seconds * source.fps))
    pending = sorted(script, key=lambda item: item[0])
    frames = []
    for k in range(n):
        while pending and pending[0][0] <= k / source.fps + 1e-9:
            character.submit(pending.pop(0)[1])
        frame, _ = character.step()
        frames.append(frame)
    J = source.layout.n_joints
    return {"positions": np.array([f["positions"] for f in frames]).reshape(n, J, 3),
            "contacts": np.array([f["contacts"] for f in frames]), "roots": np.array([f["root"] for f in frames]),
            "facing": np.array([f["facing"] for f in frames]), "speed": np.array([f["speed"] for f in frames]),
            "frames": frames}


def record_gif(source: DemoSource, settings: DemoSettings, path, seconds: float = 5.0,
               size: Tuple[int, int] = (220, 260), fps: float = 12.0) -> Path:
    """Record :func:`tour` from ``settings.style`` and write it as an animated GIF at ``path``.

    The GIF's camera looks at the middle of the circle walked (an extra joint there, with no bone,
    is the track's root), so the floor stands still and only the character changes from frame to
    frame: a camera following the walker redraws the whole floor every frame, and such a GIF of
    the same 5 s took 350 KB instead of under 200 KB."""
    other = second_style(source, settings.style)
    rec = record_session(source, settings, tour(other), seconds)
    P, roots = rec["positions"], rec["roots"]
    n, J, _ = P.shape
    centre = roots[min(n - 1, int(source.fps)):].mean(axis=0)          # after the first second's start-up
    anchor = np.tile([centre[0], 0.0, centre[1]], (n, 1, 1))
    trail = np.stack([roots[:, 0], np.zeros(n), roots[:, 1]], axis=1)
    toes = source.contact_joints()
    track = Track(f"{settings.style} -> {other}", np.concatenate([P, anchor], axis=1),
                  list(source.layout.parents) + [-1], source.fps,
                  contacts=np.clip(rec["contacts"], 0.0, 1.0) if toes else None, contact_joints=toes or None,
                  trail=trail, root=J, joint_names=list(source.layout.joint_names) + ["(camera)"])
    write_gif(track, path, fps=fps, size=size)
    return Path(path)
