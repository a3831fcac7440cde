"""`motecal sim` end to end: file, TCP and pty outputs, bad input, tinyos3 cross-check."""
from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import time
from collections import defaultdict

import numpy as np
import pytest
import serial

from motecal.line import protocol as P

pytestmark = pytest.mark.timeout(120)

MOTECAL = [sys.executable, "-m", "motecal"]


def motecal(*args, **kw):
    return subprocess.run(MOTECAL + list(args), capture_output=True, text=True, timeout=90, **kw)


def tinyos3_packets(data: bytes):
    """Packets as tinyos3's tos.HDLC reads them (protocol byte .. payload)."""
    tos = pytest.importorskip("tinyos3.tos")

    class Src:
        def __init__(self, data):
            self.data, self.i, self.debug, self._ts = data, 0, False, None

        def getByte(self):
            if self.i >= len(self.data):
                raise tos.Timeout()
            self.i += 1
            return self.data[self.i - 1]

        def getTimeout(self):
            return None

        def setTimeout(self, t):
            pass

    hdlc = tos.HDLC(Src(data))
    out = []
    while (pkt := hdlc.read()) is not None:
        out.append(bytes(pkt.data))
    return out


def samples(frames):
    got = defaultdict(list)
    for f in frames:
        am = f.am()
        if am is not None and am.am_type == P.AM_NINEDOF_SAMPLES_MSG:
            got[am.src].append(P.unpack_samples(am.payload))
    return got


def flat(msgs):
    seq = np.concatenate([np.arange(m.seq, m.seq + len(m.records)) for m in msgs])
    return seq, np.concatenate([m.records for m in msgs])


# ---------------------------------------------------------------- --out
@pytest.fixture(scope="module")
def static80(tmp_path_factory):
    d = tmp_path_factory.mktemp("sim")
    out, truth = d / "f.bin", d / "truth.json"
    r = motecal("sim", "--motes", "3", "--session", "static80", "--seed", "1",
                "--out", str(out), "--truth", str(truth))
    assert r.returncode == 0, r.stderr
    return out.read_bytes(), json.loads(truth.read_text()), r.stderr


@pytest.mark.slow
def test_out_decodes_identically_with_tinyos3(static80):
    data, _, _ = static80
    ours = P.decode_stream(data)
    theirs = tinyos3_packets(data)
    assert len(ours) > 20000
    assert theirs == [bytes((f.protocol, f.dispatch)) + f.body for f in ours]
    # nothing but whole frames on the line
    assert b"".join(P.encode_am(f.am()) for f in ours) == data


def test_every_sample_accounted_for_and_equal_to_physics(static80):
    from motecal.sim.model import load_model
    from motecal.sim.trajectory import Trajectory

    data, truth, stderr = static80
    frames = P.decode_stream(data)
    got = samples(frames)
    assert sorted(got) == [1, 2, 3]
    t = truth["truth"]
    duration = t["session"]["duration_s"]
    assert duration > 250                        # the whole static80 session
    model = load_model(None)
    # the truth file is itself a model that reproduces the boards
    tmodel = load_model(_write(truth))
    traj = Trajectory.from_json(t["trajectory"])
    for m in (1, 2, 3):
        seq, rec = flat(got[m])
        assert seq[-1] < 65536
        assert np.array_equal(seq, np.arange(len(seq))), f"mote {m}: gap or duplicate"
        ppm = model.board(m, 1).clock_ppm
        assert t["network"][str(m)]["clock_ppm"] == ppm
        assert abs(len(seq) - duration * 125 * (1 + ppm * 1e-6)) <= 1
        net = t["network"][str(m)]
        times = net["t0_s"] + seq * net["period_s"]
        assert np.array_equal(rec, tmodel.board(m, 1).sampler(traj, 1).read(times))
        assert all(s.flags == 0 for s in got[m])          # raw: no calibration in force
        assert all(len(s.records) == P.NINEDOF_BATCH for s in got[m][:-1])
    kinds = defaultdict(int)
    for f in frames:
        kinds[(f.am().src, f.am().am_type)] += 1
    for m in (1, 2, 3):
        assert abs(kinds[(m, P.AM_NINEDOF_MOTE_STATUS_MSG)] - duration / 2) <= 1
    assert abs(kinds[(0, P.AM_NINEDOF_BS_STATUS_MSG)] - duration / 2) <= 1
    assert "0 lost" in stderr


