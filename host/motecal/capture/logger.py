"""The logger loop (``motecal log``): record what the BaseStation forwards into the database,
optionally guiding a person through 80 static poses or a rotation sweep.

Data path, all vectorised per read (``bench/bench_logger.py`` measures it):
source bytes -> ``protocol.FrameDecoder`` (in ``sources``) -> sample messages
decoded together (``decode_sample_frames``) -> sequence numbers unwrapped and
checked per mote (``LinkTracker``: gaps = lost samples, duplicates dropped,
late ones filling gaps counted as reordered) -> ``store.SessionWriter``, which
commits a transaction every 0.25 s.  Other messages (mote and BaseStation
status) go into the link statistics, the motes' temperature messages into the
session's temperature readings; anything unusable is counted and skipped.

The port may vanish (unplugged, TCP closed): the logger commits, records a
``disconnect`` event, retries with backoff and resumes.  Ctrl-C and SIGTERM
end the session cleanly: everything received is committed and the session is
marked ended.
"""
from __future__ import annotations

import threading
import time

import numpy as np

from ..line import protocol as P
from ..line import sources as S
from ..line.samples import decode_sample_frames
from ..sessions.store import SessionWriter, StoreError
from .guide import GuidedFlow
from .link import LinkTracker

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
        self._lock_began = 0.0

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
        """Log until stopped; raises ``StoreError`` (after ending the session
        with what was committed) when the database fails."""
        failure = None
        self.started = time.monotonic()
        src = self.source or S.open_source(self.spec)
        self.connected = True
        self.display.start(self)
        drain_since = None
        last_data = time.monotonic()
        try:
            while not self._time_up():
                try:
                    frames = src.read_block()
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
                if len(frames):
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
        except StoreError as e:
            failure = e
        finally:
            if src is not None:
                self.handle(src.flush())
                self.tracker.decoder(src.stats, closed=True)
                src.close()
            self.connected = False
            failure = self._finish(failure)
            self.display.stop(self)
        if failure is not None:
            raise failure

    def _finish(self, failure: StoreError | None) -> StoreError | None:
        """Commit what is queued and mark the session ended.  When the store
        fails (disk full, I/O error, a lock held past the timeout) the session
        is still marked ended with what was committed, and the failure comes
        back as one line saying how much was stored and how much was not."""
        w = self.writer
        if failure is None:
            try:
                while not self.commit():          # a held lock: wait (bounded)
                    time.sleep(0.05)
                w.mark_ended()
                return None
            except StoreError as e:
                failure = e
        lost = w.discard()
        try:
            w.mark_ended()
            state = "marked ended"
        except StoreError:
            state = "left open (the database refused even that)"
        self.stop_reason = "database failed"
        return type(failure)(f"{failure}; logging stopped: {w.committed_samples} samples stored, "
                          f"{lost} received samples not stored; session {w.name} {state}",
                          exit_code=failure.exit_code)

    def handle(self, frames: P.FrameBlock | list[P.Frame]) -> None:
        if not len(frames):
            return
        batch, others = decode_sample_frames(frames)
        if others:
            self.tracker.other(others)
        rows = self.tracker.samples(batch)
        for mote, seq, temp, count in self.tracker.take_temps():
            self.writer.add_temp(mote, seq, self.writer.now(), temp, count)
        if not len(rows):
            return
        t = np.full(len(rows), self.writer.now())
        self.writer.add_samples(rows.mote, rows.seq, t, rows.flags, rows.raw)
        self.display.rows(rows)
        if self.guide is not None:
            for ev in self.guide.update(rows.mote, rows.seq, rows.raw):
                if ev.kind == "label":
                    self.writer.set_label(ev.mote, ev.seq_lo, ev.seq_hi, ev.label)
                    continue
                if ev.kind != "capturing":
                    self.writer.add_event(ev.kind, ev.text, ev.mote)
                self.display.guide_event(ev)

    def _set_counters(self) -> None:
        for m, link in self.tracker.seen().items():
            self.writer.set_link_stats(m, link.c)
        self.writer.set_line_stats(self.tracker.line)

    def commit(self) -> bool:
        """Commit what is queued.  While another process holds the database's
        write lock the samples stay queued (``SessionWriter.commit``) and the
        loop reads on; the wait is shown and stored as a ``db_locked`` event."""
        w = self.writer
        waiting = w.locked_since is not None
        self._set_counters()
        done = w.commit()
        if not done and not waiting:
            self.display.event(f"database locked by another process: buffering samples, "
                               f"retrying for up to {w.lock_timeout:g} s")
        elif done and waiting:
            waited = time.monotonic() - self._lock_began
            w.add_event("db_locked", f"database locked by another process for {waited:.1f} s; "
                                     "samples were buffered, none lost")
            self.display.event(f"database free again after {waited:.1f} s; buffered samples "
                               "stored")
            self._set_counters()
            w.commit()
        if not done and not waiting:
            self._lock_began = time.monotonic()
        return done

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
            if link.temp_range is not None:
                lo, hi = link.temp_range
                line += f", temperature {lo:.1f}..{hi:.1f} C"
            cap = self.guide.captures.get(m) if self.guide else None
            if cap is not None and cap.kind == "static80":
                line += f", poses {len(cap.accepted)}/{cap.poses}"
            elif cap is not None and cap.kind == "adaptive":
                line += (f", poses {len(cap.accepted)} (at most {cap.poses}), targets "
                         + ("met" if cap.met else "not met") + (f": {cap.text}" if cap.text
                                                               else ""))
            elif cap is not None:
                line += f", rotation {cap.count} samples, coverage {cap.coverage.fraction:.0%}"
            out.append(line)
        if w.duplicates or w.conflicts:
            out.append(f"  other writers of this session: {w.duplicates} samples they had "
                       f"stored already (duplicates), {w.conflicts} stored with other values "
                       "(conflicts, kept in sample_conflicts)")
        ln = tr.line
        out.append(f"  line: {ln['frames']} frames, {ln['crc_errors']} CRC errors, "
                   f"{ln['cut_off']} cut off, "
                   f"{ln['bad_frames'] + ln['bad_msgs']} malformed, {ln['unknown_msgs']} "
                   f"unknown, {ln['garbage_bytes']} garbage bytes, {ln['disconnects']} "
                   f"disconnects ({ln['gap_s']:.1f} s)")
        return out


class NullDisplay:
    """What the loop tells a display (all called from the logging thread; a
    display must return at once: ``tick`` comes after every read)."""
    def start(self, logger): pass
    def event(self, text): pass
    def tick(self, logger): pass
    def stop(self, logger): pass

    def rows(self, rows):
        """The rows just stored (``link.Rows``); do not keep or change them."""

    def guide_event(self, ev):
        """A ``guide.GuideEvent`` (its text is what a screen shows)."""
        self.event(ev.text)


class TeeDisplay(NullDisplay):
    """Several displays at once (the terminal and the browser view)."""

    def __init__(self, *displays):
        self.displays = displays

    def start(self, logger):
        for d in self.displays:
            d.start(logger)

    def event(self, text):
        for d in self.displays:
            d.event(text)

    def tick(self, logger):
        for d in self.displays:
            d.tick(logger)

    def stop(self, logger):
        for d in self.displays:
            d.stop(logger)

    def rows(self, rows):
        for d in self.displays:
            d.rows(rows)

    def guide_event(self, ev):
        for d in self.displays:
            d.guide_event(ev)
