"""One page's character: a batch-1 runtime Controller steered by what the page holds.

Per frame (:meth:`Character.step`, called by the stage's frame loop, never by the network thread):

1. the page's messages that arrived since the last frame are applied in order (held input, style
   change, settings, reset); the page's thread only appends them to a queue;
2. the steering turns the heading and gives the target facing and velocity (m/s);
3. the velocity goes through the style's speed calibration (released network) and the style mix
   advances (smoothstep transitions);
4. :meth:`Controller.step` (Sec. 4.4) makes the frame, with the skeleton fit and foot locking as
   toggled;
5. the guard: if anything in the new state is not finite, or the body has flown apart (a joint
   more than ``MAX_REACH`` metres from the root), or the step raised, the character is reset where
   it last stood and the page is told. The network's output never reaches the page unchecked.
"""
from __future__ import annotations

import collections
import math
import time
import traceback
from dataclasses import dataclass
from typing import Callable, List, Optional, Tuple

import numpy as np

from minifilm.demo.calibrations import Calibrations
from minifilm.demo.paths import frame_paths
from minifilm.demo.protocol import InputMessage, ResetMessage, SettingsMessage, StyleMessage, weights_dict
from minifilm.demo.source import DemoSource
from minifilm.demo.steering import Steering, heading_vector
from minifilm.demo.style_mix import StyleMix
from minifilm.runtime.controller import Controller
from minifilm.runtime.held_body import foot_locker

MAX_REACH = 20.0          # metres from the root: further means the network's output blew up
SPEED_WINDOW = 0.25       # seconds over which the shown actual speed is measured
#: a command is scaled to this share of the fastest the style was measured to go (its speed
#: calibration), so what is asked can be reached: Shift drives the style at its top. (The released
#: network's Neutral runs at most 1.8 m/s in the loop, about 87 % of the 2.06 m/s it reaches when
#: shown a perfect run trajectory, and 2.5 m/s is 3.4 standard deviations out in its training
#: rows: benchmarks/run_speed.py, reports/2026-12-04_released_run_speed.md.)
REACHABLE = 1.0
#: seconds over which Shift's run feed (``Controller.run_feed``) is blended in and out
RUN_BLEND = 0.3


class RateCounter:
    """Events (frames sent to a page) in the last second; ``tick()`` from one thread, ``rate()``
    from another (deque appends and pops are atomic in CPython)."""

    def __init__(self, window: float = 1.0):
        self.window = window
        self.times = collections.deque(maxlen=1000)

    def tick(self) -> None:
        self.times.append(time.monotonic())

    def rate(self) -> Optional[float]:
        """Events in the last second; None until a second has passed since the first one."""
        now = time.monotonic()
        times = list(self.times)
        if not times or now - times[0] < self.window:
            return None
        return float(sum(1 for t in times if now - t <= self.window))


@dataclass
class DemoSettings:
    """What every new character starts with, and how the user's input maps to speeds."""

    style: str
    walk_speed: float = 1.3
    run_speed: float = 2.8
    turn_rate_deg: float = 120.0
    foot_lock: bool = False
    fit: bool = True

    def __post_init__(self):
        if not self.run_speed >= self.walk_speed:
            raise ValueError(f"the running speed (--run-speed {self.run_speed:g} m/s) must be at least the "
                             f"walking speed (--walk-speed {self.walk_speed:g} m/s): Shift runs faster, not slower")


