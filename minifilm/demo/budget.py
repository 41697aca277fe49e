"""A page's message budget: one page sending a flood must not take the frame loop's time.

Every message a page sends is parsed on the server's event-loop thread, which shares Python's GIL
with the frame loop. A real page sends at most one ``input`` per animation frame (60-144 a
second), a ``ping`` a second and the odd click; a script sending tens of thousands a second
slowed the loop from 60 to 49 fps and starved the other pages. So each connection gets a token
bucket: ``rate`` messages a second, bursts of up to ``rate``. Messages over it are dropped
unparsed (the page is told once per second), and a page that keeps flooding, more than
``2 * rate`` dropped within one second, is disconnected (close code 1008, policy violation).
"""
from __future__ import annotations

import time
from typing import Callable

#: Messages a second one page may send (far above what the page itself sends; see above).
MESSAGES_PER_SECOND = 300


class MessageBudget:
    """``take()`` for each message received: True to handle it, False to drop it; then
    ``should_warn`` says whether to tell the page (once per second of dropping) and ``flooding``
    whether to disconnect it."""

    def __init__(self, rate: float = MESSAGES_PER_SECOND, clock: Callable[[], float] = time.monotonic):
        if not rate > 0:
            raise ValueError(f"MessageBudget: rate must be positive, got {rate}")
        self.rate, self.clock = float(rate), clock
        self.tokens, self.last = self.rate, clock()
        self.window_start, self.dropped_in_window = self.last, 0
        self.dropped = 0                   # in all
        self.should_warn = False
        self.flooding = False

    def take(self) -> bool:
        now = self.clock()
        self.tokens = min(self.rate, self.tokens + (now - self.last) * self.rate)
        self.last = now
        self.should_warn = False
        if self.tokens >= 1.0:
            self.tokens -= 1.0
            return True
        if now - self.window_start >= 1.0:  # a new second of dropping
            self.window_start, self.dropped_in_window = now, 0
        self.dropped += 1
        self.dropped_in_window += 1
        self.should_warn = self.dropped_in_window == 1
        self.flooding = self.dropped_in_window > 2 * self.rate
        return False
