"""Issue 15, case 8: the commands that only read open the database read-only
(URI mode=ro; immutable when no write-ahead log is live) and work on
read-only media; calibrate still writes cal.json and says it could not record
it.  The database stays byte-identical and nothing appears beside it."""
import contextlib
import json
import os
import shutil
import sqlite3
import stat
import subprocess

import numpy as np
import pytest

from clirun import digest, motecal, session as small_session
from motecal.sessions.store import open_store
from synthetic import paper_sized_session


@pytest.fixture(scope="module")
def master(tmp_path_factory):
    """A database with one calibratable session (checkpointed: no WAL left)."""
    path = tmp_path_factory.mktemp("ro") / "master.db"
    s = paper_sized_session(3, mote=1, rotation=False, n_poses=30, per_pose=100)
    s.name = "board"
    with open_store(str(path), create=True) as st:
        st.save_session(s)
        st.save_session(_small_sweep())                 # a quick report
    return path


def _small_sweep():
    """400 rows whose magnetometer turns through every direction (the rest
    plausible counts): the least a report draws something from (random
    counts are a hold of noise, which calibrate rightly leaves alone)."""
    s = small_session("small")
    rng = np.random.default_rng(1)
    k = np.arange(len(s)) / len(s)              # a smooth spiral from pole to pole
    th, ph = np.arccos(1 - 2 * k), 2 * np.pi * 12 * k
    d = np.column_stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)])
    s.raw[:, 6:9] = np.round(500 * d + rng.normal(0, 1.5, (len(s), 3)) + [40, -25, 10])
    return s


def _copy(master, folder):
    folder.mkdir()
    db = folder / "r.db"
    shutil.copy(master, db)
    return str(db)


READS = [
    ("sessions",), ("sessions", "--json"),
    ("export", "--session", "board", "--csv", "{out}/b.csv"),
    ("export", "--session", "board", "--csv", "-"),
    ("diagnose", "--session", "board", "--no-sim", "--json", "{out}/d.json", "--no-keep"),
]


def _argv(cmd, db, out):
    return [cmd[0], "--db", db] + [a.replace("{out}", str(out)) for a in cmd[1:]]


def test_case8_read_commands_leave_the_database_byte_identical(master, tmp_path):
    db = _copy(master, tmp_path / "db")
    out = tmp_path / "out"
    out.mkdir()
    before = digest(db)
    for cmd in READS:
        rc, _, err = motecal(*_argv(cmd, db, out))
        assert rc == 0, (cmd, err)
        assert digest(db) == before, cmd
        assert os.listdir(tmp_path / "db") == ["r.db"], cmd        # no -wal, -shm, journal


def test_case8_read_only_open_sees_a_live_write_ahead_log(master, tmp_path):
    """While a logger writes (WAL not yet checkpointed) a read-only open still
    sees what it committed (no immutable shortcut then)."""
    db = _copy(master, tmp_path / "db")
    with open_store(db) as writer:
        w = writer.open_session("live", kind="free")
        import numpy as np
        w.add_samples(np.ones(3, int), np.arange(3), np.zeros(3), np.zeros(3, int),
                      np.zeros((3, 9), int))
        w.commit()
        assert os.path.getsize(db + "-wal") > 0
        with open_store(db, readonly=True) as ro:
            assert ro.readonly and len(ro.load_session("live")) == 3
        w.end()


@contextlib.contextmanager
def read_only_media(folder, monkeypatch):
    """Make ``folder`` read-only media: a read-only bind mount as root (root
    ignores permission bits), else permission bits.  Without mount rights as
    root, the write checks are made to see read-only media (os.access) and the
    file's bytes are checked instead.  Yields how it was done."""
    if os.geteuid() != 0:
        for p in folder.iterdir():
            os.chmod(p, 0o444)
        os.chmod(folder, 0o555)
        try:
            yield "permission bits"
        finally:
            os.chmod(folder, 0o755)
        return
    ok = subprocess.run(["mount", "--bind", str(folder), str(folder)],
                        capture_output=True).returncode == 0
    if ok and subprocess.run(["mount", "-o", "remount,ro,bind", str(folder)],
                             capture_output=True).returncode == 0:
        try:
            yield "read-only bind mount"
        finally:
            subprocess.run(["umount", str(folder)], check=True)
        return
    if ok:
        subprocess.run(["umount", str(folder)], check=True)
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode, **kw: False if (
        mode & os.W_OK and str(p).startswith(str(folder))) else real(p, mode, **kw))
    yield "simulated (os.access)"


def test_case8_every_command_works_on_read_only_media(master, tmp_path, monkeypatch):
    folder = tmp_path / "media"
    db = _copy(master, folder)
    before = digest(db)
    out = tmp_path / "out"
    out.mkdir()
    with read_only_media(folder, monkeypatch) as how:
        print("read-only media:", how)
        if how == "read-only bind mount":
            with pytest.raises(OSError):
                (folder / "probe").write_text("x")
        for cmd in READS + [("report", "--session", "small", "--out", "{out}/rep", "-q")]:
            rc, _, err = motecal(*_argv(cmd, db, out))
            assert rc == 0, (how, cmd, err)
        # calibrate: cal.json is written; the database cannot record it and says so
        rc, text, err = motecal("calibrate", "--db", db, "--session", "board", "--out",
                                out / "cal.json", "--kfold", "0", "--seed", "1")
        assert rc == 0, (how, err)
        assert "not recorded in the database" in text
        assert json.loads((out / "cal.json").read_text())["session"] == "board"
        # diagnose keeps its result when it can: here it says it could not
        rc, text, err = motecal("diagnose", "--db", db, "--session", "board", "--no-sim")
        assert rc == 0 and "not kept with the session: the database is read-only" in text, \
            (how, text, err)
        # log and import need to write: one line, exit 2, nothing changed
        rc, _, err = motecal("import", out / "b.csv", "--db", db, "--session", "again")
        assert rc == 2 and "Traceback" not in err and err.count("\n") == 1, err
        assert os.listdir(folder) == ["r.db"]
    assert digest(db) == before
    assert (out / "rep" / "index.html").is_file() and (out / "d.json").is_file()
    con = sqlite3.connect(db)
    assert con.execute("SELECT COUNT(*) FROM calibrations").fetchone()[0] == 0
    con.close()
    assert stat.S_ISREG(os.stat(db).st_mode)
