"""TinyOS serial framing and the motecal messages.

The message layouts below are the host's reading of ``tinyos/NineDofMsg.h``;
``tests/test_protocol_header.py`` parses that header and fails if a field
name, order, size or AM type here differs from it.

Framing is TinyOS's (tos/lib/serial): ``0x7E``, escaped bytes, ``0x7E``;
inside a frame ``0x7E``/``0x7D`` travel as ``0x7D, byte ^ 0x20``.  The frame
body is protocol byte, [sequence byte], dispatch byte, 7-byte AM header,
payload, then CRC-16-CCITT (XMODEM, ``binascii.crc_hqx(.., 0)``) over
everything before it, low byte first.
"""
from __future__ import annotations

import binascii
import itertools
import re
import struct
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

# --------------------------------------------------------------------------
# Serial framing constants (tos/lib/serial/Serial.h)
# --------------------------------------------------------------------------
HDLC_FLAG = 0x7E
HDLC_ESC = 0x7D
PROTO_ACK = 0x43            # 'C': ack frame, PC <- mote
PROTO_PACKET_ACK = 0x44     # 'D': packet with sequence byte, ack requested
PROTO_PACKET_NOACK = 0x45   # 'E': packet, no ack (what motes send)
DISPATCH_AM = 0x00
AM_HEADER = struct.Struct(">HHBBB")   # dest, src, length, group, type
AM_BROADCAST = 0xFFFF
MOTE_ID_MIN = 1                        # a sensing mote's id: 0 is the BaseStation,
MOTE_ID_MAX = 0xFFFE                   # 0xFFFF the broadcast address
DEFAULT_GROUP = 0x22
MAX_FRAME = 255                        # unescaped bytes between flags

# --------------------------------------------------------------------------
# Message definitions (mirrors tinyos/NineDofMsg.h; checked by a test)
# --------------------------------------------------------------------------
AM_NINEDOF_SAMPLES_MSG = 0x60
AM_NINEDOF_CAL_FRAG_MSG = 0x61
AM_NINEDOF_CAL_FRAG_ACK_MSG = 0x62
AM_NINEDOF_CAL_COMMIT_MSG = 0x63
AM_NINEDOF_CAL_COMMIT_ACK_MSG = 0x64
AM_NINEDOF_CAL_QUERY_MSG = 0x65
AM_NINEDOF_CAL_REPORT_MSG = 0x66
AM_NINEDOF_MOTE_STATUS_MSG = 0x67
AM_NINEDOF_BS_STATUS_MSG = 0x68
AM_NINEDOF_MOTE_TEMP_MSG = 0x69
AM_NINEDOF_SAMPLES = AM_NINEDOF_SAMPLES_MSG

NINEDOF_BATCH = 5           # default records per sample message (build-time)
NINEDOF_RATE_HZ = 125
NINEDOF_RECORD_SIZE = 18
NINEDOF_FRAG_DATA = 20
NINEDOF_STATUS_PERIOD_MS = 2000
NINEDOF_TEMP_PERIOD_MS = 1000

FLAG_CORRECTED = 0x01
FLAG_VERSION_SHIFT = 4
FLAG_VERSION_MASK = 0xF0

SENSOR_ACCEL, SENSOR_GYRO, SENSOR_MAG = 0, 1, 2
SENSORS = ("accel", "gyro", "mag")

CAL_APPLY = 1
CAL_RESET = 2

CAL_REASONS = {
    0: ("NINEDOF_CAL_OK", "accepted"),
    1: ("NINEDOF_CAL_E_MOTE", "addressed to another mote"),
    2: ("NINEDOF_CAL_E_FRAG", "fragment offset/length outside the set"),
    3: ("NINEDOF_CAL_E_INCOMPLETE", "commit before every byte of the set arrived"),
    4: ("NINEDOF_CAL_E_CRC", "CRC over the staged set does not match"),
    5: ("NINEDOF_CAL_E_VERSION", "version 0, or not the version being staged"),
    6: ("NINEDOF_CAL_E_RANGE", "parameters outside plausibility limits"),
    7: ("NINEDOF_CAL_E_FORMAT", "shift, reserved bytes or length invalid"),
    8: ("NINEDOF_CAL_E_STORAGE", "the mote could not persist the set"),
    9: ("NINEDOF_CAL_E_ACTION", "unknown commit action"),
}
CAL_OK = 0


