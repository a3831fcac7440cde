"""Calibrate a whole board (one mote) from a session: accelerometer,
gyroscope and magnetometer in one run.

``calibrate_board(data, ...)`` takes the ``SessionData`` of one mote and
returns a ``BoardCalibration`` with a ``SensorCalibration`` per sensor the
session can calibrate, quality metrics for the gate and held-out validation.

Which rows are used
-------------------
* accelerometer: static poses (label >= 1);
* gyroscope: bias (the mean) from the static poses; scale/misalignment from the moves
  between consecutive poses (rows between them, contiguous), when there are
  enough of them and the accelerometer was calibrated;
* magnetometer: data set ``R`` = rotation rows (``LABEL_ROT``), ``O`` = the
  static poses; both are fitted when present (``mag_sets``) and ``R`` is the
  calibration (it covers the sphere densely) unless it has fewer than
  ``MIN_SWEEP`` samples.  A session without any labels (an imported sweep) is
  treated as ``R``.  Overflowed readings (-4096) are dropped.  A set that
  cannot determine a model by the quality gate's limits (fewer than six
  distinct poses, directions not around the centre, a sweep covering under
  80 % of the sphere's equal-area cells) is not fitted: a gate warning when another set is;
  when none is, the reason the magnetometer is refused -- or, in a session
  without a rotation sweep, left out with a warning (``settings["skipped"]``).
"""
from __future__ import annotations

import datetime as _dt

import numpy as np

from .. import __version__
from ..errors import UserError
from ..maths.sphere import coverage, distinct_directions, unit
from ..sessions.session import (HMC5883L_OVERFLOW, LABEL_NONE, LABEL_ROT, NOMINAL_CHIPS, UNITS,
                                SessionData)
from ..sessions.still import StillThresholds
from ..sessions.importer import CSV_FRAME
from . import fit as _fit
from .content import poses_from_stillness, temperature_content
from . import gate as _gate
from . import gyro as _gyro
from . import rotations as _rotations
from . import thermal as _thermal
from .ga import GAOptions
from .models import MagnitudeModel, mag_groups, make_model
from .result import BoardCalibration, Param, SensorCalibration

MIN_SWEEP = 200
KFOLD = 5

ANGLE_NOTE = ("the paper's angles only multiply the scales (an exact re-parametrisation of "
              "offset and scale): they cannot represent misalignment and are not "
              "identifiable; use --model full for cross-axis terms")


def _seeds(seed):
    if seed is None:
        seed = int(np.random.SeedSequence().entropy % (2 ** 31))
    ss = np.random.SeedSequence(int(seed))
    return int(seed), ss.spawn(3)


