"""Issue 15: every command under hostile command lines (hypothesis).

For each of the ten commands, argument lists are drawn from pools of hostile and valid
values: paths that are the database, a foreign sqlite file, a FIFO, a folder,
a symlink to the database, '-', garbage, missing files; numbers that are
huge, negative, NaN, infinite, text; names that are empty or blank.  Each
run must: exit 0 or 2 (3 for calibrate's quality refusal), never raise (a
traceback), say a failure in one line, leave the databases byte-identical
unless the command writes to them (and then consistent), and touch no file
outside the outputs it names.  Hypothesis keeps no database of examples
(``database=None``): nothing is written outside the temporary folders.
"""
import json
import os
import sqlite3
import tempfile
from pathlib import Path

from hypothesis import HealthCheck, given, settings, strategies as st

from clirun import digest, make_db, motecal, session, snapshot
from motecal.sessions import importer
from motecal.targets import FORMATS as TARGET_FORMATS
from test_logger_streams import sample_frames

import numpy as np

NUMBERS = ["0", "-1", "1", "2", "nan", "inf", "-inf", "1e308", "-1e308", "1e-320",
           "99999999999999999999", "0x10", "1.5", "", " ", "x", "é", "--", "-"]
NAMES = ["board", "tiny", "nope", "", " ", "\t", "x" * 300, "rot", "a'b\"c", "-"]


_REAL_CAL = []


def real_cal() -> str:
    """A whole cal.json (motecal calibrate of a simulated board), made once."""
    if not _REAL_CAL:
        from motecal.calib.board import calibrate_board
        from synthetic import paper_sized_session
        data = paper_sized_session(3, mote=1, rotation=False, n_poses=30, per_pose=100)
        _REAL_CAL.append(calibrate_board(data, seed=1, kfold=0).dumps())
    return _REAL_CAL[0]


class Files:
    """The temporary folder of one run: a database with sessions 'board' and
    'tiny', a foreign sqlite file, a FIFO, a folder, a symlink to the
    database, garbage, a CSV, a recording, a cal.json and a bad one."""

    def __init__(self, root: Path):
        self.root = root
        self.db = make_db(root / "m.db", "board")
        from motecal.sessions.store import open_store
        with open_store(self.db) as st_:
            st_.save_session(session("tiny", n=3))
        con = sqlite3.connect(root / "foreign.db")
        con.execute("CREATE TABLE schema_version (version TEXT)")
        con.execute("INSERT INTO schema_version VALUES ('1')")
        con.commit()
        con.close()
        os.mkfifo(root / "fifo")
        (root / "folder").mkdir()
        os.symlink("m.db", root / "link.db")
        (root / "garbage.bin").write_bytes(bytes(range(256)) * 8)
        (root / "empty").write_bytes(b"")
        importer.write_csv(session("c", n=60), root / "in.csv")
        rng = np.random.default_rng(0)
        frames, _ = sample_frames({1: rng.integers(-999, 999, (50, 9)).astype(np.int16)})
        (root / "rec.bin").write_bytes(b"".join(frames))
        cal = {"format_version": 1, "mote": 1,
               "accel": {"A": (np.eye(3) / 256).tolist(), "c": [0.0, 0.0, 0.0]}}
        (root / "cal.json").write_text(json.dumps(cal))
        cal["accel"]["c"] = ["0", None, 1]
        (root / "badcal.json").write_text(json.dumps(cal))
        (root / "full.json").write_text(real_cal())
        (root / "float.log").write_text("0.01 -0.02 9.81\n" * 60)      # other tools' shapes
        (root / "raw.txt").write_text("Raw:10,-20,2048,1,2,3,100,200,-300\n" * 60)

    def inputs(self):
        r = str(self.root)
        return [self.db, f"{r}/foreign.db", f"{r}/fifo", f"{r}/folder", f"{r}/link.db",
                f"{r}/garbage.bin", f"{r}/empty", f"{r}/in.csv", f"{r}/rec.bin",
                f"{r}/cal.json", f"{r}/badcal.json", f"{r}/missing", "-", "", f"{r}/m.db-wal",
                f"{r}/float.log", f"{r}/raw.txt", f"{r}/full.json"]

    def outputs(self):
        r = str(self.root)
        return [f"{r}/out/o.x", f"{r}/out/o.json", f"{r}/out/dir", "-", self.db,
                f"{r}/link.db", f"{r}/fifo", f"{r}/folder", f"{r}/in.csv", f"{r}/nodir/o",
                f"{r}/m.db-wal", ""]


