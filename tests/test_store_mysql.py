"""The store on MySQL/MariaDB (sessions/store_mysql.py): URLs and the dialect,
then a real MariaDB server (Debian's packages, started by the `mariadb`
fixture in a temporary folder, dbservers.py): connection problems are one
line; a simulated 3-mote session logged into MariaDB and into sqlite exports
to the same CSV; two loggers writing into one server at once lose nothing.
The sessions, calibrations, counters and migrations every backend keeps alike
are tested on all three in test_store.py (test_roundtrip_on_every_backend,
test_older_schemas_migrate_and_a_newer_is_refused).  (~30 s)"""
import subprocess
import sys
import threading

import numpy as np
import pytest

from motecal.errors import UserError
from motecal.sessions import store as store_mod
from motecal.sessions import store_mysql as M
from motecal.sessions.store import SCHEMA_VERSION, open_store
from motecal.sim.serve import serve_in_thread, write_file
from motecal.sim.world import World


def _motecal(*args, timeout=180):
    return subprocess.run([sys.executable, "-m", "motecal", *args], capture_output=True,
                          text=True, timeout=timeout, stdin=subprocess.DEVNULL)


# --------------------------------------------------------------------------
# URLs and dialect (no server)
# --------------------------------------------------------------------------
def test_url_forms():
    args, shown = M.parse_url("mysql://lab:s%40cret@db.example:3307/motecal")
    assert args == dict(host="db.example", port=3307, user="lab", password="s@cret",
                        database="motecal")
    assert shown == "mysql://lab:***@db.example:3307/motecal"
    assert M.parse_url("mariadb://lab@10.0.0.2/m")[0]["port"] == 3306
    args, _ = M.parse_url("mysql://lab@/motecal?unix_socket=/tmp/x/mysql.sock")
    assert args["unix_socket"] == "/tmp/x/mysql.sock" and "host" not in args
    assert M.parse_url("mysql://lab@/motecal")[0]["unix_socket"] == M.DEFAULT_SOCKET
    assert M.parse_url("mysql:///motecal")[0]["user"] is None
    for url, msg in [("mysql://lab@host", "names no database"),
                     ("mysql://lab@host/", "names no database"),
                     ("mysql://lab@host:port/db", "bad database URL"),
                     ("mysql://lab@host/db?sslmode=on", "unknown option")]:
        with pytest.raises(UserError, match=msg) as e:
            open_store(url)
        assert "\n" not in str(e.value)


def test_dialect():
    opts = "ENGINE=InnoDB"
    ddl = {}
    for stmt in store_mod.MIGRATIONS[1] + store_mod.MIGRATIONS[2]:
        q, ret = M.translate(stmt.format(**M.MysqlBackend.types), opts)
        assert not ret and "{" not in q
        ddl[q.split()[2]] = q
    assert "name VARCHAR(700) NOT NULL UNIQUE" in ddl["sessions"]
    assert "label VARCHAR(16) NOT NULL DEFAULT ''" in ddl["samples"]
    assert "detail LONGTEXT NOT NULL DEFAULT ('')" in ddl["events"]
    assert "id BIGINT AUTO_INCREMENT PRIMARY KEY" in ddl["calibrations"]
    assert all(q.endswith(opts) for k, q in ddl.items() if k not in ("calibrations_session",
                                                                     "events_session"))
    q, ret = M.translate("INSERT INTO calibrations (session, mote) VALUES (?, ?) RETURNING id",
                         opts)
    assert (q, ret) == ("INSERT INTO calibrations (session, mote) VALUES (%s, %s)", True)
    q, _ = M.translate(store_mod.SessionWriter._INSERT, opts)
    assert q.endswith("VALUES (" + ", ".join(["%s"] * 14) + ") "
                      "ON DUPLICATE KEY UPDATE session = session")
    q, _ = M.translate("INSERT INTO line_stats (session, frames, updated) VALUES (?, ?, ?) "
                       "ON CONFLICT (session) DO UPDATE SET frames = excluded.frames, "
                       "updated = excluded.updated", opts)
    assert q.endswith("ON DUPLICATE KEY UPDATE frames = VALUES(frames), "
                      "updated = VALUES(updated)")


