"""Shared test fixtures.

Real data (BVH files, the authors' released network) lives in ``../shared/data`` beside the
project root, never inside the repository. Tests that need it skip with a clear reason when it
is absent. ``MINIFILM_SHARED_DATA`` points elsewhere if your copy lives somewhere else.
"""
import os
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("MINIFILM_SHARED_DATA", REPO_ROOT.parent / "shared" / "data"))


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """Path to ``../shared/data``; skips the test when it is not there."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"real data folder not found at {SHARED_DATA} (set MINIFILM_SHARED_DATA)")
    return SHARED_DATA
