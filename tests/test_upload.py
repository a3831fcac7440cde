"""motecal upload against the simulated network, in process and in simulated
time (sim.world.WorldPort): the mote runs the firmware's C receiver.

A real calibration (simulated static80 of mote 1's board, calibrated) goes up
at 0 % and 30 % radio loss and is read back bit for bit; the samples after the
commit are flagged and equal what the C code computes, within rounding of the
float calibration.  Bad sets (corrupted fragment, wrong CRC, wrong mote, out
of range, incomplete, wrong version, fragment outside the set) are rejected
with their reason and the old set stays in force.  Missing replies, a silent
mote and a BaseStation that does not ack are retried and then reported.
"""
import numpy as np
import pytest

from motecal import upload as U
from motecal.calib.board import calibrate_board
from motecal.errors import QualityError
from motecal.firmware import fixedpoint as FP
from motecal.firmware import mote_c
from motecal.line import protocol as P
from motecal.line.sources import PortSpec
from motecal.sim import simulate_session
from motecal.sim.world import World, WorldPort

ALL = 0b111


@pytest.fixture(scope="module")
def cal(tmp_path_factory):
    """Mote 1's board calibrated from a simulated static80 (seed 1): the same
    board the worlds below put on mote 1."""
    data = simulate_session("static80", motes=(1,), seed=1)[1]
    board = calibrate_board(data, seed=1, kfold=0)
    path = tmp_path_factory.mktemp("cal") / "cal.json"
    board.save(path)
    return U.load_cal(path)


def _world(loss=0.0, seed=1, motes=1):
    w = World(motes=motes, session="idle", seed=seed, loss=loss, duration=3600.0)
    port = WorldPort(w)
    w.run_until(0.5)                     # sampling
    return w, port


def _uploader(port, mote=1, **kw):
    return U.Uploader(U.Link(port, **kw), mote)


def test_fragments_and_versions():
    data = bytes(range(P.CALSET_SIZE))
    pieces = U.fragments(data)
    assert [o for o, _ in pieces] == [0, 20, 40, 60, 80, 100]
    assert [len(c) for _, c in pieces] == [20, 20, 20, 20, 20, 2]
    assert b"".join(c for _, c in pieces) == data
    assert [U.next_version(v) for v in (0, 1, 41, 65534, 65535)] == [1, 2, 42, 65535, 1]
    assert U.flags_for(0x2B, ALL) == 0xB1 and U.flags_for(0x2B, 0) == 0xB0


@pytest.mark.parametrize("loss", [0.0, 0.3])
def test_upload_completes_bit_identical_and_the_mote_corrects(cal, loss):
    w, port = _world(loss=loss, seed=3)
    res = U.upload_cal(port, cal, 1, U.Options(), progress=U.NullProgress())
    calset, report = U.build_set(cal, 1, 1)
    assert (res.version, res.previous, res.crc, res.sensors) == (1, 0, P.crc16(calset), ALL)
    assert res.readback and res.samples.checked == U.VERIFY_MESSAGES
    rx = w.motes[1].cal                                   # the mote's own state
    assert rx.active_calset() == calset and rx.version == 1 and rx.crc == P.crc16(calset)
    st = res.stats
    print(f"loss {loss:.0%}: {res.seconds:.3f} simulated s, {st.messages} messages, "
          f"{st.retries} repeated")
    # query, fragments, commit, read-back, then queries of the stored set
    assert st.messages == 1 + 6 + 1 + 6 + res.stored.polls
    assert res.stored.reported and rx.stored_version == 1 and rx.stored_crc == P.crc16(calset)
    # 108 bytes at 3.4 ms from the commit, then a query: not before, and at most one poll after
    assert 0.37 < res.stored.seconds < 0.37 + (0.8 if loss else 0.15)
    if loss:
        assert st.retries > 0 and res.seconds < 15.0
    else:
        assert st.retries == 0 and st.serial_retries == 0 and res.seconds < 0.7
    # what reached the line: raw, then corrected with the new flags (never back)
    w.run_until(w.now + 2.0)
    sent = w.sent[1]
    new = sent.flags == U.flags_for(1, ALL)
    assert set(sent.flags.tolist()) == {0, U.flags_for(1, ALL)}
    assert 100 < new.sum() and np.all(np.diff(new.astype(int)) >= 0)
    raw, rec = sent.raw[new], sent.records[new]
    assert np.array_equal(rec, mote_c.correct(calset, raw))            # the firmware's code
    assert np.abs(rec - FP.reference_correct(calset, raw)).max() < 1.0   # error feedback
    # and what the host computed in float: within quantisation + output rounding
    for name, sl in (("accel", slice(0, 3)), ("gyro", slice(3, 6)), ("mag", slice(6, 9))):
        A, c = cal.physical[name]
        exact = FP.physical_correct(name, A, c, raw[:, sl])
        M, off = FP.counts_domain(name, A, c)
        fs = report[name].fixed
        bound = np.abs(raw[:, sl]) @ np.abs(fs.matrix - M).T + np.abs(fs.offset - off) \
            + FP.OUTPUT_ROUNDING_LSB       # error feedback: the output within 1 LSB
        err = np.abs(rec[:, sl] - exact)
        assert np.all(err < bound), name


