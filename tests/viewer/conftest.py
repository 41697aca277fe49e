"""Fixtures of the viewer tests: a synthetic walker, real BVH files (headless Chromium: tests/conftest.py)."""
from __future__ import annotations

from pathlib import Path

import pytest

from minifilm.motion.motion import Motion
from repo_paths import need_data
from viewer_helpers import synthetic_walker


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
