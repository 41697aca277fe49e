"""A page's frame budget: one page sending a flood must not take the frame loop's time.

Every message a page sends is parsed on the server's event-loop thread, which shares Python's GIL
with the frame loop. A real page sends at most one ``input`` per animation frame (60-144 a
second), a ``ping`` a second and the odd click; a script sending tens of thousands a second
slowed the loop from 60 to 49 fps and starved the other pages. So each connection gets a token
bucket: ``rate`` messages a second, bursts of up to ``rate``. Messages over it are dropped
unparsed (the page is told once per second), and a page that keeps flooding, more than
``2 * rate`` dropped within one second, is disconnected (close code 1008, policy violation).

The bucket counts WebSocket *frames*, not messages, as they come off the wire: text, binary and
continuation frames, and the control frames the transport would otherwise answer by itself
(ping, pong, close). A flood of 64k pings a second was answered with 64k pongs by the
transport, never reached the message loop, cut another page to 20 frames a second and was never
disconnected. :func:`budgeted_connection` hooks the budget in where each frame is parsed, before
any reply: a ping over the budget gets no pong, a message over it is dropped whole (all its
fragments), and a flooding page is failed at once (a close frame, then everything it still sends
is discarded unparsed), logged in one line.

What a client does between pages -- opening connections, sending HTTP requests -- takes from its
address's budget, in the same unit (:class:`AddressBudgets`, used by ``http_front.py``): a page's
own budget ends with its connection, so connection churn was free.
"""
from __future__ import annotations

import logging
import time
from typing import Callable, Optional

#: Messages a second one page may send (far above what the page itself sends; see above).
MESSAGES_PER_SECOND = 300
#: What opening a connection and sending an HTTP request take from the client address's budget,
#: in messages (:class:`AddressBudgets`): at most 50 connections a second from one address.
CONNECTION_COST = 6.0
REQUEST_COST = 1.0


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

    def take(self, cost: float = 1.0) -> bool:
        """Take ``cost`` messages' worth (1: a message; more for what costs more, see
        :data:`CONNECTION_COST`)."""
        now = self.clock()
        self.tokens = min(self.rate, self.tokens + (now - self.last) * self.rate)
        self.last = now
        self.should_warn = False
        if self.tokens >= cost:
            self.tokens -= cost
            return True
        if now - self.window_start >= 1.0:  # a new second of dropping
            self.window_start, self.dropped_in_window = now, 0
        self.dropped += 1
        self.dropped_in_window += 1
        self.should_warn = self.dropped_in_window == 1
        self.flooding = self.dropped_in_window > 2 * self.rate
        return False


class AddressBudgets:
    """One :class:`MessageBudget` per client address, for what a client does *between* pages:
    opening connections and sending HTTP requests (``http_front.py``).

    A page's own budget lives as long as its connection, so a client that opens and closes
    connections got a fresh one each time: four local clients opening ~180 connections a second
    each cost the frame loop half its frame rate (accepting a connection, reading its request and
    setting up the WebSocket machinery costs far more than parsing a message), and no budget saw
    it. So each address has a budget in the same unit, messages a second: a connection takes
    :data:`CONNECTION_COST` messages' worth, an HTTP request :data:`REQUEST_COST`. A page load
    (six files and one WebSocket, on at most seven connections) takes about 50 of the
    ``rate`` = 300 a second; a client over it has its connections closed unread and its requests
    answered 503, and is logged once per second of it. All clients on one machine are one address
    (they cannot be told apart), and addresses whose budget is full again are forgotten.
    """

    def __init__(self, rate: float = MESSAGES_PER_SECOND, clock: Callable[[], float] = time.monotonic,
                 max_addresses: int = 4096):
        self.rate, self.clock, self.max_addresses = float(rate), clock, int(max_addresses)
        self._budgets = {}

    def take(self, address: str, cost: float):
        """``(taken, should_warn)`` for ``cost`` messages' worth from ``address``'s budget."""
        budget = self._budgets.get(address)
        if budget is None:
            if len(self._budgets) >= self.max_addresses:
                self._forget_full()
            budget = self._budgets[address] = MessageBudget(self.rate, self.clock)
        taken = budget.take(cost)
        return taken, budget.should_warn

    def _forget_full(self) -> None:
        """Drop the addresses that have not spent anything for a second (their budget is full)."""
        now = self.clock()
        self._budgets = {a: b for a, b in self._budgets.items() if now - b.last < 1.0}
        if len(self._budgets) >= self.max_addresses:     # a flood of addresses: start again
            self._budgets.clear()


