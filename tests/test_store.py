"""The motecal database: schema and migrations, sessions in and out, atomic
imports, calibrations, the live writer, CSV export, and one-line errors."""
import csv
import hashlib
import os
import re
import sqlite3
import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest

from motecal.commands.export import CSV_HEADER, export_csv
from motecal.errors import UserError
from motecal.sessions import store as store_mod
from motecal.sessions import store_schema
from motecal.sessions.fingerprint import data_key
from motecal.sessions.session import LABEL_ROT, SessionData
from motecal.sessions.store import SCHEMA_VERSION, open_store


def _session(name="s1", n=12, motes=(1, 2), seed=0):
    rng = np.random.default_rng(seed)
    k = n // len(motes)
    mote = np.repeat(motes, k)
    seq = np.tile(np.arange(70000, 70000 + k), len(motes))
    raw = rng.integers(-2000, 2000, (len(mote), 9)).astype(float)
    raw[2, 6:] = np.nan                        # magnetometer missing in one row
    raw[5, :6] = np.nan
    t = np.linspace(0, 1, len(mote))
    t[3] = np.nan
    label = np.zeros(len(mote), int)
    label[1:4] = 7
    label[4] = LABEL_ROT
    return SessionData(name, raw, mote, seq, t, label, np.full(len(mote), 0x11),
                       kind="static80", scales={"accel": 256.0, "gyro": 14.375, "mag": 1300.0},
                       chips={"accel": "ADXL345", "gyro": "ITG3200", "mag": "HMC5843"},
                       meta={"source": "unit test", "rate_hz": 125, "notes": "n",
                             "boards": {"1": "B7"}, "started": "2024-05-01T10:00:00Z"})


# --------------------------------------------------------------------------
# Every backend: sqlite, and real PostgreSQL and MariaDB servers (Debian's
# packages, started once per run in a temporary folder, reached through their
# unix sockets: fixtures pg_url and mariadb, conftest.py / dbservers.py).
# --------------------------------------------------------------------------
BACKENDS = ("sqlite", "postgresql", "mariadb")


@pytest.fixture(params=BACKENDS)
def new_db(request, tmp_path):
    """On each backend in turn, a maker of empty databases of their own:
    ``new_db(name)`` -> the ``--db`` target (a sqlite file in the test's
    folder, or a new database on the run's server); ``new_db.kind`` names
    the backend."""
    kind = request.param
    tag = (re.sub(r"\W", "_", request.node.name.lower())[:30] + "_"
           + hashlib.sha1(request.node.nodeid.encode()).hexdigest()[:8])
    server = None if kind == "sqlite" else request.getfixturevalue(
        "pg_url" if kind == "postgresql" else "mariadb")

    def make(name: str = "db") -> str:
        if kind == "sqlite":
            return str(tmp_path / f"{name}.db")
        db = f"t_{tag}_{name[:12]}"
        if kind == "postgresql":
            import psycopg
            with psycopg.connect(server, autocommit=True) as con:
                con.execute(f'DROP DATABASE IF EXISTS "{db}"')
                con.execute(f'CREATE DATABASE "{db}"')
            return server.replace("/motecal?", f"/{db}?")
        import dbservers
        return dbservers.new_database(server, db)

    make.kind = kind
    return make


def _old_db(target: str, version: int, *rows: tuple) -> None:
    """A database made by the migrations up to ``version`` (as released), then
    the statements ``rows`` ((sql, params) in the store's SQL), through the
    backend itself: the same on every backend."""
    b = store_mod._backend_for(target, True)
    try:
        cur = b.cursor()
        for v in range(1, version + 1):
            for stmt in store_schema.MIGRATIONS[v]:
                cur.execute(b.sql(stmt.format(**b.types)))
        cur.execute(b.sql("INSERT INTO schema_version (version) VALUES (?)"), (version,))
        for sql, params in rows:
            cur.execute(b.sql(sql), params)
    finally:
        b.close()


def _same(a: SessionData, b: SessionData):
    order = np.lexsort((a.seq, a.mote))
    np.testing.assert_array_equal(b.mote, a.mote[order])
    np.testing.assert_array_equal(b.seq, a.seq[order])
    np.testing.assert_array_equal(b.raw, a.raw[order])          # NaN == NaN here
    np.testing.assert_allclose(b.t, a.t[order], equal_nan=True)
    np.testing.assert_array_equal(b.label, a.label[order])
    np.testing.assert_array_equal(b.flags, a.flags[order])


