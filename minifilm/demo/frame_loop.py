"""The frame loop: every connected character stepped at the data's frame rate, on a thread of its own.

Simulation time follows the clock (:class:`FrameClock`): network step k is due at
``start + k / fps``, so the character covers its metres per *real* second. Each pass of the loop
runs every step that has fallen due since the last one, as a batch, and sends the page only the
last frame of the batch (making and sending a frame costs about as much as a step: when the
machine is busy, batching is what lets it keep up). A page shows the newest frame (it may
interpolate between them), so after a stall the character is where it would have been. A batch
is at most ``MAX_BATCH`` steps; after a longer stall (a suspended laptop, a debugger, a machine
that cannot keep up at all) the steps beyond it are dropped and counted, and every frame tells
its page how many steps the loop is behind the clock (``behind``), how many it dropped in the
last second (``dropped``) and how many steps it ran in the last second of wall time
(``stepsPerSecond``): the page says so instead of showing slow motion as real time. With
nobody connected the thread sleeps and costs nothing.

Its own thread, apart from the network's event loop, so that what a page does (a slow
connection, a burst of messages, the download of the page) does not wait for a frame, nor a frame
for it: pages only append messages to a character's queue (the two threads still share Python's
GIL, which is why each page has a message budget, ``budget.py``), and the loop hands finished
frames to ``deliver`` callbacks that must return at once (the server's posts the text to its event
loop). Each character is stepped at
batch 1 by its own :class:`~minifilm.demo.character.Character`.

Idle work (``idle_work``: the speed calibrations, ``calibrations.py``) runs on this thread in the
time left before the next frame is due, one bounded slice at a time (:meth:`Stage._spare`): a slice
runs only when it is expected (the median of the last slices, plus ``SPARE_MARGIN``) to end before
the deadline, so a frame waits at most for one slice that took longer than expected. (The median,
not the longest: a slice the scheduler paused once would otherwise stop all slices while a page is
connected; they are all alike, one network step of the same batch.) On a machine so busy that no
slice fits any more (the scheduler stretches each one's wall time), the times measured are
forgotten after ``PROBE_AFTER`` seconds without a slice and one is tried again: the work goes on,
slowly, and delays a frame by at most one slice that often.
With nobody connected the slices run back to back.

Nothing a character does can stop the loop: a failing frame resets that character (see
``character.py``) and any other error is reported and the loop carries on.
"""
from __future__ import annotations

import collections
import statistics
import threading
import time
import traceback
from typing import Callable, Dict, Tuple

from minifilm.demo.protocol import encode, notice

#: ``deliver(text, is_frame)``: hand a message to a page; must not block.
Deliver = Callable[[str, bool], None]
#: Steps the loop may run in one batch to catch up with the clock (half a second at 60 fps); the
#: steps due beyond it are dropped (and reported). (A limit of 4 lost 8 frames in 10 minutes to the
#: 70-85 ms stalls of a shared 2-core machine, benchmarks/demo_soak.py; 15 lost whole seconds at
#: load 7, where every pass fell further behind.)
MAX_BATCH = 30
#: seconds a slice of idle work is expected to leave before the next frame is due (a pause of the
#: scheduler, the frame's own jitter). A trade: with 4 ms a shared 2-core machine at load 4 kept
#: the first minute of calibrations as smooth as a later one, but at load 5 with a page connected
#: the start style was not measured in 12 minutes; with 2 ms it was, in about 2.5 minutes at load
#: 3-13, and the first minute had 24 frame intervals over 33 ms (a later one 1)
SPARE_MARGIN = 0.002
#: seconds a slice of idle work is assumed to take before any has been timed
FIRST_SLICE_GUESS = 0.008
#: seconds the loop sleeps before a slice while pages are connected, so the event loop's thread
#: can take Python's GIL and send the frame just made (the slice would hold it for up to 5 ms)
SPARE_BREATH = 0.0005
#: slices whose times make the estimate of the next one
SLICE_MEMORY = 32
#: seconds without a slice (none fitted) after which the slices' times are forgotten and one is tried
PROBE_AFTER = 0.5

