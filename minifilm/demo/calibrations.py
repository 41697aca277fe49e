"""Speed calibration per style for the live demo, measured in the frame loop's idle time.

The released network needs one (:func:`minifilm.runtime.calibration.calibrate_speed`: commanding
1.3 m/s makes it walk at about 0.5 m/s), and so does a run trained here (train_small's Drunk walks
0.68 m/s at 1.3 m/s commanded, its PendulumHands 2.36; measured with the commands its data holds,
``source.calibration_commands``). Measuring one for the released network takes about 2.4 s of
CPU (27 characters for 8 s of frames: 481 steps of one batch, about 5 ms each). So nothing is
measured before the server listens (it serves its page within a second or two): calibrations come
from the package (the released network's) or the cache of earlier runs (``calibration_cache.py``,
keyed by a hash of the network and of each style; a run's styles are measured at its first
start, about a second each), and the missing
ones, the start style first, any other style the first time a page asks for it, are measured one
batch step at a time (:func:`~minifilm.runtime.calibration.calibrate_speed_stepwise`) by the
frame loop, in the time left before the next frame is due (:meth:`run_slice`, called by
``frame_loop.py`` only when the slice is expected to end before the deadline). A measurement
cannot hold a frame up by more than one slice that took longer than expected: in a
worker process at low priority (the earlier design) it shared the cores with the frame loop, and
on a busy 2-core machine the frame interval's 95th percentile doubled while one ran
(``benchmarks/demo_realtime.py --only calibration``). The price: on a busy machine few slices fit
and a measurement takes minutes instead of seconds (4-8 s on an idle one). Each one measured is printed in the
terminal, added to the cache, and counted in :meth:`Calibrations.progress` (sent to the pages in
every frame). Until a style's calibration is there, another style's stands in for it (the first
one there), and before any is there the speed is commanded as asked (the network then walks
slower than asked; the frames say ``calibrated: false``).

A mix of styles is commanded with the mix of their commands, ``sum_s w_s command_s(speed)``, the
same linear mixing the FiLM vectors get. Only the styles of a mix with at least
``MEASURED_WEIGHT`` of it are measured for it (heaviest first): a style with a few per cent of a
blend moves its command by a few per cent, and a blend of all 100 styles would otherwise queue
100 measurements (ten minutes and more). The terminal is told how many styles are queued and
about how long they take at the pace measured so far.
"""
from __future__ import annotations

import collections
import math
import sys
import threading
import time
from typing import Dict, Generator, Mapping, Optional, Sequence

import numpy as np

from minifilm.demo.calibration_cache import CalibrationCache, max_speed
from minifilm.runtime.calibration import SpeedCalibration, calibrate_speed, calibrate_speed_stepwise
from minifilm.runtime.controller import Controller

#: a style with less of a mix than this is not measured for it (a stand-in's calibration serves)
MEASURED_WEIGHT = 0.1
#: seconds one style's measurement is assumed to take before any has been timed (2.4 s of CPU in
#: slices of the frames' idle time: one or two 5 ms slices per 16.7 ms frame)
FIRST_PACE = 10.0


def _start_of(source, name: str):
    """A new Controller for ``source`` and the style's start frame (x, p) (None, None: the mean)."""
    ctrl = Controller(source.network, source.layout, fps=source.fps, **source.options)
    x, p = source.starts.get(name, (None, None))
    return ctrl, x, p


def measure(source, name: str) -> SpeedCalibration:
    """The SpeedCalibration of style ``name`` of a :class:`~minifilm.demo.source.DemoSource`, all at
    once (the plain version: tests, ``--record``)."""
    ctrl, x, p = _start_of(source, name)
    return calibrate_speed(ctrl, source.library[name], commands=source.calibration_commands, phases=p, start_x=x)


def measure_steps(source, name: str) -> Generator[None, None, SpeedCalibration]:
    """:func:`measure` one slice per ``next()``: the Controller made and reset, then one batch step
    each; returns the same SpeedCalibration (tested equal)."""
    ctrl, x, p = _start_of(source, name)
    yield
    return (yield from calibrate_speed_stepwise(ctrl, source.library[name], commands=source.calibration_commands,
                                                phases=p, start_x=x))



def estimate(seconds: float) -> str:
    """How long, said plainly: "20 s", "3 min"."""
    if seconds < 90:
        return f"{max(5, int(round(seconds / 5.0)) * 5)} s"
    return f"{int(round(seconds / 60.0))} min"


def say(text: str) -> None:
    """A line on stderr in one write: this runs on the measuring thread while the command prints
    on its own, and print's separate write of the newline let two lines run into one."""
    sys.stderr.write(text + "\n")
    sys.stderr.flush()


