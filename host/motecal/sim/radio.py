"""One IEEE 802.15.4 channel and the RF230 MAC as TinyOS's rfxlink stack runs it.

Airtime (250 kbit/s, 32 us per byte) of a TinyOS AM data frame on the RF230::

    PHY   preamble 4 + SFD 1 + PHR 1                         =  6 bytes
    MAC   FCF 2 + DSN 1 + dest PAN 2 + dest 2 + src 2        =  9 bytes
    TinyOS network byte 1 (6LoWPAN dispatch 0x3F) + AM type 1 =  2 bytes
    payload                                                     n bytes
    FCS 2                                                     =  2 bytes

so ``n + 19`` bytes; an ack frame is PHY 6 + FCF 2 + DSN 1 + FCS 2 = 11 bytes
(352 us).  The AM group travels as the destination PAN.

Medium access (tos/lib/rfxlink, RF230RadioP values):

* RandomCollisionLayer: wait ``320 us + U(0, 4960 us)``, clear-channel
  assessment; if busy wait ``320 us + U(0, 2240 us)`` and assess again; if
  still busy the attempt returns EBUSY.  MessageBufferLayer repeats an EBUSY
  send up to 5 times.
* CCA looks at the last 128 us (8 symbols); the first bit goes on air 32 us
  after a clear decision (RF230 PLL_ON -> BUSY_TX plus SPI), so two nodes
  deciding within that window collide.
* Every node that hears a frame requesting an ack keeps off the air for
  864 us after it (RandomCollisionLayer's transmit barrier), protecting the ack.
* SoftwareAckLayer: the receiver sends the ack 256 us after the frame ends
  (no CCA); the sender gives up waiting 1000 us after its frame ended.
* UniqueLayer: a retransmission keeps its DSN; a receiver drops a frame
  whose (source, DSN) equals the last one it accepted from that source
  (it is still acked).
* PacketLink (built with PACKET_LINK): a message asking for an ack is sent
  at most ``1 + max_retries`` times, the same frame with the same DSN, until
  it is acked; EBUSY (the channel busy through all 5 rounds) ends it at once
  (PacketLinkLayerP passes the error up without another try) and sets
  ``ebusy``: the firmware then starts the message again (a new DSN).

Collisions: every node hears every other (one star cell).  Two transmissions
that overlap in time destroy each other at every receiver (half duplex: a node
also cannot receive while it transmits).  ``loss`` drops each surviving frame
(data or ack) independently at each receiver.
"""
from __future__ import annotations

BYTE_TIME = 32e-6                 # s per byte at 250 kbit/s
PHY_BYTES = 6
MAC_BYTES = 13                    # 9 MAC header + 2 TinyOS (network, AM type) + 2 FCS
ACK_BYTES = 11
CCA_TIME = 128e-6
TX_DELAY = 32e-6
ACK_DELAY = 256e-6
ACK_TIMEOUT = 1000e-6
BACKOFF_MIN = 320e-6
BACKOFF_INIT = 4960e-6
BACKOFF_CONG = 2240e-6
BARRIER = 32 * (-5 + 16 + 11 + 5) * 1e-6   # 864 us
EBUSY_ROUNDS = 5
BROADCAST = 0xFFFF


def data_airtime(payload_len: int) -> float:
    """Seconds on air for an AM data frame with ``payload_len`` payload bytes."""
    return (PHY_BYTES + MAC_BYTES + payload_len) * BYTE_TIME


ACK_AIRTIME = ACK_BYTES * BYTE_TIME


class Frame:
    """One transmission on the channel (data or ack)."""
    __slots__ = ("src", "dest", "group", "am_type", "payload", "dsn", "ack_req",
                 "is_ack", "start", "end", "corrupt", "mac", "msg", "data")

    def __init__(self, src, dest, group, am_type, payload, dsn, ack_req, mac, msg,
                 is_ack=False, data=None):
        self.src = src
        self.dest = dest
        self.group = group
        self.am_type = am_type
        self.payload = payload
        self.dsn = dsn
        self.ack_req = ack_req
        self.is_ack = is_ack
        self.mac = mac            # sending Mac
        self.msg = msg            # what the sender queued (mote Message / BS packet)
        self.data = data          # for an ack: the data frame it acknowledges
        self.corrupt = False
        self.start = self.end = 0.0


