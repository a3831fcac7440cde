"""Faults: SIGKILL while logging, the port closing and coming back, corrupted
bytes, signals, and bad command lines (one line on stderr, no traceback)."""
import os
import signal
import socket
import sqlite3
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from motecal.capture.link import LinkTracker
from motecal.capture.logger import Logger
from motecal.line import sources as S
from motecal.sessions.store import open_store
from test_logger_streams import sample_frames

RATE = 125.0


def _motecal(*args, **kw):
    return [sys.executable, "-m", "motecal", *args]


def _raws(n, motes=(1, 2, 3), seed=0):
    rng = np.random.default_rng(seed)
    return {m: rng.integers(-3000, 3000, (n, 9)).astype(np.int16) for m in motes}


class StreamServer(threading.Thread):
    """A TCP 'serial line' sending ``frames``; ``pace`` frames per second
    (None: as fast as the reader takes them).  Logs when each frame was sent."""

    def __init__(self, frames, pace=None):
        super().__init__(daemon=True)
        self.frames = frames
        self.pace = pace
        self.lsock = socket.create_server(("127.0.0.1", 0))
        self.port = self.lsock.getsockname()[1]
        self.sent_at = np.full(len(frames), np.inf)
        self.stop = threading.Event()

    def run(self):
        conn, _ = self.lsock.accept()
        t0 = time.monotonic()
        try:
            step = 64 if self.pace is None else 3
            for i in range(0, len(self.frames), step):
                if self.stop.is_set():
                    break
                if self.pace is not None:
                    delay = t0 + i / self.pace - time.monotonic()
                    if delay > 0:
                        time.sleep(delay)
                conn.sendall(b"".join(self.frames[i:i + step]))
                self.sent_at[i:i + step] = time.monotonic()
        except OSError:
            pass
        finally:
            conn.close()
            self.lsock.close()


