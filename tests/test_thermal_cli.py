"""Issue 16 through the command line: a session with the board temperature
in the database is calibrated against it (``motecal calibrate`` says what it
fitted; cal.json format 2) and diagnosed (``motecal diagnose`` names
``temperature``); the same session without its temperature is calibrated as
before.  (~15 s)"""
from __future__ import annotations

import dataclasses
import json
import os

import numpy as np
import pytest

from clirun import motecal
from motecal.sessions.store import open_store
from warmup import plant_temperature, simulate_plant, thermal_board, warmup_session

SEED = int(os.environ.get("MOTECAL_TEST_SEED", "0")) + 11


@pytest.mark.slow
def test_calibrate_and_diagnose_a_session_with_temperature(tmp_path):
    m, b = thermal_board(SEED)
    ses = warmup_session(b, SEED, hold_s=300.0, n_poses=40)
    ses.name = "warm"
    bare = dataclasses.replace(ses, name="bare", temp=None)
    p = plant_temperature("gyro", np.random.default_rng(SEED))
    p["term"]["offset_per_c"] = [0.0, 1.0, 0.0]
    gy = simulate_plant(p, SEED)
    gy.name = "gyro"
    gy.meta = {"source": "sim", "rate_hz": 125.0}
    ses.meta = {"source": "sim", "rate_hz": 125.0}
    bare.meta = dict(ses.meta)
    db = str(tmp_path / "t.db")
    with open_store(db, create=True) as st:
        for s in (ses, bare, gy):
            st.save_session(s)

    rc, out, err = motecal("calibrate", "--db", db, "--session", "warm", "--out",
                           tmp_path / "cal.json", "--seed", 1, "--kfold", 0, "--force")
    assert rc == 0, out + err
    assert "gyro: temperature: offset" in out and "accel: temperature: offset" in out, out
    d = json.loads((tmp_path / "cal.json").read_text())
    assert d["format_version"] == 2
    assert d["gyro"]["temperature"]["range_c"][1] > d["gyro"]["temperature"]["range_c"][0] + 2
    assert set(d["settings"]["temperature"]["fitted"]) >= {"gyro", "accel"}

    rc, out, err = motecal("calibrate", "--db", db, "--session", "bare", "--out",
                           tmp_path / "bare.json", "--seed", 1, "--kfold", 0, "--force")
    assert rc == 0, out + err
    assert "temperature" not in out
    assert json.loads((tmp_path / "bare.json").read_text())["format_version"] == 1

    rc, out, err = motecal("diagnose", "--db", db, "--session", "gyro", "--json",
                           tmp_path / "diag.json", "--no-sim")
    assert rc == 0, out + err
    f = json.loads((tmp_path / "diag.json").read_text())["findings"]
    t = [x for x in f if x["cause"] == "temperature"]
    assert t and t[0]["sensor"] == "gyro", f
    assert abs(t[0]["evidence"]["coef_per_c"][1] - 1.0 / 14.375) < 0.01, t[0]["evidence"]
