"""Put a simulated serial line where a program expects a port: a file, a TCP
socket (pyserial ``socket://HOST:PORT``) or a pseudo-terminal.

Pacing: ``speed=None`` runs as fast as the reader takes the bytes (the
simulation waits while nobody reads); ``speed=X`` keeps simulated time at X
times wall time (``--realtime`` is X = 1), bytes appear when their last bit
would have left the UART, and bytes produced while no client is connected (or
that the client does not take) are lost, as on a real line, and counted in
``world.stats["line"]["unread_bytes"]``.  Bytes a client writes reach the
BaseStation's UART at the simulated time they arrive.

TCP: one client at a time; a new connection replaces the old one.  The
simulated motes boot when the first client connects.  PTY: the path printed
is the slave side, configured raw at a sentinel speed of 50 baud; the motes
boot when a client configures the port (any termios change, which pyserial
and every serial program make on open), so what pyserial's open flushes is
nothing.
"""
from __future__ import annotations

import errno
import math
import os
import select
import socket
import threading
import time
import termios
import tty

from ..errors import UserError

AFAP_CHUNK = 0.05            # simulated seconds per step when not paced
AFAP_HIGH_WATER = 1 << 16    # do not run ahead of a slow reader by more than this
PACED_BACKLOG = 1 << 20      # paced bytes kept for a client that does not read
IDLE_WAIT = 0.05
PACED_TICK = 0.005
TCP_GRACE = 0.05             # s after a client appears before the motes boot: pyserial's
                             # open discards what arrives while it opens


class Pump:
    """Advances a world in simulated time, paced or not."""

    def __init__(self, world, speed: float | None = None):
        if speed is not None and not speed > 0:
            raise UserError("--speed must be positive")
        self.world = world
        self.speed = speed
        self.started = False
        self._wall0 = 0.0
        self._sim0 = 0.0

    def start(self, delay: float = 0.0) -> None:
        """Boot the motes (``delay`` seconds of wall time from now)."""
        if not self.started:
            self.started = True
            self._wall0 = time.monotonic() + delay
            self._sim0 = self.world.now

    def idle(self) -> bool:
        """Nothing scheduled (only meaningful when not paced)."""
        w = self.world
        return w.loop.pending == 0 and math.isinf(w.next_output_time())

    def produce(self, can_take: bool = True) -> bytes:
        """Advance the world to where it should be now; its new serial bytes."""
        if not self.started or time.monotonic() < self._wall0:
            return b""
        w = self.world
        if self.speed:
            target = self._sim0 + (time.monotonic() - self._wall0) * self.speed
            return w.run_until(target) if target > w.now else b""
        if not can_take or self.idle():
            return b""
        return w.run_until(w.now + AFAP_CHUNK)

    def wait(self, can_take: bool) -> float:
        """How long the caller may block in select before the next step."""
        if not self.started:
            return IDLE_WAIT
        early = self._wall0 - time.monotonic()
        if early > 0:
            return min(IDLE_WAIT, early)
        if self.speed:
            return PACED_TICK
        return 0.0 if (can_take and not self.idle()) else IDLE_WAIT


def write_file(world, fh, speed: float | None = None, until_done: bool = True) -> int:
    """Write the whole serial stream of ``world`` to a binary file object."""
    pump = Pump(world, speed)
    pump.start()
    n = 0
    while not world.done:
        data = pump.produce()
        if data:
            fh.write(data)
            n += len(data)
            if speed:
                fh.flush()
        if speed:
            time.sleep(PACED_TICK)
    return n


class _Endpoint:
    """Shared loop: one readable/writable fd with an outgoing buffer."""

    def __init__(self, world, speed):
        self.world = world
        self.pump = Pump(world, speed)
        self._out = bytearray()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.error: BaseException | None = None

    # subclasses: _read_fds(), _on_readable(fd), _fd_out(), _send(bytes) -> int, _connected()
    def _lose(self, n: int) -> None:
        if n:
            self.world.note_unread(n)

    def _drop_out(self) -> None:
        self._lose(len(self._out))
        self._out.clear()

    def step(self) -> None:
        out_fd = self._fd_out() if self._out else None
        rfds = self._read_fds()
        timeout = self.pump.wait(self._connected() and len(self._out) < AFAP_HIGH_WATER)
        try:
            r, w, _ = select.select(rfds, [out_fd] if out_fd is not None else [], [], timeout)
        except (OSError, ValueError):
            r, w = [], []
        for fd in r:
            self._on_readable(fd)
        connected = self._connected()
        paced = self.pump.speed is not None
        data = self.pump.produce(can_take=connected and len(self._out) < AFAP_HIGH_WATER)
        if data:
            if not connected:
                self._lose(len(data))
            elif paced and len(self._out) > PACED_BACKLOG:
                self._lose(len(data))
            else:
                self._out += data
        if self._out and self._connected():
            try:
                n = self._send(bytes(self._out))
            except (BlockingIOError, InterruptedError):
                n = 0
            except OSError:
                self._disconnect()
                n = 0
            if n:
                del self._out[:n]

    def serve_forever(self) -> None:
        try:
            while not self._stop.is_set():
                self.step()
        except BaseException as e:      # surfaced by stop() / the CLI
            self.error = e
            raise
        finally:
            self._close()

    def start(self) -> "_Endpoint":
        self._thread = threading.Thread(target=self.serve_forever, daemon=True,
                                        name=type(self).__name__)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=5)

    def _disconnect(self) -> None:
        self._drop_out()

    def _close(self) -> None:
        pass

    def close(self) -> None:
        """Release the socket / pseudo-terminal (after stop(), or when stepping by hand)."""
        self._close()


