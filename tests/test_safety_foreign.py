"""Issue 15, case 7: a sqlite file that is not a motecal database is refused
by every command before anything is written to it: no WAL switch, no tables,
no version change (PRAGMA application_id and the schema's signature)."""
import os
import sqlite3

import numpy as np
import pytest

from clirun import digest, make_db, motecal
from motecal.errors import UserError
from motecal.sessions import store as store_mod
from motecal.sessions.store import APPLICATION_ID, SCHEMA_VERSION, open_store
from motecal.sessions.store_sqlite import SqliteBackend


def _foreign(path, statements, app_id=0):
    con = sqlite3.connect(path)
    for s in statements:
        con.execute(s)
    if app_id:
        con.execute(f"PRAGMA application_id = {app_id}")
    con.commit()
    con.close()
    return str(path)


FOREIGN = {
    # another program's table named schema_version (motecal used to add its tables)
    "schema_version_only": ["CREATE TABLE schema_version (version INTEGER)",
                            "INSERT INTO schema_version VALUES (1)",
                            "CREATE TABLE notes (x TEXT)"],
    # once gave "no such table: line_stats"
    "signature_v2_without_link_tables": [
        "CREATE TABLE schema_version (version INTEGER)", "INSERT INTO schema_version VALUES (3)"]
        + [m.format(**SqliteBackend.types) for m in store_mod.MIGRATIONS[1][1:]],
    # once gave "invalid literal for int()"
    "text_version": ["CREATE TABLE schema_version (version TEXT)",
                     "INSERT INTO schema_version VALUES ('abc')"]
        + [m.format(**SqliteBackend.types) for m in store_mod.MIGRATIONS[1][1:]],
    "two_versions": [m.format(**SqliteBackend.types) for m in store_mod.MIGRATIONS[1]]
        + ["INSERT INTO schema_version VALUES (1)", "INSERT INTO schema_version VALUES (1)"],
    "samples_without_our_columns": ["CREATE TABLE schema_version (version INTEGER)",
                                    "INSERT INTO schema_version VALUES (1)",
                                    "CREATE TABLE sessions (id INTEGER, name TEXT)",
                                    "CREATE TABLE samples (a, b)",
                                    "CREATE TABLE calibrations (id)"],
    "plain_app": ["CREATE TABLE customers (id INTEGER PRIMARY KEY, name TEXT)",
                  "INSERT INTO customers (name) VALUES ('x')"],
}


def _commands(db, tmp_path, rec):
    out = tmp_path / "out"
    return [
        ("sessions", "--db", db), ("sessions", "--db", db, "--json"),
        ("export", "--db", db, "--session", "s", "--csv", out / "x.csv"),
        ("calibrate", "--db", db, "--session", "s", "--out", out / "c.json"),
        ("diagnose", "--db", db, "--session", "s"),
        ("report", "--db", db, "--session", "s", "--out", out / "rep"),
        ("log", "--port", rec, "--db", db, "--session", "s"),
        ("log", "--port", rec, "--db", db, "--session", "s", "--append"),
        ("import", rec.parent / "in.csv", "--db", db, "--session", "s"),
    ]


@pytest.mark.parametrize("shape", sorted(FOREIGN) + ["other_application_id"])
def test_case7_foreign_sqlite_is_refused_by_every_command_untouched(tmp_path, shape):
    work = tmp_path / "w"
    work.mkdir()
    (tmp_path / "out").mkdir()
    if shape == "other_application_id":   # motecal's whole schema, another program's id
        db = make_db(work / "f.db")
        con = sqlite3.connect(db)
        con.execute("PRAGMA journal_mode = DELETE")
        con.execute("PRAGMA application_id = 1234")
        con.commit()
        con.close()
    else:
        db = _foreign(work / "f.db", FOREIGN[shape])
    rec = tmp_path / "rec.bin"
    rec.write_bytes(b"")
    (tmp_path / "in.csv").write_text("mote,seq,t,label,ax,ay,az,gx,gy,gz,mx,my,mz\n"
                                     "1,0,0,,1,2,3,4,5,6,7,8,9\n")
    before = digest(db)
    for argv in _commands(db, tmp_path, rec):
        rc, out, err = motecal(*argv)
        assert rc == 2 and "not a motecal database" in err, (argv, rc, err)
        assert err.count("\n") == 1 and "Traceback" not in err
        assert digest(db) == before, argv                       # not one byte written
        assert os.listdir(work) == ["f.db"], argv               # no -wal, no -journal
    con = sqlite3.connect(db)
    assert con.execute("PRAGMA journal_mode").fetchone()[0] == "delete"
    con.close()
    assert os.listdir(tmp_path / "out") == []


def test_case7_an_older_motecal_database_is_recognised_and_marked(tmp_path):
    """A version 3 database made before the application id is recognised by its
    whole signature, read as it is read-only, and marked when written."""
    v3 = str(tmp_path / "v3.db")
    con = sqlite3.connect(v3)
    for v in (1, 2, 3):
        for stmt in store_mod.MIGRATIONS[v]:
            con.execute(stmt.format(**SqliteBackend.types))
    con.execute("INSERT INTO schema_version VALUES (3)")
    con.execute("INSERT INTO sessions (name, kind, started, scales, chips, meta) VALUES "
                "('three', 'free', 0, '{}', '{}', '{}')")
    con.execute("INSERT INTO samples (session, mote, seq, ax) VALUES (1, 2, 5, 7)")
    con.commit()
    con.close()
    before = digest(v3)
    with open_store(v3, readonly=True) as st:                    # read as it is
        assert st.version == 3 and st.load_session("three").raw[0, 0] == 7
        assert st.link_stats("three") == {"line": {}, "motes": {}} and st.writers("three") == []
    assert digest(v3) == before and os.listdir(tmp_path) == ["v3.db"]
    rc, out, err = motecal("sessions", "--db", v3)
    assert rc == 0 and "three" in out and digest(v3) == before
    with open_store(v3) as st:                                   # a writer migrates and marks
        assert st.schema_version == SCHEMA_VERSION
    con = sqlite3.connect(v3)
    assert con.execute("PRAGMA application_id").fetchone()[0] == APPLICATION_ID
    con.close()


def test_case7_new_databases_carry_the_application_id(tmp_path):
    db = make_db(tmp_path / "n.db")
    con = sqlite3.connect(db)
    assert con.execute("PRAGMA application_id").fetchone()[0] == APPLICATION_ID
    con.close()


def test_case7_special_files_as_the_database(tmp_path):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    rec = tmp_path / "rec.bin"
    rec.write_bytes(b"")
    csv = tmp_path / "in.csv"
    csv.write_text("mote,seq,t,label,ax,ay,az,gx,gy,gz,mx,my,mz\n1,0,0,,1,2,3,4,5,6,7,8,9\n")
    for argv in (("log", "--port", rec, "--db", fifo, "--session", "s"),
                 ("sessions", "--db", fifo), ("import", csv, "--db", fifo, "--session", "s")):
        rc, out, err = motecal(*argv)
        assert rc == 2 and "not a database file" in err and "Traceback" not in err, (argv, err)
    with pytest.raises(UserError, match="not a database file"):
        open_store(str(fifo), create=True)
