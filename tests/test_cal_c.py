"""The mote's calibration C code (tinyos/ninedof_calset.c, ninedof_correct.c,
ninedof_calrx.c) on the host, via mote_c.

Checked against the numpy float64 reference (fixedpoint.reference_correct) and
an exact int64 evaluation of the header's formula with its error-feedback
rounding (fixedpoint.feedback_correct); the mean of a still run; every
reject reason; the
upload receiver (fragments in any order, duplicates, read-back, reset); the
two-slot EEPROM image with torn writes.
"""
import binascii

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from motecal.firmware import fixedpoint as FP
from motecal.firmware import mote_c as M
from motecal.line import protocol as P

R = {n: c for c, (n, _) in P.CAL_REASONS.items()}
OK, E_MOTE, E_FRAG, E_INCOMPLETE, E_CRC, E_VERSION, E_RANGE, E_FORMAT, E_ACTION = (
    R[f"NINEDOF_CAL_{x}"] for x in ("OK", "E_MOTE", "E_FRAG", "E_INCOMPLETE", "E_CRC",
                                    "E_VERSION", "E_RANGE", "E_FORMAT", "E_ACTION"))
MOTE = 7
HYP = settings(max_examples=40, deadline=None)


# --------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------
def random_fixed(rng, shift=None) -> FP.FixedSensor:
    """A plausible counts-domain correction (inside the mote's limits)."""
    Mx = np.diag(rng.uniform(0.55, 1.95, 3)) + (1 - np.eye(3)) * rng.uniform(-0.45, 0.45, (3, 3))
    off = rng.uniform(-4000, 4000, 3)
    fs = FP.quantise(Mx, off)
    if shift is not None and shift != fs.shift:
        k = fs.shift - shift
        fs = FP.FixedSensor(fs.a >> k, fs.c >> k, shift)
    return fs


def random_calset(rng, mask=7, shift=None, version=3, mote=MOTE) -> bytes:
    sensors = {n: random_fixed(rng, shift) for i, n in enumerate(P.SENSORS) if mask >> i & 1}
    return FP.pack_calset(mote, version, sensors)


def exact(calset: bytes, raw, resid=None) -> np.ndarray:
    """The header's formula in int64, rounded with error feedback (the
    Python reference, fixedpoint.feedback_correct)."""
    return FP.feedback_correct(calset, raw, resid)