def test_every_backend_implements_the_interface():
    """One module, one class per backend, each all of store_backend.Backend
    (no method left abstract), with its types for the schema's statements."""
    from motecal.sessions.store_backend import Backend, shown_url
    from motecal.sessions.store_mysql import MysqlBackend
    from motecal.sessions.store_postgres import PostgresBackend
    from motecal.sessions.store_sqlite import SqliteBackend
    classes = (SqliteBackend, PostgresBackend, MysqlBackend)
    for cls in classes:
        assert issubclass(cls, Backend) and not cls.__abstractmethods__, cls
        assert set(cls.types) == {"int16", "real", "id_pk", "wr"}, cls
        for stmts in store_schema.MIGRATIONS.values():
            for stmt in stmts:
                assert "{" not in stmt.format(**cls.types)
    assert [c.name for c in classes] == ["sqlite", "postgresql", "mysql"]
    assert shown_url("postgresql://lab:s3cret@db:5432/m") == "postgresql://lab:***@db:5432/m"
    assert shown_url("postgresql://lab@/m?host=/run/pg") == "postgresql://lab@/m?host=/run/pg"


def test_empty_or_blank_session_names_are_refused(tmp_path):
    with open_store(str(tmp_path / "m.db"), create=True) as st:
        for name in ("", "   ", "\t\n"):
            with pytest.raises(UserError, match="not empty or blank"):
                st.open_session(name, kind="free")
            with pytest.raises(UserError, match="not empty or blank"):
                st.save_session(_session(name))
        assert st.sessions() == []
        st.save_session(_session(" x "))                  # blanks around a name are fine
        assert [s["name"] for s in st.sessions()] == [" x "]


def test_open_errors_are_one_line_user_errors(tmp_path):
    text = tmp_path / "notes.txt"
    text.write_text("hello, not a database\n" * 50)
    other = tmp_path / "other.db"
    sqlite3.connect(other).execute("CREATE TABLE foo (x)").connection.commit()
    cases = [
        (str(tmp_path / "missing.db"), False, "no database"),
        (str(text), False, "not a motecal database"),
        (str(other), True, "not a motecal database"),
        (str(tmp_path / "nofolder" / "x.db"), True, "does not exist"),
        (str(text / "x.db"), True, "does not exist"),
        (str(tmp_path), True, "is a directory"),
        ("ftp://host/db", True, "unsupported database URL"),
        ("", True, "no database given"),
    ]
    for target, create, msg in cases:
        with pytest.raises(UserError, match=msg) as e:
            open_store(target, create=create)
        assert "\n" not in str(e.value)


# --------------------------------------------------------------------------
# The round trip, the same on every backend
# --------------------------------------------------------------------------
def _missing(new_db, target: str) -> str:
    """A target on the same backend naming no database."""
    if new_db.kind == "sqlite":
        return os.path.join(os.path.dirname(target), "nosuch.db")
    return re.sub(r"/t_\w+\?", "/nosuchdb?", target)


def _orphans(st) -> dict:
    """Rows of any table that belong to no session (a deletion left behind)."""
    out = {}
    for table in ("samples", "calibrations", "link_stats", "line_stats", "events", "writers",
                  "sample_conflicts", "temps", "diagnoses"):
        n = st._query(f"SELECT COUNT(*) FROM {table} WHERE session NOT IN "
                      "(SELECT id FROM sessions)")[0][0]
        if n:
            out[table] = n
    return out