def calibrate_board(data: SessionData, *, model: str = "full", groups=None, seed=None,
                    gauge: str | None = None, field: float | None = None,
                    gyro_matrix: bool = True, kfold: int = KFOLD,
                    ga_options: GAOptions = GAOptions(),
                    still: StillThresholds = StillThresholds(),
                    created: str | None = None) -> BoardCalibration:
    """Calibrate every sensor of one mote's session (see the module doc)."""
    motes = data.motes
    if len(motes) != 1:
        raise UserError(f"session {data.name} holds motes {motes}: calibrate one mote at a time")
    data, found = poses_from_stillness(data)
    whole, tc = data, None
    if data.has_temp:                    # issue 16: holds fit the temperature terms only
        tc = temperature_content(data)
        data = _thermal.without_holds(data, tc)
    seed, (s_acc, s_gyr, s_mag) = _seeds(seed)
    created = created or _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
    board = BoardCalibration(mote=motes[0], session=data.name, created=created,
                             tool=f"motecal {__version__}")
    board.settings = {"model": model, "params": list(groups) if groups else None,
                      "seed": seed, "gauge": gauge, "field_gauss": field,
                      "gyro_matrix": bool(gyro_matrix), "kfold": kfold,
                      "skipped": {}, "insufficient": {},
                      # the axes the calibration is in (export-cal's Razor frame): a
                      # session without it is the mote's own samples, in the chips' axes
                      "axis_frame": (data.meta or {}).get("axis_frame") or CSV_FRAME}
    if found:
        board.settings["poses_found"] = found
    chips = dict(NOMINAL_CHIPS)
    chips.update(data.chips or {})

    # accelerometer -------------------------------------------------------------
    acc_rows = (data.label >= 1) & data.has("accel")
    if not data.has("accel").any():
        board.settings["skipped"]["accel"] = "no accelerometer data in the session"
    elif not acc_rows.any():
        board.settings["skipped"]["accel"] = "no static poses in the session"
    elif len(np.unique(data.label[acc_rows])) < 2:
        # a still hold (one orientation) is what a gyroscope bias is recorded
        # with: it determines the gyro, not the accelerometer -- left out
        board.settings["skipped"]["accel"] = ("a still hold in one orientation: it determines "
                                              "the gyroscope bias, not the accelerometer "
                                              "(that needs several orientations)")
    else:
        mdl = make_model("accel", model, groups)
        board.accel = _magnitude_sensor(
            "accel", mdl, data.sensor("accel")[acc_rows], data.label[acc_rows],
            data.scales["accel"], chips["accel"], s_acc, seed, ga_options, kfold,
            dataset="O", still_limit=still.accel_g)

    # gyroscope ----------------------------------------------------------------------
    gyr_rows = (data.label >= 1) & data.has("gyro")
    if not data.has("gyro").any():
        board.settings["skipped"]["gyro"] = "no gyroscope data in the session"
    elif not gyr_rows.any():
        board.settings["skipped"]["gyro"] = "no still (static pose) data in the session"
    elif gyr_rows.sum() < 10:
        board.settings["insufficient"]["gyro"] = "fewer than 10 still samples"
    else:
        board.gyro = _gyro_sensor(data, gyr_rows, board.accel, chips["gyro"], s_gyr, seed,
                                  ga_options, kfold, gyro_matrix, still)
        _rotations.refine_board(board, data)     # known turns / turntable runs, if listed

    # magnetometer ----------------------------------------------------------------
    all_sets = mag_data_sets(data)
    sets = {k: rows for k, (rows, why) in all_sets.items() if why is None}
    unfit = [f"set {k} not fitted: {why}" for k, (_, why) in all_sets.items() if why]
    if not data.has("mag").any():
        board.settings["skipped"]["mag"] = "no magnetometer data in the session"
    elif not sets:
        why = "; ".join(unfit) if all_sets else "needs a rotation sweep or static poses"
        if "R" in all_sets:          # a sweep, recorded for it: refused
            board.settings["insufficient"]["mag"] = why
        else:                        # static poses recorded for the accelerometer: left out
            board.settings["skipped"]["mag"] = ("no rotation sweep, and the static poses "
                                                f"cannot determine it ({why})")
    else:
        main = "R" if "R" in sets and sets["R"].sum() >= MIN_SWEEP else "O"
        if main not in sets:
            main = next(iter(sets))
        mgroups, mnote = (mag_groups(groups, gauge, field) if model == "paper"
                          else (groups, None))
        for name, rows in sets.items():
            mdl = make_model("mag", model, mgroups, gauge=gauge, field=field)
            sc = _magnitude_sensor(
                "mag", mdl, data.sensor("mag")[rows],
                data.label[rows] if name == "O" else None,
                data.scales["mag"], chips["mag"], s_mag, seed, ga_options, kfold,
                dataset=name, still_limit=still.mag_gauss)
            board.mag_sets[name] = {
                "dataset": name, "n_samples": sc.n_samples, "model": sc.model,
                "field_gauss": sc.field_gauss, "field_std": sc.field_std,
                "mse_before": sc.mse_before, "mse_after": sc.mse_after,
                "min_after": sc.min_after, "max_after": sc.max_after,
                "validation": sc.validation, "used": name == main}
            if name == main:
                board.mag = sc
        if unfit:
            board.mag.quality.setdefault("warnings", []).extend(unfit)
        if mnote:
            board.mag.notes.append(mnote)
            board.mag.quality.setdefault("warnings", []).append(mnote)
    if tc is not None:
        _thermal.attach(board, whole, data, tc)
    return board


