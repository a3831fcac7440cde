"""``motecal upload``: a calibration (cal.json) to a mote, through the
BaseStation and the radio, then verified.

    motecal upload cal.json --port URL [--mote ID] [--version N] [--timeout S] [--retries N]
    motecal upload cal.json --dry-run [--mote ID] [--version N]
    motecal upload --show [cal.json] --port URL --mote ID
    motecal upload --reset --port URL --mote ID [--version N]

Protocol (messages of ``tinyos/NineDofMsg.h``), one message at a time:

1. CAL_QUERY offset 0 -> CAL_REPORT: the version in force; the new set gets
   that + 1 (65535 -> 1) unless ``--version``.
2. The set (``fixedpoint.build_calset``, 102 bytes) in fragments of
   NINEDOF_FRAG_DATA (20) bytes: CAL_FRAG -> CAL_FRAG_ACK (status) each.
3. CAL_COMMIT (APPLY, length, CRC-16 of the set) -> CAL_COMMIT_ACK (status,
   the CRC the mote computed, the version in force, sensors corrected).
4. Read-back: CAL_QUERY offsets 0, 20, .. 100 -> CAL_REPORTs; the set in
   force must equal the set sent byte for byte.
5. The mote's next sample messages must carry the corrected flag and the
   version's low 4 bits.

Transport.  Each message goes to the serial line as a 0x44 frame with a
sequence byte; the BaseStation acknowledges it with a 0x43 frame (SerialP).
No 0x43 within ``SERIAL_ACK_TIMEOUT``: the same frame is sent again, up to
``SERIAL_RETRIES`` times, then the upload stops (no BaseStation on the port).
The BaseStation sends PC packets by radio without link-layer acks, so a lost
fragment (or a lost reply) is the host's business: no reply within
``--timeout`` seconds and the message is sent again, up to ``--retries``
times.  Every message is idempotent on the mote (fragments restage the same
bytes, a repeated commit of the set in force is acknowledged again), so a
repeat is harmless.  A SerialForwarder (``sf@``) does the serial acks
itself; then only the replies are waited for.

Errors are one line on stderr: bad input exits 2, a set that cannot be
represented or that the mote's own checks would refuse exits 3, and an
upload that fails (no answer, rejected, verification failed) exits 1.
"""
from __future__ import annotations

import json
import sys
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import fixedpoint as FP
from . import protocol as P
from . import sources as S
from .cliargs import MOTE_ID_MAX, MOTE_ID_MIN, baud_rate, int_range, mote_id, positive
from .errors import QualityError, UserError
from .session import NOMINAL_SCALES, UNITS

DEFAULT_TIMEOUT = 0.3        # s: a mote's reply, counted from the BaseStation's serial ack
DEFAULT_RETRIES = 20         # repeats of one message after the first try
SERIAL_ACK_TIMEOUT = 0.25    # s: the BaseStation's 0x43 for one 0x44 frame
SERIAL_RETRIES = 3
VERIFY_WAIT = 2.0            # s: for the mote's sample messages after the commit
VERIFY_MESSAGES = 3          # consecutive sample messages with the new flags
VERIFY_STALE_MAX = 12        # old-flag messages tolerated first (queued before the commit)
MAX_VERSION = 0xFFFF
SAMPLE_LOG = 4096            # sample messages remembered for the verification


class UploadFailed(UserError):
    """The upload did not complete: no answer, rejected, or not verified."""

    exit_code = 1


class NoAnswer(UploadFailed):
    pass


class Rejected(UploadFailed):
    """The mote answered with a reason code other than NINEDOF_CAL_OK."""

    def __init__(self, message: str, status: int):
        super().__init__(message)
        self.status = status


def next_version(in_force: int) -> int:
    """The version after ``in_force``: +1, 65535 wraps to 1 (0 is never valid)."""
    return in_force % MAX_VERSION + 1


def fragments(calset: bytes) -> list[tuple[int, bytes]]:
    """(offset, bytes) pieces of NINEDOF_FRAG_DATA bytes."""
    n = P.NINEDOF_FRAG_DATA
    return [(off, bytes(calset[off:off + n])) for off in range(0, len(calset), n)]


# --------------------------------------------------------------------------
# Progress display
# --------------------------------------------------------------------------
class NullProgress:
    """Shows nothing."""

    def note(self, text: str) -> None:
        pass

    def task(self, name: str, total: int) -> None:
        pass

    def step(self, text: str) -> None:
        pass

    def close(self) -> None:
        pass


class PlainProgress(NullProgress):
    """Plain lines (no TTY): one per message and one per event."""

    def __init__(self, out=None, steps: bool = True):
        self.out = out or sys.stdout
        self.steps = steps

    def note(self, text: str) -> None:
        print(text, file=self.out, flush=True)

    def step(self, text: str) -> None:
        if self.steps:
            self.note("  " + text)


