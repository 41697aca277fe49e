"""Shared test fixtures.

Real data (BVH files, the authors' released network) lives in ``../shared/data`` beside the
project root, never inside the repository. Tests that need it skip with a clear reason when it
is absent. ``MINIFILM_SHARED_DATA`` points elsewhere if your copy lives somewhere else.
"""
from pathlib import Path

import pytest

import gradcheck_report
from repo_paths import REPO_ROOT, SHARED_DATA  # noqa: F401  (re-exported for the fixtures below)


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """Path to ``../shared/data``; skips the test when it is not there."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"real data folder not found at {SHARED_DATA} (set MINIFILM_SHARED_DATA)")
    return SHARED_DATA


def pytest_terminal_summary(terminalreporter):
    """The gradient-check table of the (case, seed) tests that ran: ``minifilm gradcheck``'s table."""
    text = gradcheck_report.table()
    if text:
        terminalreporter.write_sep("=", "gradient checks (minifilm gradcheck)")
        terminalreporter.write_line(text)
