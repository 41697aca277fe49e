"""Helpers of the demo tests: the released network or a miniature run folder, a demo server on an
ephemeral 127.0.0.1 port, raw HTTP requests, headless Chromium.

(A module with its own name rather than ``conftest``; its fixtures are imported by the test
modules that use them.)
"""
from __future__ import annotations

import os
import shutil
import socket
from dataclasses import replace
from pathlib import Path

import pytest

from repo_paths import SHARED_DATA, need_data

websockets = pytest.importorskip("websockets", reason="the demo needs the websockets package (pip install "
                                                      "'minifilm[demo]')")

from minifilm.demo.character import DemoSettings  # noqa: E402  (after the skip: it needs nothing more)
from minifilm.demo.server import DemoServer  # noqa: E402
from minifilm.demo.source import DemoSource  # noqa: E402
from minifilm.pipeline.train_small import Settings, run  # noqa: E402

RELEASED = SHARED_DATA / "released-lpn"
CHROMIUM = os.environ.get("MINIFILM_CHROMIUM") or shutil.which("chromium") or "/usr/bin/chromium"
# Software WebGL: headless machines have no GPU, and SwiftShader renders the same everywhere.
CHROMIUM_ARGS = ["--use-angle=swiftshader", "--enable-unsafe-swiftshader"]


def make_tiny_run(out: Path) -> Path:
    """A miniature run folder (two styles, one gait, one epoch; about a second): enough to serve,
    not to follow commands."""
    settings = replace(Settings(out=out).quick(), styles=("Neutral", "LeftHop"), gaits=("FW",),
                       seconds_per_clip=6.0, epochs=1, generate_seconds=0.5)
    run(settings)
    return out


@pytest.fixture(scope="module")
def tiny_source(tmp_path_factory) -> DemoSource:
    return DemoSource.run_folder(make_tiny_run(tmp_path_factory.mktemp("tiny_run")))


@pytest.fixture(scope="module")
def released_source() -> DemoSource:
    """The authors' released network; skips when it is not in the shared data folder."""
    need_data(RELEASED / "Xmean.bin", "the released network")      # skipped here, failed in CI
    return DemoSource.released(RELEASED)


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


@pytest.fixture(scope="module")
def browser():
    """Headless Chromium through playwright; skips with the reason when either is unavailable.
    (Module-scoped: one sync playwright per thread at a time, and the viewer tests start their own.)"""
    try:
        from playwright.sync_api import sync_playwright  # optional: browser tests only
    except ImportError:
        pytest.skip("playwright is not installed (pip install playwright; no browser download needed)")
    if not Path(CHROMIUM).is_file():
        pytest.skip(f"Chromium not found at {CHROMIUM} (apt-get install chromium, or set MINIFILM_CHROMIUM)")
    manager = sync_playwright().start()
    try:
        chromium = manager.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
    except Exception as e:  # noqa: BLE001 - any launch failure means: cannot test here
        manager.stop()
        pytest.skip(f"Chromium at {CHROMIUM} could not be launched: {e}")
    yield chromium
    chromium.close()
    manager.stop()