def mag_data_sets(data: SessionData, limits: _gate.GateLimits = _gate.LIMITS) -> dict:
    """Every magnetometer data set of the session, ``{"R": (mask, why), "O":
    (mask, why)}`` (see the module doc; overflowed readings left out, sets
    under 10 rows dropped).  ``why`` is None for a set that can determine a
    model, else why it cannot: the quality gate's orientation, hull and
    coverage limits applied before the fit (``gate.set_metrics``), at least
    ``min_orientations`` static poses for O and ``min_mag_coverage`` of the
    sphere for R."""
    ok = data.has("mag") & ~(data.sensor("mag") == HMC5883L_OVERFLOW).any(axis=1)
    sets = {}
    if (data.label == LABEL_ROT).any():
        sets["R"] = ok & (data.label == LABEL_ROT)
    elif not (data.label >= 1).any():
        sets["R"] = ok & (data.label == LABEL_NONE)
    if (data.label >= 1).any():
        sets["O"] = ok & (data.label >= 1)
    out = {}
    for name, rows in sets.items():
        if rows.sum() < 10:
            continue
        u = data.sensor("mag")[rows] / data.scales["mag"]
        q = _gate.set_metrics(u, data.label[rows] if name == "O" else None)
        why = _gate.coverage_reasons(q, limits.min_orientations, limits)
        out[name] = (rows, "; ".join(why) if why else None)
    return out


def mag_sets(data: SessionData) -> dict:
    """Rows of each magnetometer data set that can determine a model,
    ``{"O": mask, "R": mask}`` (``mag_data_sets`` without the others)."""
    return {k: rows for k, (rows, why) in mag_data_sets(data).items() if why is None}


# ---------------------------------------------------------------------------
# accelerometer and magnetometer: magnitude models
# ---------------------------------------------------------------------------
def _kfold_groups(label, n, k):
    """Fold index per row: static poses dealt round-robin, else time blocks."""
    if label is not None:
        poses, inv = np.unique(label, return_inverse=True)
        return inv % k, "poses"
    return (np.arange(n) * k) // max(n, 1), "time blocks"


def kfold_validation(mdl: MagnitudeModel, theta, u, label, k: int, need: int) -> dict:
    """Held-out error: refit (LM from the full fit) without each fold of
    orientations and evaluate on it."""
    if k < 2:
        return {}
    fold, kind = _kfold_groups(label, len(u), k)
    if label is not None and len(np.unique(label)) - int(np.ceil(len(np.unique(label)) / k)) < need:
        return {"k": k, "groups": kind, "mse_heldout": None,
                "note": "too few orientations to leave any out"}
    sq = 0.0
    for f in range(k):
        te = fold == f
        if not te.any() or te.all():
            continue
        th, _ = _fit.polish(mdl, theta, u[~te])
        r = mdl.residuals(th, u[te])
        sq += float(r @ r)
    return {"k": k, "groups": kind, "mse_heldout": sq / len(u)}


