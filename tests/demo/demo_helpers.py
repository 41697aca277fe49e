"""Helpers of the demo tests: the released network or a miniature run folder, a demo server on an
ephemeral 127.0.0.1 port, raw HTTP requests, a page in headless Chromium.

(A module with its own name rather than ``conftest``; its fixtures are imported by the test
modules that use them.)
"""
from __future__ import annotations

import socket

import pytest

from repo_paths import SHARED_DATA, need_data

websockets = pytest.importorskip("websockets", reason="the demo needs the websockets package (pip install "
                                                      "'minifilm[demo]')")

from minifilm.demo.character import DemoSettings  # noqa: E402  (after the skip: it needs nothing more)
from minifilm.demo.server import DemoServer  # noqa: E402
from minifilm.demo.source import DemoSource  # noqa: E402

RELEASED = SHARED_DATA / "released-lpn"


@pytest.fixture(scope="module")
def tiny_source(tiny_run) -> DemoSource:
    """The session's tiny trained run (tests/conftest.py), loaded as a demo source (it only reads it)."""
    return DemoSource.run_folder(tiny_run)


@pytest.fixture(scope="module")
def released_source() -> DemoSource:
    """The authors' released network; skips when it is not in the shared data folder."""
    need_data(RELEASED / "Xmean.bin", "the released network")      # skipped here, failed in CI
    return DemoSource.released(RELEASED)


@pytest.fixture
def budget_clock_stopped(monkeypatch):
    """The message budget of every page that connects from now on (minifilm/demo/budget.py) sees
    all its messages arrive in the same instant. The budget is a rate, so what a flood or a burst
    leads to would otherwise depend on how fast this machine sends and the server reads, which a
    loaded machine slows down; so a test of it depends on what was sent, not on the load. (The
    budget's clock itself is tested in test_demo_budget.py; a client address's budget, given
    its clock by AddressBudgets, keeps the real one.)"""
    from minifilm.demo import budget

    class Stopped(budget.MessageBudget):
        def __init__(self, rate=budget.MESSAGES_PER_SECOND, clock=None):
            super().__init__(rate, (lambda: 0.0) if clock is None else clock)

    monkeypatch.setattr(budget, "MessageBudget", Stopped)


def serve(source: DemoSource, max_characters: int = 2, **settings) -> DemoServer:
    """A started server on 127.0.0.1, any free port; stop it with ``.stop()``."""
    server = DemoServer(source, DemoSettings(style=source.default_style(), **settings), host="127.0.0.1", port=0,
                        max_characters=max_characters, background_calibration=False)
    server.start()
    return server


def http_get(port: int, target: str, host: str = None, extra: str = "") -> tuple:
    """(status code, body bytes) of a raw ``GET target`` to 127.0.0.1:port, the request line sent
    exactly as given (no client normalises the path)."""
    host = host or f"127.0.0.1:{port}"
    with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
        s.sendall(f"GET {target} HTTP/1.1\r\nHost: {host}\r\n{extra}Connection: close\r\n\r\n".encode("latin-1"))
        data = b""
        while True:
            chunk = s.recv(65536)
            if not chunk:
                break
            data += chunk
    head, _, body = data.partition(b"\r\n\r\n")
    status = int(head.split(b" ", 2)[1]) if head.startswith(b"HTTP/") else 0
    return status, body