def cal_reason(code: int) -> str:
    """Human text for an ack status code."""
    name, text = CAL_REASONS.get(code, (f"code {code}", "unknown reason"))
    return f"{text} ({name})"


@dataclass(frozen=True)
class Field:
    """One field of an nx_struct: name, C base type, array length (1 = scalar)."""
    name: str
    ctype: str
    count: int = 1

    @property
    def fmt(self) -> str:
        return {"nx_uint8_t": "B", "nx_int8_t": "b", "nx_uint16_t": "H",
                "nx_int16_t": "h", "nx_uint32_t": "I", "nx_int32_t": "i"}[self.ctype]

    @property
    def size(self) -> int:
        return struct.calcsize(">" + self.fmt) * self.count


@dataclass(frozen=True)
class MessageSpec:
    """Layout of one fixed-size nx_struct message.

    Messages only grow at their end (tinyos/NineDofMsg.h, "How messages
    change").  ``earlier`` holds the sizes the message had before, oldest
    first (the header's ``NINEDOF_<NAME>_SIZE_V<n>``); ``decode`` takes a
    payload of the current size, of an earlier one (an older image's or
    host's: the fields it lacks are absent from the dict) or longer (a newer
    image's: the fields known here, the rest ignored), and nothing else.
    """
    name: str                  # struct name in the header, e.g. ninedof_cal_frag_msg
    am_type: int | None
    fields: tuple[Field, ...]
    earlier: tuple[int, ...] = ()
    _struct: struct.Struct = field(init=False, repr=False, compare=False)
    _layouts: dict = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        def fmt(fields):
            return ">" + "".join(f"{f.count}{f.fmt}" if f.count > 1 and f.fmt != "B"
                                 else (f"{f.count}s" if f.count > 1 else f.fmt)
                                 for f in fields)
        object.__setattr__(self, "_struct", struct.Struct(fmt(self.fields)))
        # size -> (fields, struct) of every layout the message has had
        layouts, at = {}, 0
        for n in range(len(self.fields) + 1):
            if at in self.earlier or n == len(self.fields):
                head = self.fields[:n]
                layouts[at] = (head, struct.Struct(fmt(head)))
            if n < len(self.fields):
                at += self.fields[n].size
        if set(self.earlier) - set(layouts) or list(self.earlier) != sorted(self.earlier):
            raise ValueError(f"{self.name}: earlier sizes {self.earlier} must end at fields, "
                             "oldest first")
        object.__setattr__(self, "_layouts", layouts)

    @property
    def size(self) -> int:
        return self._struct.size

    def fields_since(self, size: int) -> tuple[str, ...]:
        """Names of the fields appended after the layout of ``size`` bytes."""
        return tuple(f.name for f in self.fields[len(self._layouts[size][0]):])

    def pack(self, **values) -> bytes:
        args = []
        for f in self.fields:
            v = values.get(f.name, 0 if f.count == 1 else None)
            if f.count == 1:
                args.append(int(v))
            elif f.fmt == "B":      # byte arrays travel as bytes
                v = bytes(v or b"")
                args.append(v.ljust(f.count, b"\0"))
            else:
                v = list(v) if v is not None else [0] * f.count
                if len(v) != f.count:
                    raise ValueError(f"{self.name}.{f.name} needs {f.count} values")
                args.extend(int(x) for x in v)
        return self._struct.pack(*args)

    def decode(self, payload: bytes) -> dict | None:
        """The fields of a payload of this message's current size, of one of
        its ``earlier`` sizes (the fields appended since are absent), or
        longer (what follows the fields known here is ignored); None for any
        other length."""
        n = len(payload)
        if n >= self.size:
            fields, st = self.fields, self._struct
            payload = payload[:self.size]
        elif n in self._layouts:
            fields, st = self._layouts[n]
        else:
            return None
        vals = list(st.unpack(payload))
        out = {}
        for f in fields:
            if f.count == 1 or f.fmt == "B":
                out[f.name] = vals.pop(0)
            else:
                out[f.name] = tuple(vals[:f.count])
                del vals[:f.count]
        return out

    def unpack(self, payload: bytes) -> dict:
        """``decode``, raising ValueError for a length it does not take."""
        out = self.decode(payload)
        if out is None:
            sizes = ", ".join(map(str, self.earlier + (self.size,)))
            raise ValueError(f"{self.name}: {len(payload)} bytes, expected {sizes} or more")
        return out


