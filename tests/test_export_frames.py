"""export-cal in the target's frame and with its checks (issue 28, item 5).

* ArduPilot: raw -> the writer's parameters -> ArduPilot's own order of
  operations, re-implemented here from its source (cited at each function)
  with a board orientation -> equals motecal's calibrated vector (the
  restricted model the parameters can hold) turned into the body frame,
  within float32 rounding.  The writer's earlier output (the compass in the
  sensor frame) is off by tens of mGauss under AHRS_ORIENTATION Yaw90.
* Razor: a chip-axis calibration goes through the firmware's register map
  (Sensors.ino, re-implemented on the registers' bytes) and its correction
  (Razor_AHRS.ino ``compensate_sensor_errors``): remapped, it is the
  calibration in the board frame; not remapped (before), it was 100+ mg off.
* Every target says when it drops a temperature model, with its cost.
* razor-yaml never writes an exponent: what the ROS node sends (``str()``)
  reads back through Arduino's ``Stream::parseFloat`` (re-implemented).
* Names from cal.json never become source lines.
"""
import re
import shutil
import struct
import subprocess

import numpy as np
import pytest

from clirun import motecal
from motecal.errors import UserError
from motecal.calib.result import TempModel
from motecal.sessions.importer import RAZOR_FRAME
from motecal.sessions.foreign import IMUCAL_FRAME
from motecal.targets import FORMATS, export
from motecal.targets import ardupilot as AP
from motecal.targets import common as C
from motecal.targets import razor as RZ
from motecal.targets.common import ExportOptions
from test_interop_writers import _rows, board, sess  # noqa: F401  (the simulated board)

G0 = 9.80665
F32 = np.float32


# ---------------------------------------------------------------- ArduPilot, restated

def ap_rotate(v, rot: int):
    """libraries/AP_Math/vector3.cpp, ``Vector3<T>::rotate(enum Rotation)``:
    the cases below copied formula for formula (float32, as Vector3f)."""
    v = np.asarray(v, F32)
    x, y, z = v[:, 0].copy(), v[:, 1].copy(), v[:, 2].copy()
    h = F32(0.70710678118654757)                       # HALF_SQRT_2
    if rot == 0:                                       # ROTATION_NONE
        pass
    elif rot == 1:                                     # ROTATION_YAW_45
        x, y = h * (x - y), h * (x + y)
    elif rot == 2:                                     # ROTATION_YAW_90: tmp = x; x = -y; y = tmp
        x, y = -y, x
    elif rot == 4:                                     # ROTATION_YAW_180
        x, y = -x, -y
    elif rot == 6:                                     # ROTATION_YAW_270: x = y; y = -tmp
        x, y = y, -x
    elif rot == 8:                                     # ROTATION_ROLL_180
        y, z = -y, -z
    elif rot == 10:                                    # ROTATION_ROLL_180_YAW_90
        x, y, z = y, x, -z
    elif rot == 12:                                    # ROTATION_PITCH_180
        x, z = -x, -z
    elif rot == 16:                                    # ROTATION_ROLL_90: tmp = z; z = y; y = -tmp
        y, z = -z, y
    elif rot == 18:                                    # ROTATION_ROLL_90_YAW_90
        y, z = -z, y
        x, y = -y, x
    elif rot == 20:                                    # ROTATION_ROLL_270: tmp = z; z = -y; y = tmp
        y, z = z, -y
    elif rot == 24:                                    # ROTATION_PITCH_90: tmp = z; z = -x; x = tmp
        x, z = z, -x
    elif rot == 25:                                    # ROTATION_PITCH_270: tmp = z; z = x; x = -tmp
        x, z = -z, x
    elif rot == 26:                                    # ROTATION_PITCH_180_YAW_90
        z = -z
        x, y = -y, -x
    elif rot == 28:                                    # ROTATION_ROLL_90_PITCH_90
        y, z = -z, y
        x, z = z, -x
    elif rot == 36:                                    # ROTATION_ROLL_90_PITCH_180_YAW_90
        y, z = -z, y
        x, z = -x, -z
        x, y = -y, x
    elif rot == 37:                                    # ROTATION_ROLL_90_YAW_270
        y, z = -z, y
        x, y = y, -x
    else:
        raise KeyError(rot)
    return np.stack([x, y, z], axis=1).astype(F32)


RESTATED = (0, 1, 2, 4, 6, 8, 10, 12, 16, 18, 20, 24, 25, 26, 28, 36, 37)


