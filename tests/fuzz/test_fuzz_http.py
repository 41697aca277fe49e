"""The demo server's HTTP front under raw-socket clients: pipelining, half-close, early close,
slowloris, garbage, every method, connection churn.

A real server is started on 127.0.0.1 (a miniature run); each case talks to it through a plain
socket, so nothing normalises what is sent. Whatever a client does: every complete request it sent
is answered, in order, or the connection is closed cleanly after an error answer; only GET is
served (HEAD: the same headers, no body; other methods 405; a lower-case or malformed method 400);
nothing is logged with a traceback or at ERROR; and a page that is open keeps getting frames.

Cases: 24 pipelining + 40 random clients + 60 methods x targets + 14 malformed heads + 4 timeouts
and keep-alive + 5 budget = 147.
"""
import logging
import random
import re
import socket
import struct
import time

import pytest

websockets = pytest.importorskip("websockets", reason="the demo needs the websockets package")

from minifilm.demo import http_front  # noqa: E402
from minifilm.demo.budget import CONNECTION_COST, MESSAGES_PER_SECOND, REQUEST_COST, AddressBudgets  # noqa: E402
from minifilm.demo.client import DemoClient  # noqa: E402

UPGRADE = ("Upgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
           "Sec-WebSocket-Version: 13\r\n")


@pytest.fixture(autouse=True)
def no_tracebacks(caplog):
    """Every case: nothing logged with a traceback or at ERROR."""
    caplog.set_level(logging.DEBUG)
    yield
    bad = [r.getMessage() for r in caplog.records if r.exc_info or r.levelno >= logging.ERROR]
    assert not bad, bad


@pytest.fixture(autouse=True)
def fresh_budget(server):
    """Each case starts with its address's budget full (the budget has its own cases)."""
    server.address_budgets._budgets.clear()


def request(port, method="GET", target="/", extra=""):
    return f"{method} {target} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n{extra}\r\n".encode("latin-1")


