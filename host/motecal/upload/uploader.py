"""The upload protocol: a calibration (cal.json) to a mote, through the
BaseStation and the radio, then verified (the command is
``motecal.commands.upload``).

Protocol (messages of ``tinyos/NineDofMsg.h``), one message at a time:

1. CAL_QUERY offset 0 -> CAL_REPORT: the version in force; the new set gets
   that + 1 (65535 -> 1) unless ``--version``.
2. The set (``fixedpoint.build_calset``, 102 bytes, or 164 with temperature
   terms) in fragments of NINEDOF_FRAG_DATA (20) bytes: CAL_FRAG ->
   CAL_FRAG_ACK (status) each.  An image built before the temperature terms
   refuses a fragment past byte 102 (NINEDOF_CAL_E_FRAG): ``NoTemperature``
   says so, and ``--no-temp`` sends the plain set instead.
3. CAL_COMMIT (APPLY, length, CRC-16 of the set) -> CAL_COMMIT_ACK (status,
   the CRC the mote computed, the version in force, sensors corrected).
4. Read-back: CAL_QUERY offsets 0, 20, .. -> CAL_REPORTs (the first one's
   format byte gives the set's length); the set in force must equal the set
   sent byte for byte.
5. The mote's next sample messages must carry the corrected flag and the
   version's low 4 bits.
6. Stored: CAL_QUERY (with QUERY_STORED) -> CAL_REPORT every STORE_POLL s
   until the report's stored set (what the mote's EEPROM holds, written and
   read back: what a reset or power loss puts in force) is the new set, for
   at most ``Options.store_timeout`` s; only then does the upload succeed.
   An image built before the stored-set report answers without it: the
   upload waits OLD_IMAGE_WAIT s (longer than its EEPROM write) and says
   that storage was not reported.

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
"""
from __future__ import annotations

import contextlib
from dataclasses import dataclass, field

from ..errors import QualityError, UserError
from ..firmware import fixedpoint as FP
from ..line import protocol as P
from ..line import sources as S
from .calfile import CalFile, build_set, check_set
from .link import (DEFAULT_RETRIES, DEFAULT_TIMEOUT, Link, LinkStats, NoAnswer, NullProgress,
                   PortLost, Rejected, UploadFailed)

VERIFY_WAIT = 2.0            # s: for the mote's sample messages after the commit
VERIFY_MESSAGES = 3          # consecutive sample messages with the new flags
VERIFY_STALE_MAX = 12        # old-flag messages tolerated first (queued before the commit)
OTHER_VERSION_REPORTS = 2    # read-back reports of another version tolerated (late replies)
# The EEPROM write: one byte per 4 ms tick, an image of up to 170 bytes
# (164-byte set + 6), read back, written again if wrong (3 tries): 0.7 s
# once, about 2 s at most on the mote's clock.  The wait counts the host's
# clock: the emulator on a busy machine runs at 0.2x real time (the release
# check's slowest mote reported its set stored 3.5 s after the commit), so
# the default leaves room for that; a write that fails is reported at once.
STORE_WAIT = 10.0            # s: for the set to be stored (--store-timeout)
STORE_POLL = 0.1             # s between queries of the stored set
OLD_IMAGE_WAIT = 1.0         # s: an image that does not report it (one write: <= 0.7 s)
MAX_VERSION = 0xFFFF
E_FRAG = next(c for c, (n, _) in P.CAL_REASONS.items() if n == "NINEDOF_CAL_E_FRAG")


def next_version(in_force: int) -> int:
    """The version after ``in_force``: +1, 65535 wraps to 1 (0 is never valid)."""
    return in_force % MAX_VERSION + 1


def choose_version(mote: int, in_force: int, opts: "Options") -> int:
    """The version of a new set: ``opts.version``, or the one in force + 1.
    Versions strictly increase (but for the wrap 65535 -> 1 of the default):
    a given version not above the one in force is refused unless
    ``opts.force`` -- two sets under one version could not be told apart by
    the samples' flags or by --show."""
    if opts.version is None:
        return next_version(in_force)
    if opts.version <= in_force and not opts.force:
        raise UserError(f"mote {mote} has version {in_force} in force: --version "
                        f"{opts.version} is not newer (versions strictly increase; "
                        "--force sends it anyway)")
    return opts.version