class RichProgress(PlainProgress):
    """A progress bar per phase on a terminal (rich); events above it."""

    def __init__(self):
        from rich.console import Console
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn
        self.console = Console()
        self.progress = Progress(TextColumn("{task.description}"), BarColumn(),
                                 MofNCompleteColumn(), TextColumn("{task.fields[detail]}"),
                                 console=self.console, transient=False)
        self.progress.start()
        self._task = None

    def note(self, text: str) -> None:
        self.progress.console.print(text, highlight=False, markup=False)

    def task(self, name: str, total: int) -> None:
        self._task = self.progress.add_task(name, total=total, detail="")

    def step(self, text: str) -> None:
        if self._task is None:
            self.note("  " + text)
        else:
            self.progress.update(self._task, advance=1, detail=text)

    def close(self) -> None:
        self.progress.stop()


def make_progress():
    return RichProgress() if sys.stdout.isatty() else PlainProgress()


# --------------------------------------------------------------------------
# The link: serial acks, replies, sample flags
# --------------------------------------------------------------------------
@dataclass
class LinkStats:
    messages: int = 0          # requests
    tries: int = 0             # radio attempts (>= messages)
    serial_frames: int = 0     # 0x44 frames written (>= tries)
    serial_retries: int = 0    # frames written again for a missing 0x43
    replies: int = 0           # calibration replies received (any)

    @property
    def retries(self) -> int:
        return self.tries - self.messages


REPLY_TYPES = (P.AM_NINEDOF_CAL_FRAG_ACK_MSG, P.AM_NINEDOF_CAL_COMMIT_ACK_MSG,
               P.AM_NINEDOF_CAL_REPORT_MSG)


class Link:
    """Request/reply with one mote over a ``sources.Source``.

    ``request`` sends a message (serial ack handled by ``_send``) and waits
    for a reply of the given type from the mote that ``match`` accepts, trying
    ``1 + retries`` times.  Replies that arrived before a request started are
    dropped when it starts (they answer something else); late replies of an
    earlier try of the same request are valid answers.  Sample messages are
    remembered (source, flags) for the verification.  ``clock`` is the
    source's own clock when it has one (a simulated world's), else wall time.
    """

    def __init__(self, source: S.Source, *, timeout: float = DEFAULT_TIMEOUT,
                 retries: int = DEFAULT_RETRIES, serial_timeout: float = SERIAL_ACK_TIMEOUT,
                 serial_retries: int = SERIAL_RETRIES, clock=None, progress=None):
        self.source = source
        self.timeout = float(timeout)
        self.retries = int(retries)
        self.serial_timeout = float(serial_timeout)
        self.serial_retries = int(serial_retries)
        self.clock = clock or getattr(source, "clock", None) or time.monotonic
        self.serial_acks = source.spec.kind != "sf"
        self.progress = progress or NullProgress()
        self.stats = LinkStats()
        self._seq = 0
        self._acked: set[int] = set()
        self._replies: deque = deque()
        self.samples: deque = deque(maxlen=SAMPLE_LOG)    # (src, flags)

    # -- reading ------------------------------------------------------------------
    def pump(self) -> None:
        """One read of the source (it waits up to its read timeout)."""
        try:
            frames = self.source.read()
        except S.SourceLost as e:
            raise UploadFailed(f"lost the port {self.source.spec}: {e}") from None
        except S.SourceEnded:
            raise UploadFailed(f"{self.source.spec} ended") from None
        for fr in frames:
            if fr.protocol == P.PROTO_ACK:
                self._acked.add(fr.seq)
                continue
            am = fr.am()
            if am is None:
                continue
            if am.am_type == P.AM_NINEDOF_SAMPLES_MSG:
                s = P.unpack_samples(am.payload)
                if s is not None:
                    self.samples.append((am.src, s.flags))
            elif am.am_type in REPLY_TYPES:
                msg = P.decode_message(am)
                if msg is not None:
                    self.stats.replies += 1
                    self._replies.append((am.src, am.am_type, msg))

    # -- sending ------------------------------------------------------------------
    def _send(self, am: P.AMPacket, what: str) -> None:
        """One AM packet onto the serial line, repeated until the BaseStation acks it."""
        if not self.serial_acks:
            self._write(am, None)
            return
        self._seq = self._seq % 255 + 1
        seq = self._seq
        self._acked.discard(seq)
        for attempt in range(1 + self.serial_retries):
            if attempt:
                self.stats.serial_retries += 1
            self._write(am, seq)
            deadline = self.clock() + self.serial_timeout
            while True:
                if seq in self._acked:
                    self._acked.discard(seq)
                    return
                if self.clock() >= deadline:
                    break
                self.pump()
        raise UploadFailed(
            f"the BaseStation on {self.source.spec} did not acknowledge {what} "
            f"(no serial ack 0x43 to {1 + self.serial_retries} frames): is a motecal "
            "BaseStation on this port, at this baud rate?")

    def _write(self, am: P.AMPacket, seq: int | None) -> None:
        self.stats.serial_frames += 1
        try:
            self.source.send(am, ack_seq=seq)
        except S.SourceLost as e:
            raise UploadFailed(f"lost the port {self.source.spec}: {e}") from None

    def _take(self, mote: int, am_type: int, match) -> dict | None:
        for i, (src, typ, msg) in enumerate(self._replies):
            if src == mote and typ == am_type and match(msg):
                del self._replies[i]
                return msg
        return None

    def request(self, spec: P.MessageSpec, reply_type: int, what: str, match=lambda m: True,
                **fields) -> dict:
        mote = int(fields["mote"])
        am = P.AMPacket(mote, 0, P.DEFAULT_GROUP, spec.am_type, spec.pack(**fields))
        self._replies.clear()
        self.stats.messages += 1
        tries = 1 + self.retries
        for attempt in range(tries):
            if attempt:
                self.progress.note(f"  no answer to {what} within {self.timeout:g} s; "
                                   f"sending it again (try {attempt + 1} of {tries})")
            self.stats.tries += 1
            self._send(am, what)
            deadline = self.clock() + self.timeout
            while True:
                msg = self._take(mote, reply_type, match)
                if msg is not None:
                    return msg
                if self.clock() >= deadline:
                    break
                self.pump()
        raise NoAnswer(f"no answer from mote {mote} to {what} after {tries} tries of "
                       f"{self.timeout:g} s: is it switched on, in range of the BaseStation "
                       f"and running the motecal firmware with ID {mote}?")