def ap_accel(raw, p, lsb):
    """libraries/AP_InertialSensor/AP_InertialSensor_Backend.cpp,
    ``_rotate_and_correct_accel``: the driver's reading (m/s^2; its chip
    rotation ``_accel_orientation``: none), ``accel -= _accel_offset``,
    ``accel.x *= accel_scale.x`` ..., then ``accel.rotate(_board_orientation)``."""
    a = np.asarray(raw, F32) * F32(G0 / lsb)
    a = a - np.array([p[f"INS_ACCOFFS_{k}"] for k in "XYZ"], F32)
    a = a * np.array([p[f"INS_ACCSCAL_{k}"] for k in "XYZ"], F32)
    return ap_rotate(a, int(p["AHRS_ORIENTATION"]))


def ap_gyro(raw, p, lsb):
    """Same file, ``_rotate_and_correct_gyro``: ``gyro -= _gyro_offset``, then
    the board rotation (rad/s)."""
    w = np.asarray(raw, F32) * F32(np.pi / 180 / lsb)
    w = w - np.array([p[f"INS_GYROFFS_{k}"] for k in "XYZ"], F32)
    return ap_rotate(w, int(p["AHRS_ORIENTATION"]))


def ap_compass(raw, p, lsb):
    """libraries/AP_Compass/AP_Compass_Backend.cpp, ``accumulate_sample``:
    ``rotate_field`` (MAG_BOARD_ORIENTATION and the driver's rotation: none;
    an internal compass: ``mag.rotate(_board_orientation)``), then
    ``correct_field``: ``mag += offsets``, ``mag *= scale_factor`` (when
    ``have_scale_factor``), ``mag = mat * mag`` with ``mat`` = [[DIA.x,
    ODI.x, ODI.y], [ODI.x, DIA.y, ODI.z], [ODI.y, ODI.z, DIA.z]] (mGauss)."""
    m = np.asarray(raw, F32) * F32(1000.0 / lsb)
    m = ap_rotate(m, int(p["AHRS_ORIENTATION"]))
    m = m + np.array([p[f"COMPASS_OFS_{k}"] for k in "XYZ"], F32)
    if 0.85 <= p.get("COMPASS_SCALE", 0.0) <= 1.3:     # CompassCalibrator.h's range
        m = m * F32(p["COMPASS_SCALE"])
    d, o = [p[f"COMPASS_DIA_{k}"] for k in "XYZ"], [p[f"COMPASS_ODI_{k}"] for k in "XYZ"]
    mat = np.array([[d[0], o[0], o[1]], [o[0], d[1], o[2]], [o[1], o[2], d[2]]], F32)
    return m @ mat.T


def test_rotation_matrices_are_ardupilots():
    """The writer's matrices (from the names' Euler angles) rotate as
    ArduPilot's Vector3f::rotate, for every case restated above."""
    v = np.random.default_rng(0).normal(size=(50, 3))
    for n in RESTATED:
        np.testing.assert_allclose(v @ AP.rotation_matrix(n).T, ap_rotate(v, n), atol=1e-6,
                                   err_msg=AP.ROTATIONS[n][0])
    assert AP.parse_rotation("2") == AP.parse_rotation("YAW_90") == 2
    assert AP.parse_rotation("rotation_roll_180_yaw_90") == AP.parse_rotation("Roll180Yaw90") == 10
    for bad in ("38", "100", "44", "yaw_91", "", "-1"):
        with pytest.raises(UserError):
            AP.parse_rotation(bad)


