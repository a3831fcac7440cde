"""The mote's own C code (``tinyos/*.c``) on the host, through ctypes.

The plain C files under ``tinyos/`` are what the firmware compiles; here they
are built with the host compiler (``cc -shared -fPIC -O2``) into a cache
directory keyed by a hash of the sources (rebuilt when any ``.c``/``.h``
changes) and loaded with ctypes.  The simulated mote calls ``CalReceiver``
for every calibration message and every batch of records, so it answers and
corrects exactly as the firmware does, bit for bit.

Environment: ``CC`` picks the compiler (default ``cc``, then ``gcc``/``clang``),
``MOTECAL_CACHE`` the cache directory (default ``~/.cache/motecal``),
``MOTECAL_TINYOS`` the source directory (default ``firmware/csrc``: a link to
the repository's ``tinyos/``, copied into the package by ``pip install``).
"""
from __future__ import annotations

import ctypes
import hashlib
import os
import shlex
import shutil
import subprocess
import tempfile
import threading
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..errors import UserError
from ..line import protocol as P

# host/motecal/firmware/csrc -> the repository's tinyos/ (in a wheel: its C files)
SRC_DIR = Path(os.environ.get("MOTECAL_TINYOS", Path(__file__).resolve().parent / "csrc"))
CFLAGS = ("-std=c99", "-O2", "-shared", "-fPIC", "-Wall", "-Wextra")
E_FORMAT = next(c for c, (n, _) in P.CAL_REASONS.items() if n == "NINEDOF_CAL_E_FORMAT")
E_FRAG = next(c for c, (n, _) in P.CAL_REASONS.items() if n == "NINEDOF_CAL_E_FRAG")
REPLY_MAX = 64          # >= the largest reply (ninedof_cal_report_msg, 33 bytes)

_lock = threading.Lock()
_lib = None


class CompilerMissing(UserError):
    """No C compiler to build the mote's C code for the host."""


def _sources(src_dir: Path) -> list[Path]:
    return sorted(p for p in src_dir.iterdir()
                  if p.suffix in (".c", ".h") and p.is_file())


def _compiler() -> list[str]:
    cc = os.environ.get("CC")
    if cc:
        cmd = shlex.split(cc)
        if shutil.which(cmd[0]):
            return cmd
        raise CompilerMissing(f"C compiler {cc!r} (from $CC) not found: the simulated "
                              "mote runs the firmware's C code and needs one")
    for name in ("cc", "gcc", "clang"):
        if shutil.which(name):
            return [name]
    raise CompilerMissing("no C compiler (cc, gcc or clang) found: the simulated mote "
                          "runs the firmware's C code; install one, e.g. "
                          "`apt-get install gcc`")


def cache_dir() -> Path:
    return Path(os.environ.get("MOTECAL_CACHE", Path.home() / ".cache" / "motecal"))


def build(src_dir: Path = SRC_DIR) -> Path:
    """Compile the shared library if the cache has none for these sources."""
    srcs = _sources(src_dir)
    cfiles = [p for p in srcs if p.suffix == ".c"]
    if not cfiles:
        raise UserError(f"no mote C sources in {src_dir}")
    cc = _compiler()
    h = hashlib.sha256()
    h.update(" ".join(cc + list(CFLAGS)).encode())
    for p in srcs:
        h.update(p.name.encode() + b"\0" + p.read_bytes() + b"\0")
    out_dir = cache_dir() / "mote_c"
    lib = out_dir / f"libninedof-{h.hexdigest()[:16]}.so"
    if lib.exists():
        return lib
    out_dir.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(suffix=".so", dir=out_dir)
    os.close(fd)
    cmd = cc + list(CFLAGS) + ["-I", str(src_dir)] + [str(p) for p in cfiles] + ["-o", tmp]
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        os.unlink(tmp)
        raise UserError(f"building the mote C code failed ({' '.join(cmd)}):\n"
                        + res.stderr.strip())
    os.replace(tmp, lib)          # atomic: parallel builders race harmlessly
    return lib