# --------------------------------------------------------------------------
# The protocol steps
# --------------------------------------------------------------------------
@dataclass
class InForce:
    """What a mote has in force (from CAL_REPORTs)."""
    mote: int
    version: int
    crc: int
    data: bytes | None = None          # the whole set, when read

    @property
    def calset(self) -> FP.Calset | None:
        return FP.unpack_calset(self.data) if self.data is not None else None


@dataclass
class SampleCheck:
    """The mote's sample messages after a commit."""
    expected_flags: int
    checked: int = 0                   # messages with the expected flags, in a row
    stale: int = 0                     # messages with old flags before them
    note: str = ""

    @property
    def seen(self) -> bool:
        return self.checked > 0


@dataclass
class Result:
    mote: int
    version: int
    crc: int
    sensors: int
    previous: int                      # version in force before
    readback: bool = False
    samples: SampleCheck | None = None
    seconds: float = 0.0
    stats: LinkStats = field(default_factory=LinkStats)


def flags_for(version: int, sensors: int) -> int:
    """The flags byte of sample messages with that set in force."""
    return ((version << P.FLAG_VERSION_SHIFT) & P.FLAG_VERSION_MASK) | \
        (P.FLAG_CORRECTED if sensors else 0)


def describe_flags(flags: int) -> str:
    state = "corrected" if flags & P.FLAG_CORRECTED else "raw"
    return f"{state}, version low bits {(flags & P.FLAG_VERSION_MASK) >> P.FLAG_VERSION_SHIFT}"