def _f(name, ctype, count=1):
    return Field(name, ctype, count)


U8, I16, U16, I32 = "nx_uint8_t", "nx_int16_t", "nx_uint16_t", "nx_int32_t"

RECORD = MessageSpec("ninedof_record", None, tuple(
    _f(n, I16) for n in ("ax", "ay", "az", "gx", "gy", "gz", "mx", "my", "mz")))
RECORD_FIELDS = tuple(f.name for f in RECORD.fields)

# The sample message is variable-length: header then `count` records.
SAMPLES_HEADER = MessageSpec("ninedof_samples_msg", AM_NINEDOF_SAMPLES_MSG, (
    _f("seq", U16), _f("flags", U8), _f("count", U8)))
# The trailing array, as the header declares it: ninedof_record_t rec[NINEDOF_BATCH]
SAMPLES_ARRAY = ("rec", "ninedof_record_t", "NINEDOF_BATCH")

CAL_SENSOR = MessageSpec("ninedof_cal_sensor", None, (
    _f("a", I16, 9), _f("c", I32, 3), _f("shift", U8), _f("reserved", U8)))

CALSET_HEADER = MessageSpec("ninedof_calset", None, (
    _f("mote", U16), _f("version", U16), _f("sensors", U8), _f("format", U8)))
CALSET_ARRAY = ("s", "ninedof_cal_sensor_t", "NINEDOF_SENSORS")
CALSET_SIZE = CALSET_HEADER.size + 3 * CAL_SENSOR.size      # 102

# The set with temperature terms (format CALSET_TEMP): the plain set, then
# temp_sensors, reserved and one ninedof_cal_temp per sensor.  A set without
# temperature terms is the plain set alone (format CALSET_PLAIN).
CALSET_PLAIN, CALSET_TEMP = 0, 1
CAL_TEMP = MessageSpec("ninedof_cal_temp", None, (
    _f("t_ref", I16), _f("t_lo", I16), _f("t_hi", I16), _f("o", I16, 3), _f("g", I16, 3),
    _f("oshift", U8), _f("gshift", U8)))
CALSET_TEMP_HEADER = MessageSpec("ninedof_calset_temp", None, (
    _f("temp_sensors", U8), _f("reserved", U8)))
CALSET_TEMP_BASE = ("base", "ninedof_calset_t", None)
CALSET_TEMP_ARRAY = ("t", "ninedof_cal_temp_t", "NINEDOF_SENSORS")
CALSET_TEMP_SIZE = CALSET_SIZE + CALSET_TEMP_HEADER.size + 3 * CAL_TEMP.size   # 164
CALSET_SIZES = {CALSET_PLAIN: CALSET_SIZE, CALSET_TEMP: CALSET_TEMP_SIZE}

CAL_FRAG = MessageSpec("ninedof_cal_frag_msg", AM_NINEDOF_CAL_FRAG_MSG, (
    _f("mote", U16), _f("version", U16), _f("offset", U8), _f("len", U8),
    _f("data", U8, NINEDOF_FRAG_DATA)))
CAL_FRAG_ACK = MessageSpec("ninedof_cal_frag_ack_msg", AM_NINEDOF_CAL_FRAG_ACK_MSG, (
    _f("mote", U16), _f("version", U16), _f("offset", U8), _f("status", U8)))
CAL_COMMIT = MessageSpec("ninedof_cal_commit_msg", AM_NINEDOF_CAL_COMMIT_MSG, (
    _f("mote", U16), _f("version", U16), _f("length", U8), _f("action", U8),
    _f("crc", U16)))
CAL_COMMIT_ACK = MessageSpec("ninedof_cal_commit_ack_msg", AM_NINEDOF_CAL_COMMIT_ACK_MSG, (
    _f("mote", U16), _f("version", U16), _f("crc", U16), _f("status", U8),
    _f("sensors", U8)))
# The query grew a flags byte and the report the stored set (firmware that
# reports what its EEPROM holds): a query with QUERY_STORED gets the longer
# report; without it, or from an image built before, the report ends after
# `data` (CAL_REPORT_SIZE_V1 bytes) and decodes without the stored_* keys.
QUERY_STORED = 0x01
STORE_IDLE, STORE_WRITING, STORE_FAILED = 0, 1, 2
CAL_QUERY = MessageSpec("ninedof_cal_query_msg", AM_NINEDOF_CAL_QUERY_MSG, (
    _f("mote", U16), _f("offset", U8), _f("flags", U8)), earlier=(3,))
