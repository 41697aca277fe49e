"""The demo server under random hostile clients: random sequences of
WebSocket frames (every opcode, reserved ones included, fragments, floods of control frames) and
random request headers (doubled, missing, malformed Host and Origin). Whatever is sent, the
server answers with a 4xx or closes that one connection with a protocol close code, never a 500,
never a traceback in its log, never more pongs than a page's budget, and another page keeps
getting frames.
"""
import logging
import random
import socket

import pytest

websockets = pytest.importorskip("websockets", reason="the demo needs the websockets package")

from minifilm.demo.budget import MESSAGES_PER_SECOND  # noqa: E402
from minifilm.demo.client import DemoClient, RawWebSocket  # noqa: E402

#: close codes a hostile connection may end with: normal, going away, protocol error, bad data,
#: policy (over the budget), too big
CLOSE_CODES = {1000, 1001, 1002, 1007, 1008, 1009}
OPCODES = [0x0, 0x1, 0x2, 0x8, 0x9, 0xA, 0x3, 0x7, 0xB, 0xF]


def random_frames(rng: random.Random) -> bytes:
    out = []
    for _ in range(rng.choice([1, 5, 50, 500, 5000])):
        kind = rng.random()
        if kind < 0.5:                       # a control frame, the common flood
            opcode = rng.choice([0x9, 0xA])
        else:
            opcode = rng.choice(OPCODES)
        payload = bytes(rng.getrandbits(8) for _ in range(rng.choice([0, 1, 10, 125])))
        if opcode == 0x1 and rng.random() < 0.5:
            payload = b'{"type":"ping","t":1}'
        frame = bytearray(RawWebSocket.frame(opcode, payload, fin=rng.random() < 0.8))
        if rng.random() < 0.05:
            frame[0] |= 0x40                 # a reserved bit
        if rng.random() < 0.05:
            frame[1] &= 0x7F                 # unmasked: not allowed from a client
        out.append(bytes(frame))
    return b"".join(out)


@pytest.mark.parametrize("seed", range(24))
def test_random_frames_end_at_most_that_connection(server, seed, caplog):
    caplog.set_level(logging.WARNING)
    rng = random.Random(seed)
    with RawWebSocket(server.port) as raw:
        assert raw.status == 101
        raw.send_raw(random_frames(rng))
        frames = RawWebSocket.frames(raw.read_until_closed(timeout=rng.choice([0.5, 3])))
    closes = [int.from_bytes(p[:2], "big") for op, p in frames if op == 0x8 and len(p) >= 2]
    assert all(c in CLOSE_CODES for c in closes), closes
    assert sum(op == 0xA for op, _ in frames) <= 2 * MESSAGES_PER_SECOND
    with DemoClient(server.url) as other:
        before = other.next_frame()["n"]
        assert other.next_frame()["n"] > before
    assert not [r for r in caplog.records if r.exc_info or r.levelno >= logging.ERROR], \
        [r.getMessage() for r in caplog.records]


HOSTS = ["127.0.0.1:{port}", "localhost:{port}", "evil.example:{port}", "", "[::1", "[::1]:{port}", "::1",
         "127.0.0.1:99999999", "127.0.0.1:{port}:{port}", "\u0661\u0662\u0667.0.0.1:{port}", "x" * 5000,
         "127.0.0.1:-1", "127.0.0.1.:{port}", "LOCALHOST:{port}", "0.0.0.0:{port}", "user@127.0.0.1:{port}"]
ORIGINS = ["http://127.0.0.1:{port}", "null", "http://evil.example:{port}", "", "file://", "http://[::1",
           "http://127.0.0.1:{port}/x?y", "https://127.0.0.1:{port}", "http://localhost:{port}", "\u00ff" * 10]


@pytest.mark.parametrize("seed", range(40))
def test_random_headers_get_a_4xx_or_the_page_never_a_500(server, seed, caplog):
    caplog.set_level(logging.WARNING)
    rng = random.Random(1000 + seed)
    port = server.port
    lines = []
    for name, values in (("Host", HOSTS), ("Origin", ORIGINS)):
        for _ in range(rng.choice([0, 1, 1, 1, 2, 3])):
            lines.append(f"{name}: {rng.choice(values).format(port=port)}")
    if rng.random() < 0.6:
        lines += ["Upgrade: websocket", "Connection: Upgrade", "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==",
                  "Sec-WebSocket-Version: 13"]
        if rng.random() < 0.2:
            lines.append("Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==")
    rng.shuffle(lines)
    target = rng.choice(["/", "/ws", "/demo.js", "/nope"])
    with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
        s.sendall((f"GET {target} HTTP/1.1\r\n" + "".join(l + "\r\n" for l in lines) + "\r\n").encode("utf-8"))
        data = b""
        try:
            while b"\r\n\r\n" not in data:
                chunk = s.recv(65536)
                if not chunk:
                    break
                data += chunk
        except socket.timeout:
            pass
    status = int(data.split(b" ", 2)[1]) if data.startswith(b"HTTP/") else 0
    assert status in (0, 101, 200, 400, 403, 404, 426), (status, lines, data[:300])
    assert not [r for r in caplog.records if r.exc_info or r.levelno >= logging.ERROR], \
        [r.getMessage() for r in caplog.records]
