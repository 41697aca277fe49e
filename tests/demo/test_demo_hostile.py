"""Hostile clients of the demo server , spoken frame by frame over a plain
socket (minifilm.demo.client.RawWebSocket): control-frame and continuation floods are counted
against the page's budget and cut off, logged once; doubled Host or Origin headers are a 400,
never a 500; the Host / Origin allow-list holds on every bind address; ``--host ''`` is refused
and ``0.0.0.0`` prints a URL a browser can open."""
import json
import logging
import socket
import subprocess
import sys
import time

import pytest

from demo_helpers import budget_clock_stopped, http_get, serve, tiny_source  # noqa: F401  (fixtures)
from minifilm.demo.budget import MESSAGES_PER_SECOND
from minifilm.demo.character import DemoSettings
from minifilm.demo.client import DemoClient, RawWebSocket
from minifilm.demo.hosts import HostAllowList, is_loopback
from minifilm.demo.server import DemoServer

websockets = pytest.importorskip("websockets")

PING, PONG, TEXT, CONT, CLOSE = 0x9, 0xA, 0x1, 0x0, 0x8
FLOOD = 40 * MESSAGES_PER_SECOND        # far over the budget (its clock stopped by the flood tests)


@pytest.fixture(scope="module")
def server(tiny_source):
    s = serve(tiny_source, max_characters=3)
    yield s
    s.stop()


def close_code(frames) -> int:
    closes = [payload for op, payload in frames if op == CLOSE]
    assert closes, "the server never closed the connection"
    return int.from_bytes(closes[0][:2], "big")


@pytest.mark.parametrize("name,flood", [
    ("pings", [RawWebSocket.frame(PING, i.to_bytes(4, "big")) for i in range(FLOOD)]),
    ("pongs", [RawWebSocket.frame(PONG, b"unasked") for _ in range(FLOOD)]),
    ("continuation frames", [RawWebSocket.frame(TEXT, b'{"type":', fin=False)]
     + [RawWebSocket.frame(CONT, b"", fin=False) for _ in range(FLOOD)]),
    ("empty text frames", [RawWebSocket.frame(TEXT, b"") for _ in range(FLOOD)]),
])
def test_a_flood_of_any_kind_of_frame_is_cut_off_and_answered_at_most_a_budget_of_times(server, name, flood,
                                                                                        budget_clock_stopped):
    with RawWebSocket(server.port) as raw:
        assert raw.status == 101
        raw.send_raw(b"".join(flood))
        frames = RawWebSocket.frames(raw.read_until_closed(timeout=10))
    assert close_code(frames) == 1008, name
    pongs = sum(op == PONG for op, _ in frames)
    assert pongs <= 2 * MESSAGES_PER_SECOND, f"{pongs} pongs answered a flood of {FLOOD} {name}"


def test_pings_within_the_budget_are_still_answered(server):
    with RawWebSocket(server.port) as raw:
        for i in range(5):
            raw.send_frame(PING, b"hello%d" % i)
        raw.sock.settimeout(5)
        data, end = b"", time.monotonic() + 5
        while sum(op == PONG for op, _ in RawWebSocket.frames(data)) < 5 and time.monotonic() < end:
            data += raw.sock.recv(65536)
    pongs = [p for op, p in RawWebSocket.frames(data) if op == PONG]
    assert pongs == [b"hello%d" % i for i in range(5)]


def test_a_ping_flood_leaves_the_other_pages_frames_coming_and_is_logged_once(server, caplog, budget_clock_stopped):
    caplog.set_level(logging.WARNING)
    with DemoClient(server.url) as other:
        floods = []
        for _ in range(3):                       # the same page three times: three lines, no more
            raw = RawWebSocket(server.port)
            raw.send_raw(b"".join(RawWebSocket.frame(PING, b"p") for _ in range(FLOOD)))
            floods.append(raw)
        for raw in floods:
            raw.read_until_closed(timeout=10)
            raw.close()
        before = other.next_frame()["n"]
        assert other.next_frame()["n"] > before
    time.sleep(0.5)
    lines = [r.getMessage() for r in caplog.records]
    assert sum("disconnected" in m for m in lines) == 3, lines
    assert not [m for m in lines if "socket.send() raised exception" in m]


def test_a_flooder_that_hangs_up_leaves_no_stream_of_log_lines(server, caplog, budget_clock_stopped):
    caplog.set_level(logging.WARNING)
    for _ in range(3):
        raw = RawWebSocket(server.port)
        raw.send_raw(b"".join(RawWebSocket.frame(PING, b"p" * 100) for _ in range(FLOOD)))
        raw.sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\1\0\0\0\0\0\0\0")     # RST, unread
        raw.close()
    time.sleep(1.0)
    with DemoClient(server.url) as page:
        page.next_frame()
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) <= 3, lines


@pytest.mark.parametrize("header", ["Host", "Origin"])
def test_two_host_or_origin_headers_are_a_bad_request_not_a_server_error(server, header, caplog):
    caplog.set_level(logging.DEBUG)
    own = f"127.0.0.1:{server.port}"
    value = own if header == "Host" else f"http://{own}"
    extra = f"{header}: {value}\r\n" if header == "Host" else f"{header}: {value}\r\n{header}: {value}\r\n"
    upgrade = ("Upgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
               "Sec-WebSocket-Version: 13\r\n")
    for target in ("/", "/ws"):
        status, body = http_get_raw(server.port, target, f"Host: {own}\r\n{extra}{upgrade}")
        assert status == 400, (header, target, status, body[:200])
        assert header.encode() in body
    assert not [r for r in caplog.records if r.exc_info], "a traceback was logged"


