"""``motecal log``: record what the BaseStation forwards into the database,
optionally guiding a person through 80 static poses or a rotation sweep.

Data path, all vectorised per read (``bench/bench_logger.py`` measures it):
source bytes -> ``protocol.FrameDecoder`` (in ``sources``) -> sample messages
decoded together (``decode_sample_frames``) -> sequence numbers unwrapped and
checked per mote (``LinkTracker``: gaps = lost samples, duplicates dropped,
late ones filling gaps counted as reordered) -> ``store.SessionWriter``, which
commits a transaction every 0.25 s.  Other messages (mote and BaseStation
status) go into the link statistics; anything unusable is counted and skipped.

The port may vanish (unplugged, TCP closed): the logger commits, records a
``disconnect`` event, retries with backoff and resumes.  Ctrl-C and SIGTERM
end the session cleanly: everything received is committed and the session is
marked ended.
"""
from __future__ import annotations

import argparse
import contextlib
import signal
import sys
import threading
import time
from collections import deque
from dataclasses import dataclass

import numpy as np

from . import protocol as P
from . import sources as S
from .cliargs import baud_rate, mote_id, positive, session_name
from .errors import UserError
from .guide import (DEFAULT_COVERAGE, DEFAULT_MIN_ANGLE, DEFAULT_POSE_SAMPLES, DEFAULT_POSES,
                    DEFAULT_ROT_SAMPLES, MAX_MIN_ANGLE, GuidedFlow, max_poses)
from .store import LINE_COUNTERS, LINK_COUNTERS, SessionWriter, open_store

# Layout offsets inside an AM frame body (AM header + sample payload), from protocol
_AMH = P.AM_HEADER.size                       # 7: dest(2) src(2) len(1) group(1) type(1)
_SRC, _TYPE = 2, 6
_SH = P.SAMPLES_HEADER.size                   # 4: seq(2) flags(1) count(1)
_REC = P.NINEDOF_RECORD_SIZE                  # 18
_REC_BYTES = np.arange(_REC)

REORDER_WINDOW = 2048        # samples back: further is a restart (or corruption)
MAX_JUMP = 1000              # samples ahead (8 s): further is held until confirmed
CONFIRM_GAP = 64             # the next frame may follow a suspect one this far on
# After a guided flow is done the logger reads on until the followed motes'
# samples of DRAIN_S more (sample time, not wall time: the same when a
# simulator is read as fast as it goes) have arrived -- every mote's samples
# still in flight through the BaseStation then have too -- or the line is
# quiet for DRAIN_IDLE_S, or DRAIN_MAX_S have passed.
DRAIN_S = 0.5
DRAIN_IDLE_S = 0.3
DRAIN_MAX_S = 3.0
BACKOFF_MIN_S, BACKOFF_MAX_S = 0.1, 2.0


# --------------------------------------------------------------------------
# Decoding many sample messages at once
# --------------------------------------------------------------------------
@dataclass
class SampleBatch:
    """Sample messages of one read, arrays in arrival order."""
    src: np.ndarray           # (m,) mote id of each message
    seq: np.ndarray           # (m,) 16-bit sequence number of its first record
    flags: np.ndarray         # (m,)
    count: np.ndarray         # (m,)
    records: np.ndarray       # (N, 9) int16, all records
    rec_msg: np.ndarray       # (N,) index of the message of each record
    rec_index: np.ndarray     # (N,) position of the record within its message
    bad: int = 0              # AM_NINEDOF_SAMPLES_MSG frames whose count/length disagree

    def __len__(self):
        return len(self.src)


