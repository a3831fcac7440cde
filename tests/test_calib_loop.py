"""Closing the loop (issue 13): ``diagnose`` keeps its result with the
session, ``calibrate`` uses it by default (not when made from other rows or
by another version; not with --no-diagnosis), each treatment or term only
when it lowers the held-out error, so the calibration is never worse than
without it; the terms it fits (g-sensitivity, warm-up drift, nonlinearity,
disturbed spans) bring the error against the planted truth down.  (~60 s)"""
import json
import sqlite3
import sys
from pathlib import Path

import numpy as np
import pytest

import plant as P
from clirun import store_db
from motecal.calib.board import calibrate_board
from motecal.calib.loop import calibrate_with_diagnosis
from motecal.commands.calibrate import TOOL
from motecal.commands.main import main
from motecal.sessions.fingerprint import data_key
from motecal.sessions.store import open_store

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "bench"))
import bench_diagnose_loop as L  # noqa: E402


def _gsens_session(seed):
    rng = np.random.default_rng([seed, 31])
    return P.simulate([P.make_plant("g_sensitivity", "gyro", rng, scale=2.0)], "static80", seed)


@pytest.mark.slow
def test_kept_diagnosis_is_used_by_default_and_said(tmp_path, capsys):
    ses = _gsens_session(5)
    db = store_db(tmp_path, ses)
    assert main(["diagnose", "--db", db, "--session", "s", "--no-sim"]) == 0
    out = capsys.readouterr().out
    assert "kept with the session (database diagnosis 1)" in out
    cal = tmp_path / "cal.json"
    args = ["calibrate", "--db", db, "--session", "s", "--out", str(cal), "--seed", "1",
            "--kfold", "0"]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "kept with the session" in out and "(motecal " in out, out
    assert "used: gyro g_sensitivity: fitted, held-out rms" in out, out
    j = json.loads(cal.read_text())
    dg = j["settings"]["diagnosis"]
    assert dg["kept"] == 1 and dg["tool"].startswith("motecal ")
    assert any(d["what"] == "g_sensitivity" and d["used"] for d in dg["decisions"])
    S = np.array(j["gyro"]["extra"]["g_sensitivity"]["S"])
    G = np.array(ses.meta["planted"][0]["term"]["G"])
    assert np.abs(S - G).max() < 0.25 * np.abs(G).max(), (S, G)
    # --no-diagnosis: the plain calibration, said
    assert main(args + ["--no-diagnosis"]) == 0
    out = capsys.readouterr().out
    assert "diagnosis: not used: --no-diagnosis" in out and "g_sensitivity" not in out
    # another version's diagnosis is not used silently
    con = sqlite3.connect(db)
    con.execute("UPDATE diagnoses SET tool = 'motecal 0.0.1'")
    con.commit()
    con.close()
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "was made by another version" in out and "used: gyro" not in out, out
    # a diagnosis of other rows (the session recorded again, longer) neither
    assert main(["diagnose", "--db", db, "--session", "s", "--no-sim"]) == 0
    longer = _gsens_session(6)
    longer.name = "s"
    with open_store(db) as st:
        st.save_session(longer, replace=True)
        assert st.load_diagnosis("s", 1) is None          # the old ones went with it
    capsys.readouterr()
    assert main(args) == 0
    assert "none kept with the session" in capsys.readouterr().out


def test_diagnosis_of_other_rows_not_used(tmp_path, capsys):
    ses = _gsens_session(7)
    db = store_db(tmp_path, ses)
    with open_store(db) as st:
        st.save_diagnosis("s", 1, {"clean": True, "findings": [], "model": {}},
                          tool=TOOL, data_key=data_key(ses.select(
                              np.arange(len(ses)) < len(ses) - 5)))
    assert main(["calibrate", "--db", db, "--session", "s", "--out", str(tmp_path / "c.json"),
                 "--seed", "1", "--kfold", "0"]) == 0
    out = capsys.readouterr().out
    assert f"was made from other data ({len(ses) - 5} rows then, {len(ses)} now)" in out, out


