"""``motecal calibrate`` end to end through the sqlite store."""
import json

import numpy as np
import pytest

from motecal.commands.calibrate import out_path
from motecal.sessions import importer
from clirun import store_db
from synthetic import paper_sized_session
from motecal.commands.main import main
from motecal.sessions.session import SessionData
from motecal.sessions.store import open_store


def _concat(name, parts):
    return SessionData(name, np.vstack([p.raw for p in parts]),
                       np.concatenate([p.mote for p in parts]),
                       np.concatenate([p.seq for p in parts]),
                       np.concatenate([p.t for p in parts]),
                       np.concatenate([p.label for p in parts]),
                       np.concatenate([p.flags for p in parts]), "static80",
                       meta={"rate_hz": 125.0, "source": "sim"})


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    """Two simulated motes ("two")."""
    return store_db(tmp_path_factory.mktemp("calcli"), _concat(
        "two", [paper_sized_session(3, mote=1, rotation=False, n_poses=30, per_pose=100),
                paper_sized_session(3, mote=2, rotation=False, n_poses=30, per_pose=100)]),
        "two")


def test_two_motes_two_files_and_the_database(db, tmp_path, capsys):
    out = tmp_path / "cal.json"
    rc = main(["calibrate", "--db", db, "--session", "two", "--out", str(out), "--seed", "5"])
    text = capsys.readouterr().out
    assert rc == 0, text
    for m in (1, 2):
        f = tmp_path / f"cal-mote{m}.json"
        d = json.loads(f.read_text())
        assert d["mote"] == m and d["session"] == "two" and d["format_version"] == 1
        assert d["gate"]["accepted"] and d["settings"]["seed"] == 5
        assert f"wrote {f}" in text
        with open_store(db) as st:
            assert st.load_calibration("two", m) == d
    assert "mote 1" in text and "mote 2" in text and "gate: accepted" in text
    assert not out.exists()


def test_one_mote_exact_name_and_paper_model(db, tmp_path, capsys):
    out = tmp_path / "one.json"
    rc = main(["calibrate", "--db", db, "--session", "two", "--mote", "2", "--out", str(out),
               "--model", "paper", "--params", "offsets,scales,angles", "--seed", "1",
               "--kfold", "0", "--no-gyro-matrix"])
    text = capsys.readouterr().out
    assert rc == 0
    d = json.loads(out.read_text())
    assert d["mote"] == 2 and d["accel"]["model"] == "paper(offsets+scales+angles)"
    assert d["gyro"]["model"] == "bias"
    names = [p["name"] for p in d["accel"]["params"] if not p["identifiable"]]
    assert {"a_zy", "a_xz", "a_yz"} <= set(names)
    assert "re-parametrisation" in text and "rank 6 of 9" in text


@pytest.mark.parametrize("params", ["angles", "offsets,angles"])
def test_any_accel_subset_with_a_magnetometer(db, tmp_path, capsys, params):
    """--params selects the accelerometer's subset (the paper's Table I); the
    magnetometer gets the nearest family it can be fitted with under the
    det(A) = 1 gauge (its angles need the scales), with a note; with a known
    field it is fitted as asked."""
    out = tmp_path / "p.json"
    base = ["calibrate", "--db", db, "--session", "two", "--mote", "1", "--out", str(out),
            "--model", "paper", "--params", params, "--seed", "1", "--kfold", "0",
            "--no-gyro-matrix", "--force"]
    rc = main(base)
    text = capsys.readouterr().out
    assert rc == 0, text
    d = json.loads(out.read_text())
    asked = params.replace(",", "+")
    assert d["accel"]["model"] == f"paper({asked})"
    fitted = "scales+angles" if params == "angles" else "offsets+scales+angles"
    assert d["mag"]["model"] == f"paper({fitted})"
    note = f"--params {params}: the magnetometer is fitted with {fitted}"
    assert any(n.startswith(note) for n in d["mag"]["notes"])
    assert any(w.startswith("mag: " + note) for w in d["gate"]["warnings"])
    assert "warning: mag: " + note in text
    assert main(base + ["--mag-field", "0.48"]) == 0
    d = json.loads(out.read_text())
    assert d["mag"]["model"] == f"paper({asked})" and d["mag"]["field_gauss"] == 0.48
    assert not any("the magnetometer is fitted with" in n for n in d["mag"]["notes"])


def test_refused_board_exit_3_and_force(measured, tmp_path, capsys):
    """The disturbed HMC5843 sweep (measured)."""
    db = store_db(tmp_path, importer.read_razor_float(
        measured / "hmc5843-disturbed-sweep" / "magnetom.float", chip="hmc5843"), "disturbed")
    out = tmp_path / "bad.json"
    rc = main(["calibrate", "--db", db, "--session", "disturbed", "--out", str(out),
               "--seed", "0"])
    cap = capsys.readouterr()
    assert rc == 3 and not out.exists()
    assert "residual too large" in cap.err and "calibration refused" in cap.err
    rc = main(["calibrate", "--db", db, "--session", "disturbed", "--out", str(out),
               "--seed", "0", "--force"])
    assert rc == 0
    d = json.loads(out.read_text())
    assert d["gate"]["forced"] and not d["gate"]["accepted"] and d["gate"]["reasons"]


@pytest.mark.parametrize("args,msg", [
    (["--model", "full", "--params", "offsets"], "--params"),
    (["--params", "tilt", "--model", "paper"], "--params"),
    (["--mag-field", "-1"], "--mag-field"),
    (["--mag-field", "inf"], "--mag-field"),
    (["--mag-field", "nan"], "--mag-field"),
    (["--mag-field", "x"], "--mag-field"),
    (["--kfold", "1"], "--kfold"),
    (["--kfold", "-1"], "--kfold"),
    (["--kfold", "101"], "--kfold"),
    (["--seed", "-3"], "--seed"),
    (["--seed", "1.5"], "--seed"),
    (["--session", "nope"], "nope"),
    (["--mote", "9"], "mote 9"),
])
def test_user_errors_exit_2(db, tmp_path, capsys, args, msg):
    base = {"--db": db, "--session": "two", "--out": str(tmp_path / "x.json")}
    for k in list(base):
        if k in args:
            base.pop(k)
    argv = ["calibrate"] + [x for kv in base.items() for x in kv] + args
    rc = main(argv)
    err = capsys.readouterr().err
    assert rc == 2 and msg in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1


def test_out_path_naming():
    assert str(out_path("cal.json", 3, several=False)) == "cal.json"
    assert str(out_path("d/cal.json", 3, several=True)) == "d/cal-mote3.json"
    assert str(out_path("cal_{mote}.json", 3, several=False)) == "cal_3.json"
