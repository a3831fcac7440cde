"""motecal report: files, images, index.html links, tables equal to the
calibration engine's results, CSV == Markdown, bad input.  Budget ~60 s."""
import re
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
from matplotlib.image import imread

from motecal.calib import BoardCalibration, calibrate_board, decide
from motecal.calib import tables as CT
from motecal.commands.main import main
from motecal.errors import UserError
from motecal.report import build as B
from motecal.report import figures as F
from motecal.report import tables as T
from motecal.report import write_report
from motecal.sessions.importer import read_razor_float, read_razor_text
from motecal.sessions.session import LABEL_ROT, SessionData
from motecal.sessions.store import open_store
from motecal.sim import simulate_session

SEED = 7


def _concat(name, parts, motes=None):
    """One session from several SessionData (seq kept increasing per mote)."""
    raws, mote, seq, t, label, flags = [], [], [], [], [], []
    last = {}
    for i, d in enumerate(parts):
        m = np.full(len(d), motes[i] if motes else d.mote[0], np.int32)
        off = last.get(int(m[0]), -1) + 1000
        raws.append(d.raw)
        mote.append(m)
        seq.append(d.seq + off)
        t.append(d.t)
        label.append(d.label)
        flags.append(d.flags)
        last[int(m[0])] = int(seq[-1].max())
    first = parts[0]
    return SessionData(name, np.vstack(raws), np.concatenate(mote), np.concatenate(seq),
                       np.concatenate(t), np.concatenate(label), np.concatenate(flags),
                       kind=first.kind, scales=dict(first.scales), chips=dict(first.chips),
                       meta={"rate_hz": first.meta.get("rate_hz"), "source": "test"})


class _Links(HTMLParser):
    def __init__(self):
        super().__init__()
        self.refs, self.external = [], []

    def handle_starttag(self, tag, attrs):
        for k, v in attrs:
            if k in ("href", "src") and v:
                if re.match(r"^[a-z]+:", v) or v.startswith("//"):
                    self.external.append(v)
                elif not v.startswith("#"):
                    self.refs.append(v)
            if tag in ("script", "link", "iframe"):
                self.external.append(tag)


def _links(index: Path):
    p = _Links()
    p.feed(index.read_text(encoding="utf-8"))
    return p


# ------------------------------------------------------------------ fixtures

@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    """Simulated static80 + rotation capture of one mote in a database, and its report."""
    d = simulate_session("static80", motes=(1,), seed=SEED)[1]
    r = simulate_session("rotation", motes=(1,), seed=SEED)[1]
    r.t = r.t + d.t[-1] + 5.0
    data = _concat("simrep", [d, r])
    base = tmp_path_factory.mktemp("sim")
    db = base / "s.db"
    with open_store(str(db), create=True) as st:
        st.save_session(data)
        # what `motecal calibrate` does: the report shows the stored calibration
        board = calibrate_board(st.load_session("simrep"), seed=SEED)
        decide(board)
        st.save_calibration("simrep", 1, board.to_json())
        index = write_report(st, "simrep", base / "report", seed=SEED)
    return {"db": db, "data": data, "index": index, "out": index.parent, "base": base,
            "board": board}


@pytest.fixture(scope="module")
def measured_db(tmp_path_factory, measured):
    razor = read_razor_text(sorted((measured / "sensorstick-boards" / "razor1")
                                   .glob("razor1_acc_*.raw")))
    sweep = read_razor_float(measured / "sensorstick-mag-sweep" / "magnetom.float")
    both = _concat("razor_sweep", [razor, sweep], motes=[1, 2])
    db = tmp_path_factory.mktemp("measured") / "m.db"
    with open_store(str(db), create=True) as st:
        st.save_session(both)
        razor.name = "razor1"
        st.save_session(razor)
    return db


# ------------------------------------------------------------------ the simulated report

