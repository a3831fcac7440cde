"""Issue 15, case 9: hostile input is one line naming file, line and field,
exit 2, checked before numpy or sqlite see the value; nothing is stored."""
import json
import os

import pytest

from clirun import digest, make_db, motecal

HEADER = "mote,seq,t,label,ax,ay,az,gx,gy,gz,mx,my,mz"
GOOD = "1,0,0,,1,2,3,4,5,6,7,8,9"

# (name, data line, words the one line must hold)
CSV_CASES = [
    ("seq_2_63", "1,9223372036854775808,0,,1,2,3,4,5,6,7,8,9", ["line 3", "seq", "range"]),
    ("seq_huge_negative", "1,-99999999999999999999,0,,1,2,3,4,5,6,7,8,9", ["line 3", "seq"]),
    ("label_99999999999", "1,1,0,99999999999,1,2,3,4,5,6,7,8,9", ["line 3", "label"]),
    ("label_digits_5000", "1,1,0," + "9" * 5000 + ",1,2,3,4,5,6,7,8,9", ["line 3", "label"]),
    ("field_10MB", "1,1,0,," + "1" * 10_000_000 + ",2,3,4,5,6,7,8,9", ["line 3", "CSV"]),
    ("mote_2_63", "9223372036854775808,1,0,,1,2,3,4,5,6,7,8,9", ["line 3", "mote"]),
    ("mote_negative", "-1,1,0,,1,2,3,4,5,6,7,8,9", ["line 3", "mote"]),
    ("t_1e308", "1,1,1e308,,1,2,3,4,5,6,7,8,9", ["line 3", "t"]),
    ("t_nan", "1,1,nan,,1,2,3,4,5,6,7,8,9", ["line 3", "t"]),
    ("value_1e400", "1,1,0,,1e400,2,3,4,5,6,7,8,9", ["line 3", "ax"]),
    ("value_int16_overflow", "1,1,0,,40000,2,3,4,5,6,7,8,9", ["line 3", "ax"]),
    ("value_text", "1,1,0,,1,2,3,4,5,6,7,8,x", ["line 3", "mz"]),
    ("columns", "1,1,0,,1,2,3", ["line 3", "columns"]),
    ("nul_byte", "1,1,0,,1,2,3,4,5,6,7,8,\x009", ["binary"]),     # not text at all
]


@pytest.mark.parametrize("name,line,words", CSV_CASES, ids=[c[0] for c in CSV_CASES])
def test_case9_hostile_csv_is_one_line_naming_file_line_field(tmp_path, name, line, words):
    db = make_db(tmp_path / "in.db")
    before = digest(db)
    f = tmp_path / f"{name}.csv"
    f.write_text(f"{HEADER}\n{GOOD}\n{line}\n")
    rc, out, err = motecal("import", f, "--db", db, "--session", "s")
    assert rc == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err and len(err) < 400
    assert f"{name}.csv" in err and all(w in err for w in words), err
    assert digest(db) == before


@pytest.mark.timeout(30)
def test_case9_special_files_never_hang(tmp_path):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    db = make_db(tmp_path / "in.db")
    for argv in (("upload", "--dry-run", fifo), ("import", fifo, "--db", db, "--session", "s"),
                 ("import", fifo, "--format", "csv", "--db", db, "--session", "s"),
                 ("report", "--db", db, "--session", "board", "--cal", fifo,
                  "--out", tmp_path / "r"),
                 ("log", "--port", tmp_path / "none.bin", "--db", fifo, "--session", "s")):
        rc, out, err = motecal(*argv)
        assert rc == 2 and err.count("\n") == 1 and "Traceback" not in err, (argv, err)


OPTION_CASES = [
    ("sim", "--out", "{t}/s.bin", "--duration", "1e308"),
    ("sim", "--out", "{t}/s.bin", "--duration", "nan"),
    ("sim", "--out", "{t}/s.bin", "--speed", "1e300"),
    ("sim", "--out", "{t}/s.bin", "--motes", "99999999999999999999"),
    ("sim", "--out", "{t}/s.bin", "--loss", "inf"),
    ("log", "--port", "{t}/none.bin", "--db", "{t}/l.db", "--session", "s", "--duration", "1e308"),
    ("log", "--port", "{t}/none.bin", "--db", "{t}/l.db", "--session", "s",
     "--pose-samples", "99999999999999"),
    ("log", "--port", "{t}/none.bin", "--db", "{t}/l.db", "--session", "s",
     "--lock-timeout", "-1"),
    ("calibrate", "--db", "{t}/in.db", "--session", "board", "--out", "{t}/c.json",
     "--mag-field", "1e308"),
    ("calibrate", "--db", "{t}/in.db", "--session", "board", "--out", "{t}/c.json",
     "--kfold", "99999999999"),
    ("upload", "--dry-run", "{t}/c.json", "--retries", "99999999999"),
    ("upload", "--dry-run", "{t}/c.json", "--timeout", "1e308"),
    ("report", "--db", "{t}/in.db", "--session", "board", "--out", "{t}/r", "--mote", "70000"),
    ("export", "--db", "{t}/in.db", "--session", "board", "--csv", "{t}/e.csv", "--mote", "0"),
]


@pytest.mark.parametrize("argv", OPTION_CASES, ids=lambda a: "-".join(a[:1] + a[-2:-1]))
def test_case9_options_out_of_range(tmp_path, argv):
    db = make_db(tmp_path / "in.db")
    before = digest(db)
    rc, out, err = motecal(*[a.replace("{t}", str(tmp_path)) for a in argv])
    assert rc == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert argv[-2] in err or "must" in err
    assert digest(db) == before
    assert sorted(os.listdir(tmp_path)) == ["in.db"]


def test_case9_report_cal_with_nan_and_strings(tmp_path):
    db = make_db(tmp_path / "in.db")
    for bad, word in (({"format_version": 1, "mote": 1, "accel": {"A": [[float("nan"), 0, 0],
                       [0, 1, 0], [0, 0, 1]], "c": [0, 0, 0]}}, "infinite"),
                      ({"format_version": 1, "mote": 1, "accel": {"A": [["1", 0, 0], [0, 1, 0],
                       [0, 0, 1]], "c": [0, 0, 0]}}, "numbers")):
        cal = tmp_path / "c.json"
        cal.write_text(json.dumps(bad))
        rc, out, err = motecal("report", "--db", db, "--session", "board", "--cal", cal,
                               "--out", tmp_path / "r")
        assert rc == 2 and word in err and "Traceback" not in err, err
    assert not (tmp_path / "r").exists()
