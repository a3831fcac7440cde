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
MEASURED_HINT = ("put them in $MOTECAL_MEASURED or in shared/data/measured beside the "
                 "checkout (../shared/data/measured)")


def in_ci() -> bool:
    """CI=true (CI runs `make test` so): missing measured data is a failure there."""
    return os.environ.get("CI", "").strip().lower() in ("true", "1", "yes")


_NO_MEASURED = f"measured data not found (looked in {MEASURED}): {MEASURED_HINT}"


def need_measured() -> Path:
    """The measured data folder.  Missing: outside CI the test is skipped (the
    summary shows all those skips as one line that says where the data go);
    under CI=true it fails."""
    if MEASURED.is_dir():
        return MEASURED
    if in_ci():
        pytest.fail(_NO_MEASURED + "; CI=true requires them")
    pytest.skip(_NO_MEASURED)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    """Every skip for missing measured data is reported at one place (here), so
    pytest's -ra summary folds them into one line instead of one per test."""
    outcome = yield
    rep = outcome.get_result()
    if rep.skipped and isinstance(rep.longrepr, tuple) and rep.longrepr[2].endswith(
            _NO_MEASURED):
        rep.longrepr = (__file__, _HERE_LINE, _NO_MEASURED)


_HERE_LINE = pytest_runtest_makereport.__code__.co_firstlineno

sys.path.insert(0, str(Path(__file__).resolve().parent))


def pytest_configure(config):
    config.addinivalue_line("markers", "slow: takes more than a few seconds")


@pytest.fixture(scope="session")
def measured():
    """The measured data folder (../shared/data/measured); see need_measured."""
    return need_measured()


# Real database servers (Debian's packages, make sysdeps), one per test run,
# each in its own temporary folder (dbservers.py).  Not installed or not
# starting: the tests that need them fail (they are part of the set-up).
@pytest.fixture(scope="session")
def pg_url():
    import dbservers
    try:
        with dbservers.postgres_server() as srv:
            yield srv.url
    except dbservers.ServerError as e:
        pytest.fail(str(e))


@pytest.fixture(scope="session")
def mariadb():
    """A MariaDB server: .url (unix socket), .tcp_url (127.0.0.1), .root."""
    import dbservers
    try:
        with dbservers.mariadb_server() as srv:
            yield srv
    except dbservers.ServerError as e:
        pytest.fail(str(e))

