"""Physical calibration -> fixed-point calibration set (host/motecal/firmware/fixedpoint.py)."""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from motecal.firmware import fixedpoint as FP
from motecal.firmware import mote_c
from motecal.line import protocol as P
from motecal.sessions.session import NOMINAL_SCALES


def physical(sensor, rng, scale_err=0.05, cross=0.02, offset_counts=100):
    """A calibration in physical units: calibrated = A raw + c."""
    k = NOMINAL_SCALES[sensor]
    M = np.diag(1 + rng.uniform(-scale_err, scale_err, 3)) + \
        (1 - np.eye(3)) * rng.uniform(-cross, cross, (3, 3))
    return M / k, rng.uniform(-offset_counts, offset_counts, 3) / k


def test_counts_domain_uses_nominal_scales():
    A = np.eye(3) / 256.0 * 1.02
    c = np.array([0.1, -0.2, 0.05])           # g
    M, off = FP.counts_domain("accel", A, c)
    np.testing.assert_allclose(M, np.eye(3) * 1.02)
    np.testing.assert_allclose(off, [25.6, -51.2, 12.8])
    M, off = FP.counts_domain("gyro", np.eye(3) / 14.375, [1.0, 0, 0])
    np.testing.assert_allclose(off, [14.375, 0, 0])
    M, off = FP.counts_domain("mag", np.eye(3) / 1090.0, [0, 0.1, 0])
    np.testing.assert_allclose(off, [0, 109.0, 0])


def test_shift_is_the_largest_that_fits():
    fs = FP.quantise(np.eye(3) * 1.3, [10.25, -3.5, 0])
    assert fs.shift == 14
    np.testing.assert_array_equal(np.diag(fs.a), [21299] * 3)     # round(1.3 * 16384)
    np.testing.assert_array_equal(fs.c, [167936, -57344, 0])
    assert FP.quantise(np.eye(3) * 1.99999, [0, 0, 0]).shift == 13     # 32768 > int16
    assert FP.quantise(np.eye(3) * 3.0, [0, 0, 0]).shift == 13
    assert FP.quantise(np.eye(3) * 100.0, [0, 0, 0]).shift == 8
    # the int32 accumulator bound: sum |a| * 32768 + |c| < 2^31
    assert FP.quantise(np.full((3, 3), 1.5), [0, 0, 0]).shift == 13
    with pytest.raises(FP.NotRepresentable):
        FP.quantise(np.eye(3) * 200.0, [0, 0, 0])
    with pytest.raises(FP.NotRepresentable):
        FP.quantise(np.eye(3), [np.nan, 0, 0])


def test_pack_unpack_round_trip_and_layout():
    rng = np.random.default_rng(3)
    fixed = {n: FP.fixed_from_physical(n, *physical(n, rng)) for n in ("accel", "mag")}
    data = FP.pack_calset(0x1234, 77, fixed)
    assert len(data) == P.CALSET_SIZE == 102
    assert data[:6] == bytes([0x12, 0x34, 0, 77, 0b101, 0])
    cs = FP.unpack_calset(data)
    assert (cs.mote, cs.version, cs.mask) == (0x1234, 77, 0b101)
    assert cs.sensors == fixed
    assert cs.stored["gyro"] == FP.IDENTITY                 # raw sensor: identity, bit clear
    assert FP.pack_calset(cs.mote, cs.version, cs.sensors) == data
    # the mote reads the same bytes the same way
    assert mote_c.validate(data, 0x1234) == P.CAL_OK
    with pytest.raises(ValueError):
        FP.pack_calset(1, 0, {})
    with pytest.raises(ValueError):
        FP.pack_calset(1, 1, {"baro": FP.IDENTITY})
    with pytest.raises(ValueError):
        FP.unpack_calset(data[:-1])


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_reported_bound_holds_over_each_chips_input_range(seed):
    """The mote's output stays within the reported worst case of the physical
    calibration over each chip's whole input range."""
    rng = np.random.default_rng(seed)
    phys = {n: physical(n, rng, scale_err=0.3, cross=0.1, offset_counts=3000)
            for n in P.SENSORS}
    data, report = FP.build_calset(5, 1, phys)
    raw = np.zeros((600, 9), np.int16)
    for n, sl in FP.SENSOR_SLICES.items():
        R = FP.INPUT_RANGE[n]
        block = rng.integers(-R, R, (600, 3))
        block[:8] = np.array([[s0, s1, s2] for s0 in (-R, R - 1) for s1 in (-R, R - 1)
                              for s2 in (-R, R - 1)])
        raw[:, sl] = block
    out = mote_c.correct(data, raw).astype(np.float64)
    for n, (A, c) in phys.items():
        sl = FP.SENSOR_SLICES[n]
        want = FP.physical_correct(n, A, c, raw[:, sl])
        lim = 4095 if n == "mag" else 32767
        inside = np.all(np.abs(want) < lim - 2, axis=1)
        err = np.abs(out[inside, sl] - want[inside])
        assert np.all(err <= report[n].worst_lsb + 1e-9), n
    # the quantisation's part (what is left after the output rounding's 1 LSB)
    assert np.all(report["accel"].worst_lsb - FP.OUTPUT_ROUNDING_LSB < 0.5)
    assert np.all(report["mag"].worst_lsb - FP.OUTPUT_ROUNDING_LSB < 0.5)
    assert np.all(report["gyro"].worst_lsb <= 3 * 2**-15 * 32768 + FP.OUTPUT_ROUNDING_LSB)  # Q14 limit


def test_rounding_report_numbers():
    A = np.eye(3) * (1 + 1 / 3) / 256.0
    r = FP.rounding_report("accel", A, [0.0, 0.0, 0.0])
    assert r.fixed.shift == 14
    assert r.matrix_error == pytest.approx(abs(21845 / 16384 - 4 / 3))
    assert r.offset_error == 0
    np.testing.assert_allclose(r.worst_lsb, r.matrix_error * 4096 + FP.OUTPUT_ROUNDING_LSB)
    np.testing.assert_allclose(r.worst_units, r.worst_lsb / 256.0)
    lines = FP.format_report({"accel": r})
    assert lines[0].startswith("accel: Q14  matrix a = [21845, 0, 0, 0, 21845")
    assert "LSB" in lines[1] and "g)" in lines[1]
    assert lines[2] == "gyro: not corrected (raw)"


def test_reference_applies_saturation_and_overflow():
    fs = FP.FixedSensor(np.eye(3, dtype=int) * 32767, np.array([0, 0, 0]), 14)
    data = FP.pack_calset(1, 1, {"gyro": fs, "mag": fs})
    raw = np.zeros((2, 9))
    raw[0, 3:9] = [30000, -30000, 5, 3000, -3000, 5]
    raw[1, 6:9] = [-4096, 10, 10]
    ref = FP.reference_correct(data, raw)
    assert ref[0, 3:5].tolist() == [32767, -32768]
    assert ref[0, 6:8].tolist() == [4095, -4095]
    assert ref[1, 6:9].tolist() == [-4096] * 3
    assert ref[0, 5] == pytest.approx(5 * 32767 / 16384)
