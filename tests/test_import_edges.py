"""Issue 28 (items 2, 3, 5 and 8), issue 31: nothing silently wrong at the
import's edges.

* every given or inferred scale, rate, gravity and angle lies in its physical
  range (``sessions.ranges``) or the import stops with one line, exit 2, the
  database unchanged;
* a scale inferred from a float log is robust to a few absurd lines (they are
  left out and named, not used) and to a few values off the grid;
* imports stream in bounded chunks (the same result, and the same first bad
  line, whatever the chunk size), refuse zero bytes at once, and what import
  stores, motecal's own export writes and import reads back;
* MotionCal ``Raw:`` lines behind a log prefix are read, as MotionCal does.
"""
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from clirun import digest, make_db, motecal
from motecal.errors import UserError
from motecal.sessions import cells, chips, floatlog, floatsession, foreign, projectcsv
from motecal.sessions import ranges as R
from motecal.sessions.imported import check_imported
from motecal.sessions.importer import read_csv
from motecal.sessions.session import SessionData
from motecal.sessions.store import open_store

REPO = Path(__file__).resolve().parent.parent
G0 = 9.80665
LSB = 2048.0                       # FreeIMU-cal's accelerometer: 9.80665 / 2048 m/s^2 steps


def freeimu_acc(n=600, seed=1) -> np.ndarray:
    """Integer counts of a board held still (1 g on z), at 2048 LSB/g."""
    rng = np.random.default_rng(seed)
    return np.rint(np.array([30.0, -50.0, LSB]) + rng.normal(0, 3, (n, 3)))


def write_lines(path, counts, extra=(), at=None) -> Path:
    """A float log in m/s^2 of ``counts`` (6 decimals, FreeIMU's print), with
    ``extra`` lines put in after line ``at`` (default: at the end)."""
    lines = [" ".join(f"{v:.6f}" for v in row * G0 / LSB) for row in counts]
    at = len(lines) if at is None else at
    lines[at:at] = list(extra)
    path.write_text("\n".join(lines) + "\n")
    return path


def one_line_error(rc, err, *words):
    assert rc == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    for w in words:
        assert w in err, (w, err)


def stored(db, name):
    with open_store(str(db)) as st:
        return st.load_session(name)


# ---------------------------------------------------------------- item 2: absurd lines

@pytest.mark.parametrize("glitch", ["1e20 0.1 9.8", "1e39 0.1 9.8"])
def test_absurd_line_is_left_out_and_named_not_used_for_the_scale(tmp_path, glitch):
    counts = freeimu_acc()
    log = write_lines(tmp_path / "still_acc.txt", counts, [glitch], at=300)
    db = tmp_path / "d.db"
    rc, out, err = motecal("import", log, "--db", db, "--session", "s", "--rate-hz", 100)
    assert rc == 0, err
    assert "at 2048 LSB/g (file step)" in out and "line 301" in out
    d = stored(db, "s")
    assert d.scales["accel"] == pytest.approx(LSB, rel=1e-6)
    np.testing.assert_array_equal(d.sensor("accel"), counts)          # not 0: the counts
    assert "1 line with a reading no chip gives left out" in d.meta["notes"]
    # the left-out line keeps its row: the rows after it keep their times
    assert d.seq[300] == 301 and d.t[300] == pytest.approx(3.01)


def test_many_absurd_lines_stop_the_import(tmp_path):
    counts = freeimu_acc(200)
    log = write_lines(tmp_path / "x_acc.txt", counts, ["1e20 0 0"] * 5, at=10)
    db = make_db(tmp_path / "d.db")
    before = digest(db)
    rc, out, err = motecal("import", log, "--db", db, "--session", "s")
    one_line_error(rc, err, "x_acc.txt: line 11:", "beyond any accelerometer's",
                   "5 of the 205 lines")
    assert digest(db) == before


def test_values_off_the_grid_do_not_move_the_inferred_step():
    q = G0 / LSB
    v = freeimu_acc(2000) * q
    v[[5, 700, 1500]] = [[9.80001, 0.1, 9.8], [0.333, 0.2, 9.7], [1.0, 2.0, 3.0]]
    assert floatlog.file_step(v) == pytest.approx(q, rel=1e-9)
    # many of them: no common step (no scale is made up)
    rng = np.random.default_rng(3)
    assert floatlog.file_step(v + rng.uniform(0, q, v.shape) * (rng.random(v.shape) < 0.2)) \
        is None


# ---------------------------------------------------------------- items 2, 8: options in range

def _float_log(tmp_path, name="still_acc.txt"):
    return write_lines(tmp_path / name, freeimu_acc(300))