class NotStored(UploadFailed):
    """The set is in force, but the mote did not report it stored in its
    EEPROM: a reset or power loss brings back the set stored before."""


class CommittedNotFinished(UploadFailed):
    """The mote acknowledged the new set in force, then the upload could not
    finish (the port lost, no answer, a read-back or sample check failed):
    the set is in force as far as the host knows, neither verified nor known
    to be stored.  Exit 1, and the message says so."""


class InForceChanged(UploadFailed):
    """After the commit another set turned out to be in force (the mote
    restarted): the message names what is in force."""


class NoTemperature(Rejected):
    """The mote's image predates the temperature terms (it refused bytes
    past the plain set)."""


def fragments(calset: bytes) -> list[tuple[int, bytes]]:
    """(offset, bytes) pieces of NINEDOF_FRAG_DATA bytes."""
    n = P.NINEDOF_FRAG_DATA
    return [(off, bytes(calset[off:off + n])) for off in range(0, len(calset), n)]



# --------------------------------------------------------------------------
# The protocol steps
# --------------------------------------------------------------------------
@dataclass
class InForce:
    """What a mote has in force (from CAL_REPORTs), and what its EEPROM holds."""
    mote: int
    version: int
    crc: int
    data: bytes | None = None          # the whole set, when read
    stored_version: int | None = None  # the stored set (0: none); None: not reported
    stored_crc: int | None = None
    store: int | None = None           # the EEPROM writer's state (P.STORE_*)

    @classmethod
    def of(cls, mote: int, report: dict, data: bytes | None = None) -> "InForce":
        return cls(mote, report["version"], report["crc"], data,
                   report.get("stored_version"), report.get("stored_crc"),
                   report.get("store"))

    @property
    def calset(self) -> FP.Calset | None:
        return FP.unpack_calset(self.data) if self.data is not None else None

    @property
    def reports_stored(self) -> bool:
        """The image reports its stored set (built with the stored-set report)."""
        return self.stored_version is not None

    @property
    def stored(self) -> bool:
        """The set in force is the set stored: a reset keeps it.  Raw output,
        version 0 (what a mote has at boot with no valid set) needs nothing
        stored: a reset gives it again."""
        if not self.reports_stored:
            return False
        if self.version == 0 and self.stored_version == 0:
            return True
        return (self.stored_version, self.stored_crc) == (self.version, self.crc)


def stored_text(version: int | None) -> str:
    """What a reset brings back, for messages."""
    if version is None:
        return "the set stored before"
    return f"version {version}" if version else "no stored set (raw output, version 0)"


