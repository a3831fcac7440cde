"""export-cal writers (motecal.targets): export -> parse back (with the target's
own parser where there is one: imucal from PyPI, gcc for the Razor constants, the
IRIS firmware's C for the fixed-point header) -> apply to the session -> the same
corrected values within the stated rounding; the restricted models' costs."""
import json
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from motecal.calib import calibrate_board
from motecal.targets import FORMATS, TARGETS, export
from motecal.targets import ardupilot as AP
from motecal.targets import cheader as CH
from motecal.targets import common as C
from motecal.targets import razor as RZ

from synthetic import paper_sized_session

G0 = 9.80665


@pytest.fixture(scope="module")
def sess():
    return paper_sized_session(seed=2, n_poses=40)


@pytest.fixture(scope="module")
def board(sess):
    return calibrate_board(sess, model="full", seed=2, kfold=0)


def _rows(sess, s):
    return sess.sensor(s)[C.cal_rows(sess, s)]


def _diag_model(cal, raw):
    """The per-axis model a target without cross terms holds: diag(A) raw + c."""
    return raw * np.diag(cal.A) + cal.c


def test_every_format_exports(board):
    for f in FORMATS:
        e = export(board, f)
        assert e.text.endswith("\n") and e.apply and e.frame
        assert TARGETS[f].name == f and TARGETS[f].what


def test_the_docs_table_lists_the_registry():
    """docs/interop.md's table of export targets has one row per registered
    target (the first cell names it), no more, no fewer; every ``--to a|b``
    list in the docs and the README names exactly the registry's targets."""
    root = Path(__file__).resolve().parent.parent
    for page in [root / "README.md"] + sorted((root / "docs").glob("*.md")):
        for listed in re.findall(r"--to ([a-z0-9-]+(?:\|[a-z0-9-]+)+)", page.read_text()):
            assert listed.split("|") == list(FORMATS), (page.name, listed)
    doc = (root / "docs" / "interop.md").read_text()
    table = doc[doc.index("| target | accelerometer |"):]
    table = table[:table.index("\n\n")]
    named = set()
    for row in table.splitlines()[2:]:
        named |= set(re.findall(r"`([a-z0-9-]+)`", row.split("|")[1]))
    assert named == set(FORMATS), (named, FORMATS)