class Uploader:
    """The upload protocol with one mote over a ``Link``.

    ``upload`` and ``reset`` are the checked paths.  ``stage``, ``commit`` and
    ``apply`` are the protocol steps themselves and send whatever they are
    given (no local check): the tests use them to send deliberately bad sets.
    """

    def __init__(self, link: Link, mote: int, progress=None):
        self.link = link
        self.mote = int(mote)
        self.progress = progress or link.progress

    # -- read ----------------------------------------------------------------------
    def query(self, offset: int, what: str | None = None, match=lambda m: True) -> dict:
        return self.link.request(P.CAL_QUERY, P.AM_NINEDOF_CAL_REPORT_MSG,
                                 what or f"the query at offset {offset}",
                                 match=lambda m: m["offset"] == offset and match(m),
                                 mote=self.mote, offset=offset)

    def in_force(self) -> InForce:
        r = self.query(0, "the query of the version in force")
        return InForce(self.mote, r["version"], r["crc"])

    def read_set(self, expect_version: int | None = None, attempts: int = 3) -> InForce:
        """The whole set in force, CAL_REPORT by CAL_REPORT, checked against its CRC.

        ``expect_version``: only reports of that version count (older ones
        still travelling are ignored).
        """
        pieces = fragments(bytes(P.CALSET_SIZE))
        match = (lambda m: True) if expect_version is None else \
            (lambda m: m["version"] == expect_version)
        for _ in range(attempts):
            self.progress.task("read-back", len(pieces))
            data = bytearray()
            head = None
            for i, (off, chunk) in enumerate(pieces):
                r = self.query(off, f"read-back {i + 1}/{len(pieces)} (offset {off})", match)
                if r["len"] != len(chunk):
                    raise UploadFailed(f"mote {self.mote} reports {r['len']} bytes at offset "
                                       f"{off}, expected {len(chunk)}: not this protocol's "
                                       f"{P.CALSET_SIZE}-byte set")
                if head is None:
                    head = (r["version"], r["crc"])
                elif (r["version"], r["crc"]) != head:
                    break                        # the set changed while reading: again
                data += r["data"][:r["len"]]
                self.progress.step(f"read-back {i + 1}/{len(pieces)} (offset {off}): "
                                   f"version {r['version']}")
            else:
                if P.crc16(bytes(data)) != head[1]:
                    raise UploadFailed(f"mote {self.mote}: the set read back does not match "
                                       f"its CRC 0x{head[1]:04x}")
                return InForce(self.mote, head[0], head[1], bytes(data))
        raise UploadFailed(f"mote {self.mote}: the set in force kept changing while it was "
                           "read back")

    # -- write -------------------------------------------------------------------
    def stage(self, calset: bytes, version: int | None = None, pieces=None) -> None:
        """Send the fragments of ``calset`` (``pieces`` = other (offset, bytes))."""
        if version is None:
            version = FP.unpack_calset(calset).version
        pieces = fragments(calset) if pieces is None else list(pieces)
        self.progress.task("fragments", len(pieces))
        for i, (off, chunk) in enumerate(pieces):
            what = f"fragment {i + 1}/{len(pieces)} (offset {off})"
            ack = self.link.request(
                P.CAL_FRAG, P.AM_NINEDOF_CAL_FRAG_ACK_MSG, what,
                match=lambda m, off=off: m["offset"] == off and m["version"] == version,
                mote=self.mote, version=version, offset=off, len=len(chunk), data=chunk)
            if ack["status"] != P.CAL_OK:
                raise Rejected(f"mote {self.mote} rejected {what} of version {version}: "
                               f"{P.cal_reason(ack['status'])}; the set in force is "
                               "unchanged", ack["status"])
            self.progress.step(f"{what}: {len(chunk)} bytes acked")

    def commit(self, version: int, crc: int, length: int = P.CALSET_SIZE,
               action: int = P.CAL_APPLY) -> dict:
        what = "the commit" if action == P.CAL_APPLY else "the reset"
        # an ack that accepts names our version; a late ack of an earlier commit does not
        ack = self.link.request(P.CAL_COMMIT, P.AM_NINEDOF_CAL_COMMIT_ACK_MSG, what,
                                match=lambda m: m["status"] != P.CAL_OK
                                or m["version"] == version,
                                mote=self.mote, version=version, length=length,
                                action=action, crc=crc)
        self.link.samples.clear()        # what follows was packed after the commit
        return ack

    def apply(self, version: int, crc: int) -> dict:
        """Commit the staged set; Rejected (with the mote's reason) unless it is
        now in force with our CRC."""
        ack = self.commit(version, crc)
        if ack["status"] != P.CAL_OK:
            raise Rejected(f"mote {self.mote} rejected calibration version {version}: "
                           f"{P.cal_reason(ack['status'])}; version {ack['version']} stays in "
                           "force", ack["status"])
        if ack["crc"] != crc or ack["version"] != version:
            raise UploadFailed(f"mote {self.mote} acknowledged version {ack['version']} with "
                               f"CRC 0x{ack['crc']:04x}, sent version {version} with CRC "
                               f"0x{crc:04x}")
        self.progress.note(f"  commit: accepted, mote CRC 0x{ack['crc']:04x} = ours, version "
                           f"{ack['version']} in force, corrected: {sensor_names(ack['sensors'])}")
        return ack

    def check_samples(self, expected_flags: int, wait: float = VERIFY_WAIT) -> SampleCheck:
        """The next sample messages of the mote carry ``expected_flags``: skip
        the old-flag ones still queued at the commit, then want
        VERIFY_MESSAGES in a row; an old one after a new one fails."""
        chk = SampleCheck(expected_flags)
        deadline = self.link.clock() + wait
        last = None
        while chk.checked < VERIFY_MESSAGES:
            while self.link.samples:
                src, flags = self.link.samples.popleft()
                if src != self.mote:
                    continue
                last = flags
                if flags == expected_flags:
                    chk.checked += 1
                elif chk.checked:
                    raise UploadFailed(f"mote {self.mote} went back to samples flagged "
                                       f"{describe_flags(flags)} after the new set was in "
                                       "force (did it restart?)")
                else:
                    chk.stale += 1
                    if chk.stale > VERIFY_STALE_MAX:
                        raise UploadFailed(
                            f"mote {self.mote} still sends samples flagged "
                            f"{describe_flags(flags)} after the commit, expected "
                            f"{describe_flags(expected_flags)}")
                if chk.checked >= VERIFY_MESSAGES:
                    break
            if chk.checked >= VERIFY_MESSAGES:
                break
            if self.link.clock() >= deadline:
                if last is None:
                    chk.note = (f"no sample messages from mote {self.mote} within {wait:g} s "
                                "(is it sampling?): flags not checked")
                else:
                    raise UploadFailed(
                        f"mote {self.mote}: only {chk.checked} sample message(s) flagged "
                        f"{describe_flags(expected_flags)} within {wait:g} s")
                break
            self.link.pump()
        return chk

    # -- the checked paths ------------------------------------------------------
    def upload(self, calset: bytes, previous: int, verify_wait: float = VERIFY_WAIT) -> Result:
        """Stage, commit, read back and check the samples; raises on any failure."""
        t0 = self.link.clock()
        cs = FP.unpack_calset(calset)
        crc = P.crc16(calset)
        self.stage(calset, cs.version)
        ack = self.apply(cs.version, crc)
        back = self.read_set(expect_version=cs.version)
        if back.data != calset:
            i = next(k for k in range(len(calset)) if back.data[k] != calset[k])
            raise UploadFailed(f"mote {self.mote}: the set read back differs from the set sent "
                               f"(first at byte {i})")
        self.progress.note(f"  read-back: {len(calset)} bytes identical, CRC 0x{back.crc:04x}")
        chk = self.check_samples(flags_for(cs.version, cs.mask), verify_wait)
        self._note_samples(chk)
        return Result(self.mote, cs.version, crc, ack["sensors"], previous, True, chk,
                      self.link.clock() - t0, self.link.stats)

    def reset(self, version: int, previous: int, verify_wait: float = VERIFY_WAIT) -> Result:
        """Back to raw output with ``version``; verified like an upload."""
        t0 = self.link.clock()
        ack = self.commit(version, 0, action=P.CAL_RESET)
        if ack["status"] != P.CAL_OK:
            raise Rejected(f"mote {self.mote} refused the reset to version {version}: "
                           f"{P.cal_reason(ack['status'])}; version {ack['version']} stays in "
                           "force", ack["status"])
        if ack["version"] != version or ack["sensors"] != 0:
            raise UploadFailed(f"mote {self.mote} acknowledged the reset with version "
                               f"{ack['version']}, sensors {ack['sensors']}")
        self.progress.note(f"  reset: accepted, raw output, version {version} in force")
        back = self.read_set(expect_version=version)
        if back.calset.sensors:
            raise UploadFailed(f"mote {self.mote}: the set read back still corrects "
                               f"{', '.join(back.calset.sensors)}")
        self.progress.note(f"  read-back: raw set, version {back.version}")
        chk = self.check_samples(flags_for(version, 0), verify_wait)
        self._note_samples(chk)
        return Result(self.mote, version, back.crc, 0, previous, True, chk,
                      self.link.clock() - t0, self.link.stats)

    def _note_samples(self, chk: SampleCheck) -> None:
        if chk.seen:
            self.progress.note(f"  samples: {chk.checked} messages in a row flagged "
                               f"{describe_flags(chk.expected_flags)}"
                               + (f" (after {chk.stale} queued before the commit)"
                                  if chk.stale else ""))
        else:
            self.progress.note(f"  warning: {chk.note}")


