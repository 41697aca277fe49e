"""Where the repository and the real data are, for tests that need a path.

Real data (BVH files, the authors' released network) lives in ``../shared/data`` beside the
project root, never inside the repository; ``MINIFILM_SHARED_DATA`` points elsewhere if your copy
lives somewhere else. (A module of its own name: every test folder may have a ``conftest``.)

A test that needs the data and does not find it skips, with the path it looked for, on a user's
machine; in CI (the environment variable ``CI`` is ``true``) it fails instead, since CI runs with
the data beside the repository and a skipped test would let it pass unseen (:func:`need_data`).
"""
import os
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("MINIFILM_SHARED_DATA", REPO_ROOT.parent / "shared" / "data"))


def in_ci(environ=os.environ) -> bool:
    """True when the environment says CI (``CI=true``, as GitHub Actions, GitLab and most others set)."""
    return environ.get("CI", "").strip().lower() in ("true", "1", "yes")


IN_CI = in_ci()


def missing_data(path: Path, what: str = "the real data") -> None:
    """Skip the test (a user's machine) or fail it (CI) because ``path`` is not there."""
    reason = f"{what} not found at {path} (put the data in ../shared/data or set MINIFILM_SHARED_DATA)"
    if IN_CI:
        pytest.fail(f"{reason}. CI=true: CI runs with the shared data, so a test that needs it must not "
                    "be skipped", pytrace=False)
    pytest.skip(reason)


def need_data(path: Path, what: str = "the real data") -> Path:
    """``path`` when it exists, else :func:`missing_data` (skip on a user's machine, fail in CI)."""
    if not Path(path).exists():
        missing_data(path, what)
    return Path(path)
