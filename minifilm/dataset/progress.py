"""A one-line progress display on stderr for long loops (building a data set, a long rollout)."""
from __future__ import annotations

import sys
import time


class Progress:
    """One status line on stderr of ``done``/``total`` ``unit``: rewritten in place on a terminal
    (at most five times a second), a line every ~10 % otherwise."""

    def __init__(self, total: int, label: str, enabled: bool = True, unit: str = "files"):
        self.total, self.label, self.enabled, self.unit = total, label, enabled, unit
        self.t0 = self.last_print = time.perf_counter()
        self.tty = enabled and sys.stderr.isatty()
        self.next_print = 0.0

    def update(self, done: int, note: str = "") -> None:
        if not self.enabled or self.total == 0:
            return
        frac = done / self.total
        now = time.perf_counter()
        if done != self.total and (now - self.last_print < 0.2 if self.tty else frac < self.next_print):
            return
        self.next_print, self.last_print = frac + 0.1, now
        el = now - self.t0
        eta = el / done * (self.total - done) if done else float("nan")
        msg = f"[{self.label}] {done}/{self.total} {self.unit}, {el:5.1f} s, eta {eta:5.1f} s" + (f" {note}" if note else "")
        if self.tty:
            sys.stderr.write("\r" + msg[:120].ljust(120) + ("\n" if done == self.total else ""))
        else:
            sys.stderr.write(msg + "\n")
        sys.stderr.flush()

    def note(self, text: str) -> None:
        """A line of its own on stderr (before the first update: how the work is shared)."""
        if self.enabled:
            sys.stderr.write(f"[{self.label}] {text}\n")
            sys.stderr.flush()
