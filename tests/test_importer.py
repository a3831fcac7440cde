"""Import of measured data: every shared real file (counts, rates, units, labels,
clipping), the project CSV round trip, broken files, and ``motecal import``."""
import re
import shutil
import struct
import warnings

import numpy as np
import pytest

from motecal.errors import UserError
from motecal.sessions import importer as I
from motecal.sessions.session import LABEL_NONE, LABEL_ROT, SessionData

BOARDS = ("razor1", "razor2")
RUNS = ("full-sphere", "rotate-ccw-around-z-pointing-up", "unmoved-with-x-pointing-forward",
        "unmoved-with-z-pointing-front-and-x-up", "unmoved-with-z-pointing-front-and-y-down")
ACC_FILES = ("acc_x_neg", "acc_x_pos", "acc_y_neg", "acc_y_pos", "acc_z_neg", "acc_z_pos")


def _razor_lines(path):
    """Independent count of the A/M/G lines of a Razor text file."""
    text = path.read_text()
    return {k: len(re.findall(rf"^#{k}-R=", text, re.M)) for k in "AMG"}


def _csv_rows(path):
    return np.loadtxt(path, delimiter=",", skiprows=1)


@pytest.fixture(scope="module")
def razor_static(measured_dir):
    out = {}
    for b in BOARDS:
        files = [measured_dir / "sensorstick-boards" / b / f"{b}_{a}.raw" for a in ACC_FILES]
        out[b] = (files, I.read_razor_text(files))
    return out


@pytest.fixture(scope="module")
def measured_dir(measured):
    return measured


@pytest.fixture(scope="module")
def timestamped(measured_dir):
    return {r: I.read_timestamped(measured_dir / "mpu6050-hmc5883l-timestamped" / r) for r in RUNS}


# ---------------------------------------------------------------- Razor text, real files

@pytest.mark.parametrize("board", BOARDS)
def test_razor_acc_files_give_six_poses_one_per_file(razor_static, board):
    files, d = razor_static[board]
    counts = [_razor_lines(f) for f in files]
    n = sum(c["A"] for c in counts)
    assert all(c["A"] == c["M"] == c["G"] for c in counts)
    assert len(d) == n and d.meta["samples"] == {"accel": n, "gyro": n, "mag": n}
    assert d.meta["format"] == "razor-text" and d.meta["source"] == "; ".join(map(str, files))
    assert d.meta["rate_hz"] == 50.0 and d.meta["rates_hz"]["gyro"] == 50.0
    np.testing.assert_allclose(d.t, np.arange(n) / 50.0)
    assert d.kind == "static" and d.meta["kind_decision"].startswith("auto: static")
    assert d.poses() == [1, 2, 3, 4, 5, 6]
    assert d.chips == {"accel": "ADXL345", "gyro": "ITG3205", "mag": "HMC5883L"}
    assert d.scales == {"accel": 256.0, "gyro": 14.375, "mag": 1090.0}
    start = 0
    for i, (f, c) in enumerate(zip(files, counts), start=1):
        rows = slice(start, start + c["A"])
        start += c["A"]
        info = d.meta["files"][i - 1]
        assert info["file"] == str(f) and info["pose"] == i and info["samples"] == c["A"]
        lab = d.label[rows]
        assert set(np.unique(lab)) <= {0, i}
        assert (lab == i).mean() > 0.95          # ~30 s held still: nearly all of it
        pose = d.select(d.label == i)
        acc = pose.physical("accel").mean(axis=0)
        # gravity along the file's axis, magnitude ~1 g (uncalibrated: within 12 %)
        assert abs(np.linalg.norm(acc) - 1.0) < 0.12
        axis = "xyz".index(ACC_FILES[i - 1][4])
        assert np.argmax(np.abs(acc)) == axis and abs(acc[axis]) > 0.85
        mag = np.linalg.norm(pose.physical("mag").mean(axis=0))
        assert 0.2 < mag < 0.7                    # Earth's field, gauss
        gyro = pose.physical("gyro")
        assert gyro.std(axis=0).max() < 0.2       # still: noise only, deg/s
        assert np.abs(gyro.mean(axis=0)).max() < 5.0
    # opposite files point gravity the opposite way
    means = [d.select(d.label == i).physical("accel").mean(axis=0) for i in range(1, 7)]
    for k in range(3):
        assert means[2 * k][k] * means[2 * k + 1][k] < 0