class DemoPage:
    """A demo page open in headless Chromium (``browser``, the fixture above) at ``url``, with what it
    logged (``messages``), requested (``requests``) and opened (``sockets``).

    Args:
        width, height: the window (the panel's layout depends on it).
        init_script: JavaScript run before the page's own (e.g. a fake gamepad).
        route: a handler for ``page.route_web_socket`` (a test between the page and the server).
        keep_frames: keep every frame the page receives, parsed, in ``frames`` (off the page's
            WebSocket, so a frame the page skips while drawing is kept too).
        ready: seconds to wait for the page to be ready and to have drawn ten frames.

    ``browser``: the fixture of tests/conftest.py. Every wait is for a condition with a bounded time-out, never for a length of time: on a busy
    machine the page is only slower. A character's own time is its step count (``frame.n``, 60 a
    second of motion): :meth:`hold` holds keys for that many steps, however long they take.
    """

    def __init__(self, browser, url: str, width: int = 960, height: int = 600, init_script: str = None,
                 route=None, keep_frames: bool = False, ready: float = 60.0):
        import json
        self.url, self.messages, self.requests, self.sockets, self.frames = url, [], [], [], []
        self.page = browser.new_page(viewport={"width": width, "height": height})
        if init_script:
            self.page.add_init_script(init_script)
        self.page.on("console", lambda m: self.messages.append((m.type, m.text)))
        self.page.on("pageerror", lambda e: self.messages.append(("pageerror", str(e))))
        self.page.on("request", lambda r: self.requests.append(r.url))
        self.page.on("websocket", lambda w: self.sockets.append(w.url))
        if keep_frames:
            def received(payload):
                if isinstance(payload, str) and payload.startswith('{"type":"frame"'):
                    self.frames.append(json.loads(payload))
            self.page.on("websocket", lambda w: w.on("framereceived", received))
        if route:
            self.page.route_web_socket("**/ws", route)
        self.page.goto(url)
        self.wait("window.minifilmDemo && minifilmDemo.ready && minifilmDemo.frames > 10", timeout=ready)

    def js(self, expression, arg=None):
        return self.page.evaluate(expression, arg)

    def wait(self, condition, timeout: float = 30.0, poll: float = 0.05):
        """Poll ``condition`` (a JavaScript expression, or a Python callable) until it is true;
        returns its value. (Not page.wait_for_function: it evaluates strings with eval, which the
        page's Content-Security-Policy forbids, as it should.)"""
        import time
        end = time.monotonic() + timeout
        while True:
            value = condition() if callable(condition) else self.js(condition)
            if value:
                return value
            if time.monotonic() > end:
                raise TimeoutError(f"not true within {timeout} s: {condition}")
            self.page.wait_for_timeout(int(poll * 1000))

    def frame(self) -> dict:
        """The newest frame the page has (``minifilmDemo.frame``)."""
        return self.js("minifilmDemo.frame")

    def steps_on(self, steps: int, timeout: float = None) -> dict:
        """The first frame ``steps`` network steps after the newest one now (the character's own
        time: ``steps / 60`` s of motion, however long a busy machine takes to make them)."""
        start = self.frame()["n"]
        timeout = timeout if timeout is not None else 60.0 + steps / 6.0     # a tenth of real time, and more
        self.wait(f"minifilmDemo.frame.n >= {start + int(steps)}", timeout=timeout)
        return self.frame()

    def applied(self, timeout: float = 60.0) -> dict:
        """The first frame made after every message the page has sent was applied (its ``ack``):
        on a loaded machine a key press reaches the character a second or more after it is made."""
        self.wait("minifilmDemo.frame.ack !== null ? minifilmDemo.frame.ack >= minifilmDemo.sent"
                  " : minifilmDemo.sent === 0", timeout=timeout)
        return self.frame()

    def hold(self, keys, steps: int, until=None, until_timeout: float = None):
        """(frame before, frame after) holding ``keys`` (one name or a list) for ``steps`` network
        steps of the character counted from when the press reached it (and, with ``until``, until
        that condition holds too: JavaScript text or a function, as :meth:`wait` takes); the keys
        are released after, in reverse order, and the release waited for."""
        keys = [keys] if isinstance(keys, str) else list(keys)
        before = self.frame()
        for key in keys:
            self.page.keyboard.down(key)
        try:
            self.applied()
            after = self.steps_on(steps)
            if until:
                self.wait(until, timeout=until_timeout or 60.0 + steps / 6.0)
                after = self.frame()
        finally:
            for key in reversed(keys):
                self.page.keyboard.up(key)
        self.applied()
        return before, after

    def mark(self) -> int:
        """A point in ``frames`` (its length now) for :meth:`since`."""
        return len(self.frames)

    def since(self, mark: int) -> list:
        return self.frames[mark:]

    def errors(self):
        return [m for m in self.messages if m[0] in ("error", "pageerror")]

    def close(self):
        self.page.close()