class Calibrations:
    """Calibrations by style name; ``command`` maps a user's velocity to the network's command.

    Args:
        source: a DemoSource; when ``source.calibrate`` is False, velocities pass unchanged.
        first: the styles measured first (the start style).
        background: measure ``first`` and the styles asked for later in slices, by whoever calls
            :meth:`run_slice` (the frame loop; ``on_request`` is called when there is work);
            False: measure ``first`` here and now and use the first style's calibration for
            every other style.
        clock: seconds, monotonic (the pace in the terminal's estimates).
        begin: with ``background``, start at once (False: at :meth:`begin`; the server begins
            once it listens, so a port in use is the only thing said).
    """

    def __init__(self, source, first: Sequence[str] = (), background: bool = True,
                 cache: Optional[CalibrationCache] = None, log=None, clock=time.monotonic, begin: bool = True):
        self.source = source
        self.enabled = bool(source.calibrate)
        self._cal: Dict[str, SpeedCalibration] = {}
        self._memo: Dict[tuple, float] = {}      # (speed, direction, mix) -> command / speed
        self._asked = set()
        self._lock = threading.RLock()
        self._queue = collections.deque()   # styles asked for, not measured yet, in order
        self._job = None                    # (name, its measure_steps generator) in hand
        self.on_request = None              # called (no arguments) when there is work to slice
        self._clock = clock
        self._background = background
        self.fallback: Optional[SpeedCalibration] = None
        self._closed = False
        self._log = log if log is not None else say
        self.cache = cache
        self.measured = 0                   # styles measured by this server (not from the cache)
        self.requested = 0                  # styles asked to be measured
        self.measuring: Optional[str] = None
        self._started: Dict[str, float] = {}
        self._paces = []                    # seconds each measurement took (the estimate's pace)
        if not self.enabled:
            return
        if self._background:
            self.requested = len(first)      # counted until the cache says what is left
            self._first, self._begun = list(first), False
            if begin:
                self.begin()
            return
        self._load_cache(first)
        for name in first:          # measured here and now (tests, --record)
            if name not in self._cal:
                self._cal[name] = measure(source, name)
                self._store(name, self._cal[name])
        if first and self.fallback is None:
            self.fallback = self._cal[first[0]]

    def begin(self) -> None:
        """Start the background work (once): the cache is read (its name hashes the network's
        files) and the start style asked for on a thread of their own, the pages served meanwhile."""
        with self._lock:
            if not self.enabled or not self._background or self._begun:
                return
            self._begun = True
        threading.Thread(target=self._start, args=(self._first,), name="minifilm-demo-calibrate", daemon=True).start()

    def _load_cache(self, first) -> None:
        if self.cache is not None:
            cached = self.cache.load()      # only entries whose style is unchanged (its vector's digest)
            with self._lock:
                self._cal.update(cached)
                self._memo.clear()
        with self._lock:
            if self._cal and self.fallback is None:
                self.fallback = self._cal.get(first[0]) if first and first[0] in self._cal \
                    else next(iter(self._cal.values()))

    def _start(self, first) -> None:
        try:
            self._load_cache(first)
        finally:
            with self._lock:
                self.requested -= len(first)
        self.request(first)

    def progress(self) -> dict:
        """What the pages are told: ``state`` ("off", "measuring" or "done"), styles measured of
        those asked for, the style being measured, and how many styles are known (cache included)."""
        with self._lock:
            if not self.enabled:
                return {"state": "off"}
            pending = self.requested - self.measured
            return {"state": "measuring" if pending > 0 else "done", "done": self.measured,
                    "total": self.requested, "measuring": self.measuring, "known": len(self._cal)}

    def max_speed(self, weights: Mapping[str, float], direction: float = 0.0) -> Optional[float]:
        """The fastest a mix can go in ``direction`` (degrees from the facing), m/s, from the
        calibrations measured (the mix of its styles' fastest); None when not known yet."""
        with self._lock:
            tops = []
            for name, w in weights.items():
                cal = self._cal.get(name, self.fallback)
                if cal is None:
                    return None
                tops.append(w * max_speed(cal, direction))
        return float(sum(tops))

    @staticmethod
    def needed(weights: Mapping[str, float]):
        """The styles of a mix worth measuring for it: at least ``MEASURED_WEIGHT``, heaviest first
        (the mix's heaviest style whatever its weight)."""
        ranked = sorted(weights.items(), key=lambda nw: -nw[1])
        return [n for i, (n, w) in enumerate(ranked) if w >= MEASURED_WEIGHT or i == 0]

    def has(self, name: str) -> bool:
        with self._lock:
            return name in self._cal

    def request(self, names) -> None:
        """Queue every style of ``names`` not measured or asked for yet; returns at once (the
        frame loop calls it: the measuring is done by :meth:`run_slice`)."""
        if not (self.enabled and self._background):
            return
        with self._lock:
            if self._closed:
                return
            todo = [n for n in dict.fromkeys(names) if n not in self._cal and n not in self._asked]
            self._asked.update(todo)
            self.requested += len(todo)
            self._queue.extend(todo)
            queued = self.requested - self.measured
            pace = sum(self._paces) / len(self._paces) if self._paces else FIRST_PACE
            wake = self.on_request
        if not todo:
            return
        if wake is not None:
            wake()
        shown = ", ".join(todo[:5]) + (f" and {len(todo) - 5} more" if len(todo) > 5 else "")
        self._log(f"minifilm demo: measuring the speed calibration of {shown} in the background "
                  f"({queued} style(s) queued, about {estimate(queued * pace)}"
                  f"{' at the pace so far' if self._paces else ''}; the page works meanwhile)")

    def pending(self) -> bool:
        """Whether a measurement is in hand or queued (the frame loop then has slices to run)."""
        with self._lock:
            return not self._closed and (self._job is not None or bool(self._queue))

    def run_slice(self) -> None:
        """One slice of the measurement in hand (about 5 ms: one network step of its batch), or the
        start of the next queued style's (its Controller made and reset). Called by one thread,
        the frame loop's, when the next frame leaves room for it."""
        with self._lock:
            if self._closed:
                return
            if self._job is None:
                while self._queue and self._queue[0] in self._cal:   # the cache had it after all
                    self._queue.popleft()
                    self.requested -= 1
                if not self._queue:
                    return
                name = self._queue.popleft()
                self._job = (name, measure_steps(self.source, name))
                self.measuring = name
                self._started[name] = self._clock()
            name, steps = self._job
        try:
            next(steps)
        except StopIteration as finished:
            self._job = None
            self._done(name, finished.value)
        except Exception as e:  # noqa: BLE001 - a failed measurement keeps the stand-in, says why
            self._job = None
            with self._lock:
                self.measured += 1
                self.measuring = None
            self._log(f"minifilm demo: speed calibration of {name!r} failed ({e}); another style's is used for it")

    def _done(self, name: str, cal: SpeedCalibration) -> None:
        with self._lock:
            if self._closed:
                return
            self._cal[name] = cal
            if self.fallback is None:
                self.fallback = cal
            self._memo.clear()
            self.measured += 1
            waited = self._clock() - self._started.pop(name, self._clock())
            if waited > 0:
                self._paces = (self._paces + [waited])[-5:]
            self.measuring = None
            done, total = self.measured, self.requested
        self._store(name, cal)
        self._log(f"minifilm demo: speed calibration of {name} measured ({done} of {total}"
                  f"{f', {waited:.0f} s' if waited >= 1 else ''})")

    def _store(self, name: str, cal: SpeedCalibration) -> None:
        if self.cache is not None and not self._closed:
            self.cache.put(name, cal)

    def command(self, velocity: np.ndarray, facing: np.ndarray, weights: Mapping[str, float]) -> np.ndarray:
        """The network's command (2,) for the user's target velocity (2,) m/s while facing (2,),
        for the mix ``weights`` (name -> w summing to 1)."""
        v = np.asarray(velocity, dtype=np.float64)
        speed = math.hypot(v[0], v[1])
        if not self.enabled or speed < 1e-9:
            return v
        cos = (v[0] * facing[0] + v[1] * facing[1]) / max(speed * math.hypot(facing[0], facing[1]), 1e-9)
        direction = math.degrees(math.acos(min(1.0, max(-1.0, cos))))
        # the same held keys ask the same question every frame: remember the answers
        key = (round(speed, 6), round(direction, 3), tuple(sorted((n, round(w, 6)) for n, w in weights.items())))
        with self._lock:
            ratio = self._memo.get(key)
            if ratio is None:
                cals = [(w, self._cal.get(n, self.fallback)) for n, w in weights.items()]
                command = sum(w * (float(c.command_for(speed, direction)) if c is not None else speed)
                              for w, c in cals)
                if len(self._memo) > 4096:
                    self._memo.clear()
                ratio = self._memo[key] = command / speed
        return v * ratio

    def close(self) -> None:
        """Stop measuring: the measurement in hand and the queued styles are dropped (nothing is
        left running: the slices are the frame loop's, and it stops with the server)."""
        with self._lock:
            self._closed = True
            self._job = None
            self._queue.clear()