CAL_REPORT = MessageSpec("ninedof_cal_report_msg", AM_NINEDOF_CAL_REPORT_MSG, (
    _f("mote", U16), _f("version", U16), _f("crc", U16), _f("offset", U8),
    _f("len", U8), _f("data", U8, NINEDOF_FRAG_DATA), _f("stored_version", U16),
    _f("stored_crc", U16), _f("store", U8)), earlier=(28,))
MOTE_STATUS = MessageSpec("ninedof_mote_status_msg", AM_NINEDOF_MOTE_STATUS_MSG, (
    _f("seq", U16), _f("version", U16), _f("sensors", U8), _f("reserved", U8),
    _f("dropped", U16), _f("send_fail", U16), _f("i2c_errors", U16), _f("late", U16),
    _f("i2c_nacks", U16), _f("bus_resets", U16), _f("chip_reinits", U16)), earlier=(14,))
# The three fault counters were appended (firmware with the board's fault
# handling); a mote built before sends the message without them, which
# decode_message accepts: its dict has no such keys.
MOTE_STATUS_FAULTS = MOTE_STATUS.fields_since(14)
BS_STATUS = MessageSpec("ninedof_bs_status_msg", AM_NINEDOF_BS_STATUS_MSG, (
    _f("radio_rx", U16), _f("radio_drops", U16), _f("serial_rx", U16),
    _f("serial_drops", U16), _f("radio_fail", U16), _f("serial_fail", U16)))

# Board temperature: the ITG3200's raw TEMP_OUT summed over a period (see the
# header); temp_c() turns it into degrees C.
MOTE_TEMP = MessageSpec("ninedof_mote_temp_msg", AM_NINEDOF_MOTE_TEMP_MSG, (
    _f("seq", U16), _f("count", U8), _f("reserved", U8), _f("temp_sum", I32)))

ITG3200_TEMP_OFFSET = -13200     # raw TEMP_OUT at 35 degrees C (datasheet)
ITG3200_TEMP_LSB_PER_C = 280.0
ITG3200_TEMP_AT_OFFSET_C = 35.0


def temp_c(raw):
    """Degrees C from the ITG3200's raw TEMP_OUT (a mean of readings is fine)."""
    return ITG3200_TEMP_AT_OFFSET_C + (np.asarray(raw, float) - ITG3200_TEMP_OFFSET) \
        / ITG3200_TEMP_LSB_PER_C


def temp_raw(celsius):
    """The raw TEMP_OUT an ITG3200 gives at ``celsius`` (inverse of temp_c, not rounded)."""
    return ITG3200_TEMP_OFFSET + (np.asarray(celsius, float) - ITG3200_TEMP_AT_OFFSET_C) \
        * ITG3200_TEMP_LSB_PER_C


FIXED_MESSAGES = {m.am_type: m for m in (
    CAL_FRAG, CAL_FRAG_ACK, CAL_COMMIT, CAL_COMMIT_ACK, CAL_QUERY, CAL_REPORT,
    MOTE_STATUS, BS_STATUS, MOTE_TEMP)}
ALL_SPECS = (RECORD, SAMPLES_HEADER, CAL_SENSOR, CALSET_HEADER, CAL_TEMP) + \
    tuple(FIXED_MESSAGES.values())

RECORD_DTYPE = np.dtype(">i2")


# --------------------------------------------------------------------------
# Frames
# --------------------------------------------------------------------------
class AMPacket(NamedTuple):
    """An active message as it leaves or enters the serial line."""
    dest: int
    src: int
    group: int
    am_type: int
    payload: bytes


class Frame(NamedTuple):
    """A decoded serial frame (CRC already checked)."""
    protocol: int            # PROTO_*
    seq: int | None          # sequence byte of 0x44 frames and 0x43 acks
    dispatch: int | None     # None for ack frames
    body: bytes              # bytes after dispatch (AM header + payload); b"" for acks

    def am(self) -> AMPacket | None:
        """The AM packet inside, or None if this is no well-formed AM frame."""
        return parse_am(self.body) if self.dispatch == DISPATCH_AM else None


def crc16(data: bytes) -> int:
    """CRC-16-CCITT as TinyOS serial uses it (XMODEM: init 0, no reflection)."""
    return binascii.crc_hqx(data, 0)