def test_razor_c_compiles_and_matches(board, sess, tmp_path):
    """gcc reads the block; the firmware's formulas (restated in the harness),
    on the readings in its board frame (Sensors.ino's map of the chips'
    registers), give the per-axis model of the calibration in that frame to
    float32 rounding; the magnetometer whole."""
    if not shutil.which("gcc"):
        pytest.fail("gcc missing (make test installs it)")
    e = export(board, "razor-c")
    (tmp_path / "block.h").write_text(e.text)
    (tmp_path / "h.c").write_text(r"""
#include <stdio.h>
#define GRAVITY 256.0f
#include "block.h"
/* Razor_AHRS.ino's calibration, restated */
#define OFS(a, b) (((a) + (b)) / 2.0f)
int main(void) {
  float r[9];
  const float amin[3] = {ACCEL_X_MIN, ACCEL_Y_MIN, ACCEL_Z_MIN};
  const float amax[3] = {ACCEL_X_MAX, ACCEL_Y_MAX, ACCEL_Z_MAX};
  const float goff[3] = {GYRO_AVERAGE_OFFSET_X, GYRO_AVERAGE_OFFSET_Y, GYRO_AVERAGE_OFFSET_Z};
  while (scanf("%f %f %f %f %f %f %f %f %f", r, r+1, r+2, r+3, r+4, r+5, r+6, r+7, r+8) == 9) {
    float t[3];
    for (int i = 0; i < 3; i++) {
      float off = OFS(amin[i], amax[i]);
      printf("%.9g ", (r[i] - off) * (GRAVITY / (amax[i] - off)));
    }
    for (int i = 0; i < 3; i++) printf("%.9g ", (r[3 + i] - goff[i]) * 0.06957f);
    for (int i = 0; i < 3; i++) t[i] = r[6 + i] - magn_ellipsoid_center[i];
    for (int i = 0; i < 3; i++)
      printf("%.9g ", magn_ellipsoid_transform[i][0] * t[0] + magn_ellipsoid_transform[i][1] * t[1]
                      + magn_ellipsoid_transform[i][2] * t[2]);
    printf("\n");
  }
  return 0;
}
""")
    exe = tmp_path / "h"
    subprocess.run(["gcc", "-std=c99", "-O1", "-o", str(exe), str(tmp_path / "h.c")], check=True)
    chip = sess.raw[np.isfinite(sess.raw).all(axis=1)][::7]
    assert "remapped from the chips' axes" in e.text         # a motecal session: chip axes
    M = RZ.CHIP_TO_BOARD
    raw = np.hstack([chip[:, sl] @ M[s].T for s, sl in
                     (("accel", slice(0, 3)), ("gyro", slice(3, 6)), ("mag", slice(6, 9)))])
    out = subprocess.run([str(exe)], input="\n".join(" ".join(f"{v:.0f}" for v in r) for r in raw),
                         capture_output=True, text=True, check=True).stdout
    got = np.array([[float(x) for x in line.split()] for line in out.splitlines()])
    Ab, cb = RZ.in_board_frame("accel", board.accel.A, board.accel.c, True)
    acc = raw[:, 0:3] * np.diag(Ab) + cb
    np.testing.assert_allclose(got[:, 0:3] / 256.0, acc, atol=2e-6)
    gb = M["gyro"] @ -np.linalg.solve(board.gyro.A, board.gyro.c)
    np.testing.assert_allclose(got[:, 3:6], (raw[:, 3:6] - gb) * 0.06957, rtol=1e-5, atol=1e-4)
    assert board.gyro.lsb_per_unit == 14.375 and "GYRO_GAIN 0.06957" in e.text
    mag = board.mag.apply(chip[:, 6:9]) @ M["mag"].T * board.mag.lsb_per_unit
    np.testing.assert_allclose(got[:, 6:9], mag, rtol=1e-5, atol=2e-3)
    # the module's own reading back (raw in the session's axes, output turned
    # back into them) agrees with gcc's
    np.testing.assert_allclose(e.apply["accel"](chip[:, 0:3]), got[:, 0:3] @ M["accel"] / 256.0,
                               atol=1e-6)


def test_razor_yaml_same_numbers_as_c(board):
    c = RZ.parse_c(export(board, "razor-c").text)
    y = RZ.parse_yaml(export(board, "razor-yaml").text)
    for k in ("ACCEL_X_MIN", "ACCEL_Z_MAX", "GYRO_AVERAGE_OFFSET_Y", "MAGN_Y_MAX"):
        assert y[k] == c[k]
    np.testing.assert_array_equal(y["magn_ellipsoid_transform"], c["magn_ellipsoid_transform"])
    assert y["calibration_magn_use_extended"] is True


def test_ardupilot_round_trip_and_conventions(board, sess):
    """ArduPilot's arithmetic restated (sensor frame): accel scal * (in - offs),
    gyro in - offs, compass M (in + ofs), M symmetric from DIA/ODI."""
    p = AP.parse(export(board, "ardupilot").text)
    raw = _rows(sess, "accel")
    a_in = raw * G0 / board.accel.lsb_per_unit
    s = np.array([p[f"INS_ACCSCAL_{a}"] for a in "XYZ"])
    o = np.array([p[f"INS_ACCOFFS_{a}"] for a in "XYZ"])
    np.testing.assert_allclose(s * (a_in - o) / G0, _diag_model(board.accel, raw), atol=1e-7)
    g = _rows(sess, "gyro")
    gb = -np.linalg.solve(board.gyro.A * board.gyro.lsb_per_unit, board.gyro.c)
    w_in = np.radians(g / board.gyro.lsb_per_unit)
    np.testing.assert_allclose(np.degrees(w_in - [p[f"INS_GYROFFS_{a}"] for a in "XYZ"]),
                               g / board.gyro.lsb_per_unit - gb, atol=1e-7)
    m = _rows(sess, "mag")
    d = [p[f"COMPASS_DIA_{a}"] for a in "XYZ"]
    x, y, z = p["COMPASS_ODI_X"], p["COMPASS_ODI_Y"], p["COMPASS_ODI_Z"]
    M = np.array([[d[0], x, y], [x, d[1], z], [y, z, d[2]]])
    ofs = np.array([p[f"COMPASS_OFS_{a}"] for a in "XYZ"])
    out = (m * 1000 / board.mag.lsb_per_unit + ofs) @ M.T / 1000
    want = board.mag.apply(m)
    # same magnitudes; the frame turned by the polar factor's angle
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), np.linalg.norm(want, axis=1),
                               rtol=1e-7)
    U, _ = C.polar(board.mag.A)
    np.testing.assert_allclose(out @ U.T, want, atol=1e-7)
    # offsets: ArduPilot adds them, so they are minus the hard-iron centre in mGauss
    centre = -np.linalg.solve(board.mag.A, board.mag.c) * 1000 / board.mag.lsb_per_unit
    np.testing.assert_allclose(ofs, -centre, rtol=1e-6, atol=1e-3)