@pytest.mark.parametrize("rot", [0, 2, 8, 18, 25, 36])
def test_ardupilot_round_trip_with_a_board_orientation(board, sess, rot):
    """raw -> parameters (written with --orientation) -> ArduPilot's order of
    operations -> body frame = R x motecal's calibrated vector (the model
    the parameters hold: per-axis accel, gyro offsets, the compass's
    symmetric part), within float32."""
    text = export(board, "ardupilot", ExportOptions(orientation=rot)).text
    p = AP.parse(text)
    assert p["AHRS_ORIENTATION"] == rot and p["COMPASS_SCALE"] == 1.0
    R = AP.rotation_matrix(rot)
    a = _rows(sess, "accel")
    want = (a * np.diag(board.accel.A) + board.accel.c) @ R.T           # g
    got = ap_accel(a, p, board.accel.lsb_per_unit) / G0
    acc_res = np.abs(got - want).max()
    assert acc_res < 2e-6, acc_res
    g = _rows(sess, "gyro")
    gb = -np.linalg.solve(board.gyro.A * board.gyro.lsb_per_unit, board.gyro.c)
    want = (g / board.gyro.lsb_per_unit - gb) @ R.T                     # deg/s
    got = np.degrees(ap_gyro(g, p, board.gyro.lsb_per_unit).astype(float))
    gyr_res = np.abs(got - want).max()
    assert gyr_res < 2e-3, gyr_res                  # float32 of up to ~300 deg/s readings
    m = _rows(sess, "mag")
    U, _ = C.polar(board.mag.A)
    want = board.mag.apply(m) @ U @ R.T * 1000.0                        # U^T cal, mGauss
    got = ap_compass(m, p, board.mag.lsb_per_unit)
    mag_res = np.abs(got - want).max()
    assert mag_res < 1e-3, mag_res                  # mGauss
    # the export's own apply is the same, turned back into the session's axes
    e = export(board, "ardupilot", ExportOptions(orientation=rot))
    np.testing.assert_allclose(e.apply["mag"](m), got.astype(float) @ R / 1000.0, atol=1e-7)
    print(f"rotation {rot} ({AP.ROTATIONS[rot][0]}): residual accel {acc_res:.2g} g, gyro "
          f"{gyr_res:.2g} deg/s, compass {mag_res:.2g} mGauss")


def test_the_sensor_frame_compass_was_off_under_yaw90(board, sess):
    """Before: COMPASS_OFS/DIA/ODI written in the sensor frame while ArduPilot
    applies them after AHRS_ORIENTATION: under Yaw90 the field is off by
    tens of mGauss; written in the rotated frame it is exact."""
    m = _rows(sess, "mag")
    old = AP.params(board, ExportOptions(orientation=0))
    old["AHRS_ORIENTATION"] = 2
    U, _ = C.polar(board.mag.A)
    want = board.mag.apply(m) @ U @ AP.rotation_matrix(2).T * 1000.0
    err_old = np.linalg.norm(ap_compass(m, old, board.mag.lsb_per_unit) - want, axis=1)
    new = AP.params(board, ExportOptions(orientation=2))
    err_new = np.linalg.norm(ap_compass(m, new, board.mag.lsb_per_unit) - want, axis=1)
    rms_old, rms_new = np.sqrt(np.mean(err_old ** 2)), np.sqrt(np.mean(err_new ** 2))
    print(f"AHRS_ORIENTATION Yaw90: compass rms error, sensor-frame params {rms_old:.1f} mGauss, "
          f"rotated params {rms_new:.2g} mGauss")
    assert rms_old > 10.0 and rms_new < 1e-3


def test_compass_offsets_checked_by_vector_length(board):
    """ArduPilot's pre-arm check (AP_Arming::compass_checks) compares the
    offsets' vector length with COMPASS_OFFS_MAX: 1100 mGauss on each axis
    (1905 long) fails it though no axis reaches 1800."""
    import copy
    b = copy.deepcopy(board)
    ofs_mg = np.array([1100.0, -1100.0, 1100.0])            # ArduPilot's COMPASS_OFS
    U, P = C.polar(b.mag.A)
    b.mag.c = U @ (P * b.mag.lsb_per_unit) @ ofs_mg / 1000.0    # the writer: ofs = M^-1 1000 U^T c
    e = export(b, "ardupilot")
    p = AP.parse(e.text)
    ofs = np.array([p[f"COMPASS_OFS_{k}"] for k in "XYZ"])
    assert np.abs(ofs).max() < 1800 < np.linalg.norm(ofs)
    assert any("COMPASS_OFFS_MAX" in n and "pre-arm" in n for n in e.notes), e.notes
    assert not any("COMPASS_OFFS_MAX" in n for n in export(board, "ardupilot").notes)


def test_orientation_option_from_the_command_line(board, tmp_path):
    cal = tmp_path / "cal.json"
    board.save(cal)
    out = tmp_path / "a.param"
    rc, so, se = motecal("export-cal", cal, "--to", "ardupilot", "--orientation", "YAW_90",
                         "--out", out)
    assert rc == 0, se
    assert "AHRS_ORIENTATION,2" in out.read_text() and "axes: " in so
    for argv, words in ((["--to", "razor-c", "--orientation", "2"], "--orientation goes with"),
                        (["--to", "ardupilot", "--orientation", "Yaw91"], "not an ArduPilot"),
                        (["--to", "ardupilot", "--axes", "chip"], "--axes goes with")):
        rc, so, se = motecal("export-cal", cal, *argv, "--out", tmp_path / "x")
        assert rc == 2 and words in se and se.count("\n") == 1, se


