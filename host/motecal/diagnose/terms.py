"""A kept fitted term as a finding: its evidence (the F-test, the held-out
rms before and after, what the gain is measured on, and the term's size and
where it is largest) and the simulator term's parameters, per cause:
``cross_axis`` (the coupling matrix), ``nonlinearity``, ``bias_drift`` (the
drift curve as a warm-up + slope, with the random walk on top),
``field_disturbance`` (its size against the gate's 5 % rule) and
``g_sensitivity``."""
from __future__ import annotations

import numpy as np

from ..calib.board import sweep_reasons
from . import causes as C
from . import extend as X
from . import fitting as F
from . import structure as ST
from .prepare import SensorObs
from .result import Finding, num

def term_finding(s, c, st: ST.Structure, o: SensorObs, g, before, after) -> Finding:
    rec = [t for t in st.tests if t.cause == c]
    best = min(rec, key=lambda t: t.p)
    ev = {"F": num(best.F), "p": num(best.p), "extra_params": best.q, "dof": best.dof,
          "delta_bic": num(best.dbic), "regime": st.regime,
          "heldout_rms_before": before, "heldout_rms_after": after, "unit": st.unit,
          "noise_floor": st.noise_floor, "points": int(len(st.points.get("X", st.points.get("Y")))),
          "gain_basis": ("held-out rms of the pose-mean magnitude residual"
                         if st.regime == "poses" else
                         "held-out rms of the magnitude residual (time blocks)"
                         if st.regime == "sweep" else
                         "held-out rms of block means (interleaved time blocks)")}
    if c == "bias_drift" and getattr(st, "kriged", False):
        ev["gain_basis"] += ("; with the drift, the random walk on top of it predicted "
                             "from the neighbouring blocks (kriging)")
    params = {}
    fit = st.fit
    if isinstance(fit, F.MagnitudeFit):
        tb, parts = fit.split()
        pmap = {e.cause: (e, p) for e, p in zip(fit.extras, parts)}
        if c == "cross_axis":
            A, cc, H = fit.affine()
            M = np.linalg.inv(A)
            D = np.diag(M)
            Cm = M / D[:, None] - np.eye(3)
            np.fill_diagonal(Cm, 0)
            i, j = np.unravel_index(np.argmax(np.abs(Cm)), Cm.shape)
            ev["max_coupling"] = float(Cm[i, j])
            ev["max_coupling_at"] = f"C[{'xyz'[i]}{'xyz'[j]}]"
            ev["matrix"] = np.round(M / np.cbrt(np.linalg.det(M)), 6)
            params = {"C": np.round(Cm, 6)}
        elif c == "nonlinearity":
            e, p = pmap["nonlinearity"]
            k = int(np.argmax(np.abs(p)))
            ev["max_coef"] = float(p[k])
            ev["max_coef_at"] = e.names()[k]
            params = {"q": np.round(p[0:3], 6), "c3": np.round(p[3:6], 6), "a": np.round(p[6:9], 6)}
        elif c == "bias_drift":
            e, p = pmap["bias_drift"]
            tt = np.linspace(*st.points["trange"], 200)
            curve = e.offset(tt, p) / o.K
            ev["drift_range"] = float(np.ptp(curve, axis=0).max())
            ev["basis"] = f"{e.J} time functions per axis"
            params = _drift_params_for(curve * X.K_NOMINAL[s], tt, e.J)
        elif c == "field_disturbance":
            e, p = pmap["field_disturbance"]
            T = st.points["T"]
            f = e.field(T, p)
            H = fit.field_magnitude()
            rel = float(np.std(f) / H)
            ev["relative_change"] = rel
            ev["field_range_gauss"] = float(np.ptp(f))
            # the same decision calibrate's gate makes, on the same robust fit
            # (calib.board.sweep_reasons: the residual of the readings kept, the
            # share set aside, the longest stretch set aside)
            ok = ~o.overflow
            why, left = sweep_reasons(o.x[ok] / o.K, o.t[ok])
            ev["calibration_rms_rel"] = left["rms_rel"]
            ev["calibration_set_aside"] = left["set_aside_frac"]
            ev["untrustworthy"] = bool(why)
            if why:
                ev["gate"] = "; ".join(why)
            ev["what"] = (f"the field magnitude moves with time by {np.std(f):.3g} gauss rms "
                          f"({np.ptp(f):.3g} peak to peak) around {H:.3g} gauss, independent "
                          f"of direction.")
            params = {"rms_gauss": round(float(np.std(f)), 6),
                      "tau_s": round(_corr_time(T, f), 3), "pose_rms_gauss": 0.0}
    else:
        cols = fit.groups.get(c, [])
        if c == "g_sensitivity":
            Gm = fit.beta[cols].T / o.K
            i, j = np.unravel_index(np.argmax(np.abs(Gm)), Gm.shape)
            ev["max_G"] = float(Gm[i, j])
            ev["max_G_at"] = f"G[{'xyz'[i]}{'xyz'[j]}] (gyro {'xyz'[i]} per accel {'xyz'[j]})"
            params = {"G": np.round(Gm, 6)}
        elif c == "bias_drift":
            J = len(cols)
            tt = np.linspace(*st.points["trange"], 200)
            Phi = F.time_basis(tt, *st.points["trange"], J)
            curve = Phi @ fit.beta[cols] / o.K
            ev["drift_range"] = float(np.ptp(curve, axis=0).max())
            ev["basis"] = f"{J} time functions per axis"
            params = _drift_params_for(curve * X.K_NOMINAL[s], tt, J)
            rw = getattr(st, "random_walk", None)
            if rw is not None:
                rws = np.asarray(rw["sigma_counts_per_sqrt_s"]) * X.sim_scale(s, o.K)
                params["sigma"] = X._r(np.maximum(np.asarray(params["sigma"], float), rws))
                ev["random_walk_sigma"] = X._r(rws)
    summ = C.summary(s, c, ev, params, g, before, after, st.unit)
    return Finding(s, c, summ, ev, params, g)


def _drift_params_for(curve_sim, tt, J):
    dp, _ = X.drift_params(tt - tt[0], curve_sim, J > F.DRIFT_J, J)
    return dp


def _corr_time(T, f) -> float:
    f = f - f.mean()
    if len(f) < 4 or not np.any(f):
        return 10.0
    ac = np.correlate(f, f, "full")[len(f) - 1:] / (f @ f)
    dt = np.median(np.diff(T)) if len(T) > 1 else 1.0
    k = np.flatnonzero(ac < np.exp(-1))
    return float((k[0] if len(k) else len(f)) * dt)
