"""The link to one mote for the upload: each message in a 0x44 frame with the
BaseStation's serial ack (0x43), the mote's reply waited for and the message
repeated when none comes, and the mote's sample flags remembered for the
verification (see ``uploader`` for the protocol).
"""
from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass

from ..errors import UserError
from ..line import protocol as P
from ..line import sources as S

DEFAULT_TIMEOUT = 0.3        # s: a mote's reply, counted from the BaseStation's serial ack
DEFAULT_RETRIES = 20         # repeats of one message after the first try
SERIAL_ACK_TIMEOUT = 0.25    # s: the BaseStation's 0x43 for one 0x44 frame
SERIAL_RETRIES = 3
SAMPLE_LOG = 4096            # sample messages remembered for the verification


class UploadFailed(UserError):
    """The upload did not complete: no answer, rejected, or not verified."""

    exit_code = 1


class NoAnswer(UploadFailed):
    pass


class PortLost(UploadFailed):
    """The port went away (unplugged, the connection closed or taken over)."""


class Rejected(UploadFailed):
    """The mote answered with a reason code other than NINEDOF_CAL_OK."""

    def __init__(self, message: str, status: int):
        super().__init__(message)
        self.status = status



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
            raise PortLost(f"lost the port {self.source.spec}: {e}") from None
        except S.SourceEnded:
            raise PortLost(f"{self.source.spec} ended") from None
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

    def wait(self, seconds: float) -> None:
        """Read on (replies, sample flags) for ``seconds`` of the link's clock."""
        end = self.clock() + seconds
        while self.clock() < end:
            self.pump()

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
            raise PortLost(f"lost the port {self.source.spec}: {e}") from None

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