# ---------------------------------------------------------------- Razor, restated

def razor_read(chip_raw: np.ndarray) -> dict:
    """Sensors.ino on the chips' registers: the bytes each chip returns
    (ADXL345 0x32.., little-endian X Y Z; ITG-3200 0x1D.., big-endian X Y Z;
    HMC5883L 0x03.., big-endian X Z Y) read as ``Read_Accel``, ``Read_Gyro``
    and ``Read_Magn`` (HW__VERSION_CODE 10736) read them into the board frame."""
    out = {"accel": [], "gyro": [], "mag": []}
    for r in np.asarray(chip_raw, int):
        ax, ay, az, gx, gy, gz, mx, my, mz = (int(v) for v in r)
        buff = struct.pack("<hhh", ax, ay, az)
        s16 = lambda hi, lo: struct.unpack(">h", bytes((hi, lo)))[0]  # noqa: E731
        out["accel"].append([s16(buff[3], buff[2]), s16(buff[1], buff[0]), s16(buff[5], buff[4])])
        buff = struct.pack(">hhh", gx, gy, gz)
        out["gyro"].append([-s16(buff[2], buff[3]), -s16(buff[0], buff[1]), -s16(buff[4], buff[5])])
        buff = struct.pack(">hhh", mx, mz, my)
        out["mag"].append([-s16(buff[4], buff[5]), -s16(buff[0], buff[1]), -s16(buff[2], buff[3])])
    return {k: np.array(v, float) for k, v in out.items()}


def razor_correct(k: dict, board_raw: dict, gain=0.06957) -> dict:
    """Razor_AHRS.ino, ``compensate_sensor_errors`` (extended magnetometer
    calibration) and the gyro's GYRO_GAIN, in float32; g, deg/s, counts."""
    f = F32
    out = {}
    mn = np.array([k[f"ACCEL_{a}_MIN"] for a in "XYZ"], f)
    mx = np.array([k[f"ACCEL_{a}_MAX"] for a in "XYZ"], f)
    off = (mn + mx) / f(2)
    out["accel"] = (board_raw["accel"].astype(f) - off) * (f(256) / (mx - off)) / 256.0
    go = np.array([k[f"GYRO_AVERAGE_OFFSET_{a}"] for a in "XYZ"], f)
    out["gyro"] = (board_raw["gyro"].astype(f) - go) * f(gain)
    ctr = np.array(k["magn_ellipsoid_center"], f)
    T = np.array(k["magn_ellipsoid_transform"], f)
    out["mag"] = (board_raw["mag"].astype(f) - ctr) @ T.T
    return out


def test_razor_map_matches_sensors_ino():
    """CHIP_TO_BOARD is what Sensors.ino does to the registers."""
    raw = np.random.default_rng(1).integers(-2000, 2000, (40, 9))
    got = razor_read(raw)
    for s, sl in (("accel", slice(0, 3)), ("gyro", slice(3, 6)), ("mag", slice(6, 9))):
        np.testing.assert_array_equal(got[s], raw[:, sl] @ RZ.CHIP_TO_BOARD[s].T)


def test_razor_chip_session_is_remapped(board, sess, capsys):
    """A calibration in the chips' axes, loaded on a Razor: the firmware's
    output is the calibration in its board frame (restricted to per-axis
    accel and gyro offsets); written unremapped (before), it was far off."""
    rows = np.flatnonzero(np.isfinite(sess.raw).all(axis=1))[::5]
    chip = sess.raw[rows]
    board_raw = razor_read(chip)
    new = razor_correct(RZ.parse_c(export(board, "razor-c").text), board_raw)
    old = razor_correct(RZ.constants(board, ExportOptions(axes="razor")), board_raw)
    M = RZ.CHIP_TO_BOARD
    sl = {"accel": slice(0, 3), "gyro": slice(3, 6), "mag": slice(6, 9)}
    errs = {}
    for s, cal in board.sensors():
        truth = cal.apply(chip[:, sl[s]]) @ M[s].T                  # the calibration, board frame
        if s == "mag":
            truth = truth * cal.lsb_per_unit
        if s == "accel":
            Ab, cb = RZ.in_board_frame(s, cal.A, cal.c, True)
            held = board_raw[s] * np.diag(Ab) + cb
        elif s == "gyro":                             # offsets, the firmware's GYRO_GAIN
            Ab, cb = RZ.in_board_frame(s, cal.A, cal.c, True)
            held = (board_raw[s] + np.linalg.solve(Ab, cb)) * 0.06957
        else:
            held = truth
        np.testing.assert_allclose(new[s], held, rtol=1e-5, atol=3e-3 if s == "gyro" else
                                   (2e-6 if s == "accel" else 2e-3))
        errs[s] = (np.sqrt(np.mean(np.sum((new[s] - truth) ** 2, axis=1))),
                   np.sqrt(np.mean(np.sum((old[s] - truth) ** 2, axis=1))))
    print(f"chip-axis session on a Razor, rms vs the calibration in the board frame: "
          f"accel {errs['accel'][0] * 1000:.1f} mg remapped (the per-axis model's cost) vs "
          f"{errs['accel'][1] * 1000:.0f} mg before; gyro {errs['gyro'][0]:.2f} vs "
          f"{errs['gyro'][1]:.1f} deg/s; mag {errs['mag'][0]:.2g} vs {errs['mag'][1]:.0f} counts")
    assert errs["accel"][1] > 0.05 > errs["accel"][0]
    assert errs["gyro"][1] > errs["gyro"][0] + 2 and errs["mag"][1] > 100 > 100 * errs["mag"][0]