@pytest.mark.slow
def test_files_exist_images_decode_and_are_not_blank(sim):
    out = sim["out"]
    pngs = sorted(out.glob("*.png"))
    names = {p.name for p in pngs}
    for sensor in ("accel", "mag"):
        for kind in ("magnitude", "scatter3d", "planes", "residual_sphere"):
            assert f"mote1_{sensor}_{kind}.png" in names
    for other in ("coverage", "gyro_allan", "ga_convergence"):
        assert f"mote1_{other}.png" in names
    for p in pngs:
        img = imread(p)
        assert img.ndim == 3 and img.shape[0] > 200 and img.shape[1] > 300, p.name
        rgb = img[..., :3]
        assert rgb.var() > 1e-3, f"{p.name} is blank"
        # more than background and one colour
        q = (rgb * 15).round().astype(int)
        assert len(np.unique(q[..., 0] * 256 + q[..., 1] * 16 + q[..., 2])) > 20, p.name
    for t in ("table1_accel", "table2_gyro", "table3_mag", "calibration"):
        assert (out / f"{t}.csv").is_file() and (out / f"{t}.md").is_file()
    # nothing left behind by the temporary directory
    assert not [p for p in out.parent.iterdir() if p.name.startswith(".report.")]


def test_index_references_every_file_and_nothing_external(sim):
    out = sim["out"]
    links = _links(sim["index"])
    assert links.external == []
    refs = set(links.refs)
    for r in refs:
        assert (out / r).is_file(), f"index.html links to missing {r}"
        assert "/" not in r and ".." not in r
    on_disk = {p.name for p in out.iterdir() if p.name != "index.html"}
    assert on_disk <= refs, f"not referenced from index.html: {on_disk - refs}"
    html = sim["index"].read_text()
    assert html.count("<img ") == len(list(out.glob("*.png")))
    # Tables I-III, the calibration shown and its choices (no temperature, no diagnosis kept)
    assert html.count("<table>") == 5


def test_session_without_temperature_has_no_temperature_section_and_says_why(sim):
    """The simulated session carries no temperature: no temperature section,
    no temperature figure or table, and the page's head says why; the other
    sections of what the calibration did are there."""
    out, html = sim["out"], sim["index"].read_text()
    assert sim["data"].temp is None
    assert 'id="temperature-mote1"' not in html and not list(out.glob("*temperature*"))
    assert ("none in the session: the session carries no board temperature" in html)
    for anchor in ("choices-mote1", "poses-mote1"):
        assert f'<section id="{anchor}">' in html, anchor
    assert "none kept with the session" in html              # no diagnosis either
    rows = T.read_csv(out / "choices.csv")
    assert {r["temperature"] for r in rows} == {"none (no temperature in the session)"}


def _num(s):
    return float(s) if s not in ("", "nan") else None


