"""The simulated BaseStation: TinyOS apps/BaseStation (BaseStationP.nc) plus our
status message, and its UART.

* Radio -> serial: every frame heard (any destination) is forwarded with its
  AM destination, source, group and type; a queue of 12 message buffers
  (including the one on the UART); full -> dropped (``radio_drops``).  Frames
  addressed to the BaseStation with an ack request are acked by the radio
  stack whether or not the queue has room; a repeated frame (same source and
  DSN as the last accepted frame) is acked and dropped (UniqueLayer).
* Serial -> radio: 0x44 and 0x45 frames from the PC carrying an AM packet go
  into a second queue of 12 (full -> ``serial_drops``) and are sent by radio
  to their AM destination, with the BaseStation's own address as the AM
  source (the radio's AM layer sets it) and the local group (0x22), as
  NineDofBaseP does: a unicast asks for an ack and is sent at most
  1 + NINEDOF_BS_RETRIES (2) times with the same DSN (PacketLink), then
  dropped and counted in ``radio_fail``; a send that ends in EBUSY (the
  channel busy through all 5 rounds) is started again, at most 2 more
  times; a broadcast goes once, unacked.  Every good 0x44 frame is
  acknowledged on the serial line by a 0x43 frame with the same sequence
  byte (SerialP), sent before the next queued packet.
* Every 2 s a ninedof_bs_status_msg (source 0, destination 0xFFFF) goes out
  from its own buffer (not one of the 12), before the next queued packet, so
  it gets through when the queue is full; a status still waiting when the
  next is due is replaced (``status_dropped``).
* UART: ``baud`` with 10 bits per byte (8N1); frames exactly as tos/lib/serial
  sends them (protocol.encode_am: 0x7E, 0x45, dispatch 0, AM header, payload,
  CRC, escaped, 0x7E) back to back.
"""
from __future__ import annotations

from collections import deque

from ..line import protocol as P
from .mote import Message
from .radio import Mac, UniqueFilter

ADDR = 0
QUEUE_LEN = 12            # NINEDOF_BS_QUEUE
RETRIES = 2               # NINEDOF_BS_RETRIES
STATUS_PERIOD = P.NINEDOF_STATUS_PERIOD_MS / 1000.0