def test_razor_frame_from_the_session(board):
    """Razor logs: written as they are; other tools' frames: as they are,
    and the text says so; --axes overrides."""
    import copy
    b = copy.deepcopy(board)
    b.settings["axis_frame"] = RAZOR_FRAME
    e = export(b, "razor-c")
    assert "as the calibration's" in e.frame
    want = RZ.constants(b, ExportOptions(axes="razor"))
    got = RZ.parse_c(e.text)
    for key, v in want.items():
        np.testing.assert_allclose(got[key], v, rtol=1e-8, err_msg=key)
    b.settings["axis_frame"] = IMUCAL_FRAME
    e = export(b, "razor-yaml")
    assert "not remapped" in e.frame and "--axes chip" in e.frame and "axes: as" in e.text
    e = export(b, "razor-yaml", ExportOptions(axes="chip"))
    assert "remapped from the chips' axes (--axes)" in e.frame
    del b.settings["axis_frame"]                 # a cal.json from before axis_frame
    assert "not recorded" in export(b, "razor-c").frame


# ---------------------------------------------------------------- razor-yaml numbers

def arduino_parse_float(text: str) -> float:
    """ArduinoCore-avr Stream.cpp, ``Stream::parseFloat``: digits into a
    ``long`` (32 bits on AVR; an overflow fails here), one '.', each
    fraction digit ``fraction *= 0.1`` in float; stops at any other
    character (an 'e' included)."""
    neg, frac, value, fraction = False, False, 0, F32(1.0)
    for ch in text:
        if ch == "-":
            neg = True
        elif ch == "." and not frac:
            frac = True
        elif ch.isdigit():
            value = value * 10 + int(ch)
            assert value < 2 ** 31, f"{text}: parseFloat's long overflows"
            if frac:
                fraction = F32(fraction * F32(0.1))
        else:
            break
    value = -value if neg else value
    return float(F32(value) * fraction) if frac else float(F32(value))


def test_razor_yaml_never_writes_an_exponent(board):
    import copy
    b = copy.deepcopy(board)
    b.gyro.c = b.gyro.A @ np.array([3e-6, -2e-5, 7.5e-5])      # tiny offsets (counts)
    b.mag.A = b.mag.A + np.array([[0, 3e-8, 0], [0, 0, -6e-8], [0, 0, 0]])
    text = export(b, "razor-yaml").text
    values = {}
    for line in text.splitlines():
        if line.startswith("#") or line.endswith(": true"):
            continue
        key, _, val = line.partition(": ")
        for tok in re.findall(r"[^\[\], ]+", val):
            assert re.fullmatch(r"-?\d+(\.\d+)?", tok), (key, tok)
            assert len(tok.lstrip("-").replace(".", "").lstrip("0")) <= 9, tok
            sent = str(float(tok))                     # what the ROS node sends
            assert "e" not in sent.lower(), sent
            got = arduino_parse_float(sent)
            assert got == pytest.approx(float(tok), rel=3e-6, abs=1e-9), (tok, got)
            values.setdefault(key, []).append(float(tok))
    assert values["gyro_average_offset_x"] == [0.0] and values["gyro_average_offset_z"] == [0.0001]
    with pytest.raises(C.TargetCannotHold):
        RZ.arduino_float(2e9)


