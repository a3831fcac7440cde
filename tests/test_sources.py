"""Opening ports: MOTECOM syntax, pyserial URLs, SerialForwarder, pty, files;
no byte is lost when the other side closes."""
import os
import socket
import threading
import time
import tty

import numpy as np
import pytest

from motecal.line import protocol as P
from motecal.line import sources as S


def _frame(mote=1, seq=0, n=5, value=0):
    rec = np.full((n, 9), value, np.int16)
    return P.encode_am(P.AMPacket(0xFFFF, mote, 0x22, P.AM_NINEDOF_SAMPLES_MSG,
                                  P.pack_samples(seq, 0, rec)))


def _read_all(src, until, timeout=5.0):
    out = []
    deadline = time.monotonic() + timeout
    while len(out) < until and time.monotonic() < deadline:
        out += src.read()
    return out


def test_parse_port_forms(tmp_path):
    rec = tmp_path / "rec.bin"
    rec.write_bytes(b"")
    cases = {
        "/dev/ttyUSB1": ("serial", "/dev/ttyUSB1", 250000, 0),
        "socket://localhost:9001": ("serial", "socket://localhost:9001", 250000, 0),
        "loop://": ("serial", "loop://", 250000, 0),
        "serial@/dev/ttyUSB1:57600": ("serial", "/dev/ttyUSB1", 57600, 0),
        "serial@/dev/ttyUSB1:iris": ("serial", "/dev/ttyUSB1", 57600, 0),
        "serial@COM3": ("serial", "COM3", 250000, 0),
        "sf@localhost:9002": ("sf", "localhost", 250000, 9002),
        "sf@lab-pc": ("sf", "lab-pc", 250000, 9002),
        "network@10.0.0.5:10002": ("serial", "socket://10.0.0.5:10002", 250000, 0),
        str(rec): ("file", str(rec), 250000, 0),
    }
    for text, (kind, target, baud, port) in cases.items():
        spec = S.parse_port(text)
        assert (spec.kind, spec.target, spec.baud, spec.port) == (kind, target, baud, port), text
        assert str(spec) == text
    assert S.parse_port("/dev/ttyS0", 115200).baud == 115200
    assert S.parse_port("serial@/dev/ttyS0:115200", 115200).baud == 115200
    # no --port: MOTECOM, as TinyOS tools do
    assert S.parse_port(None, env={"MOTECOM": "serial@/dev/ttyUSB0:115200"}).target == "/dev/ttyUSB0"
    bad = {None: "no port", "serial@/dev/x:57600": "says 57600", "sf@host:99999": "bad TCP port",
           "sf@host:http": "bad TCP port", "network@host": "no TCP port", "foo@bar": "unknown port kind",
           "serial@": "no device"}
    for text, msg in bad.items():
        with pytest.raises(S.PortError, match=msg):
            S.parse_port(text, 250000 if text and "57600" in text else None, env={})
    for baud in (-5, 0, 1, 299, 4_000_001):                  # one rule for every baud rate
        with pytest.raises(S.PortError, match="baud rate must be a whole number 300..4000000"):
            S.parse_port("/dev/ttyS0", baud)
    with pytest.raises(S.PortError, match="serial@/dev/ttyS0:1: baud rate must be"):
        S.parse_port("serial@/dev/ttyS0:1")


def test_loop_url_and_send():
    src = S.open_source("loop://", 250000)
    src.send(P.AMPacket(0xFFFF, 3, 0x22, P.AM_NINEDOF_SAMPLES_MSG, P.pack_samples(7, 0, np.ones((2, 9)))))
    frames = _read_all(src, 1)
    src.close()
    assert len(frames) == 1
    s = P.decode_message(frames[0].am())
    assert s.seq == 7 and s.records.tolist() == [[1] * 9] * 2 and frames[0].am().src == 3


def test_missing_device_and_refused_tcp_are_port_errors():
    with pytest.raises(S.PortError, match="cannot open port /dev/does-not-exist"):
        S.open_source("/dev/does-not-exist")
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()                                   # nobody listens there now
    with pytest.raises(S.PortError, match="cannot open port"):
        S.open_source(f"socket://127.0.0.1:{port}")
    with pytest.raises(S.PortError, match="cannot open port"):
        S.open_source(f"sf@127.0.0.1:{port}")


