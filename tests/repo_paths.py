"""Where the repository and the real data are, for tests that need a path.

Real data (BVH files, the authors' released network) lives in ``../shared/data`` beside the
project root, never inside the repository; ``MINIFILM_SHARED_DATA`` points elsewhere if your copy
lives somewhere else. (A module of its own name: every test folder may have a ``conftest``.)
"""
import os
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("MINIFILM_SHARED_DATA", REPO_ROOT.parent / "shared" / "data"))
