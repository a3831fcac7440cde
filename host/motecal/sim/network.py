"""Motes + radio + BaseStation + serial line, driven by one event loop in
simulated time.

``Network`` knows nothing about physics: each mote gets a *sampler* (anything
with ``read(t_true: ndarray) -> int16 (n, 9)``, called with increasing
blocks) and a clock error in ppm.  ``motecal.sim.world.World`` builds one from
the physics model; tests may build one from any sampler.

Time is float seconds of true (simulated) time.  ``run_until(t)`` runs every
event up to ``t`` and returns the serial bytes whose last bit left the
BaseStation's UART by ``t`` (byte ``i`` of a frame started at ``s`` is done at
``s + (i + 1) * 10 / baud``), so paced and as-fast-as-possible output use the
same code.
"""
from __future__ import annotations

import heapq
import math
import random
from collections import deque

import numpy as np

from ..line import protocol as P
from .basestation import BaseStation
from .mote import SimMote
from .radio import Channel


class EventLoop:
    """A heap of (time, order, callback, argument)."""
    __slots__ = ("now", "_heap", "_n")

    def __init__(self):
        self.now = 0.0
        self._heap: list = []
        self._n = 0

    def at(self, t: float, fn, arg=None) -> None:
        self._n += 1
        heapq.heappush(self._heap, (t, self._n, fn, arg))

    def run_until(self, t: float) -> None:
        heap = self._heap
        pop = heapq.heappop
        while heap and heap[0][0] <= t:
            tt, _, fn, arg = pop(heap)
            self.now = tt
            fn(arg)
        if t > self.now:
            self.now = t

    @property
    def pending(self) -> int:
        return len(self._heap)

    def next_time(self) -> float:
        return self._heap[0][0] if self._heap else math.inf


class SentLog:
    """What of one mote reached the serial line, sample by sample.

    ``seq``: unwrapped sequence numbers (int64; the wire carries ``seq %
    65536``), ``raw``: what the sensors produced, ``records``: what was sent
    (corrected when ``flags & FLAG_CORRECTED``), ``flags``, ``t``: true time
    each sample was taken (seconds).
    """

    def __init__(self, mote):
        self._mote = mote
        self._k0: list[int] = []
        self._n: list[int] = []
        self._raw: list[np.ndarray] = []
        self._rec: list[np.ndarray] = []
        self._flags: list[int] = []

    def add(self, msg) -> None:
        self._k0.append(msg.k0)
        self._n.append(msg.count)
        self._raw.append(msg.raw)
        self._rec.append(msg.records)
        self._flags.append(msg.flags)

    def __len__(self) -> int:
        return int(sum(self._n))

    @property
    def seq(self) -> np.ndarray:
        if not self._k0:
            return np.zeros(0, np.int64)
        return np.concatenate([np.arange(k, k + n, dtype=np.int64)
                               for k, n in zip(self._k0, self._n)])

    @property
    def raw(self) -> np.ndarray:
        return np.concatenate(self._raw) if self._raw else np.zeros((0, 9), np.int16)

    @property
    def records(self) -> np.ndarray:
        return np.concatenate(self._rec) if self._rec else np.zeros((0, 9), np.int16)

    @property
    def flags(self) -> np.ndarray:
        return np.repeat(np.asarray(self._flags, np.uint8), self._n)

    @property
    def t(self) -> np.ndarray:
        return self._mote.t0 + self.seq * self._mote.period


def _default_cal_factory():
    """``CalReceiver`` from motecal.firmware.mote_c when it can be loaded, else None."""
    try:
        from ..firmware.mote_c import CalReceiver
    except (ImportError, OSError):
        return None
    return CalReceiver