@pytest.mark.parametrize("board", BOARDS)
def test_razor_gyro_file_is_idle_and_still(measured_dir, board):
    f = measured_dir / "sensorstick-boards" / board / f"{board}_gyr_xyz.raw"
    d = I.read_any([f])
    c = _razor_lines(f)
    assert len(d) == c["G"] and d.meta["format"] == "razor-text"
    assert d.kind == "idle" and d.poses() == [1]
    assert d.meta["still_fraction"] > 0.95 and (d.label == 1).mean() > 0.95
    assert d.physical("gyro").std(axis=0).max() < 0.2
    assert d.meta["clipped"] == {}


def test_razor_kind_can_be_forced(measured_dir):
    f = measured_dir / "sensorstick-boards" / "razor1" / "razor1_gyr_xyz.raw"
    d = I.read_razor_text([f], kind="rotation")
    assert d.kind == "rotation" and (d.label == LABEL_ROT).all()
    assert d.meta["kind_decision"].startswith("given: rotation")


# ---------------------------------------------------------------- Razor float, real files

def test_magnetometer_sweep_is_rotation_in_gauss(measured_dir):
    f = measured_dir / "sensorstick-mag-sweep" / "magnetom.float"
    d = I.read_any([f])
    assert d.meta["format"] == "razor-float" and len(d) == f.stat().st_size // 12 == 10000
    assert d.meta["samples"] == {"accel": 0, "gyro": 0, "mag": 10000}
    assert np.isnan(d.raw[:, :6]).all() and not np.isnan(d.raw[:, 6:]).any()
    assert d.kind == "rotation" and (d.label == LABEL_ROT).all()
    assert d.meta["still_fraction"] < 0.2
    assert d.chips["mag"] == "HMC5883L" and d.scales["mag"] == 1090.0
    assert d.meta["rates_hz"] == {"mag": 50.0}
    mag = d.physical("mag")
    # swept through all directions: every axis takes both signs
    assert (mag.min(axis=0) < -0.3).all() and (mag.max(axis=0) > 0.3).all()
    # the repository's published calibration makes the field a sphere (frame as recorded)
    import json
    cal = json.loads((f.parent / "published_calibration.json").read_text())["magnetom.float"]
    c, T = np.array(cal["magn_ellipsoid_center"]), np.array(cal["magn_ellipsoid_transform"])
    before = np.linalg.norm(d.sensor("mag") - d.sensor("mag").mean(axis=0), axis=1)
    after = np.linalg.norm((d.sensor("mag") - c) @ T.T, axis=1)
    assert after.std() / after.mean() < 0.05 < before.std() / before.mean()
    assert 0.3 < after.mean() / 1090 < 0.6


def test_disturbed_hmc5843_sweep_with_chip_override(measured_dir):
    f = measured_dir / "hmc5843-disturbed-sweep" / "magnetom.float"
    d = I.read_razor_float(f, chip="hmc5843")
    d2 = I.read_any([f], chip=["mag=hmc5843"])
    assert d.chips["mag"] == d2.chips["mag"] == "HMC5843"
    assert d.scales["mag"] == d2.scales["mag"] == 1300.0
    assert len(d) == 10000 and d.kind == "rotation" and (d.label == LABEL_ROT).all()
    field = np.linalg.norm(d.physical("mag"), axis=1)
    assert 0.2 < np.median(field) < 0.8
    assert d.meta["chips_from"] == "--chip mag=HMC5843"


# ---------------------------------------------------------------- timestamped pairs, real files