# ---------------------------------------------------------------- rejections
def _bad_physical(cal, scale):
    phys = dict(cal.physical)
    A, c = phys["accel"]
    phys["accel"] = (A * scale, c)
    return phys


def _corrupted(calset):
    pieces = U.fragments(calset)
    off, chunk = pieces[2]
    pieces[2] = (off, chunk[:5] + bytes([chunk[5] ^ 0x40]) + chunk[6:])   # one bit in flight
    return pieces


CASES = {      # what is sent -> the mote's reason code
    "corrupted fragment": 4,
    "wrong CRC": 4,
    "wrong mote id": 1,
    "out of range": 6,
    "incomplete": 3,
    "wrong version": 5,
    "fragment outside the set": 2,
}


@pytest.mark.parametrize("case", list(CASES))
def test_bad_sets_are_rejected_and_the_old_set_stays(cal, case):
    w, port = _world(seed=5)
    res = U.upload_cal(port, cal, 1, U.Options(), progress=U.NullProgress())
    old = U.build_set(cal, 1, 1)[0]
    assert res.version == 1
    up = _uploader(port)
    good, _ = U.build_set(cal, 1, 2)
    crc = P.crc16(good)
    with pytest.raises(U.Rejected) as exc:
        if case == "corrupted fragment":
            up.stage(good, 2, pieces=_corrupted(good))
            up.apply(2, crc)
        elif case == "wrong CRC":
            up.stage(good, 2)
            up.apply(2, crc ^ 0x0100)
        elif case == "wrong mote id":
            other, _ = U.build_set(cal, 2, 2)             # mote 2's set sent to mote 1
            up.stage(other, 2)
            up.apply(2, P.crc16(other))
        elif case == "out of range":
            bad, _ = FP.build_calset(1, 2, _bad_physical(cal, 2.2))     # scale 2.2 > 2
            up.stage(bad, 2)
            up.apply(2, P.crc16(bad))
        elif case == "incomplete":
            up.stage(good, 2, pieces=U.fragments(good)[:4])
            up.apply(2, crc)
        elif case == "wrong version":
            up.stage(good, 2)
            up.apply(3, crc)
        else:
            up.stage(good, 2, pieces=[(150, good[:20])])    # past the 164-byte set
    code = CASES[case]
    assert exc.value.status == code
    msg = str(exc.value)
    name, text = P.CAL_REASONS[code]
    assert f"{text} ({name})" in msg and "\n" not in msg
    if case == "fragment outside the set":
        assert "rejected fragment 1/1 (offset 150) of version 2" in msg
        assert msg.endswith("the set in force is unchanged")
    else:
        assert msg.startswith("mote 1 rejected calibration version ")
        assert msg.endswith("version 1 stays in force")
    # the old set is still in force, read back and in the samples
    back = up.read_set()
    assert back.version == 1 and back.data == old
    assert w.motes[1].cal.active_calset() == old
    chk = up.check_samples(U.flags_for(1, ALL))
    assert chk.checked == U.VERIFY_MESSAGES and chk.stale == 0