OPTION_CASES = [
    # (options, words of the one line)
    (["--scale", "gyro=1e-300", "--columns", "gyro"], ["--scale gyro=1e-300", "0.5..4096"]),
    (["--scale", "accel=1e9"], ["--scale accel=1e9", "1..32767 LSB/g"]),
    (["--chip", "accel=mine:0.001"], ["--chip accel=mine:0.001", "LSB/g"]),
    (["--gravity", "-9.81"], ["--gravity", "9.5..10 m/s^2"]),
    (["--gravity", "0"], ["--gravity", "9.5..10"]),
    (["--rate-hz", "1e-300"], ["--rate-hz", "0.01..100000 Hz"]),
    (["--rate-hz", "1e300"], ["--rate-hz", "0.01..100000 Hz"]),
    (["--angle-deg", "nan"], ["--angle-deg", "10..3600"]),
    (["--angle-deg", "6.28"], ["--angle-deg", "10..3600"]),
    (["--rpm", "1e300"], ["--rpm", "1..4000 deg/s"]),
    (["--rate-dps", "0.001"], ["--rate-dps", "1..4000 deg/s"]),
    (["--columns", "accel,acc"], ["--columns accel,acc: a sensor named twice"]),
]


@pytest.mark.parametrize("opts,words", OPTION_CASES, ids=[" ".join(c[0]) for c in OPTION_CASES])
def test_options_out_of_their_range_are_one_line(tmp_path, opts, words):
    log = _float_log(tmp_path)
    db = make_db(tmp_path / "d.db")
    before = digest(db)
    rc, out, err = motecal("import", log, "--db", db, "--session", "s", *opts)
    one_line_error(rc, err, *words)
    assert digest(db) == before


def test_inferred_scale_out_of_range_is_one_line(tmp_path):
    """A file printed at 1e-4 m/s^2 with no sensor's step: the 'step' would be
    1e5 LSB/g; one line asking for the scale instead of storing rubbish."""
    rng = np.random.default_rng(5)
    v = np.array([0, 0, G0]) + rng.normal(0, 0.05, (600, 3))
    log = tmp_path / "fine_acc.txt"
    np.savetxt(log, v, fmt="%.4f")
    rc, out, err = motecal("import", log, "--db", tmp_path / "d.db", "--session", "s")
    one_line_error(rc, err, "fine_acc.txt: accel:", "file's step", "--scale accel=LSB")


def test_rate_from_a_files_times_in_range(tmp_path):
    data = read_csv(_csv(tmp_path / "a.csv", t_scale=1.0))
    assert data.meta["rate_hz"] == pytest.approx(125.0)
    with pytest.raises(UserError, match="the rate its times give.*is t in seconds"):
        read_csv(_csv(tmp_path / "b.csv", t_scale=1e-7))      # t in 0.1 us: 1.25 GHz


def _csv(path, n=300, t_scale=1.0, seq0=0) -> Path:
    rng = np.random.default_rng(0)
    lines = ["mote,seq,t,label,ax,ay,az,gx,gy,gz,mx,my,mz"]
    for i in range(n):
        vals = rng.integers(-300, 300, 9)
        lines.append(f"1,{seq0 + i},{i / 125 * t_scale:.9g},," + ",".join(map(str, vals)))
    path.write_text("\n".join(lines) + "\n")
    return path


def test_imucal_sample_numbers_beyond_2_53_are_refused(tmp_path):
    head = "part,samples,acc_x,acc_y,acc_z,gyr_x,gyr_y,gyr_z"
    for cell, words in (("9007199254740993", ["samples out of range"]),
                        ("1e300", ["samples out of range"]),
                        ("inf", ["samples is not a finite number"]),
                        ("1.5", ["samples is not a whole number"])):
        f = tmp_path / "ann.csv"
        f.write_text(f"{head}\nx_p,{cell},1,2,3,4,5,6\n")
        rc, out, err = motecal("import", f, "--db", tmp_path / "d.db", "--session", "s",
                               "--rate-hz", 100, "--scale", "accel=2048,gyro=16.4")
        one_line_error(rc, err, "ann.csv: line 2:", *words)
    # sample numbers far apart at a slow rate: t beyond 1e10 s
    f.write_text(f"{head}\n" + "\n".join(f"{p},{k},1,2,3,4,5,6" for k, p in
                                         enumerate(["x_p", "x_a", "y_p", "y_a", "z_p"]))
                 + "\nz_a,9007199254740000,1,2,3,4,5,6\n")
    rc, out, err = motecal("import", f, "--db", tmp_path / "d.db", "--session", "s",
                           "--rate-hz", 100, "--scale", "accel=2048,gyro=16.4")
    one_line_error(rc, err, "line 7", "beyond 1e+10 s")