@pytest.mark.parametrize("run", RUNS)
def test_timestamped_runs_keep_their_own_time_bases(measured_dir, timestamped, run):
    d = timestamped[run]
    folder = measured_dir / "mpu6050-hmc5883l-timestamped" / run
    mag, imu = _csv_rows(folder / "hmc5883l_counts.csv"), _csv_rows(folder / "mpu6050_counts.csv")
    assert d.meta["samples"] == {"accel": len(imu), "gyro": len(imu), "mag": len(mag)}
    assert len(d) == len(mag) + len(imu)
    assert np.all(np.diff(d.t) >= 0)
    assert d.t[0] == min(mag[0, 0], imu[0, 0]) and d.t[-1] == max(mag[-1, 0], imu[-1, 0])
    has_m, has_a, has_g = d.has("mag"), d.has("accel"), d.has("gyro")
    assert np.array_equal(has_a, has_g) and np.array_equal(has_m, ~has_a)
    np.testing.assert_array_equal(d.t[has_m], mag[:, 0])
    np.testing.assert_array_equal(d.sensor("mag")[has_m], mag[:, 1:])
    # the converter wrote +250 deg/s as 32768, one past int16: stored as full scale 32767
    np.testing.assert_array_equal(d.raw[has_a, :6], np.minimum(imu[:, 1:], 32767))
    n_over = int((imu[:, 1:] == 32768).sum())
    assert (f"{n_over} values of 32768" in d.meta.get("notes", "")) == (n_over > 0)
    assert 74 < d.meta["rates_hz"]["mag"] < 80 and 95 < d.meta["rates_hz"]["accel"] < 101
    assert d.chips == {"accel": "MPU6050", "gyro": "MPU6050", "mag": "HMC5883L"}
    assert d.scales == {"accel": 16384.0, "gyro": 131.0, "mag": 1090.0}
    acc = np.linalg.norm(d.physical("accel")[has_a], axis=1)
    assert abs(np.median(acc) - 1.0) < 0.06
    field = np.linalg.norm(d.physical("mag")[has_m], axis=1)
    assert 0.3 < np.median(field) < 0.65


@pytest.mark.parametrize("run", [r for r in RUNS if r.startswith("unmoved")])
def test_unmoved_runs_are_still(timestamped, run):
    d = timestamped[run]
    assert d.kind == "idle" and d.poses() == [1]
    assert d.meta["still_fraction"] > 0.98
    for s in ("accel", "mag"):          # both clocks carry the label
        assert (d.label[d.has(s)] == 1).mean() > 0.98
    assert d.physical("gyro")[d.has("gyro")].std(axis=0).max() < 0.3
    assert d.meta["clipped"] == {}


@pytest.mark.parametrize("run", ["full-sphere", "rotate-ccw-around-z-pointing-up"])
def test_turning_runs_are_rotation(timestamped, run):
    d = timestamped[run]
    assert d.kind == "rotation" and (d.label == LABEL_ROT).all()
    assert d.meta["still_fraction"] < 0.1
    assert d.meta["kind_decision"].startswith("auto: rotation")


def test_gyro_clipping_is_visible(measured_dir, timestamped):
    imu = _csv_rows(measured_dir / "mpu6050-hmc5883l-timestamped" / "full-sphere" / "mpu6050_counts.csv")
    at_limit = (np.abs(imu[:, 4:7]) >= 32767).any(axis=1).sum()
    assert at_limit >= 10
    d = timestamped["full-sphere"]
    g = d.sensor("gyro")[d.has("gyro")]
    assert g.max() >= 32767 and g.min() <= -32767
    assert d.meta["clipped"] == {"gyro": int(at_limit)}
    assert "gyro" not in timestamped["rotate-ccw-around-z-pointing-up"].meta["clipped"]
    assert f"gyro {at_limit} samples" in I.summary(d)


# ---------------------------------------------------------------- detection by content

def test_formats_detected_by_content_not_name(measured_dir, tmp_path):
    src = {
        "razor-text": measured_dir / "sensorstick-boards" / "razor1" / "razor1_acc_x_pos.raw",
        "razor-float": measured_dir / "sensorstick-mag-sweep" / "magnetom.float",
        "timestamped-csv": measured_dir / "mpu6050-hmc5883l-timestamped" / "full-sphere" / "hmc5883l_counts.csv",
    }
    for i, (fmt, f) in enumerate(src.items()):
        dst = tmp_path / f"mystery{i}.txt"
        shutil.copyfile(f, dst)
        assert I.detect_format(dst) == fmt
        d = I.read_any([dst])
        assert d.meta["format"] == fmt and len(d) > 1000
    assert I.detect_format(measured_dir / "mpu6050-hmc5883l-timestamped" / "full-sphere") == "timestamped-csv"
    # a lone magnetometer file of a timestamped run: mag only, chip from its header
    d = I.read_any([tmp_path / "mystery2.txt"])
    assert d.meta["samples"]["accel"] == 0 and d.chips["mag"] == "HMC5883L"
    csvf = tmp_path / "roundtrip.dat"
    I.write_csv(d.select(np.arange(50)), csvf)
    assert I.detect_format(csvf) == "csv"