class Network:
    """N motes, one radio channel, a BaseStation and its serial line."""

    def __init__(self, samplers: dict, clock_ppm: dict, *, duration: float,
                 baud: int = 250000, loss: float = 0.0, batch: int = P.NINEDOF_BATCH,
                 seed: int = 1, rate_hz: float = P.NINEDOF_RATE_HZ, cal_factory="auto",
                 eeprom: dict | None = None, temperature: bool = True):
        if not 0.0 <= loss <= 1.0:
            raise ValueError("loss must be within 0..1")
        if not 1 <= batch <= 255:
            raise ValueError("batch must be 1..255")
        if baud <= 0:
            raise ValueError("baud must be positive")
        self.duration = float(duration)
        self.baud = int(baud)
        self.byte_time = 10.0 / self.baud
        self.batch = int(batch)
        self.loss = float(loss)
        self.loop = EventLoop()
        rng = random.Random(seed)
        self.channel = Channel(self.loop, random.Random(rng.getrandbits(64)), loss)
        self.bs = BaseStation(self, random.Random(rng.getrandbits(64)), baud=self.baud,
                              duration=self.duration)
        if cal_factory == "auto":
            cal_factory = _default_cal_factory()
        self.cal_available = cal_factory is not None
        self.motes: dict[int, SimMote] = {}
        self.sent: dict[int, SentLog] = {}
        for mote_id in sorted(samplers):
            cal = cal_factory(mote_id) if cal_factory is not None else None
            m = SimMote(self, mote_id, samplers[mote_id], clock_ppm.get(mote_id, 0.0),
                        random.Random(rng.getrandbits(64)), batch=self.batch,
                        rate_hz=rate_hz, duration=self.duration, cal=cal,
                        eeprom=(eeprom or {}).get(mote_id), temperature=temperature)
            m.bs_dropped = 0
            m.line_duplicates = 0           # sample messages the line carried twice
            self.motes[mote_id] = m
            self.sent[mote_id] = SentLog(m)
        self._segments: deque = deque()     # [start time, bytes, bytes already returned]
        self.bytes_returned = 0
        self.unread_bytes = 0               # produced while nobody listened (serve)

    # ---------------------------------------------------------------- hooks
    def uart_start(self, t: float, data: bytes) -> None:
        self._segments.append([t, data, 0])

    def eeprom_written(self, mote_id: int) -> None:
        """A mote finished writing a calibration image into its EEPROM."""

    def delivered(self, msg) -> None:
        if msg.on_line:                   # sent again after EBUSY: a duplicate on the line
            self.motes[msg.mote].line_duplicates += 1
            return
        msg.on_line = True
        if msg.bs_dropped:                # an earlier copy was dropped, this one got through
            msg.bs_dropped = False
            self.motes[msg.mote].bs_dropped -= msg.count
        self.sent[msg.mote].add(msg)

    # ---------------------------------------------------------------- API
    @property
    def now(self) -> float:
        return self.loop.now

    def run_until(self, t: float) -> bytes:
        """Run to simulated time ``t``; the serial bytes completed meanwhile."""
        self.loop.run_until(t)
        out = []
        segs = self._segments
        bt = self.byte_time
        while segs:
            seg = segs[0]
            start, data, done = seg
            n = len(data)
            upto = min(n, int((t - start) / bt + 1e-6))
            if upto > done:
                out.append(data[done:upto] if (done or upto < n) else data)
                seg[2] = upto
            if upto >= n:
                segs.popleft()
            else:
                break
        res = b"".join(out)
        self.bytes_returned += len(res)
        return res

    def write(self, data: bytes) -> None:
        """Bytes from the PC into the BaseStation's UART, from the current time."""
        self.bs.serial_write(data)

    @property
    def done(self) -> bool:
        """The session is over and every queue, radio and the line are empty."""
        return (self.loop.now >= self.duration and not self.loop.pending
                and not self._segments)

    def next_output_time(self) -> float:
        """When the next serial byte completes (inf if nothing is scheduled)."""
        if self._segments:
            start, data, done = self._segments[0]
            return start + (done + 1) * self.byte_time
        return self.loop.next_time()

    def note_unread(self, n: int) -> None:
        self.unread_bytes += n

    @property
    def stats(self) -> dict:
        """Counters: per mote (samples and frames), BaseStation, channel, line.

        Per mote, once ``done``: ``generated == delivered + dropped +
        radio_lost + bs_dropped`` (samples).
        """
        motes = {}
        for mid, m in self.motes.items():
            d = m.counters()
            d["bs_dropped"] = m.bs_dropped
            d["line_duplicates"] = m.line_duplicates
            d["delivered"] = len(self.sent[mid])
            motes[mid] = d
        return dict(
            now=self.loop.now, duration=self.duration, done=self.done,
            motes=motes, basestation=self.bs.counters(),
            channel=dict(frames=self.channel.frames, collisions=self.channel.collisions),
            line=dict(baud=self.baud, bytes_out=self.bs.bytes_out,
                      bytes_returned=self.bytes_returned, unread_bytes=self.unread_bytes,
                      bytes_in=self.bs.bytes_in))