class FrameClock:
    """When the network steps are due: step k at ``start + k * period`` (seconds of ``clock``).

    ``due(now)`` says how many steps to run now (0: wait until ``next_due``), at most
    ``max_batch``; the steps beyond that are dropped (``dropped`` counts them, the schedule moves
    on). ``ran(n)`` records that n steps were run. ``behind(now)``: steps due and not yet run.
    ``rate(now)``: steps run in the last second of the clock. Pure arithmetic on the times it is
    given, so tests drive it with a fake clock.
    """

    def __init__(self, period: float, max_batch: int = MAX_BATCH):
        if not period > 0 or max_batch < 1:
            raise ValueError(f"FrameClock: period must be > 0 and max_batch >= 1, got {period}, {max_batch}")
        self.period, self.max_batch = float(period), int(max_batch)
        self.next_due = None
        self.dropped = 0
        self._ran = collections.deque(maxlen=4096)          # (time, steps) of each batch
        self._drops = collections.deque(maxlen=4096)        # (time, steps dropped)

    def restart(self, now: float) -> None:
        """Step 0 is due at ``now`` (the first page joined, or the loop woke from sleeping)."""
        self.next_due = now

    def due(self, now: float) -> int:
        if self.next_due is None:
            self.restart(now)
        if now < self.next_due:
            return 0
        n = int((now - self.next_due) // self.period) + 1
        if n > self.max_batch:
            lost = n - self.max_batch
            self.dropped += lost
            self._drops.append((now, lost))
            self.next_due += lost * self.period
            n = self.max_batch
        return n

    def ran(self, n: int, now: float) -> None:
        self.next_due += n * self.period
        self._ran.append((now, n))

    def behind(self, now: float) -> int:
        """Steps due at ``now`` that have not been run (0 when on time)."""
        if self.next_due is None or now < self.next_due:
            return 0
        return int((now - self.next_due) // self.period) + 1

    def rate(self, now: float, window: float = 1.0) -> int:
        """Steps run in the last ``window`` seconds."""
        return sum(n for t, n in self._ran if now - t < window)

    def recently_dropped(self, now: float, window: float = 1.0) -> int:
        return sum(n for t, n in self._drops if now - t < window)


class StageFull(RuntimeError):
    """Every character is taken."""


class Stage:
    """Up to ``max_characters`` characters stepped together every ``1 / fps`` seconds.

    Args:
        make_character: ident -> a new Character (called by :meth:`join`).
        fps: frames per second (the data's: 60 for the released network).
        clock: seconds, monotonic (``time.perf_counter``).

    Statistics (for tests and debugging): ``ticks`` passes of the loop (one frame sent per
    character each), ``steps`` network steps run, ``behind`` passes that ran more than one step
    (a batch, catching up), ``restarts`` passes that had to drop steps and ``skipped`` the steps so
    dropped, ``frame_ms`` the last passes' times (ms), ``errors`` unexpected errors the loop survived,
    ``slices`` slices of idle work run and ``late_slices`` those that ended after a frame fell due.

    ``idle_work``: None, or an object with ``pending()`` (bool) and ``run_slice()`` (a few ms of work).
    ``sleep``: seconds -> None (``time.sleep``; tests give a fake clock's).
    """

    def __init__(self, make_character: Callable[[int], object], fps: float, max_characters: int = 4,
                 clock: Callable[[], float] = time.perf_counter, sleep: Callable[[float], None] = time.sleep):
        if max_characters < 1:
            raise ValueError(f"Stage: max_characters must be >= 1, got {max_characters}")
        self.make_character, self.fps, self.max_characters, self.clock = make_character, float(fps), max_characters, clock
        self.sleep = sleep
        self.idle_work = None
        self.slices = self.late_slices = 0
        self.slice_seconds = collections.deque(maxlen=SLICE_MEMORY)
        self._last_slice = None             # when the last slice ended (the probe's clock)
        self.period = 1.0 / self.fps
        self._members: Dict[int, Tuple[object, Deliver]] = {}
        self._lock = threading.Lock()
        self._wake, self._stop = threading.Event(), threading.Event()
        self._thread = None
        self._next_ident = 1
        self.start_time = clock()
        self.ticks = self.steps = self.behind = self.restarts = self.skipped = self.errors = 0
        self.frames = FrameClock(self.period)
        self.frame_ms = collections.deque(maxlen=600)        # bounded: the loop runs for hours

    # ---- members ----------------------------------------------------------------------------
    def join(self, deliver: Deliver):
        """A new character for a page whose messages go to ``deliver``; StageFull when all are taken."""
        with self._lock:
            if len(self._members) >= self.max_characters:
                raise StageFull(f"all {self.max_characters} characters of this demo are in use (one per page): "
                                "close another demo tab, then reload this one")
            ident = self._next_ident
            self._next_ident += 1
        character = self.make_character(ident)       # outside the lock: it takes a few milliseconds
        with self._lock:
            if len(self._members) >= self.max_characters:   # another page joined meanwhile
                raise StageFull(f"all {self.max_characters} characters of this demo are in use")
            self._members[ident] = (character, deliver)
        self._wake.set()
        return character

    def leave(self, character) -> None:
        """Free a page's character (its page closed)."""
        with self._lock:
            self._members.pop(character.ident, None)

    def member(self, ident: int):
        """The character ``ident`` (None when its page has gone)."""
        with self._lock:
            found = self._members.get(ident)
        return found[0] if found else None

    @property
    def count(self) -> int:
        with self._lock:
            return len(self._members)

    # ---- frames -----------------------------------------------------------------------------
    def tick(self, now: float = None, steps: int = 1) -> None:
        """``steps`` network steps of every character (a batch when the loop is behind the clock),
        the last one's frame delivered to its page."""
        now = self.clock() if now is None else now
        with self._lock:
            members = list(self._members.values())
        t = round(now - self.start_time, 6)
        timing = {"steps": steps, "dropped": self.frames.recently_dropped(now),
                  "stepsPerSecond": self.frames.rate(now)}
        for character, deliver in members:
            try:
                t0 = self.clock()
                frame, notices = character.step(steps=steps, now=now)
                done = self.clock()
                frame["frameMs"] = round(1e3 * (done - t0), 4)
                frame["t"] = t
                frame.update(timing)
                # behind: the steps due by the time this frame is sent that are still not run. The
                # batch's own steps are not behind (counting them said "1 behind" on every frame of
                # a machine that keeps up); the schedule has not been moved past them yet (ran()).
                frame["behind"] = max(0, self.frames.behind(done) - steps)
                self.frame_ms.append(frame["frameMs"])
                for text in notices:
                    deliver(notice(text), False)
                deliver(encode(frame), True)
            except Exception:  # noqa: BLE001 - the loop outlives any one character's failure
                self._report()
        self.ticks += 1
        self.steps += steps

    def _report(self) -> None:
        self.errors += 1
        if self.errors <= 5:     # enough to debug; a repeating error must not flood the log
            traceback.print_exc()

    def start(self) -> None:
        """Run the loop on its own thread (a daemon: it never keeps the process alive)."""
        if self._thread is None:
            self._stop.clear()
            self._thread = threading.Thread(target=self._run, name="minifilm-demo-frames", daemon=True)
            self._thread.start()

    def stop(self, timeout: float = 2.0) -> None:
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout)
            self._thread = None

    def wake(self) -> None:
        """Idle work has arrived (any thread): a loop asleep with nobody connected starts on it."""
        self._wake.set()

    def _spare(self) -> bool:
        """One slice of ``idle_work`` if there is one and the next frame leaves room for it; True
        if one ran. Room: the slice is expected (the median of the last ``SLICE_MEMORY``) to end
        ``SPARE_MARGIN`` before the next frame is due, so no frame waits longer than one slice that
        took longer than expected. With nobody connected there is no deadline."""
        work = self.idle_work
        if work is None or not work.pending():
            return False
        connected = bool(self.count)
        if connected:
            now = self.clock()
            if self._last_slice is None or now - self._last_slice > PROBE_AFTER:
                self.slice_seconds.clear()          # none fitted for a while: measure again
                self._last_slice = now
            expected = statistics.median(self.slice_seconds) if self.slice_seconds else FIRST_SLICE_GUESS
            if self.frames.next_due is not None and \
                    self.frames.next_due - self.clock() < SPARE_BREATH + expected + SPARE_MARGIN:
                return False
            self.sleep(SPARE_BREATH)
        t0 = self.clock()
        work.run_slice()
        end = self._last_slice = self.clock()
        self.slice_seconds.append(end - t0)
        self.slices += 1
        if connected and self.frames.next_due is not None and end > self.frames.next_due:
            self.late_slices += 1
        return True

    def _run(self) -> None:
        clock = self.frames
        while not self._stop.is_set():
            try:
                if not self.count:
                    clock.next_due = None           # the schedule starts again with the next page
                    if self._spare():
                        self.sleep(0.001)           # the event loop serves the page meanwhile
                        continue
                    self._wake.wait(0.5)
                    self._wake.clear()
                    continue
                now = self.clock()
                dropped = clock.dropped
                n = clock.due(now)
                if n == 0:
                    if not self._spare():
                        self.sleep(max(clock.next_due - now, 0.0))
                    continue
                if clock.dropped > dropped:
                    self.restarts += 1
                    self.skipped += clock.dropped - dropped
                if n > 1:
                    self.behind += 1
                self.tick(now, steps=n)
                clock.ran(n, now)
            except Exception:  # noqa: BLE001 - see the module docstring: the loop never dies
                self._report()
                self.sleep(self.period)
