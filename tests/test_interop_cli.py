"""``motecal export-cal`` and ``motecal import`` of the foreign formats from the
command line: outputs written whole, costs printed, bad input one line and exit 2."""
import json

import numpy as np
import pytest

import interop_data as D
from motecal.commands import main as cli
from motecal.calib import calibrate_board
from motecal.sessions.store import open_store

from synthetic import paper_sized_session


def main(argv):
    return cli.main([str(a) for a in argv])


@pytest.fixture(scope="module")
def stored(tmp_path_factory):
    """A simulated session in a database and its cal.json."""
    tmp = tmp_path_factory.mktemp("cli")
    sess = paper_sized_session(seed=3, n_poses=30)
    sess.name = "bench3"
    db = tmp / "s.db"
    with open_store(str(db), create=True) as st:
        st.save_session(sess)
    board = calibrate_board(sess, model="full", seed=3, kfold=0)
    cal = tmp / "cal.json"
    board.save(cal)
    return db, cal, board


def test_export_cal_writes_and_prints_costs(stored, tmp_path, capsys):
    db, cal, board = stored
    out = tmp_path / "ap.param"
    assert main(["export-cal", cal, "--to", "ardupilot", "--out", out, "--db", db]) == 0
    text = capsys.readouterr().out
    assert f"wrote {out} (ardupilot)" in text
    assert "accel: offset and scale per axis" in text and "session 'bench3'" in text
    assert out.read_text().count("INS_ACCSCAL_") == 3
    # to standard output: the text there, the costs on stderr, over directions without --db
    assert main(["export-cal", cal, "--to", "imucal"]) == 0
    cap = capsys.readouterr()
    assert json.loads(cap.out)["cal_type"] == "Ferraris"
    assert "2000 directions" in cap.err and "mag: not held" in cap.err


def test_export_cal_bad_input(stored, tmp_path, capsys):
    db, cal, board = stored
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    out = tmp_path / "x.h"
    assert main(["export-cal", bad, "--to", "c-header", "--out", out]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not JSON" in err and not out.exists()
    assert main(["export-cal", cal, "--to", "nope"]) == 2
    assert main(["export-cal", cal, "--to", "razor-c", "--db", db, "--session", "missing",
                 "--out", out]) == 2
    assert capsys.readouterr().err.count("\n") == 2 and not out.exists()
    assert list(tmp_path.iterdir()) == [bad]          # no temporary file left behind


def test_import_foreign_formats(tmp_path, capsys):
    s = D.ferraris(7)
    ann = D.write_annotated(s, tmp_path / "ann.csv")
    db = tmp_path / "d.db"
    assert main(["import", ann, "--db", db, "--session", "ann", "--rate-hz", 200,
                 "--scale", "accel=2048", "--scale", "gyro=16.4"]) == 0
    out = capsys.readouterr().out
    assert "imucal-annotated" in out and "6 poses found" in out
    sess_csv, lst = D.write_session(s, tmp_path / "ferraris.csv")
    assert main(["import", sess_csv, lst, "--db", db, "--session", "sess", "--rate-hz", 200,
                 "--gravity", 9.81]) == 0
    with open_store(str(db)) as st:
        d = st.load_session("sess")
        assert d.meta["format"] == "imucal-session" and len(d.meta["rotations"]) == 3
        np.testing.assert_array_equal(d.sensor("accel"), s["acc"])
    t = D.turntable(2)
    log = D.write_float_log(t["rad_s"], tmp_path / "33RPMgyr.txt")
    assert main(["import", log, "--db", db, "--session", "tt", "--rpm", "33.333333",
                 "--rate-hz", t["rate"]]) == 0
    assert "float-log" in capsys.readouterr().out


def test_import_bad_foreign_file_stores_nothing(tmp_path, capsys):
    s = D.ferraris(8)
    ann = D.write_annotated(s, tmp_path / "ann.csv")
    lines = ann.read_text().splitlines()
    ann.write_text("\n".join(lines[:20] + [lines[20] + ",nan"] + lines[21:]) + "\n")
    db = tmp_path / "d.db"
    assert main(["import", ann, "--db", db, "--session", "x", "--rate-hz", 200,
                 "--scale", "accel=2048,gyro=16.4"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{ann}: line 21: expected 8 columns, found 9" in err
    assert not db.exists() or "x" not in [r["name"] for r in open_store(str(db)).sessions()]
