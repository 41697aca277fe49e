"""Fixtures of the fuzz suite: a copy of the session's tiny trained run (``tiny_run``, made once in
tests/conftest.py) that a case may change, and a demo server on the run."""
import shutil

import pytest


@pytest.fixture
def run(tiny_run, tmp_path):
    """A copy of the tiny run that the case may change (without its caches, generated files and pictures)."""
    folder = tmp_path / "run"
    shutil.copytree(tiny_run, folder, ignore=shutil.ignore_patterns("cache", "generated", "*.png"))
    return folder


@pytest.fixture(scope="module")
def server(tiny_run):
    """A demo server on the tiny run, on a free local port, for one test module (the modules that
    use it skip without the websockets package before asking for it)."""
    # here, not at the top: the demo needs the optional websockets package
    from minifilm.demo.character import DemoSettings
    from minifilm.demo.server import DemoServer
    from minifilm.demo.source import DemoSource
    source = DemoSource.run_folder(tiny_run)
    s = DemoServer(source, DemoSettings(style=source.default_style()), host="127.0.0.1", port=0,
                   max_characters=3, background_calibration=False)
    s.start()
    yield s
    s.stop()
