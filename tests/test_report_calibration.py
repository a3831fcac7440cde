"""The report shows what the calibration did (issue 33): a warming board
(the simulator's ``thermal`` model: a 2-minute warm-up hold from power-on,
then 30 poses), diagnosed with ``motecal diagnose --report``, calibrated with
``motecal calibrate`` (which uses the kept diagnosis and keeps the poses-needed
curve) and reported with ``motecal report --diagnosis-report``.  Checked:

* the temperature section: the board temperature over the session and, per
  sensor, each axis' still offset against temperature without and with the
  temperature term, the fitted line with its band, flat outside its valid
  range; the table equal to cal.json;
* the calibration's choices (model per sensor, the gate's verdict and
  metrics), the poses needed (the curve kept in cal.json), the diagnosis
  kept with the session (findings, gains, the evidence pictures copied and
  linked);
* in headless Chromium (tests/browser.py, as the live view's test): every
  figure of these sections in index.html is loaded and not blank (the pixel
  variance of its region on the page), and view.html draws the same charts
  on canvases.  The screenshots of each section land in the test's temporary
  folder; ``scripts/report_shots.py`` copies them to docs/img.

A session without temperature (tests/test_report.py's) has no temperature
section and says why there.
"""
import copy
import json
import re
import sys
from pathlib import Path

import numpy as np
import pytest
from matplotlib.image import imread

from motecal.calib import BoardCalibration
from motecal.calib.design import describe_poses_needed
from motecal.commands.main import main
from motecal.report import poses as RP
from motecal.report import temperature as TT
from motecal.report import tables as T
from motecal.sessions.store import open_store
from warmup import thermal_board, warmup_session

SEED = 5
NAMES = {"accel": "accelerometer", "gyro": "gyroscope", "mag": "magnetometer"}
SECTIONS = ("choices", "temperature", "poses", "diagnosis")
SHOTS = {"choices": "report-choices.png", "temperature": "report-temperature.png",
         "poses": "report-poses.png", "diagnosis": "report-diagnosis.png"}


@pytest.fixture(scope="module")
def warm(tmp_path_factory):
    base = tmp_path_factory.mktemp("warm")
    _, board = thermal_board(SEED)
    ses = warmup_session(board, SEED, hold_s=120.0, n_poses=30)
    ses.name = "warm"
    db = str(base / "w.db")
    with open_store(db, create=True) as st:
        st.save_session(ses)
    diag, cal, out = base / "diag", base / "cal.json", base / "report"
    assert main(["diagnose", "--db", db, "--session", "warm", "--report", str(diag),
                 "--no-sim"]) == 0
    assert main(["calibrate", "--db", db, "--session", "warm", "--out", str(cal), "--seed",
                 "1", "--kfold", "3"]) == 0
    assert main(["report", "--db", db, "--session", "warm", "--out", str(out),
                 "--diagnosis-report", str(diag), "-q"]) == 0
    with open_store(db) as st:
        kept = st.load_diagnosis("warm", 1)
    return {"db": db, "data": ses, "out": out, "cal": BoardCalibration.load(cal),
            "cal_json": json.loads(cal.read_text()), "diag": diag, "kept": kept,
            "html": (out / "index.html").read_text(encoding="utf-8")}


def _view_doc(out: Path) -> dict:
    page = (out / "view.html").read_text(encoding="utf-8")
    m = re.search(r"window\.MOTECAL_STATE = (\{.*?\});</script>", page, re.S)
    return json.loads(m.group(1).replace("<\\/", "</"))


def _groups(out: Path) -> dict:
    return {g["heading"]: g["charts"] for g in _view_doc(out)["motes"][0]["calibration"]}


def _section(html: str, anchor: str) -> str:
    m = re.search(rf'<section id="{anchor}">(.*?)</section>', html, re.S)
    assert m, f"no section {anchor}"
    return m.group(1)


def _not_blank(path: Path):
    img = imread(path)[..., :3]
    assert img.shape[0] > 100 and img.shape[1] > 300, path.name
    assert img.var() > 1e-3, f"{path.name} is blank"


def _series(chart, label):
    return next(s for s in chart["series"] if s.get("label") == label)


def _arr(v):
    return np.array([np.nan if x is None else x for x in v], float)


