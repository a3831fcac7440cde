"""Opening the line to the BaseStation: serial ports, pyserial URLs, TinyOS
MOTECOM sources and recorded byte streams.

Accepted port specifications (``--port``, else the ``MOTECOM`` variable):

* a device path (``/dev/ttyUSB1``, a pty from ``motecal sim --pty``);
* any pyserial URL: ``socket://host:port``, ``rfc2217://host:port``, ``loop://``;
* TinyOS MOTECOM syntax: ``serial@/dev/ttyUSB1:250000`` (the baud may also be
  a platform name such as ``iris``), ``sf@host:9002`` (SerialForwarder),
  ``network@host:port`` (raw serial bytes over TCP, same as ``socket://``);
* a regular file holding a recorded serial byte stream (``motecal sim --out``);
  it ends at end of file.

Every source turns what it reads into checked ``protocol.Frame`` objects and
counts what it had to skip in ``stats`` (``protocol.DecoderStats``).

A serial device is one program's at a time: it is opened with an exclusive
``flock`` (pyserial's ``exclusive=True``), and a UUCP lock file of a running
process (``/run/lock/LCK..ttyUSB1``, as minicom and RXTX write them) is
honoured; the second opener gets one line (``PortError``, exit 2).  Two
readers of one line would each lose what the other read.  URLs
(``socket://``, ``loop://``), SerialForwarder and files are not locked: a
SerialForwarder is how several programs share one BaseStation.
"""
from __future__ import annotations

import abc
import os
import select
import socket
import stat
import struct
from dataclasses import dataclass

import serial
from serial.urlhandler import protocol_socket

from ..errors import UserError
from . import protocol as P

BAUD_MIN, BAUD_MAX = 300, 4_000_000      # serial rates: a port's, the simulator's line


def baud_problem(value) -> str | None:
    """Why ``value`` is no baud rate (None if it is one): the one rule of
    ``--baud``, ``serial@DEV:BAUD`` and the simulator's line."""
    if isinstance(value, bool) or not isinstance(value, int) \
            or not BAUD_MIN <= value <= BAUD_MAX:
        return f"baud rate must be a whole number {BAUD_MIN}..{BAUD_MAX}, not {value!r}"
    return None


DEFAULT_BAUD = 250000          # the BaseStation's rate in this project
LOCK_DIRS = ("/run/lock", "/var/lock")   # UUCP lock files of other serial programs (read only)
SF_DEFAULT_PORT = 9002
READ_TIMEOUT = 0.05            # seconds a read waits for data
READ_SIZE = 1 << 16

# TinyOS platform names usable as the baud rate in serial@PORT:PLATFORM
PLATFORM_BAUD = {"iris": 57600, "micaz": 57600, "mica2": 57600, "mica2dot": 19200,
                 "telos": 115200, "telosb": 115200, "tmote": 115200, "eyes": 115200,
                 "intelmote2": 115200, "shimmer": 115200}


class PortError(UserError):
    """The port cannot be opened (bad specification, missing device, refused)."""


class SourceLost(Exception):
    """The port went away while reading (unplugged, connection closed)."""


class SourceEnded(Exception):
    """A finite source (a recorded file) has no more data."""


@dataclass(frozen=True)
class PortSpec:
    kind: str            # "serial" (device path or pyserial URL), "sf", "file"
    target: str          # device path, URL, host name or file path
    baud: int
    port: int = 0        # TCP port for "sf"
    text: str = ""       # as the user gave it

    def __str__(self):
        return self.text or self.target


def _parse_baud(text: str, where: str) -> int:
    if text.lower() in PLATFORM_BAUD:
        return PLATFORM_BAUD[text.lower()]
    try:
        baud = int(text)
    except ValueError:
        raise PortError(f"bad baud rate {text!r} in {where}") from None
    problem = baud_problem(baud)
    if problem:
        raise PortError(f"{where}: {problem}")
    return baud