_ESCAPE_RE = re.compile(rb"[\x7d\x7e]")
_UNESCAPE_RE = re.compile(rb"\x7d(.)", re.S)


def escape(data: bytes) -> bytes:
    return _ESCAPE_RE.sub(lambda m: bytes((HDLC_ESC, m.group()[0] ^ 0x20)), data)


def unescape(data: bytes) -> bytes:
    """Undo the escaping: ``0x7D, b`` becomes ``b ^ 0x20`` (a 0x7D at the end stays)."""
    n = data.count(b"\x7d")
    if n == data.count(b"\x7d\x5e") + data.count(b"\x7d\x5d"):
        # every escape is one a sender makes: two replaces do it (the same
        # result as the general rule below, which a corrupted frame needs)
        return data.replace(b"\x7d\x5e", b"\x7e").replace(b"\x7d\x5d", b"\x7d") if n else data
    return _UNESCAPE_RE.sub(lambda m: bytes((m.group(1)[0] ^ 0x20,)), data)


def encode_frame(body: bytes) -> bytes:
    """Frame an unescaped body (protocol byte .. payload): add CRC, escape, flags."""
    crc = crc16(body)
    return b"\x7e" + escape(body + bytes((crc & 0xFF, crc >> 8))) + b"\x7e"


def encode_am(am: AMPacket, *, ack_seq: int | None = None) -> bytes:
    """A whole serial frame carrying an AM packet.

    Motes send 0x45 frames (no sequence byte); the PC sends 0x44 frames with
    ``ack_seq`` and expects a 0x43 ack carrying the same sequence byte.
    """
    if len(am.payload) > 255:
        raise ValueError("AM payload longer than 255 bytes")
    hdr = AM_HEADER.pack(am.dest & 0xFFFF, am.src & 0xFFFF, len(am.payload),
                         am.group & 0xFF, am.am_type & 0xFF)
    if ack_seq is None:
        head = bytes((PROTO_PACKET_NOACK, DISPATCH_AM))
    else:
        head = bytes((PROTO_PACKET_ACK, ack_seq & 0xFF, DISPATCH_AM))
    return encode_frame(head + hdr + am.payload)


def encode_ack(seq: int) -> bytes:
    """The 0x43 frame acknowledging a 0x44 frame with sequence byte ``seq``."""
    return encode_frame(bytes((PROTO_ACK, seq & 0xFF)))


def parse_am(body: bytes) -> AMPacket | None:
    """AM header + payload; None if the length byte does not match."""
    if len(body) < AM_HEADER.size:
        return None
    dest, src, length, group, am_type = AM_HEADER.unpack_from(body)
    payload = body[AM_HEADER.size:]
    if len(payload) != length:
        return None
    return AMPacket(dest, src, group, am_type, bytes(payload))


def parse_frame_body(raw: bytes) -> Frame | None:
    """Check CRC and structure of one unescaped frame body (with its CRC)."""
    n = len(raw)
    if n < 4 or n > MAX_FRAME:
        return None
    if crc16(raw[:-2]) != (raw[-2] | (raw[-1] << 8)):
        return None
    proto = raw[0]
    if proto == PROTO_PACKET_NOACK:
        if n < 4 + AM_HEADER.size - 1:
            return None
        frame = Frame(proto, None, raw[1], bytes(raw[2:-2]))
    elif proto == PROTO_PACKET_ACK:
        if n < 5:
            return None
        frame = Frame(proto, raw[1], raw[2], bytes(raw[3:-2]))
    elif proto == PROTO_ACK:
        if n != 4:
            return None
        return Frame(proto, raw[1], None, b"")
    else:
        return None
    if frame.dispatch == DISPATCH_AM and parse_am(frame.body) is None:
        return None
    return frame


@dataclass
class DecoderStats:
    frames: int = 0          # good frames returned
    crc_errors: int = 0      # delimited frames whose CRC failed
    bad_frames: int = 0      # CRC ok but malformed (length mismatch, unknown protocol)
    garbage_bytes: int = 0   # bytes outside any frame or in oversize runs
    cut_off: int = 0         # a frame the end of the stream cut short (finish())

    def as_dict(self) -> dict:
        return dict(frames=self.frames, crc_errors=self.crc_errors,
                    bad_frames=self.bad_frames, garbage_bytes=self.garbage_bytes,
                    cut_off=self.cut_off)