def test_what_import_stores_export_writes_and_import_reads_back(tmp_path):
    """Every format's session goes out through motecal export and back in
    with the same rows (the values, times and sequence numbers that were
    refused before: issue 28's 'export then refuses to re-import')."""
    log = write_lines(tmp_path / "rt_acc.txt", freeimu_acc(400), ["1e20 0 0"], at=50)
    db = tmp_path / "d.db"
    assert motecal("import", log, "--db", db, "--session", "f", "--rate-hz", 0.01)[0] == 0
    out = tmp_path / "f.csv"
    rc, _, err = motecal("export", "--db", db, "--session", "f", "--csv", out)
    assert rc == 0, err
    rc, _, err = motecal("import", out, "--db", db, "--session", "back")
    assert rc == 0, err
    a, b = stored(db, "f"), stored(db, "back")
    np.testing.assert_array_equal(a.raw, b.raw)
    np.testing.assert_array_equal(a.seq, b.seq)
    np.testing.assert_allclose(a.t, b.t, atol=1e-6)


def test_nan_in_metadata_or_times_never_reaches_the_store():
    d = SessionData(
        "x", np.zeros((3, 9)), np.ones(3, np.int64), np.arange(3), np.arange(3.0),
        np.zeros(3, np.int32), np.zeros(3, np.uint8), meta={"source": "f.csv",
                                                            "rotations": [{"angle_deg": np.nan}]})
    with pytest.raises(UserError, match=r"f.csv: meta\['rotations'\]\[0\]\['angle_deg'\] is not"):
        check_imported(d)
    d.meta = {"source": "f.csv"}
    d.t = np.array([0.0, 1.0, 1e300])
    with pytest.raises(UserError, match="row 3: t = 1e\\+300 s is beyond"):
        check_imported(d)


# ---------------------------------------------------------------- item 3: streaming, zeros

def test_zero_bytes_are_refused_at_once_with_bounded_memory(tmp_path):
    """120 MB of zero bytes (a sparse file) is not a Razor magnetometer log:
    refused at the first block, in a child whose peak memory is printed."""
    z = tmp_path / "zeros.bin"
    with open(z, "wb") as f:
        f.truncate(120_000_000)
    db = make_db(tmp_path / "d.db")
    before = digest(db)
    code = ("import resource, sys; from motecal.commands.main import main; "
            f"rc = main(['import', {str(z)!r}, '--db', {db!r}, '--session', 'z']); "
            "print(rc, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, file=sys.stdout)")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    rc, peak_kb = map(int, res.stdout.split())
    one_line_error(rc, res.stderr, "zeros.bin: sample 1 (byte 0): 25 mag samples of exactly 0")
    print(f"zero bytes: refused, peak {peak_kb / 1024:.0f} MB")
    assert peak_kb < 400_000                     # the whole file would be 1.4 GB as floats
    assert digest(db) == before


def test_zero_runs_in_text_logs(tmp_path):
    counts = freeimu_acc(300)
    counts[100:130] = 0
    log = write_lines(tmp_path / "z_acc.txt", counts)
    rc, out, err = motecal("import", log, "--db", tmp_path / "d.db", "--session", "s")
    one_line_error(rc, err, "z_acc.txt: line 101: 25 accel samples of exactly 0, 0, 0")
    # a gyroscope may read zero: its log is not refused for it
    gyr = tmp_path / "still_gyr.txt"
    g = np.zeros((300, 3))
    g[::7] = [0.00122173, 0, -0.00122173]
    np.savetxt(gyr, g, fmt="%.8f")
    assert motecal("import", gyr, "--db", tmp_path / "d.db", "--session", "g")[0] == 0


def test_text_chunks_split_lines_as_the_whole_file(tmp_path):
    rng = np.random.default_rng(7)
    alphabet = ["a", "1,2", "\n", "\r\n", "\r", "é", "  ", "\u2028", "\x0b", "\ufeff"]
    for trial in range(150):
        s = "".join(rng.choice(alphabet) for _ in range(rng.integers(0, 50)))
        if trial % 5 == 0:
            s = "\ufeff" + s
        p = tmp_path / "t.txt"
        p.write_bytes(s.encode())
        want = p.read_bytes().decode("utf-8-sig").splitlines()
        for block in (1, 2, 5, 64):
            got = list(cells.numbered_lines(p, block))
            assert [ln for _, ln in got] == want and [k for k, _ in got] == \
                list(range(1, len(want) + 1)), (s, block)


