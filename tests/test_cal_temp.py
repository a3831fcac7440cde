"""On-mote temperature correction (calset format 1, tinyos/ninedof_correct.c).

The C correction with temperature terms against the float reference
(fixedpoint.reference_correct) over random valid sets and temperatures: within
1 LSB everywhere, clamped outside the calibrated range; cal.json's TempModel
-> the set (and back, in physical units); sets without temperature stay the
102-byte plain set byte for byte; the receiver, read-back and EEPROM image of
the 164-byte set; a set an old image saved in its second slot (0x180) still
loads; an image that refuses the longer set is named in one line and
--no-temp uploads the plain set.
"""
import binascii
import json

import numpy as np
import pytest
from hypothesis import assume, given, settings, strategies as st

from motecal import upload as U
from motecal.calib.result import TempModel
from motecal.firmware import fixedpoint as FP
from motecal.firmware import mote_c as M
from motecal.line import protocol as P
from motecal.sessions.session import NOMINAL_SCALES
from motecal.sim.world import World, WorldPort

from clirun import motecal

MOTE = 7


def random_fixed(rng) -> FP.FixedSensor:
    Mx = np.diag(rng.uniform(0.55, 1.95, 3)) + (1 - np.eye(3)) * rng.uniform(-0.45, 0.45, (3, 3))
    return FP.quantise(Mx, rng.uniform(-4000, 4000, 3))


def random_temp(rng) -> FP.FixedTemp:
    """Temperature terms inside the mote's limits: a range of up to 40 C
    (11200 TEMP_OUT counts) around t_ref, |g dT| <= 1/8, |o dT| <= 4096."""
    t_ref = int(rng.integers(-25000, -5000))
    t_lo = max(t_ref - int(rng.integers(0, 11200)), -32768)
    t_hi = t_ref + int(rng.integers(0, 11200))
    span = max(t_ref - t_lo, t_hi - t_ref, 100)
    g = rng.uniform(-0.12, 0.12, 3) / span * rng.choice([1.0, 1e-2, 1e-4])
    o = np.clip(rng.uniform(-4000, 4000, 3) / span, -1.9, 1.9) * rng.choice([1.0, 1e-2, 1e-4])
    oq, osh = FP._quantise16(o, FP.OSHIFT_MIN, FP.OSHIFT_MAX, "offsets")
    gq, gsh = FP._quantise16(g, FP.GSHIFT_MIN, FP.GSHIFT_MAX, "gains")
    return FP.FixedTemp(t_ref, t_lo, t_hi, oq, gq, osh, gsh)


