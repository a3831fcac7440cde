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


def _measured_present() -> bool:
    """The folder exists and holds something (an empty one counts as absent)."""
    try:
        return MEASURED.is_dir() and any(True for _ in os.scandir(MEASURED))
    except OSError:
        return False


def need_measured() -> Path:
    """The measured data folder: the one lookup every test that reads the
    measured data goes through (directly or by the `measured` fixture; the
    guard below fails a test that reads them without it).  Missing or empty:
    outside CI the test is skipped (the summary shows all those skips as one
    line that says where the data go); under CI=true it fails."""
    n = len(_GUARD.reads)
    present = _measured_present()
    del _GUARD.reads[n:]              # looking is not reading
    if present:
        _GUARD.allow()
        return MEASURED
    if in_ci():
        pytest.fail(_NO_MEASURED + "; CI=true requires them")
    pytest.skip(_NO_MEASURED)


# --- the guard: reading the measured data without the lookup fails ---------
# A Python audit hook (sys.addaudithook) sees every file open, directory
# listing, glob, sqlite connect and subprocess launch of this process.  While a
# test (its fixtures included) or a test module's collection runs, any of them
# that names a path under MEASURED is recorded unless that test went through
# need_measured(): it asks for the `measured` fixture, or for a fixture that
# called need_measured() (remembered by fixture definition, not by name), or
# called it itself before reading.  A recorded read fails the test (or the
# collection) with one message, even where the read succeeded and even if the
# test caught the error: so a new test that forgets the lookup fails on every
# machine that has the data (CI, a developer's), not only in a bare clone where
# the read itself fails.  The hook stays cheap: a set lookup for most events,
# a string prefix test for the few watched ones.
_WATCH_PATH = frozenset({"open", "os.listdir", "os.scandir", "glob.glob", "glob.glob/2",
                         "sqlite3.connect", "sqlite3.connect/handle", "shutil.copyfile",
                         "shutil.copytree", "os.chdir"})
_WATCH_CMD = frozenset({"subprocess.Popen", "os.system", "os.posix_spawn", "os.exec",
                        "os.spawn"})


class _MeasuredGuard:
    def __init__(self):
        self.roots = tuple(sorted({os.path.abspath(MEASURED), os.path.realpath(MEASURED)}))
        self.spelt = tuple(sorted({*self.roots, os.fspath(MEASURED)}))   # inside a command
        self.node = None             # the test or collector running now
        self.allowed = False         # it went through the lookup
        self.reads: list[str] = []   # what it read without
        self.setting_up: list = []   # fixture definitions being set up now
        self.blessed: set = set()    # fixture definitions that called need_measured()

    def allow(self):
        self.allowed = True
        self.blessed.update(self.setting_up)

    def _under(self, p) -> bool:
        if isinstance(p, int) or p is None:
            return False
        s = os.fsdecode(p)
        if s.startswith("file:"):                # sqlite's URI form
            s = s[5:].split("?")[0]
        s = os.path.abspath(s)
        return any(s == r or s.startswith(r + os.sep) for r in self.roots)

    def _mentions(self, cmd) -> bool:
        parts = [cmd] if isinstance(cmd, (str, bytes, os.PathLike)) else list(cmd or ())
        for a in parts:
            if isinstance(a, (str, bytes, os.PathLike)):
                a = os.fsdecode(a)
                if self._under(a) or any(r in a for r in self.spelt):
                    return True
        return False

    def audit(self, event, args):
        if self.node is None or self.allowed:
            return
        try:
            if event in _WATCH_PATH:
                hit = args[0] if args and self._under(args[0]) else None
            elif event in _WATCH_CMD:
                hit = next((a for a in args[:3] if self._mentions(a)), None)
            else:
                return
        except Exception:            # never break the audited call
            return
        if hit is not None:
            self.reads.append(f"{event} {hit if isinstance(hit, str) else repr(hit)}")

    def start(self, node, allowed=False):
        self.node, self.allowed, self.reads = node, allowed, []

    def stop(self):
        self.node = None

    def message(self) -> str:
        shown = "; ".join(dict.fromkeys(self.reads))
        return (f"reads the measured data without the lookup ({shown[:300]}): take the "
                "`measured` fixture or call conftest.need_measured() before reading, so the "
                "test is skipped where the data are absent (tests/conftest.py)")


