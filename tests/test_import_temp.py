"""Temperature in imports and exports: the project CSV's optional ``temp``
column (degrees C) and an MPU6050-style timestamped log's temperature
column with its unit (``temp_c``, ``temp_f``, ``temp_raw`` of the named
chip); hostile cells give one line on stderr, exit 2, and the database is
left as it was.  (~3 s)"""
import shutil
from pathlib import Path

import numpy as np
import pytest

from motecal.commands.main import main
from motecal.sessions.importer import TEMP_RAW_C, read_csv, read_timestamped, write_csv
from motecal.sessions.session import SessionData
from motecal.sessions.store import open_store

RUN = "mpu6050-hmc5883l-timestamped/unmoved-with-x-pointing-forward"
HEADER = "mote,seq,t,label,ax,ay,az,gx,gy,gz,mx,my,mz"


def _motecal(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def _data(n=300, temp=True, seed=0):
    rng = np.random.default_rng(seed)
    raw = rng.integers(-500, 500, (n, 9)).astype(float)
    t = np.arange(n) / 125.0
    d = SessionData("x", raw, np.repeat([1, 2], n // 2), np.tile(np.arange(n // 2), 2), t,
                    np.zeros(n, int), np.zeros(n, np.uint8))
    if temp:
        d.temp = 22.0 + rng.random(n) * 3
        d.temp[:5] = np.nan                 # unknown in some rows
    return d


def test_project_csv_temp_column_round_trip(tmp_path):
    d = _data()
    path = tmp_path / "a.csv"
    write_csv(d, path)
    lines = path.read_text().splitlines()
    assert lines[0] == HEADER + ",temp"
    assert lines[1].endswith(",")           # unknown: an empty cell
    back = read_csv(path)
    np.testing.assert_array_equal(back.temp, d.temp)       # NaN == NaN here, exact floats
    np.testing.assert_array_equal(back.raw, d.raw)
    # without a temperature: no column, and read back as None
    plain = _data(temp=False)
    write_csv(plain, tmp_path / "b.csv")
    assert (tmp_path / "b.csv").read_text().splitlines()[0] == HEADER
    assert read_csv(tmp_path / "b.csv").temp is None


def test_temperature_survives_selections_and_the_store(tmp_path, capsys):
    d = _data()
    assert np.array_equal(d.for_mote(2).temp, d.temp[150:], equal_nan=True)
    write_csv(d, tmp_path / "a.csv")
    db = tmp_path / "a.db"
    code, out, err = _motecal(capsys, "import", tmp_path / "a.csv", "--db", db, "--session", "s")
    assert code == 0, err
    code, out, err = _motecal(capsys, "export", "--db", db, "--session", "s", "--mote", "2",
                              "--csv", tmp_path / "b.csv")
    assert code == 0, err
    back = read_csv(tmp_path / "b.csv")
    np.testing.assert_array_equal(back.temp, d.temp[150:])


@pytest.mark.parametrize("cell, message", [
    ("abc", "temp is not a number: 'abc'"),
    ("nan", "temp is not a finite number: 'nan'"),
    ("1e400", "temp is not a finite number"),
    ("-300", "temp = -300 is -300 degrees C, outside -100..200"),
])
def test_hostile_temp_cells_are_one_line_and_store_nothing(tmp_path, capsys, cell, message):
    path = tmp_path / "bad.csv"
    path.write_text(HEADER + ",temp\n1,0,0.0,,1,2,3,4,5,6,7,8,9,21.5\n"
                    f"1,1,0.008,,1,2,3,4,5,6,7,8,9,{cell}\n")
    db = tmp_path / "d.db"
    with open_store(str(db), create=True):
        pass
    before = db.read_bytes()
    code, out, err = _motecal(capsys, "import", path, "--db", db, "--session", "s")
    assert code == 2 and err.strip().count("\n") == 0, err
    assert f"bad.csv: line 3: {message}" in err and "Traceback" not in err
    assert db.read_bytes() == before


def test_missing_temp_cell_and_a_bad_header(tmp_path, capsys):
    path = tmp_path / "short.csv"
    path.write_text(HEADER + ",temp\n1,0,0.0,,1,2,3,4,5,6,7,8,9\n")
    code, _, err = _motecal(capsys, "import", path, "--db", tmp_path / "d.db", "--session", "s")
    assert code == 2 and "line 2: expected 14 columns, found 13" in err
    assert not (tmp_path / "d.db").exists()
    path.write_text(HEADER + ",temperature\n1,0,0.0,,1,2,3,4,5,6,7,8,9,20\n")
    code, _, err = _motecal(capsys, "import", path, "--db", tmp_path / "d.db", "--session", "s")
    assert code == 2 and "unknown format" in err and len(err.strip().splitlines()) == 1


def _with_temp(src: Path, dst: Path, name: str, values, comment=None):
    """A copy of a measured MPU6050 file with a temperature column added
    (after the accelerometer, where the chip's registers have it)."""
    lines = src.read_text().splitlines()
    head, _, note = lines[0].partition("(")
    cols = [c.strip() for c in head.split(",")]
    cols.insert(4, name)
    out = [",".join(cols) + ("  (" + (comment or note) if note or comment else "")]
    for line, v in zip(lines[1:], values):
        parts = line.split(",")
        parts.insert(4, v)
        out.append(",".join(parts))
    dst.write_text("\n".join(out) + "\n")


def test_mpu6050_log_temperature_column_with_its_unit(tmp_path, capsys):
    from conftest import need_measured
    src = need_measured() / RUN
    n = len((src / "mpu6050_counts.csv").read_text().splitlines()) - 1
    raw_t = np.round(np.linspace(-2000, -1500, n)).astype(int)     # warming from ~30.6 C
    celsius = raw_t / 340.0 + 36.53
    run = tmp_path / "run"
    run.mkdir()
    shutil.copy(src / "hmc5883l_counts.csv", run)
    _with_temp(src / "mpu6050_counts.csv", run / "mpu6050_counts.csv", "temp_raw",
               [str(v) for v in raw_t])
    d = read_timestamped(run)
    mpu = d.has("accel")
    np.testing.assert_allclose(d.temp[mpu], celsius, atol=1e-9)
    assert np.isnan(d.temp[~mpu]).all()
    assert "MPU6050" in d.meta["temp_from"][str(run / "mpu6050_counts.csv")]
    # degrees F and C give the same
    _with_temp(src / "mpu6050_counts.csv", run / "mpu6050_counts.csv", "temp_f",
               [repr(float(c) * 9 / 5 + 32) for c in celsius])
    np.testing.assert_allclose(read_timestamped(run).temp[mpu], celsius, atol=1e-9)
    # into the store: the magnetometer's rows (its own clock) get the board's temperature
    db = tmp_path / "m.db"
    code, out, err = _motecal(capsys, "import", run, "--db", db, "--session", "m")
    assert code == 0, err
    with open_store(str(db)) as st:
        back = st.load_session("m")
    assert np.isfinite(back.temp).all()
    np.testing.assert_allclose(back.temp[mpu], celsius, atol=1e-9)
    lo, hi = celsius.min(), celsius.max()
    assert (back.temp[~mpu] >= lo - 1e-9).all() and (back.temp[~mpu] <= hi + 1e-9).all()


@pytest.mark.parametrize("name, cell, comment, message", [
    ("temp", "25", None, "temperature column 'temp': name its unit (temp_c, temp_f, temp_raw)"),
    ("temp_raw", "-1500", "unknown chip", "temp_raw: no chip with a known temperature sensor"),
    ("temp_c", "warm", None, "line 2: temp_c is not a number: 'warm'"),
    ("temp_c", "inf", None, "line 2: temp_c is not a finite number: 'inf'"),
    ("temp_c", "", None, None),                     # empty: unknown, accepted
])
def test_hostile_timestamped_temperature(tmp_path, capsys, name, cell, comment, message):
    path = tmp_path / ("log_counts.csv" if comment else "mpu6050_counts.csv")
    path.write_text(f"t_s,acc_x,acc_y,acc_z,{name},gyr_x,gyr_y,gyr_z"
                    + (f"  ({comment})" if comment else "") + "\n"
                    + "".join(f"{i / 100},1,2,3,{cell},4,5,6\n" for i in range(300)))
    code, out, err = _motecal(capsys, "import", path, "--db", tmp_path / "d.db", "--session", "s")
    if message is None:
        assert code == 0, err
        with open_store(str(tmp_path / "d.db")) as st:
            assert st.load_session("s").temp is None        # no reading at all
        return
    assert code == 2 and len(err.strip().splitlines()) == 1 and message in err, err
    assert "Traceback" not in err and not (tmp_path / "d.db").exists()


def test_temp_raw_conversions_are_the_datasheets():
    f, o = TEMP_RAW_C["MPU6050"]
    assert -521 * f + o == pytest.approx(35.0, abs=0.01)        # MPU-6000/6050 register map
    f, o = TEMP_RAW_C["ITG3200"]
    assert -13200 * f + o == pytest.approx(35.0) and 280 * f == pytest.approx(1.0)
