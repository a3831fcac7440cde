"""The browser view (``motecal log --view``), over HTTP, during simulated
logging runs: the page and its data and nothing else, the state document
(JSON and Server-Sent Events) against what the logger stored, a browser that
leaves and comes back, one that stops reading, a port already taken; and the
stored session's document (the report's view.html).
"""
import argparse
import http.client
import json
import socket
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from motecal.sessions.store import open_store
from motecal.sim.serve import serve_in_thread
from motecal.sim.world import World
from motecal.view import static_page
from motecal.view.server import parse_address
from motecal.view.state import session_state, sweep_numbers


# ------------------------------------------------------------------ helpers
class LogRun:
    """``motecal log ... --view 127.0.0.1:0`` against a simulator in this process."""

    def __init__(self, tmp_path, *, kind="static80", motes=2, seed=3, speed=None, extra=()):
        self.world = World(motes=motes, session=kind, seed=seed)
        self.server, port = serve_in_thread(self.world, speed=speed)
        self.db = str(tmp_path / f"{kind}.db")
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "motecal", "log", "--port", f"socket://127.0.0.1:{port}",
             "--db", self.db, "--session", "s", "--guided", kind, "--yes",
             "--view", "127.0.0.1:0", *extra],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, stdin=subprocess.DEVNULL,
            text=True)
        first = self.proc.stdout.readline()
        assert first.startswith("view: http://127.0.0.1:"), (first, self.proc.stderr.read())
        self.url = first.split()[1]
        self.port = int(self.url.rsplit(":", 1)[1].strip("/"))
        self.out = []
        self._reader = threading.Thread(target=lambda: self.out.extend(self.proc.stdout),
                                        daemon=True)
        self._reader.start()

    def get(self, path, method="GET", headers=None):
        c = http.client.HTTPConnection("127.0.0.1", self.port, timeout=10)
        c.request(method, path, headers=headers or {})
        r = c.getresponse()
        body = r.read()
        c.close()
        return r.status, r.getheader("Content-Type"), body

    def state(self):
        code, ctype, body = self.get("/state.json")
        assert code == 200 and ctype == "application/json"
        return json.loads(body)

    def wait(self, timeout=120):
        rc = self.proc.wait(timeout=timeout)
        self._reader.join(5)
        return rc, self.proc.stderr.read()

    def close(self):
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()
        self.server.stop()
        self.server.close()