def test_mixed_formats_one_session(measured_dir):
    """Files of different formats are one session, each read by its own
    reader (tests/test_import_combine.py has the rest); a board's sensors
    must agree: an ADXL345 beside an MPU6050 is refused."""
    face = measured_dir / "sensorstick-boards" / "razor1" / "razor1_acc_x_pos.raw"
    sweep = measured_dir / "sensorstick-mag-sweep" / "magnetom.float"
    d = I.read_any([face, sweep])
    assert d.meta["format"] == "razor-text+razor-float"
    assert len(d) == len(I.read_razor_text([face])) + len(I.read_razor_float(sweep))
    with pytest.raises(UserError, match="accel: .* ADXL345 at 256 .* MPU6050 at 16384: one "
                                        "board per session"):
        I.read_any([face, measured_dir / "mpu6050-hmc5883l-timestamped" / "full-sphere"])


# ---------------------------------------------------------------- chips

def test_chip_overrides():
    assert I.parse_chip_overrides("mag=hmc5843") == {"mag": ("HMC5843", 1300.0)}
    assert I.parse_chip_overrides(["hmc5843", "gyro=ITG-3205"]) == {
        "mag": ("HMC5843", 1300.0), "gyro": ("ITG3205", 14.375)}
    assert I.parse_chip_overrides({"accel": "mpu6050"}) == {"accel": ("MPU6050", 16384.0)}
    assert I.parse_chip_overrides("acc=mpu6050,gyr=mpu6050") == {
        "accel": ("MPU6050", 16384.0), "gyro": ("MPU6050", 131.0)}
    assert I.parse_chip_overrides("mag=lsm303:1100") == {"mag": ("LSM303", 1100.0)}
    for bad in ("accel=hmc5843", "mpu6050", "mag=nochip", "baro=bmp180", "mag=x:-3"):
        with pytest.raises(UserError, match="--chip"):
            I.parse_chip_overrides(bad)


# ---------------------------------------------------------------- project CSV

def _synthetic(rate=125.0, seed=1):
    """still 2 s, 0.5 s turn about y, still 2 s, turn, still 2 s (one clock)."""
    rng = np.random.default_rng(seed)
    still, turn = int(2 * rate), int(0.5 * rate)
    ang = np.concatenate([np.zeros(still), np.linspace(0, np.pi / 2, turn),
                          np.full(still, np.pi / 2), np.linspace(np.pi / 2, np.pi, turn),
                          np.full(still, np.pi)])
    n = len(ang)
    raw = np.zeros((n, 9))
    raw[:, 0] = 256 * np.sin(ang); raw[:, 2] = 256 * np.cos(ang)
    raw[:, 3:6] = [20, -10, 5]
    raw[:, 4] += np.gradient(ang) * rate * 180 / np.pi * 14.375
    raw[:, 6] = 400 * np.cos(ang); raw[:, 7] = 200; raw[:, 8] = -400 * np.sin(ang)
    raw += rng.normal(0, 1.0, raw.shape)
    return np.round(raw), np.arange(n) / rate


def test_csv_round_trip(measured_dir, tmp_path, razor_static):
    _, d = razor_static["razor1"]
    part = d.select(np.r_[0:300, 2000:2300])
    part.label[:5] = LABEL_ROT
    part.raw[10, 3:6] = np.nan                 # a missing gyro sample
    part.t[11] = np.nan                         # and an unknown time
    path = tmp_path / "s.csv"
    I.write_csv(part, path)
    lines = path.read_text().splitlines()
    assert lines[0] == "mote,seq,t,label,ax,ay,az,gx,gy,gz,mx,my,mz"
    assert lines[1].split(",")[3] == "rot" and ",,," in lines[11]
    back = I.read_csv(path)
    assert np.array_equal(back.raw, part.raw, equal_nan=True)
    assert np.array_equal(back.t, part.t, equal_nan=True)
    assert np.array_equal(back.label, part.label)
    assert np.array_equal(back.mote, part.mote) and np.array_equal(back.seq, part.seq)
    assert back.meta["kind_decision"] == "auto: static (labels from the file)"
    assert back.meta["format"] == "csv" and back.scales["accel"] == 256.0
    assert back.meta["rates_hz"]["accel"] == pytest.approx(50.0, rel=0.02)


