"""Calibration against board temperature (issue 16): each sensor's output as
a function of the temperature the session carries (``SessionData.temp``).

What the still data determine (``content.temperature_content`` judges the
span once, for calibrate and diagnose):

* **gyroscope** -- the zero-rate output against temperature: every still
  block (1 s) of the static poses and holds (a warm-up hold of several
  minutes after power-on is the typical source) gives the calibrated rate,
  whose truth is 0; the slope per axis is fitted through the bias the
  calibration measured at ``t_ref`` (the mean temperature of its rows).  The
  sensitivity's coefficient per output axis comes from the moves between
  poses when their temperatures span the same 2 C (``tempscale``), and
  is used only when determined to ``SCALE_STD_LIMIT`` and better on held-out
  moves; otherwise the note says why.
* **accelerometer** -- the zero-g offset against temperature: within a hold
  (one orientation) the calibrated vector's change per block follows
  ``offset_per_c dT``; across static poses that span a temperature range the
  pose magnitudes' residuals follow ``u . offset_per_c dT`` (fitted jointly
  with a small change of the static fit's own map, so that what that fit
  absorbed of the drift is given back).  The gain's coefficient (ADXL345:
  0.01 %/C, a twentieth of the offset's effect at 1 g) is not fitted.
* **magnetometer** -- a relative sensitivity coefficient per axis (the
  HMC5883L's -0.3 %/C), or one for the three axes when each axis' own is not
  determined (an axis that reads little of the field in a hold): within a
  hold the field vector grows by ``k dT`` (hard iron included: a field the
  chip measures); across poses or a sweep over a span the field magnitude
  does.

Every observation set is kept only when its own temperature span reaches
``content.MIN_TEMP_SPAN_C``; the sets of a sensor are fitted together by
weighted least squares (each weighted by its own residual scatter), and the
term is used only when the stacked design has full rank, the coefficients'
standard deviations are below ``STD_LIMITS``, and the term predicts held-out
blocks better than no term (5 interleaved folds).  The result is
``result.TempModel`` with the range the data covered (``apply`` clamps to
it).  A session without temperature is not touched.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..maths.heldout import kfold_heldout
from ..sessions.session import HMC5883L_OVERFLOW, LABEL_NONE, LABEL_ROT, SessionData
from . import templag as TL
from .tempscale import FOLDS, SCALE_STD_LIMIT, gyro_scale_fit  # noqa: F401
from .content import MIN_POSE_ORIENTATIONS, MIN_TEMP_SPAN_C, TempContent, recording_parts
from .result import BoardCalibration, TempModel

BLOCK_S = 1.0              # still data are averaged over blocks this long
MAX_SWEEP_ROWS = 3000      # sweep rows used for the magnetometer (evenly strided)
STD_LIMITS = {"accel": 2e-4, "gyro": 0.01, "mag": 1e-4}   # g/C, deg/s/C, 1/C
UNITS = {"accel": "g/C", "gyro": "deg/s/C", "mag": "/C"}


@dataclass
class ObsSet:
    """Observations y = Xt theta + Xn nu + e (one set, own noise level)."""
    name: str
    y: np.ndarray
    Xt: np.ndarray            # (m, q) columns of the temperature parameters
    Xn: np.ndarray            # (m, r) the set's own nuisance columns
    fold: np.ndarray          # (m,) held-out fold
    temp: np.ndarray          # temperatures the set covers (for its span and range)
    sigma: float = 1.0

    @property
    def span(self) -> float:
        return float(np.ptp(self.temp)) if len(self.temp) else 0.0


def without_holds(data: SessionData, tc: TempContent) -> SessionData:
    """The rows the static calibration uses: the holds (long still poses,
    kept for the temperature fit) left out when at least 12 other poses
    remain, so a 20-minute warm-up does not outweigh the 80 poses (a session
    of a few long holds, such as the Razor files, keeps them as its poses)."""
    if not tc.holds:
        return data
    hold = np.isin(data.label, tc.holds)
    others = np.unique(data.label[(data.label >= 1) & ~hold])
    if len(others) < 2 * MIN_POSE_ORIENTATIONS:    # a session of holds: they are its poses
        return data
    label = data.label.copy()
    label[hold] = LABEL_NONE
    return dataclasses.replace(data, label=label)


# --------------------------------------------------------------------------
# still blocks
# --------------------------------------------------------------------------
def _usable(data: SessionData, sensor: str) -> np.ndarray:
    """Rows with the sensor's three values (not an overflow) and a temperature."""
    x = data.sensor(sensor)
    ok = ~np.isnan(x).any(axis=1) & np.isfinite(data.temp)
    if sensor == "mag":
        ok &= ~(x == HMC5883L_OVERFLOW).any(axis=1)
    return ok