def sse_events(port, n, timeout=20, out=None):
    """The first n ``state`` events of /events (a fresh connection), appended
    to ``out`` as they come."""
    s = socket.create_connection(("127.0.0.1", port), timeout=timeout)
    s.sendall(b"GET /events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
    buf, out = b"", ([] if out is None else out)
    end = time.monotonic() + timeout
    while len(out) < n and time.monotonic() < end:
        chunk = s.recv(65536)
        if not chunk:
            break
        buf += chunk
        while b"\n\n" in buf and len(out) < n:
            block, buf = buf.split(b"\n\n", 1)
            lines = block.split(b"\n")
            if b"event: state" in lines:
                data = b"".join(x[6:] for x in lines if x.startswith(b"data: "))
                out.append(json.loads(data))
    s.close()
    return out


@pytest.fixture
def run(tmp_path):
    runs = []

    def start(**kw):
        r = LogRun(tmp_path, **kw)
        runs.append(r)
        return r
    yield start
    for r in runs:
        r.close()


# ------------------------------------------------------------------ addresses
def test_view_address():
    assert parse_address("8080") == ("127.0.0.1", 8080)
    assert parse_address("0.0.0.0:0") == ("0.0.0.0", 0)
    assert parse_address("[::1]:9000") == ("::1", 9000)
    for bad in ("", "x", "host:", "1:99999", "127.0.0.1:-1"):
        with pytest.raises(argparse.ArgumentTypeError):
            parse_address(bad)


# ------------------------------------------------------------------ a static80 run
@pytest.mark.slow
def test_static80_page_state_and_events_follow_the_logger(run):
    r = run(kind="static80", motes=1, speed=30)
    # the page, its script and style: served by motecal, nothing from elsewhere
    code, ctype, page = r.get("/")
    assert code == 200 and ctype.startswith("text/html")
    assert b'src="view.js"' in page and b"http" not in page.replace(b"http-equiv", b"")
    code, ctype, js = r.get("/view.js")
    assert code == 200 and ctype.startswith("text/javascript") and b"EventSource" in js
    assert r.get("/view.css")[0] == 200
    # poses advance, coverage rises, in the JSON and in the event stream
    seen = []
    end = time.monotonic() + 60
    while time.monotonic() < end:
        doc = r.state()
        st = [m["static"] for m in doc["motes"] if m["static"]]
        if st:
            seen.append((st[0]["pose"], st[0]["coverage"], len(st[0]["accepted"])))
        if seen and seen[-1][2] >= 6:
            break
        time.sleep(0.2)
    assert seen[-1][2] >= 6 and seen[-1][0] > seen[0][0] and seen[-1][1] > seen[0][1], seen
    doc = r.state()
    m1 = doc["motes"][0]
    assert doc["flow"] == "static80" and doc["connected"] and not doc["ended"]
    assert [m["id"] for m in doc["motes"]] == [1]
    st = m1["static"]
    assert len(st["targets"]) == 80 and st["poses"] == 80 and st["samples"] == 200
    assert np.allclose(np.linalg.norm(st["accepted"], axis=1), 1.0, atol=1e-3)
    assert len(st["hits"]) == 20 and abs(np.mean(st["hits"]) - st["coverage"]) < 1e-9
    assert m1["live"] is not None and len(m1["live"]["acc"]) == 3
    assert m1["link"]["samples"] > 0 and m1["link"]["rate"] > 0 and m1["state"] == "receiving"
    assert any(e["kind"] == "accepted" for e in doc["events"])
    # a browser that comes: its first event is the full state; it leaves, comes back
    a = sse_events(r.port, 2)
    assert len(a) == 2 and a[1]["version"] > a[0]["version"]
    assert len(a[0]["motes"]) == 1 and len(a[0]["motes"][0]["static"]["accepted"]) >= 6
    b = sse_events(r.port, 1)
    assert b[0]["version"] >= a[1]["version"]
    assert len(b[0]["motes"][0]["static"]["accepted"]) >= len(a[1]["motes"][0]["static"]["accepted"])
    rc, err = r.wait(timeout=120)
    assert rc == 0, err
    assert any("guided flow done" in line for line in r.out)


# ------------------------------------------------------------------ a sweep
@pytest.mark.slow
def test_rotation_sweep_points_fit_and_coverage(run):
    r = run(kind="rotation", motes=1, seed=5, speed=4)
    sw = None
    end = time.monotonic() + 60
    while time.monotonic() < end:
        m = r.state()["motes"]
        sw = m[0]["sweep"] if m else None
        if sw and sw["count"] >= 600:
            break
        time.sleep(0.2)
    assert sw is not None and sw["count"] >= 600
    pts = np.array(sw["points"])
    assert 0 < len(pts) <= 1500 and pts.shape[1] == 3
    assert len(sw["hits"]) == 100 and abs(np.mean(sw["hits"]) - sw["coverage"]) < 1e-9
    # the fit quality is about the centre the guide fitted: |m - c| spreads little
    r_ = np.linalg.norm(pts - sw["centre"], axis=1)
    assert abs(r_.mean() - sw["radius"]) < 0.05 * sw["radius"]
    assert sw["fit_error"] is not None and 0 <= sw["fit_error"] < 30
    rc, err = r.wait()
    assert rc == 0, err


def test_sweep_numbers_planted_sphere():
    rng = np.random.default_rng(0)
    d = rng.normal(size=(4000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    c = np.array([120.0, -40.0, 300.0])
    pts = c + 500.0 * d * (1 + 0.01 * rng.normal(size=(4000, 1)))
    from motecal.maths.sphere import coverage_counts
    hits = coverage_counts(pts - c)
    sw = sweep_numbers(pts, c, hits, 10, 10, max_points=1000)
    assert len(sw["points"]) <= 1000 and sw["count"] == 4000
    assert abs(sw["radius"] - 500.0) < 2.0 and 0.5 < sw["fit_error"] < 1.5
    assert sw["coverage"] == 1.0


# ------------------------------------------------------------------ what it serves, and to whom
def test_serves_only_its_page_and_data(run):
    r = run(kind="static80", motes=1, speed=5)
    for path in ("/etc/passwd", "/../../etc/passwd", "/assets/", "/assets/view.js",
                 "/view.js/..", "/%2e%2e/%2e%2e/etc/passwd", "/state.json/x", "/static/",
                 "//etc/passwd", "/index.html/../view.py", "/server.py"):
        code, _, body = r.get(path)
        assert code == 404, path
        assert b"Directory listing" not in body and b"<li>" not in body
    s = socket.create_connection(("127.0.0.1", r.port), timeout=5)     # raw, not normalised
    s.sendall(b"GET ../../../../etc/passwd HTTP/1.0\r\n\r\n")
    reply = s.recv(4096)
    s.close()
    assert b"root:" not in reply and not reply.startswith(b"HTTP/1.0 200")
    assert r.get("/state.json", method="POST")[0] in (405, 501)
    # a page asked for under another host name (DNS rebinding) is refused
    assert r.get("/state.json", headers={"Host": "evil.example:80"})[0] == 403
    assert r.get("/state.json", headers={"Host": f"localhost:{r.port}"})[0] == 200
    # bound to loopback only
    with socket.socket() as probe:
        probe.settimeout(1)
        other = [a for a in _own_addresses() if not a.startswith("127.")]
        for a in other:
            assert probe.connect_ex((a, r.port)) != 0, a
    r.close()


def test_port_lost_shows_while_the_logger_reconnects(run):
    """The line goes away mid-session: the view keeps serving and says so
    (connected false, one disconnect), and the logger still ends cleanly."""
    r = run(kind="static80", motes=1, speed=5)
    end = time.monotonic() + 30
    while time.monotonic() < end and not (r.state()["motes"] or [{}])[0].get("static"):
        time.sleep(0.1)
    r.server.stop()
    r.server.close()
    end = time.monotonic() + 30
    doc = r.state()
    while time.monotonic() < end and doc["connected"]:
        time.sleep(0.1)
        doc = r.state()
    assert not doc["connected"] and doc["line"]["disconnects"] == 1
    assert any(e["kind"] == "line" and "port lost" in e["text"] for e in doc["events"])
    r.proc.terminate()
    rc, err = r.wait(timeout=30)
    assert rc == 0, err


def _own_addresses():
    try:
        out = subprocess.run(["hostname", "-I"], capture_output=True, text=True).stdout
    except OSError:
        return []
    return [a for a in out.split() if "." in a]


def test_port_taken_one_line_exit_2_nothing_logged(tmp_path):
    world = World(motes=1, session="static80", seed=1)
    server, port = serve_in_thread(world)
    busy = socket.socket()
    busy.bind(("127.0.0.1", 0))
    busy.listen(1)
    db = tmp_path / "x.db"
    try:
        p = subprocess.run([sys.executable, "-m", "motecal", "log", "--port",
                            f"socket://127.0.0.1:{port}", "--db", str(db), "--session", "s",
                            "--view", f"127.0.0.1:{busy.getsockname()[1]}", "--duration", "5"],
                           capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL)
    finally:
        busy.close()
        server.stop()
        server.close()
    assert p.returncode == 2
    assert len(p.stderr.strip().splitlines()) == 1 and "Traceback" not in p.stderr
    assert "--view" in p.stderr and "cannot listen" in p.stderr
    assert not db.exists() and world.sent[1].seq.size == 0     # logging never started
    bad = subprocess.run([sys.executable, "-m", "motecal", "log", "--port", "loop://", "--db",
                          str(db), "--session", "s", "--view", "99999"],
                         capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and "--view" in bad.stderr and not db.exists()


@pytest.mark.slow
def test_stuck_viewers_cost_nothing_and_the_last_state_is_the_database(run):
    """Read as fast as it goes, with one viewer reading and nine that connect
    and never read (more than the stream limit): every sample reaches the
    database, as without a view, and the reading viewer's last event is the
    ended session with the counters the database holds."""
    r = run(kind="static80", motes=3, seed=6)
    events = []
    t = threading.Thread(target=sse_events, args=(r.port, 10_000, 90, events))
    t.start()
    end = time.monotonic() + 30
    while not events and time.monotonic() < end:      # the reader's stream is one of the 8
        time.sleep(0.01)
    stuck = []
    for _ in range(9):
        s = socket.socket()
        s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        s.connect(("127.0.0.1", r.port))
        s.sendall(b"GET /events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
        stuck.append(s)
    rc, err = r.wait()
    t.join(30)
    for s in stuck:
        s.close()
    assert rc == 0, err
    with open_store(r.db) as st:
        data = st.load_session("s")
        stats = st.link_stats("s")
    for m in (1, 2, 3):
        sent = r.world.sent[m]
        np.testing.assert_array_equal(data.for_mote(m).seq, sent.seq)
        # lost = what never reached the serial line (the simulated radio), nothing more
        assert stats["motes"][m]["lost"] == sent.seq[-1] - sent.seq[0] + 1 - len(sent.seq)
        assert data.for_mote(m).poses() == list(range(1, 81))
    last = events[-1]
    assert last["ended"] and last["stop_reason"] == "guided flow done"
    for m in last["motes"]:
        c = stats["motes"][m["id"]]
        for k in ("samples", "lost", "duplicates", "reordered", "frames"):
            assert m["link"][k] == c[k], (m["id"], k)
        assert -40 <= m["link"]["temp_c"] <= 85          # the mote's temperature message
        assert m["static"]["pose"] == 80 and len(m["static"]["accepted"]) == 80
    for k in ("frames", "crc_errors", "garbage_bytes", "disconnects"):
        assert last["line"][k] == stats["line"][k]


# ------------------------------------------------------------------ the stored session
def test_session_state_and_static_page(tmp_path):
    from motecal.sim import simulate_session
    d = simulate_session("static80", motes=(1,), seed=2)[1]
    rot = simulate_session("rotation", motes=(1,), seed=2)[1]
    from motecal.sessions.session import SessionData
    both = SessionData(name="two", raw=np.vstack([d.raw, rot.raw]),
                       mote=np.concatenate([d.mote, rot.mote]),
                       seq=np.concatenate([d.seq, rot.seq + d.seq.max() + 1]),
                       t=np.concatenate([d.t, rot.t + d.t[-1] + 1]),
                       label=np.concatenate([d.label, rot.label]),
                       flags=np.zeros(len(d) + len(rot)), kind="static80")
    doc = session_state(both)
    m = doc["motes"][0]
    assert doc["mode"] == "static" and doc["ended"]
    assert len(m["static"]["accepted"]) == len(d.poses()) == 80
    # each pose's direction is the mean accelerometer direction of its rows
    k = 7
    acc = both.raw[both.label == k, :3].mean(axis=0)
    assert np.allclose(m["static"]["accepted"][k - 1], acc / np.linalg.norm(acc), atol=1e-4)
    assert m["sweep"]["count"] == int((both.label == -1).sum()) > 0
    assert m["sweep"]["coverage"] > 0.5
    html = static_page(doc)
    assert "window.MOTECAL_STATE = {" in html and '<script src=' not in html
    assert 'href="view.css"' not in html and "http://" not in html and "https://" not in html
    # the embedded JSON reads back
    blob = html.split("window.MOTECAL_STATE = ", 1)[1].split(";</script>", 1)[0]
    assert json.loads(blob.replace("<\\/", "</"))["motes"][0]["id"] == 1


# ------------------------------------------------------------------ the snapshot, without a server
class _FakeLogger:
    """What LiveView reads of a Logger: tracker, writer name, guide, ..."""

    def __init__(self, guide):
        from motecal.capture.link import LinkTracker
        self.tracker = LinkTracker()
        self.guide = guide
        self.writer = type("W", (), {"name": "unit"})()
        self.spec = "loop://"
        self.started = time.monotonic()
        self.elapsed = 0.0
        self.connected = True
        self.stop_reason = ""


def test_live_view_reads_the_guide_knock_and_too_close():
    """A knock during pose 1's capture: the document carries the discard (count,
    event with its pose) exactly as the guide decided it; poses and cells are
    the guide's own."""
    from motecal.capture.guide import GuidedFlow
    from motecal.capture.link import Rows
    from motecal.view.state import LiveView
    from test_logger_streams import pose_trajectory
    raw, truth = pose_trajectory(n_poses=3, seed=4, still=400)
    raw = raw.copy()
    bump = np.flatnonzero(truth == 1)[0] + 120
    raw[bump:bump + 6, :3] += np.array([40, -30, 25], np.int16)
    flow = GuidedFlow("static80", options=dict(poses=3))
    lg = _FakeLogger(flow)
    view = LiveView(every=0.0)
    view.start(lg)
    versions = []
    for i in range(0, len(raw), 50):
        seq = np.arange(i, min(i + 50, len(raw)))
        for ev in flow.update(np.ones(len(seq), np.int32), seq, raw[seq]):
            if ev.kind != "label":
                view.guide_event(ev)
        view.rows(Rows(np.ones(len(seq), np.int32), seq, np.zeros(len(seq), np.uint8), raw[seq]))
        view._rows_next = 0.0
        view.tick(lg)
        versions.append(view.version)
    view.stop(lg)
    doc = json.loads(view.document()[1])
    cap = flow.captures[1]
    st = doc["motes"][0]["static"]
    assert doc["ended"] and versions == sorted(versions) and len(set(versions)) == len(versions)
    assert st["discards"] == cap.discards == 1
    assert len(st["accepted"]) == len(cap.accepted) == 3 and st["done"]
    np.testing.assert_allclose(st["accepted"], [p.direction for p in cap.accepted], atol=1e-4)
    assert st["hits"] == (cap.coverage.hits > 0).astype(int).tolist()
    disc = [e for e in doc["events"] if e["kind"] == "discarded"]
    assert len(disc) == 1 and disc[0]["pose"] == 1 and "moved during pose 1" in disc[0]["text"]
    assert doc["motes"][0]["live"]["acc"] == raw[-1, :3].astype(float).tolist()
