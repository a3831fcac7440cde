"""The report's temperature section: what ``motecal calibrate`` fitted
against the board temperature (``calib.thermal``, stored per sensor as a
``TempModel`` in cal.json), drawn from that stored model and the session's
own rows -- nothing is refitted here.

Per mote: the board temperature over the session, and per sensor each
axis' still offset against temperature twice -- through the calibration
without its temperature term ("uncorrected") and through the calibration
as delivered ("corrected") -- with the fitted term as a line, its band of
2 standard deviations, and the range it is valid in (outside it the
temperature is clamped, as on the mote: the line is flat there).  What a
sensor's still data show on each axis:

* gyroscope: the still rate of every 1 s block of the static poses and
  holds (its truth is 0); the term predicts ``-offset_per_c dT``;
* accelerometer and magnetometer in a hold (one orientation, the warm-up):
  the change of each axis within the hold (a hold shows changes, not the
  level: each hold is placed on the line at its mean);
* accelerometer and magnetometer over poses or a sweep: the magnitude error
  of the readings whose direction lies within 30 deg of an axis, divided by
  that axis' share (the offset or sensitivity of that axis; the other axes
  add at most tan 30 deg of theirs), and the magnitude error itself.

The magnetometer's term is a relative sensitivity: its panels are in % of
the reading.  A chip that calibrate found lagging the recorded temperature
(``TempModel.lag_s``, ``calib.templag``) is drawn against its own: the
recorded temperature through that lag, also drawn over the session.  The held-out error with and without the term is the one
calibrate measured (``TempModel.extra``).
"""
from __future__ import annotations

import numpy as np

from pathlib import Path

from ..sessions.session import HMC5883L_OVERFLOW, LABEL_ROT
from . import charts as C
from . import html as H
from .parts import Part
from .tables import Column

BLOCK_S = 1.0                      # still data are averaged over 1 s blocks
NEAR_AXIS_COS = float(np.cos(np.radians(30.0)))
MAX_SWEEP_ROWS = 3000
NAMES = {"accel": "Accelerometer", "gyro": "Gyroscope", "mag": "Magnetometer"}
NO_TEMP = ("the session carries no board temperature (motes running an image without the "
           "temperature message, or an import without a temperature column), so calibrate "
           "fitted no temperature terms and there is nothing to draw")


def _unit(sensor: str, sc) -> str:
    return "%" if sensor == "mag" else sc.unit


def expected(tm, sensor: str, axis: int, T) -> np.ndarray:
    """What the term says the uncorrected still offset of ``axis`` is at
    board temperature ``T`` (clamped to the valid range)."""
    d = tm.dt(np.asarray(T, float))
    if sensor == "mag":
        return -100.0 * tm.scale_per_c[axis] * d
    return -tm.offset_per_c[axis] * d


def spread(tm, sensor: str, axis: int, T) -> np.ndarray:
    """2 standard deviations of ``expected`` (the coefficient's; the static
    calibration's own uncertainty at ``t_ref`` is not in it)."""
    d = np.abs(tm.dt(np.asarray(T, float)))
    sd = 100.0 * tm.scale_per_c_std[axis] if sensor == "mag" else tm.offset_per_c_std[axis]
    return 2.0 * (sd if np.isfinite(sd) else 0.0) * d


# ------------------------------------------------------------------ the session's still data

def blocks(t, label, ok, labels) -> list:
    """Row indices of the 1 s blocks of each still pose in ``labels`` (a pose
    shorter than 1.5 blocks is one block), as ``calib.thermal`` averages."""
    out = []
    for p in labels:
        idx = np.flatnonzero((label == p) & ok)
        if len(idx) < 3:
            continue
        n = max(1, int(round((t[idx[-1]] - t[idx[0]]) / BLOCK_S)))
        out += [part for part in np.array_split(idx, n) if len(part)]
    return out


def _means(arr, groups):
    return np.array([arr[g].mean(axis=0) for g in groups]).reshape(len(groups), *arr.shape[1:])