def _label_rows(label: np.ndarray, ok: np.ndarray, labels) -> dict:
    """{p: the ``ok`` rows labelled p, ascending} for p in ``labels``."""
    idx = np.flatnonzero(ok & np.isin(label, list(labels)))
    lab = label[idx]
    order = np.argsort(lab, kind="stable")
    idx, lab = idx[order], lab[order]
    if not len(idx):
        return {}
    cuts = np.flatnonzero(np.diff(lab)) + 1
    return {int(p): rows for p, rows in zip(lab[np.r_[0, cuts]], np.split(idx, cuts))}


def _group_means(values: np.ndarray, rows: np.ndarray, group: np.ndarray, n: int) -> np.ndarray:
    """Mean of ``values`` (rows, or rows x columns) over each of ``n`` groups."""
    cnt = np.bincount(group, minlength=n)
    v = values[rows]
    if v.ndim == 1:
        return np.bincount(group, weights=v, minlength=n) / cnt
    return np.column_stack([np.bincount(group, weights=v[:, j], minlength=n)
                            for j in range(v.shape[1])]) / cnt[:, None]


def _blocks(data: SessionData, labels, sensor: str):
    """Per still pose/hold in ``labels``: blocks of ``BLOCK_S`` (a pose
    shorter than 1.5 blocks is one block; consecutive rows split as
    ``np.array_split`` does): mean raw counts, mean temperature, the pose
    label."""
    t = data.sample_times()
    by = _label_rows(data.label, _usable(data, sensor), labels)
    rows, group, lab, k = [], [], [], 0
    for p in labels:
        idx = by.get(int(p))
        if idx is None or len(idx) < 3:
            continue
        n = max(1, int(round((t[idx[-1]] - t[idx[0]]) / BLOCK_S)))
        q, r = divmod(len(idx), n)
        rows.append(idx)
        group.append(k + np.repeat(np.arange(n), [q + 1] * r + [q] * (n - r)))
        lab += [int(p)] * n
        k += n
    if not k:
        return np.zeros((0, 3)), np.zeros(0), np.zeros(0, int)
    rows, group = np.concatenate(rows), np.concatenate(group)
    return (_group_means(data.sensor(sensor), rows, group, k),
            _group_means(data.temp, rows, group, k), np.array(lab, int))


def _pose_means(data: SessionData, poses, sensor: str):
    """Each pose's mean raw counts and temperature over its usable rows."""
    by = _label_rows(data.label, _usable(data, sensor), poses)
    keep = [p for p in poses if int(p) in by]
    if not keep:
        return np.zeros((0, 3)), np.zeros(0)
    rows = np.concatenate([by[int(p)] for p in keep])
    group = np.repeat(np.arange(len(keep)), [len(by[int(p)]) for p in keep])
    return (_group_means(data.sensor(sensor), rows, group, len(keep)),
            _group_means(data.temp, rows, group, len(keep)))


def _t_ref(data: SessionData, rows) -> float:
    T = data.temp[rows]
    T = T[np.isfinite(T)]
    return float(T.mean()) if len(T) else float("nan")


def _poses(data, tc):
    return [int(p) for p in np.unique(data.label[data.label >= 1]) if p not in tc.holds]


def sym_cols(u, v):
    """Columns of u^T W v + u^T d for a symmetric W (6) and d (3): a small
    change of the static fit's map, seen in a magnitude."""
    return np.column_stack([u[:, 0] * v[:, 0], u[:, 1] * v[:, 1], u[:, 2] * v[:, 2],
                            u[:, 0] * v[:, 1] + u[:, 1] * v[:, 0],
                            u[:, 0] * v[:, 2] + u[:, 2] * v[:, 0],
                            u[:, 1] * v[:, 2] + u[:, 2] * v[:, 1], u])


