"""What is left after every kept term: scatter beyond the noise.

``excess_finding``, per sensor after its fitted terms are decided: leftover
that is only finer time structure of a kept drift, a random walk of the bias
(``randomwalk``) or the kept motion is no finding; in poses, the
magnetometer's extra scatter is a ``field_disturbance`` when the dip angle
scatters too (``_dip_test``: the angle between calibrated gravity and field
per pose), else ``unexplained`` with its structure named (time correlation,
heavy tails, the outlier poses by label and time).  A sweep's leftover
(``_sweep_leftover``) is tested after a kept field wander too: scatter
beyond the noise that is also correlated in time, and single readings far
from the rest (docs/diagnosis-method.md, "A kept finding does not end the
questions")."""
from __future__ import annotations

import numpy as np
from scipy import stats

from ..calib.gate import residual_reason
from ..maths.sphere import angle_deg, unit
from . import causes as C
from . import fitting as F
from . import gain as G
from . import randomwalk as RW
from . import structure as ST
from .prepare import SensorObs
from .result import Finding

OUTLIER_MIN_REL = 0.03     # an outlier reading must also be this far off (share of the field)


def excess_finding(s, st: ST.Structure, o, sobs, structures, a_test, record, mot, force=None):
    """Scatter beyond the noise after every kept term: field disturbance
    (magnetometer) or unexplained."""
    ratio, p = st.excess
    if s == "mag" and st.regime == "sweep":
        # what is left of a sweep (after a kept field wander too: it does not
        # end the questions) is tested against the noise, and for outliers
        return _sweep_leftover(s, st, o, a_test, record, force)
    fit = st.fit
    if isinstance(fit, F.MagnitudeFit):
        X_, T = st.points["X"], st.points["T"]
        r = fit.residuals(X_, T)
        V = st.points["V"]
    else:
        Xd, names, groups = ST._design(st.points, frozenset(st.accepted), st.points["trange"])
        r = ((st.points["Y"] - Xd @ fit.beta) / o.K).ravel()
        V = ((1.0 / st.points["W"]) / o.K).ravel() ** 2
    time_kept = any(c in st.causes for c in ("bias_drift", "field_disturbance"))
    kept = p < a_test
    if force is not None:
        kept = (s, "field_disturbance") in force or (s, "unexplained") in force
        time_kept = False
    if kept and "bias_drift" in st.causes and not isinstance(fit, F.MagnitudeFit):
        # a random walk on top of the smooth drift (restricted likelihood)
        rw = getattr(st, "random_walk", None)
        if rw is not None:
            if rw["excess"][1] >= a_test:
                record(s, "excess", p, False, ratio=ratio,
                       note=f"explained by a random walk of the kept drift "
                            f"(sigma {np.round(rw['sigma_counts_per_sqrt_s'], 3).tolist()} "
                            f"counts/sqrt(s); chi-square p {rw['excess'][1]:.2g})")
                return None
    if kept and time_kept:
        # leftover that is just finer time structure of a kept drift
        T = st.points["T"]
        rr = r if r.shape == T.shape else r.reshape(-1, 3)
        ac, z = ST.lag1(rr, T)
        if z > 1.645:                 # one-sided 5 %: correlated, i.e. still the drift
            record(s, "excess", p, False, ratio=ratio,
                   note=f"time-correlated leftover (lag-1 {ac:.2f}) of the kept drift")
            return None
    if kept and mot is not None and s in ("accel", "gyro"):
        record(s, "excess", p, False, ratio=ratio, note="explained by the kept motion")
        return None
    if not kept:
        record(s, "excess", p, False, ratio=ratio)
        return None
    if force is None and not isinstance(fit, F.MagnitudeFit) and "bias_drift" not in st.causes:
        fd = RW.random_walk_finding(s, st, o, a_test)
        if fd is not None:
            record(s, "excess", p, True, ratio=ratio,
                   note="a random walk of the bias (restricted likelihood ratio "
                        f"p {fd.evidence['p']:.2g}): named bias_drift")
            return fd
    k = len(r)
    dof = max(1, k - fit.p)
    fold = (np.arange(k) % ST.KFOLD) if st.regime != "poses" else st.points["fold"]

    def tau2(mask):
        return max(0.0, float(np.mean(r[mask] ** 2) * k / max(dof, 1) - np.mean(V[mask])))

    tau2_all = tau2(np.ones(k, bool))
    if s == "mag" and st.regime in ("poses", "single"):
        gval, before, after = G.variance_gain(r, V, fold, tau2)
        ev = {"excess_ratio": ratio, "p": p, "level": a_test, "regime": st.regime,
              "heldout_rms_before": before, "heldout_rms_after": after,
              "gain_basis": "held-out rms of (measured - predicted) pose-residual spread"}
        dip = _dip_test(st, sobs, structures)
        H = fit.field_magnitude() if isinstance(fit, F.MagnitudeFit) else np.nan
        tau = float(np.sqrt(tau2_all))
        ev.update({"extra_scatter_gauss": tau, "relative_change": tau / H if H == H else None,
                   "untrustworthy": bool(H == H and residual_reason("mag", tau / H) is not None)})
        what = (f"pose field magnitudes scatter {ratio:.2g}x their noise "
                f"({tau:.2g} gauss beyond it).")
        if dip is not None:
            ev.update(dip)
            what += (f" The dip angle scatters {dip['dip_sd_deg']:.3g} deg across poses "
                     f"({dip['dip_excess_ratio']:.2g}x its noise).")
        ev["what"] = what
        is_field = dip is None or dip["dip_p"] < a_test
        if force is not None:
            is_field = (s, "field_disturbance") in force
        record(s, "excess", p, True, ratio=ratio)
        if is_field:
            # time correlation splits the scatter into per-pose jumps and a wander
            Tt = st.points["T"]
            order = np.argsort(Tt)
            x = r[order]
            ac = float(x[1:] @ x[:-1] / max(x @ x, 1e-30)) if len(x) > 3 else 0.0
            params = {"pose_rms_gauss": round(tau, 6), "rms_gauss": 0.0, "tau_s": 10.0}
            if ac > 3.0 / np.sqrt(len(x)):
                dt = float(np.median(np.diff(Tt[order])))
                params = {"pose_rms_gauss": round(tau * np.sqrt(1 - ac), 6),
                          "rms_gauss": round(tau * np.sqrt(ac), 6),
                          "tau_s": round(-dt / np.log(min(ac, 0.99)), 3)}
            ev["pose_residual_autocorrelation"] = ac
            return Finding(s, "field_disturbance",
                           C.summary(s, "field_disturbance", ev, params, gval, before, after,
                                     "gauss"), ev, params, gval)
        ev["structure"] = ("field magnitude scatter without a dip-angle change: "
                           + _structure_text(st, r))
        return Finding(s, "unexplained", C.summary(s, "unexplained", ev, {}, None), ev, {}, 1.0)
    record(s, "excess", p, True, ratio=ratio)
    ev = {"excess_ratio": ratio, "p": p, "level": a_test, "regime": st.regime,
          "extra_scatter": float(np.sqrt(tau2_all)), "unit": st.unit,
          "structure": _structure_text(st, r)}
    return Finding(s, "unexplained", C.summary(s, "unexplained", ev, {}, None), ev, {}, 1.0)


