"""``motecal diagnose`` end to end on a database: summary, --json (exactly
{clean, findings, model}), --model-out (a model ``motecal sim`` accepts),
--report, several motes, user errors.  (~25 s)"""
import json

import numpy as np
import pytest

from motecal.commands.main import main
import plant as P
from motecal.sessions.session import SessionData
from motecal.sessions.store import open_store
from motecal.sim import load_model


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    path = tmp_path_factory.mktemp("diag") / "d.db"
    rng = np.random.default_rng(3)
    plants = [P.make_plant("cross_axis", "accel", rng), P.make_plant("stale_samples", "mag", rng)]
    planted = P.simulate(plants, "static80", 31)
    planted.name = "planted"
    clean = P.simulate([], "idle", 32, duration=30.0)
    clean.name = "clean"
    # two motes in one session: mote 1 planted, mote 2 clean
    two = P.simulate([], "static80", 33, n_poses=20)
    m2 = SessionData("two", two.raw, np.full(len(two), 2, np.int32), two.seq, two.t, two.label,
                     two.flags, two.kind, meta=dict(two.meta))
    both = SessionData("two", np.vstack([planted.raw, m2.raw]),
                       np.concatenate([planted.mote, m2.mote]),
                       np.concatenate([planted.seq, m2.seq]), np.concatenate([planted.t, m2.t]),
                       np.concatenate([planted.label, m2.label]),
                       np.concatenate([planted.flags, m2.flags]), "static80",
                       meta={"rate_hz": 125.0})
    with open_store(str(path), create=True) as st:
        for s in (planted, clean, both):
            st.save_session(s)
    return path


def test_planted_session_summary_json_model_report(db, tmp_path, capsys):
    out_json = tmp_path / "d.json"
    out_model = tmp_path / "ext.json"
    rep = tmp_path / "rep"
    rc = main(["diagnose", "--db", str(db), "--session", "planted", "--json", str(out_json),
               "--model-out", str(out_model), "--report", str(rep)])
    assert rc == 0
    text = " ".join(capsys.readouterr().out.split())          # paragraphs are wrapped
    assert "1. What the simulation gets wrong" in text
    assert "[accel] cross_axis" in text and "[mag] stale_samples" in text
    assert text.count("Gain on held-out data") >= 2
    assert "Simulated statistics on the held-out half" in text
    j = json.loads(out_json.read_text())
    assert set(j) == {"clean", "findings", "model"} and j["clean"] is False
    for f in j["findings"]:
        assert set(f) == {"sensor", "cause", "summary", "evidence", "params", "gain"}
        assert f["sensor"] in ("accel", "gyro", "mag")
    causes = {(f["sensor"], f["cause"]) for f in j["findings"]}
    assert causes == {("accel", "cross_axis"), ("mag", "stale_samples")}
    assert json.loads(out_model.read_text()) == j["model"]
    m = load_model(str(out_model))
    terms = [t.id for t in m.board(1, 0).sensors["mag"].terms]
    assert "stale_samples" in terms
    files = {p.name for p in rep.iterdir()}
    assert {"diagnosis.json", "summary.txt", "statistics.png"} <= files
    assert any(n.startswith("finding1-accel-cross_axis") for n in files)
    details = json.loads((rep / "diagnosis.json").read_text())["details"]
    assert details["n_tests"] >= 10 and details["tests"]


def test_extended_model_runs_in_motecal_sim(db, tmp_path):
    model = tmp_path / "ext.json"
    main(["diagnose", "--db", str(db), "--session", "planted", "--model-out", str(model),
          "--no-sim"])
    stream = tmp_path / "serial.bin"
    rc = main(["sim", "--model", str(model), "--motes", "1", "--session", "idle",
               "--duration", "1", "--out", str(stream)])
    assert rc == 0 and stream.stat().st_size > 1000


def test_clean_session(db, capsys):
    assert main(["diagnose", "--db", str(db), "--session", "clean", "--no-sim"]) == 0
    assert "clean: nothing beyond the paper's starting model" in capsys.readouterr().out


def test_several_motes_get_one_file_each(db, tmp_path, capsys):
    out = tmp_path / "d.json"
    assert main(["diagnose", "--db", str(db), "--session", "two", "--json", str(out),
                 "--no-sim"]) == 0
    text = capsys.readouterr().out
    assert "mote 1" in text and "mote 2" in text
    j1 = json.loads((tmp_path / "d-mote1.json").read_text())
    j2 = json.loads((tmp_path / "d-mote2.json").read_text())
    assert not j1["clean"] and j2["clean"]


@pytest.mark.parametrize("args,msg", [
    (["--session", "nope"], "nope"),
    (["--session", "clean", "--alpha", "2"], "--alpha"),
    (["--session", "clean", "--alpha", "nan"], "--alpha"),
    (["--session", "clean", "--alpha", "0"], "--alpha"),
    (["--session", "clean", "--seed", "-1"], "--seed"),
    (["--session", "clean", "--json", "/nonexistent-folder/x.json"], "does not exist"),
    (["--session", "two", "--mote", "9"], "no samples"),
])
def test_user_errors_are_one_line(db, capsys, args, msg):
    rc = main(["diagnose", "--db", str(db)] + args)
    err = capsys.readouterr().err
    assert rc == 2 and msg in err and len(err.strip().splitlines()) == 1