def test_roundtrip_on_every_backend(new_db, monkeypatch):
    """What every backend must keep, on sqlite, PostgreSQL and MariaDB alike:
    sessions (samples with their NaN, labels, metadata, the listing, names
    compared exactly), imports all or nothing, calibrations and diagnoses
    (the latest per mote; gone with a replaced session), temperatures (an
    import's per-row values, a live writer's readings once each), and the
    live writer (batches, labels, counters, events, replays, --append)."""
    target = new_db()
    with pytest.raises(UserError, match="no database" if new_db.kind == "sqlite"
                       else "cannot connect") as e:
        open_store(_missing(new_db, target))
    assert "\n" not in str(e.value)
    data = _session("s1", n=3000, motes=(1, 2, 3))
    with open_store(target, create=True) as st:
        assert st.schema_version == SCHEMA_VERSION and st.sessions() == []
        with pytest.raises(UserError, match="it holds no sessions"):
            st.load_session("x")
        # -- a session in and out --------------------------------------------
        st.save_session(data)
        got = st.load_session("s1")
        _same(data, got)                           # NaN (missing sensor, t) kept
        only2 = st.load_session("s1", mote=2)
        assert set(only2.mote) == {2} and len(only2) == 1000
        assert got.kind == "static80" and got.scales["mag"] == 1300.0
        assert got.chips["mag"] == "HMC5843"
        assert got.meta["source"] == "unit test" and got.meta["rate_hz"] == 125.0
        assert got.meta["boards"] == {"1": "B7"}
        assert got.meta["started"] == "2024-05-01T10:00:00.000Z"
        assert st.sessions() == [dict(name="s1", kind="static80",
                                      started="2024-05-01T10:00:00.000Z", ended=None,
                                      source="unit test", rate_hz=125.0, notes="n",
                                      samples=3000, motes=[1, 2, 3], poses=1)]
        # labels are stored as CSV text, NULL where a sensor is missing
        assert sorted(r[0] for r in st._query("SELECT DISTINCT label FROM samples")) == \
            ["", "7", "rot"]
        assert st._query("SELECT COUNT(*) FROM samples WHERE mx IS NULL")[0][0] == 1
        if new_db.kind == "sqlite":
            con = sqlite3.connect(target)
            assert con.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
            con.close()
        # names compare exactly: case, trailing blanks, accents count
        names = ["s1", "S1", "s1 ", "s\u00ef", "s" * 700]
        for name in names[1:]:
            st.save_session(_session(name))
        assert [s["name"] for s in st.sessions()] == names
        with pytest.raises(UserError) as e:
            st.load_session("gamma")
        assert str(e.value) == (f"unknown session 'gamma' in {st.target} "
                                f"(known: {', '.join(names)})")
        with pytest.raises(UserError, match=r"no samples of mote 9 \(motes: 1, 2, 3\)"):
            st.load_session("s1", mote=9)
        # -- an import is all or nothing ---------------------------------------
        stored = st._query("SELECT COUNT(*) FROM samples")[0][0]
        big = _session("big", n=150_000, motes=(1, 2, 3))      # two chunks of 100000
        calls = {"n": 0}
        real = st._b_insert

        def failing(cur, rows):           # dies after the second chunk was written
            calls["n"] += 1
            real(cur, rows)
            if calls["n"] == 2:
                raise RuntimeError("connection lost")

        monkeypatch.setattr(st, "_b_insert", failing)
        with pytest.raises(RuntimeError):
            st.save_session(big)
        monkeypatch.undo()
        assert calls["n"] == 2 and [s["name"] for s in st.sessions()] == names
        assert st._query("SELECT COUNT(*) FROM samples")[0][0] == stored
        # bad data is refused before anything is written
        bad = _session("bad")
        bad.raw[0, 0] = 0.5
        with pytest.raises(UserError, match="integer counts"):
            st.save_session(bad)
        dup = _session("dup")
        dup.seq[1] = dup.seq[0]
        with pytest.raises(UserError, match="sequence number 70000 twice"):
            st.save_session(dup)
        with pytest.raises(UserError, match="already exists"):
            st.save_session(_session("s1", seed=5))
        assert [s["name"] for s in st.sessions()] == names
        # -- calibrations: the latest per mote ---------------------------------
        a = st.save_calibration("s1", 1, {"accel": {"A": np.eye(3), "c": np.zeros(3)}})
        b = st.save_calibration("s1", 2, {"mag": {"A": np.eye(3)}})
        c = st.save_calibration("s1", 1, {"v": 3, "f": np.float32(1.5)})
        assert 1 <= a < b < c
        assert st.load_calibration("s1", 1) == {"v": 3, "f": 1.5}
        assert st.load_calibration("s1", 2) == {"mag": {"A": np.eye(3).tolist()}}
        assert st.load_calibration("s1") == {"v": 3, "f": 1.5}
        with pytest.raises(UserError, match="no calibration stored for session 's1' mote 5"):
            st.load_calibration("s1", 5)
        with pytest.raises(UserError, match="unknown session"):
            st.save_calibration("nope", 1, {})
        with pytest.raises(UserError, match="not JSON"):
            st.save_calibration("s1", 1, {"x": object()})
        # -- diagnoses: the latest per mote, with the fingerprint of its rows ---
        key = data_key(data.for_mote(1))
        assert data_key(st.load_session("s1", mote=1)) == key
        big_d = {"clean": False, "findings": [{"sensor": "mag", "cause": "unexplained",
                                               "evidence": {"outlier_times_s": list(range(5000))}}]}
        i = st.save_diagnosis("s1", 1, big_d, tool="motecal x", data_key=key)
        j = st.save_diagnosis("s1", 1, {"clean": True, "findings": []}, tool="motecal y",
                              data_key=key)
        got_d = st.load_diagnosis("s1", 1)
        assert 1 <= i < j and got_d["id"] == j and got_d["diagnosis"] == {"clean": True,
                                                                          "findings": []}
        assert got_d["tool"] == "motecal y" and got_d["data_key"] == key
        assert got_d["created"].endswith("Z") and st.load_diagnosis("s1", 2) is None
        # -- a replaced session loses its calibrations and diagnoses -----------
        st.save_session(_session("s1", n=3000, motes=(1, 2, 3), seed=4), replace=True)
        _same(_session("s1", n=3000, motes=(1, 2, 3), seed=4), st.load_session("s1"))
        with pytest.raises(UserError, match="no calibration"):
            st.load_calibration("s1")
        assert st.load_diagnosis("s1", 1) is None
        assert [s["name"] for s in st.sessions()] == names[1:] + ["s1"]
        assert _orphans(st) == {}
        # -- temperatures --------------------------------------------------------
        tw = _session("tw", n=400, motes=(1, 3))
        tw.temp = np.round(np.linspace(18.25, 31.5, len(tw)), 6)
        tw.temp[7] = np.nan                   # unknown in one row: its neighbours fill it
        st.save_session(tw)
        want = tw.temp[np.lexsort((tw.seq, tw.mote))]
        back = st.load_session("tw").temp
        known = np.isfinite(want)
        assert np.array_equal(back[known], want[known])
        assert np.isclose(back[7], (want[6] + want[8]) / 2)
        assert np.array_equal(st.load_session("tw", mote=3).temp, want[200:])
        assert st.load_session("S1").temp is None              # a session without any
        w = st.open_session("live", kind="free", meta={"rate_hz": 125})
        w.add_samples(np.full(500, 2), np.arange(500), np.zeros(500), np.zeros(500, int),
                      np.ones((500, 9), int))
        w.add_temp(2, 124, 1.0, 25.5, 125)
        w.add_temp(2, 249, 2.0, 26.5, 125)
        w.add_temp(2, 249, 2.0, 26.5, 125)                     # the same message again
        w.commit()
        w.add_temp(2, 249, 2.0, 99.0, 125)                     # ... in a later commit
        w.end()
        assert st.temps("live").tolist() == [[2, 124, 1.0, 25.5, 125], [2, 249, 2.0, 26.5, 125]]
        d = st.load_session("live")
        assert d.temp[62] == 25.5 and d.temp[187] == d.temp[437] == 26.5
        assert np.isnan(d.temp[438:]).all() and np.isclose(d.temp[124], 25.5 + 62 / 125)
        st.save_session(_session("tw", seed=3), replace=True)  # replacing drops them
        assert st.load_session("tw").temp is None and len(st.temps("tw")) == 0
        # -- the live writer -----------------------------------------------------
        w = st.open_session("run", kind="free", meta={"source": "loop://", "notes": None})
        with pytest.raises(UserError, match="already exists"):
            st.open_session("run", kind="free")
        raw = np.arange(40 * 9).reshape(40, 9) - 100
        w.add_samples(np.full(40, 3), np.arange(65530, 65570), np.full(40, 0.5),
                      np.zeros(40, int), raw)
        w.set_label(3, 65540, 65549, 12)
        detail = "it's a \"quote\", a back\\slash and None"
        w.add_event("disconnect", detail)
        w.set_link_stats(3, {"frames": 8, "samples": 40, "lost": 2})
        w.set_line_stats({"crc_errors": 5, "gap_s": 0.25})
        assert w.pending == 40
        run = "SELECT COUNT(*) FROM samples s JOIN sessions n ON n.id = s.session " \
              "WHERE n.name = 'run'"
        with open_store(target) as other:          # nothing is seen before the commit
            assert other._query(run)[0][0] == 0
            w.commit()
            assert other._query(run)[0][0] == 40
        # a replay after reconnecting: stored rows are kept, new ones added;
        # counters are set to their latest values
        w.add_samples(np.full(2, 3), np.array([65530, 65570]), np.array([np.nan, 1.0]),
                      np.zeros(2, int), np.ones((2, 9), int))
        w.set_link_stats(3, {"frames": 9, "samples": 41})
        w.end()
        d = st.load_session("run")
        assert len(d) == 41 and d.raw[0].tolist() == list(range(-100, -91))
        assert d.raw[40].tolist() == [1] * 9 and d.t[40] == 1.0
        assert (np.flatnonzero(d.label == 12) == np.arange(10, 20)).all()
        stats = st.link_stats("run")
        m3 = stats["motes"][3]
        assert (m3["frames"], m3["samples"], m3["lost"]) == (9, 41, 2)
        assert stats["line"]["gap_s"] == 0.25 and stats["line"]["crc_errors"] == 5
        assert [(e["kind"], e["detail"]) for e in st.events("run")] == [("disconnect", detail)]
        info = {s["name"]: s for s in st.sessions()}
        assert info["run"]["ended"] is not None
        # --append continues the same session and reopens it
        w2 = st.open_session("run", kind="free", append=True)
        assert {s["name"]: s for s in st.sessions()}["run"]["ended"] is None
        assert st.last_seqs("run") == {3: 65570}
        w2.end()
        with pytest.raises(ValueError):
            w2.set_link_stats(1, {"bogus": 1})
        st.save_session(_session("run"), replace=True)
        assert _orphans(st) == {}


