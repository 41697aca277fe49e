"""The frame loop: every connected character stepped at the data's frame rate, on a thread of its own.

The loop keeps absolute deadlines (frame k is due at ``start + k / fps``), so it does not drift:
sleeping too long once makes the next wait shorter, and frames that fell behind (the process was
not scheduled for a while: the cores are shared) are run at once until the loop is back on time,
so the character's time keeps up with the clock. A page shows the newest frame, so after such a
stall the character is where it would have been, as after any stall. Only after a stall of more
than ``MAX_CATCH_UP`` frames (a suspended laptop, a debugger) does the schedule restart from now
instead of running them all. With nobody connected the thread sleeps and costs nothing.

Its own thread, apart from the network's event loop, so that what a page does (a slow
connection, a burst of messages, the download of the page) does not wait for a frame, nor a frame
for it: pages only append messages to a character's queue (the two threads still share Python's
GIL, which is why each page has a message budget, ``budget.py``), and the loop hands finished
frames to ``deliver`` callbacks that must return at once (the server's posts the text to its event
loop). Each character is stepped at
batch 1 by its own :class:`~minifilm.demo.character.Character`.

Nothing a character does can stop the loop: a failing frame resets that character (see
``character.py``) and any other error is reported and the loop carries on.
"""
from __future__ import annotations

import collections
import threading
import time
import traceback
from typing import Callable, Dict, Tuple

from minifilm.demo.protocol import encode, notice

#: ``deliver(text, is_frame)``: hand a message to a page; must not block.
Deliver = Callable[[str, bool], None]
#: Frames the loop may run late to catch up with the clock (a quarter of a second at 60 fps); after
#: a longer stall it restarts its schedule instead. (With 4, stalls of 70-85 ms on this shared
#: 2-core machine made the loop lose 8 frames in 10 minutes: benchmarks/demo_soak.py.)
MAX_CATCH_UP = 15


class StageFull(RuntimeError):
    """Every character is taken."""


class Stage:
    """Up to ``max_characters`` characters stepped together every ``1 / fps`` seconds.

    Args:
        make_character: ident -> a new Character (called by :meth:`join`).
        fps: frames per second (the data's: 60 for the released network).
        clock: seconds, monotonic (``time.perf_counter``).

    Statistics (for tests and debugging): ``ticks`` frames run, ``behind`` frames started over a
    period late (then caught up), ``restarts`` times the schedule restarted after a long stall and
    ``skipped`` the frames so lost, ``frame_ms`` the last step times (ms), ``errors`` unexpected
    errors the loop survived.
    """

    def __init__(self, make_character: Callable[[int], object], fps: float, max_characters: int = 4,
                 clock: Callable[[], float] = time.perf_counter):
        if max_characters < 1:
            raise ValueError(f"Stage: max_characters must be >= 1, got {max_characters}")
        self.make_character, self.fps, self.max_characters, self.clock = make_character, float(fps), max_characters, clock
        self.period = 1.0 / self.fps
        self._members: Dict[int, Tuple[object, Deliver]] = {}
        self._lock = threading.Lock()
        self._wake, self._stop = threading.Event(), threading.Event()
        self._thread = None
        self._next_ident = 1
        self.start_time = clock()
        self.ticks = self.behind = self.restarts = self.skipped = self.errors = 0
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
    def tick(self, now: float = None) -> None:
        """One frame of every character, delivered to its page."""
        now = self.clock() if now is None else now
        with self._lock:
            members = list(self._members.values())
        t = round(now - self.start_time, 6)
        for character, deliver in members:
            try:
                t0 = self.clock()
                frame, notices = character.step()
                frame["frameMs"] = round(1e3 * (self.clock() - t0), 4)
                frame["t"] = t
                self.frame_ms.append(frame["frameMs"])
                for text in notices:
                    deliver(notice(text), False)
                deliver(encode(frame), True)
            except Exception:  # noqa: BLE001 - the loop outlives any one character's failure
                self._report()
        self.ticks += 1

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

    def _run(self) -> None:
        due = None
        while not self._stop.is_set():
            try:
                if not self.count:
                    self._wake.wait(0.5)
                    self._wake.clear()
                    due = None
                    continue
                now = self.clock()
                if due is None:
                    due = now
                elif now < due:
                    time.sleep(due - now)
                    now = self.clock()
                late = now - due
                if late > MAX_CATCH_UP * self.period:    # a long stall: do not run all it missed
                    self.restarts += 1
                    self.skipped += int(late / self.period)
                    due = now
                elif late > self.period:
                    self.behind += 1
                self.tick(now)
                due += self.period
            except Exception:  # noqa: BLE001 - see the module docstring: the loop never dies
                self._report()
                time.sleep(self.period)
