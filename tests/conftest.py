"""Shared test set-up."""
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # before numpy: see motecal/__init__.py
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
SHARED = REPO.parent / "shared"
MEASURED = Path(os.environ.get("MOTECAL_MEASURED", SHARED / "data" / "measured"))

sys.path.insert(0, str(Path(__file__).resolve().parent))


def pytest_configure(config):
    config.addinivalue_line("markers", "slow: takes more than a few seconds")


@pytest.fixture
def measured():
    if not MEASURED.is_dir():
        pytest.fail(f"measured data not found at {MEASURED}")
    return MEASURED