# ------------------------------------------------------------------ temperature

def test_temperature_section_draws_each_sensor_raw_and_corrected(warm):
    out, cal = warm["out"], warm["cal"]
    sec = _section(warm["html"], "temperature-mote1")
    files = ["mote1_temperature_session.png"] + [f"mote1_{s}_temperature.png"
                                                  for s in ("accel", "gyro", "mag")]
    for f in files:
        assert f'src="{f}"' in sec, f
        _not_blank(out / f)
    groups = _groups(out)
    assert "board temperature" in groups
    for name, sc in cal.sensors():
        tm = sc.temperature
        assert tm is not None, (name, sc.notes)
        charts = groups[f"{NAMES[name]} against temperature"]
        assert [c["title"] for c in charts[:3]] == ["x axis", "y axis", "z axis"]
        for i, ch in enumerate(charts[:3]):
            raw = _series(ch, "without the temperature term")
            cor = _series(ch, "corrected (as delivered)")
            assert len(raw["x"]) >= 3 and len(raw["x"]) == len(cor["x"]), (name, i)
            # the fitted term: through 0 at t_ref, -offset per C (the magnetometer: -
            # its sensitivity, in %) inside the range, flat (clamped) outside it
            line = _series(ch, "fitted term")
            x, y = _arr(line["x"]), _arr(line["y"])
            k = (100 * tm.scale_per_c[i]) if name == "mag" else tm.offset_per_c[i]
            want = -k * (np.clip(x, *tm.range_c) - tm.t_ref_c)
            assert np.allclose(y, want, rtol=1e-4, atol=1e-4 * np.abs(want).max())
            assert x.min() < tm.range_c[0] and x.max() > tm.range_c[1]
            assert _series(ch, "outside the valid range: clamped")
    # the gyroscope drifts with the planted warm-up: corrected, its still offset
    # no longer follows the temperature
    axes = groups["gyroscope against temperature"][:3]
    raw = np.concatenate([_arr(_series(c, "without the temperature term")["y"]) for c in axes])
    cor = np.concatenate([_arr(_series(c, "corrected (as delivered)")["y"]) for c in axes])
    assert np.sqrt(np.mean(cor ** 2)) < np.sqrt(np.mean(raw ** 2)) / 3, (raw, cor)


def test_a_chip_lagging_the_recorded_temperature_is_drawn_against_its_own(warm):
    """With a lag in the accelerometer's term (calibrate's calib.templag), its
    points sit at the recorded temperature through that lag, and the
    session's figure draws the chip's temperature."""
    from motecal.calib.content import recording_parts
    board = BoardCalibration.from_json(copy.deepcopy(warm["cal_json"]))
    tm = board.accel.temperature
    tm.lag_s = 20.0
    data = warm["data"]
    holds = board.settings["temperature"]["holds"]
    sd = TT.SensorData("accel", board.accel, data, holds)
    chip = tm.lagged(data.temp, data.sample_times(), recording_parts(data))
    assert np.abs(chip - data.temp)[np.isfinite(data.temp)].max() > 0.3   # a lag that shows
    t = data.sample_times()
    ok = data.has("accel") & np.isfinite(chip)
    want = [chip[g].mean() for g in TT.blocks(t, data.label, ok, holds)]
    assert np.allclose(sd.axes[0][0][:len(want)], want)
    charts = TT.sensor_charts(sd)
    assert "20 s lag" in charts[0]["xlabel"]
    sess = TT.session_chart(data, board)
    assert any(s.get("label") == "accel chip: 20 s behind" for s in sess["series"])


def test_temperature_table_is_the_calibrations(warm):
    rows = {(r["sensor"], r["term"]): r for r in T.read_csv(warm["out"] / "temperature.csv")}
    for name, sc in warm["cal"].sensors():
        tm = sc.temperature
        term = "sensitivity change" if name == "mag" else "offset correction"
        r = rows[(name, term)]
        k = -100 * tm.scale_per_c if name == "mag" else tm.offset_per_c
        assert [float(r[a]) for a in "xyz"] == pytest.approx(list(k), rel=1e-12)
        assert float(r["valid_from"]) == tm.range_c[0] and float(r["valid_to"]) == tm.range_c[1]
        assert float(r["t_ref"]) == tm.t_ref_c
        assert float(r["heldout_without"]) == tm.extra["heldout_rms_before"]
        assert float(r["heldout_with"]) == tm.extra["heldout_rms_after"]