def _declare(lib):
    c = ctypes
    u8p, i16p = c.POINTER(c.c_uint8), c.POINTER(c.c_int16)
    sig = {
        "ninedof_crc16": (c.c_uint16, [c.c_uint16, c.c_char_p, c.c_uint16]),
        "ninedof_cal_decode": (c.c_uint8, [c.c_char_p, c.c_uint8, c.c_void_p]),
        "ninedof_cal_set_temp": (None, [c.c_void_p, c.c_int16]),
        "ninedof_cal_validate": (c.c_uint8, [c.c_void_p, c.c_uint16]),
        "ninedof_correct_block": (None, [c.c_void_p, i16p, i16p, c.c_uint16]),
        "ninedof_calrx_init": (None, [c.c_void_p, c.c_uint16]),
        "ninedof_calrx_handle": (c.c_uint8, [c.c_void_p, c.c_uint8, c.c_char_p, c.c_uint8,
                                             u8p, u8p]),
        "ninedof_calrx_flags": (c.c_uint8, [c.c_void_p]),
        "ninedof_calrx_correct_block": (None, [c.c_void_p, i16p, i16p, c.c_uint16]),
        "ninedof_calrx_set_temp": (None, [c.c_void_p, c.c_int16]),
        "ninedof_calrx_image": (c.c_uint8, [c.c_void_p, c.c_uint16, u8p]),
        "ninedof_image_check": (c.c_uint8, [c.c_char_p, c.c_uint8, c.c_uint16,
                                            c.POINTER(c.c_uint16)]),
        "ninedof_calrx_restore": (c.c_uint8, [c.c_void_p, c.c_char_p, c.c_char_p,
                                              c.c_char_p, u8p, c.POINTER(c.c_uint16)]),
        "ninedof_calrx_size": (c.c_size_t, []),
        "ninedof_cal_size": (c.c_size_t, []),
        "ninedof_calset_size": (c.c_size_t, []),
        "ninedof_calset_temp_size": (c.c_size_t, []),
        "ninedof_eeprom_legacy1": (c.c_uint16, []),
        "ninedof_image_size": (c.c_size_t, []),
        "ninedof_calrx_version": (c.c_uint16, [c.c_void_p]),
        "ninedof_calrx_sensors": (c.c_uint8, [c.c_void_p]),
        "ninedof_calrx_crc": (c.c_uint16, [c.c_void_p]),
        "ninedof_calrx_dirty": (c.c_uint8, [c.c_void_p]),
        "ninedof_calrx_set_dirty": (None, [c.c_void_p, c.c_uint8]),
        "ninedof_calrx_active": (None, [c.c_void_p, u8p]),
        "ninedof_calrx_active_len": (c.c_uint8, [c.c_void_p]),
        "ninedof_calrx_stored_version": (c.c_uint16, [c.c_void_p]),
        "ninedof_calrx_stored_crc": (c.c_uint16, [c.c_void_p]),
        "ninedof_calrx_store": (c.c_uint8, [c.c_void_p]),
        "ninedof_status_payload": (c.c_uint8, [c.POINTER(c.c_uint16), c.c_void_p, u8p]),
        "ninedof_eewriter_size": (c.c_size_t, []),
        "ninedof_eewriter_init": (None, [c.c_void_p, c.c_uint8, c.c_uint16]),
        "ninedof_eewriter_poll": (c.c_uint8, [c.c_void_p, c.c_void_p]),
        "ninedof_eewriter_next": (c.c_uint8, [c.c_void_p, c.POINTER(c.c_uint16), u8p]),
        "ninedof_eewriter_pending": (c.c_uint8, [c.c_void_p]),
        "ninedof_eewriter_addr": (c.c_uint16, [c.c_void_p]),
        "ninedof_eewriter_check": (c.c_uint8, [c.c_void_p, c.c_void_p, c.c_char_p]),
        "ninedof_eewriter_busy": (c.c_uint8, [c.c_void_p]),
        "ninedof_slot_addr": (c.c_uint16, [c.c_uint8]),
    }
    for name, (res, args) in sig.items():
        f = getattr(lib, name)
        f.restype, f.argtypes = res, args
    return lib