def test_older_schemas_migrate_and_a_newer_is_refused(new_db):
    """A database of every released schema version before this one: read as
    it is read-only (later tables and counters read empty or 0), migrated
    when opened for writing, and then every later table and counter column
    is there and works; a fresh database has a column for every counter; a
    newer schema is refused.  On every backend."""
    link_cols = {"session", "mote", "updated"} | set(store_schema.LINK_COUNTERS)
    line_cols = {"session", "updated"} | set(store_schema.LINE_COUNTERS)
    for v in range(1, SCHEMA_VERSION):
        target = new_db(f"v{v}")
        rows = [("INSERT INTO sessions (name, kind, started, scales, chips, meta) VALUES "
                 "(?, 'free', 0, '{}', '{}', '{}')", (f"v{v}",)),
                ("INSERT INTO samples (session, mote, seq, ax, ay, az) VALUES (1, 4, 9, 1, 2, 3)",
                 ())]
        if v >= 2:
            rows += [("INSERT INTO line_stats (session, frames, crc_errors) VALUES (1, 7, 1)", ()),
                     ("INSERT INTO link_stats (session, mote, frames, mote_i2c_errors) "
                      "VALUES (1, 5, 11, 2)", ())]
        _old_db(target, v, *rows)
        for readonly in (True, False):
            with open_store(target, readonly=readonly) as st:
                assert st.schema_version == (v if readonly else SCHEMA_VERSION), (v, readonly)
                d = st.load_session(f"v{v}")
                assert d.raw[0, :3].tolist() == [1, 2, 3] and np.isnan(d.raw[0, 3:]).all()
                assert d.temp is None and st.load_diagnosis(f"v{v}", 4) is None
                assert st.writers(f"v{v}") == [] and len(st.temps(f"v{v}")) == 0
                assert len(st.conflicts(f"v{v}")) == 0
                if readonly:                     # as it was made: later columns and tables absent
                    assert ("temps" in st._tables, "diagnoses" in st._tables) == (v >= 6, False)
                    if v >= 2:
                        assert ("cut_off" in st._b.columns("line_stats")) == (v >= 3)
                        assert ("mote_bus_resets" in st._b.columns("link_stats")) == (v >= 4)
                stats = st.link_stats(f"v{v}")
                if v == 1:
                    assert stats == {"line": {}, "motes": {}}
                else:
                    line, mote = stats["line"], stats["motes"][5]
                    assert (line["frames"], line["crc_errors"], line["cut_off"]) == (7, 1, 0)
                    assert (mote["frames"], mote["mote_i2c_errors"]) == (11, 2)
                    assert (mote["mote_i2c_nacks"], mote["mote_bus_resets"],
                            mote["mote_chip_reinits"]) == (0, 0, 0)
        with open_store(target) as st:           # what the later versions added works
            assert st._b.columns("link_stats") == link_cols, v
            assert st._b.columns("line_stats") == line_cols, v
            assert st._b.columns("temps") == {"session", "mote", "seq", "t", "temp_c", "count"}
            w = st.open_session(f"v{v}", kind="free", append=True, meta={"source": "again"})
            # seq 9 held NULLs where these are 0: a conflict, kept, not dropped
            w.add_samples(np.full(2, 4), np.array([9, 10]), np.zeros(2), np.zeros(2, int),
                          np.array([[1, 2, 3, 0, 0, 0, 0, 0, 0], [5] * 9]))
            w.add_temp(4, 10, 0.5, 21.5, 125)
            w.set_link_stats(4, {"mote_chip_reinits": 3})
            w.set_line_stats({"cut_off": 2})
            w.end()
            (wr,) = st.writers(f"v{v}")
            assert (wr["source"], wr["stored"], wr["conflicts"]) == ("again", 1, 1)
            assert len(st.conflicts(f"v{v}")) == 1
            assert st.temps(f"v{v}").tolist() == [[4, 10, 0.5, 21.5, 125]]
            stats = st.link_stats(f"v{v}")
            assert stats["motes"][4]["mote_chip_reinits"] == 3 and stats["line"]["cut_off"] == 2
            i = st.save_diagnosis(f"v{v}", 4, {"clean": True}, tool="motecal x", data_key="2:ab")
            got = st.load_diagnosis(f"v{v}", 4)
            assert (got["id"], got["tool"], got["data_key"], got["diagnosis"]) == \
                (i, "motecal x", "2:ab", {"clean": True})
            assert got["created"].endswith("Z") and st.load_diagnosis(f"v{v}", 1) is None
            warm = _session("warm")
            warm.temp = np.linspace(20.0, 21.0, len(warm))
            st.save_session(warm)
            want = warm.temp[np.lexsort((warm.seq, warm.mote))]
            assert np.array_equal(st.load_session("warm").temp, want)
    fresh = new_db("fresh")
    with open_store(fresh, create=True) as st:
        assert st._b.columns("link_stats") == link_cols
        assert st._b.columns("line_stats") == line_cols
        with st._tx() as cur:
            cur.execute(st._b.sql("UPDATE schema_version SET version = ?"), (SCHEMA_VERSION + 1,))
    with pytest.raises(UserError, match="newer than this motecal") as e:
        open_store(fresh)
    assert "\n" not in str(e.value)