def test_csv_handwritten_with_two_motes_and_gaps(tmp_path):
    path = tmp_path / "two.csv"
    path.write_text("# exported by hand\n"
                    "mote,seq,t,label,ax,ay,az,gx,gy,gz,mx,my,mz\n"
                    "1,0,0.000,1,1,2,256,3,4,5,,,\n"
                    "2,7,0.004,rot,,,,,,,100,-200,300\n"
                    "1,1,0.008,1,1,2,255,3,4,5,,,\n"
                    "\n")
    d = I.read_csv(path)
    assert len(d) == 3 and d.motes == [1, 2]
    assert list(d.label) == [1, LABEL_ROT, 1] and d.seq[1] == 7
    assert d.meta["samples"] == {"accel": 2, "gyro": 2, "mag": 1}
    assert np.isnan(d.raw[0, 6:]).all() and d.raw[1, 8] == 300


def test_unlabelled_csv_gets_still_segments(tmp_path):
    raw, t = _synthetic()
    n = len(raw)
    path = tmp_path / "u.csv"
    d0 = SessionData("u", raw, np.full(n, 3), np.arange(n), t, np.zeros(n), np.zeros(n))
    I.write_csv(d0, path)
    d = I.read_csv(path)
    assert d.kind == "static" and d.poses() == [1, 2, 3]
    assert d.meta["still_thresholds"]["accel_g"] == 0.02
    # each pose is one orientation: gravity differs by 90 degrees between poses
    g = [d.select(d.label == k).physical("accel").mean(axis=0) for k in (1, 2, 3)]
    assert g[0][2] > 0.95 and g[1][0] > 0.95 and g[2][2] < -0.95
    assert (d.label[d.raw[:, 4] > 200] == LABEL_NONE).all()   # turning rows unlabelled
    # forced rotation
    assert (I.read_csv(path, kind="rotation").label == LABEL_ROT).all()


def test_timestamped_synthetic_poses_on_two_clocks(tmp_path):
    """Separate clocks (mag 75 Hz, IMU 100 Hz, jittered): still segments are
    found on the common time line and labelled on both sensors' rows."""
    rng = np.random.default_rng(5)
    raw, t = _synthetic(rate=250.0)             # 7 s of 'truth' at 250 Hz
    ti = np.sort(rng.uniform(0, t[-1], 700)); tm = np.sort(rng.uniform(0, t[-1], 525))
    pick = lambda tt: np.searchsorted(t, tt).clip(0, len(t) - 1)
    imu, mag = raw[pick(ti)], raw[pick(tm)]
    (tmp_path / "mpu6050_counts.csv").write_text(
        "t_s,acc_x,acc_y,acc_z,gyr_x,gyr_y,gyr_z  (MPU6050 raw counts)\n" + "".join(
            f"{a:.6f}," + ",".join(str(int(v)) for v in r[:6]) + "\n" for a, r in zip(ti, imu)))
    (tmp_path / "hmc5883l_counts.csv").write_text(
        "t_s,mag_x,mag_y,mag_z\n" + "".join(
            f"{a:.6f}," + ",".join(str(int(v)) for v in r[6:]) + "\n" for a, r in zip(tm, mag)))
    d = I.read_any([tmp_path], chip="accel=adxl345,gyro=itg3200")
    assert d.meta["format"] == "timestamped-csv"
    assert d.kind == "static" and d.poses() == [1, 2, 3]
    for k in (1, 2, 3):
        tk = d.t[d.label == k]
        assert (d.has("mag") & (d.label == k)).sum() > 50
        assert (d.has("accel") & (d.label == k)).sum() > 70
        assert tk.max() - tk.min() > 1.0
    assert d.chips["mag"] == "HMC5883L"        # from the file name


# ---------------------------------------------------------------- broken files

def _err(excinfo):
    return str(excinfo.value)