def test_the_host_refuses_what_the_mote_would_reject_before_sending(cal):
    w, port = _world()
    bad = U.CalFile("bad.json", 1, _bad_physical(cal, 2.2))
    with pytest.raises(QualityError, match=r"bad.json: the mote would reject this calibration: "
                                           r"parameters outside plausibility limits"):
        U.upload_cal(port, bad, 1, U.Options(), progress=U.NullProgress())
    assert w.bs.serial_rx == 0 and w.bs.bytes_in == 0
    huge = U.CalFile("huge.json", 1, _bad_physical(cal, 300.0))
    with pytest.raises(FP.NotRepresentable, match="huge.json: accel: calibration does not fit"):
        U.upload_cal(port, huge, 1, U.Options(), progress=U.NullProgress())
    refused = U.CalFile("r.json", 1, cal.physical, gate={"accepted": False,
                                                          "reasons": ["too few poses"]})
    with pytest.raises(QualityError, match=r"refused by the quality gate \(too few poses\); "
                                           r"--force"):
        U.upload_cal(port, refused, 1, U.Options(), progress=U.NullProgress())
    assert w.bs.bytes_in == 0


# ---------------------------------------------------------------- silence and repeats
def test_a_mote_that_does_not_answer(cal):
    w, port = _world()
    up = _uploader(port, mote=9, timeout=0.2, retries=3)
    t0 = port.clock()
    with pytest.raises(U.NoAnswer) as exc:
        up.in_force()
    assert str(exc.value) == ("no answer from mote 9 to the query of the version in force "
                              "after 4 tries of 0.2 s: is it switched on, in range of the "
                              "BaseStation and running the motecal firmware with ID 9?")
    assert 0.8 <= port.clock() - t0 < 0.9                 # 4 x 0.2 s plus the serial acks
    assert up.link.stats.tries == 4 and w.bs.serial_rx == 4


class _Silent:
    """A port where nothing answers, with its own clock."""
    spec = PortSpec("serial", "x", 250000)

    def __init__(self):
        self.t = 0.0
        self.sent = []

    def clock(self):
        return self.t

    def read(self):
        self.t += 0.01
        return []

    def send(self, am, ack_seq=None):
        self.sent.append(ack_seq)


def test_no_serial_ack_repeats_the_frame_then_gives_up():
    port = _Silent()
    up = _uploader(port, timeout=0.2, retries=5)
    with pytest.raises(U.UploadFailed, match=r"the BaseStation on x did not acknowledge the "
                                             r"query of the version in force \(no serial ack "
                                             r"0x43 to 4 frames\)"):
        up.in_force()
    assert port.sent == [1, 1, 1, 1]                      # the same frame, same sequence byte
    assert port.t == pytest.approx(4 * U.SERIAL_ACK_TIMEOUT, abs=0.02)


class _LosesAcks(WorldPort):
    """The world's line, but the first ``n`` serial acks (0x43) are lost."""

    def __init__(self, world, n):
        super().__init__(world)
        self.n = n

    def read(self):
        out = []
        for f in super().read():
            if f.protocol == P.PROTO_ACK and self.n:
                self.n -= 1
                continue
            out.append(f)
        return out


def test_lost_serial_acks_are_repeated_and_the_upload_completes(cal):
    w = World(motes=1, session="idle", seed=2, duration=3600.0)
    port = _LosesAcks(w, 2)
    w.run_until(0.5)
    res = U.upload_cal(port, cal, 1, U.Options(), progress=U.NullProgress())
    assert res.version == 1 and res.stats.serial_retries == 2
    assert w.motes[1].cal.active_calset() == U.build_set(cal, 1, 1)[0]
    assert w.bs.serial_acks == res.stats.serial_frames == res.stats.tries + 2