class TcpLine(_Endpoint):
    """The serial line as a TCP server (pyserial ``socket://host:port``)."""

    def __init__(self, world, host: str = "127.0.0.1", port: int = 0,
                 speed: float | None = None):
        super().__init__(world, speed)
        try:
            self._lsock = socket.create_server((host, port))
        except OSError as e:
            raise UserError(f"cannot listen on {host}:{port}: "
                            f"{e.strerror or e}") from None
        self._lsock.setblocking(False)
        self.host = host
        self.port = self._lsock.getsockname()[1]
        self._client: socket.socket | None = None
        self.connections = 0

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"socket://{host}:{self.port}"

    def _read_fds(self):
        return [self._lsock] + ([self._client] if self._client is not None else [])

    def _fd_out(self):
        return self._client

    def _connected(self) -> bool:
        return self._client is not None

    def _on_readable(self, fd) -> None:
        if fd is self._lsock:
            try:
                conn, _ = self._lsock.accept()
            except (BlockingIOError, InterruptedError):
                return
            if self._client is not None:
                self._disconnect()
            conn.setblocking(False)
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self._client = conn
            self.connections += 1
            self.pump.start(TCP_GRACE)
        elif fd is self._client:
            try:
                data = self._client.recv(65536)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                data = b""
            if data:
                self.world.write(data)
            else:
                self._disconnect()

    def _send(self, data: bytes) -> int:
        return self._client.send(data)

    def _disconnect(self) -> None:
        super()._disconnect()
        if self._client is not None:
            try:
                self._client.close()
            except OSError:
                pass
            self._client = None

    def _close(self) -> None:
        self._disconnect()
        try:
            self._lsock.close()
        except OSError:
            pass


class PtyLine(_Endpoint):
    """The serial line as a pseudo-terminal; ``path`` is the port to open."""

    def __init__(self, world, speed: float | None = None):
        super().__init__(world, speed)
        try:
            self._master, self._slave = os.openpty()
        except OSError as e:
            raise UserError(f"cannot create a pseudo-terminal: {e.strerror or e}") from None
        tty.setraw(self._slave)
        attr = termios.tcgetattr(self._slave)
        attr[4] = attr[5] = termios.B50            # sentinel: no client has set it up
        termios.tcsetattr(self._slave, termios.TCSANOW, attr)
        self._attr0 = termios.tcgetattr(self._slave)
        os.set_blocking(self._master, False)
        self.path = os.ttyname(self._slave)

    def step(self) -> None:
        if not self.pump.started:
            try:
                changed = termios.tcgetattr(self._slave) != self._attr0
            except termios.error:
                changed = False
            if changed:
                self.pump.start(TCP_GRACE)
        super().step()

    def _read_fds(self):
        return [self._master]

    def _fd_out(self):
        return self._master

    def _connected(self) -> bool:
        return True

    def _on_readable(self, fd) -> None:
        try:
            data = os.read(self._master, 65536)
        except (BlockingIOError, InterruptedError):
            return
        except OSError as e:
            if e.errno == errno.EIO:
                return
            raise
        if data:
            self.world.write(data)

    def _send(self, data: bytes) -> int:
        try:
            return os.write(self._master, data[:4096])
        except OSError as e:
            if e.errno in (errno.EAGAIN, errno.EIO):
                return 0
            raise

    def _close(self) -> None:
        fds, self._master, self._slave = (self._master, self._slave), -1, -1
        for fd in fds:
            if fd >= 0:
                try:
                    os.close(fd)
                except OSError:
                    pass


def serve_in_thread(world, host: str = "127.0.0.1", port: int = 0,
                    speed: float | None = None):
    """Serve ``world`` over TCP from a daemon thread: ``(server, port)``.

    ``server.stop()`` ends it; ``server.url`` is the pyserial URL.
    """
    server = TcpLine(world, host, port, speed)
    server.start()
    return server, server.port


def pty_in_thread(world, speed: float | None = None):
    """Serve ``world`` on a pseudo-terminal from a daemon thread: ``(line, path)``."""
    line = PtyLine(world, speed)
    line.start()
    return line, line.path