def test_broken_csv(tmp_path):
    good = "mote,seq,t,label,ax,ay,az,gx,gy,gz,mx,my,mz\n" + "1,0,0.0,,1,2,3,4,5,6,7,8,9\n" * 4
    cases = {
        "hdr.csv": ("mote,seq,time,label,ax,ay,az,gx,gy,gz,mx,my,mz\n1,0,0,,1,2,3,4,5,6,7,8,9\n",
                    "line 1", "bad header"),
        "num.csv": (good + "1,1,0.1,,1,2,x3,4,5,6,7,8,9\n", "line 6", "az is not a number"),
        "cols.csv": (good + "1,1,0.1,,1,2,3,4,5,6,7,8\n", "line 6", "expected 13 columns, found 12"),
        "lab.csv": (good[:good.index("\n") + 1] + "1,0,0.0,zero,1,2,3,4,5,6,7,8,9\n", "line 2", "label"),
        "empty.csv": ("", "line 1", "empty file"),
        "nohdrdata.csv": (good.splitlines()[0] + "\n", "line 1", "no samples"),
    }
    for name, (text, where, what) in cases.items():
        p = tmp_path / name
        p.write_text(text)
        with pytest.raises(UserError) as e:
            I.read_csv(p)
        msg = _err(e)
        assert msg.startswith(f"{p}: {where}:") and what in msg, msg
        assert "\n" not in msg


def test_broken_razor_text(measured_dir, tmp_path):
    lines = (measured_dir / "sensorstick-boards" / "razor1" / "razor1_acc_x_pos.raw").read_text().splitlines()
    cases = {
        "num.raw": (lines[:40] + ["#M-R=-264.00,abc,-16.00"] + lines[41:90], "line 41", "not a number"),
        "order.raw": (lines[:29] + lines[30:60], "line 30", "expected #G-R="),
        "three.raw": (lines[:9] + ["#A-R=1.00,2.00"] + lines[10:30], "line 10", "expected 3 values"),
        "junk.raw": (lines[:12] + ["hello"] + lines[12:30], "line 13", "not a Razor"),
    }
    for name, (ls, where, what) in cases.items():
        p = tmp_path / name
        p.write_text("\n".join(ls) + "\n")
        with pytest.raises(UserError) as e:
            I.read_razor_text([p])
        msg = _err(e)
        assert msg.startswith(f"{p}: {where}:") and what in msg, msg
    # a capture that stops mid-sample keeps the whole samples and says so
    p = tmp_path / "cut.raw"
    p.write_text("\n".join(lines[:32]) + "\n")
    d = I.read_razor_text([p])
    assert len(d) == 10 and "incomplete last sample from line 31" in d.meta["notes"]


def test_broken_float_and_timestamped(measured_dir, tmp_path):
    buf = (measured_dir / "sensorstick-mag-sweep" / "magnetom.float").read_bytes()
    p = tmp_path / "cut.float"
    p.write_bytes(buf[:1205])
    with pytest.raises(UserError) as e:
        I.read_any([p])
    assert _err(e).startswith(f"{p}: sample 101 (byte 1200): truncated float file")
    p2 = tmp_path / "nan.float"
    p2.write_bytes(buf[:120] + struct.pack(">fff", 1.0, float("nan"), 2.0) + buf[132:240])
    with pytest.raises(UserError, match=r"sample 11 \(byte 120\)"):
        I.read_razor_float(p2)
    ts = (measured_dir / "mpu6050-hmc5883l-timestamped" / "full-sphere" / "mpu6050_counts.csv").read_text().splitlines()
    p3 = tmp_path / "mpu6050_counts.csv"
    p3.write_text("\n".join(ts[:20] + [ts[20].replace(",", ",,", 1)] + ts[21:40]) + "\n")
    with pytest.raises(UserError) as e:
        I.read_any([p3])
    assert _err(e).startswith(f"{p3}: line 21: expected 7 columns, found 8")
    p3.write_text("\n".join(ts[:7] + ["0.5,1,2,3,4,5,--"] + ts[8:40]) + "\n")
    with pytest.raises(UserError, match=rf"{re.escape(str(p3))}: line 8: column 7 is not a number"):
        I.read_any([p3])
    p3.write_text("t_s,acc_x,acc_q\n1,2,3\n")
    with pytest.raises(UserError, match="line 1: bad header"):
        I.read_any([p3])


def test_unknown_formats(tmp_path):
    p = tmp_path / "notes.txt"
    p.write_text("\n\nhello world\n")
    with pytest.raises(UserError) as e:
        I.read_any([p])
    assert _err(e).startswith(f"{p}: line 3: unknown format")
    b = tmp_path / "blob.bin"
    b.write_bytes(bytes(range(256)) * 3)
    with pytest.raises(UserError, match=re.escape(str(b))):
        I.read_any([b])
    with pytest.raises(UserError, match="no such file"):
        I.read_any([tmp_path / "missing.raw"])