# per command: (positional pool or None, required options, optional options);
# a pool entry is a list of values or a key: "in" (input paths), "out"
# (output paths), "db" (databases), "num", "name"
COMMANDS = {
    "sessions": (None, {"--db": "db"}, {"--json": None}),
    "export": (None, {"--db": "db", "--session": "name", "--csv": "out"}, {"--mote": "num"}),
    "import": ("in", {"--db": "db", "--session": "name"},
               {"--format": ["auto", "csv", "razor-text", "razor-float", "timestamped-csv",
                             "imucal-annotated", "imucal-session", "float-log", "motioncal",
                             "x"],
                "--chip": ["mag=hmc5843", "mag=name:0", "mag=name:nan", "x", "accel=", "=1"],
                "--kind": ["auto", "static", "rotation", "idle", "x"], "--replace": None,
                "--units": ["si", "counts", "gyro=deg/s", "x", "gyro="],
                "--scale": ["accel=256", "accel=nan", "accel=0", "x"],
                "--gravity": "num", "--rate-hz": "num", "--rate-dps": "num", "--rpm": "num",
                "--columns": ["gyro", "accel,gyro", "x", ""], "--angle-deg": "num"}),
    "calibrate": (None, {"--db": "db", "--session": "name", "--out": "out"},
                  {"--mote": "num", "--model": ["paper", "full", "x"],
                   "--params": ["offsets", "scales,angles", "x", ""], "--seed": "num",
                   "--mag-field": "num", "--kfold": "num", "--no-gyro-matrix": None,
                   "--force": None}),
    "diagnose": (None, {"--db": "db", "--session": "name", "--no-sim": None},
                 {"--mote": "num", "--json": "out", "--model-out": "out", "--alpha": "num",
                  "--seed": "num"}),
    "report": (None, {"--db": "db", "--session": "name", "--out": "out", "-q": None},
               {"--mote": "num", "--cal": "in", "--seed": "num"}),
    "sim": (None, {"--out": "out", "--duration": ["0.05", "0", "-1", "nan", "1e308", "x", ""],
                   "--quiet": None},
            {"--motes": ["1", "2", "0", "-1", "1001", "nan", "x"],
             "--session": ["static80", "idle", "rotation,idle", "x", "", ","],
             "--seed": "num", "--baud": ["250000", "57600", "iris", "0", "-1", "x", "1e9"],
             "--loss": "num", "--batch": "num", "--model": "in", "--truth": "out"}),
    "log": (None, {"--port": ["{r}/rec.bin", "{r}/empty", "{r}/garbage.bin", "{r}/missing",
                              "{r}/folder", "socket://127.0.0.1:1", "x://y", ""],
                   "--db": "db", "--session": "name"},
            {"--append": None, "--duration": "num",
             "--guided": ["static80", "rotation", "x"], "--yes": None, "--mote": "num",
             "--kind": ["free", "idle", "x"], "--board": ["1=B7", "x", "0=", "=B"],
             "--poses": "num", "--pose-samples": "num", "--min-angle": "num",
             "--rot-samples": "num", "--coverage": "num", "--lock-timeout": "num",
             "--baud": ["250000", "0", "x"]}),
    "export-cal": ("in", {"--to": list(TARGET_FORMATS) + ["x"]},     # from the registry
                   {"--out": "out", "--db": "db", "--session": "name",
                    "--axes": ["chip", "razor", "x"], "--orientation": ["2", "YAW_90", "38", "x"]}),
    "upload": ("in", {"--dry-run": None},
               {"--mote": "num", "--version": "num", "--timeout": "num", "--retries": "num",
                "--force": None}),
}
WRITES_DB = {"import", "calibrate", "log"}
# exit 3 (QualityError): a calibration the gate refuses, a set the mote cannot hold,
# a session with no data for any of the report's tables
OK = {"calibrate": (0, 2, 3), "upload": (0, 2, 3), "report": (0, 2, 3)}
# the index of a valid input / output per command (Files.inputs / Files.outputs)
IN_GOOD = {"import": 7, "report": 17, "upload": 17, "sim": 11, "export-cal": 17}
OUT_GOOD = {"export": 0, "calibrate": 1, "diagnose": 1, "report": 2, "sim": 0,
            "export-cal": 0}