def test_both_flags_and_read_only_database(tmp_path, capsys):
    ses = P.simulate([], "idle", 3)
    db = store_db(tmp_path, ses)
    rc = main(["calibrate", "--db", db, "--session", "s", "--out", str(tmp_path / "c.json"),
               "--diagnosis", "x.json", "--no-diagnosis"])
    err = capsys.readouterr().err
    assert rc == 2 and len(err.strip().splitlines()) == 1
    # --no-keep leaves the database as it was
    assert main(["diagnose", "--db", db, "--session", "s", "--no-sim", "--no-keep"]) == 0
    with open_store(db, readonly=True) as st:
        assert st.load_diagnosis("s", 1) is None


def test_data_key_changes_with_the_rows():
    ses = P.simulate([], "idle", 2)
    k = data_key(ses)
    assert data_key(ses.select(np.ones(len(ses), bool))) == k
    other = ses.select(np.ones(len(ses), bool))
    other.raw = other.raw.copy()
    other.raw[10, 0] += 1
    assert data_key(other) != k and k.startswith(f"{len(ses)}:")


@pytest.mark.slow
@pytest.mark.parametrize("cause", ["stale_samples-accel", "saturation-accel"])
def test_never_worse_than_without(cause):
    """Leaving readings out is kept only when the held-out error falls: on 3
    seeds, the calibration with the diagnosis is never worse against the
    planted truth than without it (repeats are unbiased: leaving them out
    must not be taken; clipped poses are biased: they must go)."""
    for seed in (21, 22, 23):
        r = L.run_case((cause, seed), lean=True)
        e = r["err"]
        assert e["full + diagnosis"] <= e["full"] * 1.0001, (seed, e, r["used"], r["not_used"])
        if cause.startswith("saturation"):
            assert e["full + diagnosis"] < 0.5 * e["full"], (seed, e)
            assert e["full + diagnosis"] <= 2.0 * e["true"], (seed, e)     # fewer poses


@pytest.mark.parametrize("cause", ["g_sensitivity-gyro", "bias_drift-gyro", "nonlinearity-accel",
                                   "spans-mag"])
def test_fitted_terms_bring_the_error_down(cause):
    """The terms calibrate fits for what the diagnosis names: against the
    planted truth, at most half the plain full model's error on at least 2
    of 3 seeds, and never worse."""
    good = 0
    for seed in (31, 32, 33):
        r = L.run_case((cause, seed), lean=True)
        e = r["err"]
        assert e["full + diagnosis"] <= e["full"] * 1.0001, (seed, e)
        good += e["full + diagnosis"] < 0.5 * e["full"]
    assert good >= 2, (cause, e, r["used"], r["not_used"])


def test_noise_only_terms_are_not_taken():
    """A clean board with a diagnosis that (wrongly) names nonlinearity,
    g-sensitivity and drift: the held-out check takes none of them on at
    least 4 of 5 seeds, and whatever it takes does not make the board worse
    than 1.1x without."""
    fake = {"findings": [{"sensor": "accel", "cause": "nonlinearity"},
                         {"sensor": "gyro", "cause": "g_sensitivity"},
                         {"sensor": "gyro", "cause": "bias_drift"}]}
    clean = 0
    for seed in range(41, 46):
        ses = P.simulate([], "static80", seed, n_poses=40, base="general")

        def cal(x):
            return calibrate_board(x, seed=1, kfold=0, gyro_matrix=False)
        board, rep = calibrate_with_diagnosis(ses, fake, cal)
        clean += not rep["used"]
        assert len(rep["decisions"]) == 3, rep
    assert clean >= 4


@pytest.mark.parametrize("finding", [
    "not a dict", {"sensor": "mag", "cause": "unexplained", "evidence": {"outlier_times_s": ["x"]}},
    {"sensor": "accel", "cause": "saturation", "evidence": {"limits": [{"axis": "q"}]},
     "params": {"overflow_code": "no"}}])
def test_malformed_diagnosis_file_is_one_line(tmp_path, capsys, finding):
    db = store_db(tmp_path, P.simulate([], "idle", 3))
    f = tmp_path / "d.json"
    f.write_text(json.dumps({"clean": False, "findings": [finding]}))
    rc = main(["calibrate", "--db", db, "--session", "s", "--out", str(tmp_path / "c.json"),
               "--diagnosis", str(f), "--kfold", "0"])
    err = capsys.readouterr().err
    assert rc == 2 and len(err.strip().splitlines()) == 1 and "diagnosis" in err, err
    assert not (tmp_path / "c.json").exists()