# ---------------------------------------------------------------- motecal import (CLI, store)

def _motecal(capsys, *argv):
    from motecal.commands.main import main
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def _db_state(db):
    """Bytes of the database and its side files (unchanged = nothing written)."""
    return {p.name: p.read_bytes() for p in sorted(db.parent.glob(db.name + "*"))}


def test_cli_import_saves_whole_sessions(measured_dir, tmp_path, capsys, razor_static):
    from motecal.sessions.store import open_store
    db = tmp_path / "m.db"
    files, expected = razor_static["razor1"]
    code, out, err = _motecal(capsys, "import", *files, "--db", db, "--session", "razor1")
    assert code == 0, err
    assert "Session 'razor1'" in out and "6 poses found" in out and "accel 9707 at 50.0 Hz" in out
    assert "ADXL345 256 LSB/g" in out and "kind static [auto: static" in out
    run = measured_dir / "mpu6050-hmc5883l-timestamped" / "full-sphere"
    code, out, err = _motecal(capsys, "import", run, "--db", db, "--session", "sphere")
    assert code == 0, err
    assert "mag 8190 at 77.0 Hz" in out and "rotation" in out and "gyro 22 samples" in out
    sweep = measured_dir / "hmc5843-disturbed-sweep" / "magnetom.float"
    code, out, err = _motecal(capsys, "import", sweep, "--db", db, "--session", "bad",
                              "--chip", "mag=hmc5843", "--kind", "rotation")
    assert code == 0, err
    assert "HMC5843 1300 LSB/gauss" in out and "given: rotation" in out
    with open_store(str(db)) as st:
        assert [s["name"] for s in st.sessions()] == ["razor1", "sphere", "bad"]
        r1 = st.load_session("razor1")
        sp = st.load_session("sphere")
        bad = st.load_session("bad")
    assert np.array_equal(r1.raw, expected.raw) and np.array_equal(r1.label, expected.label)
    assert r1.kind == "static" and r1.poses() == [1, 2, 3, 4, 5, 6]
    assert r1.scales == expected.scales and r1.chips["gyro"] == "ITG3205"
    assert r1.meta["source"] == "; ".join(map(str, files)) and r1.meta["rate_hz"] == 50.0
    assert r1.meta["files"][5]["pose"] == 6 and r1.meta["axis_frame"].startswith("as recorded")
    ref = I.read_timestamped(run)
    order = np.lexsort((ref.seq, ref.mote))
    assert np.array_equal(sp.raw, ref.raw[order], equal_nan=True)
    assert np.array_equal(sp.t, ref.t[order]) and (sp.label == LABEL_ROT).all()
    assert sp.meta["rates_hz"] == ref.meta["rates_hz"] and sp.scales["gyro"] == 131.0
    assert sp.meta["clipped"] == {"gyro": 22}
    assert bad.scales["mag"] == 1300.0 and bad.chips["mag"] == "HMC5843" and bad.kind == "rotation"


def test_cli_failed_import_leaves_db_unchanged(measured_dir, tmp_path, capsys):
    db = tmp_path / "m.db"
    good = measured_dir / "sensorstick-boards" / "razor2" / "razor2_gyr_xyz.raw"
    assert _motecal(capsys, "import", good, "--db", db, "--session", "g")[0] == 0
    before = _db_state(db)
    lines = good.read_text().splitlines()
    broken = tmp_path / "broken.raw"
    broken.write_text("\n".join(lines[:500] + ["#G-R=1.00,2.00,three"] + lines[501:]) + "\n")
    trunc = tmp_path / "cut.float"
    trunc.write_bytes((measured_dir / "sensorstick-mag-sweep" / "magnetom.float").read_bytes()[:999])
    junk = tmp_path / "junk.txt"
    junk.write_text("time;x;y;z\n1;2;3;4\n")
    cases = [   # files, session, the one line on stderr
        ((good, broken), "new", f"{broken}: line 501: #G-R value 3 is not a number"),
        ((trunc,), "new", f"{trunc}: sample 84 (byte 996): truncated float file"),
        ((junk,), "new", f"{junk}: line 1: unknown format"),
        ((tmp_path / "nope.raw",), "new", "no such file"),
        ((good,), "g", "session 'g' already exists"),
    ]
    for files, session, msg in cases:
        code, out, err = _motecal(capsys, "import", *files, "--db", db, "--session", session)
        assert code == 2 and out == ""
        assert err.count("\n") == 1 and msg in err and "Traceback" not in err, err
        assert _db_state(db) == before, msg
    code, out, err = _motecal(capsys, "import", good, "--db", db, "--session", "g", "--kind", "static",
                              "--replace")
    assert code == 0 and "kind static [given: static" in out
    code, out, err = _motecal(capsys, "import", good, "--db", db, "--session", "x", "--chip", "mag=abc")
    assert code == 2 and "--chip mag=abc: unknown mag chip" in err