def _schema_with_a_counter(name: str) -> types.ModuleType:
    """store_schema as a developer would leave it after adding one link
    counter the way docs/CONTRIBUTING.md says (a line in LINK_COUNTERS, a new
    migration adding its column, SCHEMA_VERSION bumped): its source changed
    so, and run as a module of its own."""
    src = Path(store_schema.__file__).read_text()
    v = store_schema.SCHEMA_VERSION + 1
    head, sep, rest = src.partition("LINK_COUNTERS = {\n")
    body, end, tail = rest.partition("\n}\n")
    src = head + sep + body + f'\n    "{name}": "a counter a later version adds",' + end + tail
    src = src.replace(f"SCHEMA_VERSION = {v - 1}\n", f"SCHEMA_VERSION = {v}\n", 1)
    src += (f"\nMIGRATIONS[{v}] = ['ALTER TABLE link_stats ADD COLUMN {name} "
            "BIGINT NOT NULL DEFAULT 0']\n")
    mod = types.ModuleType("motecal.sessions.store_schema_next")
    mod.__package__ = "motecal.sessions"
    exec(compile(src, "store_schema_next.py", "exec"), mod.__dict__)
    assert mod.SCHEMA_VERSION == v and name in mod.LINK_COUNTERS
    return mod


def test_a_counter_added_by_a_new_migration(new_db, monkeypatch):
    """Issue 24 item 5: the released migrations are literals, so a counter
    added with a new migration leaves them as they were: a fresh database is
    made (no "duplicate column name"), and a database of the released
    version gains the column, its rows reading 0; on every backend."""
    name = "mote_new_counter"
    nxt = _schema_with_a_counter(name)
    released = store_schema.MIGRATIONS
    assert {k: nxt.MIGRATIONS[k] for k in released} == released
    old = new_db("old")
    with open_store(old, create=True) as st:                    # the released version
        w = st.open_session("before", kind="free")
        w.set_link_stats(2, {"frames": 5, "lost": 1})
        w.end()
    monkeypatch.setattr(store_mod, "SCHEMA_VERSION", nxt.SCHEMA_VERSION)
    monkeypatch.setattr(store_mod, "MIGRATIONS", nxt.MIGRATIONS)
    monkeypatch.setitem(store_schema.LINK_COUNTERS, name, nxt.LINK_COUNTERS[name])
    fresh = new_db("fresh")
    for target in (fresh, old):
        with open_store(target, create=True) as st:
            assert st.schema_version == nxt.SCHEMA_VERSION
            w = st.open_session("after", kind="free")
            w.set_link_stats(3, {"frames": 9, name: 7})
            w.end()
            motes = st.link_stats("after")["motes"]
            assert (motes[3]["frames"], motes[3][name], motes[3]["lost"]) == (9, 7, 0)
    with open_store(old) as st:
        mote = st.link_stats("before")["motes"][2]
        assert (mote["frames"], mote["lost"], mote[name]) == (5, 1, 0)