def sensor_names(mask: int) -> str:
    names = [n for i, n in enumerate(P.SENSORS) if mask >> i & 1]
    return ", ".join(names) if names else "none (raw output)"


# --------------------------------------------------------------------------
# cal.json -> the set
# --------------------------------------------------------------------------
def _matrix(d, key, shape, where):
    try:
        a = np.array(d[key], dtype=np.float64)
    except KeyError:
        raise UserError(f"{where}: no {key!r}") from None
    except (TypeError, ValueError):
        raise UserError(f"{where}: {key!r} is not a list of numbers") from None
    if a.shape != shape:
        raise UserError(f"{where}: {key!r} must be {'x'.join(map(str, shape))}, not "
                        f"{'x'.join(map(str, a.shape)) or 'a number'}")
    if not np.all(np.isfinite(a)):
        raise UserError(f"{where}: {key!r} holds a missing or infinite value")
    return a


@dataclass
class CalFile:
    """What upload needs of a cal.json: per sensor (A, c), the mote, the gate."""
    path: str
    mote: int
    physical: dict                     # sensor -> (A (3, 3), c (3,)) in its unit
    session: str = ""
    gate: dict = field(default_factory=dict)

    @property
    def refused(self) -> bool:
        return bool(self.gate) and not self.gate.get("accepted", True)


