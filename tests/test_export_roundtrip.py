"""log -> export -> import -> calibrate gives the calibration of the logged
session: the exported ``t`` is each sample's time (a logged session stores
batch receive times, compressed when the line is read faster than real
time), so the import measures 125 Hz and the gyroscope's moves integrate
over the right times.  (~10 s)"""
import csv
import os

import numpy as np
import pytest

from motecal.calib.board import calibrate_board
from motecal.commands.main import main
from motecal.sessions.session import SessionData, batch_times, rate_from_times
from motecal.sessions.store import open_store


@pytest.fixture(scope="module")
def logged(tmp_path_factory):
    d = tmp_path_factory.mktemp("rt")
    bin_, db = d / "q.bin", d / "log.db"
    assert main(["sim", "--model", "general", "--session", "static80", "--seed", "5",
                 "--motes", "1", "--out", str(bin_), "--quiet"]) == 0
    assert main(["log", "--port", str(bin_), "--db", str(db), "--session", "s",
                 "--guided", "static80", "--yes"]) == 0
    return d, db


def _param_dict(board):
    return {(name, p.name): (p.value, p.std) for name, sc in board.sensors() for p in sc.params}


def test_export_import_calibrate_gives_the_logged_calibration(logged, capsys):
    d, db = logged
    out, db2 = d / "s.csv", d / "imp.db"
    assert main(["export", "--db", str(db), "--session", "s", "--csv", str(out)]) == 0
    mask = os.umask(0)
    os.umask(mask)
    assert os.stat(out).st_mode & 0o777 == 0o666 & ~mask          # as open() makes it
    capsys.readouterr()
    assert main(["import", str(out), "--db", str(db2), "--session", "r"]) == 0
    assert "accel 37275 at 125.0 Hz" in capsys.readouterr().out
    with open_store(str(db)) as st:
        a = st.load_session("s")
    with open_store(str(db2)) as st:
        b = st.load_session("r")
    assert batch_times(a.t)                       # what the logger stores: receive times
    assert np.ptp(a.t) < 10                       # 298 s of samples read in a few seconds
    np.testing.assert_allclose(b.t, a.sample_times(), atol=1e-6)
    assert b.rate() == pytest.approx(125.0, abs=1e-3)
    assert np.array_equal(b.raw, a.raw) and np.array_equal(b.label, a.label)
    assert b.kind == "static"                     # the CSV carries labels, not the kind
    ca = calibrate_board(a, seed=1, kfold=0)
    cb = calibrate_board(b, seed=1, kfold=0)
    assert [(n, s.model) for n, s in cb.sensors()] == [(n, s.model) for n, s in ca.sensors()]
    assert cb.gyro.model == "bias+matrix"
    pa, pb = _param_dict(ca), _param_dict(cb)
    assert pa.keys() == pb.keys()
    for k in pa:                                  # same rows, same times: the same fit
        assert pb[k][0] == pytest.approx(pa[k][0], rel=1e-6, abs=1e-9), k


@pytest.mark.slow
def test_unlabelled_export_imports_as_static_poses(logged, capsys):
    """With the labels blanked the importer finds the poses itself (at the
    batch times it saw 22730 Hz, no still window, and called it rotation)."""
    d, db = logged
    out, blank, db2 = d / "a.csv", d / "blank.csv", d / "blank.db"
    assert main(["export", "--db", str(db), "--session", "s", "--csv", str(out)]) == 0
    rows = list(csv.reader(out.open()))
    for r in rows[1:]:
        r[3] = ""
    with blank.open("w", newline="") as f:
        csv.writer(f, lineterminator="\n").writerows(rows)
    capsys.readouterr()
    assert main(["import", str(blank), "--db", str(db2), "--session", "u"]) == 0
    text = capsys.readouterr().out
    assert "kind static [auto: static" in text and "80 poses found" in text
    with open_store(str(db)) as st:
        a = st.load_session("s")
    with open_store(str(db2)) as st:
        u = st.load_session("u")
    ca = calibrate_board(a, seed=1, kfold=0)
    cu = calibrate_board(u, seed=1, kfold=0)
    assert [(n, s.model) for n, s in cu.sensors()] == [(n, s.model) for n, s in ca.sensors()]
    pa, pu = _param_dict(ca), _param_dict(cu)
    for k in pa:                                  # other still rows: within the noise
        (va, sa), (vu, su) = pa[k], pu[k]
        assert abs(vu - va) < 5 * np.hypot(sa, su), (k, va, vu, sa, su)


def test_rate_from_batch_receive_times():
    """Rows of a batch share its receive time: the rate counts samples by seq
    over the time between batches (1 / the median step would give 25 Hz)."""
    seq = np.arange(1000)
    t = 0.3 + (seq // 5) * 5 / 125.0 + 0.001 * (np.arange(1000) // 5 % 3)
    assert batch_times(t)
    assert rate_from_times(t, seq) == pytest.approx(125.0, rel=0.01)
    n = len(seq)
    s = SessionData("b", np.zeros((n, 9)), np.ones(n), seq, t, np.zeros(n), np.zeros(n))
    assert s.rate() == pytest.approx(125.0, rel=0.01)
    np.testing.assert_allclose(s.sample_times(), seq / s.rate())
    # lost samples count, pauses do not
    keep = (seq < 400) | (seq >= 410)
    tp = np.where(seq >= 500, t + 30.0, t)
    assert rate_from_times(tp[keep], seq[keep]) == pytest.approx(125.0, rel=0.01)