# ---------------------------------------------------------------- temperature

def test_every_target_says_when_it_drops_a_temperature_model(board, sess):
    """razor, ardupilot and imucal cannot hold a temperature model: each says
    so with its cost (at the range's ends without data; on the rows at their
    temperatures with data); c-header holds it (the 164-byte set)."""
    import copy
    b = copy.deepcopy(board)
    b.gyro.temperature = TempModel(t_ref_c=25.0, range_c=(15.0, 40.0),
                                   offset_per_c=[0.02, -0.01, 0.03],
                                   offset_per_c_std=[0.001] * 3, scale_per_c=[2e-4, 0, 0])
    raw = C.sphere_counts(b.gyro)
    d = np.concatenate([np.linalg.norm(b.gyro.apply(raw, t) - b.gyro.apply(raw), axis=1)
                        for t in (15.0, 40.0)])
    for fmt in FORMATS:
        e = export(b, fmt)
        cost = C.costs(b, e)
        lines = C.cost_lines(e, cost)
        gyro = next(line for line in lines if line.startswith("gyro:"))
        if fmt == "c-header":
            assert e.holds_temperature == ("gyro",) and "temperature" not in cost["gyro"]
            assert "temperature model dropped" not in gyro
            from motecal.targets import cheader
            assert len(cheader.parse(e.text)) == 164
            continue
        t = cost["gyro"]["temperature"]
        assert "temperature model dropped" in gyro and "15..40 C" in gyro, gyro
        assert t["max"] == pytest.approx(d.max()) and t["rms"] == pytest.approx(
            np.sqrt(np.mean(d ** 2)))
        assert t["max"] > 0.3                      # 0.03 deg/s/C x 15 C and the gain term
    # with a session: on its rows, at their own temperatures
    s2 = copy.deepcopy(sess)
    s2.temp = np.linspace(20.0, 35.0, len(s2.raw))
    cost = C.costs(b, export(b, "ardupilot"), s2)["gyro"]["temperature"]
    rows = C.cal_rows(s2, "gyro")
    g = s2.sensor("gyro")[rows]
    d = np.linalg.norm(b.gyro.apply(g, s2.temp[rows]) - b.gyro.apply(g), axis=1)
    assert cost["rms"] == pytest.approx(np.sqrt(np.mean(d ** 2))) and "at their temperatures" \
        in cost["on"]


# ---------------------------------------------------------------- names

HOSTILE = "evil\n#error injected */ /* \\\n??/ %41 é\r\x00"


def test_names_never_become_source(board, tmp_path):
    """A session name or date with newlines, '#error', '*/', a line splice
    or a trigraph stays inside its comment in every target; gcc compiles the
    C targets with -Werror."""
    import copy
    b = copy.deepcopy(board)
    b.session, b.created = HOSTILE, "2020-01-01\n#define ACCEL_X_MIN 0"
    names = {"razor-c": None, "razor-yaml": None}
    for fmt in FORMATS:
        text = export(b, fmt).text
        assert "\r" not in text and "\x00" not in text
        for line in ([] if fmt == "imucal" else text.splitlines()):
            assert not line.lstrip().startswith(("#error", "#define ACCEL_X_MIN 0")), (fmt, line)
            assert "*/ /*" not in line and "\\" not in line and "??/" not in line, (fmt, line)
        if fmt == "ardupilot":
            assert set(AP.parse(text)) == set(AP.params(b))
        if fmt == "razor-yaml":
            assert set(RZ.parse_yaml(text)) == set(RZ.parse_c(export(b, "razor-c").text)) | {
                "calibration_magn_use_extended"}
        if fmt == "imucal":
            import json
            assert HOSTILE in json.loads(text)["comment"]       # data, JSON-escaped
        names[fmt] = text
    if not shutil.which("gcc"):
        pytest.fail("gcc missing (make test installs it)")
    for fmt in ("razor-c", "c-header"):
        src = tmp_path / f"{fmt}.c"
        src.write_text(names[fmt] + "\nint main(void) { return 0; }\n")
        r = subprocess.run(["gcc", "-std=c99", "-Wall", "-Werror", "-Wno-unused-const-variable",
                            "-c", "-o", str(tmp_path / "o.o"), str(src)],
                           capture_output=True, text=True)
        assert r.returncode == 0, (fmt, r.stderr)
    assert C.safe_text(HOSTILE).count("%") >= 10 and "\n" not in C.safe_text(HOSTILE)