def load_cal(path) -> CalFile:
    """Read and check a cal.json (the JSON of ``calib.result.BoardCalibration``).

    Only what upload needs must be there: ``format_version``, ``mote`` and,
    per calibrated sensor, ``A`` (3x3) and ``c`` (3); the messages name the
    field that is missing or wrong."""
    from .calib.result import FORMAT_VERSION
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as e:
        raise UserError(f"cannot read {path}: {e.strerror or e}") from None
    try:
        d = json.loads(text)
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise UserError(f"{path} is not JSON: {e}") from None
    if not isinstance(d, dict) or "format_version" not in d:
        raise UserError(f"{path} is not a motecal calibration (no format_version)")
    fv = d["format_version"]
    if isinstance(fv, bool) or not isinstance(fv, int) or fv > FORMAT_VERSION:
        raise UserError(f"{path}: calibration format_version {fv!r} is not one this motecal "
                        f"reads (1..{FORMAT_VERSION})")
    mote = d.get("mote")
    if isinstance(mote, bool) or not isinstance(mote, int) or \
            not MOTE_ID_MIN <= mote <= MOTE_ID_MAX:
        raise UserError(f"{path}: no mote id (\"mote\": an integer "
                        f"{MOTE_ID_MIN}..{MOTE_ID_MAX})")
    gate = d.get("gate") or {}
    if not isinstance(gate, dict):
        raise UserError(f"{path}: \"gate\" is not an object")
    return CalFile(str(path), mote, _physical(d, str(path)), str(d.get("session") or ""), gate)


def cal_from_board(board, where: str = "calibration") -> CalFile:
    d = board.to_json()
    return CalFile(where, int(board.mote), _physical(d, where), board.session,
                   dict(board.gate or {}))


def _physical(d: dict, where: str) -> dict:
    physical = {}
    for name in P.SENSORS:
        s = d.get(name)
        if not s:
            continue
        if not isinstance(s, dict):
            raise UserError(f"{where}: {name} is not an object")
        A = _matrix(s, "A", (3, 3), f"{where}: {name}")
        c = _matrix(s, "c", (3,), f"{where}: {name}")
        physical[name] = (A, c)
    if not physical:
        raise UserError(f"{where}: no calibrated sensor (accel, gyro or mag with A and c): "
                        "nothing to upload")
    return physical


def build_set(cal: CalFile, mote: int, version: int) -> tuple[bytes, dict]:
    """The set's bytes and fixedpoint's rounding report per sensor."""
    for name, (A, c) in cal.physical.items():
        try:
            FP.fixed_from_physical(name, A, c)
        except FP.NotRepresentable as e:
            raise FP.NotRepresentable(f"{cal.path}: {name}: {e}") from None
    try:
        return FP.build_calset(mote, version, cal.physical)
    except ValueError as e:
        raise UserError(f"{cal.path}: {e}") from None


def mote_check(calset: bytes, mote: int) -> int | None:
    """The reason code the mote's own validation gives (tinyos/ninedof_cal.c
    through ctypes), None when the C code cannot be built here."""
    try:
        from . import mote_c
        return mote_c.validate(calset, mote)
    except (UserError, OSError, ImportError):
        return None


def check_set(calset: bytes, mote: int, where: str) -> None:
    code = mote_check(calset, mote)
    if code not in (None, P.CAL_OK):
        raise QualityError(f"{where}: the mote would reject this calibration: "
                           f"{P.cal_reason(code)}")


# --------------------------------------------------------------------------
# Showing a set
# --------------------------------------------------------------------------
def _fmt_row(v, spec):
    return "[" + ", ".join(format(float(x), spec) for x in v) + "]"


def show_lines(inf: InForce, cal: CalFile | None = None) -> list[str]:
    """The set in force, decoded, in physical units."""
    cs = inf.calset
    lines = [f"mote {inf.mote}: calibration version {inf.version} in force "
             f"(CRC 0x{inf.crc:04x}), corrected: {sensor_names(cs.mask)}"]
    if cs.mote != inf.mote:
        lines.append(f"  (the set names mote {cs.mote})")
    for name in P.SENSORS:
        fs = cs.sensors.get(name)
        if fs is None:
            lines.append(f"  {name}: raw")
            continue
        k, unit = NOMINAL_SCALES[name], UNITS[name]
        A, c = fs.matrix / k, fs.offset / k
        lines.append(f"  {name} (Q{fs.shift}): calibrated [{unit}] = A @ raw [counts] + c")
        for i in range(3):
            lines.append(f"    A[{i}] = {_fmt_row(A[i], '+.6e')}")
        lines.append(f"    c    = {_fmt_row(c, '+.6f')} {unit}"
                     f"  (= {_fmt_row(fs.offset, '+.2f')} counts)")
        per = f"({unit})" if "/" in unit else unit
        lines.append(f"    scale {_fmt_row(np.diag(fs.matrix), '.5f')} x nominal "
                     f"{k:g} LSB/{per}")
    if cal is not None:
        mine, _ = build_set(cal, inf.mote, inf.version if inf.version else 1)
        same = inf.version and mine == inf.data
        lines.append(f"  {'equals' if same else 'differs from'} {cal.path} "
                     f"(quantised for mote {inf.mote}, version {inf.version})")
    return lines


