"""A simulated sensor mote: what the firmware in tinyos/ does, in simulated time.

* Sample clock: exactly ``rate_hz`` (125 Hz) in the mote's own time base, which
  runs ``clock_ppm`` fast against true time, from a random start phase in the
  first period.  Sample ``k`` is taken at true time ``t0 + k / (rate * (1 + ppm
  1e-6))`` and gets sequence number ``k mod 65536``.
* One instant per record: all nine axes of record ``k`` are of sample time
  ``k``.  The firmware completes a record with the field that the next read
  brings (the HMC5883L returns the measurement the previous read started:
  ninedof_align_push), so record ``k`` is ready at sample time ``k + 1``.
* Batching: ``batch`` records per ninedof_samples_msg (``seq`` = first
  record's); at the end of the session the partial batch is sent.  As in
  tinyos/ninedof_sampling.c, records are kept raw and corrected with the set
  in force when the batch is packed, so one set and one flags byte cover the
  whole message.
* Radio, as NineDofAppP sends: three buffers take turns on the radio in
  round robin (AMSenderC's queue), in the firmware's order -- samples,
  status, calibration reply.  Group 0x22, AM source = mote id.
  - Samples: a send queue of 4 messages including the one on the radio; a
    batch that finds it full is dropped and its samples counted in
    ``dropped``.  Unicast to the BaseStation (address 0), ack requested, at
    most 2 retries of the same frame (PacketLink: same DSN).  A send that
    ends in EBUSY (the channel busy through all 5 rounds) is started again,
    at most 2 more times, with a new DSN: if an earlier try reached the
    BaseStation unacknowledged, it forwards the message twice (the logger
    drops the duplicate; ``Network`` counts it in ``line_duplicates``).  A message given up (``send_fail``, the only sends the
    firmware counts) whose
    frames all failed to reach the BaseStation loses its samples
    (``radio_lost``); one whose acks were lost got through.
  - Status: a ninedof_mote_status_msg every 2 s (mote time, random phase)
    from its own buffer, to the BaseStation, no ack, no retry; one still on
    its way when the next is due is skipped (``status_dropped``).
  - Temperature: a ninedof_mote_temp_msg every NINEDOF_TEMP_PERIOD_MS (1 s,
    mote time, random phase), sent as status is (own buffer, no ack, no
    retry, skipped while the last is on its way: ``temp_dropped``): the sum
    of the raw ITG3200 TEMP_OUT of every sample read since the last message
    (``round(temp_raw(T))`` of the board temperature ``T`` at the sample's
    time, ``board_temperature``), their count, and the seq of the newest.
    ``temperature=False`` is an image built before that message: it sends none.
  - Calibration: frames addressed to this mote (or broadcast) go to
    ``CalReceiver.handle`` (the firmware's C code through ctypes; an image
    built before the temperature terms, ``temperature=False``, answers as
    ``mote_c.handle_as_pre_temperature_image``: it refuses a set with
    temperature terms and does not report the stored set); the reply
    goes to the frame's AM source from its own buffer, sent as a sample
    message is (ack, 2 retries, EBUSY: again);
    a reply while the previous one is still on its way is not sent
    (``replies_dropped``: the host repeats its message).
  A frame repeated by its sender with the same DSN as the last one accepted
  from that sender is dropped (UniqueLayer).
* Correction: samples are corrected with ``CalReceiver.correct`` and
  flagged with ``CalReceiver.flags()``.  Without it: raw records, flags 0.
* Status: ``ninedof_status_pack`` of the firmware (``mote_c.status_payload``)
  packs the message from the mote's counters and the set in force; the
  counters the simulation has no cause for (``i2c_errors``, ``late`` and the
  bus fault counters) are 0.
* EEPROM: an accepted set is persisted by the firmware's own background
  writer (``mote_c.EepromWriter``, one byte per 3.4 ms while sampling goes
  on, about 0.37 s for a plain set and 0.58 s for one with temperature
  terms) into the mote's EEPROM, which a World can keep in a file across
  runs, then read back: only then is it stored (the file written, and the
  report's stored set says so).  The simulation advances only as its reader
  reads: a run stopped before the write completed keeps the older set in the
  file, as a mote reset or switched off within that time does.  At boot the
  set in force is restored from it, as the firmware does; ``reboot()``
  models a reset in the running world.
"""
from __future__ import annotations

