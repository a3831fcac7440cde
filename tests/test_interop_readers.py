"""Readers of other tools' recordings (motecal.foreign, motecal.floatlog): imucal's
annotated CSV (its real example, MIT) and its continuous session with a section
list, FreeIMU-cal float logs with declared or inferred scales, turntable runs, and
bad files (one error naming file and line)."""
import numpy as np
import pytest

import interop_data as D
from motecal.sessions import floatlog as F
from motecal.sessions import foreign as X
from motecal.errors import UserError
from motecal.sessions.session import LABEL_ROT


# ---------------------------------------------------------------- imucal, the real example

def test_imucal_example_annotated_session(tmp_path):
    path = D.imucal_annotated(tmp_path)
    d = X.read_imucal_annotated(path, rate_hz=204.8, scale="accel=2048,gyro=16.4")
    assert len(d) == 9414 and d.kind == "static"
    assert d.poses() == [1, 2, 3, 4, 5, 6]
    assert d.meta["pose_names"] == {"1": "x_p", "2": "x_a", "3": "y_p", "4": "y_a",
                                    "5": "z_p", "6": "z_a"}
    rot = {r["name"]: r for r in d.meta["rotations"]}
    assert sorted(rot) == ["x_rot", "y_rot", "z_rot"]
    for r in rot.values():
        a, b = r["rows"]
        assert (d.label[a:b] == LABEL_ROT).all() and r["angle_deg"] == 360.0
    assert (d.label == LABEL_ROT).sum() == 1305 + 1093 + 1420
    # counts stay counts: nothing rounded
    assert "at most 0 count" in d.meta["rounding"]["accel"]
    np.testing.assert_array_equal(d.raw[:, :6], np.rint(d.raw[:, :6]))
    assert np.isnan(d.raw[:, 6:]).all()
    # x_p: +1 g on x (about 2048 counts)
    xp = d.sensor("accel")[d.label == 1].mean(axis=0)
    assert 1950 < xp[0] < 2150 and abs(xp[1]) < 200
    np.testing.assert_allclose(d.t, d.seq / 204.8)


def test_imucal_annotated_needs_rate_and_scale(tmp_path):
    path = D.imucal_annotated(tmp_path)
    with pytest.raises(UserError, match="--rate-hz"):
        X.read_imucal_annotated(path, scale="accel=2048,gyro=16.4")
    with pytest.raises(UserError, match="counts need a scale"):
        X.read_imucal_annotated(path, rate_hz=204.8)


# ---------------------------------------------------------------- imucal shapes, planted truth

def test_annotated_synthetic_labels(tmp_path):
    s = D.ferraris(3)
    p = D.write_annotated(s, tmp_path / "ann.csv")
    d = X.read_imucal_annotated(p, rate_hz=s["rate"], scale="accel=2048,gyro=16.4")
    np.testing.assert_array_equal(d.sensor("accel"), s["acc"])      # back in time order
    np.testing.assert_array_equal(d.sensor("gyro"), s["gyr"])
    for i, name in enumerate(D.FACES, start=1):
        want = np.array([p == name for p in s["parts"]])
        np.testing.assert_array_equal(d.label == i, want)


def test_session_with_section_list_is_lossless(tmp_path):
    s = D.ferraris(4)
    csv_path, lst = D.write_session(s, tmp_path / "ferraris_session.csv")
    d = X.read_imucal_session(csv_path, rate_hz=s["rate"], gravity=9.81)   # list found beside
    # the file's own step: 9.81 / 2048 m/s^2 and 1 / 16.4 deg/s -> the counts, exactly
    assert d.scales["accel"] == pytest.approx(2048.0, rel=1e-9)
    assert d.scales["gyro"] == pytest.approx(16.4, rel=1e-9)
    np.testing.assert_array_equal(d.sensor("accel"), s["acc"])
    np.testing.assert_array_equal(d.sensor("gyro"), s["gyr"])
    assert d.meta["units_in"] == {"accel": "m/s^2", "gyro": "deg/s"}
    assert d.poses() == [1, 2, 3, 4, 5, 6] and len(d.meta["rotations"]) == 3
    # explicit list file works as well; at the standard g the scale is 2047.3 LSB/g
    d2 = X.read_imucal_session(csv_path, lst, rate_hz=s["rate"])
    assert d2.scales["accel"] == pytest.approx(2048 * 9.80665 / 9.81, rel=1e-9)
    np.testing.assert_array_equal(d2.sensor("accel"), s["acc"])


