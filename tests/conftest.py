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
from dataclasses import replace
from pathlib import Path

import pytest

import gradcheck_report
from repo_paths import REPO_ROOT, SHARED_DATA, need_data  # noqa: F401  (re-exported for the fixtures below)


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """Path to ``../shared/data``; skips the test when it is not there (fails it in CI)."""
    return need_data(SHARED_DATA, "the real data folder")


@pytest.fixture(scope="session")
def tiny_job(tmp_path_factory):
    """The main job in miniature, made once for the whole session (two synthetic styles, one gait
    of 6 s, one epoch, 0.5 s generated: a few seconds): (run folder, the job's result). It has
    model.npz, styles.npz, starts.npz, run.json, skeleton.bvh, data/, generated/ and cache/.
    Every test that needs a trained run reads this one; a test that changes a run changes a copy
    (shutil.copytree), never this folder."""
    from minifilm.pipeline.train_small import Settings, run
    out = tmp_path_factory.mktemp("tiny_run")
    settings = replace(Settings(out=out).quick(), styles=("Neutral", "LeftHop"), gaits=("FW",), seconds_per_clip=6.0,
                       epochs=1, generate_seconds=0.5)
    return out, run(settings)


@pytest.fixture(scope="session")
def tiny_run(tiny_job) -> Path:
    """The folder of :func:`tiny_job`'s run (read it; copy it to change it)."""
    return tiny_job[0]


def pytest_ignore_collect(collection_path, config):
    """Under ``-m gradcheck`` alone, a test module whose text does not mention gradcheck holds no
    gradient check (the mark is written on the test, or the module is named for it): it is not
    even imported, which saves most of the collection."""
    if config.getoption("markexpr") == "gradcheck" and collection_path.suffix == ".py" \
            and collection_path.name.startswith("test_"):
        return "gradcheck" not in collection_path.read_text(encoding="utf-8") or None
    return None


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
