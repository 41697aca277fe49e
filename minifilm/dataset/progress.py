"""A one-line progress display on stderr for long loops (dataset building)."""
from __future__ import annotations

import sys
import time


class Progress:
    """One status line on stderr, rewritten in place on a terminal, every ~10 % otherwise."""

    def __init__(self, total: int, label: str, enabled: bool = True):
        self.total, self.label, self.enabled = total, label, enabled
        self.t0 = time.perf_counter()
        self.tty = enabled and sys.stderr.isatty()
        self.next_print = 0.0

    def update(self, done: int, note: str = "") -> None:
        if not self.enabled or self.total == 0:
            return
        frac = done / self.total
        if not self.tty and frac < self.next_print and done != self.total:
            return
        self.next_print = frac + 0.1
        el = time.perf_counter() - self.t0
        eta = el / done * (self.total - done) if done else float("nan")
        msg = f"[{self.label}] {done}/{self.total} files, {el:5.1f} s, eta {eta:5.1f} s {note}"
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
