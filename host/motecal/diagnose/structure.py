"""Calibration-type causes: terms that change the *mean* reading, found by
nested least squares and confirmed on held-out data.

Per sensor, one of four regimes decides what the observations are:

* ``poses``  (accelerometer, magnetometer; >= ``MIN_POSES`` still
  orientations): one magnitude residual per pose mean, weighted by its noise;
  candidates ``cross_axis``, ``nonlinearity``, ``bias_drift``.
* ``sweep``  (magnetometer without enough poses): one magnitude residual per
  reading; candidates ``cross_axis`` and ``field_disturbance`` as a field
  magnitude that moves with time.  Consecutive readings share slow
  leftovers, so small terms get a cluster-robust Wald test.  Two causes are
  left to static poses: a drifting hard iron cannot be told from a changing
  field without a reference, and on single noisy readings the nonlinearity
  F-test is not calibrated (pure noise passes it far more often than its
  level: 40-55 % at 5 % in simulated sweeps).
* ``single`` (accelerometer or magnetometer in one or a few orientations):
  per axis, block means = a constant per orientation + drift; candidate
  ``bias_drift``.
* ``still``  (gyroscope): per axis, block means = bias (per recording) +
  g-sensitivity x specific force + drift; candidates ``g_sensitivity``,
  ``bias_drift``.

Selection is forward and greedy: in each round every remaining candidate is
added to the current model and F-tested against it; the most significant one
is kept if its p-value is below the per-test level the engine passes in
(``alpha``, Bonferroni over every test of the diagnosis).  The held-out gain
of each kept term is then measured by K-fold cross-validation over
interleaved poses, time blocks or (sweeps) readings: held-out rms of the
residual of the final model without the term / with it (both refitted on
the other folds).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..maths import sphere as S
from . import fitting as F
from .prepare import SensorObs

MIN_POSES = 12            # orientations needed for magnitude (calibration) terms
KFOLD = 5
SWEEP_CHUNK_S = 2.0       # time chunk of sweep data for held-out folds
MAX_SWEEP_POINTS = 4000   # sweeps are thinned to this many readings
HELDOUT_NFEV = 12         # held-out refits start at the full fit: a few steps suffice
MIN_DOF = 5
PAIRED_MIN_POINTS = 15    # held-out points a paired test of them needs


@dataclass
class TestRecord:
    round: int
    cause: str
    q: int
    F: float
    p: float
    dof: int
    dbic: float
    rss0: float
    rss1: float


@dataclass
class Structure:
    sensor: str
    regime: str
    unit: str
    accepted: list                 # spec items (cause[:size]), in the order added
    tests: list                    # TestRecord
    fit0: object                   # starting model fit
    fit: object                    # final fit
    fits: dict                     # frozenset(causes) -> fit
    points: dict                   # arrays used (for evidence and pictures)
    excess: tuple = (1.0, 1.0)     # (rss/dof, p) of the final model
    heldout: dict = field(default_factory=dict)    # cause -> (rms_without, rms_with)
    heldout_total: tuple | None = None             # (rms start model, rms final)
    fold_wins: dict = field(default_factory=dict)  # cause -> folds where the term helped
    heldout_p: dict = field(default_factory=dict)  # cause -> paired test of the held-out points
    noise_floor: float = np.nan    # rms a perfect model leaves on the points (sensor unit)
    notes: list = field(default_factory=list)

    @property
    def causes(self) -> list[str]:
        return [cause_of(c) for c in self.accepted]


# ---------------------------------------------------------------------------
# magnitude sensors
# ---------------------------------------------------------------------------
def cause_of(item: str) -> str:
    """Spec items are cause ids, optionally with a basis size: "bias_drift:16"."""
    return item.split(":")[0]


def _size(spec, cause, default):
    for it in spec:
        if cause_of(it) == cause and ":" in it:
            return int(it.split(":")[1])
    return default


def _causes(spec) -> set:
    return {cause_of(it) for it in spec}


def _spec_fit(sensor, K, X, T, W, spec: frozenset, trange, Jf, start=None, max_nfev=None):
    causes = _causes(spec)
    family = "full" if "cross_axis" in causes else "paper"
    extras = []
    if "nonlinearity" in causes:
        extras.append(F.NonlinearityExtra())
    if "bias_drift" in causes:
        extras.append(F.DriftExtra(*trange, _size(spec, "bias_drift", F.DRIFT_J)))
    if "field_disturbance" in causes:
        extras.append(F.FieldExtra(*trange, _size(spec, "field_disturbance", Jf)))
    return F.fit_magnitude(sensor, K, X, T, W, family=family, extras=extras, start=start,
                           max_nfev=max_nfev)


def drift_sizes(duration: float, max_params: int, per_axis: int = 3) -> list[int]:
    """Basis sizes tried for a drift: a smooth one (linear, slow warm-up), one
    function per ~30 s (a fast warm-up) and one per ~10 s (a random walk), as
    the data allow (at most ``max_params`` parameters: a sixth of the points,
    so that the drift cannot follow everything else that varies with time)."""
    cap = max_params // per_axis
    if cap < F.DRIFT_J:
        # too few points for the smooth basis (a hand session's 24-30 poses):
        # a straight line per axis, which the points can test
        return [1]
    small = F.DRIFT_J
    out = [small]
    for j in (int(np.clip(round(duration / 30.0), 6, 20)),
              int(np.clip(round(duration / 10.0), 8, 40))):
        j = min(j, cap)
        if j > out[-1]:
            out.append(j)
    return out


def lag1(r: np.ndarray, T: np.ndarray) -> tuple[float, float]:
    """Pooled lag-1 autocorrelation of residuals in time order (columns are
    separate series) and its z-score under white residuals."""
    r = np.asarray(r, float)
    if r.ndim == 1:
        r = r[:, None]
    o = np.argsort(T, kind="stable")
    x = r[o] - r[o].mean(axis=0)
    num = float(np.sum(x[1:] * x[:-1]))
    den = float(np.sum(x * x))
    if den <= 0 or len(x) < 3:
        return 0.0, 0.0
    rho = num / den
    return rho, rho * np.sqrt((len(x) - 1) * x.shape[1])


NW_LAG_S = 1.0            # Newey-West window for correlated sweep residuals


def inflation(fit, resid_fn, lags: int) -> float:
    """Long-run variance ratio of the (time-ordered) weighted residuals:
    1 + 2 sum_k (1 - k/(L+1)) rho_k over L lags (Newey-West, Bartlett
    weights).  1 for white residuals; > 1 when leftovers are correlated, so
    that contrasts that vary slowly are not over-trusted."""
    if resid_fn is None or lags < 1:
        return 1.0
    r = resid_fn(fit)
    r = r - r.mean()
    d = float(r @ r)
    if d <= 0 or len(r) < 4 * lags:
        return 1.0
    k = np.arange(1, lags + 1)
    rho = np.array([r[j:] @ r[:-j] / d for j in k])
    return float(max(1.0, 1.0 + 2.0 * np.sum((1.0 - k / (lags + 1.0)) * rho)))


def _greedy(candidates: dict, fits: dict, fit_fn, n_obs: int, alpha: float, tests: list,
            resid_fn=None, lags: int = 0, robust_fn=None):
    """Forward selection.  ``candidates``: cause -> list of spec items (variants;
    a cause's p-value is its best variant's times the number of variants)."""
    cur = frozenset()
    accepted = []
    remaining = dict(candidates)
    rnd = 0
    while remaining:
        rnd += 1
        best = None
        for cause, variants in remaining.items():
            cbest = None
            for item in variants:
                spec = cur | {item}
                if spec not in fits:
                    fits[spec] = fit_fn(spec, fits[cur])
                f0, f1 = fits[cur], fits[spec]
                q = f1.p - f0.p
                dof = n_obs - f1.p
                if dof < MIN_DOF or not getattr(f1, "ok", True):
                    continue
                rob = robust_fn(f1, cause) if robust_fn is not None else None
                if rob is not None:
                    Fv, p = rob
                else:
                    Fv, p = F.f_test(f0.rss, f1.rss, q, dof)
                    kap = inflation(f1, resid_fn, lags)
                    if kap > 1.0:
                        from scipy import stats as _st
                        Fv = Fv / kap
                        p = float(_st.f.sf(Fv, q, max(1, int(dof / kap))))
                rec = TestRecord(rnd, cause, q, Fv, min(1.0, p * len(variants)), dof,
                                 F.delta_bic(f0.rss, f1.rss, q, n_obs), f0.rss, f1.rss)
                rec.item = item
                # among a cause's variants (basis sizes) the significant one with
                # the lowest BIC: the size is resolution, not another finding (a
                # random walk finer than the chosen basis is measured afterwards,
                # see random_walk)
                rec.aic = float(n_obs * np.log(max(f1.rss, 1e-300) / max(f0.rss, 1e-300))
                                + q * np.log(n_obs))
                if cbest is None:
                    cbest = rec
                else:
                    sig_new, sig_old = rec.p < alpha, cbest.p < alpha
                    if (sig_new and not sig_old) or (sig_new == sig_old and (
                            (sig_new and rec.aic < cbest.aic)
                            or (not sig_new and rec.p < cbest.p))):
                        cbest = rec
            if cbest is None:
                continue
            tests.append(cbest)
            if best is None or (cbest.p, -cbest.F) < (best.p, -best.F):
                best = cbest
        if best is None or not (best.p < alpha):
            break
        cur = cur | {best.item}
        accepted.append(best.item)
        del remaining[best.cause]
    return cur, accepted


def residual_variance(fit: F.MagnitudeFit, X, T, var_counts) -> np.ndarray:
    """Variance of each magnitude residual (sensor unit^2) from the variance
    of the raw point per axis (counts^2)."""
    A, c, H = fit.affine()
    v = fit.calibrate(X, T)
    nv = S.unit(v)
    g = (nv @ A) / fit.K                         # d|v| / d raw counts
    return np.sum(g * g * var_counts, axis=1)


def pose_vectors(acc: SensorObs, acc_fit, mag: SensorObs, mag_fit, groups=None,
                 min_accel: int = 5):
    """Calibrated gravity and field of the magnetometer's still segments
    (indices ``groups``, default all) that the accelerometer sampled at least
    ``min_accel`` times within (its first to last row's time): the mean
    accelerometer reading there and the segment's mean field, each calibrated
    at its time.  Returns (g (n, 3), b (n, 3), accelerometer samples (n,),
    segment index (n,))."""
    groups = range(len(mag.segs.rows)) if groups is None else groups
    g, b, n_acc, idx = [], [], [], []
    for gi in groups:
        rows = mag.segs.rows[gi]
        sel = (acc.t >= mag.t[rows[0]]) & (acc.t <= mag.t[rows[-1]])
        if sel.sum() < min_accel:
            continue
        g.append(acc_fit.calibrate(acc.x[sel].mean(axis=0)[None],
                                   np.array([acc.t[sel].mean()]))[0])
        b.append(mag_fit.calibrate(mag.segs.mean[gi][None], np.array([mag.segs.t[gi]]))[0])
        n_acc.append(int(sel.sum()))
        idx.append(int(gi))
    return (np.array(g).reshape(-1, 3), np.array(b).reshape(-1, 3), np.array(n_acc, int),
            np.array(idx, int))


def magnitude_points(obs: SensorObs, regime: str, drop_rows: np.ndarray | None = None):
    """Points of the poses or sweep regime: X counts, T, raw variance per axis,
    fold and group (pose) ids."""
    if regime == "poses":
        segs = obs.segs
        keep = np.ones(len(segs), bool)
        if segs.n_bad is not None:
            keep &= segs.n_bad <= 0.01 * segs.n          # overflow codes inside the pose
        if drop_rows is not None:
            for i, g in enumerate(segs.rows):
                if drop_rows[g].mean() > 0.01:
                    keep[i] = False
        idx = np.flatnonzero(keep)
        X = segs.mean[idx]
        T = segs.t[idx]
        var = obs.var_of_mean(segs.n[idx])
        fold = np.arange(len(idx)) % KFOLD
        pose = np.array([int(obs.label[segs.rows[i][0]]) if len(segs.rows[i]) else 0
                         for i in idx], np.int64)
        return {"X": X, "T": T, "var": var, "fold": fold, "group": idx, "pose": pose,
                "n": segs.n[idx], "dropped": int((~keep).sum())}
    # sweep: every (non-overflow, non-clipped) reading, thinned
    ok = ~obs.overflow
    if drop_rows is not None:
        ok &= ~drop_rows
    idx = np.flatnonzero(ok)
    step = max(1, int(np.ceil(len(idx) / MAX_SWEEP_POINTS)))
    idx = idx[::step]
    X = obs.x[idx]
    T = obs.t[idx]
    var = np.tile(obs.sigma ** 2, (len(idx), 1))
    chunk = np.floor((T - T[0]) / SWEEP_CHUNK_S).astype(int)
    # interleaved readings: a held-out reading lies between fitted ones, so a
    # field that moves with time is checked at its own resolution
    fold = np.arange(len(idx)) % KFOLD
    return {"X": X, "T": T, "var": var, "fold": fold, "group": chunk, "n": np.ones(len(idx)),
            "dropped": int((~ok).sum()), "step": step}


def field_basis_size(duration: float) -> int:
    return int(np.clip(round(duration / 5.0), 4, 40))


def field_sizes(duration: float, n_points: int) -> list[int]:
    """Field-magnitude time bases tried on a sweep: one function per ~5 s and
    one per 2.5 s (a wander with faster components), as the points allow.
    Finer bases would follow the turning itself (a sweep's directions are a
    function of time) and trade off against the direction terms."""
    out = [field_basis_size(duration)]
    fine = int(min(round(duration / 2.5), 100, n_points // 20))
    if fine > 2 * out[0]:
        out.append(fine)
    return out


def analyse_magnitude(obs: SensorObs, regime: str, candidates: list[str], alpha: float,
                      drop_rows=None) -> Structure | None:
    pts = magnitude_points(obs, regime, drop_rows)
    X, T = pts["X"], pts["T"]
    k = len(X)
    if k < 8:
        return None
    trange = (float(T.min()), float(T.max()))
    Jf = field_basis_size(trange[1] - trange[0])
    unit = "g" if obs.sensor == "accel" else "gauss"
    # starting model: calib's LM fit, then weights from its noise propagation
    fit0 = _spec_fit(obs.sensor, obs.K, X, T, np.ones(k), frozenset(), trange, Jf)
    V = residual_variance(fit0, X, T, pts["var"])
    W = 1.0 / np.sqrt(V)
    fit0 = _spec_fit(obs.sensor, obs.K, X, T, W, frozenset(), trange, Jf, start=fit0)
    fits = {frozenset(): fit0}
    cand = {}
    for c in candidates:
        if c == "bias_drift":
            sizes = drift_sizes(trange[1] - trange[0], (k - fit0.p) // 6)
            cand[c] = [f"bias_drift:{j}" for j in sizes]
        elif c == "field_disturbance":
            cand[c] = [f"field_disturbance:{j}" for j in field_sizes(trange[1] - trange[0], k)]
        else:
            cand[c] = [c]
    tests = []
    # sweeps: consecutive readings share slow leftovers; the F-test is deflated
    # sweeps: consecutive readings share leftovers (a field that moves faster
    # than any basis follows): terms with few parameters get a cluster-robust
    # Wald test (clusters of NW_LAG_S), the others an F-test deflated by the
    # residuals' long-run variance ratio
    resid_fn = robust_fn = None
    lags = 0
    if regime == "sweep" and k > 1:
        resid_fn = (lambda f: W * f.residuals(X, T))
        lags = int(round(NW_LAG_S / max(np.median(np.diff(T)), 1e-6)))
        def robust_fn(f, cause):
            # clusters of NW_LAG_S, shorter when the sweep is too short for
            # ten clusters per tested parameter
            idx = f.new_param_index(cause)
            span = max(T[-1] - T[0], 1e-9)
            length = min(NW_LAG_S, span / (10.0 * max(len(idx), 1)))
            clusters = np.floor((T - T[0]) / length).astype(int)
            return F.robust_wald(f, X, T, W, idx, clusters)
    cur, accepted = _greedy(cand, fits, lambda spec, start: _spec_fit(
        obs.sensor, obs.K, X, T, W, spec, trange, Jf, start=start), k, alpha, tests,
        resid_fn, lags, robust_fn)
    final = fits[cur]
    st = Structure(obs.sensor, regime, unit, accepted, tests, fit0, final, fits,
                   dict(pts, W=W, V=V, trange=trange, Jf=Jf))
    if regime == "sweep":
        # a sweep's noise level is not known well enough for a chi-square: test
        # whether the leftover is white instead (structure shows as correlation)
        rho, z = lag1(W * final.residuals(X, T), T)
        from scipy import stats as _st
        st.excess = (1.0 / max(1.0 - rho, 1e-6), float(_st.norm.sf(z)))
    else:
        st.excess = F.chi2_excess(final.rss, k - final.p)
    st.noise_floor = float(np.sqrt(np.mean(V)))
    _heldout_magnitude(st, obs)
    return st


def _heldout_magnitude(st: Structure, obs: SensorObs):
    pts = st.points
    X, T, W, fold = pts["X"], pts["T"], pts["W"], pts["fold"]
    full = frozenset(st.accepted)
    specs = {frozenset(): None, full: None}
    for c in st.accepted:
        specs[full - {c}] = None
    out, folds = {}, {}
    for spec in specs:
        r = np.full(len(X), np.nan)
        start = st.fits.get(spec)
        if start is None:
            start = _spec_fit(st.sensor, obs.K, X, T, W, spec, pts["trange"], pts["Jf"],
                              start=st.fit)
            st.fits[spec] = start
        for f in np.unique(fold):
            te = fold == f
            tr = ~te
            if tr.sum() - start.p < 1:
                continue
            fk = _spec_fit(st.sensor, obs.K, X[tr], T[tr], W[tr], spec, pts["trange"],
                           pts["Jf"], start=start, max_nfev=HELDOUT_NFEV)
            r[te] = fk.residuals(X[te], T[te])
        out[spec] = float(np.sqrt(np.nanmean(r * r)))
        folds[spec] = np.array([np.nanmean(r[fold == f] ** 2) for f in np.unique(fold)])
    for c in st.accepted:
        st.heldout[cause_of(c)] = (out[full - {c}], out[full])
        st.fold_wins[cause_of(c)] = int(np.sum(folds[full] < folds[full - {c}]))
    st.heldout_total = (out[frozenset()], out[full])


# ---------------------------------------------------------------------------
# linear: gyroscope and one-orientation data
# ---------------------------------------------------------------------------
def _design(pts, spec, trange):
    causes = _causes(spec)
    cols, names, groups = [], [], {}
    for j, p in enumerate(pts["const_groups"]):
        cols.append((pts["cgroup"] == p).astype(float))
        names.append(f"const{j}")
    groups["const"] = list(range(len(cols)))
    if "g_sensitivity" in causes:
        i0 = len(cols)
        for j in range(3):
            cols.append(pts["F"][:, j])
            names.append("gsens_" + "xyz"[j])
        groups["g_sensitivity"] = list(range(i0, len(cols)))
    if "bias_drift" in causes:
        i0 = len(cols)
        B = F.time_basis(pts["T"], *trange, _size(spec, "bias_drift", F.DRIFT_J))
        for j in range(B.shape[1]):
            cols.append(B[:, j])
            names.append(f"drift{j}")
        groups["bias_drift"] = list(range(i0, len(cols)))
    return np.column_stack(cols), names, groups


def linear_points(obs: SensorObs, accel_g: np.ndarray | None, per_orientation: bool):
    """Block means with their weights; ``accel_g`` (blocks, 3) the specific
    force in g during each block (gyroscope), or None."""
    b = obs.blocks
    Y = b.mean
    W = 1.0 / np.sqrt(obs.var_of_mean(b.n) if b.var is None else b.var)
    T = b.t
    if per_orientation:
        cgroup = b.seg                                   # one constant per orientation
    else:
        cgroup = obs.part[[g[0] for g in b.rows]]        # one bias per recording
    return {"Y": Y, "W": W, "T": T, "F": accel_g, "cgroup": np.asarray(cgroup),
            "const_groups": list(np.unique(cgroup)), "fold": np.arange(len(Y)) % KFOLD,
            "seg": b.seg, "n": b.n}


def analyse_linear(obs: SensorObs, candidates: list[str], alpha: float,
                   accel_g: np.ndarray | None = None, per_orientation: bool = False,
                   drop_blocks: np.ndarray | None = None) -> Structure | None:
    if obs.blocks is None:
        return None
    pts = linear_points(obs, accel_g, per_orientation)
    if drop_blocks is not None and drop_blocks.any():
        keep = ~drop_blocks
        pts = {k: (v[keep] if isinstance(v, np.ndarray) and len(v) == len(keep) else v)
               for k, v in pts.items()}
        pts["const_groups"] = list(np.unique(pts["cgroup"]))
    k = len(pts["Y"])
    if k < 4:
        return None
    trange = (float(pts["T"].min()), float(pts["T"].max()))
    if pts["F"] is None:
        candidates = [c for c in candidates if c != "g_sensitivity"]
    else:
        # g-sensitivity needs orientations that span the sphere
        Fu = S.unit(pts["F"])
        if np.linalg.matrix_rank(Fu - Fu.mean(axis=0), tol=0.2) < 3:
            candidates = [c for c in candidates if c != "g_sensitivity"]

    def fit(spec):
        X, names, groups = _design(pts, spec, trange)
        return F.fit_linear(X, pts["Y"], pts["W"], names, groups)

    fits = {frozenset(): fit(frozenset())}
    cand = {}
    for c in candidates:
        if c == "bias_drift":
            sizes = drift_sizes(trange[1] - trange[0], (k - fits[frozenset()].p // 3) // 6, 1)
            cand[c] = [f"bias_drift:{j}" for j in sizes]
        else:
            cand[c] = [c]
    tests = []
    cur, accepted = _greedy(cand, fits, lambda spec, start: fit(spec), 3 * k, alpha, tests)
    final = fits[cur]
    unit = {"accel": "g", "gyro": "deg/s", "mag": "gauss"}[obs.sensor]
    st = Structure(obs.sensor, "single" if per_orientation else "still", unit, accepted, tests,
                   fits[frozenset()], final, fits, dict(pts, trange=trange))
    st.excess = F.chi2_excess(final.rss, 3 * k - final.p)
    st.noise_floor = float(np.sqrt(np.mean(1.0 / pts["W"] ** 2))) / obs.K
    _heldout_linear(st, obs, fit_fn=lambda spec, keep: _fit_subset(pts, spec, trange, keep))
    return st


def _fit_subset(pts, spec, trange, keep):
    X, names, groups = _design(pts, spec, trange)
    return F.fit_linear(X[keep], pts["Y"][keep], pts["W"][keep], names, groups), X


def _nanmean(x) -> float:
    """Mean of the finite values; NaN (quietly) when there are none (a fold
    whose blocks all lie in orientations with no training block)."""
    x = np.asarray(x, float)
    ok = np.isfinite(x)
    return float(x[ok].mean()) if ok.any() else float("nan")


def paired_heldout_p(without: np.ndarray, with_: np.ndarray) -> float | None:
    """One-sided p of a paired t-test that the held-out points are
    predicted better with a term than without (per point, the squared
    weighted residual without less with it), or None with too few points.
    Unlike the count of folds won, its power grows with the number of
    points: 24-33 hand-held poses make 5 folds of 5-7 points each, where a
    real term loses a fold by chance."""
    from scipy import stats
    d = np.asarray(without, float) - np.asarray(with_, float)
    d = d[np.isfinite(d)]
    if len(d) < PAIRED_MIN_POINTS or not np.std(d) > 0:
        return None
    return float(stats.ttest_1samp(d, 0.0, alternative="greater").pvalue)


def _heldout_linear(st: Structure, obs: SensorObs, fit_fn):
    pts = st.points
    fold = pts["fold"]
    full = frozenset(st.accepted)
    specs = [frozenset(), full] + [full - {c} for c in st.accepted]
    out, folds, point = {}, {}, {}
    for spec in specs:
        r = np.full(pts["Y"].shape, np.nan)
        for f in np.unique(fold):
            te = fold == f
            fk, X = fit_fn(spec, ~te)
            # a held-out block whose constant group has no training block is skipped
            usable = te.copy()
            for j, g in enumerate(pts["const_groups"]):
                if not np.any((pts["cgroup"] == g) & ~te):
                    usable &= pts["cgroup"] != g
            r[usable] = pts["Y"][usable] - X[usable] @ fk.beta
        if obs.blocks is not None and obs.blocks.var is not None:
            # blocks known to different precision (the gyro's, the board's turn
            # taken out): each residual weighted by it, in counts on average
            W = pts["W"]
            r = r * W / np.sqrt(np.mean(W * W, axis=0))
        out[spec] = float(np.sqrt(_nanmean(r * r))) / obs.K
        folds[spec] = np.array([_nanmean(r[fold == f] ** 2) for f in np.unique(fold)])
        point[spec] = np.sum(r * r, axis=1)
    for c in st.accepted:
        st.heldout[cause_of(c)] = (out[full - {c}], out[full])
        st.fold_wins[cause_of(c)] = int(np.sum(folds[full] < folds[full - {c}]))
        if obs.blocks is not None and obs.blocks.var is not None:
            st.heldout_p[cause_of(c)] = paired_heldout_p(point[full - {c}], point[full])
    st.heldout_total = (out[frozenset()], out[full])
    st.fold_ms = folds


# ---------------------------------------------------------------------------
# saturation in static poses: censored residuals
# ---------------------------------------------------------------------------
def censored_residuals(fit: F.MagnitudeFit, X, T, clip: list) -> np.ndarray:
    """Residuals where ``clip[k]`` = (axis, side, limit) marks a pose whose axis
    read its limit: the true reading is anywhere beyond the limit, so the
    residual is 0 when some value beyond it gives the right magnitude, else
    the smallest |residual| beyond it."""
    r = fit.residuals(X, T)
    for k, c in enumerate(clip):
        if c is None:
            continue
        a, side, L = c
        grid = L + side * np.linspace(0.0, 0.6 * fit.K, 121)
        Xk = np.repeat(X[k][None], len(grid), axis=0)
        Xk[:, a] = grid
        rk = fit.residuals(Xk, np.full(len(grid), T[k]))
        r[k] = 0.0 if rk.min() <= 0.0 <= rk.max() else rk[np.argmin(np.abs(rk))]
    return r


FULLY_CLIPPED = 0.97      # a pose clipped in this share of its readings is censored


def saturation_gain(st: Structure, obs: SensorObs, clip_rows: np.ndarray, limits: list):
    """Held-out gain of the saturation term on the pose means: without it,
    clipped poses are fitted and predicted as ordinary readings; with it they
    are left out of the fit and predicted as censored.  Returns (gain, rms
    before, rms after) or None."""
    if st is None or st.regime != "poses" or obs.segs is None:
        return None
    pts = magnitude_points(obs, "poses", None)
    X, T, fold = pts["X"], pts["T"], pts["fold"]
    clip = []
    for gi in pts["group"]:
        rows = obs.segs.rows[gi]
        frac = clip_rows[rows].mean()
        c = None
        if frac > 0.01:
            best = None
            for h in limits:
                a = "xyz".index(h["axis"])
                n = int(np.sum(obs.x[rows, a] == h["limit_counts"]))
                if n and (best is None or n > best[0]):
                    best = (n, (a, 1 if h["side"] == "high" else -1, h["limit_counts"]))
            c = best[1] if best else None
        clip.append(c)
    isclip = np.array([c is not None for c in clip])
    if not isclip.any():
        return None
    # a pose only partly clipped (noise around the limit) has a known true
    # mean: with white noise sigma, the clipped share f = P(beyond L) gives
    # mu = L - side sigma Phi^-1(1 - f) (a Tobit estimate); only poses
    # clipped (nearly) throughout are censored
    from scipy.stats import norm
    Xa = X.copy()
    for k, c in enumerate(clip):
        if c is None:
            continue
        a, side, L = c
        rows = obs.segs.rows[pts["group"][k]]
        f = float(np.mean(obs.x[rows, a] == L))
        if 0.0 < f < FULLY_CLIPPED:
            Xa[k, a] = L - side * obs.sigma[a] * norm.ppf(1.0 - f)
            clip[k] = None
    isclip = np.array([c is not None for c in clip])
    spec = frozenset(st.accepted)
    V = residual_variance(st.fit, X, T, pts["var"])
    W = 1.0 / np.sqrt(V)
    trange, Jf = st.points["trange"], st.points["Jf"]
    rb = np.full(len(X), np.nan)
    ra = np.full(len(X), np.nan)
    for f in np.unique(fold):
        te = fold == f
        tr = ~te
        fb = _spec_fit(st.sensor, obs.K, X[tr], T[tr], W[tr], spec, trange, Jf, start=st.fit)
        rb[te] = fb.residuals(X[te], T[te])
        tra = tr & ~isclip
        fa = _spec_fit(st.sensor, obs.K, Xa[tra], T[tra], W[tra], spec, trange, Jf,
                       start=st.fit)
        ra[te] = censored_residuals(fa, Xa[te], T[te], [c for c, m in zip(clip, te) if m])
    b = float(np.sqrt(np.nanmean(rb ** 2)))
    a = float(np.sqrt(np.nanmean(ra ** 2)))
    return (b / a if a > 0 else float("inf")), b, a


# ---------------------------------------------------------------------------
# random walk on top of a smooth drift (linear models)
# ---------------------------------------------------------------------------
def random_walk(st: Structure, obs: SensorObs) -> dict | None:
    """Per axis, the random-walk intensity left on top of the fitted design:
    block means y = X beta + w(t) + e, w a Brownian motion (variance s^2 t), e
    the known noise of each mean; s^2 by restricted maximum likelihood.
    Returns the whitened chi-square of the residuals under that model and
    sigma (counts/sqrt(s)) per axis."""
    pts = st.points
    Xd, _, _ = _design(pts, frozenset(st.accepted), pts["trange"])
    T = pts["T"] - pts["T"].min()
    B = np.minimum(T[:, None], T[None, :])
    k, p = Xd.shape
    if k - p < MIN_DOF:
        return None
    from scipy.optimize import minimize_scalar
    sig = np.zeros(3)
    chi2 = 0.0
    lr = 0.0
    for a in range(3):
        y = pts["Y"][:, a]
        D = np.diag(1.0 / pts["W"][:, a] ** 2)

        def nll(ls, y=y, D=D):
            S = D + np.exp(ls) * B
            try:
                L = np.linalg.cholesky(S)
            except np.linalg.LinAlgError:
                return 1e30
            Xw = np.linalg.solve(L, Xd)
            yw = np.linalg.solve(L, y)
            XtX = Xw.T @ Xw
            beta = np.linalg.lstsq(Xw, yw, rcond=None)[0]
            r = yw - Xw @ beta
            sign, ld = np.linalg.slogdet(XtX)
            return float(np.sum(np.log(np.diag(L))) + 0.5 * ld + 0.5 * r @ r)

        base = float(np.median(1.0 / pts["W"][:, a] ** 2)) / max(T.max(), 1e-9)
        lo, hi = np.log(base * 1e-6), np.log(base * 1e4)
        res = minimize_scalar(nll, bounds=(lo, hi), method="bounded")
        s2 = float(np.exp(res.x))
        nll0 = nll(lo)
        if nll0 <= res.fun + 1e-9:
            s2 = 0.0
        lr += 2.0 * max(0.0, nll0 - float(res.fun))
        S = D + s2 * B
        L = np.linalg.cholesky(S)
        Xw = np.linalg.solve(L, Xd)
        yw = np.linalg.solve(L, y)
        beta = np.linalg.lstsq(Xw, yw, rcond=None)[0]
        r = yw - Xw @ beta
        chi2 += float(r @ r)
        sig[a] = np.sqrt(s2)
    dof = 3 * (k - p) - 3
    return {"sigma_counts_per_sqrt_s": sig, "chi2": chi2, "dof": dof,
            "excess": F.chi2_excess(chi2, dof), "lr": lr, "lr_p": variance_lr_p(lr, 3)}


def variance_lr_p(lr: float, m: int) -> float:
    """p-value of a restricted likelihood-ratio statistic summed over ``m``
    independent variance components tested at the boundary (each 50:50
    chi-square 0 / 1 under the null: the sum is a binomial mixture)."""
    from math import comb

    from scipy import stats as _st
    if lr <= 0:
        return 1.0
    return float(sum(comb(m, j) / 2.0 ** m * _st.chi2.sf(lr, j) for j in range(1, m + 1)))


def heldout_random_walk(st: Structure, obs: SensorObs, sigma) -> tuple | None:
    """Held-out rms (sensor unit) of the final linear model *with* a random
    walk of intensity ``sigma`` (counts/sqrt(s) per axis) on top: per fold,
    the design's coefficients by generalised least squares on the other
    blocks (covariance D + s^2 min(t, t')), and each held-out block predicted
    by the design plus the walk's conditional mean given the other blocks
    (kriging; the best prediction a random-walk model can make).  Returns
    (rms, per-fold mean squares) or None."""
    pts = st.points
    Xd, _, _ = _design(pts, frozenset(st.accepted), pts["trange"])
    T = pts["T"] - pts["T"].min()
    B = np.minimum(T[:, None], T[None, :])
    fold = pts["fold"]
    sigma = np.broadcast_to(np.asarray(sigma, float), (3,))
    r = np.full(pts["Y"].shape, np.nan)
    for f in np.unique(fold):
        te = fold == f
        tr = ~te
        usable = te.copy()
        for g in pts["const_groups"]:
            if not np.any((pts["cgroup"] == g) & tr):
                usable &= pts["cgroup"] != g
        cols = np.any(Xd[tr] != 0, axis=0)
        for a in range(3):
            y = pts["Y"][:, a]
            D = 1.0 / pts["W"][:, a] ** 2
            S = np.diag(D[tr]) + sigma[a] ** 2 * B[np.ix_(tr, tr)]
            try:
                L = np.linalg.cholesky(S)
            except np.linalg.LinAlgError:
                return None
            Xw = np.linalg.solve(L, Xd[tr][:, cols])
            yw = np.linalg.solve(L, y[tr])
            beta = np.linalg.lstsq(Xw, yw, rcond=None)[0]
            e = y[tr] - Xd[tr][:, cols] @ beta
            w = np.linalg.solve(L.T, np.linalg.solve(L, e))
            pred = Xd[usable][:, cols] @ beta + sigma[a] ** 2 * B[np.ix_(usable, tr)] @ w
            r[usable, a] = y[usable] - pred
    if not np.isfinite(r).any():
        return None
    ms = np.array([np.nanmean(r[fold == f] ** 2) for f in np.unique(fold)])
    return float(np.sqrt(np.nanmean(r * r))) / obs.K, ms
