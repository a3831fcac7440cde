"""Closing the loop (issue 13): a board calibrated with what a diagnosis of
its session found, each finding's treatment kept only when it lowers the
error on held-out data.

``calibrate_with_diagnosis(data, diagnosis, calibrate)``:

1. the plain calibration (``calibrate(data)``, the caller's
   ``calibrate_board`` with its options);
2. the readings the findings make wrong (``calib.terms.treatments``:
   repeats, clipped readings, outliers) are left out and the board is
   calibrated again; for each sensor, both calibrations are refitted without
   each fold of held-out poses (a sweep: of 1 s chunks) and judged on it --
   on the held-out readings the diagnosis did not call wrong, the same rows
   for both.  The treatment is used only when the held-out error falls by
   more than ``extra_terms.Z_ACCEPT`` standard errors; otherwise the plain
   calibration stays (what leaving out unbiased repeats changes is chance);
3. terms the calibration can fit (``calib.extra_terms``): the gyroscope's
   g-sensitivity and warm-up drift (the warm-up in time only when the
   gyroscope has no temperature model: a session with temperature whose
   term passed its gate has its drift modelled against temperature, and one
   model of it is used, not both), the accelerometer's nonlinearity, and
   for a small field disturbance the disturbed time spans of the sweep, each
   when the session can determine it (``content.term_support``) and kept
   only when the held-out error falls likewise.

Every finding ends in ``report["used"]`` or ``report["not_used"]`` with what
it changed (held-out rms before -> after, samples left out) or why not.
"""
from __future__ import annotations

import numpy as np

from ..errors import UserError
from ..maths.heldout import interleaved, kfold_heldout
from . import extra_terms as X
from . import fit as _fit
from . import robust as _robust
from .board import mag_data_sets
from .content import poses_from_stillness, term_support
from .models import mag_groups, make_model, theta_from_affine
from .terms import Treatment, drop_rows, treatments

CHUNK_S = 1.0              # a sweep's held-out groups: chunks of this long
SPAN_SMOOTH_S = 0.5        # the field magnitude is averaged over this long ...
SPAN_MAD = 3.0             # ... and a span deviating more than this many robust sd is disturbed
SPAN_MAD_TRIES = (2.0, 3.0, 4.0, 6.0)   # the first pass (from the calibration the disturbance
                                        # pulled): the widest cut that leaves a calibration
SPAN_PAD_S = 0.0           # and this much on both sides of it (at least one reading)
SPAN_ITER = 3              # spans found again from the calibration without them, at most this often


def sensor_model(sensor: str, settings: dict):
    """The magnitude model ``calibrate_board`` fitted for ``sensor`` (accel,
    mag) with ``settings`` (the board's)."""
    chosen = (settings.get("models") or {}).get(sensor)
    if chosen:                     # the model fitted (chosen by calib.determine, or given)
        model, groups = chosen["model"], chosen.get("params")
    else:
        model, groups = settings.get("model") or "full", settings.get("params")
        model = "full" if model == "auto" else model
    groups = tuple(groups) if groups else None
    if sensor == "accel":
        return make_model("accel", model, groups)
    gauge, field = settings.get("gauge"), settings.get("field_gauss")
    if chosen:
        return make_model("mag", model, groups, gauge=gauge, field=field)
    mg = mag_groups(groups, gauge, field)[0] if model == "paper" else groups
    return make_model("mag", model, mg, gauge=gauge, field=field)