class SensorData:
    """A sensor's still data against temperature (the section's points)."""

    def __init__(self, sensor, sc, data, holds):
        self.sensor, self.sc = sensor, sc
        tm = sc.temperature
        t = data.sample_times()
        x = data.sensor(sensor)
        # a chip that lags the recorded (ITG3200) temperature is drawn against
        # its own, the recorded one through the lag calibrate fitted
        self.lag_s = float(getattr(tm, "lag_s", 0.0) or 0.0) if tm is not None else 0.0
        temp = data.temp
        if self.lag_s:
            from ..calib.content import recording_parts
            temp = tm.lagged(data.temp, t, recording_parts(data))
        self.temp = temp
        ok = data.has(sensor) & np.isfinite(temp)
        if sensor == "mag":
            ok &= ~(x == HMC5883L_OVERFLOW).any(axis=1)
        self.axes = [([], [], [], "") for _ in range(3)]      # (T, unc, cor, what)
        self.mag_T = self.mag_unc = self.mag_cor = None
        self.what = []
        poses = [int(p) for p in np.unique(data.label[data.label >= 1]) if p not in holds]
        unc = lambda raw: sc.apply(raw)                       # noqa: E731
        cor = lambda raw, T: sc.apply(raw, T) if tm is not None else sc.apply(raw)  # noqa
        if sensor == "gyro":
            g = blocks(t, data.label, ok, list(holds) + poses)
            if g:
                raw, T = _means(x, g), _means(temp, g)
                self._axes(T, unc(raw), cor(raw, T), "still blocks (1 s)")
                self.what.append(f"{len(g)} still blocks of 1 s")
            return
        # holds: the change of each axis within the hold
        g_all = []
        for h in holds:
            g = blocks(t, data.label, ok, [h])
            if len(g) < 2:
                continue
            g_all += g
            raw, T = _means(x, g), _means(temp, g)
            vu, vc = unc(raw), cor(raw, T)
            for i in range(3):
                if sensor == "mag":
                    ref = np.linalg.norm(vu.mean(axis=0) - sc.c)
                    bu, bc = vu.mean(axis=0)[i] - sc.c[i], vc.mean(axis=0)[i] - sc.c[i]
                    if abs(bu) < 0.3 * ref:
                        continue                    # this axis reads little of the field
                    yu = 100.0 * (vu[:, i] - vu[:, i].mean()) / bu
                    yc = 100.0 * (vc[:, i] - vc[:, i].mean()) / bc
                else:
                    yu, yc = vu[:, i] - vu[:, i].mean(), vc[:, i] - vc[:, i].mean()
                if tm is not None:
                    yu = yu + expected(tm, sensor, i, T).mean()
                self._add(i, T, yu, yc)
        if g_all:
            self.what.append(f"{len(holds)} hold(s), {len(g_all)} blocks of 1 s")
        # poses or the sweep: the magnitude error
        if sensor == "mag" and sc.dataset == "R":
            rot = data.label == LABEL_ROT
            rows = np.flatnonzero(ok & (rot if rot.any() else (data.label == 0)))
            rows = rows[np.unique(np.linspace(0, len(rows) - 1,
                                              min(len(rows), MAX_SWEEP_ROWS)).astype(int))] \
                if len(rows) else rows
            if len(rows) >= 12:
                raw, T = x[rows], temp[rows]
                self._magnitude(T, unc(raw), cor(raw, T))
                self.what.append(f"{len(rows)} sweep readings")
        else:
            g = [np.flatnonzero((data.label == p) & ok) for p in poses]
            g = [i for i in g if len(i)]
            if len(g) >= 3:
                raw, T = _means(x, g), _means(temp, g)
                self._magnitude(T, unc(raw), cor(raw, T))
                self.what.append(f"{len(g)} static poses")

    def _add(self, i, T, yu, yc):
        a = self.axes[i]
        self.axes[i] = (np.r_[a[0], T], np.r_[a[1], yu], np.r_[a[2], yc], a[3])

    def _axes(self, T, vu, vc, what):
        for i in range(3):
            self._add(i, T, vu[:, i], vc[:, i])

    def _magnitude(self, T, vu, vc):
        sensor, sc = self.sensor, self.sc
        ref = 1.0 if sensor == "accel" else float(sc.field_gauss or np.median(
            np.linalg.norm(vc, axis=1)))
        nu, nc = np.linalg.norm(vu, axis=1), np.linalg.norm(vc, axis=1)
        ru, rc = nu - ref, nc - ref
        k = 100.0 / ref if sensor == "mag" else 1.0
        self.mag_T, self.mag_unc, self.mag_cor = T, k * ru, k * rc
        uu, uc = vu / nu[:, None], vc / nc[:, None]
        for i in range(3):
            near = np.abs(uu[:, i]) >= NEAR_AXIS_COS
            if sensor == "mag":
                du, dc = vu[:, i] - sc.c[i], vc[:, i] - sc.c[i]
                near &= (np.abs(du) >= 0.3 * ref) & (np.abs(dc) >= 0.3 * ref)
                yu = 100.0 * ru[near] / (uu[near, i] * du[near])
                yc = 100.0 * rc[near] / (uc[near, i] * dc[near])
            else:
                yu, yc = ru[near] / uu[near, i], rc[near] / uc[near, i]
            if near.any():
                self._add(i, T[near], yu, yc)

    @property
    def has_points(self) -> bool:
        return any(len(a[0]) for a in self.axes) or self.mag_T is not None