def _hold_rows(v, temp, lab, xt_of):
    """Within each hold: the block's vector minus the hold's mean, per axis."""
    ys, xs, fs, ts = [], [], [], []
    for h in np.unique(lab):
        m = lab == h
        vb, tb = v[m], temp[m]
        dv, dt = vb - vb.mean(axis=0), tb - tb.mean()
        k = np.arange(m.sum()) % FOLDS
        for i in range(3):
            ys.append(dv[:, i])
            xs.append(xt_of(dt, vb.mean(axis=0), i))
            fs.append(k)
            ts.append(tb)
    if not ys:
        return None
    return (np.concatenate(ys), np.vstack(xs), np.concatenate(fs), np.concatenate(ts))


# --------------------------------------------------------------------------
# observation sets per sensor
# --------------------------------------------------------------------------
def gyro_sets(board, data, tc, t_ref) -> list[ObsSet]:
    """The still blocks' calibrated rates against temperature, through the
    bias at ``t_ref``; each hold has an offset of its own (a hold is one
    orientation, not the poses' mean: with a g-sensitivity its still rate
    differs by G a, which would otherwise be taken for temperature)."""
    sc = board.gyro
    raw, temp, lab = _blocks(data, list(tc.holds) + _poses(data, tc), "gyro")
    if not len(raw):
        return []
    w = sc.apply(raw)
    dT = temp - t_ref
    m = len(w)
    Xt = np.zeros((3 * m, 3))
    holds = [h for h in tc.holds if (lab == h).any()]
    Xn = np.zeros((3 * m, 3 * len(holds)))
    for i in range(3):
        Xt[i * m:(i + 1) * m, i] = dT
        for k, h in enumerate(holds):
            Xn[i * m:(i + 1) * m, 3 * k + i] = lab == h
    fold = np.tile(np.arange(m) % FOLDS, 3)
    return [ObsSet("still blocks", w.T.reshape(-1), Xt, Xn, fold, temp)]


def accel_sets(board, data, tc, t_ref) -> list[ObsSet]:
    sc = board.accel
    out = []
    raw, temp, lab = _blocks(data, tc.holds, "accel")
    if len(raw):
        r = _hold_rows(sc.apply(raw), temp, lab,
                       lambda dt, vbar, i: np.outer(dt, np.eye(3)[i]))
        if r is not None:
            out.append(ObsSet("holds", r[0], r[1], np.zeros((len(r[0]), 0)), r[2], r[3]))
    poses = _poses(data, tc)
    if len(poses) >= 12:
        pm, pt = _pose_means(data, poses, "accel")
        v = sc.apply(pm)
        nv = np.linalg.norm(v, axis=1)
        u = v / nv[:, None]
        out.append(ObsSet("poses", nv - 1.0, u * (pt - t_ref)[:, None], sym_cols(u, v),
                          np.arange(len(v)) % FOLDS, pt))
    return out


def mag_sets(board, data, tc, t_ref, per_axis: bool = True) -> list[ObsSet]:
    """Holds and the main set (sweep or poses); ``per_axis``: a sensitivity
    coefficient per axis (3 parameters), else one for the three."""
    sc = board.mag
    c = sc.c
    out = []
    raw, temp, lab = _blocks(data, tc.holds, "mag")

    def hold_col(dt, vbar, i):
        x = dt * (vbar[i] - c[i])
        return np.outer(x, np.eye(3)[i]) if per_axis else x[:, None]
    if len(raw):
        r = _hold_rows(sc.apply(raw), temp, lab, hold_col)
        if r is not None:
            out.append(ObsSet("holds", r[0], r[1], np.zeros((len(r[0]), 0)), r[2], r[3]))
    x = data.sensor("mag")
    ok = _usable(data, "mag")
    if sc.dataset == "R":
        rows = np.flatnonzero(ok & ((data.label == LABEL_ROT) if (data.label != 0).any()
                                    else np.ones(len(data), bool)))
        rows = rows[np.linspace(0, len(rows) - 1, min(len(rows), MAX_SWEEP_ROWS)).astype(int)] \
            if len(rows) else rows
        vals, temps = x[rows], data.temp[rows]
    else:
        vals, temps = _pose_means(data, _poses(data, tc), "mag")
    if len(vals) >= 12:
        v = sc.apply(vals)
        nv = np.linalg.norm(v, axis=1)
        u = v / nv[:, None]
        B = float(sc.field_gauss) if sc.field_gauss else float(np.median(nv))
        xt = (temps - t_ref)[:, None] * u * (v - c)
        if not per_axis:
            xt = xt.sum(axis=1, keepdims=True)
        out.append(ObsSet("sweep" if sc.dataset == "R" else "poses", nv - B, xt,
                          sym_cols(u, v), np.arange(len(v)) % FOLDS, temps))
    return out