def library():
    """The loaded library (built on first use)."""
    global _lib
    with _lock:
        if _lib is None:
            lib = _declare(ctypes.CDLL(str(build())))
            if (lib.ninedof_calset_size(), lib.ninedof_calset_temp_size()) != \
                    (P.CALSET_SIZE, P.CALSET_TEMP_SIZE):
                raise RuntimeError("C and protocol.py disagree on the calibration set size")
            _lib = lib
        return _lib


def _i16p(a):
    return a.ctypes.data_as(ctypes.POINTER(ctypes.c_int16))


def _records(raw) -> np.ndarray:
    a = np.asarray(raw)
    if a.ndim != 2 or a.shape[1] != 9:
        raise ValueError("records must be an (n, 9) array")
    if a.dtype != np.int16:
        if np.any(a < -32768) or np.any(a > 32767):
            raise ValueError("records must be int16 counts")
        a = a.astype(np.int16)
    return np.ascontiguousarray(a)


def _correct_with(fn, obj, raw) -> np.ndarray:
    src = _records(raw)
    out = np.empty_like(src)
    # the C block length is 16 bits
    for i in range(0, len(src), 0xFFFF):
        s, o = src[i:i + 0xFFFF], out[i:i + 0xFFFF]
        fn(obj, _i16p(s), _i16p(o), len(s))
    return out


# --------------------------------------------------------------------------
# Module functions on calibration-set bytes
# --------------------------------------------------------------------------
def crc16(data: bytes, crc: int = 0) -> int:
    """The mote's CRC-16 (equals ``binascii.crc_hqx(data, crc)``)."""
    data = bytes(data)
    return library().ninedof_crc16(crc, data, len(data))


def _decode(calset: bytes):
    lib = library()
    calset = bytes(calset)
    if len(calset) not in P.CALSET_SIZES.values():
        return E_FORMAT, None
    buf = ctypes.create_string_buffer(lib.ninedof_cal_size())
    return lib.ninedof_cal_decode(calset, len(calset), buf), buf


def validate(calset: bytes, mote_id: int) -> int:
    """Reason code the mote gives this set (0 = NINEDOF_CAL_OK)."""
    code, buf = _decode(calset)
    if code != 0:
        return code
    return library().ninedof_cal_validate(buf, mote_id)


def correct(calset: bytes, raw, temp_raw: int | None = None) -> np.ndarray:
    """Correct ``(n, 9)`` int16 records with a set, as the mote would.

    The set is decoded (a badly formatted one raises ValueError) but not
    validated; an in-range set gives exactly the firmware's output.
    ``temp_raw`` is the board temperature in force (raw ITG-3200 TEMP_OUT)
    for a set with temperature terms; None: no temperature yet (each sensor
    at its reference temperature).  The records are one run in sampling
    order from a freshly applied set: the rounding's residuals (error
    feedback, ``ninedof_correct.h``) start at 0 each call (``Corrector`` carries
    them from call to call).
    """
    code, buf = _decode(calset)
    if code != 0:
        raise ValueError(f"calibration set rejected: {P.cal_reason(code)}")
    if temp_raw is not None:
        library().ninedof_cal_set_temp(buf, _temp16(temp_raw))
    return _correct_with(library().ninedof_correct_block, buf, raw)