def test_session_declared_scale_reports_rounding(tmp_path):
    s = D.ferraris(5)
    csv_path, _ = D.write_session(s, tmp_path / "sess.csv")
    d = X.read_imucal_session(csv_path, rate_hz=s["rate"], scale="accel=4096")
    assert d.scales["accel"] == 4096.0
    text = d.meta["rounding"]["accel"]
    assert "declared" in text and "does not match the file's resolution" in text
    assert "does not match" in d.meta["notes"]
    err = np.abs(d.sensor("accel") / 4096 - s["acc"] / 2048 * 9.81 / 9.80665).max() * 4096
    assert err <= 0.5 + 1e-9


# ---------------------------------------------------------------- FreeIMU-cal float logs

def test_freeimu_accelerometer_log_in_si(tmp_path):
    rng = np.random.default_rng(1)
    counts = np.vstack([np.tile(v, (300, 1)) for v in
                        ([0, 0, 2048], [2048, 0, 0], [0, -2048, 0], [0, 0, -2048])])
    counts = counts + rng.integers(-3, 4, counts.shape)
    path = D.write_float_log(counts * F.G0 / 2048, tmp_path / "Officeacc.txt")
    d = X.read_float_log(path, rate_hz=50)
    assert d.scales["accel"] == pytest.approx(2048.0, rel=1e-6)
    np.testing.assert_array_equal(d.sensor("accel"), counts)
    assert "m/s^2 -> counts" in d.meta["rounding"]["accel"]
    assert d.kind == "static" and len(d.poses()) == 4
    assert np.isnan(d.raw[:, 3:]).all()
    # a declared chip scale instead of the step
    d2 = X.read_float_log(path, rate_hz=50, scale="accel=256")
    assert d2.scales["accel"] == 256.0
    np.testing.assert_allclose(d2.sensor("accel"), np.rint(counts / 8), atol=0)


def test_freeimu_turntable_gyro_scales(tmp_path):
    worst = []
    for seed in range(4):
        t = D.turntable(seed)
        path = D.write_float_log(t["rad_s"], tmp_path / f"33RPMgyr{seed}.txt")
        d = X.read_float_log(path, rate_hz=t["rate"], rpm=100 / 3)
        assert d.scales["gyro"] == pytest.approx(t["lsb"], rel=1e-4)
        assert len(d.meta["turntable"]["segments"]) == 3 and d.meta["turntable"]["rates_dps"] == [200]
        from motecal.calib import rotations as R
        b = np.array([d.physical("gyro")[d.label == p].mean(axis=0) for p in d.poses()]).mean(0)
        obs = R.observations(d, b)
        rf = R.fit(obs, b_std=np.full(3, 0.01))
        assert rf.model == "scales"                      # no accelerometer: sizes only
        err = np.abs(np.diag(rf.G) - t["k"])
        worst.append(float((err / np.diag(rf.std)).max()))
        assert err.max() < 2e-3, (seed, err)
    assert max(worst) < 3, worst


def test_turntable_needs_turns(tmp_path):
    t = D.turntable(0)
    path = D.write_float_log(t["rad_s"], tmp_path / "gyr.txt")
    with pytest.raises(UserError, match="no steady turn at 270 deg/s"):
        X.read_float_log(path, rate_hz=t["rate"], rpm=45)


def test_turntable_two_speeds_in_two_files(tmp_path):
    """FreeIMU-cal's 33 1/3 and 45 rpm runs of one board, one file each."""
    a, b = D.turntable(5), D.turntable(5, rpm=45)
    pa = D.write_float_log(a["rad_s"], tmp_path / "33RPMgyr.txt")
    pb = D.write_float_log(b["rad_s"], tmp_path / "45RPMgyr.txt")
    d = X.read_float_log([pa, pb], rate_hz=100, rpm="33.3333333,45")
    tt = d.meta["turntable"]
    assert tt["rates_dps"] == [pytest.approx(200), 270] and len(tt["segments"]) == 6
    assert [round(r) for r in tt["segment_rates_dps"]] == [200] * 3 + [270] * 3
    from motecal.calib import rotations as R
    b0 = np.array([d.physical("gyro")[d.label == p].mean(axis=0) for p in d.poses()]).mean(0)
    rf = R.fit(R.observations(d, b0), b_std=np.full(3, 0.01))
    assert np.abs(np.diag(rf.G) - a["k"]).max() < 2e-3