def test_tables_equal_the_calibration_engine(sim):
    """Recomputed through calib.tables with the report's seed from another copy
    of the data (the report's is loaded from the database): bit for bit."""
    data, out = sim["data"], sim["out"]
    t1 = T.read_csv(out / "table1_accel.csv")
    ref1 = CT.table1(data, seed=SEED)
    before = ref1[0]
    assert [r["parameters"] for r in t1] == [r["parameters"] for r in ref1[1:]]
    # every combination of offsets, scales and angles the paper tried, and ours
    assert [r["parameters"] for r in t1] == [
        "offsets", "scales", "angles", "offsets + scales", "offsets + angles",
        "scales + angles", "offsets + scales + angles", "full model"]
    for row, ref in zip(t1, ref1[1:]):
        assert row["mote"] == "1"
        assert row["identifiable"] == f"{ref['rank']} of {ref['params']}"
        for k in ("error", "min", "max"):
            assert _num(row[f"{k}_after"]) == ref[k], (row["parameters"], k)
            assert _num(row[f"{k}_before"]) == before[k]
    # the paper's findings hold in the table: offsets+scales >> scales only; with
    # the scales free the angles change nothing (they cannot: they only multiply
    # the scales, 6 of 9 identifiable); without scales they are scales <= 1 on
    # y and z, between no scale and a free one; the full model beats the paper
    # model (simulated cross-axis error)
    err = {r["parameters"]: _num(r["error_after"]) for r in t1}
    ident = {r["parameters"]: r["identifiable"] for r in t1}
    assert err["offsets + scales"] < 0.2 * err["scales"]
    assert err["offsets + scales + angles"] == pytest.approx(err["offsets + scales"], rel=1e-9)
    assert err["scales + angles"] == pytest.approx(err["scales"], rel=1e-9)
    tol = 1 + 1e-9
    assert err["offsets + scales"] <= err["offsets + angles"] * tol
    assert err["offsets + angles"] <= err["offsets"] * tol
    assert err["scales"] <= err["angles"] * tol and err["angles"] <= before["error"] * tol
    # on this board an axis reads too long: shortening it helps a lot
    assert err["offsets + angles"] < 0.5 * err["offsets"]
    assert ident["offsets + scales + angles"] == "6 of 9"
    assert ident["offsets + scales"] == "6 of 6" and ident["full model"] == "9 of 9"
    assert err["full model"] < 0.9 * err["offsets + scales"]

    t2 = T.read_csv(out / "table2_gyro.csv")
    ref2 = CT.table2(data, seed=SEED)
    assert len(t2) == 1
    for k in ("error_before", "error_after", "b_x", "b_y", "b_z", "mean_x", "mean_y", "mean_z"):
        assert _num(t2[0][k]) == pytest.approx(ref2[0][k], rel=1e-9, abs=1e-12)
    assert int(t2[0]["samples"]) == int(((data.label >= 1) & data.has("gyro")).sum())

    t3 = T.read_csv(out / "table3_mag.csv")
    ref3 = CT.table3(data, seed=SEED)
    assert sorted(r["set"] for r in t3) == ["O", "R"]
    for row, ref in zip(t3, ref3):
        assert row["set"] == ref["set"] and int(row["samples"]) == ref["n"]
        for fit in ("offsets", "all", "full"):
            for k in (f"field_{fit}", f"error_{fit}"):
                assert _num(row[k]) == ref[k], k
            assert row[f"identifiable_{fit}"] == f"{ref['rank_' + fit]} of {ref['params_' + fit]}"
        assert (row["identifiable_offsets"], row["identifiable_all"],
                row["identifiable_full"]) == ("4 of 4", "6 of 9", "9 of 9")
        assert row["not_computable"] == "" and ref["not_computable"] is None
        assert _num(row["error_full"]) < _num(row["error_offsets"])
    assert int(next(r for r in t3 if r["set"] == "R")["samples"]) == \
        int((data.label == LABEL_ROT).sum())


def test_calibration_shown_is_the_stored_one(sim):
    """The calibration stored in the database is the one shown (its numbers in
    the calibration table); its full-model rows agree with Tables I-III (same
    objective, same optimum)."""
    board = sim["board"]
    rows = {r["sensor"]: r for r in T.read_csv(sim["out"] / "calibration.csv")}
    assert set(rows) == {"accel", "gyro", "mag"}
    for name, sc in board.sensors():
        r = rows[name]
        assert r["model"] == sc.model and r["dataset"] == sc.dataset
        assert int(r["samples"]) == sc.n_samples
        for k in ("mse_before", "mse_after", "min_before", "max_before", "min_after",
                  "max_after"):
            assert _num(r[k]) == getattr(sc, k), (name, k)
    assert _num(rows["mag"]["field_gauss"]) == board.mag.field_gauss
    assert "stored in the database" in (sim["out"] / "calibration.md").read_text()
    t1 = {r["parameters"]: r for r in T.read_csv(sim["out"] / "table1_accel.csv")}
    # Table I is the paper's least squares over every sample; calibrate's error
    # after is its robust fit's, over the samples it kept (a few per mille set aside)
    assert _num(t1["full model"]["error_after"]) == pytest.approx(board.accel.mse_after,
                                                                   rel=1e-2)
    t2 = T.read_csv(sim["out"] / "table2_gyro.csv")[0]
    for i, axis in enumerate("xyz"):     # eq. 6 minimiser (the paper's), and the mean used
        assert _num(t2[f"b_{axis}"]) == pytest.approx(board.gyro.extra["bias_eq6"][i], abs=1e-9)
        assert _num(t2[f"mean_{axis}"]) == pytest.approx(board.gyro.param(f"b_{axis}").value,
                                                         abs=1e-12)
    t3 = {r["set"]: r for r in T.read_csv(sim["out"] / "table3_mag.csv")}
    # Table III is least squares over every reading, calibrate's field its robust fit's
    assert _num(t3["R"]["field_full"]) == pytest.approx(board.mag_sets["R"]["field_gauss"],
                                                        rel=1e-4)
    # the gate's decision on it is in the page header
    html = sim["index"].read_text()
    state = "accepted" if board.gate.get("accepted") else "refused"
    assert f"mote 1: {state}" in html