def test_imucal_round_trip_with_imucal(board, sess):
    """imucal's own FerrarisCalibrationInfo reads the JSON and calibrates the
    session's rows to motecal's values (m/s^2 at imucal's g = 9.81)."""
    from imucal import FerrarisCalibrationInfo
    text = export(board, "imucal").text
    info = FerrarisCalibrationInfo.from_json(text)
    rows = np.flatnonzero(sess.has("accel") & sess.has("gyro"))
    acc, gyr = sess.sensor("accel")[rows], sess.sensor("gyro")[rows]
    a, g = info.calibrate(acc, gyr, "a.u.", "a.u.")
    np.testing.assert_allclose(a, 9.81 * board.accel.apply(acc), atol=1e-9)
    np.testing.assert_allclose(g, board.gyro.apply(gyr), atol=1e-9)
    assert json.loads(text)["_format_version"] == "2.0"


def test_c_header_through_the_firmware_code(board, sess):
    """The header's calset, corrected by the firmware's own C (mote_c), is the
    calibration within the fixed-point worst case fixedpoint states."""
    from motecal.firmware import fixedpoint as FP
    from motecal.firmware import mote_c
    text = export(board, "c-header").text
    calset = CH.parse(text)
    _, report = CH.build(board)
    raw = sess.raw[np.isfinite(sess.raw).all(axis=1)].astype(np.int64)
    out = mote_c.correct(calset, raw)
    for s, cal in board.sensors():
        sl = FP.SENSOR_SLICES[s]
        want = FP.physical_correct(s, cal.A, cal.c, raw[:, sl])
        err = np.abs(out[:, sl] - want).max(axis=0)
        assert (err <= report[s].worst_lsb + 1e-9).all(), (s, err, report[s].worst_lsb)
        # and the header's numbers are the ones fixedpoint built
        fs = report[s].fixed
        assert f"motecal_{s}_a[9] = {{" + ", ".join(str(int(v)) for v in fs.a.reshape(9)) in text
        np.testing.assert_allclose(export(board, "c-header").apply[s](raw[:, sl]),
                                   out[:, sl] / FP.NOMINAL_SCALES[s], atol=1e-12)


def test_costs_are_the_restricted_models_errors(board, sess):
    """The printed cost is |target - calibration| on the session's rows, as the
    test computes it from the restricted model itself."""
    e = export(board, "ardupilot")
    cost = C.costs(board, e, sess)
    raw = _rows(sess, "accel")
    d = np.linalg.norm(_diag_model(board.accel, raw) - board.accel.apply(raw), axis=1)
    assert cost["accel"]["rms"] == pytest.approx(np.sqrt(np.mean(d ** 2)), rel=1e-4)
    assert cost["accel"]["rms"] > 1e-3              # this board has cross-axis coupling
    assert cost["mag"]["magnitude_rms"] < 1e-6      # the symmetric part keeps magnitudes
    lines = C.cost_lines(e, cost)
    assert any(l.startswith("accel: offset and scale per axis") for l in lines)
    sphere = C.costs(board, e)                       # without data: over directions
    assert "2000 directions" in sphere["accel"]["on"]
