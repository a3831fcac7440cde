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