# --------------------------------------------------------------------------
# the stacked fit
# --------------------------------------------------------------------------
def _design(sets, thermal=True):
    q = sets[0].Xt.shape[1] if thermal else 0
    r = [s.Xn.shape[1] for s in sets]
    X = np.zeros((sum(len(s.y) for s in sets), q + sum(r)))
    y = np.zeros(X.shape[0])
    w = np.zeros(X.shape[0])
    i, j = 0, q
    for s, rk in zip(sets, r):
        m = len(s.y)
        if thermal:
            X[i:i + m, :q] = s.Xt
        X[i:i + m, j:j + rk] = s.Xn
        y[i:i + m] = s.y
        w[i:i + m] = 1.0 / s.sigma
        i += m
        j += rk
    return X, y, w


def _solve(X, y, w):
    Xw, yw = X * w[:, None], y * w
    if not X.shape[1]:
        return np.zeros(0), np.zeros((0, 0)), int(0)
    beta, *_ = np.linalg.lstsq(Xw, yw, rcond=None)
    cn = np.linalg.norm(Xw, axis=0)
    cn[cn == 0] = 1.0
    rank = int(np.linalg.matrix_rank(Xw / cn))
    res = yw - Xw @ beta
    dof = max(1, len(y) - X.shape[1])
    chi2 = float(res @ res) / dof
    cov = np.linalg.pinv(Xw.T @ Xw) * max(1.0, chi2)
    return beta, cov, rank


def _set_sigma(s: ObsSet) -> float:
    X = np.hstack([s.Xt, s.Xn])
    beta, *_ = np.linalg.lstsq(X, s.y, rcond=None)
    res = s.y - X @ beta
    return float(np.sqrt(res @ res / max(1, len(s.y) - X.shape[1]))) or 1e-12


def _heldout(sets, errors: bool = False):
    """rms of held-out observations without and with the temperature term
    (each fold refitted on the others: ``maths.heldout.kfold_heldout``);
    ``errors``: also each observation's held-out error with the term."""
    fold = np.concatenate([s.fold for s in sets]) if sets else np.zeros(0, int)
    ends = np.cumsum([len(s.y) for s in sets])

    def part(mask):
        return [dataclasses.replace(s, y=s.y[m], Xt=s.Xt[m], Xn=s.Xn[m])
                for s, m in zip(sets, np.split(mask, ends[:-1]))]

    def fit(tr):
        return [_solve(*_design(part(tr), th))[0] for th in (False, True)]

    def score(betas, te):
        cols = []
        for th, beta in zip((False, True), betas):
            Xe, ye, _ = _design(part(te), th)
            cols.append(ye - Xe @ beta)
        return np.column_stack(cols)
    r = kfold_heldout(fold, fit, score)
    ncol = {th: _design(sets, th)[0].shape[1] for th in (False, True)} if sets else {}
    sq = {False: 0.0, True: 0.0}
    n = 0
    for f in np.unique(fold):
        te = fold == f
        for j, th in enumerate((False, True)):
            e = r[te, j]
            sq[th] += float(np.sum(e ** 2)) if ncol[th] else float(e @ e)
        n += int(te.sum())
    n = max(n, 1)
    rms = float(np.sqrt(sq[False] / n)), float(np.sqrt(sq[True] / n))
    return (rms, r[:, 1]) if errors else rms