def test_live_writer_stores_temperature_readings(tmp_path):
    """Readings of the mote's temperature messages: stored once (a repeated
    message is ignored), interpolated by seq to every row when loaded, the
    nearest within 2 s before the first and after the last, NaN further."""
    db = str(tmp_path / "temp.db")
    rate = 125
    with open_store(db, create=True) as st:
        w = st.open_session("warm", kind="free", meta={"rate_hz": rate})
        n = 20 * rate
        seq = np.arange(n)
        w.add_samples(np.full(n, 4), seq, np.full(n, 0.5), np.zeros(n, int), np.ones((n, 9), int))
        # one reading a second from second 5 to 12: 125 readings each, newest at seq
        newest = np.arange(5, 13) * rate - 1
        temps = 20.0 + 0.5 * np.arange(len(newest))
        for s, c in zip(newest, temps):
            w.add_temp(4, int(s), 1.0, float(c), rate)
        w.add_temp(4, int(newest[0]), 1.0, 99.0, rate)      # the same message again
        w.commit()
        w.add_temp(4, int(newest[1]), 1.0, 99.0, rate)      # ... in a later commit
        w.end()
        assert len(st.temps("warm")) == len(newest)
        d = st.load_session("warm")
    centre = newest - (rate - 1) / 2
    assert np.allclose(d.temp[centre.astype(int)], temps, atol=0.5 * 0.5 / rate)
    inside = (seq >= centre[0]) & (seq <= centre[-1])
    assert np.allclose(d.temp[inside], np.interp(seq[inside], centre, temps))
    before = seq < centre[0]
    near = before & (seq >= centre[0] - 2 * rate)
    assert np.all(d.temp[near] == temps[0]) and np.isnan(d.temp[before & ~near]).all()
    after = seq > centre[-1]
    near = after & (seq <= centre[-1] + 2 * rate)
    assert np.all(d.temp[near] == temps[-1]) and np.isnan(d.temp[after & ~near]).all()