@st.composite
def command_lines(draw, cmd):
    """(argv template, names of output options used) for one command."""
    positional, required, optional = COMMANDS[cmd]

    def either(good, bad):          # the valid value half the time: runs get far
        return good if draw(st.booleans()) else bad

    def value(pool):
        if isinstance(pool, list):
            return either(pool[0], draw(st.sampled_from(pool)))
        return {"num": lambda: either("1", draw(st.sampled_from(NUMBERS))),
                "name": lambda: either("board", draw(st.sampled_from(NAMES))),
                "db": lambda: ("@in", either(0, draw(st.integers(0, 17)))),
                "in": lambda: ("@in", either(IN_GOOD[cmd], draw(st.integers(0, 17)))),
                "out": lambda: ("@out", either(OUT_GOOD[cmd], draw(st.integers(0, 11))))}[pool]()

    argv = [cmd]
    if positional:
        argv.append(value(positional))
    chosen = dict(required)
    for opt in draw(st.lists(st.sampled_from(sorted(optional)), unique=True, max_size=4)):
        chosen[opt] = optional[opt]
    for opt, pool in chosen.items():
        if draw(st.integers(0, 19)) == 0 and opt in required:
            continue                                     # a required option left out
        argv.append(opt)
        if pool is not None:
            argv.append(value(pool))
    return argv


def run_one(cmd, template):
    with tempfile.TemporaryDirectory(prefix="motecal-fuzz-") as tmp:
        root = Path(tmp)
        files = Files(root)
        (root / "out").mkdir()
        ins, outs = files.inputs(), files.outputs()
        argv, named = [], set()
        for a in template:
            if isinstance(a, tuple):
                a = (ins if a[0] == "@in" else outs)[a[1]]
                named.add(a)
            argv.append(a.replace("{r}", tmp) if isinstance(a, str) else a)
        before = snapshot(root)
        db_before = digest(files.db)
        cwd = os.getcwd()
        os.chdir(root)                   # relative names ('-' as a folder...) land here
        try:
            rc, out, err = motecal(*argv)
        finally:
            os.chdir(cwd)
        where = f"motecal {' '.join(map(repr, argv))}"
        assert rc in OK.get(cmd, (0, 2)), f"{where}: exit {rc}: {err}"
        assert "Traceback" not in err, where
        if rc:
            assert err.count("\n") == 1 and err.endswith("\n"), f"{where}: {err!r}"
        writes_db = (cmd in WRITES_DB and rc == 0 or cmd == "calibrate"
                     # diagnose keeps its result with the session unless --no-keep
                     or cmd == "diagnose" and rc == 0 and "--no-keep" not in argv)
        if not writes_db:
            assert digest(files.db) == db_before, f"{where}: the database changed"
        else:
            con = sqlite3.connect(files.db)
            assert con.execute("PRAGMA integrity_check").fetchone()[0] == "ok", where
            con.close()
        after = snapshot(root)
        allowed = {os.path.relpath(os.path.realpath(p), tmp) for p in named if p}
        if writes_db:
            allowed |= {"m.db", "m.db-wal", "m.db-shm", "m.db-journal"}
        for name in set(before) | set(after):
            if before.get(name) == after.get(name):
                continue
            top = name.split(os.sep)
            ok = any(name == a or name.startswith(a.rstrip(os.sep) + os.sep) for a in allowed)
            # sessions created as the named output's folder; outputs' own dir
            ok = ok or (top[0] == "out" and any(a.startswith("out") for a in allowed))
            if not ok and cmd in ("import", "log") and name in ("m.db", "link.db") and rc == 0:
                ok = True
            assert ok, f"{where}: touched {name}"