def fit_sensor(sensor: str, sets: list[ObsSet]) -> dict:
    """The stacked fit of one sensor's temperature term: ``{"theta", "std",
    "why" (None when usable), "sets", "heldout", ...}``."""
    spans = {s.name: s.span for s in sets}
    sets = [s for s in sets if s.span >= MIN_TEMP_SPAN_C and len(s.y) > s.Xt.shape[1] + s.Xn.shape[1]]
    out = {"spans_c": spans, "sets": [s.name for s in sets]}
    if not sets:
        out["why"] = ("no data over a span of at least "
                      f"{MIN_TEMP_SPAN_C:g} C (" + ", ".join(f"{k} {v:.2f} C"
                                                             for k, v in spans.items())
                      + ")" if spans else "no data with a temperature")
        return out
    for s in sets:
        s.sigma = _set_sigma(s)
    X, y, w = _design(sets)
    beta, cov, rank = _solve(X, y, w)
    q = sets[0].Xt.shape[1]
    theta, std = beta[:q], np.sqrt(np.clip(np.diag(cov)[:q], 0, None))
    (before, after), errors = _heldout(sets, errors=True)
    out.update(theta=theta, std=std, nuisance=beta[q:], rank=rank, params=X.shape[1],
               heldout_rms_before=before, heldout_rms_after=after,
               heldout_errors=errors, heldout_sizes=[len(s.y) for s in sets],
               n_obs=int(len(y)), temp_lo=float(min(s.temp.min() for s in sets)),
               temp_hi=float(max(s.temp.max() for s in sets)))
    lim = STD_LIMITS[sensor]
    if rank < X.shape[1]:
        out["why"] = f"the temperature term is not identifiable (rank {rank} of {X.shape[1]})"
    elif std.max() > lim:
        out["why"] = (f"poorly determined: std {std.max():.2g} {UNITS[sensor]} "
                      f"(limit {lim:g})")
    elif not after < before:
        out["why"] = (f"it does not predict held-out blocks better (rms {before:.3g} -> "
                      f"{after:.3g})")
    else:
        out["why"] = None
    return out


def _fmt(v):
    return "(" + ", ".join(f"{x:+.3g}" for x in v) + ")"


def attach(board: BoardCalibration, data: SessionData, main: SessionData,
           tc: TempContent) -> dict:
    """Fit each calibrated sensor's temperature term from ``data`` (the
    whole session, holds included); ``main`` is what the static calibration
    used (for each sensor's reference temperature).  Sets
    ``SensorCalibration.temperature``, adds a note per sensor saying what was
    fitted or why not, and returns ``board.settings["temperature"]``."""
    report = {"span_c": tc.span_c, "range_c": [tc.lo, tc.hi], "holds": list(tc.holds),
              "fitted": [], "not_fitted": {}}
    times, part = data.sample_times(), recording_parts(data)
    for name, sc in board.sensors():
        lag = None
        if name in TL.SENSORS and data.has_temp:
            # the ADXL345 and the HMC5883L lag the ITG3200's die (calib.templag)
            def fit_at(lag_s, name=name, sc=sc):
                T = TL.lag_filter(data.temp, times, lag_s, part)
                return _fit_one(name, sc, board, dataclasses.replace(data, temp=T),
                                dataclasses.replace(main, temp=T), tc)
            lag = TL.choose_lag(fit_at)
            res = lag["res"]
        else:
            res = _fit_one(name, sc, board, data, main, tc)
        t_ref = res["t_ref"]
        why = res["why"]
        if why is not None:
            report["not_fitted"][name] = why
            sc.notes.append(f"temperature: not fitted: {why}")
            continue
        tm = _temp_model(name, sc, res, t_ref)
        if lag is not None:
            _lag_note(tm, lag)
        if name == "gyro":
            _gyro_scale(board, main, tm)
        sc.temperature = tm
        report["fitted"].append(name)
        sc.notes.extend(f"temperature: {n}" for n in tm.notes)
    board.settings["temperature"] = report
    return report


def _fit_one(name, sc, board, data, main, tc) -> dict:
    """``fit_sensor`` of one sensor with its reference temperature
    (``res["t_ref"]``); the magnetometer falls back on one coefficient for
    the three axes when each axis' own is not determined or does not predict
    held-out blocks better."""
    t_ref = _t_ref(main, _main_rows(main, name, sc))
    builder = {"accel": accel_sets, "gyro": gyro_sets, "mag": mag_sets}[name]
    res = fit_sensor(name, builder(board, data, tc, t_ref) if np.isfinite(t_ref) else [])
    if name == "mag" and np.isfinite(t_ref):
        common = fit_sensor(name, mag_sets(board, data, tc, t_ref, per_axis=False))
        if common["why"] is None and (
                res["why"] is not None
                or not res["heldout_rms_after"] < common["heldout_rms_after"]):
            common["per_axis_why"] = res["why"] or (
                f"held-out rms {res['heldout_rms_after']:.3g}, not below the common "
                f"coefficient's {common['heldout_rms_after']:.3g}")
            res = common
    res["t_ref"] = t_ref
    return res