def test_csv_and_markdown_agree(sim):
    tables = {"table1_accel": B.TABLE1_COLUMNS, "table2_gyro": B.TABLE2_COLUMNS,
              "table3_mag": B.TABLE3_COLUMNS, "calibration": B.CAL_COLUMNS}
    for name, cols in tables.items():
        csv_rows = T.read_csv(sim["out"] / f"{name}.csv")
        md_rows = T.read_markdown(sim["out"] / f"{name}.md")
        assert len(csv_rows) == len(md_rows) > 0, name
        assert list(md_rows[0]) == [c.header for c in cols]
        for c_row, m_row in zip(csv_rows, md_rows):
            for c in cols:
                cv, mv = c_row[c.key], m_row[c.header]
                if c.fmt and cv not in ("", "nan"):
                    assert mv == format(float(cv), c.fmt), (name, c.key)
                    assert float(mv) == pytest.approx(float(cv), rel=1e-2, abs=1e-3)
                elif cv == "":
                    assert mv == "", (name, c.key)
                else:
                    assert mv == cv, (name, c.key)


# ------------------------------------------------------------------ measured data, CLI

@pytest.mark.slow
def test_cli_measured_two_motes_tables_per_mote(measured_db, tmp_path, capsys):
    out = tmp_path / "rep"
    assert main(["report", "--db", str(measured_db), "--session", "razor_sweep",
                 "--out", str(out), "--seed", "3"]) == 0
    captured = capsys.readouterr()
    assert captured.err == ""
    assert f"report written: {out / 'index.html'}" in captured.out
    # mote 1: the six razor1 accel poses (Tables I and II; their field directions
    # do not surround the centre: no magnetometer set); mote 2: the sweep (Table III)
    t1 = T.read_csv(out / "table1_accel.csv")
    assert {r["mote"] for r in t1} == {"1"} and len(t1) == len(CT.ACCEL_ROWS) + 1
    t3 = T.read_csv(out / "table3_mag.csv")
    assert sorted((r["mote"], r["set"]) for r in t3) == [("2", "R")]
    assert ("Table III: no magnetometer data set can determine a model (O: poses too "
            "clustered") in (out / "index.html").read_text()
    with open_store(str(measured_db)) as st:
        sweep = st.load_session("razor_sweep", 2)
    ref = CT.table3(sweep, seed=3)[0]
    row = next(r for r in t3 if r["mote"] == "2")
    assert _num(row["field_full"]) == ref["field_full"]
    assert _num(row["error_all"]) == ref["error_all"]
    # measured sweep (HMC5883L, Sensor Stick): a field of roughly half a gauss
    assert 0.3 < _num(row["field_full"]) < 0.7
    names = {p.name for p in out.glob("*.png")}
    assert "mote2_mag_magnitude.png" in names and "mote2_accel_magnitude.png" not in names
    assert "mote1_accel_magnitude.png" in names
    links = _links(out / "index.html")
    assert {p.name for p in out.iterdir()} - {"index.html"} <= set(links.refs)
    # nothing stored: each board calibrated now with the report's seed
    cal = {(r["mote"], r["sensor"]): r for r in T.read_csv(out / "calibration.csv")}
    assert sorted(cal) == [("1", "accel"), ("1", "gyro"), ("2", "mag")]
    board2 = calibrate_board(sweep, seed=3)
    assert cal[("2", "mag")]["dataset"] == "R"
    assert _num(cal[("2", "mag")]["mse_after"]) == board2.mag.mse_after
    assert _num(cal[("2", "mag")]["field_gauss"]) == board2.mag.field_gauss
    assert "calibrated now" in (out / "calibration.md").read_text()


