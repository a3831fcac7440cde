"""Sequence numbers and link statistics per mote: what the logger's
``LinkTracker`` makes of decoded sample messages (gaps = lost samples,
duplicates dropped, late ones filling gaps counted as reordered, restarts)
and of the motes' and BaseStation's status messages.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..line import protocol as P
from ..line.samples import SampleBatch
from ..sessions.store_schema import LINE_COUNTERS, LINK_COUNTERS

REORDER_WINDOW = 2048        # samples back: further is a restart (or corruption)
MAX_JUMP = 1000              # samples ahead (8 s): further is held until confirmed
CONFIRM_GAP = 64             # the next frame may follow a suspect one this far on
TEMP_WAIT_MAX = 64           # temperature readings kept until a mote's first samples


# The mote status message's fields -> link counters (link_stats columns,
# sessions.store.LINK_COUNTERS): each field as "mote_" + its name, but the
# set in force's two and the fields that are no counters.  A field appended
# to the message (docs/CONTRIBUTING.md, "How to add a status field") needs
# no change here, only its column; test_status_counters.py checks that
# every field has one.
STATUS_RENAMED = {"version": "cal_version", "sensors": "cal_sensors"}
STATUS_NOT_COUNTERS = ("seq", "reserved")


def status_counter(field: str) -> str | None:
    """The link counter a status message field goes to (None: none)."""
    if field in STATUS_NOT_COUNTERS:
        return None
    return STATUS_RENAMED.get(field, "mote_" + field)


def _wrapdiff(a, b):
    """a - b in 16-bit sequence space, in -32768..32767."""
    return (np.asarray(a, np.int64) - b + 32768) % 65536 - 32768


class MoteLink:
    """Sequence state and counters of one mote.

    Sequence numbers are unwrapped (continued past 65535) so that ordering
    survives the wrap.  ``end`` is one past the highest record seen; records
    beyond it leave a hole (lost); a late record inside a hole fills it
    (reordered, no longer lost); one seen before is a duplicate (dropped).

    A frame that does not fit -- a mote's first frame, a jump of more than
    ``MAX_JUMP`` samples ahead, more than ``REORDER_WINDOW`` back, or a frame
    at sequence numbers already received whose records differ from the ones
    received there -- is held as *suspect* until the mote's next frame: if
    that one continues it, the suspect is released (a long gap, or a mote
    that restarted, whose numbering is then continued after ``end``);
    otherwise it is rejected.  A frame corrupted in a way CRC-16 missed (1 in
    65536) then cannot derail the numbering or invent a mote.

    A real duplicate (a radio retransmission the BaseStation forwarded twice)
    carries the very records received before; a mote that rebooted starts
    again from 0 with new ones.  The last ``REORDER_WINDOW`` records are kept
    to tell the two apart, so a reboot is detected even when the mote had
    sent fewer than ``REORDER_WINDOW`` samples (or its sequence number, mod
    65536, was that small) -- the numbering cannot tell then.

    A link resumed from an earlier run (``last_seq``, ``motecal log --append``)
    takes its first frame as the new start: what the mote sent while nobody
    was logging is not link loss.  Its numbering continues after the stored
    records, congruent to the mote's 16-bit sequence number.
    """

    def __init__(self, mote: int, counters: dict | None = None, last_seq: int | None = None):
        self.mote = mote
        self.c = {k: 0 for k in LINK_COUNTERS}
        self.c.update(counters or {})
        self.last16 = None
        self.last_u = self.end = 0
        if last_seq is not None:
            self.last16 = last_seq & 0xFFFF
            self.last_u = last_seq
            self.end = last_seq + 1
        self.holes: list[list[int]] = []        # [lo, hi) ranges not received
        self.suspect = None                     # (u, count, seq16, payload, restart)
        self.resumed = last_seq is not None     # the next frame starts this run
        # the records of the last REORDER_WINDOW sequence numbers received
        self.recent = np.zeros((REORDER_WINDOW, 9), np.int16)
        self.recent_u = np.full(REORDER_WINDOW, -1, np.int64)
        # the board temperature (ninedof_mote_temp_msg): latest degrees C, messages
        # received, and readings waiting for the mote's first samples (to unwrap)
        self.temp_c: float | None = None
        self.temp_range: tuple[float, float] | None = None   # lowest, highest seen
        self.temp_msgs = 0
        self.temp_rejected = 0                  # readings whose seq fits no sample of the mote
        self._temp_wait: list[tuple[int, float, int]] = []

    def _remember(self, u: np.ndarray, rec: np.ndarray) -> None:
        if len(u) > REORDER_WINDOW:
            u, rec = u[-REORDER_WINDOW:], rec[-REORDER_WINDOW:]
        i = u % REORDER_WINDOW
        self.recent[i] = rec
        self.recent_u[i] = u

    def _differs(self, u: int, rec: np.ndarray) -> bool:
        """Records u.. of a frame differ from those received at the same
        sequence numbers (a new stream, not a duplicate)."""
        r = u + np.arange(len(rec))
        i = r % REORDER_WINDOW
        seen = (r < self.end) & (self.recent_u[i] == r)
        return bool(seen.any() and (self.recent[i[seen]] != rec[seen]).any())

    def _gap(self, lo: int, hi: int):
        self.c["lost"] += hi - lo
        self.holes.append([lo, hi])

    def _prune(self):
        if self.holes and self.holes[0][1] < self.end - REORDER_WINDOW:
            self.holes = [h for h in self.holes if h[1] >= self.end - REORDER_WINDOW]

    def accept(self, seq16: np.ndarray, count: np.ndarray, payload=None, records=None):
        """Per message: unwrapped first sequence number; per record of these
        messages: keep or not (None: keep all); and the suspect frames released
        now, as ``[(u, payload(i))]`` (``payload(i)`` is asked for when message
        i becomes suspect).  ``records``: the messages' records, in order
        (``(count.sum(), 9)``), to tell duplicates from a rebooted mote."""
        seq16 = np.asarray(seq16, np.int64)
        count = np.asarray(count, np.int64)
        self.c["frames"] += len(seq16)
        if self.resumed and len(seq16):
            self._resume(int(seq16[0]))
        if self.last16 is not None and self.suspect is None:
            prev = np.concatenate([[self.last16], seq16[:-1]])
            u = self.last_u + np.cumsum(_wrapdiff(seq16, prev))
            ends = u + count
            prev_end = np.maximum.accumulate(np.concatenate([[self.end], ends[:-1]]))
            jump = u - prev_end
            if ((jump >= 0) & (jump <= MAX_JUMP)).all():    # in order, perhaps with gaps
                for i in np.flatnonzero(jump > 0):
                    self._gap(int(prev_end[i]), int(u[i]))
                self.end = int(max(prev_end[-1], ends[-1]))
                self.last16, self.last_u = int(seq16[-1]), int(u[-1])
                self.c["samples"] += int(count.sum())
                self.c["last_seq"] = self.end - 1
                self._prune()
                if records is not None:
                    first = np.cumsum(count) - count
                    self._remember(np.repeat(u - first, count) + np.arange(len(records)),
                                   records)
                return u, None, []
        return self._accept_slow(seq16, count, payload, records)

    def _resume(self, s0: int) -> None:
        """First frame of a resumed run: its records follow on without a gap.
        (Whether the mote kept counting or restarted cannot be told from the
        16-bit number alone; either way the numbering stays unique.)"""
        self.resumed = False
        d = int(_wrapdiff(s0, self.last16))
        u0 = self.last_u + d if d >= 1 else self.end + (s0 - self.end) % 65536
        self.end = u0
        self.last_u, self.last16 = u0 - 1, (s0 - 1) & 0xFFFF

    def _take(self, u: int, c: int, s16: int, keep: list, rec=None) -> None:
        """Records u..u+c-1 of a frame that fits (after any suspect decision)."""
        self.last16, self.last_u = s16, u
        k0 = len(keep)
        for r in range(u, u + c):
            if r >= self.end:
                if r > self.end:
                    self._gap(self.end, r)
                self.end = r + 1
                keep.append(True)
            elif self._fill(r):
                self.c["reordered"] += 1
                self.c["lost"] -= 1
                keep.append(True)
            else:
                self.c["duplicates"] += 1
                keep.append(False)
        if rec is not None:
            k = np.array(keep[k0:], bool)
            self._remember(u + np.flatnonzero(k), rec[k])

    def _accept_slow(self, seq16, count, payload, records=None):
        us = np.empty(len(seq16), np.int64)
        keep: list[bool] = []
        released = []
        first = np.cumsum(count) - count
        for i, (s, c) in enumerate(zip(seq16.tolist(), count.tolist())):
            rec = None if records is None else records[first[i]:first[i] + c]
            if self.suspect is not None:
                su, sc, s16, data, srec, restart = self.suspect
                self.suspect = None
                if 0 <= _wrapdiff(s, s16) - sc <= CONFIRM_GAP:      # it continues the suspect
                    if self.last16 is None:                         # a new mote's first frame
                        self.end = su
                        self.c["first_seq"] = su
                    elif restart or su < self.end - REORDER_WINDOW:  # numbering started again
                        self.c["restarts"] += 1
                        su = self.end
                    k0 = len(keep)
                    self._take(su, sc, s16, keep, srec)
                    self.c["samples"] += sum(keep[k0:])
                    del keep[k0:]
                    released.append((su, data))
                else:
                    self.c["rejected"] += 1
            if self.last16 is None:
                u = s
            else:
                u = self.last_u + int(_wrapdiff(s, self.last16))
            us[i] = u
            far = self.last16 is None or u - self.end > MAX_JUMP or u < self.end - REORDER_WINDOW
            if far or (u < self.end and rec is not None and self._differs(u, rec)):
                self.suspect = (u, c, s, payload(i) if payload is not None else None, rec,
                                not far)
                keep.extend([False] * c)
                continue
            k0 = len(keep)
            self._take(u, c, s, keep, rec)
            self.c["samples"] += sum(keep[k0:])
        self.c["last_seq"] = max(self.end - 1, 0)
        self._prune()
        return us, np.array(keep, bool), released

    def _fill(self, r: int) -> bool:
        for k, (lo, hi) in enumerate(self.holes):
            if lo <= r < hi:
                parts = [p for p in ([lo, r], [r + 1, hi]) if p[1] > p[0]]
                self.holes[k:k + 1] = parts
                return True
        return False

    def temperature(self, msg: dict) -> None:
        """A temperature message: ``temp_sum`` of ``count`` raw TEMP_OUT
        readings, the newest of the sample with 16-bit number ``seq``.  A
        message with no reading (count 0) is counted, nothing else."""
        self.temp_msgs += 1
        if msg["count"] < 1:
            return
        c = float(P.temp_c(msg["temp_sum"] / msg["count"]))
        self.temp_c = c
        lo, hi = self.temp_range or (c, c)
        self.temp_range = (min(lo, c), max(hi, c))
        if len(self._temp_wait) < TEMP_WAIT_MAX:
            self._temp_wait.append((int(msg["seq"]), c, int(msg["count"])))

    def take_temps(self) -> list[tuple[int, float, int]]:
        """Readings ready to store: (unwrapped seq, degrees C, count).  The
        16-bit seq is unwrapped against the mote's samples, so a reading waits
        until the mote's first samples are accepted."""
        if self.last16 is None or not self._temp_wait:
            return []
        out = []
        for s, c, n in self._temp_wait:
            u = self.last_u + int(_wrapdiff(s, self.last16))
            if self.end - REORDER_WINDOW <= u <= self.end + MAX_JUMP:
                out.append((u, c, n))
            else:                    # not near the mote's samples (a reboot not yet confirmed)
                self.temp_rejected += 1
        self._temp_wait = []
        return out

    @property
    def seen(self) -> bool:
        """Anything of this mote was accepted (not only suspect frames)."""
        return self.c["samples"] > 0 or self.c["status_msgs"] > 0

    def status(self, msg: dict) -> None:
        """The mote's latest status counters; the fields an older mote's
        message lacks are absent, and their counters keep what they had."""
        c = self.c
        c["status_msgs"] += 1
        for k, v in msg.items():
            name = status_counter(k)
            if name is not None:
                c[name] = v