FUZZ = settings(max_examples=12, deadline=None, database=None, derandomize=False,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])


def _test(cmd, examples=12):
    @settings(FUZZ, max_examples=examples)
    @given(command_lines(cmd))
    def test(template):
        run_one(cmd, template)
    test.__name__ = f"test_fuzz_{cmd}"
    return test


test_fuzz_sessions = _test("sessions", 15)
test_fuzz_export = _test("export", 15)
test_fuzz_import = _test("import", 15)
test_fuzz_calibrate = _test("calibrate", 12)
test_fuzz_diagnose = _test("diagnose", 6)
test_fuzz_report = _test("report", 3)
test_fuzz_sim = _test("sim", 10)
test_fuzz_log = _test("log", 15)
test_fuzz_upload = _test("upload", 15)
test_fuzz_export_cal = _test("export-cal", 12)


# ---------------------------------------------------------------- imports: options and float logs
# (issue 28: tracebacks 0 and silent corruptions 0 over import options and float logs)

import math                                                    # noqa: E402

import interop_data as D                                        # noqa: E402
from motecal.sessions import floatlog as FL                     # noqa: E402
from motecal.sessions import ranges as RG                       # noqa: E402

G_STD = 9.80665
# each sensor's file: its name, its LSB per unit, its unit, the value of one count in it
FLOAT_FILES = {"accel": ("fz_acc.txt", 2048.0, "m/s^2", G_STD / 2048),
               "gyro": ("fz_gyr.txt", 1 / 0.07, "rad/s", math.radians(0.07)),
               "mag": ("fz_mag.txt", 1090.0, "uT", 100 / 1090)}
OPTION_VALUES = {
    "--scale": ["accel=2048", "gyro=14.2857", "mag=1090", "accel=1e-300", "gyro=1e-300",
                "mag=1e9", "accel=0.5", "accel=1", "accel=32767", "accel=32768", "gyro=4096",
                "gyro=4097", "mag=50", "mag=49", "accel=nan", "accel=-3", "x"],
    "--gravity": ["9.80665", "9.81", "9.5", "10", "10.01", "9.49", "-9.81", "0", "nan", "inf",
                  "1e300", "x", ""],
    "--rate-hz": ["100", "0.01", "0.0099", "100000", "100001", "1e-300", "1e300", "nan", "-1",
                  "0", "x"],
    "--angle-deg": ["360", "-360", "10", "9.99", "3600", "3601", "6.28", "nan", "inf", "x"],
    "--rpm": ["33.333", "45", "33.333,45", "0.1", "1e300", "nan", "x"],
    "--rate-dps": ["200", "1", "0.99", "4000", "4001", "nan"],
    "--units": ["si", "accel=g", "accel=m/s^2", "gyro=deg/s", "mag=ut", "mag=gauss", "counts",
                "x"],
    "--chip": ["accel=mine:2048", "accel=mine:1e-300", "gyro=mpu6050", "mag=hmc5843",
               "accel=mine:nan", "mag=mine:40"],
    "--columns": ["accel", "gyro", "mag", "accel,gyro", "x"],
}


