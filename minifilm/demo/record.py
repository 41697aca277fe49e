"""Recording the demo: a scripted session on the server side, and the page's "record" button.

1. :func:`record_session` / :func:`record_gif`: the same :class:`~minifilm.demo.character.Character`
   the server steps, fed the messages a page would send at given times (no network, no browser),
   so a recording shows exactly what the demo does. ``minifilm demo --record FILE.gif`` writes one
   with :func:`minifilm.viewer.write_gif` (the README's GIF).
2. The page's record button: every frame a page's character shows is kept for the last
   ``MAX_RECORD_SECONDS`` (:class:`FrameHistory`, filled by the server after each frame), and the
   page's ``{"type": "record", "seconds": s, "gif": true}`` is answered by :func:`answer_record`
   with ``{"type": "recording", "seq", "seconds", "frames", "fps", "bvh": text, "gif": bool}``:
   the last ``s`` seconds as BVH on the source skeleton (the joints' predicted positions and axes
   put back on it as ``minifilm generate`` does), at once; then, when a GIF was asked for,
   ``{"type": "recordingGif", "seq", "gif": base64 or null, "note"}``: that BVH drawn by
   ``minifilm view`` in a process of its own (tens of seconds on a busy machine) when matplotlib
   and Pillow are installed on the server, else null and the note says why.
"""
from __future__ import annotations

import base64
import math
import os
import subprocess
import sys
import tempfile
import threading
from pathlib import Path
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np

from minifilm.demo.calibrations import Calibrations
from minifilm.demo.character import Character, DemoSettings
from minifilm.demo.protocol import MAX_RECORD_SECONDS, InputMessage, RecordMessage, StyleMessage, encode, error  # noqa: F401 (RecordMessage: the server's and the tests' name for it here)
from minifilm.demo.source import DemoSource
from minifilm.files import file_name
from minifilm.viewer import Track, write_gif
from minifilm.motion.bvh_write import format_bvh
from minifilm.motion.retarget import axes_to_rotation, retarget
from minifilm.motion.skeletons import STYLE100
from minifilm.runtime.start_state import root_joint_indices
from minifilm.viewer.deps import check_output_tools


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


# ---------------------------------------------------------------------------------------------
# The page's record button
# ---------------------------------------------------------------------------------------------

#: The longest stretch a page may ask for is protocol.MAX_RECORD_SECONDS (every character keeps it).
#: A root moving further than this in one frame is a reset: the history starts again there.
JUMP_METRES = 1.0
GIF_FPS = 15.0
GIF_TIMEOUT = 180.0      # seconds the GIF may take before the page gets the BVH alone