def _magnitude_sensor(sensor, mdl: MagnitudeModel, counts, label, lsb, chip, ss, seed,
                      ga_options, kfold, dataset, still_limit) -> SensorCalibration:
    u = counts / lsb
    fr = _fit.ga_fit(mdl, u, label, seed=ss, options=ga_options)
    A, c, H = mdl.affine(fr.theta)
    H = float(H)
    mag_b = np.linalg.norm(u, axis=1)
    v = u @ A.T + c
    mag_a = np.linalg.norm(v, axis=1)
    if sensor == "accel":
        mse_before = float(np.mean((mag_b - 1.0) ** 2))
    else:                      # no calibration: the best constant field for the raw readings
        mse_before = float(np.mean((mag_b - mag_b.mean()) ** 2))
    params = []
    for p, val, sd, ok in zip(mdl.params, fr.theta, fr.std, fr.ident.identifiable):
        params.append(Param(p.name, float(val), float(sd), p.unit, bool(ok)))
    notes = [fr.ident.note()]
    if "angles" in mdl.groups:
        notes.append(ANGLE_NOTE)
    if sensor == "mag":
        notes.append("gauge: " + (
            "det(A) = 1 in nominal units: the geometric-mean scale is the datasheet gain "
            f"({lsb:g} LSB/gauss), so the field is in gauss as far as that gain is right"
            if mdl.gauge == "det" else f"field magnitude given: {mdl.field:g} gauss"))
    if fr.note:
        notes.append(fr.note)
    # quality metrics
    q = {"identifiable_params": fr.ident.rank, "rms_rel": float(np.sqrt(fr.mse)) / H,
         "condition": fr.ident.condition}
    if label is not None:
        poses = np.unique(label)
        means = np.array([v[label == p].mean(axis=0) for p in poses])
        q["distinct_orientations"] = distinct_directions(means)
        q["hull_depth"] = _gate.hull_depth(means)
        spread = _gate.pose_spread(counts / lsb, label)
        q["worst_pose_sd"] = max(spread.values()) if spread else 0.0
        q["not_still"] = [p for p, s in spread.items() if s > still_limit]
        q["still_limit"] = still_limit
    else:                      # a sweep: how much of the sphere it covers
        q["hull_depth"] = _gate.hull_depth(v[:: max(1, len(v) // 2000)])
        q["coverage"] = coverage(v)
    validation = kfold_validation(mdl, fr.theta, u, label, kfold, fr.ident.rank)
    validation["mse_fit"] = fr.mse
    sc = SensorCalibration(
        sensor=sensor, unit=UNITS[sensor], chip=chip, lsb_per_unit=float(lsb),
        model=mdl.family if mdl.family == "full" else f"paper({'+'.join(mdl.groups)})",
        params=params, A=A / lsb, c=c, mse_before=mse_before, mse_after=fr.mse,
        min_before=float(mag_b.min()), max_before=float(mag_b.max()),
        min_after=float(mag_a.min()), max_after=float(mag_a.max()),
        n_samples=len(u), n_poses=0 if label is None else len(np.unique(label)),
        dataset=dataset, rank=fr.ident.rank, notes=notes, validation=validation, quality=q,
        ga={"seed": seed, "generations": fr.ga_generations, "evaluations": fr.ga_evaluations,
            "stop": fr.ga_stop, "polish_nfev": fr.polish_nfev, "trace": fr.trace},
        gauge=mdl.gauge)
    Mj = mdl.affine_jacobian(fr.theta)[:12]          # d (A nominal, c) / d theta
    Mj[:9] /= lsb                                      # A per count, as sc.A
    sc.affine_cov = Mj @ fr.cov @ Mj.T
    if sensor == "mag":
        sc.field_gauss = H
        if mdl.free_field:
            sc.field_std = float(fr.std[-1])
    return sc


# ---------------------------------------------------------------------------
# gyroscope
# ---------------------------------------------------------------------------
def _recording_parts(data) -> np.ndarray:
    """Per row, the recording it belongs to: imported files (meta["files"] row
    ranges) are separate recordings; rows between them are not a move."""
    part = np.zeros(len(data), np.int64)
    for i, f in enumerate(data.meta.get("files") or []):
        rows = f.get("rows") if isinstance(f, dict) else None
        if rows and len(rows) == 2:
            part[int(rows[0]):int(rows[1])] = i + 1
    return part

def _gyro_sensor(data, rows, accel, chip, ss, seed, ga_options, kfold, gyro_matrix,
                 still) -> SensorCalibration:
    lsb = data.scales["gyro"]
    counts = data.sensor("gyro")[rows]
    label = data.label[rows]
    g = counts / lsb
    T = _gyro.bias_table(g)
    bm = _gyro.mean_bias(g, label)
    b = bm.b
    bf = _gyro.ga_bias(g, seed=ss, options=ga_options, table=T)     # the paper's eq. 6
    e6 = float(T(b))
    G = np.eye(3)
    params = [Param(f"b_{a}", float(v), float(s), "deg/s") for a, v, s in zip("xyz", b, bm.std)]
    notes = ["bias: mean of the still rates; std = the larger of sample sd / sqrt(n) and the "
             "scatter of the pose means",
             "the paper's eq. 6 (GA + exact minimiser) gives b = ("
             + ", ".join(f"{v:.4f}" for v in bf.b) + ") deg/s, ("
             + ", ".join(f"{v:+.4f}" for v in bf.b - b) + ") from the mean (its minimiser "
             "sits on a kink of the piecewise quadratic, often a whole count)"]
    warnings = []
    extra = {"bias_eq6": bf.b.tolist(), "bias_eq6_minus_mean": (bf.b - b).tolist(),
             "eq6_at_bias_eq6": bf.e6, "noise_sd": bm.sd.tolist(),
             "bias_std_white": bm.std_white.tolist(),
             "bias_std_poses": [None if not np.isfinite(v) else float(v) for v in bm.std_poses]}
    model = "bias"
    if gyro_matrix and accel is not None:
        poses = np.unique(label)
        acc = data.sensor("accel")
        grav, dirs = {}, {}
        for p in poses:
            sel = (data.label == p) & data.has("accel")
            if sel.any():
                ubar = acc[sel].mean(axis=0)
                v = accel.apply(ubar[None])[0]
                grav[int(p)] = unit(v)
                # d unit(A ubar + c) / d (A row-major, c)
                P = (np.eye(3) - np.outer(grav[int(p)], grav[int(p)])) / np.linalg.norm(v)
                dirs[int(p)] = P @ np.hstack([np.kron(np.eye(3), ubar[None, :]), np.eye(3)])
        moves = _gyro.find_moves(data.label, data.sample_times(), data.seq, data.sensor("gyro") / lsb,
                                 data.sensor("gyro"), grav, data.meta.get("rate_hz") or 125.0,
                                 part=_recording_parts(data))
        if len(moves) >= _gyro.MIN_MOVES:
            mf = _gyro.fit_matrix(moves, b, b_cov=np.diag(bm.std ** 2), dirs=dirs,
                                  dirs_cov=accel.affine_cov)
            extra["matrix_fit"] = {"moves": mf.n_moves, "rank": mf.rank,
                                   "rms_deg_before": float(np.rad2deg(mf.rms_before)),
                                   "rms_deg_after": float(np.rad2deg(mf.rms_after)),
                                   "std_from": {k: v.tolist() for k, v in mf.std_parts.items()}}
            ok = (mf.rank == 9 and np.rad2deg(mf.rms_after) < _gyro.MAX_RMS_DEG
                  and np.abs(mf.G - np.eye(3)).max() < _gyro.MAX_G_DEVIATION)
            if ok:
                G = mf.G
                model = "bias+matrix"
                for i, ai in enumerate("xyz"):
                    for j, aj in enumerate("xyz"):
                        params.append(Param(f"G_{ai}{aj}", float(G[i, j]), float(mf.std[i, j])))
                notes.append(f"scale and misalignment from {mf.n_moves} moves between still "
                             f"poses (gravity direction error {np.rad2deg(mf.rms_before):.2f} "
                             f"-> {np.rad2deg(mf.rms_after):.2f} deg rms); G maps into the "
                             f"calibrated accelerometer frame")
            else:
                warnings.append(
                    f"scale/misalignment fit from {mf.n_moves} moves not used: rank {mf.rank}/9, "
                    f"gravity direction error {np.rad2deg(mf.rms_after):.2f} deg rms (limit "
                    f"{_gyro.MAX_RMS_DEG:g}), max |G - I| {np.abs(mf.G - np.eye(3)).max():.3f} "
                    f"(limit {_gyro.MAX_G_DEVIATION:g}): bias only")
        else:
            warnings.append(f"only {len(moves)} usable moves between still poses: bias only")
    mag_b = np.linalg.norm(g, axis=1)
    w_after = (g - b) @ G.T
    mag_a = np.linalg.norm(w_after, axis=1)
    spread = _gate.pose_spread(g, label)
    q = {"not_still": [p for p, s in spread.items() if s > still.gyro_dps],
         "still_limit": still.gyro_dps,
         "worst_pose_sd": max(spread.values()) if spread else 0.0,
         "warnings": warnings}
    validation = {}
    if kfold >= 2 and len(np.unique(label)) >= 2:
        fold = np.unique(label, return_inverse=True)[1] % kfold
        sq = 0.0
        for f in range(kfold):
            te = fold == f
            if not te.any() or te.all():
                continue
            bk = g[~te].mean(axis=0)
            sq += float(np.sum(np.abs(g[te] - bk).sum(axis=1) ** 2))
        validation = {"k": kfold, "groups": "poses", "mse_heldout": sq / len(g),
                      "mse_fit": e6}
    return SensorCalibration(
        sensor="gyro", unit="deg/s", chip=chip, lsb_per_unit=float(lsb), model=model,
        params=params, A=G / lsb, c=-G @ b, mse_before=bf.e6_before, mse_after=e6,
        min_before=float(mag_b.min()), max_before=float(mag_b.max()),
        min_after=float(mag_a.min()), max_after=float(mag_a.max()),
        n_samples=len(g), n_poses=bm.n_poses, dataset="still", rank=3 + (9 if model != "bias" else 0),
        notes=notes, validation=validation, quality=q,
        ga={"seed": seed, "generations": bf.ga_generations, "stop": bf.ga_stop,
            "trace": bf.trace},
        extra=extra)