def decode_sample_frames(frames: list[P.Frame]) -> tuple[SampleBatch, list[P.Frame]]:
    """Split frames into sample messages (decoded together with numpy, the
    same result as ``protocol.decode_message`` frame by frame) and the rest."""
    n = len(frames)
    bodies = [f.body for f in frames]
    lens = np.fromiter(map(len, bodies), np.int64, n)
    is_am = np.fromiter((f.dispatch == P.DISPATCH_AM for f in frames), bool, n)
    blob = np.frombuffer(b"".join(bodies), np.uint8)
    starts = np.zeros(n, np.int64)
    if n > 1:
        np.cumsum(lens[:-1], out=starts[1:])
    has_type = is_am & (lens >= _AMH)
    typ = np.full(n, -1, np.int64)
    typ[has_type] = blob[starts[has_type] + _TYPE]
    is_samples = typ == P.AM_NINEDOF_SAMPLES_MSG
    count = np.zeros(n, np.int64)
    long_enough = is_samples & (lens >= _AMH + _SH)
    count[long_enough] = blob[starts[long_enough] + _AMH + 3]
    ok = long_enough & (count >= 1) & (lens == _AMH + _SH + _REC * count)
    idx = np.flatnonzero(ok)
    s = starts[idx]
    cnt = count[idx]
    src = (blob[s + _SRC].astype(np.int64) << 8) | blob[s + _SRC + 1]
    seq = (blob[s + _AMH].astype(np.int64) << 8) | blob[s + _AMH + 1]
    flags = blob[s + _AMH + 2].astype(np.int64)
    total = int(cnt.sum())
    rec_msg = np.repeat(np.arange(len(idx)), cnt)
    first = np.cumsum(cnt) - cnt
    rec_index = np.arange(total) - first[rec_msg]
    off = s[rec_msg] + _AMH + _SH + _REC * rec_index
    records = blob[off[:, None] + _REC_BYTES].copy().view(P.RECORD_DTYPE).reshape(total, 9) \
        .astype(np.int16)
    others = [frames[i] for i in np.flatnonzero(~ok & ~is_samples)]
    batch = SampleBatch(src, seq, flags, cnt, records, rec_msg, rec_index,
                        bad=int((is_samples & ~ok).sum()))
    return batch, others


# --------------------------------------------------------------------------
# Sequence numbers and link statistics
# --------------------------------------------------------------------------
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

    @property
    def seen(self) -> bool:
        """Anything of this mote was accepted (not only suspect frames)."""
        return self.c["samples"] > 0 or self.c["status_msgs"] > 0

    def status(self, msg: dict) -> None:
        c = self.c
        c["status_msgs"] += 1
        c["mote_dropped"] = msg["dropped"]
        c["mote_send_fail"] = msg["send_fail"]
        c["mote_i2c_errors"] = msg["i2c_errors"]
        c["mote_late"] = msg["late"]
        c["cal_version"] = msg["version"]
        c["cal_sensors"] = msg["sensors"]


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
            elif am.am_type == P.AM_NINEDOF_BS_STATUS_MSG:
                line["bs_status_msgs"] += 1
                line.update({"bs_" + k: v for k, v in msg.items()})

    def decoder(self, stats: P.DecoderStats, closed: bool = False) -> None:
        """Take the current source's decoder counters (``closed``: it is done)."""
        for k, v in stats.as_dict().items():
            self.line[k] = self._dec_base[k] + v
        if closed:
            self._dec_base = {k: self.line[k] for k in self._dec_base}