def test_missing_driver_is_one_line_exit_2(tmp_path):
    """Without PyMySQL (or psycopg) a server URL gives one line and exit 2."""
    code = ("import sys; sys.modules['pymysql'] = None; sys.modules['psycopg'] = None; "
            "from motecal.commands.main import main; sys.exit(main(sys.argv[1:]))")
    for url, want in [("mysql://lab@db/m", "needs the PyMySQL package (pip install "
                                           "'./host[mysql]')"),
                      ("postgresql://lab@db/m", "needs the psycopg package (pip install "
                                                "'./host[postgres]')")]:
        r = subprocess.run([sys.executable, "-c", code, "sessions", "--db", url],
                           capture_output=True, text=True, timeout=60)
        assert r.returncode == 2, r.stderr
        assert want in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr


# --------------------------------------------------------------------------
# A real MariaDB server
# --------------------------------------------------------------------------
@pytest.fixture
def fresh_db(mariadb, request):
    """An empty database of its own on the test server (URL over the socket)."""
    import dbservers
    return dbservers.new_database(mariadb, "t_" + request.node.name[:40].replace("[", "_")
                                  .replace("]", "_").replace("-", "_"))


def test_connection_problems_are_one_line(mariadb, fresh_db):
    import dbservers
    bad = [(mariadb.url.replace(dbservers.MARIADB_PASSWORD, "wrong"), "Access denied"),
           (mariadb.url.replace("/motecal?", "/nosuchdb?"), "nosuchdb"),
           (mariadb.url.replace("mysql.sock", "none.sock"), "cannot connect"),
           (f"mysql://motecal:{dbservers.MARIADB_PASSWORD}@127.0.0.1:1/motecal",
            "cannot connect")]
    for url, msg in bad:
        with pytest.raises(UserError, match=msg) as e:
            open_store(url)
        text = str(e.value)
        assert "\n" not in text and dbservers.MARIADB_PASSWORD not in text
        assert "wrong" not in text and "motecal:***@" in text
    # a database with other tables is not taken over
    import pymysql
    con = pymysql.connect(unix_socket=str(mariadb.root / "mysql.sock"), user="root",
                          autocommit=True)
    with con, con.cursor() as cur:
        cur.execute(f"CREATE TABLE {M.parse_url(fresh_db)[0]['database']}.foo (x INT)")
    with pytest.raises(UserError, match=r"not a motecal database \(.*it holds foo\)"):
        open_store(fresh_db)
    r = _motecal("sessions", "--db", fresh_db)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr


def _recording(path, seed, duration):
    world = World(motes=3, session="static80", seed=seed, duration=duration)
    with open(path, "wb") as f:
        write_file(world, f)
    return world


def test_simulated_session_same_csv_from_mariadb_and_sqlite(mariadb, tmp_path):
    """A simulated 3-mote session logged into MariaDB (over TCP) and into
    sqlite: the same samples as the simulator sent, and byte-identical CSVs."""
    rec = tmp_path / "line.bin"
    world = _recording(rec, seed=3, duration=90)
    targets = {"sqlite": str(tmp_path / "s.db"), "mariadb": mariadb.tcp_url}
    csvs = {}
    for kind, db in targets.items():
        r = _motecal("log", "--port", str(rec), "--db", db, "--session", "sim3", "--guided",
                     "static80", "--yes")
        assert r.returncode == 0, (kind, r.stderr)
        out = tmp_path / f"{kind}.csv"
        e = _motecal("export", "--db", db, "--session", "sim3", "--csv", str(out))
        assert e.returncode == 0, (kind, e.stderr)
        csvs[kind] = out.read_bytes()
        with open_store(db) as st:
            data = st.load_session("sim3")
            stats = st.link_stats("sim3")
        assert data.motes == [1, 2, 3] and data.poses()
        for m in (1, 2, 3):
            dm = data.for_mote(m)
            np.testing.assert_array_equal(dm.seq, world.sent[m].seq)
            np.testing.assert_array_equal(dm.raw, world.sent[m].records)
            assert stats["motes"][m]["samples"] == len(world.sent[m])
    assert csvs["sqlite"] == csvs["mariadb"]
    assert len(csvs["sqlite"].splitlines()) == 1 + sum(len(world.sent[m]) for m in (1, 2, 3))


