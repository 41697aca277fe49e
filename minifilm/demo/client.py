"""A page without a browser: a blocking WebSocket client of a demo server, for tests, benchmarks
and scripts that steer a character from Python.

    with DemoClient("http://127.0.0.1:8765/") as page:
        page.send({"type": "input", "move": [0, 1], "turn": 0, "speed": 0})
        frame = page.next_frame()

It never goes through a proxy (the environment's proxy settings are ignored): a demo server is
on this machine.
"""
from __future__ import annotations

import inspect
import json
import time
from typing import Callable, Optional, Union
from urllib.parse import urlsplit

from minifilm.demo.protocol import TRANSPORT_MAX_BYTES


class DemoClient:
    """One connection to ``url`` (the page's http:// URL, or the ws:// URL of /ws).

    ``hello`` is the server's first message (or ``refused``, with the connection closed after it);
    ``other`` collects what :meth:`next_frame` skipped (errors, notices, pongs).
    """

    def __init__(self, url: str, timeout: float = 10.0, origin: Optional[str] = None):
        try:
            # an optional extra (minifilm[demo]): imported only when a client is made
            from websockets.sync.client import connect
        except ImportError as e:
            raise ImportError(f"the demo client needs the websockets package: pip install 'minifilm[demo]' ({e})") \
                from None
        parts = urlsplit(url)
        ws_url = url if parts.scheme in ("ws", "wss") else f"ws://{parts.netloc}/ws"
        options = dict(open_timeout=timeout, compression=None, max_size=TRANSPORT_MAX_BYTES, origin=origin)
        if "proxy" in inspect.signature(connect).parameters:    # websockets >= 15 reads proxy settings
            options["proxy"] = None
        # entered as a context manager, the one way every websockets version opens it without warning
        self._connection = connect(ws_url, **options)
        self.ws = self._connection.__enter__()
        self.timeout = timeout
        self.seq = 0
        self.other = []
        self.hello = self.recv()

    def send(self, message: Union[dict, str, bytes]) -> Optional[int]:
        """Send a message (a dict gets the next ``seq``; text and bytes go as they are)."""
        if isinstance(message, dict):
            self.seq += 1
            message = dict(message, seq=self.seq)
            self.ws.send(json.dumps(message))
            return self.seq
        self.ws.send(message)
        return None

    def recv(self, timeout: Optional[float] = None) -> dict:
        """The next message (TimeoutError after ``timeout`` seconds)."""
        return json.loads(self.ws.recv(timeout=self.timeout if timeout is None else timeout))

    def next_frame(self, timeout: Optional[float] = None) -> dict:
        """The next frame; other messages on the way are kept in ``other``."""
        while True:
            m = self.recv(timeout)
            if m.get("type") == "frame":
                return m
            self.other.append(m)

    def wait_for(self, predicate: Callable[[dict], bool], timeout: Optional[float] = None) -> dict:
        """The first message (of any type) for which ``predicate`` holds; others are dropped
        (non-frames kept in ``other``)."""
        end = time.monotonic() + (self.timeout if timeout is None else timeout)
        while True:
            left = end - time.monotonic()
            if left <= 0:
                raise TimeoutError("no such message in time")
            m = self.recv(left)
            if predicate(m):
                return m
            if m.get("type") != "frame":
                self.other.append(m)

    def close(self) -> None:
        self._connection.__exit__(None, None, None)

    def __enter__(self) -> "DemoClient":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
