"""The demo server on an ephemeral 127.0.0.1 port (minifilm/demo/server.py, page_files.py), driven by a
Python WebSocket client: it serves its own files and nothing else, refuses other hosts and
origins, and a page connects, steers, gets an error reply for each bad message without losing
its connection, and frees its character when it leaves."""
import json
import time

import pytest

from demo_helpers import budget_clock_stopped, http_get, serve, tiny_source  # noqa: F401  (fixtures)
from minifilm.demo.client import DemoClient
from minifilm.demo.protocol import MAX_MESSAGE_BYTES, TRANSPORT_MAX_BYTES
from minifilm.demo.page_files import Site

websockets = pytest.importorskip("websockets")


@pytest.fixture(scope="module")
def server(tiny_source):
    s = serve(tiny_source, max_characters=2)
    yield s
    s.stop()


def wait_until(predicate, timeout=60.0):          # a deadline for what should happen at once, not a measure
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.02)
    return False


def test_it_listens_on_loopback_and_serves_the_page_and_its_files(server):
    assert server.url.startswith("http://127.0.0.1:") and server.port > 0
    for path, kind in [("/", b"<title>minifilm demo"), ("/demo.js", b"minifilmDemo"), ("/demo.css", b"#panel"),
                       ("/scene.js", b"export function createStage"), ("/three.module.min.js", b"REVISION")]:
        status, body = http_get(server.port, path)
        assert status == 200 and kind in body, path
    status, body = http_get(server.port, "/?reload=1")
    assert status == 200 and body == Site(f"minifilm demo: {server.source.name}").files["/"][0]


def test_every_response_forbids_loading_from_elsewhere(server):
    import socket
    with socket.create_connection(("127.0.0.1", server.port), timeout=10) as s:
        s.sendall(f"GET / HTTP/1.1\r\nHost: 127.0.0.1:{server.port}\r\n\r\n".encode())
        head = s.recv(65536).split(b"\r\n\r\n")[0].decode().lower()
    assert "content-security-policy: default-src 'none'; script-src 'self' 'sha256-" in head
    assert "connect-src 'self'" in head and "x-content-type-options: nosniff" in head


@pytest.mark.parametrize("target", [
    "/../../../../etc/passwd", "/..%2f..%2f..%2fetc%2fpasswd", "/%2e%2e/%2e%2e/etc/passwd", "//etc/passwd",
    "/demo.js/../../server.py", "/assets/demo.js", "/minifilm/demo/server.py", "/..\\..\\server.py",
    "/scene.js%00.html", "/vendor/three.module.min.js", "/demo.js/", "/DEMO.JS", "/favicon.ico",
    "http://127.0.0.1/../../etc/passwd",
])
def test_nothing_but_its_own_files_is_served(server, target):
    status, body = http_get(server.port, target)
    assert status in (400, 404), (target, status)
    assert b"root:" not in body and b"import" not in body


def test_requests_naming_another_host_are_refused(server):
    status, body = http_get(server.port, "/", host="evil.example:80")
    assert status == 403 and b"Host" in body
    status, _ = http_get(server.port, "/", host=f"localhost:{server.port}")
    assert status == 200


def test_a_websocket_from_another_sites_page_is_refused(server):
    with pytest.raises(websockets.exceptions.InvalidStatus) as e:
        DemoClient(server.url, origin="http://evil.example")
    assert e.value.response.status_code == 403
    with DemoClient(server.url, origin=f"http://127.0.0.1:{server.port}") as page:   # its own page
        assert page.hello["type"] == "hello"


def test_a_page_connects_steers_and_leaves(server, tiny_source):
    with DemoClient(server.url) as page:
        hello = page.hello
        assert hello["type"] == "hello" and hello["styles"] == tiny_source.library.names
        assert hello["fps"] == tiny_source.fps and len(hello["parents"]) == tiny_source.layout.n_joints
        assert server.stage.count == 1
        first = page.next_frame()
        seq = page.send({"type": "input", "move": [0, 1], "turn": 0, "speed": 1})
        frame = page.wait_for(lambda m: m.get("type") == "frame" and m["ack"] == seq)
        assert frame["commanded"] == pytest.approx(2.8) and frame["velocity"] == pytest.approx([0.0, 2.8])
        for _ in range(60):
            frame = page.next_frame()
        assert frame["n"] > first["n"] + 60 - 1
        moved = ((frame["root"][0] - first["root"][0]) ** 2 + (frame["root"][1] - first["root"][1]) ** 2) ** 0.5
        assert moved > 0.2
        pong = page.send({"type": "ping", "t": 12.5})
        assert page.wait_for(lambda m: m.get("type") == "pong")["seq"] == pong
    assert wait_until(lambda: server.stage.count == 0)            # its character was freed