def full_range_raw(rng, n):
    raw = rng.integers(-32768, 32768, (n, 9))
    raw[:8] = np.array([-32768, 32767, 0, -1, 1, -32767, 16384, -16384])[:, None]
    # a few magnetometer overflow markers on single axes
    idx = rng.choice(n, size=max(1, n // 20), replace=False)
    raw[idx, 6 + rng.integers(0, 3, len(idx))] = -4096
    return raw.astype(np.int16)


def frag(version, offset, data, mote=MOTE):
    return P.CAL_FRAG.pack(mote=mote, version=version, offset=offset, len=len(data), data=data)


def commit(version, crc, action=P.CAL_APPLY, mote=MOTE, length=P.CALSET_SIZE):
    return P.CAL_COMMIT.pack(mote=mote, version=version, length=length, action=action, crc=crc)


def send_frag(rx, version, offset, data, mote=MOTE):
    t, pl = rx.handle(P.AM_NINEDOF_CAL_FRAG_MSG, frag(version, offset, data, mote))
    assert t == P.AM_NINEDOF_CAL_FRAG_ACK_MSG
    return P.CAL_FRAG_ACK.unpack(pl)


def send_commit(rx, version, crc, **kw):
    t, pl = rx.handle(P.AM_NINEDOF_CAL_COMMIT_MSG, commit(version, crc, **kw))
    assert t == P.AM_NINEDOF_CAL_COMMIT_ACK_MSG
    return P.CAL_COMMIT_ACK.unpack(pl)


def upload(rx, calset, version, order=None):
    offs = list(range(0, len(calset), P.NINEDOF_FRAG_DATA)) if order is None else order
    for o in offs:
        ack = send_frag(rx, version, o, calset[o:o + P.NINEDOF_FRAG_DATA])
        assert ack == dict(mote=rx.mote_id, version=version, offset=o, status=OK)
    return send_commit(rx, version, binascii.crc_hqx(calset, 0))


def read_back(rx):
    out, off = b"", 0
    while True:
        t, pl = rx.handle(P.AM_NINEDOF_CAL_QUERY_MSG, P.CAL_QUERY.pack(mote=rx.mote_id,
                                                                        offset=off))
        rep = P.CAL_REPORT.unpack(pl)
        assert t == P.AM_NINEDOF_CAL_REPORT_MSG and rep["mote"] == rx.mote_id
        if rep["len"] == 0:
            return out, rep
        out += rep["data"][:rep["len"]]
        off += rep["len"]


# --------------------------------------------------------------------------
# CRC and the library build
# --------------------------------------------------------------------------
@HYP
@given(st.binary(max_size=300), st.integers(0, 0xFFFF))
def test_crc_is_crc_hqx(data, init):
    assert M.crc16(data, init) == binascii.crc_hqx(data, init)


def test_crc_check_value_and_library_cached():
    assert M.crc16(b"123456789") == 0x31C3
    assert M.build() == M.build()             # second call: same cached file


def test_missing_compiler_is_one_clear_error(monkeypatch):
    monkeypatch.setenv("CC", "no-such-cc-xyz")
    with pytest.raises(M.CompilerMissing, match="no-such-cc-xyz"):
        M.build()


# --------------------------------------------------------------------------
# Correction
# --------------------------------------------------------------------------
@HYP
@given(st.integers(0, 2**32 - 1), st.sampled_from([None, 14, 13, 11, 8]))
def test_correction_matches_reference_over_full_int16_range(seed, shift):
    rng = np.random.default_rng(seed)
    cs = random_calset(rng, shift=shift)
    raw = full_range_raw(rng, 400)
    out = M.correct(cs, raw)
    ref = FP.reference_correct(cs, raw)
    assert out.dtype == np.int16
    assert np.max(np.abs(out - ref)) < 1.0                  # the goal: within 1 LSB
    np.testing.assert_array_equal(out, exact(cs, raw))      # and bit-exact formula


def test_rounds_half_up_with_error_feedback_like_the_header():
    # a = 0.5 exactly.  One sample of a fresh set: plain half up
    # (raw 1 -> 0.5 -> 1, raw -1 -> -0.5 -> 0, raw 3 -> 1.5 -> 2) ...
    fs = FP.FixedSensor(np.eye(3, dtype=int) * (1 << 13), np.zeros(3, int), 14)
    cs = FP.pack_calset(MOTE, 1, {"accel": fs})
    one = np.zeros((1, 9), np.int16)
    for r, want in ((1, 1), (-1, 0), (3, 2)):
        one[0, 0] = r
        assert M.correct(cs, one)[0, 0] == want
    # ... and in a run the residual carries: 0.5 - 0.5 - 1/2 = -1 -> -1, then
    # 1.5 + 0 -> 2 (residual -1/2), 0.5 - 1/2 -> 0, 0.5 + 1/2 -> 1, ...
    raw = np.zeros((7, 9), np.int16)
    raw[:, 0] = [1, -1, 3, 1, 1, 1, 1]
    assert M.correct(cs, raw)[:, 0].tolist() == [1, -1, 2, 0, 1, 0, 1]


def _still_run(rng, cs, n):
    """n copies of one raw record whose corrected values are not clipped."""
    while True:
        rec = rng.integers(-1500, 1500, 9)
        ref = FP.reference_correct(cs, rec[None])[0]
        if np.all(np.abs(ref[6:]) < 4000):
            return np.tile(rec, (n, 1)).astype(np.int16), ref


@pytest.mark.parametrize("seed", range(8))
def test_mean_of_a_still_run_follows_the_float_reference(seed):
    """Constant raw input (a still board without noise): every sample within
    1 LSB of the float reference, and the mean of N outputs within 1/N of
    it (plain rounding would be off by the value's fraction, up to 1/2)."""
    rng = np.random.default_rng(seed)
    cs = random_calset(rng, shift=[None, 14, 12][seed % 3])
    n = int(rng.integers(200, 3000))
    raw, ref = _still_run(rng, cs, n)
    out = M.correct(cs, raw)
    assert np.abs(out - ref).max() < 1.0, f"seed {seed}"
    err = np.abs(out.mean(axis=0) - ref)
    assert err.max() <= 1.0 / n + 1e-12, f"seed {seed}: mean off by {err.max()} (N = {n})"
    np.testing.assert_array_equal(out, exact(cs, raw))
    # the same run in blocks through the receiver: the residual carries over
    rx = M.CalReceiver(MOTE)
    upload(rx, cs, 3)
    got = np.concatenate([rx.correct(raw[i:i + 5]) for i in range(0, n, 5)])
    np.testing.assert_array_equal(got, out, err_msg=f"seed {seed}")


def test_residuals_reset_on_apply_reset_and_overflow():
    rng = np.random.default_rng(11)
    cs = random_calset(rng)
    raw, _ = _still_run(rng, cs, 7)
    rx = M.CalReceiver(MOTE)
    upload(rx, cs, 3)
    first = rx.correct(raw)
    resid = np.zeros(9, np.int64)
    np.testing.assert_array_equal(first, exact(cs, raw, resid))
    assert np.any(resid != 0)                                  # a residual is carried
    cs2 = random_calset(rng, version=4)
    upload(rx, cs2, 4)                                         # a new set: from 0
    np.testing.assert_array_equal(rx.correct(raw), exact(cs2, raw))
    rx.correct(raw)
    assert send_commit(rx, 5, 0, action=P.CAL_RESET)["status"] == OK   # raw set
    np.testing.assert_array_equal(rx.correct(raw), raw)
    upload(rx, cs, 3)                                          # the first set again: from 0
    np.testing.assert_array_equal(rx.correct(raw), first)
    # an overflow sample on the magnetometer resets its residuals only
    over = raw.copy()
    over[3, 7] = -4096
    resid = np.zeros(9, np.int64)
    want = exact(cs, over, resid)
    assert want[3, 6:].tolist() == [-4096] * 3
    np.testing.assert_array_equal(M.correct(cs, over), want)
    np.testing.assert_array_equal(want[4:, 6:], exact(cs, raw[4:])[:, 6:])


def test_saturates_instead_of_wrapping():
    big = FP.FixedSensor(np.diag([32767, 32767, 32767]), np.array([2**26, -2**26, 0]), 14)
    cs = FP.pack_calset(MOTE, 1, {"accel": big, "gyro": big, "mag": big})
    raw = np.zeros((4, 9), np.int16)
    raw[0] = 32767
    raw[1] = -32768
    raw[2] = [20000, -20000, 0] * 3
    raw[3] = [3000, -3000, 2500] * 3
    out = M.correct(cs, raw)
    assert out[0, :6].tolist() == [32767] * 6
    assert out[1, :6].tolist() == [-32768] * 6
    assert out[2, :6].tolist() == [32767, -32768, 0] * 2
    assert out[0, 6:].tolist() == [4095] * 3                 # mag saturates at +-4095
    assert out[1, 6:].tolist() == [-4095] * 3                # -4096 is reserved
    assert out[3, 6:].tolist() == [4095, -4095, 4095]
    np.testing.assert_array_equal(out, exact(cs, raw))


def test_mag_overflow_passes_through_and_disabled_sensors_are_raw():
    rng = np.random.default_rng(1)
    cs = random_calset(rng, mask=0b101)                      # accel + mag; gyro raw
    raw = rng.integers(-2000, 2000, (5, 9)).astype(np.int16)
    raw[1, 6] = raw[2, 7] = raw[3, 8] = -4096
    out = M.correct(cs, raw)
    assert np.all(out[1:4, 6:] == -4096)
    assert not np.any(out[[0, 4], 6:] == -4096)
    np.testing.assert_array_equal(out[:, 3:6], raw[:, 3:6])  # gyro untouched
    raw_only = random_calset(rng, mask=0b011)                # mag not corrected
    np.testing.assert_array_equal(M.correct(raw_only, raw)[:, 6:], raw[:, 6:])


def test_correct_rejects_bad_format():
    cs = bytearray(random_calset(np.random.default_rng(2)))
    cs[5] = 1                                               # reserved byte
    with pytest.raises(ValueError, match="E_FORMAT"):
        M.correct(bytes(cs), np.zeros((1, 9), np.int16))


# --------------------------------------------------------------------------
# Validation: every reason
# --------------------------------------------------------------------------
def _set(mote=MOTE, version=3, mask=7, a=None, c=None, shift=14, sensor=0):
    base = {n: FP.IDENTITY for n in P.SENSORS}
    if a is not None or c is not None or shift != 14:
        base[P.SENSORS[sensor]] = FP.FixedSensor(
            np.asarray(a if a is not None else FP.IDENTITY.a),
            np.asarray(c if c is not None else [0, 0, 0]), shift)
    sel = {n: base[n] for i, n in enumerate(P.SENSORS) if mask >> i & 1}
    return FP.pack_calset(mote, version, sel)


def _field(cs, offset, value):
    b = bytearray(cs)
    b[offset] = value
    return bytes(b)


def test_validate_every_reason():
    q = 1 << 14
    good = _set()
    assert M.validate(good, MOTE) == OK
    assert M.validate(good, MOTE + 1) == E_MOTE
    assert M.validate(_field(_field(good, 2, 0), 3, 0), MOTE) == E_VERSION
    # format: shift outside 8..14, reserved bytes, unknown sensor bits, length
    assert M.validate(_set(a=np.eye(3) * 2**7, shift=7), MOTE) == E_FORMAT
    assert M.validate(_set(shift=15), MOTE) == E_FORMAT
    assert M.validate(_field(good, 5, 1), MOTE) == E_FORMAT
    assert M.validate(_field(good, 6 + 31, 1), MOTE) == E_FORMAT   # sensor reserved
    assert M.validate(_field(good, 4, 0x0F), MOTE) == E_FORMAT     # unknown bit
    assert M.validate(good[:-1], MOTE) == E_FORMAT
    # range: diagonal, off-diagonal, offset
    assert M.validate(_set(a=np.diag([q // 2 - 1, q, q])), MOTE) == E_RANGE
    assert M.validate(_set(a=np.diag([q // 2, q, q])), MOTE) == OK
    assert M.validate(_set(a=np.diag([q, q, -q])), MOTE) == E_RANGE
    off = np.diag([q, q, q]) + np.array([[0, q // 2, 0], [0] * 3, [0] * 3])
    assert M.validate(_set(a=off), MOTE) == OK
    off[0, 1] = q // 2 + 1
    assert M.validate(_set(a=off), MOTE) == E_RANGE
    assert M.validate(_set(c=[4096 * q, 0, 0]), MOTE) == OK
    assert M.validate(_set(c=[0, -4096 * q - 1, 0]), MOTE) == E_RANGE
    # limits scale with shift: Q10 diagonal 2047 = 1.999 ok, 2048 = 2.0 not
    assert M.validate(_set(a=np.diag([2047, 1024, 1024]), shift=10), MOTE) == OK
    assert M.validate(_set(a=np.diag([2048, 1024, 1024]), shift=10), MOTE) == E_RANGE
    # a sensor that is not corrected is not range-checked
    assert M.validate(_set(mask=0b110, a=np.zeros((3, 3))), MOTE) == OK
    assert M.validate(_set(mask=0b111, a=np.zeros((3, 3))), MOTE) == E_RANGE


# --------------------------------------------------------------------------
# Upload receiver
# --------------------------------------------------------------------------
@HYP
@given(st.integers(0, 2**32 - 1), st.data())
def test_fragments_in_any_order_with_duplicates(seed, data):
    rng = np.random.default_rng(seed)
    cs = random_calset(rng, version=9)
    rx = M.CalReceiver(MOTE)
    # arbitrary fragment boundaries covering the set, shuffled, some repeated
    cuts = sorted(set(data.draw(st.lists(st.integers(1, P.CALSET_SIZE - 1), max_size=12))))
    bounds = [0] + cuts + [P.CALSET_SIZE]
    pieces = [(o, min(o + 20, b)) for a, b in zip(bounds, bounds[1:])
              for o in range(a, b, 20)]
    order = data.draw(st.permutations(pieces))
    dup = data.draw(st.lists(st.sampled_from(pieces), max_size=5))
    for a, b in list(order) + dup:
        assert send_frag(rx, 9, a, cs[a:b])["status"] == OK
    ack = send_commit(rx, 9, binascii.crc_hqx(cs, 0))
    assert ack == dict(mote=MOTE, version=9, crc=binascii.crc_hqx(cs, 0), status=OK,
                       sensors=7)
    assert rx.version == 9 and rx.sensors == 7 and rx.dirty
    assert rx.flags() == (9 << 4) | P.FLAG_CORRECTED
    back, rep = read_back(rx)
    assert back == cs and rep["crc"] == binascii.crc_hqx(cs, 0) and rep["version"] == 9
    raw = full_range_raw(rng, 50)
    np.testing.assert_array_equal(rx.correct(raw), M.correct(cs, raw))


def test_read_back_offsets_and_raw_state():
    rx = M.CalReceiver(MOTE)
    assert (rx.version, rx.sensors, rx.flags(), rx.dirty) == (0, 0, 0, False)
    back, rep = read_back(rx)
    assert len(back) == P.CALSET_SIZE and FP.unpack_calset(back).sensors == {}
    for off, n in ((0, 20), (100, 2), (101, 1), (102, 0), (255, 0)):
        _, pl = rx.handle(P.AM_NINEDOF_CAL_QUERY_MSG, P.CAL_QUERY.pack(mote=MOTE, offset=off))
        r = P.CAL_REPORT.unpack(pl)
        assert r["len"] == n and r["offset"] == off
        assert r["data"][:n] == back[off:off + n]
    raw = np.arange(-40, 50).reshape(10, 9).astype(np.int16)
    np.testing.assert_array_equal(rx.correct(raw), raw)


def test_rejects_leave_the_set_in_force():
    rng = np.random.default_rng(5)
    rx = M.CalReceiver(MOTE)
    good = random_calset(rng, version=4)
    assert upload(rx, good, 4)["status"] == OK
    rx.mark_persisted()
    before = (rx.active_calset(), rx.flags())

    def rejected(code, ack):
        assert ack["status"] == code, P.cal_reason(ack["status"])
        assert ack["version"] == 4 and ack["sensors"] == 7
        assert (rx.active_calset(), rx.flags(), rx.dirty) == (*before, False)

    # fragments: other mote, version 0, outside the set, bad lengths
    assert send_frag(rx, 5, 0, good[:20], mote=MOTE + 1) == \
        dict(mote=MOTE, version=5, offset=0, status=E_MOTE)
    assert send_frag(rx, 0, 0, good[:20])["status"] == E_VERSION
    assert send_frag(rx, 5, 150, good[:20])["status"] == E_FRAG   # past the 164-byte set
    assert send_frag(rx, 5, 0, b"")["status"] == E_FRAG
    bad_len = bytearray(frag(5, 0, good[:20]))
    bad_len[5] = 21
    assert P.CAL_FRAG_ACK.unpack(rx.handle(P.AM_NINEDOF_CAL_FRAG_MSG, bytes(bad_len))[1])[
        "status"] == E_FRAG
    # commit before every byte arrived
    for o in range(0, 80, 20):
        send_frag(rx, 5, o, good[o:o + 20])
    rejected(E_INCOMPLETE, send_commit(rx, 5, binascii.crc_hqx(good, 0)))
    # wrong CRC (a corrupted fragment), reported CRC is what the mote computed
    corrupt = bytearray(good)
    corrupt[85] ^= 0x10
    for o in (80, 100):
        send_frag(rx, 5, o, bytes(corrupt[o:o + 20]))
    ack = send_commit(rx, 5, binascii.crc_hqx(good, 0))
    rejected(E_CRC, ack)
    assert ack["crc"] == binascii.crc_hqx(bytes(corrupt), 0)
    # commit of a version not being staged, unknown action, wrong length, other mote
    rejected(E_VERSION, send_commit(rx, 6, 0))
    rejected(E_ACTION, send_commit(rx, 5, 0, action=7))
    rejected(E_FORMAT, send_commit(rx, 5, binascii.crc_hqx(bytes(corrupt), 0), length=101))
    rejected(E_MOTE, send_commit(rx, 5, 0, mote=MOTE + 1))
    # complete, CRC right, but the set itself is wrong: mote, version field, range
    for cs, code in ((random_calset(rng, version=6, mote=MOTE + 1), E_MOTE),
                     (random_calset(rng, version=99), E_VERSION),
                     (_set(version=6, a=np.diag([8191, 1 << 14, 1 << 14])), E_RANGE),
                     (_field(random_calset(rng, version=6), 5, 1), E_FORMAT)):
        for o in range(0, P.CALSET_SIZE, 20):
            send_frag(rx, 6, o, cs[o:o + 20])
        rejected(code, send_commit(rx, 6, binascii.crc_hqx(cs, 0)))
    # too short and unknown messages get no reply
    assert rx.handle(P.AM_NINEDOF_CAL_FRAG_MSG, frag(5, 0, good[:20])[:-1]) is None
    assert rx.handle(P.AM_NINEDOF_CAL_COMMIT_MSG, b"\0" * 7) is None
    assert rx.handle(P.AM_NINEDOF_CAL_QUERY_MSG, b"\0\7") is None
    assert rx.handle(P.AM_NINEDOF_SAMPLES_MSG, b"\0" * 40) is None
    assert rx.handle(P.AM_NINEDOF_CAL_QUERY_MSG, P.CAL_QUERY.pack(mote=MOTE + 1)) is None
    assert (rx.active_calset(), rx.flags()) == before


def test_new_version_restarts_staging():
    rng = np.random.default_rng(6)
    rx = M.CalReceiver(MOTE)
    v1, v2 = random_calset(rng, version=1), random_calset(rng, version=2)
    for o in range(0, 60, 20):
        send_frag(rx, 1, o, v1[o:o + 20])
    for o in range(60, 102, 20):
        send_frag(rx, 2, o, v2[o:o + 20])          # v2 starts: v1's bytes are gone
    assert send_commit(rx, 1, binascii.crc_hqx(v1, 0))["status"] == E_VERSION
    assert send_commit(rx, 2, binascii.crc_hqx(v2, 0))["status"] == E_INCOMPLETE
    assert upload(rx, v2, 2)["status"] == OK and rx.active_calset() == v2


def test_repeated_commit_is_idempotent_and_reset():
    rng = np.random.default_rng(7)
    rx = M.CalReceiver(MOTE)
    cs = random_calset(rng, version=0x123)
    assert upload(rx, cs, 0x123)["status"] == OK
    assert rx.dirty and rx.flags() == 0x31
    rx.mark_persisted()
    ack = send_commit(rx, 0x123, binascii.crc_hqx(cs, 0))      # the ack was lost
    assert ack["status"] == OK and ack["version"] == 0x123 and not rx.dirty
    # reset: raw output, given version, persisted again
    assert send_commit(rx, 0, 0, action=P.CAL_RESET)["status"] == E_VERSION
    ack = send_commit(rx, 0x124, 0, action=P.CAL_RESET)
    assert ack["status"] == OK and ack["version"] == 0x124 and ack["sensors"] == 0
    assert ack["crc"] == rx.crc == binascii.crc_hqx(rx.active_calset(), 0)
    assert rx.dirty and rx.flags() == 0x40 and rx.version == 0x124
    raw = full_range_raw(rng, 30)
    np.testing.assert_array_equal(rx.correct(raw), raw)
    back = FP.unpack_calset(read_back(rx)[0])
    assert (back.mote, back.version, back.sensors) == (MOTE, 0x124, {})


# --------------------------------------------------------------------------
# Persistent image: two slots, torn writes
# --------------------------------------------------------------------------
def test_image_restore_and_torn_writes():
    rng = np.random.default_rng(8)
    old_cs, new_cs = random_calset(rng, version=10), random_calset(rng, version=11)
    rx = M.CalReceiver(MOTE)
    upload(rx, old_cs, 10)
    img_old = rx.image(41)
    assert len(img_old) == P.CALSET_SIZE + 6 and img_old[:2] == b"N9"
    assert M.image_check(img_old, MOTE) == 41 and M.image_check(img_old, MOTE + 1) is None
    upload(rx, new_cs, 11)
    img_new = rx.image(42)
    blank = b"\xff" * len(img_old)

    def boot(s0, s1):
        r = M.CalReceiver(MOTE)
        return r.restore(s0, s1), r

    res, r = boot(blank, blank)
    assert res == (None, 0, 1) and r.version == 0 and r.flags() == 0
    res, r = boot(img_old, blank)
    assert res == (0, 1, 42) and r.active_calset() == old_cs and not r.dirty
    res, r = boot(img_old, img_new)
    assert res == (1, 0, 43) and r.active_calset() == new_cs
    raw = full_range_raw(rng, 20)
    np.testing.assert_array_equal(r.correct(raw), M.correct(new_cs, raw))
    # the new image torn at every byte while being written over an older one
    # in slot 1: the old set in slot 0 is chosen until the last byte lands
    rx_older = M.CalReceiver(MOTE)
    upload(rx_older, random_calset(rng, version=9), 9)
    older = rx_older.image(40)
    first_done = None
    for k in range(len(img_new) + 1):
        torn = img_new[:k] + older[k:]
        res, r = boot(img_old, torn)
        done = torn == img_new         # also when the rest happened to be equal
        assert res == ((1, 0, 43) if done else (0, 1, 42)), k
        assert r.active_calset() == (new_cs if done else old_cs)
        if done and first_done is None:
            first_done = k
    assert first_done >= len(img_new) - 4     # only the equal tail (shift, reserved)
    # a flipped bit anywhere invalidates a slot
    for pos in (0, 3, 5, 6, 50, len(img_new) - 1):
        bad = bytearray(img_new)
        bad[pos] ^= 0x01
        assert boot(img_old, bytes(bad))[0].slot == 0
    # generation wrap-around: 0x0000 is newer than 0xFFFF
    assert boot(rx.image(0x0000), rx.image(0xFFFF))[0] == (0, 1, 1)
    assert boot(rx.image(0xFFFF), rx.image(0x0000))[0] == (1, 0, 1)


def test_a_set_missing_any_single_byte_is_never_applied():
    """Never a partial set: for every byte of the set, an upload that covers
    all the others (in 1..20-byte fragments, a random order) is refused as
    incomplete, and the set in force, its flags and the EEPROM flag stay as
    they were; sending the missing byte then completes it."""
    for seed in range(3):
        rng = np.random.default_rng(100 + seed)
        rx = M.CalReceiver(MOTE)
        old = random_calset(rng, version=3)
        assert upload(rx, old, 3)["status"] == OK
        rx.mark_persisted()
        before = (rx.active_calset(), rx.flags())
        new = random_calset(rng, version=4)
        crc = binascii.crc_hqx(new, 0)
        for gap in rng.permutation(P.CALSET_SIZE)[:40]:
            gap = int(gap)
            r = M.CalReceiver(MOTE)
            assert upload(r, old, 3)["status"] == OK
            r.mark_persisted()
            pieces = []
            for lo, hi in ((0, gap), (gap + 1, P.CALSET_SIZE)):
                o = lo
                while o < hi:
                    n = int(min(hi - o, rng.integers(1, P.NINEDOF_FRAG_DATA + 1)))
                    pieces.append((o, new[o:o + n]))
                    o += n
            for i in rng.permutation(len(pieces)):
                assert send_frag(r, 4, *pieces[i])["status"] == OK
            ack = send_commit(r, 4, crc)
            assert ack["status"] == E_INCOMPLETE, (seed, gap)
            assert (r.active_calset(), r.flags(), r.dirty) == (*before, False), (seed, gap)
            assert send_frag(r, 4, gap, new[gap:gap + 1])["status"] == OK
            assert send_commit(r, 4, crc)["status"] == OK and r.active_calset() == new


@pytest.mark.parametrize("seed", range(3))
def test_corrector_carries_the_residuals_from_block_to_block(seed):
    rng = np.random.default_rng(100 + seed)
    cs = random_calset(rng)
    raw = full_range_raw(rng, 300)
    cor = M.Corrector(cs)
    got = np.concatenate([cor.correct(raw[i:i + 7]) for i in range(0, len(raw), 7)])
    np.testing.assert_array_equal(got, M.correct(cs, raw), err_msg=f"seed {seed}")
    np.testing.assert_array_equal(got, exact(cs, raw), err_msg=f"seed {seed}")
