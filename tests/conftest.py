"""Shared test fixtures.

Real data (BVH files, the authors' released network) lives in ``../shared/data`` beside the
project root, never inside the repository. Tests that need it skip with a clear reason when it
is absent, and fail instead when ``CI=true`` (repo_paths.need_data). ``MINIFILM_SHARED_DATA``
points elsewhere if your copy lives somewhere else.

The gradient checks stand on their own: ``python -m pytest -q -m gradcheck`` runs every one (the
tests of the modules named ``*gradcheck*``, marked here, and the tests marked ``gradcheck`` in
other modules). At the end of a session the gradient-check rows that ran are printed as one
table, the table of ``minifilm gradcheck``, and the other checks below it (gradcheck_report.py).
"""
from pathlib import Path

import pytest

import gradcheck_report
from repo_paths import REPO_ROOT, SHARED_DATA, need_data  # noqa: F401  (re-exported for the fixtures below)


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """Path to ``../shared/data``; skips the test when it is not there (fails it in CI)."""
    return need_data(SHARED_DATA, "the real data folder")


def pytest_collection_modifyitems(items):
    """Every test of a module named ``*gradcheck*`` is a gradient check (``-m gradcheck``)."""
    for item in items:
        if "gradcheck" in item.path.name:
            item.add_marker(pytest.mark.gradcheck)


def pytest_terminal_summary(terminalreporter):
    """The gradient checks that ran: ``minifilm gradcheck``'s table of the (case, seed) tests, then
    the other checks, one line each."""
    text = gradcheck_report.table()
    if text:
        terminalreporter.write_sep("=", "gradient checks (the table of minifilm gradcheck, then the others)")
        terminalreporter.write_line(text)