def _lag_note(tm: TempModel, lag: dict) -> None:
    """The chip's lag behind the recorded temperature, or why none."""
    tried = ", ".join(f"{k:g} s {v:.3g}" for k, v in lag["tried"].items() if v is not None)
    tm.extra["lag"] = {"lag_s": lag["lag_s"], "z": lag["z"], "why": lag["why"],
                       "heldout_rms_by_lag": {str(k): v for k, v in lag["tried"].items()}}
    if lag["why"] is None:
        tm.lag_s = float(lag["lag_s"])
        tm.notes.append(f"lag {tm.lag_s:.3g} s behind the ITG3200's temperature (first order; "
                        f"held-out {lag['z']:+.1f} standard errors better than none; held-out "
                        f"rms by lag: {tried}); on the mote: not applied (the set has no lag)")
    else:
        tm.notes.append(f"no lag behind the ITG3200's temperature: {lag['why']}")


def _gyro_scale(board, main, tm: TempModel) -> None:
    """Add the gyroscope's sensitivity coefficient to ``tm`` when the moves
    determine it; say so either way."""
    gs = gyro_scale_fit(board, main, tm)
    tm.extra["scale_fit"] = {k: v for k, v in gs.items() if k not in ("s", "std")}
    if gs["why"] is not None:
        tm.notes[1] = f"sensitivity against temperature not determined: {gs['why']}"
        return
    tm.scale_per_c, tm.scale_per_c_std = gs["s"], gs["std"]
    tm.notes[1] = (f"sensitivity {_fmt(gs['s'] * 100)} +- {_fmt(gs['std'] * 100)} %/C from "
                   f"{gs['moves']} moves over {gs['span_c']:.1f} C (held-out direction error "
                   f"{gs['heldout_rms_deg_before']:.3f} -> {gs['heldout_rms_deg_after']:.3f} deg)")


def _main_rows(main: SessionData, name: str, sc):
    if name == "mag" and sc.dataset == "R":
        return main.label == LABEL_ROT if (main.label != 0).any() else np.ones(len(main), bool)
    return (main.label >= 1) & main.has(name)


def _temp_model(name, sc, res, t_ref) -> TempModel:
    lo, hi = min(res["temp_lo"], t_ref), max(res["temp_hi"], t_ref)
    theta, std = res["theta"], res["std"]
    extra = {k: res[k] for k in ("sets", "spans_c", "n_obs", "rank", "params",
                                 "heldout_rms_before", "heldout_rms_after")}
    ho = f"held-out rms {res['heldout_rms_before']:.3g} -> {res['heldout_rms_after']:.3g} {sc.unit}"
    src = " + ".join(res["sets"])
    if name == "mag":
        k, sk = np.broadcast_to(theta, 3), np.broadcast_to(std, 3)
        if len(theta) == 1:
            what = (f"{k[0] * 100:+.3f} +- {sk[0] * 100:.3f} %/C (one coefficient for the three "
                    f"axes; per axis: {res.get('per_axis_why')})")
        else:
            what = f"{_fmt(k * 100)} +- {_fmt(sk * 100)} %/C per axis"
        notes = [f"sensitivity {what} from {src}, {lo:.1f}-{hi:.1f} C around {t_ref:.2f} C; {ho}"]
        return TempModel(t_ref, (lo, hi), np.zeros(3), np.full(3, np.nan),
                         scale_per_c=-k, scale_per_c_std=sk, notes=notes, extra=extra)
    o = -theta                    # the correction removes what the data showed
    notes = [f"offset {_fmt(o)} +- {_fmt(std)} {sc.unit}/C from {src}, "
             f"{lo:.1f}-{hi:.1f} C around {t_ref:.2f} C; {ho}",
             ("sensitivity against temperature not determined (it needs turns at different "
              "temperatures)" if name == "gyro" else
              "gain against temperature not fitted (ADXL345: 0.01 %/C, a twentieth of the "
              "offset's effect at 1 g)")]
    if name == "accel" and "poses" in res["sets"]:
        # the static fit absorbed part of the drift: give it back (linearised step)
        nu = res["nuisance"][:9]
        W = np.array([[nu[0], nu[3], nu[4]], [nu[3], nu[1], nu[5]], [nu[4], nu[5], nu[2]]])
        d = nu[6:9]
        sc.A = (np.eye(3) - W) @ sc.A
        sc.c = (np.eye(3) - W) @ sc.c - d
        extra["static_map_change"] = {"W": W.tolist(), "d": d.tolist()}
        notes.append("A and c refined jointly with the temperature term (one linearised "
                     "step; the parameters listed are the static fit's)")
    return TempModel(t_ref, (lo, hi), o, std, notes=notes, extra=extra)