def _host_port(text: str, default: int | None, where: str) -> tuple[str, int]:
    host, sep, port = text.rpartition(":")
    if not sep:
        host, port = text, ""
    if not host:
        raise PortError(f"no host in {where}")
    if not port:
        if default is None:
            raise PortError(f"no TCP port in {where}")
        return host, default
    try:
        n = int(port)
    except ValueError:
        raise PortError(f"bad TCP port {port!r} in {where}") from None
    if not 0 < n < 65536:
        raise PortError(f"bad TCP port {port!r} in {where}")
    return host, n


def parse_port(text: str | None, baud: int | None = None, env=None) -> PortSpec:
    """Turn ``--port`` (or ``MOTECOM`` when it is None) and ``--baud`` into a PortSpec."""
    env = os.environ if env is None else env
    if not text:
        text = env.get("MOTECOM", "")
        if not text:
            raise PortError("no port: give --port (device, pyserial URL, serial@DEV:BAUD, "
                            "sf@HOST:PORT) or set MOTECOM")
    problem = None if baud is None else baud_problem(baud)
    if problem:
        raise PortError(problem)
    spec_baud = None
    if "://" in text:
        kind, target = "serial", text
    elif text.startswith("serial@"):
        dev = text[len("serial@"):]
        head, sep, tail = dev.rpartition(":")
        if sep and head and (tail.isdigit() or tail.lower() in PLATFORM_BAUD):
            dev, spec_baud = head, _parse_baud(tail, text)
        if not dev:
            raise PortError(f"no device in {text}")
        kind, target = "serial", dev
    elif text.startswith("sf@"):
        host, port = _host_port(text[3:], SF_DEFAULT_PORT, text)
        return PortSpec("sf", host, baud or DEFAULT_BAUD, port, text)
    elif text.startswith("network@"):
        host, port = _host_port(text[len("network@"):], None, text)
        kind, target = "serial", f"socket://{host}:{port}"
    elif "@" in text.split("/")[0]:
        raise PortError(f"unknown port kind in {text!r} (serial@, sf@ or network@)")
    else:
        try:
            st = os.stat(text)
        except OSError:
            st = None
        kind = "file" if st is not None and stat.S_ISREG(st.st_mode) else "serial"
        target = text
    if spec_baud is not None and baud is not None and spec_baud != baud:
        raise PortError(f"{text} says {spec_baud} baud but --baud says {baud}")
    return PortSpec(kind, target, spec_baud or baud or DEFAULT_BAUD, 0, text)


