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
import os

# The suite runs in two worker processes (setup.cfg: pytest-xdist's -n 2); each keeps one BLAS
# thread, set before numpy loads, so that two workers' threads do not take turns on two cores.
if os.environ.get("PYTEST_XDIST_WORKER"):
    for _key in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_key, "1")

import shutil  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import pytest  # noqa: E402

import gradcheck_report  # noqa: E402
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


CHROMIUM = os.environ.get("MINIFILM_CHROMIUM") or shutil.which("chromium") or "/usr/bin/chromium"
# Software WebGL: headless machines have no GPU, and SwiftShader renders the same everywhere.
CHROMIUM_ARGS = ["--use-angle=swiftshader", "--enable-unsafe-swiftshader"]


@pytest.fixture(scope="module")
def browser():
    """Headless Chromium through playwright, for the viewer's and the demo's pages; skips with the
    reason when either is unavailable. (Module-scoped: one sync playwright per thread at a time.)"""
    try:
        from playwright.sync_api import sync_playwright  # optional: the page tests only
    except ImportError:
        pytest.skip("playwright is not installed (pip install playwright; no browser download needed)")
    if not Path(CHROMIUM).is_file():
        pytest.skip(f"Chromium not found at {CHROMIUM} (apt-get install chromium, or set MINIFILM_CHROMIUM)")
    manager = sync_playwright().start()
    try:                                    # playwright's driver is stopped however the module ends
        try:
            chromium = manager.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        except Exception as e:  # noqa: BLE001 - any launch failure means: cannot test here
            pytest.skip(f"Chromium at {CHROMIUM} could not be launched: {e}")
        try:
            yield chromium
        finally:
            chromium.close()
    finally:
        manager.stop()


def pytest_ignore_collect(collection_path, config):
    """Under ``-m gradcheck`` alone, a test module whose text does not mention gradcheck holds no
    gradient check (the mark is written on the test, or the module is named for it): it is not
    even imported, which saves most of the collection."""
    if config.getoption("markexpr") == "gradcheck" and collection_path.suffix == ".py" \
            and collection_path.name.startswith("test_"):
        return "gradcheck" not in collection_path.read_text(encoding="utf-8") or None
    return None


@pytest.hookimpl(tryfirst=True)      # before pytest-xdist reads the groups
def pytest_collection_modifyitems(items):
    """Every test of a module named ``*gradcheck*`` is a gradient check (``-m gradcheck``). With two
    workers (``--dist loadgroup``) a module's tests run in one worker, so its fixtures are made
    once, and every gradient check runs in one worker, whose rows make the one table below."""
    for item in items:
        if "gradcheck" in item.path.name:
            item.add_marker(pytest.mark.gradcheck)
        group = "gradcheck" if item.get_closest_marker("gradcheck") else item.nodeid.split("::")[0]
        item.add_marker(pytest.mark.xdist_group(group))


GRADCHECK_TABLES = []       # the table of each worker that ran gradient checks (pytest-xdist)


def pytest_sessionfinish(session):
    """In a worker of pytest-xdist: its gradient-check table goes to the main process."""
    if hasattr(session.config, "workeroutput"):
        session.config.workeroutput["gradcheck_table"] = gradcheck_report.table()


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node, error):
    """In the main process of pytest-xdist: a worker's gradient-check table, when it has one."""
    text = getattr(node, "workeroutput", {}).get("gradcheck_table")
    if text:
        GRADCHECK_TABLES.append(text)


def pytest_terminal_summary(terminalreporter):
    """The gradient checks that ran: ``minifilm gradcheck``'s table of the (case, seed) tests, then
    the other checks, one line each."""
    text = gradcheck_report.table() or "\n\n".join(GRADCHECK_TABLES)
    if text:
        terminalreporter.write_sep("=", "gradient checks (the table of minifilm gradcheck, then the others)")
        terminalreporter.write_line(text)