def test_export_csv_format_and_atomic(tmp_path, monkeypatch):
    data = _session()
    out = tmp_path / "out.csv"
    assert export_csv(data, str(out)) == 12
    rows = list(csv.reader(out.open()))
    assert tuple(rows[0]) == CSV_HEADER
    assert rows[0] == "mote,seq,t,label,ax,ay,az,gx,gy,gz,mx,my,mz".split(",")
    r = {int(x[0]) * 10**6 + int(x[1]): x for x in rows[1:]}
    for i in range(len(data)):
        x = r[int(data.mote[i]) * 10**6 + int(data.seq[i])]
        assert x[2] == ("" if np.isnan(data.t[i]) else f"{data.t[i]:.6f}")
        assert x[3] == {0: "", 7: "7", LABEL_ROT: "rot"}[int(data.label[i])]
        assert x[4:] == ["" if np.isnan(v) else str(int(v)) for v in data.raw[i]]
    # a failure while writing leaves the old file untouched and no temp file
    out.write_text("previous\n")
    import motecal.sessions.importer

    class Boom(Exception):
        pass

    def half_then_fail(d, f):              # dies after writing part of the file
        f.write("mote,seq\n1,2\n")
        f.flush()
        raise Boom()

    monkeypatch.setattr(motecal.sessions.importer, "write_csv", half_then_fail)
    with pytest.raises(Boom):
        export_csv(data, str(out))
    assert out.read_text() == "previous\n"
    assert sorted(os.listdir(tmp_path)) == ["out.csv"]


