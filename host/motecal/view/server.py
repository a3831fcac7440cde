"""The view's HTTP server (``motecal log --view [HOST:]PORT``): one page, its
script and style, and the state (``/state.json`` once, ``/events`` as
Server-Sent Events); everything else is 404.

Standard library only (``http.server.ThreadingHTTPServer``), in daemon
threads: the logging thread never waits for it.  A reconnecting browser gets
the full state in the first event.  Bound where told (loopback by default);
on a loopback address a request naming another host (DNS rebinding) is
refused (403).  At most ``MAX_STREAMS`` event streams at once (503 beyond).

A client that misbehaves costs the logger nothing and prints nothing: each
connection's socket times out after ``REQUEST_TIMEOUT_S`` (a request that
never completes, a reader that stops reading), at most ``MAX_CONNECTIONS``
are served at once (more are closed at once), and a connection dropped,
reset or timed out mid-request ends its handler quietly (``handle_error``;
they are counted in ``ViewServer.dropped``).  Only an error of the server's
own code is reported, as one line, never a traceback.
"""
from __future__ import annotations

import argparse
import ipaddress
import select
import socket
import sys
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources

from ..errors import UserError

DEFAULT_HOST = "127.0.0.1"
MAX_STREAMS = 8
MAX_CONNECTIONS = 32    # connections served at once (streams, page loads, half-open ones)
REQUEST_TIMEOUT_S = 10.0    # a socket with no progress this long is dropped
POLL_S = 0.1            # an event stream looks for a new snapshot this often
KEEPALIVE_S = 10.0      # comment line on an idle stream (finds closed browsers)
LOOPBACK_NAMES = {"localhost", "127.0.0.1", "::1", "[::1]"}


def parse_address(text: str) -> tuple[str, int]:
    """``PORT``, ``HOST:PORT`` or ``[V6]:PORT`` -> (host, port); HOST defaults
    to loopback.  An argparse type: bad text is an ``ArgumentTypeError``."""
    host, sep, port = text.rpartition(":")
    if not sep:
        host = DEFAULT_HOST
    if host.startswith("[") and host.endswith("]"):
        host = host[1:-1]
    if not host or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise argparse.ArgumentTypeError(f"want [HOST:]PORT (port 0..65535), not {text!r}")
    return host, int(port)


def asset(name: str) -> bytes:
    return resources.files(__package__).joinpath("assets", name).read_bytes()


PAGES = {"/": ("index.html", "text/html; charset=utf-8"),
         "/index.html": ("index.html", "text/html; charset=utf-8"),
         "/view.js": ("view.js", "text/javascript; charset=utf-8"),
         "/charts.js": ("charts.js", "text/javascript; charset=utf-8"),
         "/view.css": ("view.css", "text/css; charset=utf-8")}


class _Handler(BaseHTTPRequestHandler):
    server_version = "motecal-view"
    sys_version = ""
    protocol_version = "HTTP/1.1"

    def setup(self):
        self.timeout = REQUEST_TIMEOUT_S      # StreamRequestHandler sets it on the socket
        super().setup()

    def log_message(self, format, *args):        # no request log on the logger's terminal
        pass

    def _send(self, code: int, body: bytes, ctype: str = "text/plain; charset=utf-8"):
        self.send_response(code)
        self.send_header("Content-Type", ctype)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.send_header("X-Content-Type-Options", "nosniff")
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def _host_ok(self) -> bool:
        if not self.server.loopback:
            return True
        host = (self.headers.get("Host") or "").strip().lower()
        name = host.rsplit(":", 1)[0] if not host.endswith("]") else host
        return not host or name in LOOPBACK_NAMES

    def do_HEAD(self):
        self.do_GET()

    def do_GET(self):
        path = self.path.split("?", 1)[0].split("#", 1)[0]
        if not self._host_ok():
            return self._send(403, b"forbidden\n")
        if path in PAGES:
            name, ctype = PAGES[path]
            return self._send(200, self.server.assets[name], ctype)
        if path == "/state.json":
            return self._send(200, self.server.view.document()[1],
                              "application/json")
        if path == "/events":
            return self._stream()
        return self._send(404, b"not found\n")

    def _gone(self) -> bool:
        """The client closed or reset its connection (an event stream's client
        sends nothing after its request, so a readable socket is a closed one)."""
        try:
            ready, _, _ = select.select([self.connection], [], [], 0)
            return bool(ready) and not self.connection.recv(1, socket.MSG_PEEK)
        except (OSError, ValueError):
            return True

    def _stream(self):
        srv = self.server
        with srv.lock:
            if srv.streams >= MAX_STREAMS:
                return self._send(503, b"too many viewers\n")
            srv.streams += 1
        try:
            self.send_response(200)
            self.send_header("Content-Type", "text/event-stream")
            self.send_header("Cache-Control", "no-store")
            self.send_header("Connection", "close")
            self.end_headers()
            self.close_connection = True
            if self.command == "HEAD":
                return
            self.wfile.write(b"retry: 1000\n\n")
            sent, idle = -1, time.monotonic()
            while not srv.closing.is_set():
                version, doc = srv.view.document()
                if version != sent:
                    self.wfile.write(b"event: state\ndata: " + doc + b"\n\n")
                    self.wfile.flush()
                    sent, idle = version, time.monotonic()
                    if srv.view.ended and version == srv.view.version:
                        return              # the session is over: the last state is sent
                elif time.monotonic() - idle >= KEEPALIVE_S:
                    self.wfile.write(b": keepalive\n\n")
                    self.wfile.flush()
                    idle = time.monotonic()
                if self._gone():
                    return                  # the browser closed: free the slot now
                srv.closing.wait(POLL_S)
        except (BrokenPipeError, ConnectionResetError, TimeoutError, OSError):
            return
        finally:
            with srv.lock:
                srv.streams -= 1