# ---------------------------------------------------------------- bad files

def _one_line(e):
    text = str(e.value)
    assert "\n" not in text
    return text


def test_bad_files_name_file_and_line(tmp_path):
    s = D.ferraris(2)
    p = D.write_annotated(s, tmp_path / "a.csv")
    lines = p.read_text().splitlines()
    # truncated: last line cut in the middle
    cut = tmp_path / "cut.csv"
    cut.write_text("\n".join(lines[:-1] + [lines[-1][:12]]) + "\n")
    with pytest.raises(UserError) as e:
        X.read_imucal_annotated(cut, rate_hz=200, scale="accel=2048,gyro=16.4")
    assert _one_line(e).startswith(f"{cut}: line {len(lines)}: expected 8 columns")
    # wrong columns
    wrong = tmp_path / "wrong.csv"
    wrong.write_text("part,samples,acc_x,acc_y,acc_z,gyr_x,gyr_y\n" + "\n".join(lines[1:]))
    with pytest.raises(UserError) as e:
        X.read_imucal_annotated(wrong, rate_hz=200, scale="accel=2048,gyro=16.4")
    assert _one_line(e).startswith(f"{wrong}: line 1: bad header")
    # NaN
    nan = tmp_path / "nan.csv"
    bad = lines[:5] + [lines[5].rsplit(",", 1)[0] + ",nan"] + lines[6:]
    nan.write_text("\n".join(bad) + "\n")
    with pytest.raises(UserError) as e:
        X.read_imucal_annotated(nan, rate_hz=200, scale="accel=2048,gyro=16.4")
    assert _one_line(e) == f"{nan}: line 6: gyr_z is not a finite number: 'nan'"
    # mixed units: a float among counts
    mixed = tmp_path / "mixed.csv"
    bad = lines[:9] + [lines[9].rsplit(",", 1)[0] + ",0.0610"] + lines[10:]
    mixed.write_text("\n".join(bad) + "\n")
    with pytest.raises(UserError) as e:
        X.read_imucal_annotated(mixed, rate_hz=200, scale="accel=2048,gyro=16.4")
    assert _one_line(e).startswith(f"{mixed}: line 10: gyro value 0.061 is not an integer count")


def test_bad_session_and_float_logs(tmp_path):
    s = D.ferraris(6)
    csv_path, lst = D.write_session(s, tmp_path / "sess.csv")
    lines = csv_path.read_text().splitlines()
    short = tmp_path / "short.csv"
    short.write_text("\n".join(lines[:4000]) + "\n")
    with pytest.raises(UserError) as e:
        X.read_imucal_session(short, lst, rate_hz=200)
    assert str(e.value).startswith(f"{lst}: line 1: section ") and "has 3999 rows" in str(e.value)
    alone = tmp_path / "alone.csv"
    alone.write_text(csv_path.read_text())
    with pytest.raises(UserError, match="without its section list"):
        X.read_imucal_session(alone, rate_hz=200)
    # FreeIMU: a line with two numbers, and a second file in deg/s beside rad/s
    t = D.turntable(1)
    good = D.write_float_log(t["rad_s"][:600], tmp_path / "a_gyr.txt")
    deg = D.write_float_log(np.rad2deg(t["rad_s"][:600]), tmp_path / "b_gyr.txt")
    with pytest.raises(UserError) as e:
        X.read_float_log([good, deg])
    assert _one_line(e).startswith(f"{deg}: line 1: gyro values step by") \
        and "mixed units" in str(e.value)
    broken = tmp_path / "c_gyr.txt"
    broken.write_text(good.read_text() + "0.1 0.2\n")
    with pytest.raises(UserError) as e:
        X.read_float_log(broken)
    assert _one_line(e) == f"{broken}: line 601: expected 3 numbers, found 2"
    with pytest.raises(UserError, match="say which sensor"):
        X.read_float_log(D.write_float_log(t["rad_s"][:50], tmp_path / "data.txt"))