def http_get_raw(port, target, headers):
    with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
        s.sendall(f"GET {target} HTTP/1.1\r\n{headers}\r\n".encode("latin-1"))
        data = b""
        while b"\r\n\r\n" not in data or len(data) < 4096:
            chunk = s.recv(65536)
            if not chunk:
                break
            data += chunk
    head, _, body = data.partition(b"\r\n\r\n")
    return int(head.split(b" ", 2)[1]), body


def test_a_request_without_a_host_is_refused(server):
    status, _ = http_get_raw(server.port, "/", "Connection: close\r\n")
    assert status == 400


@pytest.fixture(scope="module")
def everywhere(tiny_source):
    """A server bound to every interface (0.0.0.0), with one extra allowed name."""
    s = DemoServer(tiny_source, DemoSettings(style=tiny_source.default_style()), host="0.0.0.0", port=0,
                   max_characters=2, background_calibration=False, allow_hosts=["demo.example.org"])
    s.start()
    yield s
    s.stop()


def test_bound_to_every_interface_it_prints_a_url_a_browser_can_open(everywhere):
    assert everywhere.url == f"http://127.0.0.1:{everywhere.port}/"
    status, _ = http_get(everywhere.port, "/", host=f"127.0.0.1:{everywhere.port}")
    assert status == 200


@pytest.mark.parametrize("host,allowed", [
    ("evil.example", False), ("127.0.0.1.nip.io", False), ("localhost.evil.example", False), ("", False),
    ("127.0.0.1", True), ("127.1", True), ("localhost", True), ("[::1]", True), ("LOCALHOST", True),
    ("demo.example.org", True), (socket.gethostname(), True),
])
def test_the_host_allow_list_holds_on_every_interface(everywhere, host, allowed):
    status, body = http_get(everywhere.port, "/", host=f"{host}:{everywhere.port}")
    assert status == (200 if allowed else 403), (host, status, body[:120])


def test_a_host_naming_another_port_is_refused(everywhere):
    assert http_get(everywhere.port, "/", host=f"127.0.0.1:{everywhere.port + 1}")[0] == 403


def test_bound_to_every_interface_a_websocket_from_another_site_is_refused(everywhere):
    with pytest.raises(websockets.exceptions.InvalidStatus) as e:
        DemoClient(everywhere.url, origin=f"http://evil.example:{everywhere.port}")
    assert e.value.response.status_code == 403
    with DemoClient(everywhere.url, origin=f"http://localhost:{everywhere.port}") as page:
        assert page.hello["type"] == "hello"


@pytest.mark.parametrize("spelling", ["127.1", "127.0.0.1", "::1", "[::1]", "localhost", "127.255.0.9", "0x7f.1"])
def test_every_spelling_of_loopback_is_loopback(spelling):
    assert is_loopback(spelling)


@pytest.mark.parametrize("other", ["0.0.0.0", "", "10.0.0.1", "evil.example", "127.0.0.1.evil", "::"])
def test_other_addresses_are_not_loopback(other):
    assert not is_loopback(other)


def test_a_server_bound_to_127_1_answers_its_own_names(tiny_source):
    s = DemoServer(tiny_source, DemoSettings(style=tiny_source.default_style()), host="127.1", port=0,
                   max_characters=1, background_calibration=False)
    s.start()
    try:
        assert s.url == f"http://127.0.0.1:{s.port}/"
        for host in ("127.1", "127.0.0.1", "localhost"):
            assert http_get(s.port, "/", host=f"{host}:{s.port}")[0] == 200, host
        assert http_get(s.port, "/", host=f"evil.example:{s.port}")[0] == 403
    finally:
        s.stop()


@pytest.mark.parametrize("bad", ["", "   "])
def test_an_empty_host_to_listen_on_is_refused(tiny_source, bad):
    with pytest.raises(ValueError, match="--host"):
        DemoServer(tiny_source, DemoSettings(style=tiny_source.default_style()), host=bad, port=0)


def test_the_command_refuses_an_empty_host_in_one_line(tmp_path):
    folder = tmp_path / "not_read"        # the host is checked before anything is loaded
    folder.mkdir()
    r = subprocess.run([sys.executable, "-m", "minifilm", "demo", "--run", str(folder),
                        "--host", "", "--port", "0"], capture_output=True, text=True, timeout=60,
                       stdin=subprocess.DEVNULL)
    assert r.returncode == 2, (r.stdout, r.stderr)
    assert "--host" in r.stderr and "Traceback" not in r.stderr and "http://:" not in r.stdout


@pytest.mark.parametrize("bad", ["", "evil/../x", "a b", "x" * 300, "h\u00e9te"])
def test_allow_host_names_are_checked(tiny_source, bad):
    with pytest.raises(ValueError, match="--allow-host"):
        HostAllowList("127.0.0.1", [bad])


def test_messages_and_pings_within_the_budget_keep_the_page_steering(server):
    with DemoClient(server.url) as page:
        for _ in range(20):
            page.ws.ping()
        seq = page.send({"type": "input", "move": [0, 1], "turn": 0, "speed": 0})
        frame = page.wait_for(lambda m: m.get("type") == "frame" and m["ack"] == seq)
        assert frame["commanded"] > 0
        assert not [m for m in page.other if m.get("type") == "error"], json.dumps(page.other)[:300]