# --------------------------------------------------------------------------
# Sources
# --------------------------------------------------------------------------
class Source(abc.ABC):
    """Common part: frames out, skip counters in ``stats``."""

    spec: PortSpec

    def __init__(self, spec: PortSpec):
        self.spec = spec
        self.stats = P.DecoderStats()

    @abc.abstractmethod
    def read(self) -> list[P.Frame]:
        """Checked frames of what arrived (waits up to READ_TIMEOUT); raises
        SourceLost when the port went away, SourceEnded at the end of a file."""

    def read_block(self) -> P.FrameBlock:
        """``read``, the frames as one ``protocol.FrameBlock`` (what the logger
        reads: a source that decodes HDLC itself gives it without a ``Frame``
        per frame)."""
        return P.FrameBlock.from_frames(self.read())

    def flush(self) -> list[P.Frame]:
        """The stream ended (closed, lost, the reader stops): a frame cut off is
        counted in ``cut_off``, not kept (a complete one whose closing flag
        never came is returned)."""
        decoder = getattr(self, "decoder", None)
        return decoder.finish() if decoder is not None else []

    @abc.abstractmethod
    def send(self, am: P.AMPacket, ack_seq: int | None = None) -> None:
        """Put one AM packet on the line (a 0x44 frame with ``ack_seq``)."""

    @abc.abstractmethod
    def close(self) -> None:
        """Release the port (safe to call twice)."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class _SocketSerial(protocol_socket.Serial):
    """pyserial's socket:// port, but ``read`` returns what one recv() gives.

    pyserial's own read keeps reading until ``size`` bytes arrived and, when
    the peer closes in between, raises and drops the bytes it already had;
    the logger must not lose those.
    """

    def read(self, size=1):
        if not self.is_open:
            raise serial.PortNotOpenError()
        ready, _, _ = select.select([self._socket], [], [], self._timeout)
        if not ready:
            return b""
        try:
            buf = self._socket.recv(size)
        except (BlockingIOError, InterruptedError):
            return b""
        except OSError as e:
            raise serial.SerialException(f"read failed: {e}") from None
        if not buf:
            raise serial.SerialException("socket disconnected")
        return buf


def _open_keeping_input(ser) -> None:
    """Open a pyserial port without its flush of what already arrived: those
    bytes are the BaseStation's (or the simulator's) data too."""
    names = ("reset_input_buffer", "_reset_input_buffer")    # public; posix's own
    for name in names:
        setattr(ser, name, lambda: None)
    try:
        ser.open()
    finally:
        for name in names:
            delattr(ser, name)


def lock_file_holder(device: str) -> int | None:
    """The PID of another running process that holds a UUCP lock file
    (``LCK..<name>`` in LOCK_DIRS: ten ASCII digits, or a binary int) for
    ``device``; None when there is none, or only a stale one."""
    name = "LCK.." + os.path.basename(os.path.realpath(device))
    for folder in LOCK_DIRS:
        try:
            with open(os.path.join(folder, name), "rb") as f:
                data = f.read(64)
        except OSError:
            continue
        try:
            pid = struct.unpack("=i", data)[0] if len(data) == 4 else int(data.strip())
        except ValueError:
            continue
        if pid <= 0 or pid == os.getpid():
            continue
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            continue                        # stale: its process is gone
        except PermissionError:
            pass                            # alive, another user's
        return pid
    return None


IN_USE = ("in use by another program (another motecal log or upload?); a serial port "
          "serves one program at a time: stop the other, or share the BaseStation through "
          "a SerialForwarder (sf@HOST:PORT)")


class SerialSource(Source):
    """A serial port: device path or any pyserial URL, TinyOS HDLC framing.
    A device is opened exclusively (module doc)."""

    def __init__(self, spec: PortSpec):
        super().__init__(spec)
        self.decoder = P.FrameDecoder()
        self.stats = self.decoder.stats
        self._socket = spec.target.startswith("socket://")
        device = "://" not in spec.target
        if device:
            holder = lock_file_holder(spec.target)
            if holder is not None:
                raise PortError(f"cannot open port {spec}: {IN_USE} (process {holder} holds "
                                f"its lock file)")
        try:
            if self._socket:
                self.ser = _SocketSerial(None, baudrate=spec.baud, timeout=READ_TIMEOUT)
                self.ser.port = spec.target
            else:
                self.ser = serial.serial_for_url(spec.target, baudrate=spec.baud,
                                                 timeout=READ_TIMEOUT, do_not_open=True,
                                                 **({"exclusive": True} if device else {}))
            _open_keeping_input(self.ser)
        except (serial.SerialException, OSError, ValueError) as e:
            if device and "exclusively lock" in str(e):
                raise PortError(f"cannot open port {spec}: {IN_USE}") from None
            raise PortError(f"cannot open port {spec}: {_reason(e)}") from None

    def read(self) -> list[P.Frame]:
        return self.read_block().frames()

    def read_block(self) -> P.FrameBlock:
        try:
            if self._socket:
                data = self.ser.read(READ_SIZE)
            else:
                n = self.ser.in_waiting
                data = self.ser.read(min(n, READ_SIZE) if n > 0 else 1)
        except (serial.SerialException, OSError) as e:
            raise SourceLost(_reason(e)) from None
        return self.decoder.feed_block(data)

    def send(self, am: P.AMPacket, ack_seq: int | None = None) -> None:
        try:
            self.ser.write(P.encode_am(am, ack_seq=ack_seq))
        except (serial.SerialException, OSError) as e:
            raise SourceLost(_reason(e)) from None

    def close(self) -> None:
        try:
            self.ser.close()
        except (serial.SerialException, OSError):
            pass


class SFSource(Source):
    """TinyOS SerialForwarder client: "U " handshake, then length-prefixed
    packets holding dispatch byte, AM header and payload (no HDLC, no CRC)."""

    HANDSHAKE = b"U "

    def __init__(self, spec: PortSpec):
        super().__init__(spec)
        try:
            self.sock = socket.create_connection((spec.target, spec.port), timeout=5.0)
            self.sock.sendall(self.HANDSHAKE)
            got = b""
            while len(got) < 2:
                chunk = self.sock.recv(2 - len(got))
                if not chunk:
                    break
                got += chunk
        except OSError as e:
            raise PortError(f"cannot open port {spec}: {_reason(e)}") from None
        if got != self.HANDSHAKE:
            self.sock.close()
            raise PortError(f"{spec}: not a SerialForwarder (handshake {got!r})")
        self.sock.settimeout(READ_TIMEOUT)
        self._buf = bytearray()

    def read(self) -> list[P.Frame]:
        try:
            data = self.sock.recv(READ_SIZE)
        except socket.timeout:
            return []
        except OSError as e:
            raise SourceLost(_reason(e)) from None
        if not data:
            raise SourceLost("SerialForwarder closed the connection")
        buf = self._buf
        buf += data
        out = []
        pos = 0
        while pos < len(buf) and pos + 1 + buf[pos] <= len(buf):
            n = buf[pos]
            packet = bytes(buf[pos + 1:pos + 1 + n])
            pos += 1 + n
            if n < 1:
                self.stats.bad_frames += 1
                continue
            frame = P.Frame(P.PROTO_PACKET_NOACK, None, packet[0], packet[1:])
            if frame.dispatch == P.DISPATCH_AM and frame.am() is None:
                self.stats.bad_frames += 1
                continue
            out.append(frame)
        del buf[:pos]
        self.stats.frames += len(out)
        return out

    def flush(self) -> list[P.Frame]:
        if self._buf:
            self.stats.cut_off += 1
            self._buf.clear()
        return []

    def send(self, am: P.AMPacket, ack_seq: int | None = None) -> None:
        body = bytes((P.DISPATCH_AM,)) + P.AM_HEADER.pack(
            am.dest & 0xFFFF, am.src & 0xFFFF, len(am.payload), am.group & 0xFF,
            am.am_type & 0xFF) + am.payload
        try:
            self.sock.sendall(bytes((len(body),)) + body)
        except OSError as e:
            raise SourceLost(_reason(e)) from None

    def close(self) -> None:
        try:
            self.sock.close()
        except OSError:
            pass


class FileSource(Source):
    """A recorded serial byte stream; raises SourceEnded at end of file."""

    def __init__(self, spec: PortSpec):
        super().__init__(spec)
        self.decoder = P.FrameDecoder()
        self.stats = self.decoder.stats
        try:
            self.f = open(spec.target, "rb")
        except OSError as e:
            raise PortError(f"cannot open {spec}: {_reason(e)}") from None

    def read(self) -> list[P.Frame]:
        return self.read_block().frames()

    def read_block(self) -> P.FrameBlock:
        data = self.f.read(READ_SIZE)
        if not data:
            raise SourceEnded(str(self.spec))
        return self.decoder.feed_block(data)

    def send(self, am: P.AMPacket, ack_seq: int | None = None) -> None:
        raise PortError(f"{self.spec} is a recorded file: nothing can be sent to it")

    def close(self) -> None:
        self.f.close()


def _reason(e: BaseException) -> str:
    text = str(e) or type(e).__name__
    return text.splitlines()[0]


def open_source(spec: PortSpec | str | None, baud: int | None = None) -> Source:
    """Open a source from a PortSpec or a port string (None: MOTECOM).

    Raises PortError (a UserError, one line) when it cannot be opened.
    """
    if not isinstance(spec, PortSpec):
        spec = parse_port(spec, baud)
    if spec.kind == "sf":
        return SFSource(spec)
    if spec.kind == "file":
        return FileSource(spec)
    return SerialSource(spec)