def talk(port, data: bytes, shut=False, timeout=10.0, chunks=1) -> bytes:
    """Send ``data`` (in ``chunks`` writes), half-close when ``shut``, read until the server closes."""
    with socket.create_connection(("127.0.0.1", port), timeout=timeout) as s:
        step = max(1, -(-len(data) // chunks))
        for i in range(0, len(data), step):
            s.sendall(data[i:i + step])
        if shut:
            s.shutdown(socket.SHUT_WR)
        out = b""
        while True:
            try:
                chunk = s.recv(1 << 16)
            except ConnectionResetError:
                raise AssertionError(f"the server reset the connection after {len(out)} bytes") from None
            if not chunk:
                return out
            out += chunk


def responses(data: bytes, methods) -> list:
    """(status, headers {lower name: value}, body) of each response in ``data``; ``methods``: the
    request method of each, in order (a HEAD answer has no body whatever its Content-Length)."""
    out, methods = [], list(methods)
    while data:
        head, sep, rest = data.partition(b"\r\n\r\n")
        assert sep, f"a cut-off response head: {data[:200]!r}"
        lines = head.decode("latin-1").split("\r\n")
        assert re.fullmatch(r"HTTP/1\.1 \d{3} .+", lines[0]), lines[0]
        headers = {k.lower(): v.strip() for k, _, v in (l.partition(":") for l in lines[1:])}
        n = 0 if (methods and methods[len(out)] == "HEAD") else int(headers["content-length"])
        out.append((int(lines[0].split()[1]), headers, rest[:n]))
        assert len(rest) >= n, "a cut-off body"
        data = rest[n:]
    return out


# ---- pipelining -------------------------------------------------------------------------------
PAGES = {"/": 200, "/demo.js": 200, "/demo.css": 200, "/nope": 404, "/scene.js?x=1": 200}


@pytest.mark.parametrize("n", [2, 3, 10])
@pytest.mark.parametrize("ending", ["close-header", "half-close"])
@pytest.mark.parametrize("seed", range(4))
def test_pipelined_requests_are_each_answered_in_order(server, n, ending, seed):
    rng = random.Random(seed * 100 + n)
    targets = [rng.choice(list(PAGES)) for _ in range(n)]
    methods = [rng.choice(["GET", "GET", "HEAD"]) for _ in range(n)]
    data = b"".join(request(server.port, m, t, "Connection: close\r\n" if (ending == "close-header" and i == n - 1)
                            else "") for i, (m, t) in enumerate(zip(methods, targets)))
    got = responses(talk(server.port, data, shut=ending == "half-close", chunks=rng.choice([1, 1, 3])), methods)
    assert [s for s, _, _ in got] == [PAGES[t] for t in targets]
    for (status, headers, body), target, method in zip(got, targets, methods):
        if status == 200:
            expected = server.site.get(target)[0]
            assert int(headers["content-length"]) == len(expected)
            assert body == (b"" if method == "HEAD" else expected)


# ---- random clients: half-close, early close, garbage, trickles ---------------------------------
def random_client(rng, port) -> tuple:
    """(bytes to send, how to end: "shut" / "close" / "reset", methods of the complete requests
    before anything malformed)"""
    parts, methods, broken = [], [], False
    for _ in range(rng.choice([1, 2, 3, 6])):
        kind = rng.random()
        if kind < 0.5:
            m = rng.choice(["GET", "HEAD"])
            parts.append(request(port, m, rng.choice(list(PAGES))))
            if not broken:
                methods.append(m)
        elif kind < 0.6:
            parts.append(request(port, "GET", "/ws", UPGRADE))     # a WebSocket, then more bytes
            broken = True
        elif kind < 0.8:
            parts.append(bytes(rng.getrandbits(8) for _ in range(rng.choice([1, 10, 300]))) + b"\r\n\r\n")
            broken = True
        else:
            parts.append(request(port)[:rng.randrange(1, 30)])       # a head cut short
            broken = True
    return b"".join(parts), rng.choice(["shut", "close", "reset"]), methods


@pytest.mark.parametrize("seed", range(40))
def test_random_clients_end_only_their_own_connection(server, seed):
    rng = random.Random(seed)
    data, end, methods = random_client(rng, server.port)
    with socket.create_connection(("127.0.0.1", server.port), timeout=10) as s:
        s.sendall(data)
        if end == "reset":            # close with RST, before reading anything
            s.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        elif end == "shut":
            s.shutdown(socket.SHUT_WR)
            out = b""
            try:
                while True:
                    chunk = s.recv(1 << 16)
                    if not chunk:
                        break
                    out += chunk
            except (socket.timeout, ConnectionResetError):
                pytest.fail(f"no clean end after half-close: {out[:200]!r}")
            statuses = re.findall(rb"HTTP/1\.1 (\d{3}) ", out)
            assert len(statuses) >= len(methods), (statuses, methods)
    with DemoClient(server.url) as page:               # the server still serves pages
        before = page.next_frame()["n"]
        assert page.next_frame()["n"] > before


# ---- methods ----------------------------------------------------------------------------------
METHODS = ["GET", "HEAD", "POST", "PUT", "DELETE", "TRACE", "OPTIONS", "PATCH", "CONNECT", "PROPFIND",
           "get", "head", "Get", "G@T", "GE T"]
TARGETS = {"/": 200, "/demo.js": 200, "/nope": 404, "/ws": 426}


@pytest.mark.parametrize("target", list(TARGETS))
@pytest.mark.parametrize("method", METHODS)
def test_only_get_is_served(server, method, target):
    data = request(server.port, method, target, "Connection: close\r\n")
    got = responses(talk(server.port, data), [method])
    assert len(got) == 1
    status, headers, body = got[0]
    if method in ("GET", "HEAD"):
        assert status == TARGETS[target]
        if method == "HEAD" and target != "/ws":      # (a GET of /ws is websockets' answer, not a file)
            full = responses(talk(server.port, request(server.port, "GET", target, "Connection: close\r\n")),
                             ["GET"])[0]
            assert body == b"" and headers["content-length"] == full[1]["content-length"]
    elif re.fullmatch("[A-Z]+", method):
        assert status == 405 and headers["allow"] == "GET, HEAD", (status, body)
    else:
        assert status == 400, (status, body)


MALFORMED = {
    "no version": (b"GET /\r\nHost: h\r\n\r\n", 400),
    "HTTP/2": (b"GET / HTTP/2.0\r\nHost: {host}\r\n\r\n", 505),
    "not HTTP": (b"GET / SPDY/3\r\nHost: {host}\r\n\r\n", 400),
    "two spaces": (b"GET  / HTTP/1.1\r\nHost: {host}\r\n\r\n", 400),
    "absolute form": (b"GET http://x/ HTTP/1.1\r\nHost: {host}\r\n\r\n", 400),
    "folded header": (b"GET / HTTP/1.1\r\nHost: {host}\r\n continued\r\n\r\n", 400),
    "space before colon": (b"GET / HTTP/1.1\r\nHost : {host}\r\n\r\n", 400),
    "no colon": (b"GET / HTTP/1.1\r\nHost {host}\r\n\r\n", 400),
    "a body": (b"GET / HTTP/1.1\r\nHost: {host}\r\nContent-Length: 5\r\n\r\nhello", 400),
    "chunked": (b"GET / HTTP/1.1\r\nHost: {host}\r\nTransfer-Encoding: chunked\r\n\r\n0\r\n\r\n", 400),
    "long line": (b"GET /" + b"a" * 9000 + b" HTTP/1.1\r\nHost: {host}\r\n\r\n", 414),
    "many headers": (b"GET / HTTP/1.1\r\nHost: {host}\r\n" + b"X-A: b\r\n" * 200 + b"\r\n", 431),
    "no host": (b"GET / HTTP/1.1\r\n\r\n", 400),
    "NUL": (b"\x00" * 10 + b"\r\n\r\n", 400),
}


@pytest.mark.parametrize("name", list(MALFORMED))
def test_malformed_heads_are_answered_then_closed(server, name):
    data, expected = MALFORMED[name]
    data = data.replace(b"{host}", f"127.0.0.1:{server.port}".encode())
    got = responses(talk(server.port, data + request(server.port)), ["GET", "GET"])
    assert [s for s, _, _ in got] == [expected]              # then a clean close: nothing after it
    assert got[0][1]["connection"] == "close"


# ---- timeouts and closes ------------------------------------------------------------------------
@pytest.fixture
def short_timeout(monkeypatch):
    monkeypatch.setattr(http_front, "HEAD_TIMEOUT", 0.3)


@pytest.mark.parametrize("sent", [b"", b"GET / HTTP/1.1\r\nHo", b"GET /ws HTTP/1.1\r\n"])
def test_a_slow_or_silent_client_is_cut_off(server, short_timeout, sent):
    with socket.create_connection(("127.0.0.1", server.port), timeout=30) as s:
        s.sendall(sent)
        try:
            assert s.recv(100) == b""                       # closed by the server, answered nothing
        except ConnectionResetError:
            pass


def test_a_kept_alive_connection_serves_the_next_request(server):
    with socket.create_connection(("127.0.0.1", server.port), timeout=10) as s:
        for target in ("/", "/demo.css", "/demo.js"):
            s.sendall(request(server.port, "GET", target))
            data = b""
            while b"\r\n\r\n" not in data or len(data.partition(b"\r\n\r\n")[2]) < len(server.site.get(target)[0]):
                chunk = s.recv(1 << 16)
                assert chunk, data[:300]                    # closed before the whole answer came
                data += chunk
            assert data.startswith(b"HTTP/1.1 200 ") and b"Connection: keep-alive" in data


# ---- the address budget -------------------------------------------------------------------------
class Clock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def test_connections_take_from_the_address_budget():
    clock = Clock()
    budgets = AddressBudgets(clock=clock)
    per_second = int(MESSAGES_PER_SECOND // CONNECTION_COST)
    taken = [budgets.take("127.0.0.1", CONNECTION_COST) for _ in range(per_second + 10)]
    assert [t for t, _ in taken].count(True) == per_second
    assert [w for _, w in taken].count(True) == 1                    # told once
    assert budgets.take("10.0.0.2", CONNECTION_COST)[0]                 # another address: its own
    clock.t = 1.0
    assert budgets.take("127.0.0.1", CONNECTION_COST)[0]               # refilled


def test_requests_take_from_the_same_budget():
    budgets = AddressBudgets(clock=Clock())
    connections = int(MESSAGES_PER_SECOND // CONNECTION_COST) - 1
    for _ in range(connections):
        assert budgets.take("a", CONNECTION_COST)[0]
    left = MESSAGES_PER_SECOND - connections * CONNECTION_COST
    assert sum(budgets.take("a", 1.0)[0] for _ in range(100)) == left


def test_many_addresses_are_forgotten_once_full():
    clock = Clock()
    budgets = AddressBudgets(clock=clock, max_addresses=10)
    for i in range(10):
        budgets.take(f"10.0.0.{i}", 1.0)
    clock.t = 2.0
    budgets.take("10.0.1.1", 1.0)
    assert len(budgets._budgets) == 1


@pytest.fixture
def frozen_budget(server):
    """The address budget with its clock stopped: what a second allows, however slowly the
    machine runs the case (no refill while it runs)."""
    server.address_budgets._budgets.clear()
    server.address_budgets.clock = lambda: 0.0
    yield
    server.address_budgets.clock = time.monotonic
    server.address_budgets._budgets.clear()


def test_connection_churn_is_refused_over_the_budget_and_a_page_keeps_its_frames(server, frozen_budget, caplog):
    per_second = int(MESSAGES_PER_SECOND // CONNECTION_COST)
    with DemoClient(server.url) as page:                     # one connection of the second's budget
        page.next_frame()
        answers = []
        for _ in range(2 * per_second):
            with socket.create_connection(("127.0.0.1", server.port), timeout=10) as s:
                try:
                    s.sendall(request(server.port, "GET", "/demo.css", "Connection: close\r\n"))
                    data = s.recv(64)
                except (ConnectionResetError, BrokenPipeError):
                    data = b""
                answers.append(data[9:12] if data else b"closed")
        # a connection and its request take CONNECTION_COST + REQUEST_COST; the page took one such
        whole = int(MESSAGES_PER_SECOND // (CONNECTION_COST + REQUEST_COST)) - 1
        assert answers[:whole] == [b"200"] * whole, answers
        assert set(answers[whole:]) <= {b"503", b"closed"} and answers[-1] == b"closed", answers
        before = page.next_frame()["n"]
        assert page.next_frame()["n"] > before                 # the open page is not cut off
    warnings = [r for r in caplog.records if "faster than its budget" in r.getMessage()]
    assert len(warnings) == 1, [r.getMessage() for r in warnings]


def test_a_pipelined_flood_is_answered_503_past_the_budget(server, frozen_budget):
    n = MESSAGES_PER_SECOND + 50
    out = talk(server.port, request(server.port, "HEAD", "/demo.css") * n, shut=True)
    statuses = re.findall(rb"HTTP/1\.1 (\d{3}) ", out)
    served = int(MESSAGES_PER_SECOND - CONNECTION_COST)
    assert statuses == [b"200"] * served + [b"503"]
