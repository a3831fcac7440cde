"""Hostile imports (issue 13): CSV files that the importer accepts but that
hold nothing sensible -- a constant (stuck) column, NaN cells, a few rows,
huge values, duplicated times, a stuck or clipped axis -- must never end
``motecal diagnose`` or ``motecal calibrate`` in a traceback: either a
result (exit 0, or 3 for a calibration the gate refuses) or one line on
stderr and exit 2.  (~15 s)"""
import sys

import numpy as np
import pytest

from motecal.commands.main import main
from motecal.sessions.importer import write_csv
from motecal.sim import simulate_session


def _base(kind="idle", seed=5):
    return simulate_session(kind, seed=seed, model="paper", duration=20.0
                            if kind in ("idle", "rotation") else None)[1]


def _hostile(name, rng):
    kind = "static80" if name.startswith("static") else "idle"
    d = _base(kind)
    raw = d.raw.astype(float).copy()
    t = d.t.copy()
    if name.endswith("constant-accel-x"):
        raw[:, 0] = raw[0, 0]
    elif name.endswith("constant-all"):
        raw[:] = raw[0]
    elif name.endswith("clipped-mag-y"):
        raw[:, 7] = np.minimum(raw[:, 7], np.percentile(raw[:, 7], 20))
    elif name.endswith("nan-cells"):
        raw[rng.random(raw.shape) < 0.05] = np.nan
    elif name.endswith("nan-sensor"):
        raw[:, 3:6] = np.nan
    elif name.endswith("few-rows"):
        keep = slice(0, 5)
        return d.select(np.arange(len(d))[keep]), None
    elif name.endswith("huge"):
        raw[::7, 6:9] = 32767.0
        raw[::11, 0:3] = -32768.0
    elif name.endswith("dup-times"):
        t = np.repeat(t[::4], 4)[:len(t)]
    elif name.endswith("zero-times"):
        t = np.zeros(len(t))
    d.raw = raw
    d.t = t
    return d, None


CASES = ["idle-constant-accel-x", "idle-constant-all", "idle-clipped-mag-y", "idle-nan-cells",
         "idle-nan-sensor", "idle-few-rows", "idle-huge", "idle-dup-times", "idle-zero-times",
         "static-constant-accel-x", "static-nan-cells", "static-dup-times", "static-huge"]


@pytest.mark.slow
@pytest.mark.parametrize("name", CASES)
def test_no_traceback_on_hostile_imports(name, tmp_path, capsys):
    rng = np.random.default_rng(abs(hash(name)) % 2**32)
    data, _ = _hostile(name, rng)
    csv = tmp_path / "x.csv"
    data.label = np.zeros(len(data), np.int32)        # unlabelled: the tool finds the poses
    write_csv(data, csv)
    db = tmp_path / "x.db"
    rc = main(["import", str(csv), "--db", str(db), "--session", "s"])
    imp = capsys.readouterr().err
    if rc != 0:
        print(name, "import", rc, imp.strip()[:200], file=sys.__stderr__)
        assert rc == 2
        return
    for argv in (["diagnose", "--db", str(db), "--session", "s", "--no-sim",
                  "--json", str(tmp_path / "d.json")],
                 ["calibrate", "--db", str(db), "--session", "s", "--out",
                  str(tmp_path / "cal.json"), "--seed", "1", "--kfold", "0"]):
        try:
            rc = main(argv)
        except Exception as e:          # a traceback would reach the user
            pytest.fail(f"{name}: {argv[0]} raised {type(e).__name__}: {e}")
        err = capsys.readouterr().err
        print(name, argv[0], rc, err.strip()[:200], file=sys.__stderr__)
        assert rc in (0, 2, 3), (name, argv[0], rc, err)
        if rc == 2:
            assert len(err.strip().splitlines()) == 1, (name, argv[0], err)