# ------------------------------------------------------------------ choices, gate

def test_choices_and_the_gates_verdict(warm):
    out, cal = warm["out"], warm["cal"]
    rows = {r["sensor"]: r for r in T.read_csv(out / "choices.csv")}
    assert set(rows) == {"accel", "gyro", "mag"}
    for name, sc in cal.sensors():
        assert rows[name]["model"] == sc.model
        assert rows[name]["temperature"].startswith(("offset per C", "sensitivity per C"))
    sec = _section(warm["html"], "choices-mote1")
    verdict = "accepted" if cal.gate["accepted"] else "refused"
    assert f"gate: {verdict}" in sec and 'src="mote1_gate.png"' in sec
    _not_blank(out / "mote1_gate.png")
    (gate,) = _groups(out)[f"quality gate: {verdict}"]
    bars = gate["series"][0]
    assert len(bars["labels"]) >= 6 and all(v > 0 for v in bars["values"])


# ------------------------------------------------------------------ poses needed

def test_poses_needed_curve_kept_by_calibrate_and_drawn(warm):
    pn = warm["cal_json"]["accel"]["quality"]["poses_needed"]
    cur = pn["curve"]
    assert cur["k"][0] == 12 and cur["k"][-1] == pn["poses"]
    assert len(cur["order"]) == pn["poses"]
    for s, b in pn["bounds_all"].items():          # all the poses: the promise printed
        assert cur["in_order"][s][-1] == b and cur["best_subset"][s][-1] == b
    sec = _section(warm["html"], "poses-mote1")
    assert "as motecal calibrate computed it" in sec
    for line in describe_poses_needed(pn):
        assert line.strip() in sec
    _not_blank(warm["out"] / "mote1_poses_needed.png")
    charts = _groups(warm["out"])["poses needed"]
    assert len(charts) == len(pn["sensors"])


def test_poses_needed_computed_for_a_calibration_without_its_curve(warm):
    """A cal.json from before the curve was kept: the report computes it with
    the same criterion and says so."""
    board = BoardCalibration.from_json(copy.deepcopy(warm["cal_json"]))
    old = dict(board.accel.quality["poses_needed"])
    del old["curve"]
    board.accel.quality["poses_needed"] = old
    pn, source = RP.stored_or_computed(board, warm["data"])
    assert source.startswith("computed by the report")
    assert pn["curve"] == warm["cal_json"]["accel"]["quality"]["poses_needed"]["curve"]
    assert "curve" not in board.accel.quality["poses_needed"]       # nothing stored


# ------------------------------------------------------------------ diagnosis

def test_diagnosis_kept_with_the_session_its_gains_and_pictures(warm):
    out, kept = warm["out"], warm["kept"]
    findings = kept["diagnosis"]["findings"]
    assert findings, "the warming board has findings (temperature at least)"
    rows = T.read_csv(out / "diagnosis.csv")
    assert [(r["sensor"], r["cause"]) for r in rows] == [(f["sensor"], f["cause"])
                                                         for f in findings]
    for r, f in zip(rows, findings):
        assert float(r["gain"]) == f["gain"]
    assert any(f["cause"] == "temperature" for f in findings)
    sec = _section(warm["html"], "diagnosis-mote1")
    assert f"database diagnosis {kept['id']}" in sec and "these very rows" in sec
    for i, f in enumerate(findings, 1):
        pic = f"diagnosis-mote1/finding{i}-{f['sensor']}-{f['cause']}.png"
        assert f'src="{pic}"' in sec, pic
        assert (out / pic).read_bytes() == (warm["diag"] / Path(pic).name).read_bytes()
    # the report's own figure of a temperature finding is linked
    t = next(f for f in findings if f["cause"] == "temperature")
    assert f'href="mote1_{t["sensor"]}_temperature.png"' in sec
    _not_blank(out / "mote1_diagnosis.png")
    # what calibrate did with it
    used = warm["cal_json"]["settings"]["diagnosis"]
    assert used.get("kept") == kept["id"]


