"""Real measured data (../shared/data/measured): the Sensor Stick sweep against
its published ellipsoid calibration, the disturbed HMC5843 sweep refused, and
the two Razor boards' accelerometer and gyroscope."""
import json

import numpy as np
import pytest

from motecal.calib import gate
from motecal.calib.board import calibrate_board
from motecal.sessions import importer


@pytest.fixture(scope="module")
def sweep_board(measured):
    d = importer.read_razor_float(measured / "sensorstick-mag-sweep" / "magnetom.float")
    b = calibrate_board(d, seed=0)
    gate.decide(b)
    return b, json.loads((measured / "sensorstick-mag-sweep" /
                          "published_calibration.json").read_text())["magnetom.float"]


def test_sensor_stick_hard_iron_centre(sweep_board):
    b, pub = sweep_board
    assert b.gate["accepted"], b.gate
    centre = -np.linalg.solve(b.mag.A, b.mag.c)        # raw counts where calibrated = 0
    assert np.abs(centre - pub["magn_ellipsoid_center"]).max() < 1.0, centre


def test_sensor_stick_soft_iron_shape(sweep_board):
    """Razor's T = V diag(min(r)/r) V^T is symmetric and scaled so its smallest
    axis is 1; ours is lower-triangular with det 1.  Both map the ellipsoid to a
    sphere, so their symmetric parts (sqrt(A^T A)) agree up to one overall scale."""
    b, pub = sweep_board
    T = np.array(pub["magn_ellipsoid_transform"])

    def shape(M):
        w, V = np.linalg.eigh(M.T @ M)
        S = V @ np.diag(np.sqrt(w)) @ V.T
        return S / np.linalg.det(S) ** (1 / 3)

    ours, theirs = shape(b.mag.A), shape(T)
    assert np.abs(ours - theirs).max() < 2e-3, (ours.round(4), theirs.round(4))
    # ... a test with teeth: the anisotropy (0.981-1.029) is 20x that tolerance
    assert np.ptp(np.diag(theirs)) > 0.04


def test_sensor_stick_field_and_residual(sweep_board):
    b, _ = sweep_board
    assert 0.5 < b.mag.field_gauss < 0.6               # ~0.54 gauss (Montreal ~0.53)
    assert b.mag.quality["rms_rel"] < 0.02
    assert b.mag.quality["coverage"] > 0.9


def test_disturbed_hmc5843_sweep_refused(measured):
    d = importer.read_razor_float(measured / "hmc5843-disturbed-sweep" / "magnetom.float",
                                  chip="hmc5843")
    assert d.scales["mag"] == 1300.0
    b = calibrate_board(d, seed=0)
    dec = gate.decide(b)
    assert not dec.accepted
    assert any(r.startswith("mag: residual too large") for r in dec.reasons), dec.reasons
    assert b.mag.quality["rms_rel"] > 3 * gate.LIMITS.max_rms_rel["mag"]


