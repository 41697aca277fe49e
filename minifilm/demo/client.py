"""A page without a browser: a blocking WebSocket client of a demo server, for tests, benchmarks
and scripts that steer a character from Python.

    with DemoClient("http://127.0.0.1:8765/") as page:
        page.send({"type": "input", "move": [0, 1], "turn": 0, "speed": 0})
        frame = page.next_frame()

It never goes through a proxy (the environment's proxy settings are ignored): a demo server is
on this machine.
"""
from __future__ import annotations

import base64
import inspect
import json
import os
import socket
import struct
import time
from typing import Callable, Optional, Union
from urllib.parse import urlsplit

#: the largest message taken from the server: a recording's BVH text and its GIF (base64) run to a
#: few megabytes (the server's own limit, TRANSPORT_MAX_BYTES, is on what pages send it)
RECEIVE_MAX_BYTES = 64 * 2 ** 20


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
        options = dict(open_timeout=timeout, compression=None, max_size=RECEIVE_MAX_BYTES, origin=origin)
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


class RawWebSocket:
    """A WebSocket spoken by hand over a plain socket, frame by frame: what a hostile client
    sends (ping, pong and continuation floods, odd headers) and no client library would.

        raw = RawWebSocket(port)              # handshake with Host 127.0.0.1:port
        raw.send_frame(0x9, b"x")             # a ping; opcodes: 0x0 continuation, 0x1 text,
                                              # 0x2 binary, 0x8 close, 0x9 ping, 0xA pong
    """

    def __init__(self, port: int, host_header: Optional[str] = None, extra_headers: str = "",
                 timeout: float = 10.0):
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=timeout)
        key = base64.b64encode(os.urandom(16)).decode("ascii")
        request = (f"GET /ws HTTP/1.1\r\nHost: {host_header or f'127.0.0.1:{port}'}\r\nUpgrade: websocket\r\n"
                   f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n"
                   f"{extra_headers}\r\n")
        self.sock.sendall(request.encode("latin-1"))
        head = b""
        while b"\r\n\r\n" not in head:
            chunk = self.sock.recv(4096)
            if not chunk:
                break
            head += chunk
        self.response, _, self.buffer = head.partition(b"\r\n\r\n")
        self.status = int(self.response.split(b" ", 2)[1]) if self.response.startswith(b"HTTP/") else 0

    @staticmethod
    def frame(opcode: int, payload: bytes = b"", fin: bool = True) -> bytes:
        """One masked client frame (RFC 6455 section 5.2); the mask is zero, which changes nothing."""
        head = bytes([(0x80 if fin else 0) | opcode])
        n = len(payload)
        if n < 126:
            head += bytes([0x80 | n])
        elif n < 65536:
            head += bytes([0x80 | 126]) + struct.pack("!H", n)
        else:
            head += bytes([0x80 | 127]) + struct.pack("!Q", n)
        return head + b"\0\0\0\0" + payload

    def send_frame(self, opcode: int, payload: bytes = b"", fin: bool = True) -> None:
        self.sock.sendall(self.frame(opcode, payload, fin))

    def send_raw(self, data: bytes) -> bool:
        """Send bytes as they are; False once the server has closed the connection."""
        try:
            self.sock.sendall(data)
            return True
        except OSError:
            return False

    def read_until_closed(self, timeout: float = 10.0) -> bytes:
        """Everything the server sends until it closes the connection (or ``timeout``)."""
        self.sock.settimeout(timeout)
        data, end = self.buffer, time.monotonic() + timeout
        try:
            while time.monotonic() < end:
                chunk = self.sock.recv(65536)
                if not chunk:
                    break
                data += chunk
        except (socket.timeout, OSError):
            pass
        return data

    @staticmethod
    def frames(data: bytes) -> list:
        """(opcode, payload) of each whole server frame (unmasked) in ``data``."""
        out, i = [], 0
        while i + 2 <= len(data):
            opcode, n = data[i] & 0x0F, data[i + 1] & 0x7F
            i += 2
            if n == 126:
                if i + 2 > len(data):
                    break
                n, i = struct.unpack("!H", data[i:i + 2])[0], i + 2
            elif n == 127:
                if i + 8 > len(data):
                    break
                n, i = struct.unpack("!Q", data[i:i + 8])[0], i + 8
            if i + n > len(data):
                break
            out.append((opcode, data[i:i + n]))
            i += n
        return out

    def close(self) -> None:
        try:
            self.sock.close()
        except OSError:
            pass

    def __enter__(self) -> "RawWebSocket":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