def address_of(peer) -> str:
    """The client address of a socket's peer name (``(host, port, ...)``), "?" when unknown."""
    try:
        return str(peer[0])
    except (TypeError, IndexError):
        return "?"


def budgeted_connection(ServerConnection, ProtocolError, Opcode):
    """A ``websockets`` ``ServerConnection`` subclass whose every received frame takes from its
    own :class:`MessageBudget` (``serve(..., create_connection=...)``).

    Arguments: the websockets classes (an optional dependency, imported by the caller).
    ``connection.on_over_budget(text)`` (set by the server's handler) is called with a warning for
    the page, once per second of dropping; ``connection.flooded`` is True once it was cut off.
    """
    data_opcodes = (Opcode.TEXT, Opcode.BINARY)
    logger = logging.getLogger("minifilm.demo")

    class FloodError(ProtocolError):
        """Stops the parser after the connection was failed (parse() then discards the rest)."""

    class BudgetedConnection(ServerConnection):
        def __init__(self, protocol, *args, **kwargs):
            super().__init__(protocol, *args, **kwargs)
            self.budget = MessageBudget()
            self.on_over_budget: Optional[Callable[[str], None]] = None
            self.flooded = False
            self._dropping_message = False       # the fragments of a message over the budget
            self._recv_frame = protocol.recv_frame
            protocol.recv_frame = self._budgeted_frame

        def _budgeted_frame(self, frame) -> None:
            if frame.opcode in data_opcodes:
                self._dropping_message = False
            elif frame.opcode is not Opcode.CONT:
                pass
            elif self._dropping_message:           # the rest of a dropped message: counted, dropped
                self.budget.take()
                if frame.fin:
                    self._dropping_message = False
                self._check_flood()
                return
            if self.budget.take() or frame.opcode is Opcode.CLOSE or frame.opcode is Opcode.CONT:
                # a close is always answered; a fragment of a message already let in is passed on
                # (dropping it would corrupt the message), but it took from the budget all the same
                self._check_flood()
                self._recv_frame(frame)
                return
            self._check_flood()
            if frame.opcode in data_opcodes and not frame.fin:
                self._dropping_message = True
            if self.budget.should_warn and self.on_over_budget is not None:
                self.on_over_budget(f"too many messages: at most {self.budget.rate:.0f} a second; "
                                    "the ones over that are dropped")

        def send_data(self) -> None:
            """What the protocol has to send, as one write (the library writes each frame on its
            own: after a peer hung up mid-flood, each of up to ``rate`` pongs was a failed write
            and, past the fifth, a "socket.send() raised exception" line on stderr); nothing once
            the transport is closing."""
            pending = b""
            for data in self.protocol.data_to_send():
                if data:
                    pending += data
                    continue
                self._write(pending)             # b"": end of the stream (half-close when possible)
                pending = b""
                if not self.transport.is_closing():
                    if self.transport.can_write_eof():
                        try:
                            self.transport.write_eof()
                        except Exception:  # noqa: BLE001 - as the library: the socket may be gone
                            pass
                    else:
                        self.transport.close()
            self._write(pending)

        def _write(self, data: bytes) -> None:
            if data and not self.transport.is_closing():
                self.transport.write(data)

        def _check_flood(self) -> None:
            if not self.budget.flooding or self.flooded:
                return
            self.flooded = True
            reason = f"too many messages (over {self.budget.rate:.0f} a second)"
            logger.warning("minifilm demo: a page at %s sent %s; disconnected",
                           _address(self.remote_address), reason)
            self.protocol.fail(1008, reason)
            raise FloodError(reason)

    return BudgetedConnection


def _address(address) -> str:
    try:
        return f"{address[0]}:{address[1]}"
    except (TypeError, IndexError):
        return "?"