# --------------------------------------------------------------------------
# The logging loop
# --------------------------------------------------------------------------
class Logger:
    """Reads a source until stopped and writes everything into a session.

    ``run`` returns when: ``request_stop`` was called (Ctrl-C, SIGTERM, 'q'),
    ``duration`` seconds passed, a recorded file ended, or the guided flow is
    done and the line has gone quiet.  It always commits and ends the session.
    """

    def __init__(self, spec: S.PortSpec, writer: SessionWriter, tracker: LinkTracker, *,
                 guide: GuidedFlow | None = None, display=None,
                 duration: float | None = None, source: S.Source | None = None):
        self.spec = spec
        self.writer = writer
        self.tracker = tracker
        self.guide = guide
        self.display = display or NullDisplay()
        self.duration = duration
        self.source = source
        self.stop_event = threading.Event()
        self.stop_reason = ""
        self.connected = False
        self.started = time.monotonic()

    def request_stop(self, reason: str = "stopped") -> None:
        if not self.stop_event.is_set():
            self.stop_reason = reason
        self.stop_event.set()

    @property
    def elapsed(self) -> float:
        return time.monotonic() - self.started

    def _time_up(self) -> bool:
        if self.duration is not None and self.elapsed >= self.duration:
            self.request_stop(f"{self.duration:g} s elapsed")
        return self.stop_event.is_set()

    def run(self) -> None:
        self.started = time.monotonic()
        src = self.source or S.open_source(self.spec)
        self.connected = True
        self.display.start(self)
        drain_since = None
        last_data = time.monotonic()
        try:
            while not self._time_up():
                try:
                    frames = src.read()
                except S.SourceEnded:
                    self.handle(src.flush())
                    self.request_stop("end of input")
                    break
                except S.SourceLost as e:
                    self.handle(src.flush())
                    self.tracker.decoder(src.stats, closed=True)
                    src.close()
                    src = None
                    if self.stop_event.is_set():
                        break
                    if drain_since is not None:
                        self.request_stop("port closed after the guided flow")
                        break
                    src = self._reconnect(str(e))
                    if src is None:
                        break
                    continue
                now = time.monotonic()
                if frames:
                    self.handle(frames)
                    last_data = now
                self.tracker.decoder(src.stats)
                if self.writer.due:
                    self.commit()
                self.display.tick(self)
                if self.guide is not None and self.guide.done:
                    if drain_since is None:
                        drain_since = now
                        more = int(round(DRAIN_S * P.NINEDOF_RATE_HZ))
                        drain_to = {m: self.tracker.mote(m).end + more
                                    for m in self.guide.captures}
                    drained = all(self.tracker.mote(m).end >= e for m, e in drain_to.items())
                    if drained or now - last_data >= DRAIN_IDLE_S \
                            or now - drain_since >= DRAIN_MAX_S:
                        self.request_stop("guided flow done")
        finally:
            if src is not None:
                self.handle(src.flush())
                self.tracker.decoder(src.stats, closed=True)
                src.close()
            self.connected = False
            self.commit()
            self.writer.end()
            self.display.stop(self)

    def handle(self, frames: list[P.Frame]) -> None:
        if not frames:
            return
        batch, others = decode_sample_frames(frames)
        if others:
            self.tracker.other(others)
        rows = self.tracker.samples(batch)
        if not len(rows):
            return
        t = np.full(len(rows), self.writer.now())
        self.writer.add_samples(rows.mote, rows.seq, t, rows.flags, rows.raw)
        if self.guide is not None:
            for ev in self.guide.update(rows.mote, rows.seq, rows.raw):
                if ev.kind == "label":
                    self.writer.set_label(ev.mote, ev.seq_lo, ev.seq_hi, ev.label)
                    continue
                if ev.kind != "capturing":
                    self.writer.add_event(ev.kind, ev.text, ev.mote)
                self.display.event(ev.text)

    def commit(self) -> None:
        for m, link in self.tracker.seen().items():
            self.writer.set_link_stats(m, link.c)
        self.writer.set_line_stats(self.tracker.line)
        self.writer.commit()

    def _reconnect(self, reason: str) -> S.Source | None:
        self.connected = False
        t0 = time.monotonic()
        self.tracker.line["disconnects"] += 1
        self.writer.add_event("disconnect", reason)
        self.commit()
        self.display.event(f"port lost ({reason}); reconnecting")
        delay = BACKOFF_MIN_S
        while not self._time_up():
            if self.stop_event.wait(delay):
                break
            try:
                src = S.open_source(self.spec)
            except S.PortError:
                delay = min(2 * delay, BACKOFF_MAX_S)
                self.display.tick(self)
                continue
            gap = time.monotonic() - t0
            self.tracker.line["gap_s"] += gap
            self.writer.add_event("reconnect", f"after {gap:.1f} s")
            self.display.event(f"port back after {gap:.1f} s")
            self.connected = True
            return src
        self.tracker.line["gap_s"] += time.monotonic() - t0
        return None

    # -- what displays show ------------------------------------------------------
    def summary_lines(self) -> list[str]:
        w, tr = self.writer, self.tracker
        out = []
        motes = tr.seen()
        total = sum(m.c["samples"] for m in motes.values())
        out.append(f"session {w.name}: {total} samples from {len(motes)} mote(s) "
                   f"in {self.elapsed:.1f} s ({self.stop_reason or 'running'})")
        for m, link in motes.items():
            c = link.c
            line = (f"  mote {m}: {c['samples']} samples, lost {c['lost']}, "
                    f"duplicates {c['duplicates']}, reordered {c['reordered']}")
            cap = self.guide.captures.get(m) if self.guide else None
            if cap is not None and cap.kind == "static80":
                line += f", poses {len(cap.accepted)}/{cap.poses}"
            elif cap is not None:
                line += f", rotation {cap.count} samples, coverage {cap.coverage.fraction:.0%}"
            out.append(line)
        ln = tr.line
        out.append(f"  line: {ln['frames']} frames, {ln['crc_errors']} CRC errors, "
                   f"{ln['cut_off']} cut off, "
                   f"{ln['bad_frames'] + ln['bad_msgs']} malformed, {ln['unknown_msgs']} "
                   f"unknown, {ln['garbage_bytes']} garbage bytes, {ln['disconnects']} "
                   f"disconnects ({ln['gap_s']:.1f} s)")
        return out