def test_socket_bytes_before_close_are_not_lost():
    """The peer sends and closes at once: every frame arrives, then SourceLost."""
    lsock = socket.create_server(("127.0.0.1", 0))
    port = lsock.getsockname()[1]
    data = b"".join(_frame(1, 5 * i, value=i) for i in range(300))

    def serve():
        conn, _ = lsock.accept()
        conn.sendall(data)
        conn.close()

    th = threading.Thread(target=serve, daemon=True)
    th.start()
    src = S.open_source(f"socket://127.0.0.1:{port}")
    frames = []
    with pytest.raises(S.SourceLost):
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:
            frames += src.read()
    src.close()
    lsock.close()
    assert [P.decode_message(f.am()).seq for f in frames] == [5 * i for i in range(300)]


def test_serialforwarder_protocol():
    lsock = socket.create_server(("127.0.0.1", 0))
    port = lsock.getsockname()[1]
    got = {}

    def sf_packet(frame_bytes):
        body = P.decode_stream(frame_bytes)[0]
        packet = bytes((body.dispatch,)) + body.body
        return bytes((len(packet),)) + packet

    def serve():
        conn, _ = lsock.accept()
        got["hello"] = conn.recv(2)
        conn.sendall(b"U ")
        stream = b"".join(sf_packet(_frame(2, 5 * i)) for i in range(40))
        stream += b"\x05\x00\x01\x02\x03\x04"     # AM packet too short: counted, skipped
        stream += sf_packet(_frame(2, 200))
        for i in range(0, len(stream), 37):       # arbitrary TCP chunking
            conn.sendall(stream[i:i + 37])
            time.sleep(0.001)
        got["sent"] = conn.recv(100)
        conn.close()

    threading.Thread(target=serve, daemon=True).start()
    src = S.open_source(f"sf@127.0.0.1:{port}")
    frames = _read_all(src, 41)
    src.send(P.AMPacket(5, 0, 0x22, P.AM_NINEDOF_CAL_QUERY_MSG, P.CAL_QUERY.pack(mote=5, offset=20)))
    time.sleep(0.2)
    src.close()
    lsock.close()
    assert got["hello"] == b"U "
    assert [P.decode_message(f.am()).seq for f in frames] == [5 * i for i in range(40)] + [200]
    assert src.stats.frames == 41 and src.stats.bad_frames == 1
    # what we sent: length byte, dispatch, AM header, payload
    sent = got["sent"]
    assert sent[0] == len(sent) - 1 and sent[1] == P.DISPATCH_AM
    am = P.parse_am(sent[2:])
    # (the query carries its flags since the stored-set report: 0 when not given)
    assert am.am_type == P.AM_NINEDOF_CAL_QUERY_MSG
    assert P.decode_message(am) == {"mote": 5, "offset": 20, "flags": 0}


def test_not_a_serialforwarder():
    lsock = socket.create_server(("127.0.0.1", 0))
    port = lsock.getsockname()[1]

    def serve():
        conn, _ = lsock.accept()
        conn.sendall(b"HTTP/1.0 200 OK\r\n")
        time.sleep(0.2)
        conn.close()

    threading.Thread(target=serve, daemon=True).start()
    with pytest.raises(S.PortError, match="not a SerialForwarder"):
        S.open_source(f"sf@127.0.0.1:{port}")
    lsock.close()


def test_pty_and_recorded_file(tmp_path):
    master, slave = os.openpty()
    tty.setraw(slave)
    path = os.ttyname(slave)
    os.write(master, b"\x00garbage" + b"".join(_frame(4, 5 * i) for i in range(10)))
    src = S.open_source(path)           # what arrived before the open is kept
    os.write(master, b"".join(_frame(4, 5 * i) for i in range(10, 20)))
    frames = _read_all(src, 20)
    assert [P.decode_message(f.am()).seq for f in frames] == [5 * i for i in range(20)]
    assert src.stats.garbage_bytes == 8
    src.close()
    os.close(master)
    os.close(slave)

    rec = tmp_path / "rec.bin"
    rec.write_bytes(b"".join(_frame(4, 5 * i) for i in range(5000)))
    src = S.open_source(str(rec))
    assert isinstance(src, S.FileSource)
    frames = []
    with pytest.raises(S.SourceEnded):
        while True:
            frames += src.read()
    assert len(frames) == 5000
    with pytest.raises(S.PortError, match="recorded file"):
        src.send(P.AMPacket(1, 0, 0x22, 0x65, b"\0\0\0"))
    src.close()