import math
import sys
from collections import deque

import numpy as np

from ..line import protocol as P
from .radio import Mac, UniqueFilter

QUEUE_LEN = 4             # NINEDOF_SEND_QUEUE
MAX_RETRIES = 2           # NINEDOF_RETRIES
SAMPLES, STATUS, TEMP, REPLY = range(4)     # the radio's clients, in round-robin order
CLIENTS = 4
STATUS_PERIOD = P.NINEDOF_STATUS_PERIOD_MS / 1000.0
TEMP_PERIOD = P.NINEDOF_TEMP_PERIOD_MS / 1000.0
DEFAULT_TEMP_C = 25.0     # a board whose model has no temperature of its own
BS_ADDR = 0
READ_BLOCK = 1250         # samples asked from the physics at a time
_EPS = 1e-9


class Message:
    """One message of a mote (samples, status or calibration reply)."""
    __slots__ = ("mote", "am_type", "payload", "k0", "count", "raw", "records", "flags",
                 "at_bs", "dest", "busy_tries", "on_line", "bs_dropped")

    def __init__(self, mote, am_type, payload, k0=None, count=0, raw=None, records=None,
                 flags=0, dest=BS_ADDR):
        self.dest = dest
        self.busy_tries = 0       # sends the busy channel refused (EBUSY)
        self.on_line = False      # the BaseStation put it on the serial line
        self.bs_dropped = False   # counted as dropped by the BaseStation (queue full)
        self.mote = mote
        self.am_type = am_type
        self.payload = payload
        self.k0 = k0
        self.count = count
        self.raw = raw
        self.records = records
        self.flags = flags
        self.at_bs = False        # the BaseStation received it (even if unacked)


def board_temperature(sampler):
    """The board temperature of a sampler's board as a function of time (s
    since power-on, the session's start) -> degrees C: the board model's
    ``temperature_c(t)`` (sim.model, the thermal model), or a constant
    ``DEFAULT_TEMP_C`` for a sampler without a board that has one."""
    f = getattr(getattr(sampler, "board", None), "temperature_c", None)
    if f is not None:
        return f
    return lambda t: np.full(np.shape(t), DEFAULT_TEMP_C)