def test_two_loggers_into_one_server_at_once(mariadb, fresh_db):
    """Two base stations (simulated, served over TCP at 5x real time), each
    logged by its own `motecal log` process into one MariaDB database at the
    same time: every sample each simulator sent is stored, in its session."""
    worlds, servers = {}, []
    try:
        for k, seed in enumerate((4, 5)):
            worlds[k] = World(motes=3, session="static80", seed=seed)
            server, port = serve_in_thread(worlds[k], speed=5.0)
            servers.append((server, port))
        procs = [subprocess.Popen(
            [sys.executable, "-m", "motecal", "log", "--port", f"socket://127.0.0.1:{port}",
             "--db", fresh_db, "--session", f"bs{k}", "--guided", "static80", "--poses", "4",
             "--yes"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            stdin=subprocess.DEVNULL) for k, (_, port) in enumerate(servers)]
        outs = [p.communicate(timeout=240) for p in procs]
    finally:
        for server, _ in servers:
            server.stop()
            server.close()
    for p, (out, err) in zip(procs, outs):
        assert p.returncode == 0, err
        assert "guided flow done" in out
    with open_store(fresh_db) as st:
        info = {s["name"]: s for s in st.sessions()}
        assert sorted(info) == ["bs0", "bs1"]
        # they did write at the same time
        assert max(i["started"] for i in info.values()) < min(i["ended"] for i in info.values())
        for k, world in worlds.items():
            d = st.load_session(f"bs{k}")
            stats = st.link_stats(f"bs{k}")
            assert d.motes == [1, 2, 3]
            for m in (1, 2, 3):
                dm, sent = d.for_mote(m), world.sent[m]
                n = len(dm)
                assert n > 4 * 200, (k, m, n)       # at least the poses the flow took
                np.testing.assert_array_equal(dm.seq, sent.seq[:n])
                np.testing.assert_array_equal(dm.raw, sent.records[:n])
                c = stats["motes"][m]
                assert (c["samples"], c["lost"], c["duplicates"]) == (n, 0, 0)
            assert len(d.poses()) == 4


def test_threads_share_nothing_but_the_server(mariadb, fresh_db):
    """Several writers in one process (one connection each) append batches
    to their own sessions concurrently: all rows arrive."""
    errors = []

    def writer(k):
        try:
            with open_store(fresh_db) as st:
                w = st.open_session(f"w{k}", kind="free")
                for i in range(20):
                    seq = np.arange(i * 500, (i + 1) * 500)
                    w.add_samples(np.full(500, k), seq, np.full(500, i * 0.1),
                                  np.zeros(500, int), np.full((500, 9), k))
                    w.commit()
                w.end()
        except Exception as e:      # surfaced below
            errors.append(e)

    threads = [threading.Thread(target=writer, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(120)
    assert not errors
    with open_store(fresh_db) as st:
        for k in range(4):
            d = st.load_session(f"w{k}")
            assert len(d) == 10_000 and (d.seq == np.arange(10_000)).all()
            assert (d.raw == k).all()


def test_first_opens_at_once_make_the_schema_once(fresh_db):
    """MySQL shows each new table at once (DDL is not transactional): openers
    of an empty database at the same moment wait for the one migrating."""
    barrier = threading.Barrier(6)
    results = []

    def opener():
        barrier.wait()
        try:
            with open_store(fresh_db) as st:
                results.append(st.schema_version)
        except Exception as e:      # surfaced below
            results.append(e)

    threads = [threading.Thread(target=opener) for _ in range(6)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(120)
    assert results == [SCHEMA_VERSION] * 6