def dry_run_lines(cal: CalFile, mote: int, version: int | None) -> list[str]:
    v = version or 1
    calset, report = build_set(cal, mote, v)
    lines = [f"{cal.path}: mote {cal.mote}" + (f", session {cal.session}" if cal.session else "")
             + (", refused by the quality gate" if cal.refused else "")]
    lines.append(f"set for mote {mote}, version {v}"
                 + ("" if version else " (at upload: the version in force + 1)")
                 + f": {len(calset)} bytes in {len(fragments(calset))} fragments, "
                   f"CRC 0x{P.crc16(calset):04x}")
    lines += FP.format_report(report)
    code = mote_check(calset, mote)
    if code is None:
        lines.append("the mote's checks: not run (no C compiler for tinyos/ninedof_cal.c)")
    elif code == P.CAL_OK:
        lines.append("the mote's checks (tinyos/ninedof_cal.c): accepted")
    else:
        lines.append(f"the mote's checks (tinyos/ninedof_cal.c): would reject: "
                     f"{P.cal_reason(code)}")
    return lines


# --------------------------------------------------------------------------
# What the commands run
# --------------------------------------------------------------------------
@dataclass
class Options:
    timeout: float = DEFAULT_TIMEOUT
    retries: int = DEFAULT_RETRIES
    version: int | None = None
    verify_wait: float = VERIFY_WAIT
    force: bool = False


def check_cal(cal: CalFile, mote: int, opts: Options) -> None:
    """Before any port is opened: the gate's verdict, and a set that is
    representable and that the mote's own checks accept (whatever the version)."""
    if cal.refused and not opts.force:
        raise QualityError(f"{cal.path} was refused by the quality gate ("
                           + "; ".join(cal.gate.get("reasons", [])) + "); --force uploads "
                           "it anyway")
    check_set(build_set(cal, mote, opts.version or 1)[0], mote, cal.path)


def upload_cal(source: S.Source, cal: CalFile, mote: int, opts: Options = Options(),
               progress=None) -> Result:
    """The whole checked upload of a cal.json's calibration over an open source."""
    check_cal(cal, mote, opts)
    progress = progress or make_progress()
    link = Link(source, timeout=opts.timeout, retries=opts.retries, progress=progress)
    up = Uploader(link, mote, progress)
    try:
        t0 = link.clock()
        old = up.in_force()
        version = opts.version or next_version(old.version)
        calset, _ = build_set(cal, mote, version)
        progress.note(f"mote {mote}: version {old.version} in force (CRC 0x{old.crc:04x}); "
                      f"uploading version {version} ({len(calset)} bytes, "
                      f"{len(fragments(calset))} fragments, CRC 0x{P.crc16(calset):04x})")
        res = up.upload(calset, old.version, opts.verify_wait)
        res.seconds = link.clock() - t0
    finally:
        progress.close()
    return res


def summary(res: Result, what: str = "calibration") -> str:
    st = res.stats
    return (f"mote {res.mote}: {what} version {res.version} in force and verified "
            f"(was {res.previous}); {st.messages} messages, {st.retries} repeated, "
            f"{st.serial_retries} serial repeats, {res.seconds:.2f} s")


def _open(spec: S.PortSpec) -> S.Source:
    if spec.kind == "file":
        raise UserError(f"{spec} is a recorded file: upload needs a live port (device, "
                        "pyserial URL, serial@DEV:BAUD or sf@HOST:PORT)")
    return S.open_source(spec)


# --------------------------------------------------------------------------
# Command line
# --------------------------------------------------------------------------
def register(sub) -> None:
    p = sub.add_parser(
        "upload", help="send a calibration to a mote (fixed point, verified)",
        description="Send a calibration (cal.json from motecal calibrate) through the "
                    "BaseStation to a mote, which then corrects its samples itself; "
                    "verified by reading the set back and by the flags of the next samples.")
    p.add_argument("cal", nargs="?", metavar="cal.json", help="calibration file")
    p.add_argument("--port", help="the BaseStation: device, pyserial URL, serial@DEV:BAUD "
                                  "or sf@HOST:PORT; default $MOTECOM")
    p.add_argument("--baud", type=baud_rate, help="baud rate (default 250000)")
    p.add_argument("--mote", type=mote_id, help="target mote (default: the mote of cal.json)")
    p.add_argument("--version", type=int_range("version", 1, MAX_VERSION),
                   help="version of the new set, 1..65535 (default: the one in force + 1)")
    mode = p.add_mutually_exclusive_group()
    mode.add_argument("--dry-run", action="store_true",
                      help="print the fixed-point values and their rounding error; no port")
    mode.add_argument("--reset", action="store_true", help="put the mote back to raw output")
    mode.add_argument("--show", action="store_true",
                      help="read back and print the set in force (with cal.json: compare)")
    p.add_argument("--timeout", type=positive(float), default=DEFAULT_TIMEOUT,
                   help=f"seconds to wait for each reply of the mote ({DEFAULT_TIMEOUT:g})")
    p.add_argument("--retries", type=int_range("whole number", 0), default=DEFAULT_RETRIES,
                   help=f"repeats of a message that gets no reply ({DEFAULT_RETRIES})")
    p.add_argument("--force", action="store_true",
                   help="upload a calibration the quality gate refused")
    p.set_defaults(func=run)


