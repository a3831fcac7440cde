"""The mote status message's fault counters (tinyos/NineDofMsg.h: i2c_nacks,
bus_resets, chip_reinits, appended; tinyos/ninedof_fault.h counts them) on
the host: the new message decodes with them, a mote built before them sends
the shorter message and is still understood (the general rule: a message
grows at its end, test_protocol.py), and the simulated mote's message is
packed by the firmware's own C."""
import numpy as np
import pytest

from motecal.capture.link import MoteLink
from motecal.firmware import mote_c
from motecal.line import protocol as P

from test_sim_network import make_net, run_all


def _am(payload):
    return P.AMPacket(0, 7, P.DEFAULT_GROUP, P.AM_NINEDOF_MOTE_STATUS_MSG, payload)


def test_new_status_message_carries_the_fault_counters():
    payload = P.MOTE_STATUS.pack(seq=9, late=2, i2c_nacks=60, bus_resets=0xFFFF,
                                 chip_reinits=3)
    assert len(payload) == 20
    msg = P.decode_message(_am(payload))
    assert (msg["i2c_nacks"], msg["bus_resets"], msg["chip_reinits"]) == (60, 0xFFFF, 3)
    assert msg["seq"] == 9 and msg["late"] == 2


def test_status_message_of_an_older_mote_is_accepted():
    old = P.MOTE_STATUS.pack(seq=5, dropped=1, i2c_errors=4, late=2)[:14]
    assert P.MOTE_STATUS.earlier == (14,) and P.MOTE_STATUS_FAULTS == (
        "i2c_nacks", "bus_resets", "chip_reinits")
    msg = P.decode_message(_am(old))
    assert msg == dict(seq=5, version=0, sensors=0, reserved=0, dropped=1, send_fail=0,
                       i2c_errors=4, late=2)
    assert not set(P.MOTE_STATUS_FAULTS) & set(msg)
    for n in (13, 15, 19):                           # no layout of the message: refused
        assert P.decode_message(_am(P.MOTE_STATUS.pack()[:n])) is None
    # a newer mote's longer message: the fields known here
    newer = P.decode_message(_am(P.MOTE_STATUS.pack(late=3, chip_reinits=1) + b"\1\2"))
    assert newer["late"] == 3 and newer["chip_reinits"] == 1 and len(newer) == 11


def test_simulated_mote_sends_the_firmware_layout():
    """The simulated mote's status message is packed by the firmware's own
    ninedof_status_pack (mote_c.status_payload): its counters, the set in force."""
    net = make_net(1, duration=4.5, cal_factory=mote_c.CalReceiver)
    frames = P.decode_stream(run_all(net))
    status = [f.am() for f in frames
              if f.am() and f.am().am_type == P.AM_NINEDOF_MOTE_STATUS_MSG]
    assert len(status) == 2
    mote = net.motes[1]
    for am in status:
        assert len(am.payload) == P.MOTE_STATUS.size == 20
        msg = P.decode_message(am)
        assert [msg[k] for k in P.MOTE_STATUS_FAULTS] == [0, 0, 0]   # no bus faults simulated
        assert 0 < msg["seq"] <= mote.generated() and msg["version"] == 0
    # byte for byte the C's packing of the same counters
    assert mote_c.status_payload(mote.cal, seq=5, dropped=6, send_fail=0x10007, late=8,
                                 bus_resets=9) == P.MOTE_STATUS.pack(
        seq=5, dropped=6, send_fail=7, late=8, bus_resets=9)
    with pytest.raises(TypeError, match="unknown status counters"):
        mote_c.status_payload(mote.cal, sequence=1)


def test_simulated_status_carries_the_set_in_force():
    from motecal.sim.world import World, WorldPort
    from motecal.upload.uploader import Uploader
    from motecal.upload.link import Link
    from motecal.firmware import fixedpoint as FP
    w = World(motes=1, session="idle", seed=3, duration=60.0)
    port = WorldPort(w)
    calset = FP.pack_calset(1, 5, {"gyro": FP.FixedSensor(np.eye(3, dtype=int) << 14,
                                                         np.array([100, -100, 7]), 14)})
    up = Uploader(Link(port), 1)
    up.stage(calset)
    up.apply(5, P.crc16(calset))
    out = bytearray()
    t = w.now
    while w.now < t + 4.5:
        out += w.run_until(w.now + 0.1)
    status = [P.decode_message(f.am()) for f in P.decode_stream(bytes(out))
              if f.am() and f.am().am_type == P.AM_NINEDOF_MOTE_STATUS_MSG]
    assert status and all((s["version"], s["sensors"]) == (5, 0b010) for s in status)


def test_the_link_keeps_the_fault_counters_of_new_and_old_motes():
    link = MoteLink(7)
    new = P.decode_message(_am(P.MOTE_STATUS.pack(late=1, i2c_nacks=4, bus_resets=5,
                                                  chip_reinits=6)))
    link.status(new)
    assert [link.c[k] for k in ("mote_late", "mote_i2c_nacks", "mote_bus_resets",
                                "mote_chip_reinits")] == [1, 4, 5, 6]
    old = P.decode_message(_am(P.MOTE_STATUS.pack(late=2)[:14]))
    link.status(old)                               # an older mote: the rest stays as it was
    assert link.c["mote_late"] == 2 and link.c["status_msgs"] == 2
    assert link.c["mote_bus_resets"] == 5


def test_every_status_field_has_its_link_counter():
    """A status field reaches the database by its name alone
    (capture.link.status_counter -> a link_stats column): the message and
    the columns cannot drift apart (docs/CONTRIBUTING.md, "How to add a
    status field")."""
    from motecal.capture.link import status_counter
    from motecal.sessions.store import LINK_COUNTERS
    names = [status_counter(f.name) for f in P.MOTE_STATUS.fields]
    assert [n for n in names if n is not None and n not in LINK_COUNTERS] == []
    assert names.count(None) == 2                                 # seq, reserved
    link = MoteLink(7)
    values = {f.name: i + 1 for i, f in enumerate(P.MOTE_STATUS.fields)}
    link.status(P.decode_message(_am(P.MOTE_STATUS.pack(**values))))
    for f in P.MOTE_STATUS.fields:
        n = status_counter(f.name)
        if n is not None:
            assert link.c[n] == values[f.name], f.name