@dataclass
class StoreCheck:
    """The wait for the new set to be stored (step 6)."""
    reported: bool                     # the image reports its stored set
    seconds: float = 0.0               # from the commit to the report saying stored
    waited: float = 0.0                # the wait itself
    polls: int = 0


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
    stored: StoreCheck | None = None


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
        """One CAL_REPORT; it has the stored_* keys when the image reports them."""
        return self.link.request(P.CAL_QUERY, P.AM_NINEDOF_CAL_REPORT_MSG,
                                 what or f"the query at offset {offset}",
                                 match=lambda m: m["offset"] == offset and match(m),
                                 mote=self.mote, offset=offset, flags=P.QUERY_STORED)

    def in_force(self) -> InForce:
        return InForce.of(self.mote, self.query(0, "the query of the version in force"))

    def read_set(self, expect_version: int | None = None, attempts: int = 3) -> InForce:
        """The whole set in force, CAL_REPORT by CAL_REPORT, checked against its CRC.

        ``expect_version``: only reports of that version count (a late one of
        another version is asked again, OTHER_VERSION_REPORTS times; then the
        mote has another set in force, and UploadFailed says so).
        """
        def pick(off, what):
            """The report at ``off``; one of another version than expected is
            a late reply of an earlier query, or, again and again, a mote that
            restarted: then it fails at once, saying so."""
            for _ in range(1 + OTHER_VERSION_REPORTS):
                r = self.query(off, what)
                if expect_version is None or r["version"] == expect_version:
                    return r
            raise InForceChanged(
                f"mote {self.mote} reports version {r['version']} (CRC 0x{r['crc']:04x}) in "
                f"force, not version {expect_version} (did it restart?); its EEPROM holds "
                f"{stored_text(r.get('stored_version'))}")

        for _ in range(attempts):
            data = bytearray()
            head = None
            first = last = pick(0, "read-back 1 (offset 0)")
            # the set's format byte (header byte 5) gives its length
            size = P.CALSET_SIZES.get(first["data"][5]) if first["len"] > 5 else None
            if size is None:
                raise UploadFailed(f"mote {self.mote} reports a set of format "
                                   f"{first['data'][5] if first['len'] > 5 else '?'}: not a "
                                   f"set this motecal knows ({P.CALSET_SIZE} or "
                                   f"{P.CALSET_TEMP_SIZE} bytes)")
            pieces = fragments(bytes(size))
            self.progress.task("read-back", len(pieces))
            for i, (off, chunk) in enumerate(pieces):
                r = first if off == 0 else \
                    pick(off, f"read-back {i + 1}/{len(pieces)} (offset {off})")
                last = r
                if r["len"] != len(chunk):
                    raise UploadFailed(f"mote {self.mote} reports {r['len']} bytes at offset "
                                       f"{off}, expected {len(chunk)}: not this protocol's "
                                       f"{size}-byte set")
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
                return InForce.of(self.mote, last, bytes(data))
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
            if ack["status"] == E_FRAG and off + len(chunk) > P.CALSET_SIZE \
                    and len(calset) > P.CALSET_SIZE:
                raise NoTemperature(f"mote {self.mote} refused the temperature terms (its "
                                    f"firmware takes no set longer than {P.CALSET_SIZE} bytes: "
                                    "an image without on-mote temperature correction); the set "
                                    "in force is unchanged; `motecal upload --no-temp` uploads "
                                    "the calibration without them", ack["status"])
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

    def apply(self, version: int, crc: int, length: int = P.CALSET_SIZE) -> dict:
        """Commit the staged set (``length`` bytes); Rejected (with the mote's
        reason) unless it is now in force with our CRC."""
        ack = self.commit(version, crc, length)
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

    def wait_stored(self, version: int, crc: int, timeout: float = STORE_WAIT,
                    since: float | None = None) -> StoreCheck:
        """Step 6: query until the mote reports the set (``version``, ``crc``)
        stored in its EEPROM, for at most ``timeout`` s (``since``: the
        commit's time, for the figure printed).  NotStored when its write
        failed or did not complete in time, UploadFailed when another set is
        in force by then (the mote restarted?).  An image that does not report
        its stored set: waits OLD_IMAGE_WAIT s and returns ``reported`` False."""
        clock = self.link.clock
        t0 = clock()
        since = t0 if since is None else since
        deadline = t0 + timeout
        chk = StoreCheck(True)
        while True:
            inf = InForce.of(self.mote, self.query(0, "the query of the stored set"))
            chk.polls += 1
            if not inf.reports_stored:
                self.link.wait(OLD_IMAGE_WAIT)
                chk.reported, chk.waited = False, clock() - t0
                self.progress.note(
                    f"  stored: not reported by mote {self.mote}'s firmware (an image built "
                    f"before the stored-set report); waited {OLD_IMAGE_WAIT:g} s, longer than "
                    "its EEPROM write")
                return chk
            if (inf.version, inf.crc) != (version, crc):
                raise InForceChanged(
                    f"mote {self.mote} has version {inf.version} (CRC 0x{inf.crc:04x}) in force "
                    f"now, not version {version}: did it restart before version {version} was "
                    f"stored? Its EEPROM holds {stored_text(inf.stored_version)}")
            if inf.stored:
                chk.seconds, chk.waited = clock() - since, clock() - t0
                self.progress.note(f"  stored: version {version} written to the EEPROM and "
                                   f"read back, {chk.seconds:.2f} s after the commit; a reset "
                                   "keeps it")
                return chk
            if inf.store == P.STORE_FAILED:
                raise NotStored(
                    f"mote {self.mote}: version {version} is in force and verified but not "
                    f"stored: its EEPROM did not read back what was written; after a reset or "
                    f"power loss it comes back with {stored_text(inf.stored_version)} "
                    "(a failing EEPROM?)")
            if clock() >= deadline:
                raise NotStored(
                    f"mote {self.mote}: version {version} is in force and verified but not "
                    f"stored: its EEPROM write did not complete within {timeout:g} s; after a "
                    f"reset or power loss it comes back with "
                    f"{stored_text(inf.stored_version)}; keep it powered, then check with "
                    "`motecal upload --show`")
            self.link.wait(min(STORE_POLL, max(0.0, deadline - clock())))

    # -- the checked paths ------------------------------------------------------
    def upload(self, calset: bytes, previous: int, verify_wait: float = VERIFY_WAIT,
               store_wait: float = STORE_WAIT) -> Result:
        """Stage, commit, read back, check the samples and wait until the set
        is stored; raises on any failure."""
        t0 = self.link.clock()
        cs = FP.unpack_calset(calset)
        crc = P.crc16(calset)
        self.stage(calset, cs.version)
        t_commit = self.link.clock()
        try:
            ack = self.apply(cs.version, crc, len(calset))
        except NoAnswer as e:
            ack = self._after_lost_ack(e, cs.version, crc, lambda back: back.data == calset,
                                       cs.mask)
        except PortLost as e:
            raise self._unknown(cs.version, e) from None
        with self._in_force(cs.version, "calibration"):     # from here the set is in force
            back = self.read_set(expect_version=cs.version)
            if back.data != calset:
                n = min(len(back.data), len(calset))
                i = next((k for k in range(n) if back.data[k] != calset[k]), n)
                raise UploadFailed(f"the set read back ({len(back.data)} bytes) differs from "
                                   f"the set sent ({len(calset)} bytes; first at byte {i})")
            self.progress.note(f"  read-back: {len(calset)} bytes identical, "
                               f"CRC 0x{back.crc:04x}")
            chk = self.check_samples(flags_for(cs.version, cs.mask), verify_wait)
            self._note_samples(chk)
            stored = self.wait_stored(cs.version, crc, store_wait, since=t_commit)
        return Result(self.mote, cs.version, crc, ack["sensors"], previous, True, chk,
                      self.link.clock() - t0, self.link.stats, stored)

    def _unknown(self, version: int, e: Exception) -> UploadFailed:
        """The port went away after the commit was sent, before its ack."""
        return UploadFailed(f"mote {self.mote}: the commit of version {version} was sent, then "
                            f"{e}: whether version {version} is in force is unknown (check with "
                            "`motecal upload --show`)")

    @contextlib.contextmanager
    def _in_force(self, version: int, what: str):
        """The steps after a commit the mote acknowledged: a failure there
        says that the mote acknowledged ``version`` in force, and that it is
        neither verified nor known to be stored (``CommittedNotFinished``),
        unless its message already says what is in force (``NotStored``,
        ``InForceChanged``)."""
        try:
            yield
        except (NotStored, InForceChanged):
            raise
        except UploadFailed as e:
            raise CommittedNotFinished(
                f"mote {self.mote} acknowledged {what} version {version} in force, but the "
                f"upload did not finish: {e}; version {version} is not verified and not known "
                "to be stored (a reset may bring back the set stored before): check with "
                "`motecal upload --show`") from None

    def reset(self, version: int, previous: int, verify_wait: float = VERIFY_WAIT,
              store_wait: float = STORE_WAIT) -> Result:
        """Back to raw output with ``version``; verified and stored like an upload."""
        t0 = self.link.clock()
        try:
            ack = self.commit(version, 0, action=P.CAL_RESET)
        except NoAnswer as e:
            ack = self._after_lost_ack(e, version, 0, lambda back: back.version == version
                                       and not back.calset.sensors, 0)
        except PortLost as e:
            raise self._unknown(version, e) from None
        if ack["status"] != P.CAL_OK:
            raise Rejected(f"mote {self.mote} refused the reset to version {version}: "
                           f"{P.cal_reason(ack['status'])}; version {ack['version']} stays in "
                           "force", ack["status"])
        if ack["version"] != version or ack["sensors"] != 0:
            raise UploadFailed(f"mote {self.mote} acknowledged the reset with version "
                               f"{ack['version']}, sensors {ack['sensors']}")
        self.progress.note(f"  reset: accepted, raw output, version {version} in force")
        with self._in_force(version, "raw output"):
            back = self.read_set(expect_version=version)
            if back.calset.sensors:
                raise UploadFailed(f"the set read back still corrects "
                                   f"{', '.join(back.calset.sensors)}")
            self.progress.note(f"  read-back: raw set, version {back.version}")
            chk = self.check_samples(flags_for(version, 0), verify_wait)
            self._note_samples(chk)
            stored = self.wait_stored(version, back.crc, store_wait, since=t0)
        return Result(self.mote, version, back.crc, 0, previous, True, chk,
                      self.link.clock() - t0, self.link.stats, stored)

    def _after_lost_ack(self, error: NoAnswer, version: int, crc: int, took, sensors: int):
        """No commit ack came (every repeat lost): the mote may have applied the
        set all the same.  The read-back decides what is reported -- the new
        set in force: go on as if acknowledged; the old one: nothing changed;
        no read-back: the state is unknown, and the message says so."""
        self.progress.note("  no commit ack: reading back what the mote has in force")
        try:
            back = self.read_set()
        except UploadFailed as e2:
            raise UploadFailed(f"{error}; reading back what is in force failed too ({e2}): "
                               f"whether version {version} is in force on mote {self.mote} "
                               "is unknown (motecal upload --show tells)") from None
        if took(back):
            self.progress.note(f"  commit ack lost, but the read-back shows version {version} "
                               f"in force (CRC 0x{back.crc:04x}): the commit took effect")
            return {"status": P.CAL_OK, "crc": back.crc if crc == 0 else crc,
                    "version": version, "sensors": sensors}
        raise UploadFailed(f"mote {self.mote} did not acknowledge the commit of version "
                           f"{version}, and the read-back shows version {back.version} "
                           f"(CRC 0x{back.crc:04x}) in force: the new set was not applied")

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
# What the commands run
# --------------------------------------------------------------------------
@dataclass
class Options:
    timeout: float = DEFAULT_TIMEOUT
    retries: int = DEFAULT_RETRIES
    version: int | None = None
    verify_wait: float = VERIFY_WAIT
    store_wait: float = STORE_WAIT     # --store-timeout
    force: bool = False
    temperature: bool = True           # False (--no-temp): the plain set, no temperature terms


