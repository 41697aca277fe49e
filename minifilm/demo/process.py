"""``minifilm demo`` in a process of its own, as a user starts it: for tests, benchmarks and
scripts that drive the server with :class:`~minifilm.demo.client.DemoClient` or a browser.

    with DemoProcess("--params", "../shared/data/released-lpn") as demo:
        with DemoClient(demo.url) as page:
            page.next_frame()

The server listens on an ephemeral port of 127.0.0.1; ``url`` is the page's address once it
listens. Its own process has its own BLAS thread setting and GIL, away from the caller's.
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tempfile
import threading
import time

URL = re.compile(r"http://127\.0\.0\.1:\d+/")


class DemoProcess:
    """``python -m minifilm demo ARGS --port 0 --host 127.0.0.1``; ``url``, ``port`` once it
    listens (RuntimeError with everything it printed when it does not start within ``timeout``
    seconds). ``stop()`` ends it (SIGTERM, then SIGKILL after 10 s).

    ``cache``: the folder of its speed-calibration cache (``MINIFILM_CACHE``); by default a new
    temporary folder, removed by ``stop()``, so tests never read or write the user's cache.
    ``started``: ``time.monotonic()`` when the process was started; ``ready_seconds``: how long
    it took until the URL was printed."""

    def __init__(self, *args, timeout: float = 180.0, cache=None):
        self._own_cache = None
        if cache is None:
            cache = self._own_cache = tempfile.mkdtemp(prefix="minifilm-demo-cache-")
        env = dict(os.environ, MINIFILM_CACHE=str(cache))
        self.started = time.monotonic()
        self.proc = subprocess.Popen([sys.executable, "-m", "minifilm", "demo", *map(str, args), "--port", "0",
                                      "--host", "127.0.0.1"],
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
        self.lines, found = [], threading.Event()
        self.ready_seconds = None

        def read():
            for line in self.proc.stdout:
                self.lines.append(line)
                if URL.search(line) and not found.is_set():
                    self.ready_seconds = time.monotonic() - self.started
                    found.set()
            found.set()
        threading.Thread(target=read, daemon=True).start()
        if not found.wait(timeout) or self.proc.poll() is not None:
            self.stop()
            raise RuntimeError("minifilm demo did not start:\n" + "".join(self.lines))
        self.url = URL.search("".join(self.lines)).group(0)
        self.port = int(self.url.rsplit(":", 1)[1].strip("/"))

    def rss_mb(self) -> float:
        """The server's resident memory (VmRSS), MB (Linux; nan elsewhere)."""
        try:
            with open(f"/proc/{self.proc.pid}/status") as f:
                for line in f:
                    if line.startswith("VmRSS:"):
                        return int(line.split()[1]) / 1024
        except OSError:
            pass
        return float("nan")

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(10)
        if self._own_cache is not None:
            shutil.rmtree(self._own_cache, ignore_errors=True)
            self._own_cache = None

    def __enter__(self) -> "DemoProcess":
        return self

    def __exit__(self, *exc) -> None:
        self.stop()