class FrameBlock:
    """The good frames of one read, side by side: ``data`` holds their bodies
    (the bytes after the dispatch byte: AM header + payload) one after another,
    and per frame ``protocol``, ``seq`` (-1: none), ``dispatch`` (-1: an ack),
    ``start`` and ``length`` of its body in ``data``, as numpy arrays.  What
    ``FrameDecoder.feed_block`` returns, so sample messages can be decoded
    together (``samples.decode_sample_frames``) without a ``Frame`` per frame;
    ``frames()`` gives the list of ``Frame``s."""

    __slots__ = ("data", "protocol", "seq", "dispatch", "start", "length")

    def __init__(self, data: bytes, protocol, seq, dispatch, start, length):
        self.data = data
        self.protocol, self.seq, self.dispatch = protocol, seq, dispatch
        self.start, self.length = start, length

    def __len__(self) -> int:
        return len(self.protocol)

    def frames(self, idx=None) -> list[Frame]:
        """The frames (those with indices ``idx``, in that order) as ``Frame``s."""
        if idx is None:
            idx = range(len(self))
        d = self.data
        out = []
        for i in idx:
            s, q, a = int(self.start[i]), int(self.seq[i]), int(self.dispatch[i])
            out.append(Frame(int(self.protocol[i]), None if q < 0 else q, None if a < 0 else a,
                             d[s:s + int(self.length[i])]))
        return out

    @classmethod
    def from_frames(cls, frames: list[Frame]) -> "FrameBlock":
        n = len(frames)
        bodies = [f.body for f in frames]
        length = np.fromiter(map(len, bodies), np.int64, n)
        start = np.zeros(n, np.int64)
        np.cumsum(length[:-1], out=start[1:n])
        return cls(b"".join(bodies), np.fromiter((f.protocol for f in frames), np.int64, n),
                   np.fromiter((-1 if f.seq is None else f.seq for f in frames), np.int64, n),
                   np.fromiter((-1 if f.dispatch is None else f.dispatch for f in frames),
                               np.int64, n), start, length)


_EMPTY = np.zeros(0, np.int64)
MAX_RUN = 2 * MAX_FRAME + 2        # escaped bytes between flags: longer is garbage
FEW_FRAMES = 16                     # reads with at most this many runs: one by one


def unescape_runs(data: bytes, lengths: np.ndarray) -> tuple[bytes, np.ndarray] | None:
    """``unescape`` for many runs laid side by side in ``data`` (their lengths
    in ``lengths``), at once with numpy: the unescaped runs side by side and
    their new lengths; None when an escape is not one a sender makes (0x7D
    then 0x5E or 0x5D in the same run: only a corrupted run has one, and
    ``unescape`` takes it one escape at a time)."""
    blob = np.frombuffer(data, np.uint8)
    esc = np.flatnonzero(blob == HDLC_ESC)
    end = np.cumsum(lengths)
    run = np.searchsorted(end, esc, side="right")
    nxt = esc + 1
    if not (nxt < end[run]).all():
        return None
    follow = blob[nxt]
    if not ((follow == 0x5E) | (follow == 0x5D)).all():
        return None
    out = blob.copy()
    out[nxt] ^= 0x20
    keep = np.ones(len(out), bool)
    keep[esc] = False
    return out[keep].tobytes(), lengths - np.bincount(run, minlength=len(lengths))