def _sweep_leftover(s, st: ST.Structure, o: SensorObs, a_test, record, force=None):
    """A sweep's residual after every kept term (the field's wander included):
    scatter beyond the white noise (chi-square, its degrees of freedom deflated
    by the residuals' long-run variance ratio, since consecutive readings share
    leftovers) and single readings far outside the rest (robust z beyond the
    Bonferroni bound of the readings).  Either is named ``unexplained``, with
    the outliers listed; no term is added."""
    X_, T, V = st.points["X"], st.points["T"], st.points["V"]
    r = st.fit.residuals(X_, T)
    k = len(r)
    dof = max(1, k - st.fit.p)
    ratio = float(np.mean(r * r) * k / dof / max(np.mean(V), 1e-30))
    lags = int(round(ST.NW_LAG_S / max(float(np.median(np.diff(T))) if k > 1 else 1.0, 1e-6)))
    kap = ST.inflation(st.fit, lambda f: f.residuals(X_, T), lags)
    dof_eff = max(1.0, dof / kap)
    p = float(stats.chi2.sf(ratio * dof_eff, dof_eff))
    # outliers among every reading (the fit saw a thinned sweep)
    ok = ~o.overflow
    Ta = o.t[ok]
    ra = st.fit.residuals(o.x[ok], Ta)
    med = float(np.median(ra))
    mad = 1.4826 * float(np.median(np.abs(ra - med)))
    z = np.abs(ra - med) / max(mad, 1e-30)
    zcrit = float(stats.norm.isf(a_test / (2 * len(ra))))
    H = st.fit.field_magnitude()
    out = np.flatnonzero((z > max(zcrit, 5.0)) & (np.abs(ra - med) > OUTLIER_MIN_REL * H))
    # scatter that is correlated in time is the kept wander, finer than its
    # basis follows; single readings far off are not
    ac, zac = ST.lag1(r, T)
    wander = "field_disturbance" in st.causes
    # a sweep's noise is not known well enough for the chi-square alone (its
    # estimate from moving readings is ~10 % low: clean simulated sweeps show
    # 1.15x): without a kept wander the leftover must also be correlated in
    # time (the whiteness test); correlated leftover after a kept wander is
    # that wander, finer than its basis
    white_p = st.excess[1]
    scatter = (p < a_test and white_p < a_test) if not wander else False
    kept = (scatter or len(out) > 0) if force is None else (s, "unexplained") in force
    record(s, "excess", min(p, 1.0), kept, ratio=ratio, outliers=int(len(out)),
           note="after the kept field wander" if wander else "sweep leftover")
    if not kept:
        return None
    parts = [f"lag-1 autocorrelation in time {ac:.2f}"
             + (" (the kept wander, finer than its basis)" if wander and p < a_test else "")]
    if len(out):
        big = out[np.argsort(-z[out])][:8]
        parts.append(f"{len(out)} outlier readings (robust z > {max(zcrit, 5.0):.1f} and > "
                     f"{100 * OUTLIER_MIN_REL:.0f} % of the field off), up to "
                     f"{100 * np.abs(ra[big[0]] - med) / H:.0f} % of the field; largest at "
                     + ", ".join(f"{Ta[i]:.1f} s ({z[i]:.0f}x)" for i in big))
    ev = {"excess_ratio": ratio, "p": p, "level": a_test, "regime": st.regime,
          "extra_scatter": float(np.sqrt(max(0.0, np.mean(r * r) - np.mean(V)))),
          "unit": st.unit, "outliers": int(len(out)),
          "outlier_times_s": [float(Ta[i]) for i in out[:200]],
          "largest_outlier_rel": float(np.abs(ra[out] - med).max() / H) if len(out) else 0.0,
          "structure": "; ".join(parts) + (" (after the kept field wander)" if wander else "")}
    return Finding(s, "unexplained", C.summary(s, "unexplained", ev, {}, None), ev, {}, 1.0)


