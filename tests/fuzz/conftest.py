"""Fixtures of the fuzz suite: one tiny trained run (a few seconds) whose files the cases mutate,
a copy of it a case may change, and a demo server on it."""
import shutil
from dataclasses import replace

import pytest

from minifilm.pipeline import train_small


@pytest.fixture(scope="session")
def tiny_run(tmp_path_factory):
    """A run folder of the main job in miniature (two synthetic styles, one epoch): model.npz,
    styles.npz, starts.npz, run.json, skeleton.bvh. Tests copy it; they never change it."""
    out = tmp_path_factory.mktemp("fuzz_run")
    s = replace(train_small.Settings(out=out).quick(), styles=("Neutral", "LeftHop"), gaits=("FW",),
                seconds_per_clip=6.0, epochs=1, generate_seconds=0.5)
    train_small.run(s)
    return out


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