@pytest.mark.parametrize("board", ["razor1", "razor2"])
def test_razor_accel_and_gyro_sane(measured, board):
    files = sorted((measured / "sensorstick-boards" / board).glob("*.raw"))
    d = importer.read_razor_text(files)
    # six +-axis poses: the paper's offsets + scales (6 parameters) are identifiable
    b = calibrate_board(d, seed=0, model="paper", groups=("offsets", "scales"))
    dec = gate.decide(b)
    acc = b.accel
    # accepted: the six poses (no rotation sweep) cannot determine the
    # magnetometer, which is left out with a warning
    assert dec.accepted, dec.reasons
    assert b.mag is None and b.to_json()["mag"] is None
    assert any(w.startswith("mag: not calibrated: no rotation sweep, and the static poses "
                            "cannot determine it (set O not fitted: poses too clustered")
               for w in dec.warnings), dec.warnings
    o = np.array([acc.param(f"o_{a}").value for a in "xyz"])
    s = np.array([acc.param(f"s_{a}").value for a in "xyz"])
    assert np.all(np.abs(o) < 0.1) and np.all(np.abs(s - 1) < 0.03)
    assert acc.mse_after < acc.mse_before / 100
    assert 0.98 < acc.min_after and acc.max_after < 1.02
    # each pose's calibrated magnitude is 1 g within 2 mg
    rows = (d.label >= 1) & d.has("accel")
    v = acc.apply(d.sensor("accel")[rows])
    for p in np.unique(d.label[rows]):
        assert abs(np.linalg.norm(v[d.label[rows] == p].mean(axis=0)) - 1) < 2e-3
    gy = b.gyro
    bias = np.array([gy.param(f"b_{a}").value for a in "xyz"])
    assert gy.model == "bias"                           # files are separate: no moves
    assert np.all(np.abs(bias) < 10) and np.abs(bias).max() > 0.1
    still = d.sensor("gyro")[(d.label >= 1) & d.has("gyro")] / d.scales["gyro"]
    assert np.allclose(bias, still.mean(axis=0))        # the bias is the mean ...
    assert np.all(np.abs(np.array(gy.extra["bias_eq6"]) - bias) < 0.05)   # eq. 6 close to it
    assert gy.mse_after < gy.mse_before / 10
    # the full model needs more orientations than six: refused with that reason
    full = calibrate_board(d, seed=0, gyro_matrix=False, kfold=0)
    assert any("accel: too few distinct orientations: 6" in r
               for r in gate.decide(full).reasons)


def test_rotation_session_calibrates_the_magnetometer_only(measured):
    d = importer.read_timestamped(measured / "mpu6050-hmc5883l-timestamped" / "full-sphere")
    b = calibrate_board(d, seed=0, kfold=0)
    dec = gate.decide(b)
    assert dec.accepted, dec.reasons
    assert b.accel is None and b.gyro is None and b.mag.dataset == "R"
    assert any("accel: not calibrated: no static poses" in w for w in dec.warnings)
    assert 0.45 < b.mag.field_gauss < 0.6 and b.mag.quality["rms_rel"] < 0.02


def test_razor_board_calibrate_command_accepts_it(measured, tmp_path, capsys):
    """What the README promises: the Razor boards are accepted with --model
    paper --params offsets,scales (exit 0), the magnetometer left out."""
    from motecal.commands.main import main
    files = sorted((measured / "sensorstick-boards" / "razor1").glob("razor1_acc_*.raw"))
    db, out = tmp_path / "r.db", tmp_path / "cal.json"
    assert main(["import", *map(str, files), "--db", str(db), "--session", "razor1"]) == 0
    rc = main(["calibrate", "--db", str(db), "--session", "razor1", "--model", "paper",
               "--params", "offsets,scales", "--out", str(out), "--seed", "0", "--kfold", "0"])
    text = capsys.readouterr().out
    assert rc == 0, text
    assert "gate: accepted" in text and "warning: mag: not calibrated" in text
    cal = json.loads(out.read_text())
    assert cal["accel"] and cal["gyro"] and cal["mag"] is None


@pytest.mark.parametrize("board", ["razor1", "razor2"])
def test_razor_gyro_hold_calibrates_the_gyro_bias_alone(measured, board):
    """The Razor ``*_gyr_xyz.raw`` files are still holds recorded for the gyro
    bias: calibrated (gate accepted), the accelerometer and magnetometer
    reported skipped, not refused."""
    d = importer.read_any([str(measured / "sensorstick-boards" / board / f"{board}_gyr_xyz.raw")])
    b = calibrate_board(d, seed=1, kfold=0)
    dec = gate.decide(b)
    assert dec.accepted and b.gyro is not None and b.accel is None and b.mag is None, dec
    assert any(w.startswith("accel: not calibrated: a still hold") for w in dec.warnings)
    assert any(w.startswith("mag: not calibrated") for w in dec.warnings)
    assert np.all(np.abs([p.value for p in b.gyro.params[:3]]) < 5.0)