class NullDisplay:
    def start(self, logger): pass
    def event(self, text): pass
    def tick(self, logger): pass
    def stop(self, logger): pass


class PlainDisplay(NullDisplay):
    """Plain lines (no TTY): every event, a status line every ``every`` seconds."""

    def __init__(self, out=None, every: float = 5.0):
        self.out = out or sys.stdout
        self.every = every
        self._next = 0.0
        self._prompted: dict = {}

    def _print(self, text):
        print(text, file=self.out, flush=True)

    def start(self, logger):
        self._print(f"logging {logger.spec} into session {logger.writer.name}"
                    + (f" ({logger.guide.kind}, guided)" if logger.guide else ""))
        self._next = time.monotonic() + self.every

    def event(self, text):
        if text:
            self._print(text)

    def tick(self, logger):
        if logger.guide is not None and not logger.guide.auto:
            for st in logger.guide.status():       # interactive without a TTY for output
                key = (st["mote"], st.get("pose"), st["armed"])
                if st["kind"] == "static80" and st["target"] and self._prompted.get(
                        st["mote"]) != key and not st["armed"]:
                    self._prompted[st["mote"]] = key
                    self._print(f"mote {st['mote']}: pose {st['pose']}/{st['poses']}: "
                                f"{st['target']}; hold still and press Enter")
        now = time.monotonic()
        if now >= self._next:
            self._next = now + self.every
            tr = logger.tracker
            total = sum(m.c["samples"] for m in tr.motes.values())
            extra = ""
            if logger.guide is not None:
                parts = []
                for st in logger.guide.status():
                    if st["kind"] == "static80":
                        parts.append(f"mote {st['mote']} pose {st['pose']}/{st['poses']}")
                    else:
                        parts.append(f"mote {st['mote']} {st['count']}/{st['samples']} "
                                     f"cov {st['coverage']:.0%}")
                extra = "; " + ", ".join(parts)
            self._print(f"[{logger.elapsed:6.1f} s] {total} samples, "
                        f"{tr.line['crc_errors']} CRC errors"
                        + ("" if logger.connected else ", reconnecting") + extra)

    def stop(self, logger):
        for line in logger.summary_lines():
            self._print(line)


class RichDisplay(NullDisplay):
    """Live panel on a terminal (rich): link per mote, guidance, recent events."""

    def __init__(self):
        from rich.console import Console
        self.console = Console()
        self.live = None
        self.events: deque = deque(maxlen=6)
        self._rates: dict = {}
        self._last = 0.0

    def start(self, logger):
        from rich.live import Live
        self.live = Live(self._render(logger), console=self.console, refresh_per_second=4,
                         transient=False)
        self.live.start()

    def event(self, text):
        if text:
            self.events.append(text)

    def tick(self, logger):
        now = time.monotonic()
        if self.live is not None and now - self._last >= 0.25:
            self._last = now
            self.live.update(self._render(logger))

    def stop(self, logger):
        if self.live is not None:
            self.live.update(self._render(logger))
            self.live.stop()
        for line in logger.summary_lines():
            self.console.print(line)

    def _rate(self, mote, samples):
        now = time.monotonic()
        hist = self._rates.setdefault(mote, deque(maxlen=20))
        hist.append((now, samples))
        t0, s0 = hist[0]
        return (samples - s0) / (now - t0) if now > t0 else 0.0

    def _render(self, logger):
        from rich.console import Group
        from rich.panel import Panel
        from rich.table import Table
        from rich.text import Text
        tr = logger.tracker
        table = Table(box=None, pad_edge=False)
        for col in ("mote", "samples", "rate/s", "lost", "dup", "reord", "status"):
            table.add_column(col, justify="right")
        for m, link in tr.seen().items():
            c = link.c
            table.add_row(str(m), str(c["samples"]), f"{self._rate(m, c['samples']):.0f}",
                          str(c["lost"]), str(c["duplicates"]), str(c["reordered"]),
                          f"drop {c['mote_dropped']} late {c['mote_late']}")
        ln = tr.line
        state = "[green]connected[/]" if logger.connected else "[red]reconnecting[/]"
        head = Text.from_markup(
            f"[b]{logger.writer.name}[/]  {logger.spec}  {state}  {logger.elapsed:.0f} s   "
            f"frames {ln['frames']}  CRC err {ln['crc_errors']}  garbage {ln['garbage_bytes']}"
            f"  disconnects {ln['disconnects']}")
        parts = [head, table]
        if logger.guide is not None:
            for st in logger.guide.status():
                parts.append(_guide_text(st))
        if self.events:
            parts.append(Text("\n".join(self.events), style="dim"))
        return Panel(Group(*parts), title="motecal log", subtitle="Ctrl-C ends the session")