# ------------------------------------------------------------------ charts

def _xlim(tm, Ts):
    vals = [np.asarray(T, float) for T in Ts if len(T)]
    lo = min([float(np.nanmin(v)) for v in vals] + ([tm.range_c[0]] if tm else []))
    hi = max([float(np.nanmax(v)) for v in vals] + ([tm.range_c[1]] if tm else []))
    pad = 0.15 * max(hi - lo, 0.5)
    return lo - pad, hi + pad


def sensor_charts(sd: SensorData) -> list:
    """One chart per axis (and one of the magnitude error), as described in
    the module doc."""
    sensor, sc = sd.sensor, sd.sc
    tm = sc.temperature
    unit = _unit(sensor, sc)
    lo, hi = _xlim(tm, [a[0] for a in sd.axes] + [sd.mag_T if sd.mag_T is not None else []])
    grid = np.linspace(lo, hi, 200)
    quantity = "sensitivity change" if sensor == "mag" else "still offset"
    xlabel = (f"chip temperature (C): the board's through a {sd.lag_s:.3g} s lag"
              if sd.lag_s else "board temperature (C)")
    out = []
    for i in range(3):
        T, yu, yc, _ = sd.axes[i]
        ser = []
        if tm is not None:
            if tm.range_c[0] > lo:
                ser.append(C.vspan(lo, tm.range_c[0], C.PALE, "outside the valid range: "
                                                              "clamped"))
            if tm.range_c[1] < hi:
                ser.append(C.vspan(tm.range_c[1], hi, C.PALE,
                                   "" if tm.range_c[0] > lo else "outside the valid range: "
                                                                 "clamped"))
            e, w = expected(tm, sensor, i, grid), spread(tm, sensor, i, grid)
            if w.any():
                ser.append(C.band(grid, e - w, e + w, C.BLUE, "fit +- 2 sd"))
            ser.append(C.line(grid, e, C.BLACK, "fitted term"))
            ser.append(C.vline(tm.t_ref_c, C.GREY, f"t_ref {tm.t_ref_c:.2f} C"))
        if len(T):
            ser.append(C.points(T, yu, C.BLUE, "without the temperature term"))
            ser.append(C.points(T, yc, C.ORANGE, "corrected (as delivered)"))
        out.append(C.chart(f"{'xyz'[i]} axis", xlabel, f"{quantity} ({unit})", ser,
                           xlim=(lo, hi)))
    if sd.mag_T is not None:
        mu = "%" if sensor == "mag" else unit
        what = "of the field" if sensor == "mag" else "(|v| - 1 g)"
        rms = [float(np.sqrt(np.mean(v ** 2))) for v in (sd.mag_unc, sd.mag_cor)]
        out.append(C.chart(f"magnitude error {what}: rms {rms[0]:.3g} -> {rms[1]:.3g} {mu}",
                           xlabel,
                           f"|v| error ({mu})",
                           [C.hline(0.0, C.GREY),
                            C.points(sd.mag_T, sd.mag_unc, C.BLUE,
                                     "without the temperature term"),
                            C.points(sd.mag_T, sd.mag_cor, C.ORANGE, "corrected")],
                           xlim=(lo, hi)))
    return out