@dataclass
class Rows:
    """Records ready to store: arrays in arrival order."""
    mote: np.ndarray
    seq: np.ndarray
    flags: np.ndarray
    raw: np.ndarray

    def __len__(self):
        return len(self.seq)


class LinkTracker:
    """Turns decoded reads into rows and keeps every link counter."""

    def __init__(self, link: dict | None = None, line: dict | None = None,
                 last_seqs: dict | None = None):
        link, last_seqs = link or {}, last_seqs or {}
        self.motes: dict[int, MoteLink] = {
            m: MoteLink(m, c, last_seqs.get(m)) for m, c in link.items()}
        for m, s in last_seqs.items():
            self.motes.setdefault(m, MoteLink(m, None, s))
        self.line = {k: 0 for k in LINE_COUNTERS}
        self.line.update(line or {})
        self.line["gap_s"] = float(self.line["gap_s"])
        # decoder counters of the sources closed so far (and of earlier runs)
        self._dec_base = {k: self.line[k] for k in P.DecoderStats().as_dict()}

    def seen(self) -> dict[int, MoteLink]:
        """Motes with accepted samples or status (not only rejected frames)."""
        return {m: self.motes[m] for m in sorted(self.motes) if self.motes[m].seen}

    def mote(self, m: int) -> MoteLink:
        link = self.motes.get(m)
        if link is None:
            link = self.motes[m] = MoteLink(m)
        return link

    def samples(self, b: SampleBatch) -> Rows:
        self.line["bad_msgs"] += b.bad
        n = len(b.records)
        if not len(b):
            return Rows(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64),
                        np.zeros((0, 9), np.int16))
        u_msg = np.empty(len(b), np.int64)
        keep = np.ones(n, bool)
        extra: list[Rows] = []
        if (b.src == b.src[0]).all():
            groups = [(int(b.src[0]), np.arange(len(b)), None)]
        else:
            rec_src = b.src[b.rec_msg]
            groups = [(int(m), np.flatnonzero(b.src == m), rec_src == m) for m in np.unique(b.src)]
        for m, mi, rsel in groups:
            def payload(i, mi=mi):                  # a message held as suspect
                j = int(mi[i])
                sel = b.rec_msg == j
                return int(b.flags[j]), b.records[sel].copy()
            rec = b.records if rsel is None else b.records[rsel]
            u, k, released = self.mote(m).accept(b.seq[mi], b.count[mi], payload, rec)
            u_msg[mi] = u
            if k is not None:
                keep[slice(None) if rsel is None else rsel] = k    # m's records, in arrival order
            for u0, (flags, rec) in released:
                r = len(rec)
                extra.append(Rows(np.full(r, m), u0 + np.arange(r), np.full(r, flags), rec))
        seq = u_msg[b.rec_msg] + b.rec_index
        rows = Rows(b.src[b.rec_msg], seq, b.flags[b.rec_msg], b.records)
        if not keep.all():
            rows = Rows(rows.mote[keep], rows.seq[keep], rows.flags[keep], rows.raw[keep])
        if extra:
            extra.append(rows)
            rows = Rows(*(np.concatenate([getattr(x, f) for x in extra])
                          for f in ("mote", "seq", "flags", "raw")))
        return rows

    def other(self, frames: list[P.Frame]) -> None:
        """Frames that are not sample messages: status into the counters,
        calibration replies (the uploader's business) checked only."""
        line = self.line
        for f in frames:
            if f.protocol == P.PROTO_ACK:
                line["acks"] += 1
                continue
            am = f.am()
            if am is None or am.am_type not in P.FIXED_MESSAGES:
                line["unknown_msgs"] += 1
                continue
            msg = P.decode_message(am)
            if msg is None:
                line["bad_msgs"] += 1
            elif am.am_type == P.AM_NINEDOF_MOTE_STATUS_MSG:
                self.mote(am.src).status(msg)
            elif am.am_type == P.AM_NINEDOF_MOTE_TEMP_MSG:
                self.mote(am.src).temperature(msg)
            elif am.am_type == P.AM_NINEDOF_BS_STATUS_MSG:
                line["bs_status_msgs"] += 1
                line.update({"bs_" + k: v for k, v in msg.items()})

    def take_temps(self) -> list[tuple[int, int, float, int]]:
        """Temperature readings ready to store: (mote, unwrapped seq, degrees C, count)."""
        return [(m, u, c, n) for m, link in self.motes.items() if link._temp_wait
                for u, c, n in link.take_temps()]

    def decoder(self, stats: P.DecoderStats, closed: bool = False) -> None:
        """Take the current source's decoder counters (``closed``: it is done)."""
        for k, v in stats.as_dict().items():
            self.line[k] = self._dec_base[k] + v
        if closed:
            self._dec_base = {k: self.line[k] for k in self._dec_base}