def _guide_text(st: dict):
    from rich.text import Text
    lines = []
    if st["kind"] == "static80":
        lines.append(f"mote {st['mote']}: pose {st['pose']} of {st['poses']}"
                     f" - {st['phase']}"
                     + (f" ({st['captured']}/{st['samples']})" if st["captured"] else ""))
        if st["target"]:
            lines.append(f"  suggested: {st['target']}")
        sketch = st["sketch"]
        cov = [f"coverage {st['coverage']:.0%} (o = suggested)"] + st["map"]
        for k in range(max(len(sketch), len(cov))):
            a = sketch[k] if k < len(sketch) else ""
            b = cov[k] if k < len(cov) else ""
            lines.append(f"  {a:24s} {b}")
        if st["warning"]:
            lines.append(f"  ! {st['warning']}")
    else:
        lines.append(f"mote {st['mote']}: rotation - {st['phase']}: {st['count']}/"
                     f"{st['samples']} samples, coverage {st['coverage']:.0%} "
                     f"(stops at {st['target_coverage']:.0%})"
                     + ("" if st["armed"] else "  -- press Enter to start"))
        lines += ["  " + r for r in st["map"]]
    return Text("\n".join(lines))


@contextlib.contextmanager
def _no_echo(active: bool):
    """Keys typed for the guide (Enter) are not echoed into the live display."""
    if not active:
        yield
        return
    import termios
    fd = sys.stdin.fileno()
    old = termios.tcgetattr(fd)
    new = list(old)
    new[3] &= ~termios.ECHO
    termios.tcsetattr(fd, termios.TCSADRAIN, new)
    try:
        yield
    finally:
        termios.tcsetattr(fd, termios.TCSADRAIN, old)


class _KeyReader(threading.Thread):
    """Interactive use: Enter confirms a pose, 'q' + Enter ends the session."""

    def __init__(self, logger: Logger, stream=None):
        super().__init__(daemon=True)
        self.logger = logger
        self.stream = stream or sys.stdin

    def run(self):
        for line in self.stream:
            if line.strip().lower() in ("q", "quit"):
                self.logger.request_stop("quit")
                return
            if self.logger.guide is not None:
                self.logger.guide.arm()


# --------------------------------------------------------------------------
# Command line
# --------------------------------------------------------------------------
def _board(text):
    mote, sep, board = text.partition("=")
    if not sep or not board:
        raise argparse.ArgumentTypeError(f"want MOTE=BOARD, not {text!r}")
    return mote_id(mote), board


