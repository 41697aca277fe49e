"""The demo's HTTP front: every connection is read here first, and only a WebSocket opening reaches ``websockets``.

The ``websockets`` package answers one request per connection and then parses whatever follows
the request as WebSocket frames, even before it has answered: two GETs sent in one write made the
second a "frame", the frame a protocol error, and the error a second end-of-stream during the
answer -- an 11-line AssertionError traceback in the log for nearly every such connection, and no
answer. So the front reads each request head itself (``http_request.py``, strict) and:

- ``GET /ws``: hands the connection to ``websockets`` with exactly that request; whatever the
  client sent after it is held back until the handshake is answered, then given to it (frames of
  an opened WebSocket, or discarded after a refusal);
- any other request: answers it here -- GET and HEAD of the page's files (HEAD: the same headers,
  no body), 405 for other methods, 400/414/431 for a malformed head -- in order, however many
  arrive in one write (pipelining). HTTP/1.1 connections stay open for the next request unless the
  client asks to close; after an error the front answers, ends its side (half-close) and discards
  what still comes, so the answer is not lost to a reset, then closes.

Limits, so no client can hold the server's memory or sockets: a request head must arrive within
:data:`HEAD_TIMEOUT` seconds (a client that trickles one byte at a time, "slowloris", is cut off);
a client that does not read its answers stops being read (the front pauses reading while
:data:`WRITE_BUFFER_LIMIT` bytes wait) and is cut off after the same timeout; a client that has
closed its side gets the answers to what it sent, then the connection is closed.

Every connection and every request is taken from its client address's budget (``budget.py``)
before anything else is done with it; over the budget a connection is closed at once and a request
answered 503.

Nothing a client sends is logged with a traceback: the front raises nothing, and a client over
its budget is logged in one line a second.
"""
from __future__ import annotations

import logging
from typing import Callable, Optional, Tuple

from minifilm.demo.budget import CONNECTION_COST, REQUEST_COST, AddressBudgets, address_of
from minifilm.demo.http_request import BadRequest, Request, head_end, parse_head

HEAD_TIMEOUT = 10.0             # seconds a client has to send a whole request head (or read its answers)
LINGER = 2.0                    # seconds the front discards input after its last answer before closing
WRITE_BUFFER_LIMIT = 1 << 20    # bytes of answers waiting for a client before it stops being read
WEBSOCKET_PATH = "/ws"
REASONS = {200: "OK", 400: "Bad Request", 403: "Forbidden", 404: "Not Found", 405: "Method Not Allowed",
           414: "URI Too Long", 426: "Upgrade Required", 431: "Request Header Fields Too Large",
           503: "Service Unavailable", 505: "HTTP Version Not Supported"}

#: answer(request, local address) -> (status, headers [(name, value)], body): the server's page
Answer = Callable[[Request, str], Tuple[int, list, bytes]]


def serialize(status: int, headers: list, body: bytes, keep_alive: bool) -> bytes:
    """The bytes of one response (``Connection`` set by the front, whatever ``headers`` say)."""
    lines = [f"HTTP/1.1 {status} {REASONS.get(status, 'Error')}"]
    lines += [f"{k}: {v}" for k, v in headers if k.lower() != "connection"]
    lines.append("Connection: keep-alive" if keep_alive else "Connection: close")
    return ("\r\n".join(lines) + "\r\n\r\n").encode("latin-1") + body


def plain(status: int, text: str) -> Tuple[int, list, bytes]:
    body = text.encode("utf-8")
    return status, [("Content-Type", "text/plain; charset=utf-8"), ("Content-Length", str(len(body))),
                    ("Cache-Control", "no-store"), ("X-Content-Type-Options", "nosniff")], body