class Channel:
    """The shared medium: overlap detection, CCA, delivery, per-frame loss."""

    def __init__(self, loop, rng, loss: float = 0.0):
        self.loop = loop
        self.rng = rng
        self.loss = float(loss)
        self.air: list[Frame] = []      # frames on air, scheduled, or ended < CCA_TIME ago
        self.nodes: dict[int, object] = {}
        self.barrier_until = -1.0
        self.collisions = 0             # frames destroyed by overlap
        self.frames = 0

    def attach(self, addr: int, node) -> None:
        self.nodes[addr] = node

    def clear(self, t: float) -> bool:
        """Clear-channel assessment at ``t`` (and the ack barrier)."""
        if t < self.barrier_until:
            return False
        lo = t - CCA_TIME
        for f in self.air:
            if f.start <= t and f.end > lo:
                return False
        return True

    def transmit(self, frame: Frame, start: float, airtime: float) -> None:
        end = start + airtime
        frame.start, frame.end = start, end
        lo = self.loop.now - CCA_TIME
        air = self.air
        if air and air[0].end <= lo:
            air = [f for f in air if f.end > lo]
        for f in air:
            if f.start < end and start < f.end:
                if not f.corrupt:
                    f.corrupt = True
                    self.collisions += 1
                if not frame.corrupt:
                    frame.corrupt = True
                    self.collisions += 1
        air.append(frame)
        self.air = air
        self.frames += 1
        self.loop.at(end, self._end, frame)

    # ------------------------------------------------------------------
    def _received(self) -> bool:
        return self.loss <= 0.0 or self.rng.random() >= self.loss

    def _end(self, f: Frame) -> None:
        if f.is_ack:
            data = f.data
            mac = data.mac
            if not f.corrupt and self._received():
                mac.acked(data)
            else:
                if f.corrupt:
                    mac.stats_ack_collided += 1
                else:
                    mac.stats_ack_lost += 1
                self.loop.at(data.end + ACK_TIMEOUT, mac.ack_timeout, data)
            return
        mac = f.mac
        if f.corrupt:
            mac.stats_collided += 1
        elif f.ack_req:
            self.barrier_until = max(self.barrier_until, f.end + BARRIER)
        will_ack = False
        if not f.corrupt:
            loss = self.loss
            if f.dest != BROADCAST:
                node = self.nodes.get(f.dest)
                if node is not None:
                    if loss <= 0.0 or self.rng.random() >= loss:
                        if f.ack_req:
                            will_ack = True
                            self._send_ack(f)
                        node.on_frame(f)
                    else:
                        mac.stats_lost += 1
            else:
                for a, node in list(self.nodes.items()):
                    if a != mac.addr and (loss <= 0.0 or self.rng.random() >= loss):
                        node.on_frame(f)
        mac.tx_end(f, will_ack)

    def _send_ack(self, data: Frame) -> None:
        ack = Frame(data.dest, data.src, data.group, None, b"", data.dsn, False,
                    None, None, is_ack=True, data=data)
        self.transmit(ack, data.end + ACK_DELAY, ACK_AIRTIME)


class UniqueFilter:
    """A node's receiving UniqueLayer: a frame whose (source, DSN) equals the
    last one accepted from that source is a repeat (it is still acked)."""

    def __init__(self):
        self._last: dict[int, int] = {}

    def repeat(self, f) -> bool:
        """Whether ``f`` repeats the last frame taken from its source; if not,
        it becomes that frame."""
        if self._last.get(f.src) == f.dsn:
            return True
        self._last[f.src] = f.dsn
        return False