def test_diagnosis_report_folder_missing_is_one_line(warm, tmp_path, capsys):
    rc = main(["report", "--db", warm["db"], "--session", "warm", "--out",
                str(tmp_path / "r"), "--diagnosis-report", str(tmp_path / "nope")])
    assert rc == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--diagnosis-report" in err[0], err
    assert not (tmp_path / "r").exists()


# ------------------------------------------------------------------ in Chromium

INK = """(function(c){var d=c.getContext('2d').getImageData(0,0,c.width,c.height).data, n=0;
  for (var i=3;i<d.length;i+=4) if (d[i]>0) n++; return n;})"""
RECT = """(function(e){var r=e.getBoundingClientRect();
  return {x: r.left + window.scrollX, y: r.top + window.scrollY, width: r.width,
          height: r.height};})"""


def _whole_page(b, width=1100):
    """The viewport as tall as the page: what a clip beyond the viewport
    shows is then painted (text far below it may not be)."""
    h = int(b.eval("document.documentElement.scrollHeight"))
    b.call("Emulation.setDeviceMetricsOverride", width=width, height=h, deviceScaleFactor=1,
           mobile=False)


def _region_var(b, tmp_path, js_el, name) -> float:
    rect = b.eval(f"{RECT}({js_el})")
    assert rect["width"] > 50 and rect["height"] > 50, (name, rect)
    p = tmp_path / f"region-{name}.png"
    b.screenshot(p, clip=rect)
    return float(imread(p)[..., :3].var())


@pytest.mark.slow
def test_report_in_chromium(warm, tmp_path):
    """index.html and view.html of the warming board's report in headless
    Chromium: each new section's figures are there, loaded and not blank;
    view.html draws every calibration chart; a screenshot of each section."""
    from browser import Browser, chromium
    if chromium() is None:
        pytest.fail("chromium is missing: `make test` installs it (TEST_PACKAGES)",
                    pytrace=False)
    out = warm["out"]
    shots = tmp_path / "shots"
    shots.mkdir()
    with Browser(tmp_path, width=1100, height=900) as b:
        b.open((out / "index.html").as_uri())
        b.wait_for("Array.from(document.images).every(function(i){return i.complete;})")
        _whole_page(b)
        for s in SECTIONS:
            sel = f"document.getElementById('{s}-mote1')"
            assert b.eval(f"!!{sel}"), s
            imgs = b.eval(f"Array.from({sel}.querySelectorAll('img')).map(function(i){{"
                          f"return [i.getAttribute('src'), i.naturalWidth, i.naturalHeight];}})")
            assert imgs, f"section {s} has no figure"
            for k, (src, w, h) in enumerate(imgs):
                assert w > 300 and h > 100, (s, src, w, h)          # loaded
                v = _region_var(b, tmp_path, f"{sel}.querySelectorAll('img')[{k}]",
                                f"{s}-{k}")
                assert v > 1e-3, f"{src} is blank on the page ({v})"
            b.screenshot(shots / SHOTS[s], clip=b.eval(f"{RECT}({sel})"))
        # view.html: the same drawings on canvases
        b.open((out / "view.html").as_uri())
        b.wait_for("document.querySelectorAll('canvas.chart').length > 0")
        _whole_page(b)
        want = sum(len(g["charts"]) for g in _view_doc(out)["motes"][0]["calibration"])
        n = b.eval("document.querySelectorAll('canvas.chart').length")
        assert n == want >= 10, (n, want)
        for k in range(n):
            cv = f"document.querySelectorAll('canvas.chart')[{k}]"
            assert b.eval(f"{INK}({cv})") > 2000, k
            assert _region_var(b, tmp_path, cv, f"view-{k}") > 1e-3, k
        titles = b.eval("Array.from(document.querySelectorAll('canvas.chart'))"
                        ".map(function(c){return c.dataset.title;})")
        assert "x axis" in titles and any(t.startswith("quality gate") for t in titles)
        b.screenshot(shots / "view-report-calibration.png",
                     clip=b.eval(f"{RECT}(document.getElementById('m1-calib'))"))
    for name in list(SHOTS.values()) + ["view-report-calibration.png"]:
        _not_blank(shots / name)
    print(f"screenshots in {shots}", file=sys.stderr)