def raw_records(rng, n):
    raw = rng.integers(-32768, 32768, (n, 9))
    raw[: n // 2] = rng.integers(-3000, 3000, (n // 2, 9))     # the usual counts
    raw[:6] = np.array([-32768, 32767, 0, -1, 1, 16384])[:, None]
    raw[rng.choice(n, n // 20, replace=False), 6 + rng.integers(0, 3, n // 20)] = -4096
    return raw.astype(np.int16)


@pytest.mark.slow
@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_within_one_lsb_of_the_float_reference(seed):
    """Random valid sets with temperature terms on random sensors, at random
    temperatures inside and outside the range: |C - reference| below
    fixedpoint.TEMP_BOUND_LSB (1 - 2^-11, ninedof_correct.h), and the C output
    is the integer model's (fixedpoint.feedback_correct) bit for bit."""
    rng = np.random.default_rng(seed)
    sensors = {n: random_fixed(rng) for n in P.SENSORS}
    names = [n for n in P.SENSORS if rng.random() < 0.7] or ["gyro"]
    temps = {n: random_temp(rng) for n in names}
    cs = FP.pack_calset(MOTE, 1, sensors, temps)
    assume(M.validate(cs, MOTE) == P.CAL_OK)     # a set the mote puts in force
    raw = raw_records(rng, 400)
    worst = 0.0
    for t in [None] + [int(v) for v in rng.integers(-32768, 32768, 3)] + \
            [max(temps[names[0]].t_lo - 500, -32768), temps[names[0]].t_hi + 500]:
        got = M.correct(cs, raw, t)
        np.testing.assert_array_equal(got, FP.feedback_correct(cs, raw, None, t),
                                      err_msg=f"seed {seed}, T {t}")
        err = np.abs(got - FP.reference_correct(cs, raw, t))
        worst = max(worst, float(err.max()))
    assert worst < FP.TEMP_BOUND_LSB, f"seed {seed}: {worst} LSB from the float reference"


def test_clamped_outside_the_range_and_reference_at_t_ref():
    rng = np.random.default_rng(3)
    tf = FP.FixedTemp(-16000, -18800, -11800, [20000, -20000, 5000], [15000, 0, -15000],
                      22, 32)
    cs = FP.pack_calset(MOTE, 2, {"gyro": random_fixed(rng)}, {"gyro": tf})
    assert M.validate(cs, MOTE) == P.CAL_OK
    raw = raw_records(rng, 200)
    base = M.correct(cs, raw)                       # no temperature yet: at t_ref
    np.testing.assert_array_equal(base, M.correct(cs, raw, -16000))
    np.testing.assert_array_equal(base, M.correct(FP.without_temperature(cs), raw))
    # clamped: every temperature beyond an end gives that end's output
    for end, beyond in ((-18800, (-30000, -18801, -20000)), (-11800, (-11799, 0, 32767))):
        at_end = M.correct(cs, raw, end)
        assert not np.array_equal(at_end, base)
        for t in beyond:
            np.testing.assert_array_equal(M.correct(cs, raw, t), at_end)
    # the offset moves the output by o dT: gyro x at dT = +4200 counts
    quiet = np.zeros((1, 9), np.int16)
    d = M.correct(cs, quiet, -11800)[0, 3:6].astype(float) - M.correct(cs, quiet)[0, 3:6]
    np.testing.assert_allclose(d, tf.offset_per_count * 4200, atol=1.0)


def test_invalid_temperature_terms_are_refused():
    rng = np.random.default_rng(4)
    fs = {"accel": random_fixed(rng)}
    ok = FP.FixedTemp(-16000, -17000, -15000, [100, 0, 0], [100, 0, 0], 20, 30)
    assert M.validate(FP.pack_calset(MOTE, 1, fs, {"accel": ok}), MOTE) == P.CAL_OK
    E_RANGE, E_FORMAT = 6, 7
    bad = {
        "range reversed": (FP.FixedTemp(-16000, -15000, -17000, [0] * 3, [0] * 3, 20, 30), E_RANGE),
        "gain over 1/8": (FP.FixedTemp(-16000, -20000, -12000, [0] * 3, [32767, 0, 0], 20,
                                       28), E_RANGE),   # 0.49 at dT 4000
        "offset over 4096": (FP.FixedTemp(-16000, -30000, -2000, [32767, 0, 0], [0] * 3, 14, 30),
                             E_RANGE),
        "dT over int16": (FP.FixedTemp(20000, -20000, 20000, [0] * 3, [0] * 3, 20, 30), E_RANGE),
        "oshift": (FP.FixedTemp(-16000, -17000, -15000, [1, 0, 0], [0] * 3, 13, 30), E_FORMAT),
        "gshift": (FP.FixedTemp(-16000, -17000, -15000, [1, 0, 0], [0] * 3, 20, 47), E_FORMAT),
    }
    for what, (tf, code) in bad.items():
        assert M.validate(FP.pack_calset(MOTE, 1, fs, {"accel": tf}), MOTE) == code, what
    # terms for a sensor that is not corrected, a reserved byte, a shift below 14
    cs = bytearray(FP.pack_calset(MOTE, 1, fs, {"accel": ok}))
    cs[P.CALSET_SIZE] |= 0b010                      # temp bit for the raw gyro
    assert M.validate(bytes(cs), MOTE) == E_FORMAT
    cs = bytearray(FP.pack_calset(MOTE, 1, fs, {"accel": ok}))
    cs[P.CALSET_SIZE + 1] = 1
    assert M.validate(bytes(cs), MOTE) == E_FORMAT
    q13 = FP.FixedSensor(fs["accel"].a >> 1, fs["accel"].c >> 1, 13)
    assert M.validate(FP.pack_calset(MOTE, 1, {"accel": q13}, {"accel": ok}), MOTE) == E_FORMAT
    # a length that is not the format's
    assert M.validate(FP.pack_calset(MOTE, 1, fs, {"accel": ok})[:P.CALSET_SIZE], MOTE) == E_FORMAT


# --------------------------------------------------------------------------
# cal.json's TempModel -> the set
# --------------------------------------------------------------------------
def tempmodel(rng, sensor):
    k = NOMINAL_SCALES[sensor]
    return TempModel(t_ref_c=25.0, range_c=(18.0, 41.5),
                     offset_per_c=rng.uniform(-3, 3, 3) / k, offset_per_c_std=[0.001] * 3,
                     scale_per_c=rng.uniform(-8e-4, 8e-4, 3))


def test_tempmodel_to_fixed_point_and_back():
    rng = np.random.default_rng(5)
    A, c = np.eye(3) / 14.375 * 1.01, np.array([0.5, -1.0, 0.2])
    tm = tempmodel(rng, "gyro")
    data, report = FP.build_calset(3, 9, {"gyro": (A, c)}, {"gyro": tm})
    assert len(data) == P.CALSET_TEMP_SIZE == 164 and data[5] == P.CALSET_TEMP
    cs = FP.unpack_calset(data)
    ft = cs.temps["gyro"]
    assert (ft.t_ref, ft.t_lo, ft.t_hi) == (-16000, -17960, -11380)   # 25, 18, 41.5 C
    per = P.ITG3200_TEMP_LSB_PER_C
    np.testing.assert_allclose(ft.offset_per_count * per / 14.375, tm.offset_per_c, rtol=1e-3)
    np.testing.assert_allclose(ft.gain_per_count * per, tm.scale_per_c, rtol=1e-3)
    assert report["gyro"].temp == ft and report["gyro"].temp_offset_error < 0.05
    # the set on the mote against the float calibration (TempModel applied on
    # the host) at temperatures across and beyond the range
    raw = np.random.default_rng(6).integers(-3000, 3000, (300, 9)).astype(np.int16)
    from motecal.calib.result import SensorCalibration
    for t_c in (10.0, 18.0, 25.0, 33.3, 41.5, 60.0):
        t_raw = int(round(float(P.temp_raw(t_c))))
        out = M.correct(data, raw, t_raw)[:, 3:6]
        y = raw[:, 3:6].astype(float) @ A.T
        dt = np.clip(t_c, *tm.range_c) - tm.t_ref_c
        host = (y * (1 + tm.scale_per_c * dt) + c + tm.offset_per_c * dt) * 14.375
        # quantisation of A (Q14) over |raw| <= 3000, rounding, a TEMP_OUT count
        assert np.abs(out - host).max() <= 1.5, t_c
    lines = FP.format_report(report)
    assert any("temperature: t_ref 25.00 C, clamped to 18.00..41.50 C" in ln for ln in lines)
    # without temperature models: the plain set, byte for byte
    plain, _ = FP.build_calset(3, 9, {"gyro": (A, c)})
    assert len(plain) == 102 and plain[5] == 0
    assert FP.without_temperature(data) == plain
    assert FP.build_calset(3, 9, {"gyro": (A, c)}, {})[0] == plain
    assert FP.pack_calset(3, 9, FP.unpack_calset(plain).sensors) == plain


# --------------------------------------------------------------------------
# The receiver and the EEPROM
# --------------------------------------------------------------------------
def _upload(rx, calset, version):
    for o in range(0, len(calset), P.NINEDOF_FRAG_DATA):
        t, pl = rx.handle(P.AM_NINEDOF_CAL_FRAG_MSG, P.CAL_FRAG.pack(
            mote=rx.mote_id, version=version, offset=o, len=len(calset[o:o + 20]),
            data=calset[o:o + 20]))
        assert P.CAL_FRAG_ACK.unpack(pl)["status"] == P.CAL_OK
    t, pl = rx.handle(P.AM_NINEDOF_CAL_COMMIT_MSG, P.CAL_COMMIT.pack(
        mote=rx.mote_id, version=version, length=len(calset), action=P.CAL_APPLY,
        crc=binascii.crc_hqx(calset, 0)))
    return P.CAL_COMMIT_ACK.unpack(pl)


def test_receiver_eeprom_and_the_old_second_slot():
    rng = np.random.default_rng(7)
    tset = FP.pack_calset(MOTE, 5, {n: random_fixed(rng) for n in P.SENSORS},
                          {"gyro": random_temp(rng), "mag": random_temp(rng)})
    assert M.validate(tset, MOTE) == P.CAL_OK
    rx = M.CalReceiver(MOTE)
    ack = _upload(rx, tset, 5)
    assert ack["status"] == P.CAL_OK and rx.active_calset() == tset and rx.crc == P.crc16(tset)
    # a commit whose length is not the set's format is refused
    ack = _upload(M.CalReceiver(MOTE), tset[:P.CALSET_SIZE], 5)
    assert ack["status"] == 7
    raw = raw_records(rng, 100)
    np.testing.assert_array_equal(rx.correct(raw), M.correct(tset, raw))   # no temperature yet
    rx.set_temperature(-14000)
    at = rx.correct(raw)                   # the residuals carry on from the block before
    ref = M.correct(tset, raw, -14000)     # a fresh set: from 0
    assert np.abs(at.astype(int) - ref).max() <= 1
    rx2 = M.CalReceiver(MOTE)
    _upload(rx2, tset, 5)
    rx2.set_temperature(-14000)
    np.testing.assert_array_equal(rx2.correct(raw), ref)
    # a set put in force later takes the temperature already known
    t2 = FP.pack_calset(MOTE, 6, {"gyro": random_fixed(rng)}, {"gyro": random_temp(rng)})
    assert _upload(rx, t2, 6)["status"] == P.CAL_OK
    np.testing.assert_array_equal(rx.correct(raw), M.correct(t2, raw, -14000))
    # EEPROM: the 170-byte image in slot 0, restored at the next boot
    ee = M.EepromWriter(rx)
    assert ee.poll()
    while ee.step():
        pass
    assert ee.slot_addr(0) == 0x100 and ee.slot_addr(1) == 0x200
    r2 = M.CalReceiver(MOTE)
    ee2 = M.EepromWriter(r2, ee.eeprom)
    assert ee2.restored == (0, 1, 2) and r2.active_calset() == t2
    # an old image's EEPROM: its second slot at 0x180 (108-byte image of a
    # plain set, newer than its first slot) is what goes in force, and the
    # next write goes to slot 1 at 0x200, overlapping neither old slot
    old_rx, newer = M.CalReceiver(MOTE), M.CalReceiver(MOTE)
    old_set = FP.pack_calset(MOTE, 3, {"accel": random_fixed(rng)})
    _upload(old_rx, old_set, 3)
    _upload(newer, FP.pack_calset(MOTE, 4, {"mag": random_fixed(rng)}), 4)
    eeprom = bytearray(b"\xff" * 4096)
    eeprom[0x100:0x100 + 108] = old_rx.image(1)
    eeprom[0x180:0x180 + 108] = newer.image(2)
    r3 = M.CalReceiver(MOTE)
    ee3 = M.EepromWriter(r3, eeprom)
    assert ee3.restored == (2, 1, 3) and r3.version == 4
    # ... and when the old first slot is the newer one, that one
    eeprom[0x180:0x180 + 108] = newer.image(0)
    r4 = M.CalReceiver(MOTE)
    assert M.EepromWriter(r4, eeprom).restored == (0, 1, 2) and r4.active_calset() == old_set
    # a temperature set is never taken from the old second slot
    eeprom[0x180:0x180 + 170] = rx.image(9)
    assert M.EepromWriter(M.CalReceiver(MOTE), eeprom).restored.slot == 0


# --------------------------------------------------------------------------
# Upload: cal.json format 2, an image without temperature terms, --no-temp
# --------------------------------------------------------------------------
@pytest.fixture(scope="module")
def cal_temp(tmp_path_factory):
    """A cal.json (format 2) with temperature models for gyro and accel."""
    rng = np.random.default_rng(8)
    d = {"format_version": 2, "mote": 1, "session": "planted"}
    for name in P.SENSORS:
        k = NOMINAL_SCALES[name]
        A = (np.eye(3) * (1 + rng.uniform(-0.03, 0.03, 3))) / k
        d[name] = {"A": A.tolist(), "c": (rng.uniform(-50, 50, 3) / k).tolist()}
    for name in ("gyro", "accel"):
        d[name]["temperature"] = tempmodel(rng, name).to_json()
    path = tmp_path_factory.mktemp("caltemp") / "cal.json"
    path.write_text(json.dumps(d))
    return path


def _world(celsius=None, temperature=True):
    """temperature=False: the mote runs an image built before the temperature
    terms (``motecal sim --no-temp``): it refuses a set with them."""
    w = World(motes=1, session="idle", seed=2, duration=3600.0, temperature=temperature)
    if celsius is not None:          # the board's temperature (the thermal model's place)
        w.motes[1].temperature_c = lambda t: np.full(np.shape(t), float(celsius))
    port = WorldPort(w)
    w.run_until(0.5)
    return w, port


def test_upload_with_temperature_terms_and_to_an_old_image(cal_temp):
    cal = U.load_cal(cal_temp)
    assert set(cal.temps) == {"gyro", "accel"}
    # a new image: the 164-byte set in 9 fragments, read back identical
    w, port = _world(celsius=35.0)
    res = U.upload_cal(port, cal, 1, U.Options(), progress=U.NullProgress())
    tset, _ = U.build_set(cal, 1, 1)
    assert len(tset) == 164 and w.motes[1].cal.active_calset() == tset
    assert res.stats.messages == 1 + 9 + 1 + 9 + res.stored.polls and res.readback
    assert res.stored.reported and w.motes[1].cal.stored_version == 1
    # the simulated mote corrects as the firmware: at the mean TEMP_OUT of the
    # last temperature message (35 C: -13200), before the first one at t_ref
    w.run_until(w.now + 2.0)
    sent = w.sent[1]
    new = np.flatnonzero(sent.flags == U.flags_for(1, 0b111))
    raw = sent.raw[new]
    at35, base = M.correct(tset, raw, -13200), M.correct(tset, raw)
    assert not np.array_equal(at35, base)
    got = sent.records[new]
    # t_ref up to the first temperature message (row k), then 35 C, the
    # rounding residuals carried across: replayed on a receiver of our own
    k = int(np.flatnonzero(np.any(got != base, axis=1))[0])
    assert np.array_equal(got[:k], base[:k])

    def replay(k):
        rx = M.CalReceiver(1)
        assert _upload(rx, tset, 1)["status"] == P.CAL_OK
        head = rx.correct(raw[:k])
        rx.set_temperature(-13200)
        return np.concatenate([head, rx.correct(raw[k:])])
    assert any(np.array_equal(got, replay(j)) for j in range(max(k - 20, 0), k + 1))
    assert np.abs(got[-150:].astype(int) - at35[-150:]).max() <= 1
    # an old image (the simulator's --no-temp mote): refused in one line at the
    # first fragment past the plain set, nothing changed on the mote
    w, port = _world(temperature=False)
    with pytest.raises(U.NoTemperature) as exc:
        U.upload_cal(port, cal, 1, U.Options(), progress=U.NullProgress())
    msg = str(exc.value)
    assert "\n" not in msg and "refused the temperature terms" in msg and "--no-temp" in msg
    assert exc.value.exit_code == 1 and w.motes[1].cal.version == 0
    assert w.motes[1].cal.handle(P.AM_NINEDOF_CAL_COMMIT_MSG, P.CAL_COMMIT.pack(
        mote=1, version=1, length=164, action=P.CAL_APPLY,
        crc=P.crc16(tset)))[1][6] == 3          # nothing past byte 102 was staged: incomplete
    # --no-temp: the plain set, byte for byte the set of a cal.json without models;
    # the old image does not report its stored set: the upload waits, and says so
    res = U.upload_cal(port, cal, 1, U.Options(temperature=False), progress=U.NullProgress())
    plain = w.motes[1].cal.active_calset()
    assert len(plain) == 102 and res.stats.messages == 1 + 6 + 1 + 6 + 1
    assert not res.stored.reported and res.stored.waited >= U.OLD_IMAGE_WAIT
    assert "stored: not reported by its firmware" in U.summary(res)
    cal_plain = U.CalFile(cal.path, cal.mote, cal.physical)
    assert plain == U.build_set(cal_plain, 1, 1)[0] == FP.without_temperature(tset)


def test_cli_dry_run_and_show_the_temperature_terms(cal_temp):
    rc, out, err = motecal("upload", cal_temp, "--dry-run")
    assert rc == 0, err
    assert "164 bytes in 9 fragments" in out and "with temperature terms" in out
    assert out.count("temperature: t_ref 25.00 C, clamped to 18.00..41.50 C") == 2
    assert "the mote's checks (tinyos/ninedof_calset.c): accepted" in out
    rc, out, err = motecal("upload", cal_temp, "--dry-run", "--no-temp")
    assert rc == 0 and "102 bytes in 6 fragments" in out
    assert "temperature models left out: --no-temp" in out and "t_ref" not in out
    # --show decodes the terms of a set in force
    cal = U.load_cal(cal_temp)
    tset, _ = U.build_set(cal, 1, 4)
    inf = U.InForce(1, 4, P.crc16(tset), tset)
    from motecal.upload.describe import show_lines
    lines = show_lines(inf, cal)
    assert sum("temperature: t_ref 25.00 C" in ln for ln in lines) == 2
    assert lines[-1].startswith("  equals ")


# --------------------------------------------------------------------------
# The first second after power-on: the latest TEMP_OUT reading, not t_ref
# --------------------------------------------------------------------------
def _booted_with(tmp_path, tset, celsius):
    """A world whose mote 1 boots with `tset` in its EEPROM (slot 0) and a
    board at temperature celsius(t) (t: seconds since power-on)."""
    rx = M.CalReceiver(1)
    assert _upload(rx, tset, 1)["status"] == P.CAL_OK
    ee = bytearray(b"\xff" * M.EepromWriter.SIZE)
    img = rx.image(1)
    at = M.library().ninedof_slot_addr(0)
    ee[at:at + len(img)] = img
    path = tmp_path / "ee.json"
    path.write_text(json.dumps({"format": "motecal-sim-eeprom", "motes": {"1": ee.hex()}}))
    w = World(motes=1, session="idle", seed=4, duration=3600.0, eeprom=path)
    w.motes[1].temperature_c = celsius
    w.run_until(2.5)
    return w


def test_first_second_corrected_at_the_latest_reading(tmp_path):
    """Before the first temperature message's mean, the simulated mote (as
    the firmware, NineDofAppP) corrects each batch at the TEMP_OUT reading
    of the read that completed it; a warm board is not corrected at t_ref."""
    ft = FP.FixedTemp(int(P.temp_raw(25.0)), int(P.temp_raw(10.0)), int(P.temp_raw(50.0)),
                      [30000, -30000, 20000], [0, 0, 0], 22, 30)       # 20-30 counts at 40 C
    fs = FP.FixedSensor(np.eye(3, dtype=np.int64) << 14, [0, 0, 0], 14)
    tset = FP.pack_calset(1, 1, {"gyro": fs}, {"gyro": ft})
    # a constant 40 C: every sample from the first corrected at 40 C (-> 1 LSB)
    w = _booted_with(tmp_path, tset, lambda t: np.full(np.shape(t), 40.0))
    sent = w.sent[1]
    at40 = M.correct(tset, sent.raw, int(P.temp_raw(40.0)))
    base = M.correct(tset, sent.raw)                                   # at t_ref
    assert np.all(sent.flags & P.FLAG_CORRECTED) and len(sent) > 250
    assert np.abs(at40[:, 3:6].astype(int) - base[:, 3:6]).min() >= 15
    assert np.abs(sent.records.astype(int) - at40).max() <= 1
    # warming fast (3 C/s): batch by batch at the completing read's TEMP_OUT
    # until the first mean (the mote's first temperature message)
    warm = lambda t: 30.0 + 3.0 * np.asarray(t, float)                # noqa: E731
    w = _booted_with(tmp_path, tset, warm)
    mote, sent = w.motes[1], w.sent[1]
    first = mote.temps[0][0]                    # newest sample of the first mean
    seq, raw, got = sent.seq, sent.raw, sent.records
    cor = M.Corrector(tset)
    checked = 0
    for k0 in range(0, first - 5, 5):
        rows = (seq >= k0) & (seq < k0 + 5)
        if rows.sum() != 5:
            continue
        t_read = int(np.rint(P.temp_raw(warm(mote.sample_times(k0 + 5, k0 + 6)))[0]))
        cor.set_temperature(t_read)
        np.testing.assert_array_equal(got[rows], cor.correct(raw[rows]), err_msg=f"k0 {k0}")
        checked += 1
    assert checked >= 10