def _groups(data, sensor: str, dataset: str | None):
    """(rows of the sensor's data set, group id per row (-1 none), pose
    means?) -- poses for the accelerometer, gyroscope and set O, 1 s chunks
    of a sweep."""
    if sensor in ("accel", "gyro") or dataset == "O":
        rows = (data.label >= 1)
        return rows, np.where(rows, data.label, -1), True
    sets = mag_data_sets(data)
    rows = sets.get(dataset or "R", (np.zeros(len(data), bool), None))[0].copy()
    t = data.sample_times()
    g = np.full(len(data), -1)
    if rows.any():
        g[rows] = ((t[rows] - t[rows][0]) // CHUNK_S).astype(int)
    return rows, g, False


def set_aside_rows(sc, n: int) -> np.ndarray:
    """The rows (of the session the calibration was made from) its robust
    fit set aside (``SensorCalibration.set_aside["rows"]``)."""
    out = np.zeros(n, bool)
    for a, c in (getattr(sc, "set_aside", None) or {}).get("rows", []):
        out[int(a):int(a) + int(c)] = True
    return out


def magnitude_heldout(sensor, data, sc_base, sc_cand, rows_base, rows_cand, group, test_ok,
                      settings, k, pose_means, z=X.Z_ACCEPT, robust: bool = True) -> X.Decision:
    """Held-out comparison of two calibrations of an accelerometer or
    magnetometer: each refitted (least squares from its own optimum, on the
    training rows its robust fit kept) without each fold of groups and
    judged, relative to its target, on the fold's rows in ``test_ok``.

    The per-group error is robust (``robust``): each squared relative
    residual is capped at ``(robust.REJECT_SD s)^2``, ``s`` the robust sd of
    the base calibration's residuals on those rows (one cap for both, so
    they are compared on the same readings).  A plain mean square is made of
    whatever glitches the held-out rows still hold -- the same glitches for
    both calibrations, so their noise swamped any difference and no
    treatment of outliers could pass.  ``robust=False`` is that plain mean
    (kept for the test that shows the difference)."""
    mdl = sensor_model(sensor, settings)
    lsb = sc_base.lsb_per_unit
    u = data.sensor(sensor) / lsb
    ids = np.unique(group[(group >= 0) & rows_base])
    need = max(int(sc_base.rank or 0), 1)
    if pose_means and len(ids) - int(np.ceil(len(ids) / k)) < need:
        return X.Decision(False, float("nan"), float("nan"), 0, 0.0,
                          why=f"too few poses to hold any out ({len(ids)} poses, {need} "
                              "parameters)")
    fold = interleaved(len(ids), k)                  # per group, in the order of ids
    tested = rows_base & test_ok & (group >= 0)

    def residuals_of(theta, rows):
        H = float(mdl.affine(theta)[2])
        if not pose_means:
            return mdl.residuals(theta, u[rows]) / H
        gs = np.unique(group[rows])
        x = np.array([u[rows & (group == g)].mean(axis=0) for g in gs]).reshape(-1, 3)
        return mdl.residuals(theta, x) / H

    cap = np.inf
    if robust and tested.any():
        th0 = np.array([p.value for p in sc_base.params], float)
        cap = (_robust.REJECT_SD * _robust.robust_sd(residuals_of(th0, tested))) ** 2 or np.inf
    out = {}
    for key, sc, rows in (("base", sc_base, rows_base), ("cand", sc_cand, rows_cand)):
        theta = np.array([p.value for p in sc.params], float)
        kept = rows & ~set_aside_rows(sc, len(rows)) if robust else rows

        def fit(train, kept=kept, theta=theta):
            tr = kept & np.isin(group, ids[train])
            if tr.sum() < 20:
                return None
            th, _ = _fit.polish(mdl, theta, u[tr])
            return th, float(mdl.affine(th)[2])

        def score(model, test):
            th, H = model
            e = np.full(int(test.sum()), np.nan)
            for i, g in enumerate(ids[test]):
                m = tested & (group == g)
                if not m.any():
                    continue
                x = u[m].mean(axis=0, keepdims=True) if pose_means else u[m]
                r = mdl.residuals(th, x) / H
                e[i] = float(np.mean(np.minimum(r * r, cap)))
            return e
        out[key] = kfold_heldout(fold, fit, score)
    return X.heldout_decision(out["base"], out["cand"], z)


def gyro_heldout_bias(data, rows_base, rows_cand, test_ok, k, z=X.Z_ACCEPT,
                      sc_base=None, sc_cand=None) -> X.Decision:
    """Held-out comparison of the gyroscope's bias (the mean of the still
    rates) from two sets of rows: per held-out pose, |pose mean - bias|^2.
    The still rates each calibration's robust fit set aside (``sc_base``,
    ``sc_cand``) are left out of its fit, and the base's out of every
    held-out pose mean (the same rows for both)."""
    g = data.sensor("gyro") / data.scales["gyro"]
    ids = np.unique(data.label[rows_base & (data.label >= 1)])
    fold = interleaved(len(ids), k)                  # per pose, in the order of ids
    test_ok = test_ok & ~set_aside_rows(sc_base, len(data))

    def score(b, test):
        e = np.full(int(test.sum()), np.nan)
        for i, p in enumerate(ids[test]):
            m = (data.label == p) & rows_base & test_ok
            if m.any():
                e[i] = float(np.sum((g[m].mean(axis=0) - b) ** 2))
        return e
    e = {}
    for key, rows, sc in (("base", rows_base, sc_base), ("cand", rows_cand, sc_cand)):
        rows = rows & ~set_aside_rows(sc, len(data))

        def fit(train, rows=rows):
            tr = rows & ~np.isin(data.label, ids[~train])
            return g[tr].mean(axis=0) if tr.any() else None
        e[key] = kfold_heldout(fold, fit, score)
    return X.heldout_decision(e["base"], e["cand"], z)


def _pose_table(data, board):
    """Per static pose with gyroscope and accelerometer: mean rate (deg/s,
    nominal), mean specific force (g, calibrated when the board has an
    accelerometer calibration), mid-time (s) and sample count; the readings
    the calibrations' robust fits set aside are left out of the means."""
    poses = [p for p in data.poses()]
    has = data.has("gyro") & data.has("accel") & ~set_aside_rows(board.gyro, len(data)) \
        & ~set_aside_rows(board.accel, len(data))
    t = data.sample_times()
    W, A, T, N = [], [], [], []
    for p in poses:
        m = (data.label == p) & has
        if m.sum() < 2:
            continue
        W.append(data.sensor("gyro")[m].mean(axis=0) / data.scales["gyro"])
        acc = data.sensor("accel")[m]
        A.append((board.accel.apply(acc) if board.accel is not None
                  else acc / data.scales["accel"]).mean(axis=0))
        T.append(float(np.mean(t[m]) - t[0]))
        N.append(int(m.sum()))
    return np.array(W).reshape(-1, 3), np.array(A).reshape(-1, 3), np.array(T), \
        np.array(N, float)


# ---------------------------------------------------------------------------
# the terms
# ---------------------------------------------------------------------------
def _gyro_terms(data, board, wanted: list, k: int, used, unused, z=X.Z_ACCEPT, log=None):
    """g_sensitivity and bias_drift of the gyroscope (``wanted`` in that
    order), each kept when the held-out pose error falls."""
    sc = board.gyro
    if sc is None:
        for c in wanted:
            unused.append(f"gyro {c}: the session gives no gyroscope calibration")
        return
    if "bias_drift" in wanted and sc.temperature is not None:
        # one model of the drift: the temperature's, when the session carries
        # it and the term passed its gate (calib.thermal); a warm-up in time on
        # top would correct the same drift twice
        wanted = [c for c in wanted if c != "bias_drift"]
        why = ("the drift is modelled against the board temperature instead (the session "
               "carries it and the temperature term passed its gate); a time-only warm-up on "
               "top would correct the same drift twice")
        unused.append(f"gyro bias_drift: not fitted: {why}")
        sc.notes.append(f"warm-up drift: the temperature model used, not the time-only "
                        f"warm-up: {why}")
    W, A, T, N = _pose_table(data, board)
    use = {"g_sensitivity": False, "bias_drift": False}
    for c in wanted:
        why = term_support(c, A, T)
        if why:
            unused.append(f"gyro {c}: not fitted: {why}")
            continue
        trial = dict(use, **{c: True})
        _, eb, ec = X.gyro_heldout(W, A, T, N, k, (use["g_sensitivity"], use["bias_drift"]),
                                   (trial["g_sensitivity"], trial["bias_drift"]))
        dec = X.heldout_decision(eb, ec, z)
        _log(log, "gyro", c, dec, "deg/s")
        if not dec.accepted:
            unused.append(f"gyro {c}: not used: {_no_gain(dec, 'deg/s')}")
            continue
        use = trial
        used.append(f"gyro {c}: fitted, {dec.text('deg/s')}")
    if not (use["g_sensitivity"] or use["bias_drift"]):
        return
    coef, tau = X._gyro_fit(W, A, T, N, use["g_sensitivity"], use["bias_drift"])
    G = np.asarray(sc.A, float) * sc.lsb_per_unit
    b_mean = -np.linalg.solve(G, np.asarray(sc.c, float))
    i = 1
    if use["g_sensitivity"]:
        S = coef[1:4].T                                  # row = gyro axis, deg/s per g
        a_mean = np.average(A, axis=0, weights=N)
        sc.extra["g_sensitivity"] = {"S": S.tolist(), "unit": "deg/s per g",
                                     "a_mean": a_mean.tolist(),
                                     "note": "still rate = bias + S (a - a_mean) (a: calibrated "
                                             "accelerometer, g; bias: the b_ parameters); "
                                             "applied on the host, not by the mote"}
        sc.notes.append("g-sensitivity from the diagnosis: still rate = b + S (a - a_mean), "
                        "largest |S| "
                        f"{np.abs(S).max():.3g} deg/s per g (extra.g_sensitivity)")
        i = 4
    if use["bias_drift"]:
        d, s = coef[i], coef[i + 1]
        t_end = float(T.max())
        a_mean = np.average(A, axis=0, weights=N) if use["g_sensitivity"] else np.zeros(3)
        b_end = coef[0] + (coef[1:4].T @ a_mean if use["g_sensitivity"] else 0.0) \
            + d * X.warmup(t_end, tau) + s * t_end
        sc.extra["bias_drift"] = {"tau_s": tau, "warmup": d.tolist(), "slope": s.tolist(),
                                  "t_end_s": t_end, "bias_mean": b_mean.tolist(),
                                  "bias_end": b_end.tolist()}
        sc.c = -G @ b_end
        for p, v in zip(sc.params[:3], b_end):
            p.value = float(v)
        sc.notes.append(f"warm-up drift from the diagnosis (tau {tau:g} s): the bias delivered is "
                        "the one at the end of the session, ("
                        + ", ".join(f"{v:.4f}" for v in b_end) + ") deg/s, instead of the "
                        "session mean (" + ", ".join(f"{v:.4f}" for v in b_mean) + "); "
                        "a warm-up in time, not against temperature: " + _why_no_temp(data, board))


def _why_no_temp(data, board) -> str:
    """Why the gyroscope's drift is not modelled against temperature."""
    if not data.has_temp:
        return "the session carries no temperature"
    why = (board.settings.get("temperature") or {}).get("not_fitted", {}).get("gyro")
    return f"the temperature term did not pass its gate ({why})" if why else \
        "the temperature term was not fitted"


def _accel_nonlinearity(data, board, k: int, used, unused, z=X.Z_ACCEPT, log=None):
    sc = board.accel
    if sc is None or sc.model != "full":
        unused.append("accel nonlinearity: not fitted: needs the full model's accelerometer "
                      "calibration")
        return
    rows = (data.label >= 1) & data.has("accel") & ~set_aside_rows(sc, len(data))
    poses = np.unique(data.label[rows])
    u = data.sensor("accel") / sc.lsb_per_unit
    U = np.array([u[rows & (data.label == p)].mean(axis=0) for p in poses]).reshape(-1, 3)
    w = np.array([(rows & (data.label == p)).sum() for p in poses], float)
    why = term_support("nonlinearity", U)
    if why:
        unused.append(f"accel nonlinearity: not fitted: {why}")
        return
    A0 = np.asarray(sc.A, float) * sc.lsb_per_unit
    c0 = np.asarray(sc.c, float)
    A, c, p, jac = X.nl_fit(U, w, A0, c0, nl=True)
    if X.nl_rank(jac) < 18:
        unused.append("accel nonlinearity: not fitted: the poses cannot determine it "
                      f"(Jacobian rank {X.nl_rank(jac)} of 18)")
        return
    _, eb, ec = X.nl_heldout(U, w, A0, c0, k)
    dec = X.heldout_decision(eb, ec, z)
    _log(log, "accel", "nonlinearity", dec, "g")
    if not dec.accepted:
        unused.append(f"accel nonlinearity: not used: {_no_gain(dec, 'g')}")
        return
    mdl = make_model("accel", "full")
    th = theta_from_affine(mdl, A, c)
    for prm, v in zip(sc.params, th):
        prm.value = float(v)
    sc.A, sc.c = A / sc.lsb_per_unit, c
    sc.extra["nonlinearity"] = {"q": p[0:3].tolist(), "c3": p[3:6].tolist(),
                                "a": p[6:9].tolist(),
                                "note": "v = A h(u) + c, h(u) = u + q u^2 + c3 u^3 + a |u| "
                                        "(u = counts / lsb); A and c are fitted with h; h is "
                                        "applied on the host, not by the mote"}
    k_ = int(np.argmax(np.abs(p)))
    sc.notes.append(f"nonlinearity from the diagnosis: largest {X.NL_NAMES[k_]} = {p[k_]:.3g}; "
                    "the affine part was fitted together with it (extra.nonlinearity)")
    used.append(f"accel nonlinearity: fitted, {dec.text('g')}")


def disturbed_spans(data, sc, rows, n_mad: float = SPAN_MAD) -> np.ndarray:
    """Rows of the sweep ``rows`` where the field magnitude (after the
    calibration ``sc``), averaged over ``SPAN_SMOOTH_S``, deviates from its
    median by more than ``n_mad`` robust standard deviations, padded by
    ``SPAN_PAD_S``."""
    idx = np.flatnonzero(rows)
    out = np.zeros(len(data), bool)
    if len(idx) < 50 or sc is None:
        return out
    t = data.sample_times()[idx]
    m = np.linalg.norm(sc.apply(data.sensor("mag")[idx]), axis=1)
    rate = max(1.0, len(idx) / max(float(np.ptp(t)), 1e-9))
    w = max(1, int(round(SPAN_SMOOTH_S * rate)))
    c = np.cumsum(np.r_[0.0, m])
    lo = np.clip(np.arange(len(m)) - w // 2, 0, max(len(m) - w, 0))
    sm = (c[lo + w] - c[lo]) / w
    med = np.median(sm)
    sd = 1.4826 * np.median(np.abs(sm - med))
    bad = np.abs(sm - med) > n_mad * sd if sd > 0 else np.zeros(len(m), bool)
    if bad.any():
        pad = max(1, int(round(SPAN_PAD_S * rate)))
        bad = np.convolve(bad.astype(float), np.ones(2 * pad + 1), "same") > 0
    out[idx] = bad
    return out


# ---------------------------------------------------------------------------
# the whole loop
# ---------------------------------------------------------------------------
def _replace_sensor(board, cand, sensor):
    setattr(board, sensor, getattr(cand, sensor))
    if sensor == "mag":
        board.mag_sets = cand.mag_sets
    for key in ("skipped", "insufficient"):
        board.settings[key].pop(sensor, None)
        if sensor in cand.settings.get(key, {}):
            board.settings[key][sensor] = cand.settings[key][sensor]


def calibrate_with_diagnosis(data, diagnosis: dict, calibrate, *, kfold: int = 5,
                             z_accept: float = X.Z_ACCEPT):
    """(board, {"used": [...], "not_used": [...]}) -- see the module doc.
    ``calibrate(data)`` calibrates one mote's data (``calibrate_board`` with
    the caller's options).  ``z_accept`` = -inf takes every treatment and
    term the session can determine without the held-out check (the bench's
    reference: the model the diagnosis names, fitted)."""
    z = z_accept
    k = max(2, int(kfold) if kfold else 5)
    data, found = poses_from_stillness(data)
    try:
        items = treatments(data, diagnosis)
    except (TypeError, ValueError, KeyError, AttributeError, IndexError) as e:
        raise UserError(f"the diagnosis has a finding calibrate cannot read ({e}); run "
                        "motecal diagnose again") from None
    board = calibrate(data)
    if found:
        board.settings["poses_found"] = found
    used, unused, log = [], [], []
    for tr in items:
        if not tr.used:
            unused.append(tr.text)
    # readings left out, per sensor, judged on held-out data
    drops = [tr for tr in items if tr.used and tr.drop is not None and tr.drop.any()]
    kept = []                        # the treatments taken: later candidates build on them
    for tr in items:
        if tr.used and tr.drop is not None and not tr.drop.any():
            unused.append(f"{tr.text}: none found in this session's rows")
    if drops:
        cand_data = drop_rows(data, drops)
        cand = calibrate(cand_data)
        for sensor in ("accel", "gyro", "mag"):
            mine = [tr for tr in drops if tr.sensor == sensor]
            if not mine:
                continue
            drop = np.any([tr.drop for tr in mine], axis=0)
            texts = "; ".join(tr.text for tr in mine)
            sb, scand = getattr(board, sensor), getattr(cand, sensor)
            if sb is None or scand is None:
                if sb is None and scand is not None:
                    _replace_sensor(board, cand, sensor)
                    used.append(f"{texts} left out (the {sensor} calibrates only without them)")
                else:
                    unused.append(f"{texts}: no {sensor} calibration either way")
                continue
            aside = set_aside_rows(sb, len(data))
            if drop.any() and not (drop & ~aside & data.has(sensor)).any():
                unused.append(f"{texts}: already set aside by the robust fit (it set aside "
                              f"{int(aside.sum())} readings in all)")
                continue
            has = data.has(sensor)
            if sensor == "gyro":
                rows = (data.label >= 1) & has
                dec = gyro_heldout_bias(data, rows, rows & ~drop, ~drop, k, z, sb, scand)
                unit = "deg/s"
            else:
                rows, group, pm = _groups(data, sensor, sb.dataset)
                rows &= has
                dec = magnitude_heldout(sensor, data, sb, scand, rows, rows & ~drop, group,
                                        ~drop, board.settings, k, pm, z)
                unit = "of the target (relative)"
            _log(log, sensor, "+".join(tr.cause for tr in mine), dec,
                 unit if sensor == "gyro" else "relative")
            if dec.accepted:
                _replace_sensor(board, cand, sensor)
                kept += mine
                used.append(f"{texts} left out (a trimmed fit): {dec.text(unit)}")
            else:
                unused.append(f"{texts}: kept in: {_no_gain(dec, unit, 'leaving them out')}")
    # the disturbed spans of a sweep (also tried when the diagnosis saw single
    # readings far off: in a sweep they may be a span of a disturbed field)
    if any(tr.sensor == "mag" and tr.cause == "outliers" for tr in items) and not any(
            tr.term == "disturbed_spans" or tr.refuse for tr in items):
        items.append(Treatment("mag", "field_disturbance", "", term="disturbed_spans"))
    for tr in items:
        if tr.term == "disturbed_spans":
            sb = board.mag
            if sb is None or sb.dataset != "R":
                unused.append(f"{tr.sensor} field_disturbance: no sweep calibration to cut "
                              "spans from")
                continue
            rows, group, _ = _groups(data, "mag", "R")
            rows &= data.has("mag")
            gone = np.zeros(len(data), bool)        # readings already left out
            for tk in kept:
                if tk.sensor == "mag":
                    gone |= tk.drop
            rows &= ~gone
            for n_mad in SPAN_MAD_TRIES:
                # a wide first cut may leave too little of the sphere: narrower ones then
                cut = disturbed_spans(data, sb, rows, n_mad)
                if not cut.any():
                    break
                cand = calibrate(drop_rows(data, kept + [Treatment("mag", "spans", "", drop=cut)]))
                if cand.mag is not None:
                    break
            if not cut.any():
                unused.append("mag field_disturbance: no disturbed span stands out of the "
                              "wander; calibrated through (the gate's residual limit holds it)")
                continue
            for _ in range(SPAN_ITER - 1):
                # the first spans come from a calibration the disturbance pulled:
                # found again with the calibration made without them
                if cand.mag is None:
                    break
                again = disturbed_spans(data, cand.mag, rows)
                if not again.any() or np.array_equal(again, cut):
                    break
                cut = again
                cand = calibrate(drop_rows(data, kept + [Treatment("mag", "spans", "", drop=cut)]))
            if cand.mag is None:
                unused.append("mag field_disturbance: without the disturbed spans the sweep "
                              "no longer determines the magnetometer: calibrated through")
                continue
            dec = magnitude_heldout("mag", data, sb, cand.mag, rows, rows & ~cut, group, ~cut,
                                    board.settings, k, False, z)
            t = data.sample_times()
            secs = float(cut.sum()) / max(1.0, data.rate("mag") or data.rate())
            text = (f"mag field_disturbance: disturbed spans left out ({int(cut.sum())} readings, "
                    f"about {secs:.0f} s of {float(np.ptp(t[rows])):.0f} s)")
            _log(log, "mag", "disturbed spans", dec, "relative")
            if dec.accepted:
                _replace_sensor(board, cand, "mag")
                used.append(f"{text}; {dec.text('of the field (relative)')}")
            else:
                unused.append(f"{text}: not used: "
                              f"{_no_gain(dec, 'of the field (relative)')}")
        elif tr.refuse and tr.sensor == "mag" and board.mag is not None:
            board.mag, board.mag_sets = None, {}
            board.settings["insufficient"]["mag"] = tr.refuse
            used.append(tr.text)
        elif tr.refuse:
            used.append(tr.text)
    # model terms (the accelerometer's first: the gyroscope's use its readings)
    if any(tr.term == "nonlinearity" and tr.sensor == "accel" for tr in items):
        _accel_nonlinearity(data, board, k, used, unused, z, log)
    wanted = [c for c in ("g_sensitivity", "bias_drift")
              if any(tr.term == c and tr.sensor == "gyro" for tr in items)]
    if wanted:
        _gyro_terms(data, board, wanted, k, used, unused, z, log)
    return board, {"used": used, "not_used": unused, "decisions": log}


def _no_gain(dec, unit, what="it"):
    if dec.why:
        return dec.text(unit)
    return f"{what} does not lower the held-out error ({dec.text(unit)})"


def _finite(x):
    return float(x) if np.isfinite(x) else None


def _log(log, sensor, what, dec, unit):
    if log is not None:
        log.append({"sensor": sensor, "what": what, "used": dec.accepted,
                    "heldout_rms_before": _finite(dec.before),
                    "heldout_rms_after": _finite(dec.after),
                    "groups": dec.groups, "z": dec.z, "unit": unit,
                    **({"why": dec.why} if dec.why else {})})