def with_http_front(Connection, answer_holder, budgets: AddressBudgets):
    """A subclass of the ``websockets`` connection class ``Connection`` (an asyncio protocol) that
    reads every connection's requests first (see the module's docstring).

    ``answer_holder``: an object whose ``answer`` attribute is the :data:`Answer` callable (the
    server sets it) and whose ``front_connections`` set holds the open connections (so that a
    stopping server can close the idle ones kept open for a next request); ``budgets``: the per-address budgets connections and requests take from.
    """
    from websockets.protocol import State    # the optional extra: imported by the caller already
    logger = logging.getLogger("minifilm.demo")

    class FrontConnection(Connection):
        def connection_made(self, transport) -> None:
            self._mode = "http"            # "http", "closing" (last answer sent), "websocket"
            self._buffer = b""
            self._held: Optional[bytes] = None     # bytes after a WebSocket opening, until it is answered
            self._held_eof = False
            self._peer_done = False
            self._timer = None
            self._address = address_of(transport.get_extra_info("peername"))
            self._refused = not self._take(CONNECTION_COST, "connections")
            if self._refused:                 # not even websockets' objects: a flood costs little
                self.transport = transport
                transport.close()
                return
            super().connection_made(transport)
            answer_holder.front_connections.add(self)
            self._arm(HEAD_TIMEOUT)

        def connection_lost(self, exc) -> None:
            self._disarm()
            if not self._refused:
                answer_holder.front_connections.discard(self)
                super().connection_lost(exc)

        def close_http(self) -> None:
            """Close the connection when it is not a WebSocket (the server is stopping)."""
            if self._mode != "websocket" and not self.transport.is_closing():
                self.transport.close()

        # ---- reading ------------------------------------------------------------------------
        def data_received(self, data: bytes) -> None:
            if self._refused:
                return
            if self._mode == "websocket":
                if self._held is not None:
                    self._held += data
                else:
                    super().data_received(data)
            elif self._mode == "http":
                self._buffer += data
                self._serve_buffered()
            # "closing": discarded

        def eof_received(self):
            if self._refused:
                return False
            if self._mode == "websocket":
                if self._held is not None:
                    self._held_eof = True
                    return True
                return super().eof_received()
            if self._mode == "closing":
                return False                 # both sides done: the transport closes
            self._peer_done = True
            self._serve_buffered()
            return True                       # the answers still being written go out first

        def _serve_buffered(self) -> None:
            """Answer every complete request in the buffer, in order, while the client reads."""
            while self._mode == "http" and not self.transport.is_closing():
                if self.transport.get_write_buffer_size() > WRITE_BUFFER_LIMIT:
                    self.transport.pause_reading()       # resumed in resume_writing
                    return
                try:
                    end = head_end(self._buffer)
                    if end is None:
                        if self._peer_done:
                            self._close_now()                # a cut-off head: nothing to answer
                        return
                    head, self._buffer = self._buffer[:end], self._buffer[end:]
                    request = parse_head(head)
                except BadRequest as e:
                    self._send(*plain(e.status, e.text), keep_alive=False)
                    return
                if not self._take(REQUEST_COST, "requests"):
                    self._send(*plain(503, "too many requests from this address; try again in a second"),
                               keep_alive=False)
                    return
                if request.method == "GET" and request.path == WEBSOCKET_PATH:
                    self._open_websocket(head)
                    return
                self._answer(request)
            if self._peer_done and self._mode == "http":
                self._close_now()

        def _answer(self, request: Request) -> None:
            if request.method not in ("GET", "HEAD"):
                status, headers, body = plain(405, f"{request.method} is not served here: only GET (and HEAD)")
                headers.append(("Allow", "GET, HEAD"))
                self._send(status, headers, body, keep_alive=False)
                return
            try:
                status, headers, body = answer_holder.answer(request, self._local())
            except Exception:  # noqa: BLE001 - a bug in answering one request must not end the server
                logger.error("minifilm demo: answering %s %s failed", request.method, request.target[:80],
                             exc_info=True)
                status, headers, body = plain(500, "internal error")
            if request.method == "HEAD":
                body = b""
            keep = request.keep_alive and status != 400 and status < 500   # 400: the head itself was wrong
            self._send(status, headers, body, keep_alive=keep)

        def _send(self, status: int, headers: list, body: bytes, keep_alive: bool) -> None:
            self.transport.write(serialize(status, headers, body, keep_alive))
            if keep_alive:
                self._arm(HEAD_TIMEOUT)           # the next request head, from now
                return
            self._mode = "closing"
            self._buffer = b""
            if self._peer_done or not self.transport.can_write_eof():
                self.transport.close()            # sends what is written, then closes
                return
            self.transport.write_eof()            # our side is done; the client reads the answer,
            self._arm(LINGER)                     # what it still sends is discarded, then close

        def _close_now(self) -> None:
            self._mode = "closing"
            self._disarm()
            self.transport.close()

        # ---- the WebSocket --------------------------------------------------------------------
        def _open_websocket(self, head: bytes) -> None:
            self._mode = "websocket"
            self._arm(HEAD_TIMEOUT)            # until the WebSocket is open (websockets' own timeout is off)
            self._held, self._buffer = self._buffer, b""
            held_eof, self._held_eof = self._peer_done, False
            super().data_received(head)        # websockets parses the request and answers it
            self._held_eof = self._held_eof or held_eof
            self._release_if_answered()

        def send_data(self) -> None:
            super().send_data()
            if getattr(self, "_held", None) is not None:
                self._release_if_answered()

        def _release_if_answered(self) -> None:
            """Give the held bytes to websockets once its handshake answer has gone out (frames of
            the open WebSocket then; after a refusal they are discarded)."""
            if self._held is None or (self.protocol.state is State.CONNECTING and not self.protocol.eof_sent):
                return
            if self.protocol.state is State.OPEN:
                self._disarm()
            held, self._held = self._held, None
            self.loop.call_soon(self._feed, held, self._held_eof)

        def _feed(self, data: bytes, eof: bool) -> None:
            if self.transport.is_closing():
                return
            if data:
                super().data_received(data)
            if eof and not self.transport.is_closing():
                if not super().eof_received():
                    self.transport.close()

        # ---- flow and time --------------------------------------------------------------------
        def resume_writing(self) -> None:
            super().resume_writing()
            if self._mode == "http":
                self.transport.resume_reading()
                self._serve_buffered()

        def _arm(self, seconds: float) -> None:
            self._disarm()
            self._timer = self.loop.call_later(seconds, self._timed_out)

        def _disarm(self) -> None:
            if self._timer is not None:
                self._timer.cancel()
                self._timer = None

        def _timed_out(self) -> None:
            self._timer = None
            if self._mode == "http":
                self.transport.abort()            # no whole request in time, or not reading its answers
            elif self._mode == "closing":
                self.transport.close()
            elif self.protocol.state is not State.OPEN:
                self.transport.abort()            # a WebSocket opening that never opened

        # ---- helpers -------------------------------------------------------------------------
        def _local(self) -> str:
            try:
                return str(self.transport.get_extra_info("sockname")[0])
            except (TypeError, IndexError):
                return ""

        def _take(self, cost: float, what: str) -> bool:
            taken, warn = budgets.take(self._address, cost)
            if warn:
                logger.warning("minifilm demo: %s opens connections and sends requests faster than its budget "
                               "(%.0f connections a second); the ones over it are refused (%s)",
                               self._address, budgets.rate / CONNECTION_COST, what)
            return taken

    return FrontConnection