def test_cli_csv_export_format_imports(tmp_path, capsys):
    from motecal.sessions.store import open_store
    raw, t = _synthetic()
    n = len(raw)
    src = SessionData("u", raw, np.full(n, 4), np.arange(100, 100 + n), t, np.zeros(n), np.zeros(n))
    path = tmp_path / "u.csv"
    I.write_csv(src, path)
    db = tmp_path / "c.db"
    code, out, err = _motecal(capsys, "import", path, "--db", db, "--session", "u", "--format", "csv")
    assert code == 0, err
    assert "3 poses found" in out
    with open_store(str(db)) as st:
        back = st.load_session("u")
    assert np.array_equal(back.raw, raw) and back.motes == [4] and back.poses() == [1, 2, 3]
    np.testing.assert_allclose(back.t, t, atol=1e-6)
    # duplicated (mote, seq) is the file's fault: named with its line
    text = path.read_text().splitlines()
    path.write_text("\n".join(text + [text[5]]) + "\n")
    code, out, err = _motecal(capsys, "import", path, "--db", db, "--session", "u2")
    assert code == 2 and f"{path}: line {len(text) + 1}: mote 4 has sequence number 104 twice" in err


def test_recordings_shorter_than_the_stillness_window_import(tmp_path, capsys):
    """5 float samples, 5 Razor text samples, a 3-row timestamped run: fewer
    rows than one stillness window (0.4 s) import with a note, no traceback."""
    fl = tmp_path / "five.float"
    fl.write_bytes(b"".join(struct.pack(">fff", 100 + i, -50, 200) for i in range(5)))
    txt = tmp_path / "five.raw"
    txt.write_text("#A-R=1,2,250\n#M-R=100,20,300\n#G-R=1,2,3\n" * 5)
    run = tmp_path / "run"
    run.mkdir()
    (run / "mpu6050_counts.csv").write_text(
        "t_s,acc_x,acc_y,acc_z,gyr_x,gyr_y,gyr_z\n" + "".join(
            f"{0.01 * i:.3f},0,0,16384,1,2,3\n" for i in range(3)))
    (run / "hmc5883l_counts.csv").write_text(
        "t_s,mag_x,mag_y,mag_z\n" + "".join(f"{0.013 * i:.3f},200,0,-400\n" for i in range(3)))
    db = tmp_path / "s.db"
    for name, path, rows in (("f", fl, 5), ("t", txt, 5), ("r", run, 6)):
        code, out, err = _motecal(capsys, "import", path, "--db", db, "--session", name)
        assert code == 0 and err == "", err
        assert f"{rows} rows" in out and "shorter than the stillness window (0.4 s)" in out


def test_random_bytes_float_file_is_one_line(tmp_path, capsys):
    """A signalling NaN among the bytes used to print numpy's RuntimeWarning
    ("invalid value encountered in cast") before the error line."""
    snan = bytes.fromhex("7f800001")
    rng = np.random.default_rng(5)
    body = b"".join(snan + rng.bytes(8) for _ in range(100))          # 1200 bytes
    f = tmp_path / "rnd.float"
    f.write_bytes(body)
    for extra in ([], ["--format", "razor-float"]):
        with warnings.catch_warnings(record=True) as caught:   # shown on stderr outside pytest
            warnings.simplefilter("always")
            code, out, err = _motecal(capsys, "import", f, "--db", tmp_path / "r.db",
                                      "--session", "x", *extra)
        assert not caught, [str(w.message) for w in caught]
        assert code == 2 and out == ""
        assert err.count("\n") == 1 and err.startswith(f"motecal: error: {f}"), err