@pytest.fixture
def small_chunks(monkeypatch):
    """Chunks of a few hundred bytes and rows: every reader crosses many."""
    monkeypatch.setattr(cells, "BLOCK_BYTES", 300)
    monkeypatch.setattr(cells, "CHUNK_ROWS", 7)
    monkeypatch.setattr(projectcsv, "CHUNK_ROWS", 7)
    monkeypatch.setattr(cells.text_chunks, "__defaults__", (300,))
    monkeypatch.setattr(cells.numbered_lines, "__defaults__", (300,))


def test_streamed_readers_give_the_whole_file_result(tmp_path, monkeypatch, small_chunks):
    csv_path = _csv(tmp_path / "s.csv", n=250)
    log = write_lines(tmp_path / "s_acc.txt", freeimu_acc(250), ["1e20 0 0"], at=120)
    small_csv, small_log = read_csv(csv_path), floatsession.read_float_log(log)
    monkeypatch.undo()
    whole_csv, whole_log = read_csv(csv_path), floatsession.read_float_log(log)
    for a, b in ((small_csv, whole_csv), (small_log, whole_log)):
        np.testing.assert_array_equal(a.raw, b.raw)
        np.testing.assert_array_equal(a.seq, b.seq)
        np.testing.assert_array_equal(a.label, b.label)
        assert a.meta == b.meta


@pytest.mark.parametrize("line,words", [
    ("1,240,1.92,,1,2,3,4,5,6,7,8,x", "line 242: mz is not a number: 'x'"),
    ("1,240,1.92,,1,2,3", "line 242: expected 13 columns, found 7"),
    ("1,240,1.92,,1,2,3,4,5,6,7,8,40000", "line 242: mz = 40000 is outside"),
    ('1,240,1.92,"rot",1,2,3,4,5,6,7,8,nan', "line 242: mz is not a finite number: 'nan'"),
])
def test_streamed_csv_names_the_same_line(tmp_path, small_chunks, line, words):
    p = _csv(tmp_path / "bad.csv", n=240)
    p.write_text(p.read_text() + line + "\n" + "1,241,1.93,,1,2,3,4,5,6,7,8,9\n")
    with pytest.raises(UserError) as e:
        read_csv(p)
    assert str(e.value).startswith(f"{p}: {words}"), str(e.value)


def test_fast_csv_block_agrees_with_the_cell_by_cell_reader():
    """projectcsv._fast_block converts a chunk at once; whatever it accepts,
    the cell-by-cell reader accepts with the same values, and whatever that
    refuses, the fast one passes to it (returns None)."""
    rng = np.random.default_rng(11)
    cells_pool = ["1", "0", "-3", "32768", "-32768", "40000", "1.5", "", " ", "nan", "inf",
                  "1e3", "1_0", "+7", "x", "rot", "7", "70000", "-1", "2e-3", " 12 ", "0x10"]
    for trial in range(400):
        n = int(rng.integers(1, 6))
        block = []
        for _ in range(n):
            row = [str(rng.integers(0, 4)), str(rng.integers(0, 1000)), "0.5", ""] + \
                  [str(rng.integers(-100, 100)) for _ in range(9)]
            for _ in range(int(rng.integers(0, 3))):
                row[int(rng.integers(0, 13))] = cells_pool[int(rng.integers(len(cells_pool)))]
            block.append(row)
        where = list(range(2, 2 + n))
        fast = projectcsv._fast_block(block, 13, False)
        try:
            slow = [projectcsv._csv_row("f", r, k, 13, False) for r, k in zip(block, where)]
        except UserError:
            assert fast is None, block
            continue
        if fast is None:
            continue
        ints = np.array([s[0] for s in slow])
        nums = np.array([s[1] for s in slow])
        np.testing.assert_array_equal(fast[0][:, :3], ints[:, :3])
        np.testing.assert_array_equal(fast[1], nums)


# ---------------------------------------------------------------- item 5: MotionCal prefix

