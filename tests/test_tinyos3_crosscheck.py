"""Code nobody here wrote against ours: TinyOS's own tos.py (the tinyos3
package, a Python 3 port) reads the simulator's serial line at the AM level,
and talks to the simulated BaseStation the way TinyOS tools do (0x44 frames
with a sequence byte, waiting for the 0x43 ack), reaching a mote's
calibration code through the radio."""
import pytest

from motecal.line import protocol as P
from motecal.sim.world import World

tos = pytest.importorskip("tinyos3.tos")


class WorldSource:
    """tos.py's byte-source interface over a simulated world: reading a byte
    runs the world on until one is there; none within ``timeout`` simulated
    seconds is tos.Timeout."""

    def __init__(self, world, step=0.002):
        self.world, self.step = world, step
        self.buf = bytearray()
        self.timeout = None
        self.ackTimeout = 0.05
        self.debug, self._ts = False, None

    def getByte(self):
        deadline = self.world.now + (self.timeout if self.timeout is not None else 5.0)
        while not self.buf:
            if self.world.now >= deadline:
                raise tos.Timeout()
            self.buf += self.world.run_until(self.world.now + self.step)
        b = self.buf[0]
        del self.buf[0]
        return b

    def putBytes(self, data):
        self.world.write(bytes(data))

    def getTimeout(self):
        return self.timeout

    def setTimeout(self, t):
        self.timeout = t


def test_tos_am_reads_the_simulated_line_as_we_do():
    w = World(motes=2, session="idle", seed=5, duration=2.0)
    data = w.run_until(3.0)
    ours = [f.am() for f in P.decode_stream(data)]
    am = tos.AM(WorldSource(World(motes=2, session="idle", seed=5, duration=2.0)))
    theirs = []
    while len(theirs) < len(ours):
        m = am.read(timeout=1.0)
        if m is None:
            break
        theirs.append(P.AMPacket(m.destination, m.source, m.group, m.type, bytes(m.data)))
    assert len(ours) > 40 and theirs == ours
    kinds = {a.am_type for a in ours}
    assert P.AM_NINEDOF_SAMPLES_MSG in kinds and P.AM_NINEDOF_MOTE_STATUS_MSG in kinds
    assert {a.src for a in ours if a.am_type == P.AM_NINEDOF_SAMPLES_MSG} == {1, 2}


def test_tos_am_write_is_acked_by_the_basestation_and_reaches_the_mote():
    w = World(motes=2, session="idle", seed=6, duration=60.0)
    w.run_until(0.5)
    src = WorldSource(w)
    am = tos.SimpleAM(src)
    replies = []
    am.oobHook = lambda m: replies.append(m)        # frames seen while waiting for the ack
    query = P.CAL_QUERY.pack(mote=2, offset=0)
    # a whole active message as tos.py takes it: dest 2, src 0, length, group, type, data
    packet = list(P.AM_HEADER.pack(2, 0, len(query), P.DEFAULT_GROUP,
                                   P.AM_NINEDOF_CAL_QUERY_MSG) + query)
    assert am.write(packet, P.AM_NINEDOF_CAL_QUERY_MSG, timeout=1.0) is True   # 0x43 ack
    for _ in range(400):
        m = am.read(timeout=0.5)
        if m is not None and m.type == P.AM_NINEDOF_CAL_REPORT_MSG:
            break
    else:
        pytest.fail("no CAL_REPORT from mote 2")
    rep = P.CAL_REPORT.unpack(bytes(m.data))
    assert m.source == 2 and rep["mote"] == 2 and rep["version"] == 0 and rep["offset"] == 0
    assert rep["len"] == P.NINEDOF_FRAG_DATA
    # broadcast, as SimpleAM addresses by default: the mote named inside answers
    packet = list(P.AM_HEADER.pack(P.AM_BROADCAST, 0, len(query), P.DEFAULT_GROUP,
                                   P.AM_NINEDOF_CAL_QUERY_MSG) + query)
    assert am.write(packet, P.AM_NINEDOF_CAL_QUERY_MSG, timeout=1.0) is True
    srcs = set()
    for _ in range(400):
        m = am.read(timeout=0.5)
        if m is not None and m.type == P.AM_NINEDOF_CAL_REPORT_MSG:
            srcs.add(m.source)
            break
    assert srcs == {2}