def _write(d):
    import tempfile
    fd, path = tempfile.mkstemp(suffix=".json")
    with os.fdopen(fd, "w") as fh:
        json.dump(d, fh)
    return path


def test_loss_option_gaps(tmp_path):
    out = tmp_path / "l.bin"
    r = motecal("sim", "--motes", "2", "--session", "idle", "--duration", "10",
                "--loss", "0.1", "--out", str(out))
    assert r.returncode == 0, r.stderr
    got = samples(P.decode_stream(out.read_bytes()))
    for m in (1, 2):
        seq, _ = flat(got[m])
        assert np.all(np.diff(seq) >= 1)
        lost = int(np.sum(np.diff(seq) - 1))
        assert f"{lost} lost" in r.stderr.splitlines()[m]


# ---------------------------------------------------------------- bad input
@pytest.mark.parametrize("args, words", [
    (["--session", "circles"], "session"),
    (["--motes", "-2"], "--motes"),
    (["--motes", "0"], "--motes"),
    (["--loss", "1.5"], "--loss"),
    (["--loss", "-0.1"], "--loss"),
    (["--batch", "7"], "--batch"),
    (["--baud", "0"], "baud rate must be a whole number 300..4000000, not 0"),
    (["--baud", "1"], "baud rate must be a whole number 300..4000000, not 1"),
    (["--eeprom", "/nonexistent/ee.json"], "cannot use EEPROM file /nonexistent/ee.json"),
    (["--model", "BADJSON"], "invalid JSON"),
    (["--model", "/no/such/model.json"], "no such file"),
    ([], "choose one output"),
])
def test_bad_input_one_line(tmp_path, args, words):
    bad = tmp_path / "bad.json"
    bad.write_text('{"format": ')
    args = [str(bad) if a == "BADJSON" else a for a in args]
    if args:
        args += ["--out", str(tmp_path / "x.bin")]
    r = motecal("sim", *args)
    assert r.returncode != 0
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    assert words in lines[0] and "Traceback" not in r.stderr


def test_port_in_use():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    s.listen(1)
    port = s.getsockname()[1]
    try:
        r = motecal("sim", "--serve", f"127.0.0.1:{port}", "--duration", "1")
    finally:
        s.close()
    assert r.returncode != 0
    assert len(r.stderr.strip().splitlines()) == 1 and str(port) in r.stderr
    assert "Traceback" not in r.stderr


# ---------------------------------------------------------------- TCP / pty
def _read_frames(port_obj, want, timeout=20.0):
    dec = P.FrameDecoder()
    frames = []
    t = time.monotonic()
    while time.monotonic() - t < timeout:
        frames += dec.feed(port_obj.read(65536))         # returns after the read timeout
        if want(frames):
            break
    return frames