def check_frames(data: bytes, lengths: np.ndarray) -> tuple[FrameBlock, int, int]:
    """``parse_frame_body`` for many unescaped frame bodies at once, laid side
    by side in ``data`` (their lengths in ``lengths``): the good frames as a
    ``FrameBlock``, and how many failed their CRC and how many were malformed
    (the same verdict, frame by frame, as ``parse_frame_body`` and
    ``FrameDecoder`` give one at a time; a test checks it)."""
    L = lengths
    n = len(L)
    if not n:
        return FrameBlock(b"", _EMPTY, _EMPTY, _EMPTY, _EMPTY, _EMPTY), 0, 0
    blob = np.frombuffer(data, np.uint8)
    s = np.zeros(n, np.int64)
    np.cumsum(L[:-1], out=s[1:])
    proto = blob[s].astype(np.int64)               # every run has at least one byte
    # the CRC over all but the last two bytes, against those two (low byte first)
    long4 = np.flatnonzero(L >= 4)
    crc_ok = np.zeros(n, bool)
    if len(long4):
        e = s[long4] + L[long4]
        stored = blob[e - 2].astype(np.int64) | (blob[e - 1].astype(np.int64) << 8)
        view = memoryview(data)
        calc = np.fromiter(map(binascii.crc_hqx,
                               map(view.__getitem__, map(slice, s[long4].tolist(),
                                                         (e - 2).tolist())),
                               itertools.repeat(0)), np.int64, len(long4))
        crc_ok[long4] = calc == stored
    crc_err = (L >= 4) & ~crc_ok
    valid = crc_ok & (L <= MAX_FRAME)
    noack = valid & (proto == PROTO_PACKET_NOACK) & (L >= 4 + AM_HEADER.size - 1)
    withack = valid & (proto == PROTO_PACKET_ACK) & (L >= 5)
    ack = valid & (proto == PROTO_ACK) & (L == 4)
    packet = noack | withack
    head = np.where(withack, 3, 2)                 # body after protocol, [seq,] dispatch
    dispatch = np.full(n, -1, np.int64)
    dispatch[packet] = blob[s[packet] + head[packet] - 1]
    seq = np.full(n, -1, np.int64)
    seq[withack | ack] = blob[s[withack | ack] + 1]
    bstart = s + head
    blen = np.where(packet, L - head - 2, 0)
    # an AM frame's length byte must match its payload (parse_am)
    am = packet & (dispatch == DISPATCH_AM)
    am_ok = am & (blen >= AM_HEADER.size)
    am_ok[am_ok] = blob[bstart[am_ok] + 4] == blen[am_ok] - AM_HEADER.size
    good = ack | (packet & ~(am & ~am_ok))
    g = np.flatnonzero(good)
    block = FrameBlock(data, proto[g], seq[g], dispatch[g], np.where(ack, 0, bstart)[g], blen[g])
    return block, int(crc_err.sum()), int(n - len(g) - crc_err.sum())


class FrameDecoder:
    """Streaming deframer: feed bytes in any chunking, get checked frames out.

    Resynchronises on the next flag after garbage, rejects every frame whose
    CRC or AM length is wrong, and never raises on any input.  A run between
    two flags that fails is counted, not returned.  ``feed`` gives ``Frame``s,
    ``feed_block`` the same frames as a ``FrameBlock`` (what the logger reads:
    the frames of a read checked together, see ``check_frames``; a read of
    at most FEW_FRAMES runs, what a live line mostly gives, one by one with
    ``parse_frame_body``, which costs less there).
    """

    def __init__(self):
        self._buf = b""
        self._synced = False       # True once a flag has been seen
        self.stats = DecoderStats()

    def feed(self, data: bytes) -> list[Frame]:
        return self.feed_block(data).frames()

    def feed_block(self, data: bytes) -> FrameBlock:
        stats = self.stats
        if not data:
            return check_frames(b"", _EMPTY)[0]
        parts = (self._buf + data).split(b"\x7e")
        # The last part is incomplete (no closing flag yet)
        tail = parts.pop()
        if not self._synced:
            # bytes before the first flag are garbage
            if parts:
                stats.garbage_bytes += len(parts[0])
                parts[0] = b""
                self._synced = True
            else:
                # still no flag: keep nothing but a bounded amount of garbage
                stats.garbage_bytes += len(tail)
                tail = b""
        parts = list(filter(None, parts))          # back-to-back flags leave empty runs
        if len(parts) <= FEW_FRAMES:
            block = self._one_by_one(parts)
        else:
            block = self._together(parts)
        stats.frames += len(block)
        if len(tail) > MAX_RUN:
            # far too long to be a frame: drop it and wait for the next flag
            stats.garbage_bytes += len(tail)
            tail = b""
            self._synced = False
        self._buf = tail
        return block

    def _one_by_one(self, parts: list[bytes]) -> FrameBlock:
        """A few runs (what a live line's read holds): ``parse_frame_body`` each."""
        stats = self.stats
        frames = []
        for p in parts:
            if len(p) > MAX_RUN:
                stats.garbage_bytes += len(p)
                continue
            raw = unescape(p) if b"\x7d" in p else p
            frame = parse_frame_body(raw)
            if frame is not None:
                frames.append(frame)
            elif len(raw) >= 4 and crc16(raw[:-2]) != (raw[-2] | (raw[-1] << 8)):
                stats.crc_errors += 1
            else:
                stats.bad_frames += 1
        return FrameBlock.from_frames(frames)

    def _together(self, parts: list[bytes]) -> FrameBlock:
        """Many runs: unescaped (``unescape_runs``) and checked (``check_frames``) at once."""
        stats = self.stats
        lengths = np.fromiter(map(len, parts), np.int64, len(parts))
        big = lengths > MAX_RUN
        if big.any():
            stats.garbage_bytes += int(lengths[big].sum())
            parts = list(itertools.compress(parts, (~big).tolist()))
            lengths = lengths[~big]
        data = b"".join(parts)
        if b"\x7d" in data:
            done = unescape_runs(data, lengths)
            if done is None:                        # a corrupted escape somewhere
                parts = [unescape(p) for p in parts]
                data = b"".join(parts)
                lengths = np.fromiter(map(len, parts), np.int64, len(parts))
            else:
                data, lengths = done
        block, crc_errors, bad = check_frames(data, lengths)
        stats.crc_errors += crc_errors
        stats.bad_frames += bad
        return block

    def finish(self) -> list[Frame]:
        """The stream ended (port closed, reader stopped): a frame whose
        closing flag never came is returned if it is whole, else counted as
        ``cut_off`` -- nothing damaged it, the end came in its middle."""
        tail = self._buf
        self._buf = b""
        if not tail:
            return []
        frame = parse_frame_body(unescape(tail) if b"\x7d" in tail else tail)
        if frame is None:
            self.stats.cut_off += 1
            return []
        self.stats.frames += 1
        return [frame]


