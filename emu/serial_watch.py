"""Read the emulated BaseStation's serial line while `make emulate` runs and
count what the host would get: sample records per mote, gaps in their
sequence numbers, the last status counters of each mote and of the
BaseStation.  Decoding is the host's own (motecal.line.protocol)."""
from __future__ import annotations

import os
import threading
import tty


class SerialWatch:
    """Reads a pty in a thread from open() until close(); summary() after."""

    def __init__(self):
        from motecal.line import protocol as P     # the host's decoder
        self.P = P
        self.dec = P.FrameDecoder()
        self.motes: dict[int, dict] = {}
        self.bs_status: dict | None = None
        self.bytes = 0
        self._fd = None
        self._thread = None
        self._stop = False

    def open(self, path: str) -> None:
        self._fd = os.open(path, os.O_RDONLY | os.O_NOCTTY)
        tty.setraw(self._fd)
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop:
            try:
                data = os.read(self._fd, 65536)
            except OSError:               # the harness closed the pty
                break
            if not data:
                break
            self.bytes += len(data)
            self._feed(data)

    def _feed(self, data: bytes) -> None:
        P = self.P
        for fr in self.dec.feed(data):
            am = fr.am()
            msg = P.decode_message(am) if am is not None else None
            if msg is None:
                continue
            if am.am_type == P.AM_NINEDOF_BS_STATUS_MSG:
                self.bs_status = msg
                continue
            m = self.motes.setdefault(am.src, {"records": 0, "messages": 0, "missing": 0,
                                               "gaps": 0, "next": None, "status": None})
            if am.am_type == P.AM_NINEDOF_SAMPLES_MSG:
                n = len(msg.records)
                if m["next"] is not None:
                    skipped = (msg.seq - m["next"]) & 0xFFFF
                    if 0 < skipped < 0x8000:
                        m["gaps"] += 1
                        m["missing"] += skipped
                m["next"] = (msg.seq + n) & 0xFFFF
                m["records"] += n
                m["messages"] += 1
            elif am.am_type == P.AM_NINEDOF_MOTE_STATUS_MSG:
                m["status"] = msg

    def close(self) -> None:
        self._stop = True
        if self._thread:
            self._thread.join(timeout=2)
        if self._fd is not None:
            try:
                os.close(self._fd)
            except OSError:
                pass

    def summary(self) -> list[str]:
        lines = [f"serial line: {self.bytes} bytes read, {self.dec.stats.as_dict()}"]
        for src, m in sorted(self.motes.items()):
            st = m["status"]
            lines.append(f"  mote {src}: {m['records']} records in {m['messages']} messages, "
                         f"sequence gaps {m['gaps']} ({m['missing']} records missing)"
                         + (f"; last status: {dict(st)}" if st else ""))
        if self.bs_status:
            lines.append(f"  BaseStation status: {dict(self.bs_status)}")
        return lines
