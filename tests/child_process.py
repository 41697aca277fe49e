"""A command under test in a process of its own, its output read with a limit on every wait.

``proc.stdout.readline()`` waits for ever on a child that stops printing without ending (a
deadlock), and reading to the end waits for ever while anything the child started (a process
pool's workers) still holds its output open. Here a thread reads the lines; every wait has a limit,
past which the child is killed and the test fails with what it printed. The child runs in a
session of its own, so one ``killpg`` ends it and whatever it started, and that is done when the
test is finished with it.

``signals``: how SIGINT and SIGTERM are set in the child when it starts ("SIG_IGN" or "SIG_DFL"
each), as a script's ``cmd &`` or ``trap '' INT`` leaves them. A small Python launcher sets them and then
execs the command (ignored signals stay ignored across exec): setting them between fork and exec
(``preexec_fn``) runs Python code in a copy of a process with threads, which can deadlock.
"""
from __future__ import annotations

import os
import queue
import signal
import subprocess
import sys
import threading
import time
from typing import Optional, Sequence

LAUNCH = ("import os, signal, sys\n"
          "signal.signal(signal.SIGINT, getattr(signal, sys.argv[1]))\n"
          "signal.signal(signal.SIGTERM, getattr(signal, sys.argv[2]))\n"
          "os.execv(sys.argv[3], sys.argv[3:])")


def minifilm_argv(*argv) -> list:
    """The argv of ``python -u -m minifilm ARGV`` (unbuffered: each line arrives as it is printed)."""
    return [sys.executable, "-u", "-m", "minifilm", *map(str, argv)]


class Child:
    """``argv`` running, stdout and stderr as one stream of lines (``seen``: every line so far)."""

    def __init__(self, argv: Sequence[str], signals: Optional[Sequence[str]] = None, **popen):
        argv = [str(a) for a in argv]
        if signals is not None:
            argv = [sys.executable, "-c", LAUNCH, *signals, *argv]
        self.proc = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT, text=True, start_new_session=True, **popen)
        self.pid, self.seen = self.proc.pid, []
        self._lines: queue.Queue = queue.Queue()
        self._ended = False
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        for line in self.proc.stdout:
            self._lines.put(line)
        self._lines.put(None)

    def _take(self, deadline: float) -> Optional[str]:
        """The next line ("" at the end of the output, None at the deadline)."""
        if self._ended:
            return ""
        try:
            line = self._lines.get(timeout=max(0.0, deadline - time.monotonic()))
        except queue.Empty:
            return None
        if line is None:
            self._ended = True
            return ""
        self.seen.append(line)
        return line

    def until(self, marker: str, timeout: float = 600.0, start: bool = False) -> str:
        """Everything printed so far, once a line holds ``marker`` (begins with it, with
        ``start``). Fails, the child killed, when it ends first or after ``timeout`` seconds."""
        deadline = time.monotonic() + timeout
        while True:
            line = self._take(deadline)
            if line is None or line == "":
                self.kill()
                why = f"within {timeout:g} s" if line is None else "before the command ended"
                raise AssertionError(f"no {marker!r} line {why}:\n{self.text()[-2000:]}")
            if line.startswith(marker) if start else marker in line:
                return self.text()

    def end(self, timeout: float = 600.0) -> str:
        """Everything printed, once the child has ended (``returncode``) and its output closed.
        Fails, the child killed, when it runs ``timeout`` seconds more. (Processes it started and
        left running hold its output open: that wait is cut short after 30 s, and they are killed
        with the child's session when the test is done with it.)"""
        try:
            self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.kill()
            raise AssertionError(f"still running after {timeout:g} s:\n{self.text()[-2000:]}") from None
        deadline = time.monotonic() + 30.0
        while self._take(deadline):
            pass
        return self.text()

    def text(self) -> str:
        return "".join(self.seen)

    @property
    def returncode(self) -> Optional[int]:
        return self.proc.returncode

    def send_signal(self, sig: int) -> None:
        self.proc.send_signal(sig)

    def kill(self) -> None:
        """SIGKILL to the child's session: the child, if it still runs, and all it started."""
        try:
            os.killpg(self.pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass
        if self.proc.poll() is None:
            self.proc.wait(30)

    def __enter__(self) -> "Child":
        return self

    def __exit__(self, *exc) -> None:
        self.kill()
        self.proc.stdout.close()