class FrameHistory:
    """The last ``seconds`` of one character's shown frames (a ring buffer): world joint positions,
    forward and up axes (F, J, 3) and foot contacts (F, 2). :meth:`capture` runs on the frame
    loop's thread after each frame, :meth:`last` on any other."""

    def __init__(self, n_joints: int, fps: float, seconds: float = MAX_RECORD_SECONDS):
        self.fps, self.size = float(fps), max(2, int(round(seconds * fps)))
        self.pos, self.fwd, self.up = (np.zeros((self.size, n_joints, 3)) for _ in range(3))
        self.contacts = np.zeros((self.size, 2))
        self.count = 0
        self.busy = False               # a recording is being made for this page
        self._root = None
        self._lock = threading.Lock()

    def capture(self, state) -> None:
        """Keep character 0 of a Controller state (``out_pos``, ``out_fwd``, ``out_up``, ``contacts``, ``root``)."""
        root = np.asarray(state.root[0], dtype=np.float64)
        with self._lock:
            if self._root is not None and not np.hypot(*(root - self._root)) <= JUMP_METRES:
                self.count = 0          # reset (or a NaN the guard will undo): nothing before it is kept
            self._root = root.copy()
            i = self.count % self.size
            self.pos[i], self.fwd[i], self.up[i] = state.out_pos[0], state.out_fwd[0], state.out_up[0]
            self.contacts[i] = state.contacts[0]
            self.count += 1

    def last(self, seconds: float) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Copies, oldest first, of the last ``seconds`` (or as many frames as there are)."""
        with self._lock:
            n = min(self.count, self.size, max(1, int(round(seconds * self.fps))))
            idx = np.arange(self.count - n, self.count) % self.size
            return self.pos[idx].copy(), self.fwd[idx].copy(), self.up[idx].copy(), self.contacts[idx].copy()


def recording_motion(source: DemoSource, positions: np.ndarray, forward: np.ndarray, up: np.ndarray):
    """The frames (F, J, 3) as a Motion on the source skeleton, as ``minifilm generate`` writes it."""
    joints = root_joint_indices(source.layout, source.skeleton)
    return retarget(positions, axes_to_rotation(forward, up), source.skeleton, joints, frame_time=1.0 / source.fps)


def bvh_scale(source: DemoSource) -> float:
    """Metres per BVH unit of the source's skeleton: the released network's 100STYLE skeleton, else cm."""
    if source.params is not None:
        return STYLE100.bvh_scale
    return 0.01


def answer_record(source: DemoSource, history: FrameHistory, message: RecordMessage, title: str = "demo",
                  send: Callable[[str], None] = None) -> List[str]:
    """The answers to ``message``: the ``recording`` message (or an ``error`` one naming what went
    wrong), then ``recordingGif`` if a GIF was asked for. Each is handed to ``send`` as soon as it
    is ready (if given) and all are returned. Never raises: it runs beside the server for one page.
    Slow (the BVH fit, the GIF): call it off the event loop."""
    out = []

    def answer(text: str) -> None:
        out.append(text)
        if send is not None:
            send(text)
    try:
        P, F, U, C = history.last(message.seconds)
        if len(P) < 2:
            answer(error("record: nothing to record yet (the character has shown fewer than two frames)", message.seq))
            return out
        bvh = format_bvh(recording_motion(source, P, F, U), scale=bvh_scale(source))
        answer(encode({"type": "recording", "seq": message.seq, "seconds": round(len(P) / source.fps, 4),
                       "frames": len(P), "fps": source.fps, "bvh": bvh, "gif": message.gif}))
        if message.gif:
            gif, note = _gif(bvh, source.fps, title)
            answer(encode({"type": "recordingGif", "seq": message.seq, "gif": gif, "note": note}))
    except Exception as e:  # noqa: BLE001 - a failed recording is the page's error, never the server's
        answer(error(f"record: failed ({type(e).__name__}: {e})", message.seq))
    return out


def _gif(bvh: str, fps: float, title: str) -> Tuple[Optional[str], str]:
    """(base64 GIF of the recorded BVH, "") or (None, why not). Drawn by ``minifilm view`` in a
    process of its own at a lower priority: drawn in the server's process, a 10 s GIF held the
    interpreter lock for most of 18 s and the frame loop fell to 39 frames a second."""
    with tempfile.TemporaryDirectory(prefix="minifilm-record-") as folder:
        path, source_bvh = Path(folder) / "recording.gif", Path(folder) / f"{_file_name(title)}.bvh"
        try:
            check_output_tools(path, "gif")
        except ImportError as e:
            return None, f"BVH only: no GIF without matplotlib and Pillow on the server ({e})"
        source_bvh.write_text(bvh, encoding="utf-8")
        every = max(1, int(math.floor(fps / GIF_FPS)))
        # The priority is lowered once the process exists, not in it before it runs (preexec_fn):
        # Python code between fork and exec can deadlock in a process with threads, as this one is.
        with subprocess.Popen([sys.executable, "-m", "minifilm", "view", str(source_bvh), "--gif", str(path),
                               "--every", str(every), "--size", "220", "280"], stdin=subprocess.DEVNULL,
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True) as drawing:
            try:
                os.setpriority(os.PRIO_PROCESS, drawing.pid, 10)
            except (AttributeError, OSError):     # no setpriority here, or it has ended already
                pass
            try:
                _, err = drawing.communicate(timeout=GIF_TIMEOUT)
            except subprocess.TimeoutExpired:
                drawing.kill()
                return None, f"BVH only: the GIF took more than {GIF_TIMEOUT:g} s"
        if drawing.returncode != 0 or not path.is_file():
            why = (err.strip().splitlines() or ["no message"])[-1]
            return None, f"BVH only: the GIF could not be made ({why[:200]})"
        return base64.b64encode(path.read_bytes()).decode("ascii"), ""


def _file_name(title: str) -> str:
    """The recorded BVH's file name, from the page's title, made safe by the one rule of names."""
    return file_name(title.strip()[:40]) if title.strip() else "recording"