def _dip_test(st: ST.Structure, sobs, structures) -> dict | None:
    """Angle between calibrated gravity and field per pose: constant unless the
    field changes direction.  A relative rotation of the two sensors (3
    parameters) and the dip are fitted; the scatter left is compared with
    the noise of the two pose means (chi-square)."""
    acc = sobs.get("accel")
    ast = structures.get("accel")
    mag = sobs.get("mag")
    if acc is None or ast is None or ast.regime != "poses" or st.regime != "poses":
        return None
    H = st.fit.field_magnitude()
    gvec, bvec, n_acc, idx = ST.pose_vectors(acc, ast.fit, mag, st.fit, st.points["group"])
    if len(gvec) < 8:
        return None
    n_mag = np.array([len(mag.segs.rows[gi]) for gi in idx])
    vg = np.mean(acc.sigma_eff ** 2) / acc.K ** 2 / n_acc
    vb = np.mean(mag.sigma_eff ** 2) / mag.K ** 2 / n_mag / H ** 2
    gu, bu = unit(gvec), unit(bvec)
    sd = np.sqrt(vg + vb)                                 # rad, per pose

    from scipy.optimize import least_squares
    from scipy.spatial.transform import Rotation

    def res(p):
        R = Rotation.from_rotvec(p[:3]).as_matrix()
        ang = np.radians(angle_deg(gu, bu @ R.T))
        return (ang - p[3]) / sd

    ang0 = np.radians(angle_deg(gu, bu))
    sol = least_squares(res, np.r_[0, 0, 0, ang0.mean()])
    rss = float(sol.fun @ sol.fun)
    dof = len(gu) - 4
    ratio, p = F.chi2_excess(rss, dof)
    R = Rotation.from_rotvec(sol.x[:3]).as_matrix()
    ang = np.radians(angle_deg(gu, bu @ R.T))
    return {"dip_deg": float(np.degrees(sol.x[3]) - 90.0), "dip_sd_deg": float(np.degrees(np.std(ang))),
            "dip_excess_ratio": ratio, "dip_p": p,
            "accel_mag_rotation_deg": float(np.degrees(np.linalg.norm(sol.x[:3])))}


def _structure_text(st: ST.Structure, r: np.ndarray) -> str:
    """What the leftover residual looks like."""
    parts = []
    T = st.points.get("T")
    if T is not None and len(r) > 8:
        o = np.argsort(T)
        rr = r[o] - r.mean()
        ac = float(rr[1:] @ rr[:-1] / max(rr @ rr, 1e-30))
        parts.append(f"lag-1 autocorrelation in time {ac:.2f}")
        z = np.abs(r) / np.sqrt(np.mean(r * r))
        parts.append(f"largest |residual| {z.max():.1f}x its rms")
        kurt = float(stats.kurtosis(r))
        if kurt > 3:
            parts.append(f"heavy tails (excess kurtosis {kurt:.1f}): outlier poses")
            out = _outliers(T, st.points.get("pose"), z)
            if out:
                parts.append("largest: " + ", ".join(out))
    return "; ".join(parts) if parts else "none identified"


def _outliers(T: np.ndarray, pose: np.ndarray | None, z: np.ndarray,
              most: int = 8) -> list[str]:
    """The poses (or still stretches) whose residual is over 3x the rms,
    largest first, named by pose label and time, for the user to look at
    (none when the residuals are not one per point of ``T``)."""
    if len(z) != len(T):
        return []
    k = [i for i in np.argsort(-z) if z[i] > 3.0][:most]
    return [(f"pose {pose[i]} " if pose is not None and pose[i] > 0 else "")
            + f"at {T[i]:.1f} s ({z[i]:.1f}x)" for i in k]
