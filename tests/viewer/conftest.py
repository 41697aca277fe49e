"""Fixtures of the viewer tests: a synthetic walker, real BVH files, headless Chromium."""
from __future__ import annotations

from pathlib import Path

import pytest

from minifilm.motion.motion import Motion
from repo_paths import need_data
from viewer_helpers import CHROMIUM, CHROMIUM_ARGS, synthetic_walker


@pytest.fixture
def walker() -> Motion:
    return synthetic_walker()


@pytest.fixture(scope="session")
def bandai_walk(shared_data) -> Path:
    """A real 30 fps BVH (Bandai dataset 2, ``normal`` walk); skips when the data is absent."""
    return need_data(shared_data / "bandai2" / "dataset-2_walk_normal_001.bvh", "a real BVH")


@pytest.fixture(scope="session")
def xia_walk(shared_data) -> Path:
    """A real 120 fps BVH (Xia et al., CMU skeleton); skips when the data is absent."""
    return need_data(shared_data / "bvh" / "xia" / "neutral_01_000.bvh", "a real BVH")


@pytest.fixture(scope="module")
def browser():
    """Headless Chromium through playwright; skips with the reason when either is unavailable.
    (Module-scoped: one sync playwright per thread at a time, and the demo's tests start their own.)"""
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.skip("playwright is not installed (pip install playwright; no browser download needed)")
    if not Path(CHROMIUM).is_file():
        pytest.skip(f"Chromium not found at {CHROMIUM} (apt-get install chromium, or set MINIFILM_CHROMIUM)")
    manager = sync_playwright().start()
    try:
        browser = manager.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
    except Exception as e:  # noqa: BLE001 - any launch failure means: cannot test here
        manager.stop()
        pytest.skip(f"Chromium at {CHROMIUM} could not be launched: {e}")
    yield browser
    browser.close()
    manager.stop()
