"""Tests that need ../shared/data skip on a user's machine when it is absent, and fail in CI
(CI=true), where the data is always there and a skip would let a test pass unseen
(tests/repo_paths.py::need_data, used by the shared_data fixture and every test that looks for
a file of the data itself)."""
import os
import subprocess
import sys

import pytest

import repo_paths
from repo_paths import REPO_ROOT


def test_ci_is_read_from_the_environment():
    assert repo_paths.in_ci({"CI": "true"}) and repo_paths.in_ci({"CI": "1"}) and repo_paths.in_ci({"CI": "True "})
    assert not repo_paths.in_ci({}) and not repo_paths.in_ci({"CI": "false"}) and not repo_paths.in_ci({"CI": ""})


def test_need_data_skips_on_a_users_machine_and_fails_in_ci(monkeypatch, tmp_path):
    assert repo_paths.need_data(tmp_path) == tmp_path
    monkeypatch.setattr(repo_paths, "IN_CI", False)
    with pytest.raises(pytest.skip.Exception, match=f"the released network not found at {tmp_path / 'nope'}"):
        repo_paths.need_data(tmp_path / "nope", "the released network")
    monkeypatch.setattr(repo_paths, "IN_CI", True)
    with pytest.raises(pytest.fail.Exception, match="CI=true"):
        repo_paths.need_data(tmp_path / "nope", "the released network")


@pytest.mark.parametrize("ci", [False, True])
def test_a_data_test_without_the_data(tmp_path, ci):
    """The real thing: a test using the shared_data fixture, run by pytest with the data folder
    pointing nowhere, is skipped with its reason, or in CI fails with it."""
    env = {k: v for k, v in os.environ.items() if k != "CI"}
    env.update(MINIFILM_SHARED_DATA=str(tmp_path / "no-data"), **({"CI": "true"} if ci else {}))
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-rsf", "-p", "no:cacheprovider",
                           "tests/synthetic/test_synthetic.py::test_skeleton_is_the_real_100style_one"],
                          cwd=REPO_ROOT, env=env, capture_output=True, text=True, timeout=120)
    reason = f"the real data folder not found at {tmp_path / 'no-data'}"
    assert reason in proc.stdout, proc.stdout
    if ci:
        assert proc.returncode == 1 and "1 error" in proc.stdout and "CI=true" in proc.stdout   # fails in its fixture
    else:
        assert proc.returncode == 0 and "1 skipped" in proc.stdout