def test_given_and_stored_calibration_are_shown(measured_db, tmp_path):
    with open_store(str(measured_db)) as st:
        data = st.load_session("razor_sweep", 2)
        board = calibrate_board(data, model="paper", groups=("offsets", "scales"), seed=1)
        cal = tmp_path / "cal.json"
        board.save(cal)
        out = tmp_path / "given"
        write_report(st, "razor_sweep", out, mote=2, cal=str(cal))
        rows = {r["sensor"]: r for r in T.read_csv(out / "calibration.csv")}
        assert set(rows) == {"mag"}
        assert rows["mag"]["model"] == "paper(offsets+scales)"
        assert _num(rows["mag"]["mse_after"]) == board.mag.mse_after
        assert _num(rows["mag"]["field_gauss"]) == board.mag.field_gauss
        assert "given calibration" in (out / "calibration.md").read_text()
        # the magnitude figure's 'after' panel is that calibration applied to the
        # sweep; its lowest magnitude over the readings the fit kept is min_after
        kept = data.has("mag").copy()
        for a, k in board.mag.set_aside["rows"]:
            kept[a:a + k] = False
        m = np.linalg.norm(board.mag.apply(data.sensor("mag")[kept]), axis=1)
        assert m.min() == pytest.approx(board.mag.min_after)
        # a calibration for another mote is refused
        with pytest.raises(UserError, match="mote 2"):
            write_report(st, "razor_sweep", tmp_path / "x", mote=1, cal=str(cal))
        # stored in the database: used without --cal; the earlier report is replaced
        st.save_calibration("razor_sweep", 2, BoardCalibration.loads(cal.read_text()).to_json())
        (out / "mote2_coverage.png").unlink()          # the new report brings it back
        write_report(st, "razor_sweep", out, mote=2)
        rows2 = {r["sensor"]: r for r in T.read_csv(out / "calibration.csv")}
        assert rows2["mag"]["model"] == "paper(offsets+scales)"
        assert _num(rows2["mag"]["mse_after"]) == board.mag.mse_after
        text = (out / "calibration.md").read_text()
        assert "stored in the database" in text and "given calibration" not in text
        assert (out / "mote2_coverage.png").is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cal.json", "given"]


# ------------------------------------------------------------------ bad input

def _err(capsys, argv, code):
    rc = main(argv)
    cap = capsys.readouterr()
    assert rc == code, cap
    lines = cap.err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in cap.err, cap.err
    return lines[0]


def test_bad_input_one_line_nonzero_nothing_written(measured_db, tmp_path, capsys):
    db = str(measured_db)
    out = tmp_path / "r"
    line = _err(capsys, ["report", "--db", db, "--session", "nope", "--out", str(out)], 2)
    assert "nope" in line
    assert not out.exists()
    assert _err(capsys, ["report", "--db", str(tmp_path / "missing.db"), "--session", "x",
                         "--out", str(out)], 2)
    # unwritable output: a file where the parent directory should be, and /proc
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert "parent" in _err(capsys, ["report", "--db", db, "--session", "razor1",
                                     "--out", str(blocker / "r")], 2)
    assert "cannot write" in _err(capsys, ["report", "--db", db, "--session", "razor1",
                                           "--out", "/proc/motecal-report"], 2)
    # a directory that is not an earlier report is not replaced
    other = tmp_path / "other"
    other.mkdir()
    (other / "keep.txt").write_text("mine")
    assert "not empty" in _err(capsys, ["report", "--db", db, "--session", "razor1",
                                        "--out", str(other)], 2)
    assert (other / "keep.txt").read_text() == "mine"
    # unknown mote, wrong --cal
    assert "mote 9" in _err(capsys, ["report", "--db", db, "--session", "razor1",
                                     "--mote", "9", "--out", str(out)], 2)
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    assert "JSON" in _err(capsys, ["report", "--db", db, "--session", "razor1",
                                   "--cal", str(bad), "--out", str(out)], 2)
    for s in ("-1", "x"):            # numpy's SeedSequence takes whole numbers >= 0
        assert "--seed" in _err(capsys, ["report", "--db", db, "--session", "razor1",
                                         "--seed", s, "--out", str(out)], 2)
    assert not out.exists()
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