# what a client's connection going away looks like: never a fault of the server
DROPPED = (ConnectionError, TimeoutError, OSError)


class ViewServer(ThreadingHTTPServer):
    daemon_threads = True
    allow_reuse_address = False       # a port in use is an error, not shared
    request_queue_size = 128          # a burst of connections is accepted, not left to retry

    def __init__(self, address: tuple[str, int], view):
        self.view = view
        self.assets = {name: asset(name) for name, _ in PAGES.values()}
        self.lock = threading.Lock()
        self.streams = 0
        self.connections = 0
        self.dropped = 0              # connections dropped, reset, timed out or turned away
        self.closing = threading.Event()
        host = address[0]
        try:
            self.loopback = ipaddress.ip_address(host).is_loopback
        except ValueError:
            self.loopback = host.lower() == "localhost"
        if ":" in host:
            self.address_family = socket.AF_INET6
        super().__init__(address, _Handler)

    # -- connections: bounded, and quiet when a client goes away ------------------
    def verify_request(self, request, client_address) -> bool:
        with self.lock:
            if self.connections >= MAX_CONNECTIONS:
                self.dropped += 1
                return False          # closed at once (shutdown_request)
            self.connections += 1
        return True

    def process_request_thread(self, request, client_address):
        try:
            super().process_request_thread(request, client_address)
        finally:
            with self.lock:
                self.connections -= 1

    def process_request(self, request, client_address):
        try:
            super().process_request(request, client_address)
        except BaseException:
            with self.lock:           # no thread started: the slot is free again
                self.connections -= 1
            raise

    def handle_error(self, request, client_address):
        """A client that dropped, reset or timed out: counted, nothing printed
        (socketserver would print a traceback on the logger's terminal).  An
        error of the server's own: one line on stderr."""
        e = sys.exc_info()[1]
        if isinstance(e, DROPPED):
            with self.lock:
                self.dropped += 1
            return
        print(f"motecal: view: a request failed: {type(e).__name__}: "
              f"{' '.join(str(e).split())[:200]}", file=sys.stderr, flush=True)

    @property
    def url(self) -> str:
        host, port = self.server_address[:2]
        return f"http://[{host}]:{port}/" if ":" in host else f"http://{host}:{port}/"

    def start(self) -> threading.Thread:
        t = threading.Thread(target=self.serve_forever, kwargs=dict(poll_interval=0.2),
                             name="motecal-view", daemon=True)
        t.start()
        return t

    def close(self, grace: float = 1.0) -> None:
        """Stop serving; open event streams first get up to ``grace`` seconds
        to send the last state (a stream ends by itself once the session has)."""
        end = time.monotonic() + grace
        while self.streams and self.view.ended and time.monotonic() < end:
            time.sleep(0.02)
        self.closing.set()
        self.shutdown()
        self.server_close()


def open_server(address: tuple[str, int], view) -> ViewServer:
    """Bind (a user error, one line, when the address cannot be had) and serve
    in a daemon thread."""
    try:
        srv = ViewServer(address, view)
    except OSError as e:
        raise UserError(f"--view {address[0]}:{address[1]}: cannot listen there: "
                        f"{e.strerror or e}") from None
    srv.start()
    return srv