def session_chart(data, board) -> dict:
    """The board temperature over the session: every row, the static poses'
    mean temperatures, the holds and the sweep, each fitted sensor's valid
    range and reference temperature."""
    t = data.sample_times()
    t = t - np.nanmin(t)
    T = data.temp
    order = np.argsort(t, kind="stable")
    ser = []
    holds = (board.settings.get("temperature") or {}).get("holds", []) if board else []
    for k, h in enumerate(holds):
        th = t[data.label == h]
        if len(th):
            ser.append(C.vspan(th.min(), th.max(), C.ORANGE, "hold" if k == 0 else ""))
    rot = data.label == LABEL_ROT
    if rot.any():
        ser.append(C.vspan(t[rot].min(), t[rot].max(), C.PURPLE, "sweep"))
    models = [(n, sc.temperature) for n, sc in (board.sensors() if board else [])
              if sc.temperature is not None]
    ranges = {}
    for n, tm in models:
        ranges.setdefault((round(tm.range_c[0], 1), round(tm.range_c[1], 1)), []).append(n)
    for k, ((a, b), names) in enumerate(ranges.items()):
        ser.append(C.hspan(a, b, (C.GREEN, C.BROWN, C.PURPLE)[k % 3],
                           f"valid range ({', '.join(names)})"))
    refs = {}
    for n, tm in models:
        refs.setdefault(round(tm.t_ref_c, 2), []).append(n)
    for r, names in refs.items():
        ser.append(C.hline(r, C.GREY, f"t_ref {r:.2f} C ({', '.join(names)})"))
    ser.append(C.line(t[order], T[order], C.BLACK, "board temperature", width=1.0))
    for (n, tm), colour in zip(models, (C.RED, C.GREEN, C.BROWN)):
        if getattr(tm, "lag_s", 0.0):
            from ..calib.content import recording_parts
            chip = tm.lagged(T, data.sample_times(), recording_parts(data))
            ser.append(C.line(t[order], chip[order], colour,
                              f"{n} chip: {tm.lag_s:.3g} s behind", dash=True, width=1.0))
    poses = [p for p in np.unique(data.label[data.label >= 1]) if p not in holds]
    if poses:
        pt = np.array([t[data.label == p].mean() for p in poses])
        pT = np.array([np.nanmean(T[data.label == p]) if np.isfinite(T[data.label == p]).any()
                       else np.nan for p in poses])
        ser.append(C.points(pt, pT, C.BLUE, f"static poses ({len(poses)})", size=4))
    mote = f", mote {data.motes[0]}" if len(data.motes) == 1 else ""
    return C.chart(f"board temperature over the session{mote}", "time (s)", "temperature (C)",
                   ser)


# ------------------------------------------------------------------ the table

def table_rows(mote: int, board, settings_temp: dict) -> list:
    """One row per calibrated sensor: its term (or why none), coefficients,
    range, reference and held-out error without and with it."""
    rows = []
    nf = (settings_temp or {}).get("not_fitted", {})
    for name, sc in board.sensors():
        tm = sc.temperature
        row = {"mote": mote, "sensor": name}
        if tm is None:
            row["not_fitted"] = nf.get(name) or "no temperature term"
            rows.append(row)
            continue
        ex = tm.extra or {}
        if name == "mag":
            # the chip's sensitivity change (the correction is its opposite), as
            # calibrate's summary prints it
            k, s, unit, term = -100 * tm.scale_per_c, 100 * tm.scale_per_c_std, "%/C", \
                "sensitivity change"
        else:
            k, s, unit, term = tm.offset_per_c, tm.offset_per_c_std, f"{sc.unit}/C", \
                "offset correction"
        row.update({"term": term, "unit": unit, "sets": " + ".join(ex.get("sets", [])),
                    "valid_from": tm.range_c[0], "valid_to": tm.range_c[1],
                    "t_ref": tm.t_ref_c, "heldout_without": ex.get("heldout_rms_before"),
                    "heldout_with": ex.get("heldout_rms_after"), "heldout_unit": sc.unit,
                    "lag_s": getattr(tm, "lag_s", None) or None})
        for i, a in enumerate("xyz"):
            row[f"{a}"] = float(k[i])
            row[f"std_{a}"] = None if not np.isfinite(s[i]) else float(s[i])
        rows.append(row)
        if name == "gyro":
            sf = ex.get("scale_fit") or {}
            if np.any(tm.scale_per_c != 0):
                r2 = {"mote": mote, "sensor": name, "term": "sensitivity (moves)", "unit": "%/C",
                      "sets": f"{sf.get('moves', '')} moves", "valid_from": tm.range_c[0],
                      "valid_to": tm.range_c[1], "t_ref": tm.t_ref_c}
                for i, a in enumerate("xyz"):
                    r2[a] = float(100 * tm.scale_per_c[i])
                    sd_ = tm.scale_per_c_std[i]
                    r2[f"std_{a}"] = None if not np.isfinite(sd_) else float(100 * sd_)
                rows.append(r2)
    return rows


COLUMNS = [
    Column("mote", "mote"), Column("sensor", "sensor"), Column("term", "term"),
    Column("x", "x", ".3g"), Column("y", "y", ".3g"), Column("z", "z", ".3g"),
    Column("std_x", "sd x", ".2g"), Column("std_y", "sd y", ".2g"), Column("std_z", "sd z", ".2g"),
    Column("unit", "unit"), Column("sets", "from"),
    Column("valid_from", "valid from C", ".2f"), Column("valid_to", "to C", ".2f"),
    Column("t_ref", "t_ref C", ".2f"),
    Column("heldout_without", "held-out rms without", ".3g"),
    Column("heldout_with", "with the term", ".3g"), Column("heldout_unit", "in"),
    Column("lag_s", "lag behind the recorded temperature (s)", ".3g"),
    Column("not_fitted", "not fitted: why")]
