"""End to end: the simulator's sessions through `motecal log` into sqlite.

static80, 3 motes, over socket://: every sample the simulator put on the
serial line is in the database (sequence-checked, values equal) and each mote
has exactly 80 poses of 200 samples, each inside the simulator's own still
stretch of that pose.  rotation over a pseudo-terminal: labelled `rot` until
the coverage is reached.
"""
import csv
import subprocess
import sys

import numpy as np
import pytest

from motecal.sessions.session import LABEL_ROT
from motecal.sessions.store import open_store
from motecal.sim.serve import pty_in_thread, serve_in_thread
from motecal.sim.world import World


def _log(*args, timeout=240):
    return subprocess.run([sys.executable, "-m", "motecal", "log", *args], capture_output=True,
                          text=True, timeout=timeout, stdin=subprocess.DEVNULL)


def _sent_equals_stored(world, data, m):
    sent = world.sent[m]
    dm = data.for_mote(m)
    np.testing.assert_array_equal(dm.seq, sent.seq)          # every sample, in order
    np.testing.assert_array_equal(dm.raw, sent.records)
    np.testing.assert_array_equal(dm.flags, sent.flags)
    return sent, dm


@pytest.mark.slow
def test_static80_three_motes_over_tcp(tmp_path):
    world = World(motes=3, session="static80", seed=1)
    server, port = serve_in_thread(world)
    db = str(tmp_path / "e2e.db")
    try:
        r = _log("--port", f"socket://127.0.0.1:{port}", "--db", db, "--session", "s80",
                 "--guided", "static80", "--yes")
    finally:
        server.stop()
        server.close()
    assert r.returncode == 0, r.stderr
    assert world.done, "the logger stopped before the simulator had sent everything"
    assert "guided flow done" in r.stdout
    with open_store(db) as st:
        data = st.load_session("s80")
        stats = st.link_stats("s80")
        info = st.sessions()[0]
    assert data.kind == "static80" and info["ended"] is not None
    assert data.motes == [1, 2, 3]
    for m in (1, 2, 3):
        sent, dm = _sent_equals_stored(world, data, m)
        truth = world.trajectory.label_at(sent.t)
        assert dm.poses() == list(range(1, 81))
        assert np.bincount(dm.label[dm.label > 0]).tolist()[1:] == [200] * 80
        for k in range(1, 81):                # the simulator held pose k for these rows
            assert set(truth[dm.label == k]) == {k}, (m, k)
        c = stats["motes"][m]
        assert (c["samples"], c["lost"], c["duplicates"]) == (len(sent), 0, 0)
    assert stats["line"]["crc_errors"] == 0 and stats["line"]["bs_status_msgs"] > 0
    # and the export is the same data
    out = tmp_path / "s80.csv"
    e = subprocess.run([sys.executable, "-m", "motecal", "export", "--db", db, "--session", "s80",
                        "--csv", str(out), "--mote", "2"], capture_output=True, text=True,
                       timeout=60)
    assert e.returncode == 0, e.stderr
    rows = list(csv.DictReader(out.open()))
    d2 = data.for_mote(2)
    assert len(rows) == len(d2)
    assert [r["label"] for r in rows[::97]] == [("" if v == 0 else str(v)) for v in d2.label[::97]]
    assert [int(r["mz"]) for r in rows[::89]] == d2.raw[::89, 8].astype(int).tolist()


def test_rotation_over_a_pty(tmp_path):
    world = World(motes=1, session="rotation", seed=2)
    line, path = pty_in_thread(world)
    db = str(tmp_path / "rot.db")
    try:
        r = _log("--port", path, "--db", db, "--session", "rot", "--guided", "rotation", "--yes")
    finally:
        line.stop()
        line.close()
    assert r.returncode == 0, r.stderr
    with open_store(db) as st:
        data = st.load_session("rot")
        events = st.events("rot")
    sent = world.sent[1]
    n = len(data)
    np.testing.assert_array_equal(data.seq, sent.seq[:n])
    np.testing.assert_array_equal(data.raw, sent.records[:n])
    rot = np.flatnonzero(data.label == LABEL_ROT)
    assert len(rot) >= 500 and (rot == np.arange(len(rot))).all()    # from the start, no holes
    done = [e for e in events if e["kind"] == "done"]
    assert len(done) == 1 and f"{len(rot)} samples" in done[0]["detail"]
    assert len(rot) == 5000 or "coverage" in done[0]["detail"]
