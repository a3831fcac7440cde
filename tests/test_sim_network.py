"""Packet-level simulator: motes, radio, BaseStation, serial line, World API."""
from __future__ import annotations

import random
from collections import defaultdict

import numpy as np
import pytest

from motecal.line import protocol as P
from motecal.sim import radio as R
from motecal.sim.network import EventLoop, Network

pytestmark = pytest.mark.timeout(120)


class RampSampler:
    """Deterministic int16 records from the true sample time (no physics)."""

    def __init__(self, mote):
        self.mote = mote
        self.calls = []

    def read(self, t):
        t = np.asarray(t, np.float64)
        self.calls.append((float(t[0]), len(t)))
        us = np.round(t * 1e6).astype(np.int64)
        cols = [(us // (j + 1) + 977 * self.mote) % 65536 - 32768 for j in range(9)]
        return np.stack(cols, axis=1).astype(np.int16)


def make_net(n=3, duration=10.0, ppm=None, cal_factory=None, **kw):
    ppm = ppm or {m: (-40.0 + 25.0 * m) for m in range(1, n + 1)}
    return Network({m: RampSampler(m) for m in range(1, n + 1)}, ppm, duration=duration,
                   cal_factory=cal_factory, **kw)


def run_all(net, step=1.0):
    out = bytearray()
    while not net.done:
        out += net.run_until(net.now + step)
    return bytes(out)


def samples_by_mote(frames):
    """mote -> list of (seq, flags, records) in arrival order."""
    got = defaultdict(list)
    for f in frames:
        am = f.am()
        if am is not None and am.am_type == P.AM_NINEDOF_SAMPLES_MSG:
            s = P.unpack_samples(am.payload)
            got[am.src].append(s)
    return got


def unwrap(seqs):
    """Unwrap 16-bit sequence numbers of one mote (arrival order)."""
    out, prev, base = [], None, 0
    for s in seqs:
        if prev is not None and s < prev - 32768:
            base += 65536
        out.append(base + s)
        prev = s
    return np.asarray(out, np.int64)


def per_sample(msgs):
    seq = unwrap([m.seq for m in msgs])
    seqs = np.concatenate([np.arange(s, s + len(m.records)) for s, m in zip(seq, msgs)])
    recs = np.concatenate([m.records for m in msgs])
    return seqs, recs


# ---------------------------------------------------------------- radio model
def test_airtime_byte_counts():
    # payload 94 (5 records): 6 PHY + 13 MAC/TinyOS + 94 = 113 bytes at 32 us
    assert R.data_airtime(94) == pytest.approx(113 * 32e-6)
    assert R.data_airtime(22) == pytest.approx(41 * 32e-6)
    assert R.ACK_AIRTIME == pytest.approx(11 * 32e-6)
    assert R.BARRIER == pytest.approx(864e-6)


class _Sink:
    def __init__(self):
        self.got = []

    def on_frame(self, f):
        self.got.append(f.payload)


def test_overlapping_frames_both_lost_and_ack_retry():
    loop = EventLoop()
    ch = R.Channel(loop, random.Random(1))
    sink = _Sink()
    ch.attach(0, sink)
    done = []
    a = R.Mac(1, ch, random.Random(2), max_retries=0)
    b = R.Mac(2, ch, random.Random(3), max_retries=0)
    # force both to decide at the same instant: same backoff
    for m in (a, b):
        m.rng = type("R", (), {"random": staticmethod(lambda: 0.5)})()
    a.send(0, 0x22, 0x60, b"A" * 20, True, "a", lambda msg, ok: done.append((msg, ok)))
    b.send(0, 0x22, 0x60, b"B" * 20, True, "b", lambda msg, ok: done.append((msg, ok)))
    loop.run_until(1.0)
    assert sink.got == []
    assert sorted(done) == [("a", False), ("b", False)]
    assert a.stats_collided == 1 and b.stats_collided == 1 and ch.collisions == 2
    # with a retry and random backoff both get through (CCA keeps them apart)
    loop2 = EventLoop()
    ch2 = R.Channel(loop2, random.Random(1))
    sink2 = _Sink()
    ch2.attach(0, sink2)
    done2 = []
    a2 = R.Mac(1, ch2, random.Random(2), max_retries=2)
    b2 = R.Mac(2, ch2, random.Random(5), max_retries=2)
    a2.send(0, 0x22, 0x60, b"A" * 20, True, "a", lambda msg, ok: done2.append((msg, ok)))
    b2.send(0, 0x22, 0x60, b"B" * 20, True, "b", lambda msg, ok: done2.append((msg, ok)))
    loop2.run_until(1.0)
    assert sorted(done2) == [("a", True), ("b", True)]
    assert sorted(sink2.got) == [b"A" * 20, b"B" * 20]


# ---------------------------------------------------------------- motes + line
def test_lossless_run_is_contiguous_and_exact():
    net = make_net(3, duration=12.0)
    data = run_all(net)
    frames = P.decode_stream(data)
    got = samples_by_mote(frames)
    assert sorted(got) == [1, 2, 3]
    for m, mote in net.motes.items():
        seqs, recs = per_sample(got[m])
        assert np.array_equal(seqs, np.arange(len(seqs))), "contiguous from 0"
        expect = 12.0 * 125 * (1 + mote.clock_ppm * 1e-6)
        assert abs(len(seqs) - expect) <= 1
        # records are exactly the sensor output at the mote's sample times
        t = mote.t0 + seqs * mote.period
        assert np.array_equal(recs, RampSampler(m).read(t))
        assert all(len(s.records) == 5 for s in got[m][:-1])
        log = net.sent[m]
        assert np.array_equal(log.seq, seqs) and np.array_equal(log.records, recs)
        assert np.array_equal(log.raw, recs) and np.allclose(log.t, t)
        st = net.stats["motes"][m]
        assert st["generated"] == st["delivered"] == len(seqs)
        assert st["dropped"] == st["radio_lost"] == st["bs_dropped"] == 0
    # status messages: every mote every 2 s, the BaseStation too
    kinds = defaultdict(int)
    for f in frames:
        am = f.am()
        kinds[(am.src, am.am_type)] += 1
        if am.am_type == P.AM_NINEDOF_MOTE_STATUS_MSG:
            st = P.decode_message(am)
            assert st["dropped"] == 0 and st["version"] == 0
        if am.am_type == P.AM_NINEDOF_BS_STATUS_MSG:
            assert am.dest == P.AM_BROADCAST and P.decode_message(am)["radio_drops"] == 0
        if am.am_type == P.AM_NINEDOF_SAMPLES_MSG:
            assert am.dest == 0 and am.group == P.DEFAULT_GROUP
    for m in (1, 2, 3):
        assert kinds[(m, P.AM_NINEDOF_MOTE_STATUS_MSG)] == 6
    assert kinds[(0, P.AM_NINEDOF_BS_STATUS_MSG)] == 6


def test_a_record_leaves_with_the_read_after_it():
    """The firmware completes record k with the field read at k + 1 (the
    HMC5883L returns the previous read's measurement): a message goes to the
    queue one period after its last record's sample time."""
    net = make_net(n=1, duration=2.0)
    mote, emitted = net.motes[1], []
    emit = mote._emit
    mote._emit = lambda k0, k1: (emitted.append((net.now, k1)), emit(k0, k1))
    run_all(net)
    t, k1 = np.array(emitted).T
    assert len(t) == -(-mote.n_total // 5)
    np.testing.assert_allclose(t - (mote.t0 + (k1 - 1) * mote.period), mote.period, atol=1e-9)


def test_output_independent_of_run_until_steps():
    a = run_all(make_net(2, duration=4.0), step=1.0)
    net = make_net(2, duration=4.0)
    rng = random.Random(7)
    out = bytearray()
    while not net.done:
        out += net.run_until(net.now + rng.choice([1e-4, 3e-4, 0.01, 0.37]))
    assert bytes(out) == a
    # bytes come out at the line rate: never more than baud/10 per second
    net = make_net(3, duration=3.0, baud=57600)
    t, n = 0.0, 0
    while not net.done:
        t += 0.05
        n += len(net.run_until(t))
        assert n <= t * 5760 + 1


def test_loss_gaps_equal_counters():
    net = make_net(4, duration=20.0, loss=0.08)
    frames = P.decode_stream(run_all(net))
    got = samples_by_mote(frames)
    total_lost = 0
    duplicates = 0
    for m, mote in net.motes.items():
        seqs, recs = per_sample(got[m])
        st = net.stats["motes"][m]
        # a message sent again after EBUSY (a new DSN) whose earlier try got
        # through unacknowledged is on the line twice: the very same records
        first = np.sort(np.unique(seqs, return_index=True)[1])
        again = np.setdiff1d(np.arange(len(seqs)), first)
        k = np.searchsorted(seqs[first], seqs[again])
        assert np.array_equal(recs[again], recs[first][k]) and np.all(seqs[first][k] == seqs[again])
        assert len(again) <= 5 * st["line_duplicates"] and (len(again) > 0) == (st["line_duplicates"] > 0)
        duplicates += st["line_duplicates"]
        seqs, recs = seqs[first], recs[first]
        assert np.all(np.diff(seqs) > 0), "in order"
        gaps = st["generated"] - len(seqs)
        assert gaps == st["dropped"] + st["radio_lost"] + st["bs_dropped"]
        assert set(np.arange(st["generated"])) - set(seqs.tolist()) == \
            set(np.arange(st["generated"])) - set(net.sent[m].seq.tolist())
        assert np.array_equal(recs, RampSampler(m).read(mote.t0 + seqs * mote.period))
        assert st["lost"] > 0 and st["retries"] > 0
        total_lost += gaps
    assert total_lost > 0
    assert net.stats["basestation"]["duplicates"] > 0      # lost acks -> retransmissions
    assert duplicates < net.stats["basestation"]["duplicates"] / 10    # mostly the same DSN


def test_basestation_queue_overflow_is_counted():
    # 6 motes, one record per message, 57600 baud: the serial line cannot keep up
    net = make_net(6, duration=6.0, baud=57600, batch=1)
    frames = P.decode_stream(run_all(net))
    got = samples_by_mote(frames)
    bs = net.stats["basestation"]
    assert bs["radio_drops"] > 0
    for m in net.motes:
        seqs, _ = per_sample(got[m])
        st = net.stats["motes"][m]
        assert st["generated"] - len(seqs) == st["dropped"] + st["radio_lost"] + st["bs_dropped"]
    assert sum(net.stats["motes"][m]["bs_dropped"] for m in net.motes) > 0
    # the BaseStation reports its own drops
    last = [P.decode_message(f.am()) for f in frames
            if f.am().am_type == P.AM_NINEDOF_BS_STATUS_MSG][-1]
    assert 0 < last["radio_drops"] <= bs["radio_drops"]


def test_sequence_numbers_wrap():
    net = Network({1: RampSampler(1)}, {1: 0.0}, duration=530.0, batch=6, cal_factory=None)
    got = samples_by_mote(P.decode_stream(run_all(net, step=50.0)))
    seqs, _ = per_sample(got[1])
    raw = [s.seq for s in got[1]]
    assert max(raw) < 65536 and seqs[-1] > 65536
    assert np.array_equal(seqs, np.arange(len(seqs)))


def test_pc_frames_acked_and_forwarded_to_the_mote():
    from motecal.firmware import mote_c
    net = make_net(2, duration=3.0, cal_factory=mote_c.CalReceiver)
    out = bytearray(net.run_until(0.5))
    q = P.message_frame(P.CAL_QUERY, dest=2, src=0, ack_seq=0x7E, mote=2, offset=0)
    bad = P.message_frame(P.CAL_QUERY, dest=1, src=0, ack_seq=0x11, mote=1, offset=0)
    net.write(q + b"\x00garbage" + bad)
    out += run_all(net)
    frames = P.decode_stream(bytes(out))
    acks = [f.seq for f in frames if f.protocol == P.PROTO_ACK]
    assert acks == [0x7E, 0x11]
    reports = [f.am() for f in frames if f.am() and f.am().am_type == P.AM_NINEDOF_CAL_REPORT_MSG]
    assert sorted(r.src for r in reports) == [1, 2]
    for r in reports:
        d = P.decode_message(r)
        assert d["mote"] == r.src and d["version"] == 0 and r.dest == 0
    bs = net.stats["basestation"]
    assert bs["serial_rx"] == 2 and bs["serial_acks"] == 2
    assert sum(net.stats["motes"][m]["replies"] for m in (1, 2)) == 2


def _on_air(net):
    """Record every data frame put on the air: (time, src, dest, am_type, dsn, ack_req)."""
    log = []
    transmit = net.channel.transmit

    def spy(frame, start, airtime):
        if not frame.is_ack:
            log.append((start, frame.src, frame.dest, frame.am_type, frame.dsn, frame.ack_req))
        transmit(frame, start, airtime)
    net.channel.transmit = spy
    return log


def test_radio_paths_are_the_firmwares():
    """As NineDofAppP / NineDofBaseP send (PacketLink, own buffers):
    samples and calibration replies ask for an ack, status messages do not;
    a reply goes to the sender from its own buffer, not behind the queued
    samples; the BaseStation asks the mote for an ack and repeats its frame
    (same DSN) at most twice, and the mote answers a repeat only once."""
    from motecal.firmware import mote_c
    net = make_net(1, duration=4.0, cal_factory=mote_c.CalReceiver)
    air = _on_air(net)
    net.run_until(2.5)
    kinds = {(src, t, ack) for _, src, _, t, _, ack in air}
    assert (1, P.AM_NINEDOF_SAMPLES_MSG, True) in kinds
    assert (1, P.AM_NINEDOF_MOTE_STATUS_MSG, False) in kinds
    assert (1, P.AM_NINEDOF_MOTE_STATUS_MSG, True) not in kinds
    # samples waiting in the mote's queue: the reply goes out after the one on the air
    mote = net.motes[1]
    for _ in range(3):
        mote._emit(mote.next_k, mote.next_k + 5)
    assert len(mote.queue) >= 3
    n = len(air)
    net.write(P.message_frame(P.CAL_QUERY, dest=1, ack_seq=1, mote=1, offset=0))
    net.run_until(net.now + 0.2)
    sent = [(src, dest, t, ack) for _, src, dest, t, _, ack in air[n:]]
    to_mote = sent.index((0, 1, P.AM_NINEDOF_CAL_QUERY_MSG, True))
    reply = sent.index((1, 0, P.AM_NINEDOF_CAL_REPORT_MSG, True))
    assert [x[2] for x in sent[to_mote + 1:reply]].count(P.AM_NINEDOF_SAMPLES_MSG) <= 1
    assert mote.counters()["replies"] == 1
    # the mote is switched off: the BaseStation tries 3 times, one DSN, then gives up
    net.channel.nodes.pop(1)
    n = len(air)
    net.write(P.message_frame(P.CAL_QUERY, dest=1, ack_seq=2, mote=1, offset=0))
    net.run_until(net.now + 0.2)
    tries = [(dsn, ack) for _, src, _, _, dsn, ack in air[n:] if src == 0]
    assert len(tries) == 3 and len(set(tries)) == 1 and tries[0][1]
    assert net.stats["basestation"]["radio_fail"] == 1
    # a repeat of a frame the mote got (its ack was lost) is not answered again
    net.channel.nodes[1] = mote
    f = R.Frame(0, 1, P.DEFAULT_GROUP, P.AM_NINEDOF_CAL_QUERY_MSG,
                P.CAL_QUERY.pack(mote=1, offset=20), 77, True, None, None)
    mote.on_frame(f)
    mote.on_frame(f)
    assert mote.counters()["replies"] + mote.counters()["replies_dropped"] == 2


# ---------------------------------------------------------------- World (physics)
def test_world_api_matches_physics():
    from motecal.sim.model import load_model
    from motecal.sim.trajectory import make_trajectory
    from motecal.sim.world import World

    w = World(motes=2, session="rotation", seed=3, duration=6.0)
    data = bytearray()
    while not w.done:
        data += w.run_until(w.now + 0.5)
    got = samples_by_mote(P.decode_stream(bytes(data)))
    truth = w.truth()
    model = load_model(None)
    traj = make_trajectory("rotation", 3, duration=6.0, rate_hz=model.rate_hz)
    for m in (1, 2):
        seqs, recs = per_sample(got[m])
        log = w.sent[m]
        assert np.array_equal(log.seq, seqs) and np.array_equal(log.records, recs)
        nt = truth["truth"]["network"][str(m)]
        board = model.board(m, 3)
        assert nt["clock_ppm"] == board.clock_ppm
        assert abs(len(seqs) - 6.0 * 125 * (1 + board.clock_ppm * 1e-6)) <= 1
        t = nt["t0_s"] + seqs * nt["period_s"]
        assert np.array_equal(recs, board.sampler(traj, 3).read(t))
    st = w.stats
    assert st["motes"][1]["generated"] == len(w.sent[1])
    assert truth["truth"]["seed"] == 3 and set(truth["truth"]["physical_truth"]) == {"1", "2"}


def test_world_sequence_samples_through_every_part():
    from motecal.sim.world import World, WorldPort

    w = World(motes=1, session="idle,idle", seed=2, duration=70.0)
    port = WorldPort(w, step=0.5)
    frames = []
    while not w.done:
        frames += port.read()
    assert port.clock() == w.now >= 70.0
    seqs, recs = per_sample(samples_by_mote(frames)[1])
    assert np.array_equal(seqs, w.sent[1].seq) and np.array_equal(recs, w.sent[1].records)
    lab = w.trajectory.label_at(w.sent[1].t)
    assert set(lab.tolist()) == {0, 1, 2}                 # both idle poses and the move
    assert abs(len(seqs) - 70.0 * 125) <= 1


def _calset(mote, version, accel_offset):
    """A calibration set: identity everywhere, accel x offset in counts."""
    eye = [16384, 0, 0, 0, 16384, 0, 0, 0, 16384]
    s = [P.CAL_SENSOR.pack(a=eye, c=[accel_offset * 16384 if i == 0 else 0, 0, 0],
                           shift=14, reserved=0) for i in range(3)]
    return P.CALSET_HEADER.pack(mote=mote, version=version, sensors=1, reserved=0) + b"".join(s)


def test_upload_through_the_network_corrects_on_the_mote():
    from motecal.firmware import mote_c
    net = make_net(2, duration=6.0, cal_factory=mote_c.CalReceiver)
    out = bytearray(net.run_until(1.0))
    cs = _calset(1, 3, 100)
    seq = 1
    for off in range(0, len(cs), P.NINEDOF_FRAG_DATA):
        chunk = cs[off:off + P.NINEDOF_FRAG_DATA]
        net.write(P.message_frame(P.CAL_FRAG, dest=1, ack_seq=seq, mote=1, version=3,
                                  offset=off, len=len(chunk), data=chunk))
        seq += 1
        out += net.run_until(net.now + 0.05)
    net.write(P.message_frame(P.CAL_COMMIT, dest=1, ack_seq=seq, mote=1, version=3,
                              length=len(cs), action=P.CAL_APPLY, crc=P.crc16(cs)))
    out += run_all(net)
    frames = P.decode_stream(bytes(out))
    assert [f.seq for f in frames if f.protocol == P.PROTO_ACK] == list(range(1, seq + 1))
    frag_acks = [P.decode_message(f.am()) for f in frames
                 if f.am() and f.am().am_type == P.AM_NINEDOF_CAL_FRAG_ACK_MSG]
    assert len(frag_acks) == 6 and all(a["status"] == P.CAL_OK for a in frag_acks)
    (commit,) = [P.decode_message(f.am()) for f in frames
                 if f.am() and f.am().am_type == P.AM_NINEDOF_CAL_COMMIT_ACK_MSG]
    assert commit["status"] == P.CAL_OK and commit["version"] == 3
    got = samples_by_mote(frames)
    mote = net.motes[1]
    seqs, recs = per_sample(got[1])
    assert np.array_equal(seqs, np.arange(len(seqs)))
    raw = RampSampler(1).read(mote.t0 + seqs * mote.period)
    flags = np.concatenate([[s.flags] * len(s.records) for s in got[1]])
    assert set(flags.tolist()) == {0x00, 0x31}
    assert np.all(np.diff((flags != 0).astype(int)) >= 0), "raw, then corrected"
    corr = flags != 0
    assert 0 < corr.sum() < len(flags)
    exp = raw.astype(np.int32)
    exp[corr, 0] += 100
    assert np.array_equal(recs, np.clip(exp, -32768, 32767).astype(np.int16))
    assert np.array_equal(net.sent[1].raw, raw) and np.array_equal(net.sent[1].flags, flags)
    # mote 2 untouched; status reports the version in force
    assert all(s.flags == 0 for s in got[2])
    st = [P.decode_message(f.am()) for f in frames
          if f.am() and f.am().src == 1 and f.am().am_type == P.AM_NINEDOF_MOTE_STATUS_MSG]
    assert st[-1]["version"] == 3 and st[-1]["sensors"] == 1