class Mac:
    """A node's sending side: CSMA rounds, link retries, ack wait.

    ``send(dest, group, am_type, payload, ack_req, msg, done, src=None)``
    sends one message (``src``: AM source if not this node's address);
    ``done(msg, ok)`` is called once, from the event loop.  One message at a
    time (the caller queues).
    """

    def __init__(self, addr: int, channel: Channel, rng, max_retries: int = 2):
        self.addr = addr
        self.channel = channel
        self.loop = channel.loop
        self.rng = rng
        self.max_retries = max_retries
        self.busy = False
        self._dsn = (addr << 4) & 0xFF          # UniqueLayer's start value
        self._frame: Frame | None = None
        self._done = None
        # counters
        self.stats_frames = 0          # data frames put on air
        self.stats_retries = 0         # attempts after the first
        self.stats_collided = 0        # own data frames destroyed by overlap
        self.stats_lost = 0            # own data frames lost (--loss) at the receiver
        self.stats_ack_collided = 0
        self.stats_ack_lost = 0
        self.stats_cca_busy = 0        # EBUSY rounds (channel busy twice)
        self.stats_failed = 0          # messages given up
        self.ebusy = False             # the last message given up ended in EBUSY

    def send(self, dest, group, am_type, payload, ack_req, msg, done, src=None) -> None:
        assert not self.busy
        self.busy = True
        self._dsn = (self._dsn + 1) & 0xFF
        self._what = (self.addr if src is None else src, dest, group, am_type, payload,
                      self._dsn, ack_req)
        self._msg = msg
        self._frame = None
        self._airtime = data_airtime(len(payload))
        self._done = done
        self._attempts = 0
        self._attempt()

    def _attempt(self) -> None:
        self._attempts += 1
        if self._attempts > 1:
            self.stats_retries += 1
        self._rounds = 0
        self._round()

    def _round(self) -> None:
        self._rounds += 1
        self._second = False
        self.loop.at(self.loop.now + BACKOFF_MIN + self.rng.random() * BACKOFF_INIT,
                     self._alarm, None)

    def _alarm(self, _) -> None:
        now = self.loop.now
        if self.channel.clear(now):
            # a fresh Frame per attempt keeps collision flags apart
            g = Frame(*self._what, self, self._msg)
            self._frame = g
            self.stats_frames += 1
            self.channel.transmit(g, now + TX_DELAY, self._airtime)
        elif not self._second:
            self._second = True
            self.loop.at(now + BACKOFF_MIN + self.rng.random() * BACKOFF_CONG,
                         self._alarm, None)
        else:
            self.stats_cca_busy += 1
            if self._rounds < EBUSY_ROUNDS:
                self._round()
            else:                          # EBUSY: PacketLink gives up at once
                self.stats_failed += 1
                self.ebusy = True
                self._finish(False)

    # called by the channel
    def tx_end(self, f: Frame, will_ack: bool) -> None:
        if not f.ack_req or f.dest == BROADCAST:
            self._finish(True)
        elif not will_ack:
            self.loop.at(f.end + ACK_TIMEOUT, self.ack_timeout, f)

    def acked(self, f: Frame) -> None:
        if f is self._frame and self.busy:
            self._finish(True)

    def ack_timeout(self, f: Frame) -> None:
        if f is self._frame and self.busy:
            self._failed_attempt()

    def _failed_attempt(self) -> None:
        if self._attempts <= self.max_retries:
            self._attempt()
        else:
            self.stats_failed += 1
            self.ebusy = False
            self._finish(False)

    def _finish(self, ok: bool) -> None:
        msg = self._msg
        done = self._done
        self.busy = False
        self._frame = None
        self._msg = None
        self._done = None
        done(msg, ok)

    def counters(self) -> dict:
        return dict(frames=self.stats_frames, retries=self.stats_retries,
                    collided=self.stats_collided, lost=self.stats_lost,
                    acks_collided=self.stats_ack_collided, acks_lost=self.stats_ack_lost,
                    cca_busy=self.stats_cca_busy, gave_up=self.stats_failed)