NOTES = [
    "the term of a sensor: calibrated = (1 + scale_per_c dT) (A raw) + c + offset_per_c dT, "
    "dT = clip(T, valid from, valid to) - t_ref: outside the range it is clamped, never "
    "extrapolated (as on the mote)",
    "offset correction: what is added per C (the drift is its opposite); sensitivity change: "
    "the chip's relative gain change per C (the correction divides it out)",
    "held-out rms: calibrate's own check (5 interleaved folds of the observations the term was "
    "fitted on: still blocks, holds, pose magnitudes or the sweep), in the sensor's unit"]


def part(mr, out: Path) -> Part:
    """The temperature section of one mote (``mr``: build.MoteReport)."""
    from ..calib.content import temperature_content
    data, board, m = mr.data, mr.board, mr.mote
    if not data.has_temp:
        return Part(meta=[("temperature", f"none in the session: {NO_TEMP}")])
    tc = temperature_content(data)
    settings = (board.settings.get("temperature") if board is not None else None) or {}
    holds = settings.get("holds", list(tc.holds))
    figs, view, notes = [], [], []
    sess = session_chart(data, board)
    f = C.save(out / f"mote{m}_temperature_session.png", [sess], ncols=1, panel=(11, 3.6))
    figs.append(H.FigureRef(f.name, "Board temperature over the session",
                            f"Every row's temperature (the ITG3200's reading), {tc.lo:.2f}-"
                            f"{tc.hi:.2f} C over the still rows; blue: the static poses' "
                            f"mean temperatures; shaded: holds (still poses of 30 s or more) "
                            f"and the sweep; green band: the range each sensor's temperature "
                            f"term is valid in (clamped outside); dashed: its reference "
                            f"temperature t_ref, where the static calibration holds; "
                            f"dashed lines, when calibrate found a chip lagging the recorded "
                            f"temperature: that chip's temperature through its lag."))
    view.append(("board temperature", [sess]))
    if tc.why:
        notes.append(f"mote {m}: no temperature term can be determined: {tc.why}")
    rows = []
    if board is None:
        notes.append(f"mote {m}: no calibration to show against temperature")
    else:
        rows = table_rows(m, board, settings)
        for name, sc in board.sensors():
            sd = SensorData(name, sc, data, holds)
            tm = sc.temperature
            if tm is None and not sd.has_points:
                continue
            charts = sensor_charts(sd)
            if tm is not None:
                ex = tm.extra or {}
                head = (f"held-out rms {ex.get('heldout_rms_before', float('nan')):.3g} -> "
                        f"{ex.get('heldout_rms_after', float('nan')):.3g} {sc.unit}")
            else:
                head = "no temperature term: " + (settings.get("not_fitted", {}).get(name)
                                                  or "not fitted")
            f = C.save(out / f"mote{m}_{name}_temperature.png", charts,
                       f"{NAMES[name]} against temperature, mote {m}: {head}",
                       ncols=2 if len(charts) == 4 else 3)
            model = "; ".join(n[len("temperature: "):] for n in sc.notes
                              if n.startswith("temperature: "))
            figs.append(H.FigureRef(
                f.name, f"{NAMES[name]}: still offset against temperature",
                f"Data: {', '.join(sd.what) or 'none'}. Blue: through the calibration without "
                f"its temperature term; orange: corrected, as delivered. Black: the fitted "
                f"term (what it predicts the uncorrected offset to be), shaded band +- 2 "
                f"standard deviations of its coefficient, grey: outside the range it is valid "
                f"in (clamped there, as on the mote). "
                + ("In % of the reading: the magnetometer's term is a relative sensitivity. "
                   if name == "mag" else "")
                + (f"Against the chip's temperature: the recorded one through the "
                   f"{sd.lag_s:.3g} s lag calibrate found. " if sd.lag_s else "")
                + ("Per-axis points from poses or a sweep: readings within 30 deg of that "
                   "axis, magnitude error / its share. " if sd.mag_T is not None else "")
                + f"Calibrate: {model or head}; the title's held-out rms is without -> with "
                  f"the term."))
            view.append((f"{NAMES[name].lower()} against temperature", charts))
    sec = H.Section(f"temperature-mote{m}", f"Temperature, mote {m}",
                    "What calibrate fitted against the board temperature, from the stored "
                    "calibration and this session's rows (nothing refitted here).",
                    figures=figs, notes=notes)
    return Part(sec, {"temperature": rows}, view)