class BaseStation:
    def __init__(self, net, rng, *, baud: int, duration: float):
        self.net = net
        self.loop = net.loop
        self.byte_time = 10.0 / baud
        self.duration = duration
        self.mac = Mac(ADDR, net.channel, rng, max_retries=RETRIES)
        net.channel.attach(ADDR, self)
        self.uart_q: deque = deque()          # (frame bytes, origin Message | None)
        self.acks: deque = deque()            # 0x43 frames waiting for the UART
        self.radio_q: deque = deque()         # AMPacket from the PC
        self._uart_busy = False
        self._uart_cur = None
        self._status_frame = None             # own buffer, not one of the 12
        self._rx_free = 0.0                   # when the UART receiver is next idle
        self._decoder = P.FrameDecoder()
        self._unique = UniqueFilter()
        self._busy_tries = 0                  # EBUSY refusals of the radio queue's head
        # counters (bs_status fields and more)
        self.radio_rx = 0
        self.radio_drops = 0
        self.serial_rx = 0
        self.serial_drops = 0
        self.radio_fail = 0
        self.serial_fail = 0
        self.duplicates = 0
        self.serial_acks = 0
        self.status_sent = 0
        self.status_dropped = 0
        self.bytes_out = 0
        self.bytes_in = 0
        self.loop.at(rng.random() * STATUS_PERIOD, self._status, None)

    # ------------------------------------------------------------ radio -> serial
    def on_frame(self, f) -> None:
        if self._unique.repeat(f):
            self.duplicates += 1
            return
        self.radio_rx += 1
        msg = f.msg if isinstance(f.msg, Message) and f.msg.count else None
        if msg is not None:
            msg.at_bs = True
        if len(self.uart_q) >= QUEUE_LEN:
            self.radio_drops += 1
            if msg is not None and msg.count and not (msg.on_line or msg.bs_dropped):
                msg.bs_dropped = True        # unless a copy sent again gets through
                self.net.motes[msg.mote].bs_dropped += msg.count
            return
        frame = P.encode_am(P.AMPacket(f.dest, f.src, f.group, f.am_type, f.payload))
        self.uart_q.append((frame, msg))
        self._uart_kick()

    def _status(self, _) -> None:
        now = self.loop.now
        if now >= self.duration:
            return
        payload = P.BS_STATUS.pack(
            radio_rx=self.radio_rx & 0xFFFF, radio_drops=self.radio_drops & 0xFFFF,
            serial_rx=self.serial_rx & 0xFFFF, serial_drops=self.serial_drops & 0xFFFF,
            radio_fail=self.radio_fail & 0xFFFF, serial_fail=self.serial_fail & 0xFFFF)
        if self._status_frame is not None:
            self.status_dropped += 1            # the previous one never got out
        self._status_frame = P.encode_am(P.AMPacket(P.AM_BROADCAST, ADDR, P.DEFAULT_GROUP,
                                                    P.AM_NINEDOF_BS_STATUS_MSG, payload))
        self._uart_kick()
        self.loop.at(now + STATUS_PERIOD, self._status, None)

    # ------------------------------------------------------------ UART out
    def _uart_kick(self) -> None:
        if self._uart_busy:
            return
        if self.acks:
            data = self.acks.popleft()
            self._uart_cur = None
        elif self._status_frame is not None:
            data, self._status_frame = self._status_frame, None
            self._uart_cur = None
            self.status_sent += 1
        elif self.uart_q:
            data, _ = self.uart_q[0]
            self._uart_cur = self.uart_q
        else:
            return
        self._uart_busy = True
        now = self.loop.now
        self.net.uart_start(now, data)
        self.bytes_out += len(data)
        self.loop.at(now + len(data) * self.byte_time, self._uart_done, None)

    def _uart_done(self, _) -> None:
        self._uart_busy = False
        if self._uart_cur is not None:
            _, msg = self.uart_q.popleft()
            if msg is not None:
                self.net.delivered(msg)
            self._uart_cur = None
        self._uart_kick()

    # ------------------------------------------------------------ serial -> radio
    def serial_write(self, data: bytes) -> None:
        """Bytes from the PC start arriving now, at the line rate."""
        if not data:
            return
        start = max(self.loop.now, self._rx_free)
        self._rx_free = start + len(data) * self.byte_time
        self.bytes_in += len(data)
        self.loop.at(self._rx_free, self._serial_rx, bytes(data))

    def _serial_rx(self, data: bytes) -> None:
        for fr in self._decoder.feed(data):
            if fr.protocol == P.PROTO_PACKET_ACK:
                self.acks.append(P.encode_ack(fr.seq))
                self.serial_acks += 1
                self._uart_kick()
            if fr.protocol in (P.PROTO_PACKET_ACK, P.PROTO_PACKET_NOACK):
                am = fr.am()
                if am is None:
                    continue
                self.serial_rx += 1
                if len(self.radio_q) >= QUEUE_LEN:
                    self.serial_drops += 1
                    continue
                self.radio_q.append(am)
                self._radio_kick()

    def _radio_kick(self) -> None:
        if self.mac.busy or not self.radio_q:
            return
        am = self.radio_q[0]
        self.mac.send(am.dest, P.DEFAULT_GROUP, am.am_type, am.payload,
                      am.dest != P.AM_BROADCAST, am, self._radio_done)

    def _radio_done(self, am, ok: bool) -> None:
        if not ok and self.mac.ebusy and self._busy_tries < RETRIES:
            self._busy_tries += 1                 # the channel was busy: send it again
        else:
            self.radio_q.popleft()
            self._busy_tries = 0
            if not ok:
                self.radio_fail += 1
        self._radio_kick()

    def counters(self) -> dict:
        d = dict(radio_rx=self.radio_rx, radio_drops=self.radio_drops,
                 serial_rx=self.serial_rx, serial_drops=self.serial_drops,
                 radio_fail=self.radio_fail, serial_fail=self.serial_fail,
                 duplicates=self.duplicates, serial_acks=self.serial_acks,
                 status_sent=self.status_sent, status_dropped=self.status_dropped,
                 bytes_out=self.bytes_out, bytes_in=self.bytes_in,
                 uart_queue=len(self.uart_q), radio_queue=len(self.radio_q))
        return d