class Corrector:
    """One decoded set that corrects block after block as the mote does:
    its rounding residuals (error feedback, ``ninedof_correct.h``) carry on from
    one call to the next and across temperature changes; ``correct`` on
    module level starts from a freshly applied set each call."""

    def __init__(self, calset: bytes):
        code, self._buf = _decode(calset)
        if code != 0:
            raise ValueError(f"calibration set rejected: {P.cal_reason(code)}")

    def set_temperature(self, temp_raw: int) -> None:
        library().ninedof_cal_set_temp(self._buf, _temp16(temp_raw))

    def correct(self, raw) -> np.ndarray:
        return _correct_with(library().ninedof_correct_block, self._buf, raw)


def _temp16(temp_raw) -> int:
    t = int(temp_raw)
    if not -32768 <= t <= 32767:
        raise ValueError(f"raw temperature {t} is not an int16 TEMP_OUT reading")
    return t


def image_check(image: bytes, mote_id: int) -> int | None:
    """Generation of a valid EEPROM image for this mote, None if invalid."""
    lib = library()
    image = bytes(image)[:lib.ninedof_image_size()]
    gen = ctypes.c_uint16()
    return gen.value if lib.ninedof_image_check(image, len(image), mote_id,
                                                ctypes.byref(gen)) else None


# --------------------------------------------------------------------------
# The mote side of the upload protocol
# --------------------------------------------------------------------------
class Restored(NamedTuple):
    slot: int | None          # slot put in force, None when neither was valid
    next_slot: int            # where the next image goes
    next_generation: int      # with this generation number


class CalReceiver:
    """One mote's calibration state, run by the firmware's C code.

    ``handle(am_type, payload)`` -> ``(reply_am_type, reply_payload)`` or None;
    ``correct(raw)`` corrects records with the set in force; ``flags()`` is the
    sample-message flags byte.  After an accepted commit ``dirty`` is True: the
    caller persists ``image(generation)`` and calls ``mark_persisted()``.
    """

    def __init__(self, mote_id: int):
        self._lib = library()
        self.mote_id = int(mote_id) & 0xFFFF
        self._rx = ctypes.create_string_buffer(self._lib.ninedof_calrx_size())
        self._image_size = self._lib.ninedof_image_size()
        self._lib.ninedof_calrx_init(self._rx, self.mote_id)
        self._reply = (ctypes.c_uint8 * REPLY_MAX)()
        self._rtype = ctypes.c_uint8()

    def handle(self, am_type: int, payload: bytes):
        payload = bytes(payload)
        if len(payload) > 255:
            return None
        n = self._lib.ninedof_calrx_handle(self._rx, am_type & 0xFF, payload, len(payload),
                                           self._reply, ctypes.byref(self._rtype))
        if n == 0:
            return None
        return int(self._rtype.value), bytes(self._reply[:n])

    def flags(self) -> int:
        return int(self._lib.ninedof_calrx_flags(self._rx))

    def correct(self, raw) -> np.ndarray:
        return _correct_with(self._lib.ninedof_calrx_correct_block, self._rx, raw)

    def set_temperature(self, temp_raw: int) -> None:
        """The board temperature (raw TEMP_OUT) the correction uses from now
        on, as the firmware sets it once a second (ninedof_calrx_set_temp)."""
        self._lib.ninedof_calrx_set_temp(self._rx, _temp16(temp_raw))

    @property
    def version(self) -> int:
        """Version of the set in force (0 = raw since boot)."""
        return int(self._lib.ninedof_calrx_version(self._rx))

    @property
    def sensors(self) -> int:
        """Bit NINEDOF_SENSOR_x set: that sensor is corrected."""
        return int(self._lib.ninedof_calrx_sensors(self._rx))

    @property
    def crc(self) -> int:
        """CRC-16 of the set in force."""
        return int(self._lib.ninedof_calrx_crc(self._rx))

    @property
    def stored_version(self) -> int:
        """Version of the set the EEPROM holds, written and read back (what a
        reset puts in force); 0: none."""
        return int(self._lib.ninedof_calrx_stored_version(self._rx))

    @property
    def stored_crc(self) -> int:
        return int(self._lib.ninedof_calrx_stored_crc(self._rx))

    @property
    def store(self) -> int:
        """The EEPROM writer's state (protocol.STORE_*)."""
        return int(self._lib.ninedof_calrx_store(self._rx))

    def active_calset(self) -> bytes:
        """Wire bytes of the set in force (what read-back returns)."""
        buf = (ctypes.c_uint8 * P.CALSET_TEMP_SIZE)()
        self._lib.ninedof_calrx_active(self._rx, buf)
        return bytes(buf[:self._lib.ninedof_calrx_active_len(self._rx)])

    @property
    def dirty(self) -> bool:
        """A commit put a set in force that is not yet persisted."""
        return bool(self._lib.ninedof_calrx_dirty(self._rx))

    def mark_persisted(self) -> None:
        self._lib.ninedof_calrx_set_dirty(self._rx, 0)

    def image(self, generation: int) -> bytes:
        buf = (ctypes.c_uint8 * self._image_size)()
        n = self._lib.ninedof_calrx_image(self._rx, generation & 0xFFFF, buf)
        return bytes(buf[:n])

    def restore(self, slot0: bytes, slot1: bytes, legacy1: bytes | None = None) -> Restored:
        """Boot-time restore from the EEPROM slot images (any may be junk):
        slot 0, slot 1 and the second slot of images built before the
        temperature terms (``legacy1``, 2 in ``Restored.slot``)."""
        n = self._image_size
        s0, s1 = (bytes(s).ljust(n, b"\xff")[:n] for s in (slot0, slot1))
        lg = None if legacy1 is None else bytes(legacy1).ljust(n, b"\xff")[:n]
        nslot, ngen = ctypes.c_uint8(), ctypes.c_uint16()
        used = self._lib.ninedof_calrx_restore(self._rx, s0, s1, lg, ctypes.byref(nslot),
                                               ctypes.byref(ngen))
        return Restored(None if used == 0xFF else int(used), int(nslot.value),
                        int(ngen.value))