def _counts(sensor, n, rng):
    """Integer counts a still-then-turning board gives at the file's LSB."""
    lsb = FLOAT_FILES[sensor][1]
    base = {"accel": [0, 0, 2048], "gyro": [3, -2, 1], "mag": [200, -150, 400]}[sensor]
    c = np.array(base, float) + rng.normal(0, 3, (n, 3))
    c[n // 2:] += rng.normal(0, 0.1 * lsb, 3)                   # a second pose
    return np.rint(c)


def _check_stored(db, name, values, units_given, tmp):
    """An import that exited 0 stored nothing silently wrong: each sample is
    its line's value at the stored scale within half a count, a line is left
    out only beyond every chip's reading (and the notes say so), the scales
    and rates lie in their ranges, the metadata is JSON without NaN, and the
    session exports and imports back unchanged."""
    from motecal.sessions.store import open_store
    with open_store(db) as st_:
        d = st_.load_session(name)
    json.dumps(d.meta, allow_nan=False)
    assert np.isfinite(d.t).all()
    left_out = np.setdiff1d(np.arange(len(values)), d.seq)
    for s, v in values.items():
        unit = d.meta["units_in"][s]
        lsb = d.scales[s]
        assert RG.SCALE[s].holds(lsb), (s, lsb)
        f = 1 / lsb if unit == "counts" else FL.unit_factor(unit, d.meta["gravity_mss"])
        want = v[d.seq] * f * lsb
        got = d.sensor(s)
        assert (np.abs(got - want) <= 0.5 + 1e-6 * np.abs(want) + (np.abs(got) == 32767)).all(), \
            (s, unit, lsb, np.abs(got - want).max())
        if len(left_out):
            assert "left out" in d.meta["notes"]
        if unit == FL.SI_UNITS[s]:
            # the physics: the readings in g, deg/s, gauss are the file's, at a gravity
            # within 3 % of the standard one (a flipped or absurd --gravity is not)
            si = v[d.seq] * FL.unit_factor(unit, G_STD)
            assert np.allclose(d.physical(s), si, rtol=0.035, atol=0.5 / lsb + 1e-9), s
    for i in left_out:
        assert any(not (np.abs(v[i] * FL.unit_factor(d.meta["units_in"][s], d.meta["gravity_mss"]))
                        <= RG.READING_MAX[s].hi).all() for s, v in values.items()), i
    for r in d.meta["rates_hz"].values():
        assert RG.RATE_HZ.holds(r)
    out = f"{tmp}/back.csv"
    assert motecal("export", "--db", db, "--session", name, "--csv", out)[0] == 0
    rc, _, err = motecal("import", out, "--db", db, "--session", name + "_back")
    assert rc == 0, err
    with open_store(db) as st_:
        b = st_.load_session(name + "_back")
    np.testing.assert_array_equal(b.raw, d.raw)
    np.testing.assert_array_equal(b.seq, d.seq)


def _run_import(tmp, argv, values=None):
    db = f"{tmp}/m.db"
    make_db(db, "board")
    before = digest(db)
    rc, out, err = motecal("import", *argv, "--db", db, "--session", "fz")
    where = f"motecal import {' '.join(map(repr, argv))}"
    assert rc in (0, 2), f"{where}: exit {rc}: {err}"
    assert "Traceback" not in err, where
    if rc:
        assert err.count("\n") == 1 and err.endswith("\n"), f"{where}: {err!r}"
        assert digest(db) == before, f"{where}: the database changed"
    elif values is not None:
        _check_stored(db, "fz", values, None, tmp)
    return rc, err


@st.composite
def import_option_runs(draw):
    fmt = draw(st.sampled_from(["float-log"] * 3 + ["imucal-session", "motioncal"]))
    opts = []
    for opt in draw(st.lists(st.sampled_from(sorted(OPTION_VALUES)), unique=True, min_size=1,
                             max_size=3)):
        opts += [opt, draw(st.sampled_from(OPTION_VALUES[opt]))]
    sensor = draw(st.sampled_from(sorted(FLOAT_FILES)))
    return fmt, sensor, opts, draw(st.integers(0, 2 ** 16))


@settings(FUZZ, max_examples=40)
@given(import_option_runs())
def test_fuzz_import_options(run):
    """Every float option of `import`, valid, at its range's edges or hostile,
    on a float log, an imucal session or a MotionCal log."""
    fmt, sensor, opts, seed = run
    rng = np.random.default_rng(seed)
    with tempfile.TemporaryDirectory(prefix="motecal-fuzz-") as tmp:
        values = None
        if fmt == "float-log":
            name, lsb, unit, step = FLOAT_FILES[sensor]
            counts = _counts(sensor, 300, rng)
            path = D.write_float_log(counts * step, f"{tmp}/{name}", "{:.8f}")
            if "--columns" not in opts and "--units" not in opts and "--chip" not in opts:
                values = {sensor: counts * step}
        elif fmt == "imucal-session":
            path, _ = D.write_session(D.ferraris(seed % 50, hold_s=0.5, turn_s=1.0),
                                      f"{tmp}/sess.csv")
        else:
            raw = rng.integers(-500, 500, (200, 9))
            raw[:, 2] += 8000
            path = f"{tmp}/motioncal.log"
            Path(path).write_text("".join("Raw:" + ",".join(map(str, r)) + "\n" for r in raw))
        _run_import(tmp, [path, *opts], values)


GOOD_LINE = object()
LINE_KINDS = {
    "glitch": ["1e20 0.1 9.8", "1e39 0 0", "-1e20 0 0", "1e300 1e300 1e300", "0 0 1e25"],
    "offgrid": ["9.80001 0.1 9.8", "0.333 0.2 0.1"],
    "bad": ["nan 0 0", "inf 1 2", "x 1 2", "1 2", "1 2 3 4", "1,,2,3", "1e400 0 0", "é 1 2"],
    "blank": ["", "   ", "\t"],
}


@st.composite
def float_log_files(draw):
    sensor = draw(st.sampled_from(sorted(FLOAT_FILES)))
    n = draw(st.integers(1, 400))
    plan = draw(st.lists(st.tuples(st.integers(0, n), st.sampled_from(
        ["glitch", "offgrid", "bad", "blank", "zeros"])), max_size=4))
    sep = draw(st.sampled_from([" ", ",", ";", "\t", "  ", ", "]))
    rate = draw(st.sampled_from([None, "50", "0.5"]))
    return sensor, n, plan, sep, rate, draw(st.integers(0, 2 ** 16))


@settings(FUZZ, max_examples=30)
@given(float_log_files())
def test_fuzz_float_logs(case):
    """Float logs of good lines with glitches, values off the grid, bad lines,
    blank lines and runs of zeros: a bad line or a zero run is one line, a
    glitch is left out and named, nothing else is lost or changed."""
    sensor, n, plan, sep, rate, seed = case
    rng = np.random.default_rng(seed)
    name, lsb, unit, step = FLOAT_FILES[sensor]
    good = _counts(sensor, n, rng) * step
    lines = [sep.join(f"{v:.8f}" for v in row) for row in good]
    values = [row for row in good]
    must_fail = False
    for at, kind in sorted(plan, reverse=True):
        if kind == "zeros":
            k = int(rng.integers(1, 40))
            lines[at:at] = [sep.join(["0"] * 3)] * k
            values[at:at] = [np.zeros(3)] * k
            must_fail |= k >= RG.ZERO_RUN and sensor != "gyro"
            continue
        text = LINE_KINDS[kind][int(rng.integers(len(LINE_KINDS[kind])))]
        lines.insert(at, text)
        if kind == "blank":
            continue
        if kind == "bad":
            must_fail = True
            values.insert(at, np.full(3, np.nan))
        else:
            values.insert(at, np.array([float(x) for x in text.split()]))
    with tempfile.TemporaryDirectory(prefix="motecal-fuzz-") as tmp:
        path = f"{tmp}/{name}"
        Path(path).write_text("\n".join(lines) + "\n")
        argv = [path] + (["--rate-hz", rate] if rate else [])
        v = np.array(values) if values else np.zeros((0, 3))
        glitches = ~(np.abs(v * FL.unit_factor(FL.SI_UNITS[sensor])) <= RG.READING_MAX[sensor].hi).all(axis=1)
        must_fail |= glitches.sum() > RG.ABSURD_MAX_FRACTION * len(v) or not len(v)
        rc, err = _run_import(tmp, argv, {sensor: v} if len(v) and not np.isnan(v).any() else None)
        if must_fail:
            assert rc == 2, f"{lines[:3]}...: a bad file was stored ({plan})"
