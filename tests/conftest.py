"""Shared test set-up."""
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # before numpy: see motecal/__init__.py
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent


def _find_measured() -> Path:
    """$MOTECAL_MEASURED, else shared/data/measured beside the checkout or above it."""
    if os.environ.get("MOTECAL_MEASURED"):
        return Path(os.environ["MOTECAL_MEASURED"])
    for d in REPO.parents:
        cand = d / "shared" / "data" / "measured"
        if cand.is_dir():
            return cand
    return REPO.parent / "shared" / "data" / "measured"


MEASURED = _find_measured()
SHARED = MEASURED.parent.parent

sys.path.insert(0, str(Path(__file__).resolve().parent))


def pytest_configure(config):
    config.addinivalue_line("markers", "slow: takes more than a few seconds")
    # hypothesis keeps caches (.hypothesis/) in the working folder: tests write
    # only in their own temporary folders, so point it at one
    if "HYPOTHESIS_STORAGE_DIRECTORY" not in os.environ:
        import atexit
        import shutil
        import tempfile
        where = tempfile.mkdtemp(prefix="motecal-hypothesis-")
        atexit.register(shutil.rmtree, where, True)
        os.environ["HYPOTHESIS_STORAGE_DIRECTORY"] = where


@pytest.fixture
def measured():
    if not MEASURED.is_dir():
        pytest.fail(f"measured data not found at {MEASURED}")
    return MEASURED