def test_motioncal_raw_lines_behind_a_log_prefix(tmp_path):
    rng = np.random.default_rng(4)
    raw = np.column_stack([rng.integers(-8200, 8200, (300, 3)), rng.integers(-50, 50, (300, 3)),
                           rng.integers(-600, 600, (300, 3))])
    lines = ["ets Jun  8 2016 00:22:57", "I (31) boot: ESP-IDF v5.1 2nd stage bootloader"]
    lines += [f"I ({100 + 10 * i}) imu: Raw:" + ",".join(map(str, r)) for i, r in enumerate(raw)]
    lines.insert(150, "W (1600) wifi: no AP found")
    log = tmp_path / "esp32.log"
    log.write_text("\n".join(lines) + "\n")
    db = tmp_path / "d.db"
    rc, out, err = motecal("import", log, "--db", db, "--session", "m", "--rate-hz", 100)
    assert rc == 0, err
    d = stored(db, "m")
    assert d.meta["format"] == "motioncal" and "3 non-Raw lines skipped" in d.meta["notes"]
    np.testing.assert_array_equal(d.raw, raw)
    # a prefixed line with a bad value still names its line
    log.write_text("\n".join(lines[:10] + ["I (5) imu: Raw:1,2,x,4,5,6,7,8,9"]) + "\n")
    with pytest.raises(UserError, match="esp32.log: line 11: value 3 is not an integer count"):
        foreign.read_motioncal(log)


# ---------------------------------------------------------------- the ranges, one table

def test_known_chips_and_formats_lie_in_the_ranges():
    for sensor, table in chips.CHIP_SCALES.items():
        for chip, scale in table.items():
            assert R.SCALE[sensor].holds(scale), (sensor, chip, scale)
    for sensor, scale in foreign.MOTIONCAL_SCALES.items():
        assert R.SCALE[sensor].holds(scale)
    for g in (9.80665, 9.81, 9.8, 9.7803, 9.8322):
        assert R.GRAVITY.holds(g)
    for hz in (0.75, 50, 99.4, 125, 204.8, 3200, 8000):
        assert R.RATE_HZ.holds(hz)


def test_ranges_are_printed_in_help_and_docs(tmp_path):
    rc, out, err = motecal("import", "--help")
    doc = (REPO / "docs" / "import.md").read_text()
    for what, rng, why in R.tables():
        assert rng in out, rng
        assert rng in doc, f"docs/import.md lacks the range {rng} ({what})"
    assert json.dumps(R.ZERO_RUN) in doc


def test_motioncal_is_not_a_comment_that_says_raw(tmp_path):
    p = tmp_path / "c.csv"
    p.write_text("# Raw: data of mote 1\nmote,seq,t,label,ax,ay,az,gx,gy,gz,mx,my,mz\n"
                 "1,0,0,,1,2,3,4,5,6,7,8,9\n")
    assert foreign.detect(p) is None                    # the project CSV's reader takes it
    assert foreign.detect_text(["I (5) imu: Raw:1,2,3,4,5,6,7,8,9"]) == "motioncal"


def test_timestamped_run_with_absurd_times_keeps_memory_bounded(tmp_path):
    """A run whose last rows sit 1e9 s after the others: the stillness grid
    is built per stretch between pauses (it asked for 1.46 TiB before)."""
    run = tmp_path / "run"
    run.mkdir()
    mag = ["t_s,mag_x,mag_y,mag_z  (HMC5883L)"] + \
        [f"{i / 77:.4f},{100 + i % 3},200,{300 - i % 2}" for i in range(200)] + ["1e9,100,200,300"]
    mpu = ["t_s,acc_x,acc_y,acc_z,gyr_x,gyr_y,gyr_z  (MPU6050)"] + \
        [f"{i / 99:.4f},{i % 3},0,16384,1,2,{i % 2}" for i in range(260)] + ["2e9,0,0,16384,1,2,3"]
    (run / "hmc5883l_counts.csv").write_text("\n".join(mag) + "\n")
    (run / "mpu6050_counts.csv").write_text("\n".join(mpu) + "\n")
    db = tmp_path / "d.db"
    rc, out, err = motecal("import", run, "--db", db, "--session", "r")
    assert rc == 0, err
    d = stored(db, "r")
    assert len(d) == 462 and d.t.max() == 2e9


def test_out_of_memory_is_one_line_and_stores_nothing(tmp_path, monkeypatch):
    """A recording too long for the machine (a 204 MB float log of plausible
    counts under a 4 GB limit ran out of memory in the labelling): one line,
    exit 1, the database as it was."""
    from motecal.sessions import labelling

    def no_memory(*a, **k):
        raise MemoryError("Unable to allocate 389. MiB")
    monkeypatch.setattr(labelling, "assign_labels", no_memory)
    log = write_lines(tmp_path / "m_acc.txt", freeimu_acc(300))
    db = make_db(tmp_path / "d.db")
    before = digest(db)
    rc, out, err = motecal("import", log, "--db", db, "--session", "s")
    assert rc == 1 and err.count("\n") == 1 and "out of memory" in err, err
    assert digest(db) == before