_GUARD = _MeasuredGuard()
sys.addaudithook(_GUARD.audit)


def _uses_lookup(item) -> bool:
    info = getattr(item, "_fixtureinfo", None)
    if info is None:
        return False
    if "measured" in info.names_closure:
        return True
    return any(fd in _GUARD.blessed for defs in info.name2fixturedefs.values() for fd in defs)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    _GUARD.start(item, _uses_lookup(item))
    try:
        yield
    finally:
        _GUARD.stop()


@pytest.hookimpl(hookwrapper=True)
def pytest_fixture_setup(fixturedef, request):
    _GUARD.setting_up.append(fixturedef)
    try:
        yield
    finally:
        _GUARD.setting_up.pop()


@pytest.hookimpl(hookwrapper=True)
def pytest_make_collect_report(collector):
    saved = _GUARD.node, _GUARD.allowed, _GUARD.reads
    _GUARD.start(collector)
    try:
        outcome = yield
        rep = outcome.get_result()
        if _GUARD.reads:
            rep.outcome = "failed"
            rep.longrepr = f"{collector.nodeid}: collecting it {_GUARD.message()}"
    finally:
        _GUARD.node, _GUARD.allowed, _GUARD.reads = saved


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    """Every skip for missing measured data is reported at one place (here), so
    pytest's -ra summary folds them into one line instead of one per test."""
    outcome = yield
    rep = outcome.get_result()
    if _GUARD.reads and _GUARD.node is item:
        first = "" if rep.passed else f"\n\n(the test's own outcome: {rep.longreprtext[-2000:]})"
        rep.outcome = "failed"
        rep.longrepr = f"{item.nodeid} {_GUARD.message()}{first}"
        _GUARD.reads = []
        return
    if rep.skipped and isinstance(rep.longrepr, tuple) and rep.longrepr[2].endswith(
            _NO_MEASURED):
        rep.longrepr = (__file__, _HERE_LINE, _NO_MEASURED)


_HERE_LINE = pytest_runtest_makereport.__code__.co_firstlineno

sys.path.insert(0, str(Path(__file__).resolve().parent))


def pytest_configure(config):
    config.addinivalue_line("markers", "slow: takes more than a few seconds (in a "
                            "parallel run it starts first)")
    # hypothesis keeps caches (.hypothesis/) in the working folder: tests write
    # only in their own temporary folders, so point it at one
    if "HYPOTHESIS_STORAGE_DIRECTORY" not in os.environ:
        import atexit
        import shutil
        import tempfile
        where = tempfile.mkdtemp(prefix="motecal-hypothesis-")
        atexit.register(shutil.rmtree, where, True)
        os.environ["HYPOTHESIS_STORAGE_DIRECTORY"] = where


@pytest.fixture(scope="session")
def measured():
    """The measured data folder (../shared/data/measured); see need_measured."""
    return need_measured()


# Real database servers (Debian's packages, make sysdeps), one per test run
# (per worker in a parallel run), each in its own temporary folder (dbservers.py).  Not installed or not
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


# --- parallel runs (make test: pytest-xdist, -n auto --dist loadfile) -------
# Each worker is a process of its own: its session fixtures (the database
# servers above, each in its own temporary folder, MariaDB's TCP on a free
# port), module fixtures, module-level caches and tmp_path are its own.  A test
# module is one work unit (loadfile): its module fixtures and caches are built
# once, on one worker.  (--dist loadgroup would split modules further, but it
# does not group with pytest 9.2's node ids: pytest-xdist issue 1386.)
# Here the modules that hold a test marked slow are handed out first, larger
# modules first within each kind, so the workers end together on short modules;
# the order inside a module is kept, and outside xdist nothing is reordered.
# No test depends on this: run alone or in another order it gives the same
# result.
@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    if not hasattr(config, "workerinput"):       # not an xdist worker: as collected
        return
    size: dict = {}
    slow: set = set()
    for it in items:
        mod = getattr(it, "module", None)
        size[mod] = size.get(mod, 0) + 1
        if it.get_closest_marker("slow") is not None:
            slow.add(mod)
    items.sort(key=lambda it: (getattr(it, "module", None) not in slow,
                               -size[getattr(it, "module", None)]))       # stable