def register(sub) -> None:
    p = sub.add_parser(
        "log", help="record a session from the BaseStation into the database",
        description="Record what the BaseStation forwards (serial port, pyserial URL, "
                    "serial@DEV:BAUD, sf@HOST:PORT, or a recorded file) into a database "
                    "session, optionally guiding through 80 static poses or a rotation.")
    p.add_argument("--port", help="device, pyserial URL (socket://, rfc2217://, loop://), "
                                  "serial@DEV:BAUD, sf@HOST:PORT or a recorded file; "
                                  "default: $MOTECOM")
    p.add_argument("--baud", type=baud_rate, help="baud rate (default 250000)")
    p.add_argument("--db", required=True, help="database: sqlite file or postgresql:// URL")
    p.add_argument("--session", required=True, type=session_name, help="session name")
    p.add_argument("--append", action="store_true", help="add to an existing session")
    p.add_argument("--guided", choices=("static80", "rotation"), help="guide a person")
    p.add_argument("--kind", choices=("free", "idle", "static80", "rotation"),
                   help="session kind when not guided (default free)")
    p.add_argument("--mote", type=mote_id, help="mote the guided flow follows (default all)")
    p.add_argument("--duration", type=positive(float), help="stop after SECONDS")
    p.add_argument("--yes", action="store_true",
                   help="non-interactive: advance whenever a new still pose appears")
    p.add_argument("--notes", help="free text stored with the session")
    p.add_argument("--board", type=_board, action="append", default=[], metavar="MOTE=BOARD",
                   help="which sensor board sits on which mote (repeatable)")
    g = p.add_argument_group("guided flow")
    g.add_argument("--poses", type=positive(int), default=DEFAULT_POSES)
    g.add_argument("--pose-samples", type=positive(int), default=DEFAULT_POSE_SAMPLES)
    g.add_argument("--min-angle", type=positive(float), default=DEFAULT_MIN_ANGLE,
                   help="degrees a new pose must be from every earlier one")
    g.add_argument("--rot-samples", type=positive(int), default=DEFAULT_ROT_SAMPLES)
    g.add_argument("--coverage", type=positive(float), default=DEFAULT_COVERAGE,
                   help="rotation stops at this fraction of sphere cells hit")
    p.add_argument("--commit-every", type=positive(float), default=0.25,
                   help=argparse.SUPPRESS)
    p.set_defaults(func=run)


def _guide(args, interactive: bool) -> GuidedFlow | None:
    if not args.guided:
        return None
    if args.guided == "static80":
        if args.pose_samples < 50:
            raise UserError("--pose-samples must be at least 50 (the stillness window)")
        if not args.min_angle <= MAX_MIN_ANGLE:
            raise UserError(f"--min-angle must be within 0..{MAX_MIN_ANGLE:g} degrees, "
                            f"not {args.min_angle:g}")
        if args.poses > max_poses(args.min_angle):
            raise UserError(f"--poses {args.poses} cannot be {args.min_angle:g} degrees apart "
                            f"from each other: the sphere has room for at most "
                            f"{max_poses(args.min_angle)} (lower --min-angle or --poses)")
        opts = dict(poses=args.poses, samples=args.pose_samples, min_angle_deg=args.min_angle,
                    rate_hz=P.NINEDOF_RATE_HZ)
    else:
        if args.coverage > 1:
            raise UserError("--coverage is a fraction, 0 < c <= 1")
        opts = dict(samples=args.rot_samples, coverage=args.coverage)
    return GuidedFlow(args.guided, follow=args.mote, auto=not interactive, options=opts)


def run(args) -> int:
    spec = S.parse_port(args.port, args.baud)
    interactive = bool(args.guided) and not args.yes and sys.stdin.isatty()
    guide = _guide(args, interactive)
    with contextlib.ExitStack() as stack:
        # the port first: if it cannot be opened, no database file is made
        source = S.open_source(spec)
        stack.callback(source.close)
        # --append continues a session: the database must be there already
        store = stack.enter_context(open_store(args.db, create=not args.append))
        meta = {"source": str(spec), "rate_hz": P.NINEDOF_RATE_HZ, "notes": args.notes,
                "baud": spec.baud}
        if args.board:
            meta["boards"] = {str(m): b for m, b in args.board}
        link = line = last = None
        if args.append and store.session_exists(args.session):
            stats = store.link_stats(args.session)
            link, line = stats["motes"], stats["line"]
            last = store.last_seqs(args.session)
        writer = store.open_session(args.session, kind=args.guided or args.kind or "free",
                                    meta=meta, append=args.append,
                                    commit_every=args.commit_every)
        tracker = LinkTracker(link, line, last)
        display = RichDisplay() if sys.stdout.isatty() else PlainDisplay()
        logger = Logger(spec, writer, tracker, guide=guide, display=display,
                        duration=args.duration, source=source)
        old = {}

        def on_signal(signum, frame):
            logger.request_stop("interrupted" if signum == signal.SIGINT else "terminated")

        for sig in (signal.SIGINT, signal.SIGTERM):
            old[sig] = signal.signal(sig, on_signal)
        try:
            with _no_echo(interactive):
                if interactive:
                    _KeyReader(logger).start()
                logger.run()
        finally:
            for sig, h in old.items():
                signal.signal(sig, h)
    return 0