# --------------------------------------------------------------------------
# An image built before the temperature terms, for the simulator
# --------------------------------------------------------------------------
def handle_as_pre_temperature_image(rx: CalReceiver, am_type: int, payload: bytes):
    """``rx.handle`` as an image built before the temperature terms answers:
    its receiver took no set longer than the plain one, so a fragment that
    reaches past byte 102 gets NINEDOF_CAL_E_FRAG and stages nothing, and it
    knew nothing of the stored-set report (a query gets the report of that
    time, ``P.CAL_REPORT.earlier[0]`` bytes, whatever it asks for).  Everything
    else is the same code: the simulator's ``--no-temp`` motes."""
    payload = bytes(payload)
    if am_type == P.AM_NINEDOF_CAL_FRAG_MSG and len(payload) >= P.CAL_FRAG.size:
        m = P.CAL_FRAG.unpack(payload[:P.CAL_FRAG.size])
        if m["mote"] == rx.mote_id and m["version"] and 0 < m["len"] <= P.NINEDOF_FRAG_DATA \
                and m["offset"] + m["len"] > P.CALSET_SIZE:
            return P.AM_NINEDOF_CAL_FRAG_ACK_MSG, P.CAL_FRAG_ACK.pack(
                mote=rx.mote_id, version=m["version"], offset=m["offset"], status=E_FRAG)
    if am_type == P.AM_NINEDOF_CAL_QUERY_MSG:
        payload = payload[:P.CAL_QUERY.earlier[0]]
    return rx.handle(am_type, payload)


# --------------------------------------------------------------------------
# The status message as the firmware packs it (ninedof_status_pack)
# --------------------------------------------------------------------------
STATUS_COUNTERS = ("seq", "dropped", "send_fail", "i2c_errors", "late", "i2c_nacks",
                   "bus_resets", "chip_reinits")
_raw_rx: "CalReceiver | None" = None