def decode_stream(data: bytes) -> list[Frame]:
    """All good frames in a complete byte stream."""
    return FrameDecoder().feed(data + b"\x7e")


# --------------------------------------------------------------------------
# Sample messages
# --------------------------------------------------------------------------
def samples_payload_size(count: int) -> int:
    return SAMPLES_HEADER.size + NINEDOF_RECORD_SIZE * count


def pack_samples(seq: int, flags: int, records) -> bytes:
    """Payload of a sample message; ``records`` is an (n, 9) integer array."""
    rec = np.asarray(records)
    if rec.ndim != 2 or rec.shape[1] != 9 or not 1 <= rec.shape[0] <= 255:
        raise ValueError("records must be an (n, 9) array with 1 <= n <= 255")
    return (SAMPLES_HEADER.pack(seq=seq & 0xFFFF, flags=flags, count=rec.shape[0])
            + rec.astype(RECORD_DTYPE).tobytes())


class Samples(NamedTuple):
    seq: int
    flags: int
    records: np.ndarray      # (count, 9) int16

    @property
    def corrected(self) -> bool:
        return bool(self.flags & FLAG_CORRECTED)

    @property
    def version_low(self) -> int:
        return (self.flags & FLAG_VERSION_MASK) >> FLAG_VERSION_SHIFT


def unpack_samples(payload: bytes) -> Samples | None:
    """Decode a sample payload; None if count and length disagree."""
    if len(payload) < SAMPLES_HEADER.size:
        return None
    seq, flags, count = struct.unpack_from(">HBB", payload)
    if count < 1 or len(payload) != samples_payload_size(count):
        return None
    rec = np.frombuffer(payload, RECORD_DTYPE, count * 9, SAMPLES_HEADER.size)
    return Samples(seq, flags, rec.reshape(count, 9).astype(np.int16))


def decode_message(am: AMPacket):
    """Decode an AM packet's payload by type: Samples, a dict, or None.  A
    fixed message of an older or newer layout decodes by the rule of
    ``MessageSpec.decode`` (fields it lacks absent, fields not known here
    ignored)."""
    if am.am_type == AM_NINEDOF_SAMPLES_MSG:
        return unpack_samples(am.payload)
    spec = FIXED_MESSAGES.get(am.am_type)
    if spec is None:
        return None
    return spec.decode(am.payload)          # an older or newer layout too (MessageSpec)


def message_frame(spec: MessageSpec, *, dest: int, src: int = 0,
                  group: int = DEFAULT_GROUP, ack_seq: int | None = None,
                  **values) -> bytes:
    """Serial frame for one fixed-size message."""
    return encode_am(AMPacket(dest, src, group, spec.am_type, spec.pack(**values)),
                     ack_seq=ack_seq)