def check_cal(cal: CalFile, mote: int, opts: Options) -> None:
    """Before any port is opened: the gate's verdict, and a set that is
    representable and that the mote's own checks accept (whatever the version)."""
    if cal.refused and not opts.force:
        raise QualityError(f"{cal.path} was refused by the quality gate ("
                           + "; ".join(cal.gate.get("reasons", [])) + "); --force uploads "
                           "it anyway")
    check_set(build_set(cal, mote, opts.version or 1, opts.temperature)[0], mote, cal.path)


def upload_cal(source: S.Source, cal: CalFile, mote: int, opts: Options = Options(),
               progress=None) -> Result:
    """The whole checked upload of a cal.json's calibration over an open source."""
    check_cal(cal, mote, opts)
    progress = progress or NullProgress()
    link = Link(source, timeout=opts.timeout, retries=opts.retries, progress=progress)
    up = Uploader(link, mote, progress)
    try:
        t0 = link.clock()
        old = up.in_force()
        version = choose_version(mote, old.version, opts)
        calset, _ = build_set(cal, mote, version, opts.temperature)
        temp = FP.unpack_calset(calset).temps
        progress.note(f"mote {mote}: version {old.version} in force (CRC 0x{old.crc:04x}); "
                      f"uploading version {version} ({len(calset)} bytes, "
                      f"{len(fragments(calset))} fragments, CRC 0x{P.crc16(calset):04x}"
                      + (f"; temperature terms: {', '.join(temp)}" if temp else "") + ")")
        res = up.upload(calset, old.version, opts.verify_wait, opts.store_wait)
        res.seconds = link.clock() - t0
    finally:
        progress.close()
    return res


def summary(res: Result, what: str = "calibration") -> str:
    """The last line: in force (verified), and stored (survives a reboot),
    or that the mote's firmware does not report it."""
    st = res.stats
    if res.stored is None or res.stored.reported:
        stored = "and stored (survives a reboot)"
    else:
        stored = (f"stored: not reported by its firmware (waited {res.stored.waited:.1f} s, "
                  "longer than its EEPROM write)")
    return (f"mote {res.mote}: {what} version {res.version} (was {res.previous}) in force and "
            f"verified, {stored}; {st.messages} messages, {st.retries} repeated, "
            f"{st.serial_retries} serial repeats, {res.seconds:.2f} s")