def test_session_with_no_usable_data_is_refused(tmp_path, capsys):
    """Accelerometer only, never still (free motion, no labels): no table."""
    d = simulate_session("free", motes=(1,), seed=1, duration=5.0)[1]
    d.raw[:, 3:9] = np.nan
    d.label[:] = 0
    d.name = "moving"
    db = tmp_path / "f.db"
    with open_store(str(db), create=True) as st:
        st.save_session(d)
    out = tmp_path / "r"
    line = _err(capsys, ["report", "--db", str(db), "--session", "moving", "--out", str(out)],
                3)
    assert "no usable data" in line and "Table I" in line
    assert not out.exists() and [p for p in tmp_path.iterdir() if p.name.startswith(".")] == []


def test_failure_midway_leaves_nothing(measured_db, tmp_path, monkeypatch):
    def boom(*a, **k):               # after the tables and some figures are written
        raise RuntimeError("disk full")
    monkeypatch.setattr(F, "convergence", boom)
    out = tmp_path / "r"
    with open_store(str(measured_db)) as st:
        with pytest.raises(RuntimeError):
            write_report(st, "razor_sweep", out, mote=2)
    assert list(tmp_path.iterdir()) == []


def test_no_traceback_through_the_command(tmp_path):
    r = subprocess.run([sys.executable, "-m", "motecal", "report", "--db",
                        str(tmp_path / "none.db"), "--session", "s", "--out",
                        str(tmp_path / "o")], capture_output=True, text=True, timeout=60)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1


# ------------------------------------------------------------------ pure helpers

def test_still_runs_split_on_label_and_gaps():
    label = np.array([1] * 10 + [0] * 3 + [2] * 10 + [2] * 10)
    seq = np.arange(len(label))
    seq[23:] += 5                       # lost packets inside pose 2
    ok = np.ones(len(label), bool)
    runs = F.still_runs(label, seq, ok)
    assert [len(r) for r in runs] == [10, 10, 10]


def test_readings_set_aside_are_drawn(tmp_path):
    """A glitchy sweep (tests/contaminated.py): the report draws its readings
    with those the robust fit set aside in red, and says how many."""
    import contaminated as CTM
    p = CTM.sweep(5, rate=0.05, size=(0.1, 0.5), stretch_s=1.0)
    db = tmp_path / "g.db"
    with open_store(str(db), create=True) as st:
        st.save_session(p.data)
        board = calibrate_board(st.load_session(p.data.name), seed=SEED, kfold=0)
        decide(board)
        st.save_calibration(p.data.name, 1, board.to_json())
        index = write_report(st, p.data.name, tmp_path / "report", seed=SEED)
    fig = index.parent / "mote1_mag_set_aside.png"
    assert fig.is_file() and fig.name in index.read_text(encoding="utf-8")
    assert f"set aside {board.mag.set_aside['count']} of" in index.read_text(encoding="utf-8")
    rgb = imread(fig)[..., :3]
    red = (rgb[..., 0] > 0.7) & (rgb[..., 1] < 0.35) & (rgb[..., 2] < 0.35)
    assert red.sum() > 200                                   # the set-aside readings drawn
