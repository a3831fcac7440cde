"""``log --view``: clients that drop their connection print nothing on the
logger's terminal, and half-open connections do not pile up (issue 28,
item 7).  Before, 300 half-open connections printed 6,600 lines of
tracebacks (socketserver's ``handle_error``) and the handlers had no
timeout.  Loopback only.
"""
import http.client
import socket
import struct
import time

import pytest

from motecal.view import server as V
from motecal.view.state import LiveView


@pytest.fixture
def srv(monkeypatch):
    monkeypatch.setattr(V, "REQUEST_TIMEOUT_S", 0.5)
    s = V.open_server(("127.0.0.1", 0), LiveView(every=0.0))
    yield s
    s.close(grace=0.0)


def _get(port, path="/state.json", timeout=5.0):
    c = http.client.HTTPConnection("127.0.0.1", port, timeout=timeout)
    c.request("GET", path)
    r = c.getresponse()
    body = r.read()
    c.close()
    return r.status, body


def _reset(sock):
    """Close with RST (SO_LINGER 0): the server sees ConnectionResetError."""
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
    sock.close()


def test_300_half_open_and_dropped_connections_print_nothing(srv, capfd):
    port = srv.server_address[1]
    held = []
    for i in range(300):
        s = socket.create_connection(("127.0.0.1", port), timeout=5)
        kind = i % 5
        if kind == 0:
            held.append(s)                                    # connects, says nothing
        elif kind == 1:
            s.sendall(b"GET /state.json HT")                  # half a request line, then RST
            _reset(s)
        elif kind == 2:
            s.sendall(b"GET /events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
            _reset(s)                                         # a stream dropped at once
        elif kind == 3:
            s.sendall(b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n")   # headers never finished
            held.append(s)
        else:
            s.sendall(b"GET /view.js HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
            _reset(s)                                         # gone before the reply
    # the view still answers while they are around
    assert _get(port)[0] == 200
    # the handlers time out: every held connection is closed by the server
    deadline = time.monotonic() + 10
    for s in held:
        s.settimeout(max(0.1, deadline - time.monotonic()))
        try:
            assert s.recv(65536) is not None
            while s.recv(65536):
                pass
        except (ConnectionResetError, socket.timeout):
            pass
        s.close()
    assert _get(port)[0] == 200
    deadline = time.monotonic() + 5                  # the last handlers see their clients go
    while srv.connections and time.monotonic() < deadline:
        time.sleep(0.05)
    assert srv.connections == 0, srv.connections
    out, err = capfd.readouterr()
    assert out == "" and err == "", err[:2000]
    assert srv.dropped > 0


def test_connections_beyond_the_cap_are_turned_away_not_queued(srv, monkeypatch):
    monkeypatch.setattr(V, "MAX_CONNECTIONS", 4)
    port = srv.server_address[1]
    idle = [socket.create_connection(("127.0.0.1", port), timeout=5) for _ in range(4)]
    time.sleep(0.2)
    extra = socket.create_connection(("127.0.0.1", port), timeout=5)
    extra.settimeout(2)
    assert extra.recv(100) == b""                  # closed at once, no thread for it
    extra.close()
    for s in idle:
        s.close()
    time.sleep(0.8)                                # the idle ones' handlers end
    assert _get(port)[0] == 200


class _Flood:
    """A view with a new 200 kB state at every look."""
    ended = False

    def __init__(self):
        self.version = 0

    def document(self):
        self.version += 1
        return self.version, b'{"x": "' + b"y" * 200000 + b'"}'


def test_a_stream_whose_reader_stops_reading_ends(monkeypatch):
    """A browser that stops reading its event stream: the stream's writes
    time out and its slot is freed (MAX_STREAMS is not used up)."""
    monkeypatch.setattr(V, "REQUEST_TIMEOUT_S", 0.5)
    srv = V.open_server(("127.0.0.1", 0), _Flood())
    try:
        s = socket.create_connection(("127.0.0.1", srv.server_address[1]), timeout=5)
        s.sendall(b"GET /events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
        deadline = time.monotonic() + 1
        while srv.streams == 0 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert srv.streams == 1                      # streaming, and never read
        deadline = time.monotonic() + 10
        while srv.streams and time.monotonic() < deadline:
            time.sleep(0.05)
        assert srv.streams == 0
        s.close()
    finally:
        srv.close(grace=0.0)