class _SerialForwarder(WorldPort):
    """The world seen through a TinyOS SerialForwarder (sf@): it does the
    serial acks itself, so the host sees none and sends no sequence bytes."""

    def __init__(self, world):
        super().__init__(world)
        self.spec = PortSpec("sf", "localhost", 250000, 9002, "sf@localhost:9002")
        self.seqs = []

    def read(self):
        return [f for f in super().read() if f.protocol != P.PROTO_ACK]

    def send(self, am, ack_seq=None):
        self.seqs.append(ack_seq)
        super().send(am, ack_seq=0)                  # the forwarder's own serial frame


def test_through_a_serialforwarder_no_serial_acks_are_awaited(cal):
    w = World(motes=1, session="idle", seed=9, duration=3600.0)
    port = _SerialForwarder(w)
    w.run_until(0.5)
    res = U.upload_cal(port, cal, 1, U.Options(), progress=U.NullProgress())
    assert res.version == 1 and res.stats.serial_retries == 0
    assert set(port.seqs) == {None} and len(port.seqs) == res.stats.tries
    assert w.motes[1].cal.active_calset() == U.build_set(cal, 1, 1)[0]


# ---------------------------------------------------------------- versions, reset, show
def test_version_wraps_reset_goes_raw_and_show_decodes(cal):
    w, port = _world(seed=4)
    progress = U.NullProgress()
    res = U.upload_cal(port, cal, 1, U.Options(version=65535), progress=progress)
    assert (res.previous, res.version) == (0, 65535)
    res = U.upload_cal(port, cal, 1, U.Options(), progress=progress)
    assert (res.previous, res.version) == (65535, 1)       # wraps to 1, never 0
    up = _uploader(port)
    inf = up.read_set()
    cs = inf.calset
    assert inf.version == 1 and cs.mask == ALL and cs.mote == 1
    for name, (A, c) in cal.physical.items():              # decoded in physical units
        k = FP.NOMINAL_SCALES[name]
        fs = cs.sensors[name]
        assert np.abs(fs.matrix / k - A).max() <= 2.0 ** -fs.shift / k
        assert np.abs(fs.offset / k - c).max() <= 2.0 ** -fs.shift / k
    lines = U.show_lines(inf, cal)
    assert lines[0].startswith("mote 1: calibration version 1 in force (CRC 0x")
    assert lines[0].endswith("corrected: accel, gyro, mag")
    assert lines[-1] == f"  equals {cal.path} (quantised for mote 1, version 1)"
    a00 = cal.physical["accel"][0][0, 0]
    row = next(x for x in lines if x.startswith("    A[0]"))
    assert abs(float(row.split("[")[2].split(",")[0]) - a00) <= 2.0 ** -15 / 256 + 1e-9
    # reset: raw output with the next version, verified
    res = _uploader(port).reset(2, 1)
    assert res.version == 2 and res.sensors == 0 and res.samples.checked == U.VERIFY_MESSAGES
    w.run_until(w.now + 1.0)
    sent = w.sent[1]
    after = sent.flags == U.flags_for(2, 0)
    assert after.sum() > 50 and np.array_equal(sent.records[after], sent.raw[after])
    inf = _uploader(port).read_set()
    assert inf.version == 2 and inf.calset.mask == 0
    assert U.show_lines(inf)[0].endswith("corrected: none (raw output)")
    assert "differs from" in U.show_lines(inf, cal)[-1]


def test_samples_check(cal):
    w, port = _world(motes=2, seed=6)
    up = _uploader(port)
    chk = up.check_samples(U.flags_for(0, 0))              # raw since boot
    assert chk.checked == 3 and chk.stale == 0
    with pytest.raises(U.UploadFailed, match=r"mote 1 still sends samples flagged raw, "
                                             r"version low bits 0 after the commit, expected "
                                             r"corrected, version low bits 7"):
        up.check_samples(U.flags_for(7, ALL))
    ended = World(motes=1, session="idle", seed=6, duration=1.0)
    while not ended.done:                                  # the session is over: no samples
        ended.run_until(ended.now + 1.0)
    chk = _uploader(WorldPort(ended)).check_samples(U.flags_for(0, 0), wait=0.5)
    assert not chk.seen and "no sample messages from mote 1 within 0.5 s" in chk.note