class SimMote:
    def __init__(self, net, mote_id: int, sampler, clock_ppm: float, rng, *,
                 batch: int, rate_hz: float, duration: float, cal=None,
                 eeprom: bytearray | None = None, temperature: bool = True):
        self.net = net
        self.loop = net.loop
        self.id = int(mote_id)
        self.sampler = sampler
        self.batch = int(batch)
        self.clock_ppm = float(clock_ppm)
        scale = 1.0 + self.clock_ppm * 1e-6
        self.period = 1.0 / (rate_hz * scale)
        self.t0 = rng.random() * self.period
        if math.isinf(duration):
            self.n_total = sys.maxsize
        elif duration > self.t0:
            n = math.ceil((duration - self.t0) / self.period)
            while n > 0 and self.t0 + (n - 1) * self.period >= duration:
                n -= 1
            while self.t0 + n * self.period < duration:
                n += 1
            self.n_total = n
        else:
            self.n_total = 0
        self.duration = duration
        self.read_ahead = READ_BLOCK           # samples asked ahead (1: a trajectory decided
        #                                        as it goes, sim.person)
        self.status_period = STATUS_PERIOD / scale
        self.cal = cal
        self.ee = None
        if cal is not None and hasattr(cal, "image"):
            from ..firmware.mote_c import EepromWriter
            self.ee = EepromWriter(cal, eeprom)        # restores the set in force
        self._ee_writing = False
        self._boots = 0                               # reboot() count: stale writer steps
        self.eeprom_writes = 0                        # images written and read back
        self.reboots = 0
        self._flags = int(cal.flags()) if cal is not None else 0   # changes only in handle()
        self.mac = Mac(self.id, net.channel, rng, max_retries=MAX_RETRIES)
        net.channel.attach(self.id, self)
        self.queue: deque[Message] = deque()   # sample messages
        self.status_msg: Message | None = None  # its own buffer
        self.temp_msg: Message | None = None    # its own buffer
        self.reply_msg: Message | None = None   # its own buffer
        self._turn = REPLY                      # client served last (round robin)
        self._unique = UniqueFilter()
        self.next_k = 0                      # first sample not yet put into a message
        self._buf = np.zeros((0, 9), np.int16)
        self._buf_k0 = 0
        # counters (samples unless said otherwise)
        self.dropped = 0                     # send queue full
        self.radio_lost = 0                  # in messages given up by the radio
        self.msgs_dropped = 0                # sample messages dropped (queue full)
        self.status_sent = 0
        self.status_dropped = 0
        self.replies = 0
        self.replies_dropped = 0             # reply buffer still busy
        self.replies_failed = 0              # replies never acked
        self.send_fail = 0                   # sample messages given up (as the firmware)
        self.temp_sent = 0                   # temperature messages handed to the radio
        self.temp_dropped = 0                # ... skipped: the last one still on its way
        self.temps: list[tuple] = []         # (newest sample k, count, temp_sum) of each
        self._temp_k = 0                     # first sample not yet in a temperature sum
        self.temperature_c = board_temperature(sampler)
        self._temp_reads = bool(temperature)  # the image reads TEMP_OUT
        self._temp_mean = False              # a second's mean is in force
        self._temp_latest = None             # before it: the reading in force
        self._schedule_batch()
        self.loop.at(rng.random() * self.status_period, self._status, None)
        if temperature:
            self.temp_period = TEMP_PERIOD / scale
            self.loop.at(rng.random() * self.temp_period, self._temperature, None)

    # ------------------------------------------------------------------ samples
    def generated(self, now: float | None = None) -> int:
        """Samples taken up to ``now`` (true time)."""
        now = self.loop.now if now is None else now
        if now < self.t0:
            return 0
        return min(self.n_total, int(math.floor((now - self.t0) / self.period + _EPS)) + 1)

    def sample_times(self, k0: int, k1: int) -> np.ndarray:
        return self.t0 + np.arange(k0, k1, dtype=np.float64) * self.period

    def _raw(self, k0: int, k1: int) -> np.ndarray:
        end = self._buf_k0 + len(self._buf)
        if k1 > end:
            upto = max(k1, min(end + self.read_ahead, self.n_total))
            new = np.asarray(self.sampler.read(self.sample_times(end, upto)), np.int16)
            keep = self._buf[k0 - self._buf_k0:]
            self._buf = np.concatenate([keep, new]) if len(keep) else new
            self._buf_k0 = k0
        i = k0 - self._buf_k0
        return self._buf[i:i + (k1 - k0)]

    def _schedule_batch(self) -> None:
        if self.next_k >= self.n_total:
            return
        k_end = min(self.next_k + self.batch, self.n_total)
        # the last record is complete at the next period's read
        self.loop.at(self.t0 + k_end * self.period, self._batch_event, None)

    def _batch_event(self, _) -> None:
        k_end = min(self.next_k + self.batch, self.n_total)
        self._emit(self.next_k, k_end)
        self._schedule_batch()

    def _emit(self, k0: int, k1: int) -> None:
        self.next_k = k1
        raw = self._raw(k0, k1)
        flags = self._flags
        rec = raw
        if self.cal is not None:
            self._early_temperature(k1)
            if flags & P.FLAG_CORRECTED:
                rec = np.asarray(self.cal.correct(raw), np.int16)
        if len(self.queue) >= QUEUE_LEN:
            self.dropped += k1 - k0
            self.msgs_dropped += 1
            return
        payload = P.pack_samples(k0 & 0xFFFF, flags, rec)
        self.queue.append(Message(self.id, P.AM_NINEDOF_SAMPLES_MSG, payload, k0, k1 - k0,
                                  raw, rec, flags))
        self._kick()

    # ------------------------------------------------------------------ radio
    def _pending(self, client: int) -> Message | None:
        if client == SAMPLES:
            return self.queue[0] if self.queue else None
        if client == TEMP:
            return self.temp_msg
        return self.status_msg if client == STATUS else self.reply_msg

    def _kick(self) -> None:
        """Start the next send: the first client after the one served last
        that has a message (AMQueueP's round robin)."""
        if self.mac.busy:
            return
        for k in range(1, CLIENTS + 1):
            client = (self._turn + k) % CLIENTS
            m = self._pending(client)
            if m is None:
                continue
            self._turn = client
            if client in (STATUS, TEMP):    # no ack, no retry
                self.mac.send(BS_ADDR, P.DEFAULT_GROUP, m.am_type, m.payload, False, m,
                              self._sent)
            else:
                self.mac.send(m.dest, P.DEFAULT_GROUP, m.am_type, m.payload, True, m,
                              self._sent)
            return

    def _sent(self, msg: Message, ok: bool) -> None:
        if msg is self.status_msg:
            self.status_msg = None
        elif msg is self.temp_msg:
            self.temp_msg = None
        elif not ok and self.mac.ebusy and msg.busy_tries < MAX_RETRIES:
            msg.busy_tries += 1           # the channel was busy: the app sends it again
        elif msg is self.reply_msg:
            self.reply_msg = None
            if not ok:
                self.replies_failed += 1
        else:
            self.queue.popleft()
            if not ok:
                self.send_fail += 1
                if not msg.at_bs:          # no ack, but the BaseStation may have it anyway
                    self.radio_lost += msg.count
        self._kick()

    def on_frame(self, f) -> None:
        """A data frame heard on the radio (any destination).  Like TinyOS's
        AM layer, the mote takes frames for its own address and broadcasts;
        the calibration code then checks the mote id inside the message."""
        if f.dest not in (self.id, P.AM_BROADCAST) or self.cal is None:
            return
        if self._unique.repeat(f):                   # a repeat of the frame it has
            return
        if self._temp_reads:
            reply = self.cal.handle(f.am_type, bytes(f.payload))
        else:                                      # an image before the temperature terms
            from ..firmware.mote_c import handle_as_pre_temperature_image
            reply = handle_as_pre_temperature_image(self.cal, f.am_type, bytes(f.payload))
        self._flags = int(self.cal.flags())
        if self.ee is not None:
            if self.ee.poll() and not self._ee_writing:
                self._ee_writing = True
                self.loop.at(self.loop.now + self.ee.BYTE_TIME_S, self._ee_step, self._boots)
        elif getattr(self.cal, "dirty", False):   # a stand-in receiver: persisted at once
            self.cal.mark_persisted()
        if reply:
            rtype, rpayload = reply
            if self.reply_msg is not None:          # the previous reply is on its way
                self.replies_dropped += 1
                return
            self.reply_msg = Message(self.id, rtype, bytes(rpayload), dest=f.src)
            self.replies += 1
            self._kick()

    def _ee_step(self, boot) -> None:
        """One EEPROM byte write of the background writer; once every byte is
        written (the last write done: one byte time after it started), the
        slot read back and checked."""
        if boot != self._boots:                     # the mote was reset meanwhile
            return
        if self.ee.step():
            self.loop.at(self.loop.now + self.ee.BYTE_TIME_S, self._ee_step, boot)
            return
        if self.ee.pending:
            # the file first: the receiver reports the set stored only after this
            self.net.eeprom_written(self.id)
            if self.ee.check() == self.ee.AGAIN:
                self.loop.at(self.loop.now + self.ee.BYTE_TIME_S, self._ee_step, boot)
                return
            self.eeprom_writes += 1
        self._ee_writing = False

    def reboot(self) -> None:
        """A reset of the mote (its RESET pin, or power lost and back): the
        EEPROM keeps what was written of it, the calibration state is lost
        and restored from the EEPROM at boot (a write under way stops), as
        the firmware does.  Simplified: the sample clock, its sequence
        numbers and the radio carry on (the firmware restarts them)."""
        self._boots += 1
        if self.cal is None or self.ee is None:
            return
        from ..firmware.mote_c import EepromWriter
        self.cal = type(self.cal)(self.id)
        self.ee = EepromWriter(self.cal, self.ee.eeprom)
        self._ee_writing = False
        self._flags = int(self.cal.flags())
        self._temp_mean = False
        self._temp_latest = None
        self.reboots += 1

    # ------------------------------------------------------------------ status
    def _status(self, _) -> None:
        now = self.loop.now
        if now >= self.duration:
            return
        from ..firmware.mote_c import CalReceiver, status_payload
        rx = self.cal if isinstance(self.cal, CalReceiver) else None
        payload = status_payload(rx, seq=self.generated(), dropped=self.dropped,
                                 send_fail=self.send_fail)
        if self.status_msg is not None:               # the last one is still on its way
            self.status_dropped += 1
        else:
            self.status_msg = Message(self.id, P.AM_NINEDOF_MOTE_STATUS_MSG, payload)
            self.status_sent += 1
            self._kick()
        self.loop.at(now + self.status_period, self._status, None)

    # ------------------------------------------------------------- temperature
    def _temp_raw(self, k0: int, k1: int) -> np.ndarray:
        """The raw TEMP_OUT readings of samples k0..k1-1."""
        return np.clip(np.rint(P.temp_raw(self.temperature_c(self.sample_times(k0, k1)))),
                       -32768, 32767).astype(np.int64)

    def _early_temperature(self, k1: int) -> None:
        """As the firmware (NineDofAppP processSamples): until the first
        second's mean is in force, the batch that the read of sample k1
        completes is corrected at that read's own TEMP_OUT (set when it
        changed), not at the sensors' reference temperature."""
        if self._temp_mean or not self._temp_reads or not hasattr(self.cal, "set_temperature"):
            return
        t = int(self._temp_raw(k1, k1 + 1)[0])
        if t != self._temp_latest:
            self._temp_latest = t
            self.cal.set_temperature(t)

    def _temperature(self, _) -> None:
        """The temperature message: every sample read since the last one
        contributed its raw TEMP_OUT reading (the burst read of the gyroscope)."""
        now = self.loop.now
        if now >= self.duration:
            return
        k1 = self.generated(now)
        k0 = self._temp_k
        self._temp_k = k1
        raw = self._temp_raw(k0, k1)
        count = min(k1 - k0, 255)
        total = int(raw[len(raw) - count:].sum())
        newest = k1 - 1
        payload = P.MOTE_TEMP.pack(seq=max(newest, 0) & 0xFFFF, count=count, reserved=0,
                                   temp_sum=total)
        if count and hasattr(self.cal, "set_temperature"):
            # as the firmware: the period's mean (rounded half away from zero,
            # ninedof_temp_pack) is the on-mote correction's temperature from now on
            mean = (abs(total) + count // 2) // count
            self.cal.set_temperature(mean if total >= 0 else -mean)
            self._temp_mean = True
        if self.temp_msg is not None:                 # the last one is still on its way
            self.temp_dropped += 1
        else:
            self.temp_msg = Message(self.id, P.AM_NINEDOF_MOTE_TEMP_MSG, payload)
            self.temps.append((newest, count, total))
            self.temp_sent += 1
            self._kick()
        self.loop.at(now + self.temp_period, self._temperature, None)

    # ------------------------------------------------------------------ stats
    def counters(self) -> dict:
        d = dict(generated=self.generated(), dropped=self.dropped,
                 radio_lost=self.radio_lost, msgs_dropped=self.msgs_dropped,
                 status_sent=self.status_sent, status_dropped=self.status_dropped,
                 replies=self.replies, replies_dropped=self.replies_dropped,
                 replies_failed=self.replies_failed, eeprom_writes=self.eeprom_writes,
                 temp_sent=self.temp_sent, temp_dropped=self.temp_dropped,
                 queued=sum(m.count for m in self.queue), clock_ppm=self.clock_ppm)
        d.update(self.mac.counters())
        d["send_fail"] = self.send_fail          # sample messages, as the firmware counts
        return d