def _wait_rows(db, n, timeout=30.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            con = sqlite3.connect(db, timeout=1)
            got = con.execute("SELECT COUNT(*) FROM samples").fetchone()[0]
            con.close()
            if got >= n:
                return got
        except sqlite3.Error:
            pass
        time.sleep(0.05)
    raise AssertionError(f"fewer than {n} rows after {timeout} s")


def _frame_index(frames_per_mote, motes):
    """(mote, first row) of each interleaved frame built by sample_frames."""
    out = []
    for i in range(frames_per_mote):
        for m in motes:
            out.append((m, 5 * i))
    return out


def _check_prefix(db, raws, session):
    """Every mote's stored rows are exactly the first rows it sent."""
    con = sqlite3.connect(db)
    assert con.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
    con.close()
    stored = {}
    with open_store(db) as st:
        d = st.load_session(session)
    for m, raw in raws.items():
        dm = d.for_mote(m)
        n = len(dm)
        np.testing.assert_array_equal(dm.seq, np.arange(n))
        np.testing.assert_array_equal(dm.raw, raw[:n])
        stored[m] = n
    return stored


@pytest.mark.parametrize("pace", [3 * RATE / 5, None], ids=["real-time", "flat-out"])
def test_sigkill_keeps_an_intact_database(tmp_path, pace):
    n = 25_000 if pace is None else 2500
    raws = _raws(n)
    frames, _ = sample_frames(raws)
    index = _frame_index(n // 5, (1, 2, 3))
    server = StreamServer(frames, pace)
    server.start()
    db = str(tmp_path / "k.db")
    proc = subprocess.Popen(_motecal("log", "--port", f"socket://127.0.0.1:{server.port}",
                                     "--db", db, "--session", "k"),
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        _wait_rows(db, 300)
        time.sleep(1.3 if pace else 0.4)
        t_kill = time.monotonic()
        proc.send_signal(signal.SIGKILL)
        proc.wait(10)
    finally:
        if proc.poll() is None:
            proc.kill()
        server.stop.set()
    stored = _check_prefix(db, raws, "k")
    assert min(stored.values()) >= 50
    if pace:
        # at the line's pace: everything sent more than a second before the kill
        # is there (flat out, the socket buffers hold more than a second) ...
        for (m, row), at in zip(index, server.sent_at):
            if at < t_kill - 1.0:
                assert stored[m] >= row + 5, (m, row, stored[m])
        # ... and at most one second of samples (125 per mote) is missing
        sent = {m: max([r + 5 for (mm, r), at in zip(index, server.sent_at)
                        if mm == m and at <= t_kill] + [0]) for m in raws}
        for m in raws:
            assert sent[m] - stored[m] <= RATE, (m, sent[m], stored[m])


def test_port_closes_and_comes_back(tmp_path):
    raws = _raws(1500, motes=(1, 2))
    frames, _ = sample_frames(raws)
    index = _frame_index(300, (1, 2))
    half = len(frames) // 2
    # mote 1's frames sent while the line was down never arrive: 25 frames = 125 samples
    skipped = [i for i in range(half, len(frames)) if index[i][0] == 1][:25]
    part_b = [f for i, f in enumerate(frames) if i >= half and i not in skipped]
    lsock = socket.create_server(("127.0.0.1", 0))
    port = lsock.getsockname()[1]
    logger_box = {}

    def serve(ls):
        conn, _ = ls.accept()
        conn.sendall(b"".join(frames[:half]) + frames[half][:40])   # ends mid-frame
        time.sleep(0.2)
        conn.close()
        ls.close()                            # the port is gone for a while
        time.sleep(0.8)
        ls = socket.create_server(("127.0.0.1", port))
        conn, _ = ls.accept()
        conn.sendall(b"".join(part_b))
        time.sleep(0.5)
        logger_box["logger"].request_stop("test done")
        time.sleep(0.2)
        conn.close()
        ls.close()

    th = threading.Thread(target=serve, args=(lsock,), daemon=True)
    db = str(tmp_path / "r.db")
    with open_store(db, create=True) as st:
        w = st.open_session("r", kind="free")
        lg = Logger(S.parse_port(f"socket://127.0.0.1:{port}"), w, LinkTracker())
        logger_box["logger"] = lg
        th.start()
        lg.run()
        d = st.load_session("r")
        stats = st.link_stats("r")
        events = st.events("r")
    th.join(5)
    missing = {index[i][1] + k for i in skipped for k in range(5)}
    d1 = d.for_mote(1)
    want1 = np.array([s for s in range(1500) if s not in missing])
    np.testing.assert_array_equal(d1.seq, want1)
    np.testing.assert_array_equal(d1.raw, raws[1][want1])
    np.testing.assert_array_equal(d.for_mote(2).raw, raws[2])
    assert stats["motes"][1]["lost"] == 125 and stats["motes"][2]["lost"] == 0
    assert stats["line"]["disconnects"] == 1 and stats["line"]["gap_s"] >= 0.7
    assert stats["line"]["cut_off"] == 1 and stats["line"]["crc_errors"] == 0   # the cut frame
    assert [e["kind"] for e in events] == ["disconnect", "reconnect"]


def _until(cond, timeout=30.0):
    deadline = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.02)


def test_a_mote_that_reboots_is_numbered_on_not_dropped(tmp_path):
    """The simulator (a mote) stops after about 1600 samples and starts again
    on the same port with another seed: the rebooted mote counts from 0
    again, below the last sequence number logged, and its samples are new
    ones, stored after the earlier ones -- not dropped as duplicates."""
    from motecal.sim.serve import TcpLine, serve_in_thread
    from motecal.sim.world import World
    first = World(motes=1, session="idle", seed=2, duration=13.0)
    server, port = serve_in_thread(first)
    with open_store(str(tmp_path / "r.db"), create=True) as st:
        lg = Logger(S.parse_port(f"socket://127.0.0.1:{port}"), st.open_session("r", kind="idle"),
                    LinkTracker())
        th = threading.Thread(target=lg.run, daemon=True)
        th.start()
        try:
            _until(lambda: first.done and lg.tracker.mote(1).c["samples"] >= len(first.sent[1]))
            n1 = len(first.sent[1])
            server.stop()
            server.close()                                 # the mote is switched off ...
            second = World(motes=1, session="idle", seed=3, duration=5.0)
            server = TcpLine(second, "127.0.0.1", port).start()    # ... and on again
            _until(lambda: second.done and lg.tracker.mote(1).c["samples"] >= n1 + len(
                second.sent[1]) or lg.tracker.mote(1).c["duplicates"] > 100)
        finally:
            lg.request_stop("test done")
            th.join(10)
            server.stop()
            server.close()
        d = st.load_session("r")
        c = st.link_stats("r")["motes"][1]
    assert 1500 < n1 < 1700 and first.sent[1].seq[-1] == n1 - 1
    n2 = len(second.sent[1])
    assert (c["duplicates"], c["restarts"], c["lost"], c["samples"]) == (0, 1, 0, n1 + n2)
    np.testing.assert_array_equal(d.seq, np.arange(n1 + n2))
    np.testing.assert_array_equal(d.raw, np.vstack([first.sent[1].raw, second.sent[1].raw]))


def test_corrupted_bytes_never_make_corrupt_rows(tmp_path):
    raws = _raws(1500, seed=3)
    frames, _ = sample_frames(raws, batch=1, status_every=100)
    data = np.frombuffer(b"".join(frames), np.uint8).copy()
    rng = np.random.default_rng(11)
    hit = rng.random(len(data)) < 0.05
    data[hit] ^= rng.integers(1, 256, hit.sum()).astype(np.uint8)
    rec = tmp_path / "noisy.bin"
    rec.write_bytes(data.tobytes())
    db = str(tmp_path / "c.db")
    with open_store(db, create=True) as st:
        w = st.open_session("c", kind="free")
        Logger(S.parse_port(str(rec)), w, LinkTracker()).run()
        d = st.load_session("c")
        stats = st.link_stats("c")
    assert set(d.motes) <= {1, 2, 3}
    assert len(d) > 500                        # a good part survives ...
    for m in d.motes:
        dm = d.for_mote(m)
        assert (dm.seq >= 0).all() and (dm.seq < 1500).all()
        np.testing.assert_array_equal(dm.raw, raws[m][dm.seq])   # ... and all of it is right
        c = stats["motes"][m]
        assert c["lost"] == c["last_seq"] - c["first_seq"] + 1 - len(dm)
    assert stats["line"]["crc_errors"] > 1000


@pytest.mark.parametrize("sig,word", [(signal.SIGTERM, "terminated"), (signal.SIGINT, "interrupted")],
                         ids=["SIGTERM", "Ctrl-C"])
def test_signal_ends_the_session_cleanly(tmp_path, sig, word):
    raws = _raws(2500)
    frames, _ = sample_frames(raws)
    server = StreamServer(frames, pace=3 * RATE / 5 * 4)
    server.start()
    db = str(tmp_path / "t.db")
    proc = subprocess.Popen(_motecal("log", "--port", f"socket://127.0.0.1:{server.port}",
                                     "--db", db, "--session", "t"),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        _wait_rows(db, 300)
        proc.send_signal(sig)
        out, err = proc.communicate(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
        server.stop.set()
    assert proc.returncode == 0, err
    assert word in out and "Traceback" not in err and "KeyboardInterrupt" not in err
    stored = _check_prefix(db, raws, "t")
    with open_store(db) as st:
        s = st.sessions()[0]
        stats = st.link_stats("t")
    assert s["ended"] is not None and s["samples"] == sum(stored.values())
    assert {m: c["samples"] for m, c in stats["motes"].items()} == stored


@pytest.mark.slow
def test_bad_command_lines(tmp_path):
    db = str(tmp_path / "ok.db")
    with open_store(db, create=True) as st:
        st.open_session("taken", kind="free").end()
    junk = tmp_path / "junk.txt"
    junk.write_text("not a database\n" * 100)
    rec = tmp_path / "rec.bin"
    rec.write_bytes(b"")
    env_nomote = {k: v for k, v in os.environ.items() if k != "MOTECOM"}
    cases = [
        (("--db", db, "--session", "x", "--port", "/dev/does-not-exist"), "cannot open port"),
        (("--db", db, "--session", "taken", "--port", str(rec)), "already exists"),
        # --append continues a session: a typo must not start a second one
        (("--db", db, "--session", "takne", "--port", str(rec), "--append"), "does not exist"),
        (("--db", str(tmp_path / "new.db"), "--session", "taken", "--port", str(rec),
          "--append"), "no database"),
        (("--db", "/proc/motecal.db", "--session", "x", "--port", str(rec)), "database"),
        (("--db", str(junk), "--session", "x", "--port", str(rec)), "not a motecal database"),
        (("--db", db, "--session", "x"), "no port"),
        (("--db", db, "--session", "x", "--port", str(rec), "--guided", "static80",
          "--pose-samples", "10"), "at least 50"),
    ]
    procs = [(args, msg, subprocess.Popen(_motecal("log", *args), stdout=subprocess.PIPE,
                                          stderr=subprocess.PIPE, text=True, env=env_nomote,
                                          stdin=subprocess.DEVNULL))
             for args, msg in cases]
    for args, msg, p in procs:
        out, err = p.communicate(timeout=60)
        assert p.returncode == 2, (args, p.returncode, err)
        assert msg in err, (args, err)
        assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, (args, err)
    # nothing was created by the failed runs
    with open_store(db) as st:
        assert [s["name"] for s in st.sessions()] == ["taken"]
    assert sorted(os.listdir(tmp_path)) == ["junk.txt", "ok.db", "rec.bin"]