def test_the_python_client_receives_a_recording_larger_than_a_page_may_send(server):
    """A recording's BVH text runs past the 64 KiB a page may send the server; the client takes it."""
    with DemoClient(server.url) as page:
        first = page.next_frame()
        page.wait_for(lambda m: m.get("type") == "frame" and m["n"] >= first["n"] + 120, timeout=120)
        seq = page.send({"type": "record", "seconds": 2, "gif": False})
        recording = page.wait_for(lambda m: m.get("type") == "recording" and m["seq"] == seq, timeout=120)
    assert len(recording["bvh"]) > TRANSPORT_MAX_BYTES and recording["bvh"].startswith("HIERARCHY")


def test_bad_messages_get_an_error_reply_and_the_connection_goes_on(server):
    bad = ["{not json", '{"type": "input", "move": [0, NaN], "turn": 0, "speed": 0}',
           json.dumps({"type": "style", "weights": {"Ninja": 1}}),
           json.dumps({"type": "style", "weights": {"Neutral": 1.5, "LeftHop": -0.5}}),
           json.dumps({"type": "reset", "pad": "x" * (2 * MAX_MESSAGE_BYTES)}), b"\x00\x01binary"]
    with DemoClient(server.url) as page:
        for message in bad:
            page.send(message)
        errors = [page.wait_for(lambda m: m.get("type") == "error") for _ in bad]
        reasons = " | ".join(e["message"] for e in errors)
        for why in ("not valid JSON", "NaN", "unknown style", ">= 0", "limit", "binary"):
            assert why in reasons
        before = page.next_frame()["n"]
        assert page.next_frame()["n"] > before                    # frames keep coming


def test_a_message_over_the_transport_limit_closes_only_that_connection(server):
    with DemoClient(server.url) as other:
        with DemoClient(server.url) as page:
            page.send("x" * (TRANSPORT_MAX_BYTES + 1))
            deadline = time.monotonic() + 60            # frames still come until the close arrives
            with pytest.raises(websockets.exceptions.ConnectionClosed) as e:
                while time.monotonic() < deadline:
                    page.recv(5)
            assert e.value.rcvd is not None and e.value.rcvd.code == 1009
        other.next_frame()
        assert wait_until(lambda: server.stage.count == 1)


def test_a_flooding_page_is_told_then_disconnected_and_the_others_carry_on(server, budget_clock_stopped):
    from minifilm.demo.budget import MESSAGES_PER_SECOND
    with DemoClient(server.url) as other:
        with DemoClient(server.url) as page:
            flood = json.dumps({"type": "input", "move": [0, 1], "turn": 0, "speed": 0})
            with pytest.raises(websockets.exceptions.ConnectionClosed) as e:
                # all in one instant of the budget's clock: a budget's worth let in, then more than
                # twice that dropped is a flood, however slowly this machine sends them
                for _ in range(4 * MESSAGES_PER_SECOND):
                    page.send(flood)
                for _ in range(10_000):                           # frames, then the close
                    page.recv()
            assert e.value.rcvd is not None and e.value.rcvd.code == 1008, e.value
            assert "too many messages" in e.value.rcvd.reason
        before = other.next_frame()["n"]
        assert other.next_frame()["n"] > before                   # the other page's frames keep coming
        assert wait_until(lambda: server.stage.count == 1)


def test_a_burst_over_the_budget_is_dropped_with_a_warning_and_the_page_stays(server, budget_clock_stopped):
    from minifilm.demo.budget import MESSAGES_PER_SECOND
    with DemoClient(server.url) as page:
        burst = json.dumps({"type": "input", "move": [0, 1], "turn": 0, "speed": 0})
        for _ in range(MESSAGES_PER_SECOND + 100):          # in one instant of the budget's clock: 100 over
            page.send(burst)
        warning = page.wait_for(lambda m: m.get("type") == "error")
        assert "too many messages" in warning["message"]
        before = page.next_frame()["n"]
        assert page.next_frame()["n"] > before


def test_a_page_beyond_the_limit_is_refused_clearly(server):
    with DemoClient(server.url), DemoClient(server.url):
        with DemoClient(server.url) as third:
            assert third.hello["type"] == "refused"
            assert "all 2 characters of this demo are in use" in third.hello["message"]
            with pytest.raises(websockets.exceptions.ConnectionClosed) as e:
                third.recv(5)
            assert e.value.rcvd.code == 1013
    assert wait_until(lambda: server.stage.count == 0)
    with DemoClient(server.url) as again:                          # freed: a new page gets one
        assert again.hello["type"] == "hello"