def test_units_and_scales_parsing():
    assert F.parse_units("si") == {"accel": "m/s^2", "gyro": "rad/s", "mag": "ut"} or \
        F.parse_units("si") == {"accel": "m/s^2", "gyro": "rad/s", "mag": "uT"}
    assert F.parse_units(["gyro=deg/s", "si"])["gyro"] == "deg/s"
    assert F.parse_units("counts") == {"accel": "counts", "gyro": "counts", "mag": "counts"}
    with pytest.raises(UserError, match="not a unit of the gyro"):
        F.parse_units("gyro=m/s^2")
    assert F.parse_scales("accel=2048,gyro=16.4") == {"accel": 2048.0, "gyro": 16.4}
    with pytest.raises(UserError, match="positive"):
        F.parse_scales("mag=-3")
    assert F.unit_factor("ut") == 0.01 and F.unit_factor("m/s^2", 9.81) == 1 / 9.81


# ---------------------------------------------------------------- MotionCal Raw: lines

def test_motioncal_raw_lines(tmp_path):
    rng = np.random.default_rng(4)
    n = 400
    raw = np.column_stack([rng.integers(-8200, 8200, (n, 3)), rng.integers(-50, 50, (n, 3)),
                           rng.integers(-600, 600, (n, 3))])
    lines = ["Uni:0.1,0.2,9.8,0,0,0,10,20,30"] + ["Raw:" + ",".join(map(str, r)) for r in raw]
    p = tmp_path / "motioncal.log"
    p.write_text("\n".join(lines) + "\n")
    assert X.detect_text(lines) == "motioncal"
    d = X.read_motioncal(p, rate_hz=50)
    np.testing.assert_array_equal(d.raw, raw)
    assert d.scales == {"accel": pytest.approx(8192 * 9.80665 / 9.8), "gyro": 16.0, "mag": 1000.0}
    assert "1 non-Raw lines skipped" in d.meta["notes"]
    bad = tmp_path / "bad.log"
    bad.write_text("\n".join(lines[:7] + ["Raw:1,2,3"] + lines[7:]) + "\n")
    with pytest.raises(UserError) as e:
        X.read_motioncal(bad)
    assert str(e.value) == f"{bad}: line 8: expected 9 values after Raw:, found 3"


def test_read_session_detects_foreign_and_native(tmp_path, measured):
    s = D.ferraris(9)
    ann = D.write_annotated(s, tmp_path / "mystery.txt")
    csv_path, lst = D.write_session(s, tmp_path / "other.dat")
    assert [X.detect(p) for p in (ann, csv_path, lst)] == \
        ["imucal-annotated", "imucal-session", "imucal-sections"]
    d = X.read_session([ann], rate_hz=200, scale="accel=2048,gyro=16.4")
    assert d.meta["format"] == "imucal-annotated"
    assert X.read_session([lst, csv_path], rate_hz=200).meta["format"] == "imucal-session"
    razor = measured / "sensorstick-boards" / "razor1" / "razor1_acc_x_pos.raw"
    assert X.read_session([razor]).meta["format"] == "razor-text"
    with pytest.raises(UserError, match="--units: only for float inputs"):
        X.read_session([razor], units="si")
    # native and other tools' files together: one session, each file read by
    # its own reader (sessions.combine); one board: the scales must agree
    both = X.read_session([razor, ann], rate_hz=200, scale="accel=256,gyro=14.375")
    assert both.meta["format"] == "razor-text+imucal-annotated"
    assert [f["format"] for f in both.meta["files"]][:1] == ["razor-text"]
    with pytest.raises(UserError, match="one board per session"):
        X.read_session([razor, ann], rate_hz=200, scale="accel=2048,gyro=16.4")
    with pytest.raises(UserError, match="give one session CSV"):
        X.read_session([lst], rate_hz=200)


def test_freeimu_magnetometer_log_in_microtesla(tmp_path):
    """FreeIMU-cal's magnetometer log (uT): with the chip declared the counts
    come back exactly; unknown sensors of a float log are refused."""
    rng = np.random.default_rng(2)
    u = rng.normal(size=(500, 3))
    counts = np.rint(550 * u / np.linalg.norm(u, axis=1, keepdims=True) + [40, -120, 75])
    path = D.write_float_log(counts / 1090 * 100, tmp_path / "Officemag.txt", "{:.5f}")
    d = X.read_float_log(path, rate_hz=50, chip="mag=hmc5883l")
    assert d.scales["mag"] == 1090.0 and d.chips["mag"] == "HMC5883L"
    np.testing.assert_array_equal(d.sensor("mag"), counts)
    assert "uT -> counts at 1090 LSB/gauss (chip)" in d.meta["rounding"]["mag"]
    assert d.kind == "rotation"