def status_payload(receiver: "CalReceiver | None" = None, **counters) -> bytes:
    """The payload of a ``ninedof_mote_status_msg``, packed by the firmware's
    ``ninedof_status_pack`` (tinyos/ninedof_sampling.c) from the counters
    (``STATUS_COUNTERS``, each wrapped to 16 bits; missing ones are 0) and
    the set in force of ``receiver`` (None: the raw set, version 0)."""
    global _raw_rx
    unknown = set(counters) - set(STATUS_COUNTERS)
    if unknown:
        raise TypeError(f"unknown status counters {sorted(unknown)}")
    lib = library()
    if receiver is None:
        if _raw_rx is None:
            _raw_rx = CalReceiver(0)
        receiver = _raw_rx
    vals = (ctypes.c_uint16 * len(STATUS_COUNTERS))(
        *(int(counters.get(k, 0)) & 0xFFFF for k in STATUS_COUNTERS))
    out = (ctypes.c_uint8 * REPLY_MAX)()
    n = lib.ninedof_status_payload(vals, receiver._rx, out)
    return bytes(out[:n])


# --------------------------------------------------------------------------
# The firmware's background EEPROM writer (tinyos/ninedof_sampling.c)
# --------------------------------------------------------------------------
class EepromWriter:
    """Writes the set in force into the EEPROM slots one byte per step, as
    the firmware does (an EEPROM byte write takes 3.4 ms while sampling goes
    on), then reads the slot back (``check``): only then is the set stored
    (``CalReceiver.stored_version``).  ``eeprom`` is a bytearray standing
    for the chip's EEPROM (any object with item access: a test's EEPROM
    that drops writes makes the check fail)."""

    BYTE_TIME_S = 0.0034
    SIZE = 4096                        # ATmega1281 EEPROM

    def __init__(self, receiver: CalReceiver, eeprom: bytearray | None = None):
        self._lib = library()
        self.rx = receiver
        self.eeprom = eeprom if eeprom is not None else bytearray(b"\xff" * self.SIZE)
        self._w = ctypes.create_string_buffer(self._lib.ninedof_eewriter_size())
        n = receiver._image_size
        slots = [bytes(self.eeprom[a:a + n]) for a in (self.slot_addr(0), self.slot_addr(1),
                                                       self._lib.ninedof_eeprom_legacy1())]
        self.restored = receiver.restore(*slots)
        self._lib.ninedof_eewriter_init(self._w, self.restored.next_slot,
                                        self.restored.next_generation)

    def slot_addr(self, slot: int) -> int:
        return int(self._lib.ninedof_slot_addr(slot))

    def poll(self) -> bool:
        """Start writing if a commit left the set in force unpersisted."""
        return bool(self._lib.ninedof_eewriter_poll(self._w, self.rx._rx))

    @property
    def busy(self) -> bool:
        """A write is under way or waits for its check."""
        return bool(self._lib.ninedof_eewriter_busy(self._w))

    @property
    def pending(self) -> bool:
        """Every byte is written: the image waits for ``check``."""
        return bool(self._lib.ninedof_eewriter_pending(self._w))

    def step(self) -> bool:
        """Write one byte; False when nothing was left to write."""
        addr, value = ctypes.c_uint16(), ctypes.c_uint8()
        if not self._lib.ninedof_eewriter_next(self._w, ctypes.byref(addr), ctypes.byref(value)):
            return False
        self.eeprom[addr.value] = value.value
        return True

    def check(self) -> int:
        """Read the slot back and compare (``ninedof_eewriter_check``):
        ``STORED``, ``AGAIN`` (written again: ``step`` on) or ``FAILED``; 0
        when nothing waited for a check."""
        if not self.pending:
            return 0
        a = int(self._lib.ninedof_eewriter_addr(self._w))
        back = bytes(self.eeprom[a:a + self.rx._image_size])
        return int(self._lib.ninedof_eewriter_check(self._w, self.rx._rx, back))

    STORED, AGAIN, FAILED = 1, 2, 3         # NINEDOF_EE_*