def _motecal(*args, **kw):
    return subprocess.run([sys.executable, "-m", "motecal", *args], capture_output=True,
                          text=True, timeout=60, **kw)


def test_export_and_sessions_commands(tmp_path):
    db = str(tmp_path / "m.db")
    with open_store(db, create=True) as st:
        st.save_session(_session("alpha"))
    out = tmp_path / "a.csv"
    good = [("export", "--db", db, "--session", "alpha", "--csv", str(out), "--mote", "2"),
            ("sessions", "--db", db)]
    bad = [(("export", "--db", db, "--session", "nope", "--csv", str(out)), "unknown session"),
           (("export", "--db", db, "--session", "alpha", "--csv",
             str(tmp_path / "no" / "a.csv")), "does not exist")]
    procs = [subprocess.Popen([sys.executable, "-m", "motecal", *args], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True)
             for args in good + [b[0] for b in bad]]
    outs = [p.communicate(timeout=60) for p in procs]
    res = [(p.returncode, o, e) for p, (o, e) in zip(procs, outs)]
    (rc, _, err), (rc2, listing, _) = res[:2]
    assert rc == 0, err
    assert len(out.read_text().splitlines()) == 1 + 6
    assert rc2 == 0 and "alpha" in listing and "static80" in listing
    for (args, msg), (rc, _, err) in zip(bad, res[2:]):
        assert rc == 2, (args, err)
        assert msg in err and len(err.strip().splitlines()) == 1, err
        assert "Traceback" not in err


# --------------------------------------------------------------------------
# PostgreSQL: a real server (Debian's postgresql package), started in a
# temporary folder, reachable only through its unix socket (fixture pg_url,
# conftest.py / dbservers.py).
# --------------------------------------------------------------------------
def test_postgres_two_base_stations_log_into_one_server(pg_url, tmp_path):
    from motecal.line import sources as S
    from motecal.capture.guide import GuidedFlow
    from motecal.capture.link import LinkTracker
    from motecal.capture.logger import Logger
    from test_logger_streams import pose_trajectory, sample_frames
    recs, sent = {}, {}
    for k, motes in enumerate(((1, 2), (7,))):
        raws = {m: pose_trajectory(n_poses=3, seed=m)[0] for m in motes}
        frames, sent[k] = sample_frames(raws, seq0={m: 65400 for m in motes})
        recs[k] = tmp_path / f"bs{k}.bin"
        recs[k].write_bytes(b"".join(frames))
    import threading
    errors = []

    def station(k):
        try:
            with open_store(pg_url) as st:
                w = st.open_session(f"bs{k}", kind="static80", meta={"source": f"bs{k}"})
                Logger(S.parse_port(str(recs[k])), w, LinkTracker(),
                       guide=GuidedFlow("static80", options=dict(poses=3))).run()
        except Exception as e:          # surfaced below
            errors.append(e)

    threads = [threading.Thread(target=station, args=(k,)) for k in sent]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    assert not errors
    with open_store(pg_url) as st:
        for k in sent:
            d = st.load_session(f"bs{k}")
            for m, (seq, raw) in sent[k].items():
                dm = d.for_mote(m)
                np.testing.assert_array_equal(dm.seq, seq)
                np.testing.assert_array_equal(dm.raw, raw)
                assert dm.poses() == [1, 2, 3]
            assert st.link_stats(f"bs{k}")["motes"].keys() == sent[k].keys()
            assert [e["kind"] for e in st.events(f"bs{k}")].count("accepted") == 3 * len(sent[k])
    out = tmp_path / "bs0.csv"
    r = _motecal("export", "--db", pg_url, "--session", "bs0", "--csv", str(out))
    assert r.returncode == 0, r.stderr
    assert len(out.read_text().splitlines()) == 1 + sum(len(s) for s, _ in sent[0].values())


def test_postgres_two_loggers_one_session_keep_every_sample(pg_url, tmp_path):
    """Issue 15 case 6 on PostgreSQL, where the two writers run side by side
    (no file lock): the same model as sqlite (test_safety_writers)."""
    from test_safety_writers import check_model, log_together, two_stations
    recs, raw, other, rows = two_stations(tmp_path, seed=2)
    writers = log_together(pg_url, recs, session="pgx")
    check_model(pg_url, writers, raw, other, rows, session="pgx")
