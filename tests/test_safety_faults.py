"""Issue 15, cases 4-5: a full disk, an I/O error or a write lock held by
another process never gives a traceback nor loses what was committed; the
logger buffers through a lock and ends the session with what was stored."""
import os
import re
import resource
import signal
import sqlite3
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from clirun import make_db, motecal, session
from motecal.capture.link import LinkTracker
from motecal.capture.logger import Logger, NullDisplay
from motecal.line import sources as S
from motecal.sessions import importer
from motecal.sessions.store import StoreBusy, open_store
from motecal.sessions.store_sqlite import SqliteBackend
from test_logger_streams import sample_frames

N_PER_MOTE = 3000


def _recording(tmp_path, n=N_PER_MOTE):
    rng = np.random.default_rng(5)
    raws = {m: rng.integers(-3000, 3000, (n, 9)).astype(np.int16) for m in (1, 2, 3)}
    frames, _ = sample_frames(raws)
    rec = tmp_path / "rec.bin"
    rec.write_bytes(b"".join(frames))
    return rec, 3 * n


def _limit_pages(monkeypatch, extra_pages):
    """sqlite opened by motecal from now on may grow by ``extra_pages`` only:
    a full disk, as sqlite sees it (SQLITE_FULL, 'database or disk is full')."""
    orig = SqliteBackend.__init__

    def init(self, path, create, *a, **kw):
        orig(self, path, create, *a, **kw)
        n = self.conn.execute("PRAGMA page_count").fetchone()[0]
        self.conn.execute(f"PRAGMA max_page_count = {n + extra_pages}")

    monkeypatch.setattr(SqliteBackend, "__init__", init)


def _check(db):
    con = sqlite3.connect(db)
    try:
        assert con.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
        return con.execute("SELECT s.name, s.ended, COUNT(x.seq) FROM sessions s LEFT JOIN "
                           "samples x ON x.session = s.id GROUP BY s.id ORDER BY s.id").fetchall()
    finally:
        con.close()


def test_case4_log_on_a_full_disk_ends_the_session_with_what_was_stored(tmp_path, monkeypatch):
    rec, total = _recording(tmp_path)
    db = make_db(tmp_path / "full.db")
    _limit_pages(monkeypatch, 80)         # about two of the three reads fit
    rc, out, err = motecal("log", "--port", rec, "--db", db, "--session", "run",
                           "--commit-every", "0.001")
    assert rc == 1, err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert "full" in err and "marked ended" in err
    rows = _check(db)
    assert rows[0] == ("board", rows[0][1], 400)                  # earlier data intact
    name, ended, stored = rows[1]
    assert name == "run" and ended is not None                    # ended, not left open
    assert 0 < stored < total
    m = re.search(r"(\d+) samples stored, (\d+) received samples not stored", err)
    assert int(m.group(1)) == stored and stored + int(m.group(2)) <= total


def test_case4_import_on_a_full_disk_stores_nothing(tmp_path, monkeypatch):
    db = make_db(tmp_path / "full.db")
    big = tmp_path / "big.csv"
    importer.write_csv(session("big", n=20000), big)
    _limit_pages(monkeypatch, 12)
    rc, out, err = motecal("import", big, "--db", db, "--session", "big")
    assert rc == 1 and err.count("\n") == 1 and "full" in err, err
    assert [r[0] for r in _check(db)] == ["board"]                # all or nothing


def _limited(max_bytes):
    def pre():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)              # EFBIG instead of a kill
        resource.setrlimit(resource.RLIMIT_FSIZE, (max_bytes, max_bytes))
    return pre


def test_case4_sim_out_on_a_full_disk_leaves_no_file(tmp_path):
    """A real write failure (RLIMIT_FSIZE: the file may not grow past 20 kB)."""
    out = tmp_path / "s.bin"
    p = subprocess.run([sys.executable, "-m", "motecal", "sim", "--out", str(out),
                        "--duration", "5", "--quiet"], capture_output=True, text=True,
                       timeout=120, preexec_fn=_limited(20_000), cwd=tmp_path)
    assert p.returncode == 1, p.stderr
    assert p.stderr.count("\n") == 1 and "Traceback" not in p.stderr and "s.bin" in p.stderr
    assert os.listdir(tmp_path) == []                              # no half file, no temp


def test_case4_import_with_a_failing_disk_keeps_the_database(tmp_path):
    db = make_db(tmp_path / "io.db")
    big = tmp_path / "big.csv"
    importer.write_csv(session("big", n=20000), big)
    size = os.path.getsize(db)
    p = subprocess.run([sys.executable, "-m", "motecal", "import", str(big), "--db", db,
                        "--session", "big"], capture_output=True, text=True, timeout=120,
                       preexec_fn=_limited(size + 30_000), cwd=tmp_path)
    assert p.returncode == 1, p.stderr
    assert p.stderr.count("\n") == 1 and "Traceback" not in p.stderr
    assert [r[0] for r in _check(db)] == ["board"]


class LockHolder(threading.Thread):
    """Another process's write lock on ``db`` for ``seconds``."""

    def __init__(self, db, seconds):
        super().__init__(daemon=True)
        self.db, self.seconds = db, seconds
        self.held = threading.Event()

    def run(self):
        con = sqlite3.connect(self.db, isolation_level=None, check_same_thread=False)
        con.execute("BEGIN IMMEDIATE")
        self.held.set()
        time.sleep(self.seconds)
        con.execute("ROLLBACK")
        con.close()


class Events(NullDisplay):
    """The logger's display interface (NullDisplay), keeping the event lines."""

    def __init__(self):
        self.lines = []

    def event(self, text):
        self.lines.append(text)


def _logger(db, rec, lock_timeout):
    st = open_store(db)
    w = st.open_session("run", kind="free", lock_timeout=lock_timeout, commit_every=0.05)
    st.set_busy_timeout(0.05)
    shown = Events()
    return st, w, Logger(S.parse_port(str(rec)), w, LinkTracker(), display=shown), shown


def test_case5_log_buffers_through_a_held_lock_and_loses_nothing(tmp_path):
    rec, total = _recording(tmp_path)
    db = make_db(tmp_path / "lock.db")
    st, w, lg, shown = _logger(db, rec, lock_timeout=30)
    holder = LockHolder(db, 1.5)
    holder.start()
    holder.held.wait(5)
    t0 = time.monotonic()
    lg.run()
    waited = time.monotonic() - t0
    st.close()
    holder.join()
    assert waited >= 1.0                                      # it did wait for the lock
    assert any("locked by another process" in x for x in shown.lines)
    rows = _check(db)
    assert rows[1][0] == "run" and rows[1][1] is not None and rows[1][2] == total
    con = sqlite3.connect(db)
    kinds = [r[0] for r in con.execute("SELECT kind FROM events")]
    con.close()
    assert "db_locked" in kinds


def test_case5_a_lock_held_past_the_timeout_is_one_line(tmp_path):
    rec, total = _recording(tmp_path)
    db = make_db(tmp_path / "lock.db")
    st, w, lg, shown = _logger(db, rec, lock_timeout=0.5)
    holder = LockHolder(db, 2.5)
    holder.start()
    holder.held.wait(5)
    with pytest.raises(StoreBusy) as e:
        lg.run()
    st.close()
    holder.join()
    msg = str(e.value)
    assert "\n" not in msg and "locked by another process" in msg
    assert f"{total} received samples not stored" in msg and "left open" in msg
    rows = _check(db)                                         # consistent, nothing half-written
    assert rows[1][:1] == ("run",) and rows[1][2] == 0