class Character:
    """A character of the stage, identified by ``ident``; see the module docstring."""

    def __init__(self, ident: int, source: DemoSource, calibrations: Calibrations, settings: DemoSettings):
        self.ident, self.source, self.calibrations = ident, source, calibrations
        self.body = Controller.skeleton_for(source.layout, source.skeleton)
        self.ctrl = Controller(source.network, source.layout, fps=source.fps, **source.options)
        self.steering = Steering(settings.walk_speed, settings.run_speed, math.radians(settings.turn_rate_deg))
        self.mix = StyleMix(source.library, {settings.style: 1.0})
        self.dt = 1.0 / source.fps
        self.pending = collections.deque(maxlen=1024)   # appended by the network thread only
        self.frame_no, self.ack = 0, None
        self.failures = 0
        # called with the Controller's state after every network step, batched or not (the server's
        # record history keeps each one: a recording must hold every step, not every frame sent)
        self.on_step: Optional[Callable] = None
        self.step_ms = 0.0           # the Controller's own time for the last frame
        self.commanded = 0.0             # m/s, what the held keys ask for
        self.reachable = 0.0             # m/s, that scaled to what the style can do (the character is steered at it)
        self.max_speed: Optional[float] = None    # m/s, the fastest the mix goes this way (calibration)
        self.speed_note: Optional[str] = None
        self.velocity = np.zeros(2)
        self.steered = np.zeros(2)       # m/s, the velocity the character is steered at (reachable)
        self.sent = RateCounter()        # frames the server actually sent to the page (server.py ticks it)
        self.input_ms: Optional[float] = None     # input -> frame latency of the last held-input change
        self._input_at: Optional[Tuple[int, float]] = None
        self._roots = collections.deque(maxlen=max(2, int(round(SPEED_WINDOW * source.fps)) + 1))
        self._timed_roots = collections.deque(maxlen=4 * int(round(SPEED_WINDOW * source.fps)) + 2)  # (time, root) per batch
        self.run_feed = 0.0              # weight of Shift's perfect run in the trajectory input
        self.set_fit(settings.fit)
        self.set_foot_lock(settings.foot_lock)
        self.reset()

    # ---- settings ---------------------------------------------------------------------------
    def set_fit(self, on: bool) -> None:
        """Put every frame on the source skeleton (and feed it back, for the released network)."""
        self.fit = bool(on)
        self.ctrl.skeleton = self.body if self.fit else None
        self.ctrl.feed_back_fit = self.fit and self.source.feed_back_fit

    def set_foot_lock(self, on: bool) -> None:
        """Foot locking on or off; it stays off on a skeleton whose toes are not found (the frames'
        ``footLock`` says so)."""
        self.ctrl.foot_locker = foot_locker(self.source.layout) if on else None
        self.foot_lock = self.ctrl.foot_locker is not None

    def reset(self, where: Optional[np.ndarray] = None, theta: float = 0.0) -> None:
        """Stand still at ``where`` (2,) (default the origin) facing heading ``theta``, in the start
        frame of the style that dominates the mix (the data's mean pose if it has none)."""
        where = np.zeros(2) if where is None else np.asarray(where, dtype=np.float64)
        x, p = self.source.starts.get(self.mix.dominant()[0], (None, None))
        self.ctrl.reset(where[None], heading_vector(theta)[None], phases=None if p is None else p[None], start_x=x)
        self.steering.reset(theta)
        self.run_feed = 0.0
        self.ctrl.run_feed = None
        self._roots.clear()
        self._timed_roots.clear()

    # ---- input ------------------------------------------------------------------------------
    def submit(self, message) -> None:
        """Queue a validated page message for the next frame (any thread)."""
        if isinstance(message, InputMessage) and message.seq is not None:
            self._input_at = (message.seq, time.monotonic())
        self.pending.append(message)

    def _apply(self, message) -> None:
        if isinstance(message, InputMessage):
            self.steering.hold(message.move, message.turn, message.speed)
        elif isinstance(message, StyleMessage):
            weights = dict(message.weights)
            self.mix.change(weights, message.seconds)
            self.calibrations.request(self.calibrations.needed(weights))
        elif isinstance(message, SettingsMessage):
            if message.fit is not None:
                self.set_fit(message.fit)
            if message.foot_lock is not None:
                self.set_foot_lock(message.foot_lock)
        elif isinstance(message, ResetMessage):
            self.reset()
        if message.seq is not None:
            self.ack = message.seq

    # ---- one frame --------------------------------------------------------------------------
    def step(self, steps: int = 1, now: Optional[float] = None) -> Tuple[dict, List[str]]:
        """Advance ``steps`` frames (a batch when the frame loop is behind the clock); returns the
        last one's frame message (a dict, see :meth:`frame_message`) and the notices for the page
        (empty unless the guard reset the character). ``now``: the wall time (seconds, monotonic)
        the stage ran the batch at, so the speed read-out is in metres per real second (None:
        per simulated second, e.g. a recording made faster than real time)."""
        notices: List[str] = []
        for _ in range(max(1, int(steps))):
            notices += self._advance()
        when = self.frame_no * self.dt if now is None else float(now)
        self._timed_roots.append((when, self.ctrl.state.root[0].copy()))
        return self.frame_message(self.mix.weights), notices

    def _advance(self) -> List[str]:
        """One network step: the page's messages applied, the steering and the style mix advanced,
        the Controller's frame made and checked. Returns the notices."""
        while self.pending:
            self._apply(self.pending.popleft())
        notices = []
        facing, velocity, self.commanded = self.steering.advance(self.dt)
        self.velocity = velocity
        film = self.mix.advance(self.dt)
        weights = self.mix.weights
        velocity = self.steered = self._reachable(velocity, facing, weights)
        self._feed_run(weights)
        pressed = self._input_at
        if pressed is not None and self.ack is not None and self.ack >= pressed[0]:
            self.input_ms, self._input_at = 1e3 * (time.monotonic() - pressed[1]), None
        try:
            command = self.calibrations.command(velocity, facing, weights)
            t0 = time.perf_counter()
            with np.errstate(all="ignore"):    # overflow is caught by the guard below, not warned
                self.ctrl.step(facing[None], command[None], film)
            self.step_ms = 1e3 * (time.perf_counter() - t0)
            problem = self._check()
        except Exception as e:  # noqa: BLE001 - a failed frame resets this character, the loop goes on
            problem = f"the frame failed ({type(e).__name__}: {e})"
            self.failures += 1
            if self.failures <= 3:         # the first few in full; a repeating failure must not flood the log
                traceback.print_exc()
        if problem:
            self._recover()
            notices.append(f"{problem}: the character was reset where it stood")
        self.frame_no += 1
        self._roots.append(self.ctrl.state.root[0].copy())
        if self.on_step is not None:
            self.on_step(self.ctrl.state)
        return notices

    def _feed_run(self, weights) -> None:
        """Shift held while moving: blend in a perfect run as the network's trajectory input (the
        released network runs only when shown one: its own past says "walking", and it walks at
        1.8 m/s at most; shown a run, Neutral runs at 2.07 m/s with flight phases,
        benchmarks/run_speed.py). The speed is the network's own for the style, the note says so."""
        speed = self.source.run_feed_speed
        if not speed:
            return
        running = self.steering.speed >= 0.5 and self.commanded > 1e-6
        self.run_feed = min(1.0, max(0.0, self.run_feed + (1 if running else -1) * self.dt / RUN_BLEND))
        self.ctrl.run_feed = np.array([self.run_feed]) if self.run_feed > 0 else None
        self.ctrl.run_feed_speed = speed
        if running:
            name = " + ".join(n for n, w in sorted(weights.items(), key=lambda nw: -nw[1]) if w > 0.01)
            top = "" if self.max_speed is None else f"; walking it goes at most {self.max_speed:.2f} m/s"
            self.speed_note = (f"Shift: {name} runs at this network's own running pace for it (the speed "
                               f"shown); it cannot run faster: no command, nor a faster run shown to it, makes it "
                               f"(measured: reports/2026-12-04_released_run_speed.md){top}")

    def _reachable(self, velocity: np.ndarray, facing: np.ndarray, weights) -> np.ndarray:
        """The held velocity, scaled down to ``REACHABLE`` of the fastest the mix was measured to go
        in that direction (when known); sets ``reachable``, ``max_speed`` and ``speed_note``."""
        speed = float(math.hypot(velocity[0], velocity[1]))
        self.reachable, self.speed_note = speed, None
        if speed < 1e-9:
            return velocity
        cos = float(velocity @ facing) / max(speed, 1e-9)
        direction = math.degrees(math.acos(min(1.0, max(-1.0, cos))))
        top = self.calibrations.max_speed(weights, direction) if self.calibrations.enabled else None
        self.max_speed = top
        if top is None or speed <= REACHABLE * top:
            return velocity
        self.reachable = REACHABLE * top
        name = " + ".join(n for n, w in sorted(weights.items(), key=lambda nw: -nw[1]) if w > 0.01)
        self.speed_note = (f"{name} goes at most {top:.2f} m/s this way: that is as fast as this network "
                           f"runs it (measured, see reports/2026-12-04_released_run_speed.md), so the {speed:.2f} m/s "
                           f"asked for is driven at {self.reachable:.2f}")
        return velocity * (self.reachable / speed)

    def _check(self) -> Optional[str]:
        st = self.ctrl.state
        arrays = (st.out_pos, st.out_fwd, st.out_up, st.joint_pos, st.joint_fwd, st.joint_up, st.joint_vel,
                  st.root, st.facing, st.phases, st.contacts, st.future_pos, st.future_dir)
        if not all(np.all(np.isfinite(a)) for a in arrays):
            return "the network's output became non-finite"
        # what is shown and what the next input is built from (they differ when the fit is not fed back)
        reach = max(np.abs(pos[0][:, [0, 2]] - st.root[0]).max() for pos in (st.out_pos, st.joint_pos))
        if reach > MAX_REACH:
            return f"the network's output flew apart (a joint {reach:.0f} m from the root)"
        return None

    def _recover(self) -> None:
        """Reset where the character last stood (its last finite root), facing its heading, with
        the keys the user holds still held."""
        where = self._roots[-1] if self._roots else np.zeros(2)
        held = self.steering.move, self.steering.turn, self.steering.speed
        self.reset(where, self.steering.theta)
        self.steering.hold(*held)

    def actual_speed(self) -> float:
        """Mean root speed (m/s) over the last ``SPEED_WINDOW`` seconds or more of the times
        :meth:`step` was given (wall time in the demo: metres per real second, however many steps
        the loop managed); before that much has passed, over the frames' own time."""
        timed = list(self._timed_roots)
        if len(timed) >= 2:
            t_end, end = timed[-1]
            start = next(((t, r) for t, r in reversed(timed[:-1]) if t_end - t >= SPEED_WINDOW), None)
            if start is not None:
                d = end - start[1]
                return math.hypot(d[0], d[1]) / (t_end - start[0])
        if len(self._roots) < 2:
            return 0.0
        d = self._roots[-1] - self._roots[0]
        return math.hypot(d[0], d[1]) / ((len(self._roots) - 1) * self.dt)

    def frame_message(self, weights=None) -> dict:
        """What the page draws: joint positions (J*3, metres, world, y up), contacts [right, left],
        phases (8: amplitude * (sin, cos) for left hand, right hand, left foot, right foot), root
        and facing (x, z), the heading steered, the commanded velocity and speed (m/s, before
        calibration: what the keys ask), ``reachable`` (that speed scaled to what the mix can do,
        the speed the character is steered at), ``maxSpeed`` (the fastest the mix was measured to
        go that way) and ``speedNote`` (says so when the command was scaled), the measured speed (``speed``: the character's own root
        over the last quarter second of wall time, metres per real second), ``sentFps`` (frames the server actually sent this page in
        the last second; None during the first), ``inputMs`` (from the server receiving the last
        input message to the frame that applied it; None before any), ``calibration`` (the speed
        calibration's progress, :meth:`Calibrations.progress`), the style mix now (``weights``, default the mix's) and
        its target and the fingerprint of its FiLM vector
        (:func:`~minifilm.demo.style_mix.film_digest`), the network's predicted trajectory and the
        held input's path (``future``, ``futureFacing``, ``path``: :mod:`minifilm.demo.paths`), the
        toggles, and the Controller's step time (ms; the stage adds ``frameMs``, the whole batch's,
        ``t``, and how the loop keeps up with the clock: ``steps`` in this batch, ``behind``,
        ``dropped`` and ``stepsPerSecond``, see ``frame_loop.py``)."""
        st = self.ctrl.state
        mix = self.mix.weights if weights is None else weights
        # every number of the frame rounded in one pass (0.1 mm, 1e-4 of a phase), then cut up
        numbers = np.round(np.concatenate([st.out_pos[0].reshape(-1), st.contacts[0], st.phases[0], st.root[0],
                                           st.facing[0], heading_vector(self.steering.theta), self.velocity]),
                           4).tolist()
        a = 3 * len(st.out_pos[0])
        cut = dict(positions=(0, a), contacts=(a, a + 2), phases=(a + 2, a + 10), root=(a + 10, a + 12),
                   facing=(a + 12, a + 14), heading=(a + 14, a + 16), velocity=(a + 16, a + 18))
        frame = {"type": "frame", "n": self.frame_no, "ack": self.ack}
        frame.update({key: numbers[i:j] for key, (i, j) in cut.items()})
        sent = self.sent.rate()
        frame.update({
            "commanded": round(self.commanded, 4), "speed": round(self.actual_speed(), 4),
            "reachable": round(self.reachable, 4),
            "maxSpeed": None if self.max_speed is None else round(self.max_speed, 3), "speedNote": self.speed_note,
            "sentFps": sent, "inputMs": None if self.input_ms is None else round(self.input_ms, 1),
            "calibration": self.calibrations.progress(),
            "weights": weights_dict(mix.items()), "target": weights_dict(self.mix.target.items()),
            "film": self.mix.digest, "footLock": self.foot_lock, "fit": self.fit, "stepMs": round(self.step_ms, 4),
            "calibrated": (not self.calibrations.enabled) or all(self.calibrations.has(n)
                                                                for n in self.calibrations.needed(mix)),
        })
        frame.update(frame_paths(self))       # the predicted trajectory and the held input's path (paths.py)
        return frame
