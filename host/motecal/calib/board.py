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

Which model
-----------
Each sensor's data are judged before any fit (``content.judge_poses`` /
``content.magnetometer_sets``, the one judgement of ``calib.determine``):
without ``model`` the richest model they determine is fitted, and a sensor
they determine nothing of is not fitted at all (a hold in one orientation:
skipped; labelled poses: refused).  The choice and why are in
``settings["models"]`` and the sensor's first note; the orientations the
fitted model needs go to its quality for the gate.  A magnitude fit takes
at most ``MAX_POSE_SAMPLES`` of a pose and ``MAX_SWEEP_SAMPLES`` of a sweep
(``bounded_rows``), and notes a polish, refit or GA that reached its bound.
"""
from __future__ import annotations

import datetime as _dt

import numpy as np

from .. import __version__
from ..errors import UserError
from ..maths.sphere import coverage, distinct_directions, unit
from ..sessions.session import NOMINAL_CHIPS, UNITS, SessionData
from ..sessions.still import StillThresholds
from ..sessions.importer import CSV_FRAME
from . import fit as _fit
from .content import (MIN_POSE_ORIENTATIONS, ORIENTATIONS_NEEDED, Judgement, judge_poses,
                      labelled_poses, magnetometer_sets, model_key, pose_means,
                      poses_from_stillness, temperature_content)
from . import gate as _gate
from . import gyro as _gyro
from . import robust as _robust
from . import rotations as _rotations
from . import thermal as _thermal
from . import worth as _worth
from .ga import GAOptions
from .models import MagnitudeModel, mag_groups, make_model
from .result import BoardCalibration, Param, SensorCalibration

MIN_SWEEP = 200
KFOLD = 5
MAX_POSE_SAMPLES = 1000      # a fit takes at most this many samples of a pose (evenly spaced) ...
MAX_SWEEP_SAMPLES = 20000    # ... and of a sweep: what carries the information (module doc)

ANGLE_NOTE = ("the paper's angles only multiply the scales (an exact re-parametrisation of "
              "offset and scale): they cannot represent misalignment and are not "
              "identifiable; use --model full for cross-axis terms")


def _seeds(seed):
    if seed is None:
        seed = int(np.random.SeedSequence().entropy % (2 ** 31))
    ss = np.random.SeedSequence(int(seed))
    return int(seed), ss.spawn(3)


def calibrate_board(data: SessionData, *, model: str | None = None, groups=None, seed=None,
                    gauge: str | None = None, field: float | None = None,
                    gyro_matrix: bool = True, kfold: int = KFOLD,
                    ga_options: GAOptions = GAOptions(),
                    still: StillThresholds = StillThresholds(),
                    created: str | None = None,
                    mag_data: SessionData | None = None) -> BoardCalibration:
    """Calibrate every sensor of one mote's session (see the module doc).
    ``model`` None fits, per sensor, the richest model the data determine
    (``content.judge_poses`` / ``judge_sweep``); "full" or "paper" (with
    ``groups``) forces one.  ``mag_data``: the magnetometer from this
    session of the same board instead (its sweep or poses)."""
    motes = data.motes
    if len(motes) != 1:
        raise UserError(f"session {data.name} holds motes {motes}: calibrate one mote at a time")
    data, found = poses_from_stillness(data)
    labelled = labelled_poses(data)
    whole, tc = data, None
    if data.has_temp:                    # issue 16: holds fit the temperature terms only
        tc = temperature_content(data)
        data = _thermal.without_holds(data, tc)
    seed, (s_acc, s_gyr, s_mag) = _seeds(seed)
    created = created or _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
    board = BoardCalibration(mote=motes[0], session=data.name, created=created,
                             tool=f"motecal {__version__}")
    board.settings = {"model": model or "auto", "params": list(groups) if groups else None,
                      "seed": seed, "gauge": gauge, "field_gauss": field,
                      "gyro_matrix": bool(gyro_matrix), "kfold": kfold,
                      "skipped": {}, "insufficient": {}, "models": {},
                      # the axes the calibration is in (export-cal's Razor frame): a
                      # session without it is the mote's own samples, in the chips' axes
                      "axis_frame": (data.meta or {}).get("axis_frame") or CSV_FRAME}
    if found:
        board.settings["poses_found"] = found
    if data.meta.get("axis_frame"):
        board.settings["axis_frame"] = data.meta["axis_frame"]
    chips = dict(NOMINAL_CHIPS)
    chips.update(data.chips or {})

    # accelerometer: judged before any fit (content.judge_poses) ------------------
    acc_rows = (data.label >= 1) & data.has("accel")
    if not data.has("accel").any():
        board.settings["skipped"]["accel"] = "no accelerometer data in the session"
    elif not acc_rows.any():
        board.settings["skipped"]["accel"] = "no static poses in the session"
    else:
        j = judge_poses("accel", pose_means(data, "accel")[1])
        meant = labelled or j.orientations >= MIN_POSE_ORIENTATIONS
        if j.orientations <= 1:
            # a still hold (one orientation) is what a gyroscope bias is recorded
            # with: it determines the gyro, not the accelerometer -- left out
            board.settings["skipped"]["accel"] = (
                "a still hold in one orientation: it determines the gyroscope bias (and the "
                "temperature terms), not the accelerometer (that needs several orientations)")
        elif j.model is None:            # not fitted, whatever --model says
            if meant:
                board.settings["insufficient"]["accel"] = j.text()
            else:
                board.settings["skipped"]["accel"] = f"a hold in the data: {j.text()}"
        else:
            fam, grp = (model, groups) if model else (j.family, j.groups)
            mdl = make_model("accel", fam, grp)
            board.accel = _magnitude_sensor(
                "accel", mdl, data.sensor("accel")[acc_rows], data.label[acc_rows],
                data.scales["accel"], chips["accel"], s_acc, seed, ga_options, kfold,
                dataset="O", still_limit=still.accel_g,
                rows=np.flatnonzero(acc_rows), times=data.sample_times()[acc_rows])
            _record_choice(board, "accel", j, fam, grp, given=model is not None)

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

    # magnetometer: each set judged before any fit (content.magnetometer_sets) ------
    md = data if mag_data is None else mag_data
    if mag_data is not None:
        board.settings["mag_session"] = mag_data.name
        mchips = dict(NOMINAL_CHIPS)
        mchips.update(mag_data.chips or {})
        chips["mag"] = mchips["mag"]
    all_sets = magnetometer_sets(md)
    sets = {k: (rows, j) for k, (rows, j) in all_sets.items() if j.model is not None}
    unfit = [f"set {k} not fitted: {j.why_not()}" for k, (_, j) in all_sets.items()
             if j.model is None]
    if not md.has("mag").any():
        board.settings["skipped"]["mag"] = "no magnetometer data in the session"
    elif not sets:
        why = "; ".join(unfit) if all_sets else "needs a rotation sweep or static poses"
        if "R" in all_sets:          # a sweep, recorded for it: refused
            board.settings["insufficient"]["mag"] = why
        else:                        # static poses recorded for the accelerometer: left out
            board.settings["skipped"]["mag"] = ("no rotation sweep, and the static poses "
                                                f"cannot determine it ({why})")
    else:
        main = "R" if "R" in sets and sets["R"][0].sum() >= MIN_SWEEP else "O"
        if main not in sets:
            main = next(iter(sets))
        mnote = None
        for name, (rows, j) in sets.items():
            if model:
                fam = model
                mgroups, mnote = (mag_groups(groups, gauge, field) if model == "paper"
                                  else (groups, None))
            else:
                fam, mgroups = j.family, j.groups
            mdl = make_model("mag", fam, mgroups, gauge=gauge, field=field)
            sc = _magnitude_sensor(
                "mag", mdl, md.sensor("mag")[rows],
                md.label[rows] if name == "O" else None,
                md.scales["mag"], chips["mag"], s_mag, seed, ga_options, kfold,
                dataset=name, still_limit=still.mag_gauss,
                rows=np.flatnonzero(rows), times=md.sample_times()[rows])
            board.mag_sets[name] = {
                "dataset": name, "n_samples": sc.n_samples, "model": sc.model,
                "field_gauss": sc.field_gauss, "field_std": sc.field_std,
                "mse_before": sc.mse_before, "mse_after": sc.mse_after,
                "min_after": sc.min_after, "max_after": sc.max_after,
                "validation": sc.validation, "used": name == main,
                "set_aside": {k: sc.set_aside.get(k) for k in ("count", "of", "fraction")}}
            if name == main:
                board.mag = sc
                _record_choice(board, "mag", j, fam, mgroups, given=model is not None)
        if unfit:
            board.mag.quality.setdefault("warnings", []).extend(unfit)
        if mnote:
            board.mag.notes.append(mnote)
            board.mag.quality.setdefault("warnings", []).append(mnote)
    if tc is not None:
        _thermal.attach(board, whole, data, tc)
    _worth.attach(board)                 # tilt / heading error in degrees (issue 25)
    return board


def _record_choice(board, sensor: str, j: Judgement, family: str, groups, given: bool):
    """The model fitted for ``sensor``, what the data determine and why, in
    ``settings["models"]`` and the sensor's notes; the orientations that
    model needs go to its quality for the gate (static poses only)."""
    key = model_key(family, groups)
    sc = getattr(board, sensor)
    entry = {"model": family, "params": list(groups) if groups else None, "key": key,
             "determined": j.model, "given": bool(given), "why": j.text()}
    board.settings["models"][sensor] = entry
    if given:
        line = f"model {key} (--model); the data determine: {j.text()}"
    else:
        line = j.text()
    sc.notes.insert(0, line)
    if j.dataset == "O" and key in ORIENTATIONS_NEEDED:
        sc.quality["orientations_needed"] = ORIENTATIONS_NEEDED[key]


def mag_data_sets(data: SessionData, limits: _gate.GateLimits = _gate.LIMITS) -> dict:
    """Every magnetometer data set of the session, ``{"R": (mask, why), "O":
    (mask, why)}`` (see the module doc; overflowed readings left out, sets
    under 10 rows dropped).  ``why`` is None for a set that can determine a
    model, else why it cannot: the one judgement, ``content.magnetometer_sets``
    (the quality gate's orientation, hull and coverage limits applied before
    the fit)."""
    return {k: (rows, None if j.model else j.why_not())
            for k, (rows, j) in magnetometer_sets(data, limits).items()}


def sweep_reasons(u, t=None, seed: int = 0) -> tuple[list, dict]:
    """The one decision whether a magnetometer sweep (``u`` nominal units,
    ``t`` its times) can be calibrated through: the robust fit calibrate
    makes (``robust.ga_fit``, the full model) and the gate's rules on what
    it leaves -- the residual of the readings kept, the share set aside and
    the longest stretch set aside.  Returns (the gate's reasons, empty when
    it can; {"rms_rel", "rms_rel_all", "set_aside_frac", "longest_s"}).
    ``diagnose`` calls it for a field disturbance, so both commands give the
    same answer."""
    u = np.asarray(u, float)
    mdl = make_model("mag", "full")
    rf = _robust.ga_fit(mdl, u, seed=seed)
    H = float(mdl.affine(rf.theta)[2])
    rel = np.linalg.norm(u @ mdl.affine(rf.theta)[0].T + mdl.affine(rf.theta)[1], axis=1) / H - 1
    aside = _robust.set_aside_record(rf.keep, t, None, rf.scale, rel=rel)
    q = {"rms_rel": float(np.sqrt(rf.fit.mse)) / H, "rms_rel_all": float(np.sqrt(rf.mse_all)) / H,
         "set_aside_frac": aside["fraction"], "longest_s": aside["longest_s"]}
    reasons = [r for r in (_gate.residual_reason("mag", q["rms_rel"], set_aside=q["set_aside_frac"]),
                           _gate.set_aside_reason("mag", q["set_aside_frac"]),
                           _gate.stretch_reason("mag", aside)) if r]
    return reasons, q


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


def kfold_validation(mdl: MagnitudeModel, theta, u, label, k: int, need: int,
                     keep=None) -> dict:
    """Held-out error: refit without each fold of orientations (least
    squares from the full fit on the training readings it kept, ``keep``)
    and evaluate on the fold -- a trimmed error: the mean squared residual
    of the held-out readings within ``robust.REJECT_SD`` robust sd (of the
    full fit's residuals; a pose's readings from their pose's median), and
    the fraction of held-out readings beyond (``heldout_set_aside``).  A
    plain mean would be made of the glitches (each counts with its square)
    and say nothing of the readings the calibration is for."""
    if k < 2:
        return {}
    fold, kind = _kfold_groups(label, len(u), k)
    if label is not None and len(np.unique(label)) - int(np.ceil(len(np.unique(label)) / k)) < need:
        return {"k": k, "groups": kind, "mse_heldout": None,
                "note": "too few orientations to leave any out"}
    lim = _robust.REJECT_SD * _robust.robust_sd(
        _robust.deviations(mdl.residuals(theta, u), label))
    sq, n_in, n_out, bound = 0.0, 0, 0, 0
    for f in range(k):
        te = fold == f
        if not te.any() or te.all():
            continue
        tr = ~te if keep is None else ~te & keep
        th, nfev = _robust.polish(mdl, theta, u[tr])
        bound += nfev >= _fit.polish_limit(len(theta))
        r = mdl.residuals(th, u[te])
        e = _robust.deviations(r, None if label is None else label[te])
        if label is None:        # a sweep's held-out block: judged from the training fit's median
            e = r - float(np.median(mdl.residuals(th, u[tr])))
        ok = np.abs(e) <= lim if lim > 0 else np.ones(len(r), bool)
        sq += float(r[ok] @ r[ok])
        n_in += int(ok.sum())
        n_out += int((~ok).sum())
    out = {"k": k, "groups": kind, "mse_heldout": sq / max(n_in, 1),
           "heldout_set_aside": n_out / max(n_in + n_out, 1)}
    if bound:
        out["note"] = (f"{bound} of {k} held-out refits stopped at the least-squares bound "
                       f"({_fit.polish_limit(len(theta))} evaluations): their error may be "
                       f"overstated")
    return out


def bounded_rows(label, n: int) -> np.ndarray | None:
    """Rows a magnitude fit takes (issue 31): at most ``MAX_POSE_SAMPLES`` of
    each static pose and ``MAX_SWEEP_SAMPLES`` of a sweep (``label`` None),
    evenly spaced over each, so a longer hold of the same pose costs no more
    once its mean is known far better than the pose-to-pose scatter (the
    adaptive planner's own limit on samples per pose); None when nothing is
    left out."""
    if label is None:
        if n <= MAX_SWEEP_SAMPLES:
            return None
        return np.unique(np.linspace(0, n - 1, MAX_SWEEP_SAMPLES).round().astype(np.int64))
    label = np.asarray(label)
    labs, inv, cnt = np.unique(label, return_inverse=True, return_counts=True)
    if cnt.max() <= MAX_POSE_SAMPLES:
        return None
    keep = np.zeros(n, bool)
    for i, c in enumerate(cnt):
        idx = np.flatnonzero(inv == i)
        if c > MAX_POSE_SAMPLES:
            idx = idx[np.unique(np.linspace(0, c - 1, MAX_POSE_SAMPLES).round().astype(np.int64))]
        keep[idx] = True
    return np.flatnonzero(keep)


def _magnitude_sensor(sensor, mdl: MagnitudeModel, counts, label, lsb, chip, ss, seed,
                      ga_options, kfold, dataset, still_limit, rows=None,
                      times=None) -> SensorCalibration:
    """One accelerometer or magnetometer data set, fitted robustly
    (``robust.ga_fit``: readings far off are set aside, ``set_aside``); the
    error after, the magnitudes after and the quality metrics are of the
    readings kept, ``rms_rel_all`` of every reading.  A long hold or sweep is
    fitted on a bounded, evenly spaced share of its rows (``bounded_rows``)."""
    bound_note = None
    sub = bounded_rows(label, len(counts))
    if sub is not None:
        total = len(counts)
        counts = counts[sub]
        label = None if label is None else label[sub]
        rows = None if rows is None else np.asarray(rows)[sub]
        times = None if times is None else np.asarray(times)[sub]
        bound_note = (f"fitted on {len(sub)} of {total} samples: at most "
                      + (f"{MAX_POSE_SAMPLES} per pose" if label is not None
                         else f"{MAX_SWEEP_SAMPLES} of the sweep")
                      + ", evenly spaced (the rest repeat what these carry)")
    u = counts / lsb
    # static poses: a reading off its pose's median vector (on any axis, beyond
    # the robust sd) is a knock, whether or not it changes the magnitude
    pre = _robust.inliers_3d(u, label) if label is not None else np.ones(len(u), bool)
    rf = _robust.ga_fit(mdl, u[pre], None if label is None else label[pre], seed=ss,
                        options=ga_options)
    fr = rf.fit
    keep = np.zeros(len(u), bool)
    keep[np.flatnonzero(pre)[rf.keep]] = True
    A, c, H = mdl.affine(fr.theta)
    H = float(H)
    mag_b = np.linalg.norm(u, axis=1)
    v = u @ A.T + c
    mag_all = np.linalg.norm(v, axis=1)
    mag_a = mag_all[keep]
    aside = _robust.set_aside_record(keep, times, rows, rf.scale, rel=mag_all / H - 1.0)
    if sensor == "accel":
        mse_before = float(np.mean((mag_b - 1.0) ** 2))
    else:                      # no calibration: the best constant field for the raw readings
        mse_before = float(np.mean((mag_b - mag_b.mean()) ** 2))
    params = []
    for p, val, sd, ok in zip(mdl.params, fr.theta, fr.std, fr.ident.identifiable):
        params.append(Param(p.name, float(val), float(sd), p.unit, bool(ok)))
    notes = [fr.ident.note()]
    if aside["count"]:
        notes.append(_robust.set_aside_text(aside, mdl.unit))
    if "angles" in mdl.groups:
        notes.append(ANGLE_NOTE)
    if sensor == "mag":
        notes.append("gauge: " + (
            "det(A) = 1 in nominal units: the geometric-mean scale is the datasheet gain "
            f"({lsb:g} LSB/gauss), so the field is in gauss as far as that gain is right"
            if mdl.gauge == "det" else f"field magnitude given: {mdl.field:g} gauss"))
    if fr.note:
        notes.append(fr.note)
    if bound_note:
        notes.append(bound_note)
    if fr.ga_stop == "max_gen":
        notes.append(f"the GA stopped at its bound of {ga_options.max_gen} generations "
                     f"(the local refinement started from its best)")
    # quality metrics (of the readings kept: a pose's or the sweep's readings
    # set aside are not what the calibration is judged on; how many were is)
    q = {"identifiable_params": fr.ident.rank, "rms_rel": float(np.sqrt(fr.mse)) / H,
         "rms_rel_all": float(np.sqrt(np.mean((mag_all - H) ** 2))) / H,
         "robust_sd_rel": rf.scale / H, "set_aside_frac": aside["fraction"],
         "set_aside_longest_s": aside["longest_s"],
         "condition": fr.ident.condition}
    if label is not None:
        lk = label[keep]
        poses = np.unique(label)
        means = np.array([v[keep & (label == p)].mean(axis=0) if (keep & (label == p)).any()
                          else v[label == p].mean(axis=0) for p in poses])
        q["distinct_orientations"] = distinct_directions(means)
        q["hull_depth"] = _gate.hull_depth(means)
        spread = _gate.pose_spread(u[keep], lk)
        q["worst_pose_sd"] = max(spread.values()) if spread else 0.0
        q["not_still"] = [p for p, s in spread.items() if s > still_limit]
        q["still_limit"] = still_limit
    else:                      # a sweep: how much of the sphere the kept readings cover
        vk = v[keep]
        q["hull_depth"] = _gate.hull_depth(vk[:: max(1, len(vk) // 2000)])
        q["coverage"] = coverage(vk)
    validation = kfold_validation(mdl, fr.theta, u, label, kfold, fr.ident.rank, keep)
    validation["mse_fit"] = fr.mse
    if validation.get("note") and validation.get("mse_heldout") is not None:
        notes.append(f"validation: {validation['note']}")
    sc = SensorCalibration(
        sensor=sensor, unit=UNITS[sensor], chip=chip, lsb_per_unit=float(lsb),
        model=mdl.family if mdl.family == "full" else f"paper({'+'.join(mdl.groups)})",
        params=params, A=A / lsb, c=c, mse_before=mse_before, mse_after=fr.mse,
        min_before=float(mag_b.min()), max_before=float(mag_b.max()),
        min_after=float(mag_a.min()), max_after=float(mag_a.max()),
        n_samples=len(u), n_poses=0 if label is None else len(np.unique(label)),
        dataset=dataset, rank=fr.ident.rank, notes=notes, validation=validation, quality=q,
        ga={"seed": seed, "generations": fr.ga_generations, "evaluations": fr.ga_evaluations,
            "stop": fr.ga_stop, "polish_nfev": fr.polish_nfev, "trace": fr.trace,
            "objective": "robust scale (biweight M-scale of |v|/H - 1), then least squares on "
                         f"the readings within {_robust.REJECT_SD:g} robust sd",
            "route": rf.route, "robust_scale": {k: float(x) for k, x in rf.scales.items()}},
        gauge=mdl.gauge, set_aside=aside)
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
    keep = _robust.inliers_3d(data.sensor("gyro")[rows] / lsb, data.label[rows])
    aside = _robust.set_aside_record(keep, data.sample_times()[rows], np.flatnonzero(rows))
    sel = np.flatnonzero(rows)[keep]            # still rates kept: glitches set aside
    rows = np.zeros(len(data), bool)
    rows[sel] = True
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
             "scatter of the pose means"] + (
        [_robust.set_aside_text(aside, "of the still rates") + " (on any axis, from their pose's "
         "median)"] if aside["count"] else []) + [
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
            mf, mkeep = _gyro.fit_matrix_robust(moves, b, b_cov=np.diag(bm.std ** 2), dirs=dirs,
                                                dirs_cov=accel.affine_cov)
            if not mkeep.all():
                bad = [f"{m.pose0}->{m.pose1}" for m, k in zip(moves, mkeep) if not k]
                notes.append(f"moves set aside from the scale and misalignment fit: {len(bad)} "
                             f"of {len(moves)} (their gravity direction error beyond "
                             f"{_robust.REJECT_SD:g} robust sd: a glitch or a knock in the move): "
                             + ", ".join(bad[:8]) + (" ..." if len(bad) > 8 else ""))
            extra["matrix_fit"] = {"moves": mf.n_moves, "rank": mf.rank,
                                   "moves_set_aside": int((~mkeep).sum()),
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
         "set_aside_frac": aside["fraction"], "set_aside_longest_s": aside["longest_s"],
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
        extra=extra, set_aside=aside)