def _start(args):
    proc = subprocess.Popen(MOTECAL + ["sim"] + args, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    first = proc.stdout.readline().strip()
    if not first:
        proc.kill()
        pytest.fail(proc.stderr.read())
    return proc, first


def test_cli_serve_socket_url_and_acks():
    proc, url = _start(["--serve", "127.0.0.1:0", "--motes", "2", "--session", "idle",
                        "--duration", "30", "--speed", "20"])
    try:
        assert url.startswith("socket://127.0.0.1:")
        ser = serial.serial_for_url(url, timeout=0.05)
        frames = _read_frames(ser, lambda fr: len(samples(fr)) == 2 and len(fr) > 40)
        assert len(samples(frames)) == 2
        ser.write(P.message_frame(P.CAL_QUERY, dest=2, ack_seq=0x42, mote=2, offset=0))
        frames = _read_frames(ser, lambda fr: any(f.protocol == P.PROTO_ACK for f in fr)
                              and any(f.am() and f.am().am_type == P.AM_NINEDOF_CAL_REPORT_MSG
                                      for f in fr))
        acks = [f.seq for f in frames if f.protocol == P.PROTO_ACK]
        assert acks == [0x42]
        rep = [f.am() for f in frames if f.am() and f.am().am_type == P.AM_NINEDOF_CAL_REPORT_MSG]
        assert [r.src for r in rep] == [2]
        ser.close()
    finally:
        proc.terminate()
        proc.wait(10)


def test_cli_pty():
    proc, path = _start(["--pty", "--motes", "1", "--session", "idle", "--duration", "30",
                         "--speed", "20"])
    try:
        assert os.path.exists(path)
        ser = serial.Serial(path, 250000, timeout=0.05)
        frames = _read_frames(ser, lambda fr: len(samples(fr).get(1, [])) >= 10)
        msgs = samples(frames)[1]
        assert len(msgs) >= 10
        seqs = [m.seq for m in msgs]
        assert np.all(np.diff(seqs) == P.NINEDOF_BATCH)
        ser.write(P.message_frame(P.CAL_QUERY, dest=1, ack_seq=9, mote=1, offset=0))
        frames = _read_frames(ser, lambda fr: any(f.protocol == P.PROTO_ACK for f in fr))
        assert [f.seq for f in frames if f.protocol == P.PROTO_ACK] == [9]
        ser.close()
    finally:
        proc.terminate()
        proc.wait(10)


def test_serve_in_thread_fast_equals_file_and_reconnect_loses_counted():
    from motecal.sim.serve import serve_in_thread
    from motecal.sim.world import World

    ref = World(motes=2, session="idle", seed=4, duration=4)
    want = bytearray()
    while not ref.done:
        want += ref.run_until(ref.now + 1)

    w = World(motes=2, session="idle", seed=4, duration=4)
    srv, port = serve_in_thread(w)             # as fast as the client reads
    try:
        ser = serial.serial_for_url(f"socket://127.0.0.1:{port}", timeout=0.05)
        got = bytearray()
        t = time.monotonic()
        while time.monotonic() - t < 20 and len(got) < len(want):
            got += ser.read(65536)
        ser.close()
    finally:
        srv.stop()
    assert bytes(got) == bytes(want)
    assert w.stats["line"]["unread_bytes"] == 0

    # paced at 5x: a client that goes away loses what the line produced meanwhile
    w = World(motes=2, session="idle", seed=4, duration=4)
    srv, port = serve_in_thread(w, speed=5.0)

    def drain(sock, until):
        buf = bytearray()
        while time.monotonic() < until:
            try:
                buf += sock.recv(65536)
            except socket.timeout:
                pass
            # never ahead of the line: 25000 bytes per simulated second
            assert len(buf) <= (time.monotonic() - t0 + 0.05) * 5 * 25000 + 200
        return buf

    try:
        c = socket.create_connection(("127.0.0.1", port))
        c.settimeout(0.01)
        t0 = time.monotonic()
        first = drain(c, t0 + 0.15)
        c.close()
        time.sleep(0.15)
        c = socket.create_connection(("127.0.0.1", port))
        c.settimeout(0.01)
        second = drain(c, t0 + 1.2)
        c.close()
        assert w.done
    finally:
        srv.stop()
    line = w.stats["line"]
    assert line["unread_bytes"] > 0 and len(first) > 0
    assert len(first) + len(second) + line["unread_bytes"] <= line["bytes_out"]
    assert len(first) + len(second) + line["unread_bytes"] > 0.9 * line["bytes_out"]
    assert len(P.decode_stream(bytes(second))) > 10        # resynchronised after the gap


def test_pty_in_thread_waits_for_the_client_and_loses_nothing():
    from motecal.sim.serve import pty_in_thread
    from motecal.sim.world import World

    ref = World(motes=1, session="idle", seed=5, duration=2)
    want = bytearray()
    while not ref.done:
        want += ref.run_until(ref.now + 1)
    w = World(motes=1, session="idle", seed=5, duration=2)
    line, path = pty_in_thread(w)
    try:
        time.sleep(0.2)
        assert w.now == 0.0, "the motes boot only when a client opens the port"
        ser = serial.Serial(path, 250000, timeout=0.05)
        got = bytearray()
        t = time.monotonic()
        while len(got) < len(want) and time.monotonic() - t < 20:
            got += ser.read(65536)
        ser.close()
    finally:
        line.stop()
        line.close()
    assert bytes(got) == bytes(want)