def run(args) -> int:
    cal = load_cal(args.cal) if args.cal else None
    if cal is None and not (args.reset or args.show):
        raise UserError("give a calibration file (cal.json), or --reset / --show")
    if cal is not None and args.reset:
        raise UserError("--reset takes no calibration file")
    mote = args.mote if args.mote is not None else (cal.mote if cal else None)
    if mote is None:
        raise UserError("--mote is needed with --reset and --show")
    if cal is not None and cal.mote != mote and not args.show:
        raise UserError(f"{cal.path} calibrates the board of mote {cal.mote}, not mote {mote} "
                        f"(use that mote's cal.json, or --mote {cal.mote})")
    if args.dry_run:
        for line in dry_run_lines(cal, mote, args.version):
            print(line)
        sys.stdout.flush()
        check_set(build_set(cal, mote, args.version or 1)[0], mote, cal.path)
        return 0
    opts = Options(timeout=args.timeout, retries=args.retries, version=args.version,
                   force=args.force)
    if not (args.show or args.reset):
        check_cal(cal, mote, opts)
    spec = S.parse_port(args.port, args.baud)
    with _open(spec) as source:
        if args.show:
            return _show(source, mote, cal, opts)
        if args.reset:
            return _reset(source, mote, opts)
        res = upload_cal(source, cal, mote, opts)
    print(summary(res))
    return 0


def _show(source, mote, cal, opts) -> int:
    link = Link(source, timeout=opts.timeout, retries=opts.retries,
                progress=PlainProgress(steps=False))     # only the repeats, then the set
    up = Uploader(link, mote)
    inf = up.read_set()
    for line in show_lines(inf, cal):
        print(line)
    return 0


def _reset(source, mote, opts) -> int:
    progress = make_progress()
    link = Link(source, timeout=opts.timeout, retries=opts.retries, progress=progress)
    up = Uploader(link, mote, progress)
    try:
        t0 = link.clock()
        old = up.in_force()
        version = opts.version or next_version(old.version)
        progress.note(f"mote {mote}: version {old.version} in force; reset to raw output, "
                      f"version {version}")
        res = up.reset(version, old.version, opts.verify_wait)
        res.seconds = link.clock() - t0
    finally:
        progress.close()
    print(summary(res, "raw output"))
    return 0


# --------------------------------------------------------------------------
# The one-step form: motecal calibrate ... --upload --port URL --mote ID
# --------------------------------------------------------------------------
def add_calibrate_options(parser) -> None:
    """``--upload``, ``--port``, ``--baud`` for ``motecal calibrate``."""
    g = parser.add_argument_group("upload (one step: calibrate, gate, upload, verify)")
    g.add_argument("--upload", action="store_true",
                   help="send each accepted calibration to its mote and verify it")
    g.add_argument("--port", help="with --upload: the BaseStation (device, pyserial URL, "
                                  "serial@DEV:BAUD, sf@HOST:PORT); default $MOTECOM")
    g.add_argument("--baud", type=baud_rate, help="with --upload: baud rate (250000)")


def calibrate_step(args):
    """For ``motecal calibrate``: None without ``--upload``, else a function
    ``step(board, path)`` that uploads a delivered calibration to its mote and
    verifies it.  The port is checked here, before calibrating."""
    if not getattr(args, "upload", False):
        if getattr(args, "port", None) or getattr(args, "baud", None):
            raise UserError("--port and --baud go with --upload")
        return None
    spec = S.parse_port(args.port, args.baud)
    if spec.kind == "file":
        _open(spec)
    opts = Options(force=bool(getattr(args, "force", False)))

    def step(board, path=None) -> Result:
        where = str(path) if path else f"mote {board.mote}"
        try:
            cal = cal_from_board(board, where)
            check_cal(cal, cal.mote, opts)
            print(f"  uploading to mote {board.mote} through {spec}", flush=True)
            with _open(spec) as source:
                res = upload_cal(source, cal, cal.mote, opts)
        except UserError as e:              # same exit status, saying what was done
            raise UserError(f"calibration saved ({where}), not uploaded: {e}",
                            exit_code=e.exit_code) from None
        print("  " + summary(res), flush=True)
        return res

    return step
