"""Build the report's files for one session into a directory.

Every number comes from the calibration engine (``motecal.calib``):

* Tables I-III are ``calib.tables.table1/2/3`` of each mote's data (the same
  seed), laid out with a mote column; nothing is refitted or rounded here.
* The calibration the figures show (and the ``calibration`` table) is, in
  order of preference: the one given (``--cal``), the latest stored in the
  database for the mote, or ``calib.calibrate_board`` run now (full model,
  the report's seed) and judged by ``calib.decide``.

A table the session has no usable data for (no accelerometer, no still
gyroscope rows, no magnetometer set) is left out with a note; a session with
nothing to report raises ``QualityError``.  The sections on what the
calibration did come from the modules named in ``calsections``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import QualityError, UserError
from ..maths import sphere as S
from ..maths.stats import allan_deviation
from ..sessions.session import SENSOR_SLICES, UNITS, SessionData
from ..view import static_page
from ..view.state import session_state
from . import charts as CH
from . import calsections as CS
from . import choices, diagnosis, poses, temperature
from . import figures as F
from . import html as H
from .tables import Column, Table, write as write_table

# what the seed paper published (boards 1/2/3), shown under our tables for comparison
PAPER_TABLE1 = ("as published (boards 1/2/3): before 0.001156 / 0.003806 / 0.003849 g^2 "
                "(|v| 0.940-1.075 / 0.859-1.089 / 0.877-1.116); offsets 0.000033 / 0.000240 / "
                "0.000110; scales 0.001069 / 0.002762 / 0.003127; offsets + scales 0.000028 / "
                "0.000034 / 0.000033 (|v| 0.979-1.026 / 0.970-1.025 / 0.974-1.025); with angles "
                "unchanged to the 5th decimal")
PAPER_TABLE2 = ("as published (boards 1/2/3): error before 373.3 / 312.7 / 769.3, after "
                "12.84 / 11.98 / 6.25 (deg/s)^2; biases up to ~10-15 deg/s")
PAPER_TABLE3 = ("as published (boards 1/2/3): R set field 0.434 / 0.471 / 0.499 gauss, error "
                "0.000896 -> 0.000183 / 0.001508 -> 0.000311 / 0.000663 -> 0.000217; O set "
                "field 0.540 / 0.458 / 0.489, error 0.001401 -> 0.000257 / 0.001889 -> "
                "0.000243 / 0.000674 -> 0.000180 (offsets only -> all parameters)")

E = ".3e"       # Markdown format of errors (MSE)
M = ".4f"       # magnitudes, fields
B = ".3f"       # biases

TABLE1_COLUMNS = [
    Column("mote", "mote"), Column("parameters", "parameters"),
    Column("model", "model"), Column("identifiable", "identifiable parameters"),
    Column("error_before", "error before (g²)", E), Column("error_after", "error after (g²)", E),
    Column("min_before", "lowest magnitude before (g)", M),
    Column("max_before", "highest magnitude before (g)", M),
    Column("min_after", "lowest magnitude after (g)", M),
    Column("max_after", "highest magnitude after (g)", M)]
TABLE2_COLUMNS = [
    Column("mote", "mote"), Column("samples", "still samples"),
    Column("error_before", "error before ((deg/s)²)", ".4g"),
    Column("error_after", "error after ((deg/s)²)", ".4g"),
    Column("b_x", "bias x (deg/s)", B), Column("b_y", "bias y (deg/s)", B),
    Column("b_z", "bias z (deg/s)", B),
    Column("mean_x", "mean x (deg/s)", B), Column("mean_y", "mean y (deg/s)", B),
    Column("mean_z", "mean z (deg/s)", B)]
TABLE3_COLUMNS = [
    Column("mote", "mote"), Column("set", "data set"), Column("samples", "samples"),
    Column("field_offsets", "field, offsets only (gauss)", M),
    Column("error_offsets", "error, offsets only (gauss²)", E),
    Column("identifiable_offsets", "identifiable, offsets only"),
    Column("field_all", "field, all paper parameters (gauss)", M),
    Column("error_all", "error, all paper parameters (gauss²)", E),
    Column("identifiable_all", "identifiable, all paper parameters"),
    Column("field_full", "field, full model (gauss)", M),
    Column("error_full", "error, full model (gauss²)", E),
    Column("identifiable_full", "identifiable, full model"),
    Column("not_computable", "not computable")]
TABLE3_FITS = ("offsets", "all", "full")
CAL_COLUMNS = [
    Column("mote", "mote"), Column("sensor", "sensor"), Column("model", "model"),
    Column("dataset", "data"), Column("samples", "samples"), Column("poses", "poses"),
    Column("unit", "unit"),
    Column("mse_before", "error before", E), Column("mse_after", "error after", E),
    Column("mse_heldout", "held-out error", E),
    Column("min_before", "lowest magnitude before", M), Column("max_before", "highest magnitude before", M),
    Column("min_after", "lowest magnitude after", M), Column("max_after", "highest magnitude after", M),
    Column("field_gauss", "field (gauss)", M)]


def _identifiable(rank, params):
    """'6 of 9': identifiable parameters (Jacobian rank at the optimum) of all."""
    return None if rank is None else f"{int(rank)} of {int(params)}"


def _plural(n: int, word: str) -> str:
    return f"{n} {word}" + ("" if n == 1 else "s")


def _f(x):
    return None if x is None else float(x)


@dataclass
class MoteReport:
    mote: int
    data: SessionData
    board: object = None             # calib.BoardCalibration shown in the figures
    source: str = ""                 # where the board came from
    gate: dict = field(default_factory=dict)
    table1: list = field(default_factory=list)
    table2: list = field(default_factory=list)
    table3: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    figures: list = field(default_factory=list)    # [(section, FigureRef)]


# ------------------------------------------------------------------ inputs

def _load_cal(cal):
    from ..calib import BoardCalibration
    if cal is None or isinstance(cal, BoardCalibration):
        return cal
    if isinstance(cal, dict):
        try:
            return BoardCalibration.from_json(cal)
        except (KeyError, TypeError, ValueError) as e:
            raise UserError(f"calibration is malformed: {e!r}") from None
    board = BoardCalibration.load(cal)
    return board


def _load_data(store, session, mote):
    if isinstance(session, SessionData):
        data = session if mote is None else session.for_mote(mote)
        if mote is not None and len(data) == 0:
            raise UserError(f"session {session.name!r} has no samples of mote {mote}")
        return data
    if store is None:
        raise UserError("no database given")
    return store.load_session(str(session), mote)


def _stored_board(store, session_name, mote):
    """The latest calibration stored for this mote, or None."""
    from ..calib import BoardCalibration
    if store is None:
        return None
    try:
        d = store.load_calibration(session_name, mote)
    except UserError:
        return None
    try:
        return BoardCalibration.from_json(d)
    except (KeyError, TypeError, ValueError, UserError):
        return None


# ------------------------------------------------------------------ engine calls

def _usable(data: SessionData) -> dict:
    """Which tables the data can give (the engine's own row selections)."""
    from ..calib.board import mag_sets
    acc = (data.label >= 1) & data.has("accel")
    gyr = (data.label >= 1) & data.has("gyro")
    return {"table1": len(np.unique(data.label[acc])) >= 2,
            "table2": int(gyr.sum()) >= 10,
            "table3": bool(mag_sets(data))}


def _engine_tables(mr: MoteReport, seed: int, log) -> None:
    from ..calib import tables as CT
    from ..calib.board import mag_data_sets
    data, m = mr.data, mr.mote
    ok = _usable(data)
    if ok["table1"]:
        log(f"mote {m}: Table I (accelerometer, every parameter subset)")
        rows = CT.table1(data, seed=seed)
        before = rows[0]
        for r in rows[1:]:
            mr.table1.append({
                "mote": m, "parameters": r["parameters"],
                "model": "full (ours)" if r["parameters"] == "full model" else "paper",
                "identifiable": _identifiable(r["rank"], r["params"]),
                "error_before": _f(before["error"]), "error_after": _f(r["error"]),
                "min_before": _f(before["min"]), "max_before": _f(before["max"]),
                "min_after": _f(r["min"]), "max_after": _f(r["max"])})
    else:
        mr.notes.append("Table I: no accelerometer data in at least two static poses")
    if ok["table2"]:
        log(f"mote {m}: Table II (gyroscope bias, eq. 6)")
        n = int(((data.label >= 1) & data.has("gyro")).sum())
        for r in CT.table2(data, seed=seed):
            mr.table2.append({"mote": m, "samples": n,
                              **{k: _f(r[k]) for k in ("error_before", "error_after",
                                                       "b_x", "b_y", "b_z", "mean_x",
                                                       "mean_y", "mean_z")}})
    else:
        mr.notes.append("Table II: fewer than 10 still (labelled) gyroscope samples")
    sets = mag_data_sets(data)
    if ok["table3"]:
        log(f"mote {m}: Table III (magnetometer, data sets {', '.join(sets)})")
        for r in CT.table3(data, seed=seed):
            row = {"mote": m, "set": r["set"], "samples": int(r["n"]),
                   "not_computable": r["not_computable"]}
            for k in TABLE3_FITS:
                row[f"field_{k}"] = _f(r[f"field_{k}"])
                row[f"error_{k}"] = _f(r[f"error_{k}"])
                row[f"identifiable_{k}"] = _identifiable(r[f"rank_{k}"], r[f"params_{k}"])
            mr.table3.append(row)
    elif sets:
        mr.notes.append("Table III: no magnetometer data set can determine a model ("
                        + "; ".join(f"{k}: {why}" for k, (_, why) in sets.items()) + ")")
    else:
        mr.notes.append("Table III: no magnetometer data set (static poses O or rotation R)")


def _board_for(mr: MoteReport, store, session_name, cal, seed, log) -> None:
    from ..calib import calibrate_board, decide
    if cal is not None:
        mr.board, mr.source = cal, f"given calibration (mote {cal.mote}, session " \
                                   f"{cal.session!r}, created {cal.created})"
    else:
        stored = _stored_board(store, session_name, mr.mote)
        if stored is not None:
            mr.board = stored
            mr.source = f"latest calibration stored in the database (created {stored.created})"
        elif any(_usable(mr.data).values()):
            log(f"mote {mr.mote}: calibrating the board (full model, seed {seed})")
            mr.board = calibrate_board(mr.data, seed=seed)
            decide(mr.board)
            mr.source = (f"calibrated now by calib.calibrate_board (model full, seed {seed}); "
                         f"not stored")
    if mr.board is not None:
        mr.gate = dict(mr.board.gate or {})


# ------------------------------------------------------------------ figures

def _fig_sensor(mr: MoteReport, sensor: str, out: Path) -> list:
    """Magnitude, 3D, planes and residual-sphere figures of accel or mag."""
    from ..calib.board import mag_sets
    sc = getattr(mr.board, sensor, None) if mr.board is not None else None
    data = mr.data
    name = {"accel": "Accelerometer", "mag": "Magnetometer"}[sensor]
    if sc is None:
        if data.has(sensor).any():
            mr.notes.append(f"{name} figures: the calibration shown has no {sensor} part")
        return []
    if sensor == "accel":
        rows = (data.label >= 1) & data.has("accel")
        sets = None
    else:
        ms = mag_sets(data)
        rows = np.zeros(len(data), bool)
        for m in ms.values():
            rows |= m
        sets = np.where(data.label[rows] >= 1, "O", "R") if len(ms) > 1 else None
    if not rows.any():
        return []
    counts = data.sensor(sensor)[rows]
    before = counts / data.scales[sensor]
    after = sc.apply(counts)
    unit = UNITS[sensor]
    if sensor == "accel":
        ref_b, ref_a = 1.0, 1.0
    else:
        ref_b = float(np.mean(np.linalg.norm(before, axis=1)))   # best constant field
        ref_a = float(sc.field_gauss) if sc.field_gauss is not None else \
            float(np.mean(np.linalg.norm(after, axis=1)))
    tag = f"mote{mr.mote}"
    fig_no = {"accel": ("3", "5"), "mag": ("4", "6")}[sensor]
    what = f"{name}, mote {mr.mote} ({sc.model}, data {sc.dataset or '?'})"
    refs = []
    f = F.magnitude_per_sample(out / f"{tag}_{sensor}_magnitude.png", before, after, ref_b,
                               ref_a, unit, f"{name} magnitude per sample, mote {mr.mote}",
                               sets)
    refs.append(H.FigureRef(f.name, f"{name} magnitude per sample (paper Fig. {fig_no[0]})",
                            f"{what}. Top: counts / datasheet scale; bottom: calibrated. "
                            f"Dashed: expected magnitude."))
    f = F.scatter_3d(out / f"{tag}_{sensor}_scatter3d.png", before, after, ref_b, ref_a, unit,
                     f"{name} samples, mote {mr.mote}", sets)
    refs.append(H.FigureRef(f.name, f"{name} in 3D before and after (paper Fig. {fig_no[1]})",
                            f"{what}; wireframe: sphere of the expected magnitude."))
    f = F.scatter_planes(out / f"{tag}_{sensor}_planes.png", before, after, ref_b, ref_a, unit,
                         f"{name} samples in three planes, mote {mr.mote}", sets)
    refs.append(H.FigureRef(f.name, f"{name} in the xy, xz and yz planes "
                                    f"(paper Fig. {fig_no[1]})",
                            f"{what}; dashed: circle of the expected magnitude."))
    f = F.residual_sphere(out / f"{tag}_{sensor}_residual_sphere.png", before, after, ref_b,
                          ref_a, unit, f"{name}: magnitude residual against direction, "
                                       f"mote {mr.mote}")
    refs.append(H.FigureRef(f.name, f"{name} residual against direction",
                            "Mollweide (equal-area) map of the direction of each sample "
                            "(longitude atan2(y, x), latitude asin(z/|v|)), coloured by "
                            "|v| minus the expected magnitude; smooth patterns are "
                            "systematic errors the model leaves."))
    return refs


def _fig_set_aside(mr: MoteReport, sensor: str, out: Path) -> list:
    """The readings the robust fit set aside, in red over those it kept
    (issue 25); none when nothing was, or when the calibration shown was
    made from other rows than this session's."""
    sc = getattr(mr.board, sensor, None) if mr.board is not None else None
    rec = getattr(sc, "set_aside", None) or {}
    if sc is None or not rec.get("count"):
        return []
    data = mr.data
    aside = np.zeros(len(data), bool)
    for a, k in rec.get("rows", []):
        if a + k > len(data):
            mr.notes.append(f"{sensor}: the readings set aside are of other rows than this "
                            "session's; not drawn")
            return []
        aside[a:a + k] = True
    from ..calib.board import mag_sets
    if sensor == "accel":
        rows = (data.label >= 1) & data.has("accel")
    else:
        rows = mag_sets(data).get(sc.dataset, data.has("mag"))
    rows = rows | (aside & data.has(sensor))
    after = sc.apply(data.sensor(sensor)[rows])
    t = data.sample_times()[rows]
    ref = 1.0 if sensor == "accel" else float(sc.field_gauss or np.median(
        np.linalg.norm(after, axis=1)))
    name = {"accel": "Accelerometer", "mag": "Magnetometer"}[sensor]
    f = F.set_aside(out / f"mote{mr.mote}_{sensor}_set_aside.png", after, aside[rows],
                    t - (t[0] if len(t) else 0.0), ref, UNITS[sensor],
                    f"{name}: readings set aside by the robust fit, mote {mr.mote}")
    from ..calib.robust import set_aside_text
    return [H.FigureRef(f.name, f"{name}: readings set aside",
                        f"Calibrated readings, red: set aside ({set_aside_text(rec, sc.unit)}); "
                        "grey: kept. They do not pull the calibration; the gate refuses when "
                        "more than 20 % are set aside or one stretch lasts over 5 s.")]


def _fig_coverage(mr: MoteReport, out: Path) -> list:
    from ..calib.board import mag_sets
    from ..calib.gate import LIMITS
    data = mr.data
    sets = []
    for sensor in ("accel", "mag"):
        sc = getattr(mr.board, sensor, None) if mr.board is not None else None
        if sensor == "accel":
            groups = {"O": (data.label >= 1) & data.has("accel")}
        else:
            groups = mag_sets(data)
        for set_name, rows in groups.items():
            if not rows.any():
                continue
            counts = data.sensor(sensor)[rows]
            v = sc.apply(counts) if sc is not None else counts / data.scales[sensor]
            sets.append((f"{sensor} {set_name}", v))
    if not sets:
        return []
    f = F.coverage(out / f"mote{mr.mote}_coverage.png", sets,
                   f"Coverage of directions, mote {mr.mote}")
    return [H.FigureRef(f.name, "Coverage of directions",
                        f"Samples per cell of the sphere's equal-area grid "
                        f"({S.COVERAGE_BANDS} equal-height bands x {S.COVERAGE_SECTORS} "
                        f"sectors of longitude) of the calibrated direction; coverage is "
                        f"the share of cells holding a sample: the number the logger "
                        f"shows while a board is turned, and which the quality gate "
                        f"asks of a magnetometer sweep (at least "
                        f"{LIMITS.min_mag_coverage:.0%}).")]


def _fig_allan(mr: MoteReport, out: Path) -> list:
    data = mr.data
    runs = F.still_runs(data.label, data.seq, data.has("gyro"), data.t)
    if not runs:
        if data.has("gyro").any():
            mr.notes.append("Allan deviation: no still (labelled) gyroscope run of 8 samples")
        return []
    sc = getattr(mr.board, "gyro", None) if mr.board is not None else None
    g = data.sensor("gyro")
    series = [sc.apply(g[r]) if sc is not None else g[r] / data.scales["gyro"] for r in runs]
    rate = data.rate("gyro")
    tau, adev, _ = allan_deviation(series, rate)
    if len(tau) < 2:
        return []
    lengths = np.array([len(r) for r in runs])
    arw = adev[0] * np.sqrt(tau[0])
    note = (f"{len(runs)} still runs, {lengths.sum()} samples, longest {lengths.max() / rate:.1f} "
            f"s, at {rate:.4g} Hz")
    f = F.allan(out / f"mote{mr.mote}_gyro_allan.png", tau, adev, "deg/s",
                f"Gyroscope Allan deviation of still data, mote {mr.mote}", note)
    note += ("; angle random walk N = sigma(tau) sqrt(tau) at the shortest tau: "
             + ", ".join(f"{a} {v:.4f}" for a, v in zip("xyz", arw)) + " deg/sqrt(s)")
    return [H.FigureRef(f.name, "Gyroscope Allan deviation",
                        "Overlapping Allan deviation pooled over every still run (contiguous "
                        "samples of one static pose); the slope -1/2 part is white rate noise "
                        "(its value at tau = 1 s is the angle random walk), a flat bottom "
                        "would be the bias instability. " + note + ".")]


def _fig_trace(mr: MoteReport, out: Path) -> list:
    if mr.board is None:
        return []
    traces = []
    for name, sc in mr.board.sensors():
        tr = (sc.ga or {}).get("trace")
        if tr:
            traces.append((f"{name} {sc.model}", [np.nan if v is None else v for v in tr]))
    if not traces:
        return []
    f = F.convergence(out / f"mote{mr.mote}_ga_convergence.png", traces,
                      f"GA convergence, mote {mr.mote}")
    return [H.FigureRef(f.name, "GA convergence",
                        "Best fitness per generation of each sensor's GA run (the magnitude "
                        "models on the per-pose reduction, the gyroscope on eq. 6); the least-"
                        "squares polish on every sample follows the last generation.")]


# ------------------------------------------------------------------ tables

def _tables(reports: list[MoteReport]) -> list[Table]:
    out = []
    t1 = [r for mr in reports for r in mr.table1]
    if t1:
        from ..calib.board import ANGLE_NOTE
        out.append(Table("table1_accel", "Table I: accelerometer", TABLE1_COLUMNS, t1, [
            "error = mean over all static-pose samples of (|a| - 1 g)^2; before = counts / "
            "datasheet scale; after = the model fitted by the GA + least-squares polish",
            "model 'paper' = eqs. 1-5 with the listed parameter groups (every combination, "
            "as the paper tried); 'full (ours)' = bias + lower-triangular matrix (9 "
            "parameters, identifiable)",
            "identifiable parameters = numerical rank of the Jacobian at the optimum "
            "(calib.identify) of the number fitted: the rest can be traded without changing "
            "any residual",
            "angles: " + ANGLE_NOTE, PAPER_TABLE1]))
    t2 = [r for mr in reports for r in mr.table2]
    if t2:
        out.append(Table("table2_gyro", "Table II: gyroscope", TABLE2_COLUMNS, t2, [
            "error = the paper's eq. 6, mean of (|x - b_x| + |y - b_y| + |z - b_z|)^2 over "
            "still samples (deg/s); before: b = 0; biases: GA on eq. 6 + exact minimiser "
            "(the paper's method; on integer counts its minimiser sits on whole counts, "
            "0.07 deg/s steps); mean: the per-axis mean of the still rates, the bias "
            "motecal calibrate uses",
            PAPER_TABLE2]))
    t3 = [r for mr in reports for r in mr.table3]
    if t3:
        out.append(Table("table3_mag", "Table III: magnetometer", TABLE3_COLUMNS, t3, [
            "O = labelled static poses, R = rotation capture (label 'rot'; an unlabelled "
            "sweep counts as R); field = fitted ('optimized') magnitude in gauss",
            "error = mean of (|m| - field)^2; offsets only -> all paper parameters (offsets, "
            "scales, angles) -> full model (ours); identifiable = Jacobian rank at the "
            "optimum of the number fitted (the field counts)",
            "not computable: a set the quality gate's limits say cannot determine a model "
            "(too few distinct orientations, directions not around the centre, a sweep "
            "covering too little of the sphere) is not fitted",
            "gauge: det(A) = 1 in nominal units (the geometric-mean scale is the datasheet "
            "gain), so the field is in gauss as far as that gain is right",
            PAPER_TABLE3]))
    cal_rows = []
    for mr in reports:
        if mr.board is None:
            continue
        for name, sc in mr.board.sensors():
            ho = (sc.validation or {}).get("mse_heldout")
            cal_rows.append({
                "mote": mr.mote, "sensor": name, "model": sc.model, "dataset": sc.dataset,
                "samples": int(sc.n_samples), "poses": int(sc.n_poses), "unit": sc.unit,
                "mse_before": _f(sc.mse_before), "mse_after": _f(sc.mse_after),
                "mse_heldout": _f(ho), "min_before": _f(sc.min_before),
                "max_before": _f(sc.max_before), "min_after": _f(sc.min_after),
                "max_after": _f(sc.max_after),
                "field_gauss": _f(sc.field_gauss) if name == "mag" else None})
    if cal_rows:
        notes = [f"mote {mr.mote}: {mr.source}" for mr in reports if mr.board is not None]
        notes.append("errors in the sensor's unit squared (gyroscope: eq. 6); held-out = "
                     "k-fold over orientations (refit without each fold, error on it)")
        out.append(Table("calibration", "Calibration shown in the figures", CAL_COLUMNS,
                         cal_rows, notes))
    return out


# ------------------------------------------------------------------ the whole report

VIEW = "view.html"


def _view_section(store, session, data, out: Path, charts: dict) -> H.Section:
    """``view.html``: the 3D views of ``motecal log --view`` for the stored
    session (one self-contained file, the data embedded), with each mote's
    calibration charts (``charts``: mote -> [(heading, [chart])], the
    drawings of the sections above, drawn by the page's script)."""
    stats = events = None
    if store is not None and not isinstance(session, SessionData):
        stats, events = store.link_stats(data.name), store.events(data.name)
    doc = session_state(data, stats, events)
    for m in doc["motes"]:
        m["calibration"] = [{"heading": h, "charts": [CH.to_view(c) for c in cs]}
                            for h, cs in charts.get(m["id"], [])]
    (out / VIEW).write_text(static_page(doc), encoding="utf-8")
    return H.Section("view", "3D views",
                     "The views of motecal log --view, from the database: per mote the poses' "
                     "gravity directions beside the suggested ones, the board, the sweep's "
                     "magnetometer points raw and as fitted, the coverage cells and gaps, the "
                     "link counters, and the calibration's drawings of the sections above "
                     "(temperature, the gate, poses needed, diagnosis). One file with the data "
                     "inside (it runs a small script, nothing external).",
                     links=[(VIEW, "open the 3D views")])


def build_report(store, session, out_dir, *, mote=None, cal=None, seed: int = 0,
                 log=None, diagnosis_report=None) -> Path:
    """Write every file of the report into ``out_dir`` (an existing, empty
    directory); returns the index.html path.  ``diagnosis_report``: a
    ``motecal diagnose --report`` folder whose pictures the diagnosis
    section shows."""
    log = log or (lambda msg: None)
    out = Path(out_dir)
    board_given = _load_cal(cal)
    if board_given is not None and mote is not None and board_given.mote != mote:
        raise UserError(f"the calibration is for mote {board_given.mote}, not --mote {mote}")
    data = _load_data(store, session, mote)
    name = data.name
    if len(data) == 0:
        raise UserError(f"session {name!r} has no samples")
    motes = data.motes
    if board_given is not None and board_given.mote not in motes:
        raise UserError(f"the calibration is for mote {board_given.mote}; session {name!r} "
                        f"holds mote(s) {', '.join(map(str, motes))}")
    reports = []
    for m in motes:
        mr = MoteReport(m, data.for_mote(m) if len(motes) > 1 else data)
        _engine_tables(mr, seed, log)
        given = board_given if (board_given is not None and board_given.mote == m) else None
        _board_for(mr, store, name, given, seed, log)
        reports.append(mr)
    if not any(mr.table1 or mr.table2 or mr.table3 for mr in reports):
        reasons = "; ".join(n for mr in reports for n in mr.notes)
        raise QualityError(f"session {name!r}: no usable data for any table ({reasons})")

    tables = _tables(reports)
    for t in tables:
        write_table(t, out)

    sections = []
    by_name = {t.name: t for t in tables}
    sections.append(H.Section(
        "tables", "The paper's tables",
        "Computed from this session by the calibration engine (motecal.calib.tables), with "
        "our identifiable full model's rows beside the paper model's. Each table is also a "
        "CSV file (full precision) and a Markdown file.",
        tables=[by_name[k] for k in ("table1_accel", "table2_gyro", "table3_mag")
                if k in by_name],
        notes=[n for mr in reports for n in mr.notes if n.startswith("Table")]))
    if "calibration" in by_name:
        sections.append(H.Section("shown", "Calibration shown", tables=[by_name["calibration"]],
                                  notes=["the quality gate's verdict, reasons and warnings: "
                                         "'What the calibration chose' below"]))
    parts, view_charts = [], {}
    for mr in reports:
        log(f"mote {mr.mote}: the calibration's choices, temperature, poses needed")
        aside = _fig_set_aside(mr, "accel", out) + _fig_set_aside(mr, "mag", out)
        mine = [choices.part(mr, out, aside), temperature.part(mr, out), poses.part(mr, out)]
        log(f"mote {mr.mote}: figures")
        figs = [] if mine[0].section is not None else aside
        figs += _fig_sensor(mr, "accel", out)
        figs += _fig_sensor(mr, "mag", out)
        figs += _fig_coverage(mr, out)
        figs += _fig_allan(mr, out)
        figs += _fig_trace(mr, out)
        mine.append(diagnosis.part(mr, out, store, name, diagnosis_report, len(motes) > 1))
        sections += [p.section for p in mine if p.section is not None]
        view_charts[mr.mote] = [v for p in mine for v in p.view]
        parts += mine
        other = [n for n in mr.notes if not n.startswith("Table")]
        if figs or other:
            sections.append(H.Section(f"mote{mr.mote}", f"Figures, mote {mr.mote}",
                                      mr.source, figures=figs, notes=other))
    CS.part_tables(parts, out)
    sections.append(_view_section(store, session, data, out, view_charts))
    meta = [("session", name), ("kind", data.kind),
            ("motes", ", ".join(map(str, motes))), ("samples", str(len(data))),
            ("source", str(data.meta.get("source", ""))),
            ("chips", ", ".join(f"{s} {data.chips.get(s)} ({data.scales.get(s):g} LSB/"
                                f"{UNITS[s]})" for s in SENSOR_SLICES
                                if data.has(s).any())),
            ("GA seed of the tables", str(seed))]
    gates = [f"mote {mr.mote}: " + ("accepted" if mr.gate.get("accepted") else
                                   f"refused ({_plural(len(mr.gate.get('reasons', [])), 'reason')}, "
                                   f"see 'Calibration shown')")
             for mr in reports if mr.gate]
    if gates:
        meta.append(("quality gate of the calibration shown", "; ".join(gates)))
    meta += CS.meta_rows(parts)
    index = out / "index.html"
    index.write_text(H.render(f"motecal report: session {name}", meta, sections),
                     encoding="utf-8")
    return index
