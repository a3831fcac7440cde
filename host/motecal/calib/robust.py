"""The robust objective of every magnitude fit (issue 25): readings that
disagree with the calibration far beyond the others' scatter are set aside,
never allowed to pull it.

Real sweeps and poses carry glitches (an I2C read that raced the
conversion) and disturbed stretches (a desk leg, a phone).  Least squares
gives each of them a pull that grows with its error; the calibration then
leaves a residual the gate refuses although most readings agree.  The fit
here is two steps, as an MM-estimator is:

1. **A high-breakdown start.**  The objective is a robust scale of the
   relative magnitude residuals ``r / H`` -- the M-scale ``s`` with
   ``mean rho(r / (H s)) = 1/2`` for Tukey's biweight ``rho`` (c = 1.547):
   an S-estimate, the fit the most readings agree with; up to half of them
   may be anything.  It has many local minima and kinks (a reading crossing
   ``c s`` changes its weight from some to none), which is where a
   population search belongs: the GA (``ga.py``) minimises it over the prior
   box on the fit's reduction (pose means, or a strided sweep).  The local
   route below is run too, and of the two the fit with the lower robust
   scale on every reading is kept.
2. **An efficient finish** (``concentrate``): readings whose residual is
   more than ``REJECT_SD`` robust standard deviations (1.4826 MAD) from the
   median are set aside and the rest fitted by least squares (the LM polish,
   ``fit.polish``), again from that fit, until the readings set aside no
   longer change.  On clean data 3.5 sd sets aside about 1 reading in 2000
   and keeps the precision of least squares (a location estimate so trimmed
   keeps 99.3 % of its efficiency); a glitch 5 % of the field off is 10-25
   sd out on a sweep and is never kept.

The local route (``local_fit``): least squares from the nominal point, three
rounds of Cauchy-weighted least squares (a smooth redescending M-estimate,
its scale re-estimated from the MAD each round; it finds the basin the
majority lies in when least squares was dragged out of it), then
``concentrate``.  The choice and its measurements: docs/calibrate.md,
bench/bench_robust.py.

Pure functions on numpy arrays; ``u`` in the model's nominal units.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import ga as _ga
from .fit import FitResult, escaped, finish, nominal_start, polish, reduce_samples
from .models import MagnitudeModel

REJECT_SD = 4.0            # set aside beyond this many robust sd from the median residual
MAD_SD = 1.4826            # MAD -> standard deviation for normal noise
BIWEIGHT_C = 1.547         # Tukey biweight, 50 % breakdown M-scale (b = rho(inf) / 2)
BIWEIGHT_B = 0.5
SCALE_ITER = 12            # fixed-point iterations of the M-scale (start: the MAD)
CAUCHY_ROUNDS = 3
MAX_CONCENTRATE = 12
REFINE_STEPS = 4           # concentration steps the GA's local refinement takes
REFINE_K = 8               # ... on this many of its best individuals, every 5 generations


def robust_sd(r) -> float:
    """1.4826 x the median absolute deviation from the median (the standard
    deviation for normal noise, unmoved by a minority of wild values)."""
    r = np.asarray(r, float)
    if not len(r):
        return 0.0
    return float(MAD_SD * np.median(np.abs(r - np.median(r))))


def deviations(r, groups=None) -> np.ndarray:
    """What a reading is judged on: its residual from the median residual,
    or, for readings in groups (static poses), from its own group's median
    -- a pose whose magnitude the model misses by more than the noise is
    not a pose of bad readings (on six Razor poses the pose-level misfit is
    several times the within-pose noise: judged against the noise, whole
    poses went), while a bump within a pose stands out of that pose."""
    r = np.asarray(r, float)
    if groups is None:
        return r - np.median(r)
    _, inv, cnt = np.unique(np.asarray(groups), return_inverse=True, return_counts=True)
    order = np.lexsort((r, inv))                      # by group, then by residual
    start = np.r_[0, np.cumsum(cnt)[:-1]]
    rs = r[order]
    med = 0.5 * (rs[start + (cnt - 1) // 2] + rs[start + cnt // 2])
    return r - med[inv]


def inliers(r, c: float = REJECT_SD, groups=None) -> np.ndarray:
    """Readings within ``c`` robust sd of the median residual (of their
    group's, see ``deviations``); all when the scale is 0 (identical
    residuals)."""
    e = deviations(r, groups)
    s = _scale_of_deviations(e)
    if not s > 0:
        return np.ones(len(e), bool)
    return np.abs(e) <= c * s


def _scale_of_deviations(e) -> float:
    """1.4826 x the median |e|; when more than half the deviations are 0
    (whole counts of a quiet sensor: the median is every other reading),
    1.2533 x the mean |e| instead (the sd for normal noise, from the mean
    absolute deviation)."""
    a = np.abs(np.asarray(e, float))
    if not len(a):
        return 0.0
    s = float(MAD_SD * np.median(a))
    return s if s > 0 else float(1.2533 * np.mean(a))


def capped_sq(r, scale: float, c: float = REJECT_SD) -> np.ndarray:
    """Squared residuals capped at ``(c scale)^2``: the bounded per-reading
    error the held-out checks sum (a reading set aside counts as the cap, so
    two calibrations compared on the same readings are compared on the same
    count, and a glitch weighs no more than a reading at the threshold)."""
    r = np.asarray(r, float)
    cap = (c * scale) ** 2 if scale > 0 else np.inf
    return np.minimum(r * r, cap)


# ---------------------------------------------------------------------------
# the high-breakdown objective: an M-scale of the relative residuals
# ---------------------------------------------------------------------------
def _biweight_rho(z):
    z2 = np.minimum((z / BIWEIGHT_C) ** 2, 1.0)
    return 1.0 - (1.0 - z2) ** 3


def m_scale(r, w=None, iters: int = SCALE_ITER) -> np.ndarray:
    """The biweight M-scale of each row of ``r`` (..., m): ``s`` with
    ``mean_w rho(r / s) = 1/2``, by fixed-point iteration from the MAD."""
    r = np.atleast_2d(np.asarray(r, float))
    s = MAD_SD * np.median(np.abs(r), axis=-1) + 1e-300
    wn = None if w is None else np.asarray(w, float) / np.sum(w)
    for _ in range(iters):
        rho = _biweight_rho(r / s[..., None])
        m = rho.mean(axis=-1) if wn is None else rho @ wn
        s = s * np.sqrt(m / BIWEIGHT_B)
        s = np.maximum(s, 1e-300)
    return s


def population_rel_residuals(model: MagnitudeModel, pop, u) -> np.ndarray:
    """(|A u + c| - H) / H for each row of ``pop`` (P, d) on points u (m, 3): (P, m)."""
    A, c, H = model.affine(np.atleast_2d(pop))
    P = len(A)
    v = (A.reshape(P * 3, 3) @ np.asarray(u, float).T).reshape(P, 3, -1) + c[:, :, None]
    H = np.asarray(H, float).reshape(P, 1)
    return (np.sqrt(np.einsum("pim,pim->pm", v, v)) - H) / H


def population_scale(model: MagnitudeModel, pop, u, w=None) -> np.ndarray:
    """The GA's fitness: the robust scale of the relative residuals, per
    individual (lower is better)."""
    r = population_rel_residuals(model, pop, u)
    s = m_scale(r, w)
    return np.where(np.isfinite(s), s, np.inf)


def scale_of(model: MagnitudeModel, theta, u, iters: int = 3 * SCALE_ITER) -> float:
    """The same robust scale for one parameter vector on every reading."""
    return float(m_scale(population_rel_residuals(model, theta, u), iters=iters)[0])


# ---------------------------------------------------------------------------
# local steps
# ---------------------------------------------------------------------------
@dataclass
class Concentrated:
    theta: np.ndarray
    keep: np.ndarray            # readings used (False: set aside)
    scale: float                # robust sd of the residuals at theta (model's unit)
    nfev: int
    steps: int


def concentrate(model: MagnitudeModel, theta, u, c: float = REJECT_SD,
                max_steps: int = MAX_CONCENTRATE, groups=None,
                known: "Concentrated | None" = None) -> Concentrated:
    """Least squares on the readings within ``c`` robust sd of the median
    residual (of their pose's, ``groups``), repeated from each fit until the
    readings set aside no longer change (or ``max_steps``); the set aside is
    judged at the final theta.  ``known``: a fixed point already found; a
    step that selects its readings ends there (the same least squares)."""
    u = np.asarray(u, float)
    theta = np.asarray(theta, float)
    need = max(model.d + 1, 10)
    keep, nfev, steps = None, 0, 0
    for steps in range(1, max_steps + 1):
        k = inliers(model.residuals(theta, u), c, groups)
        if known is not None and np.array_equal(k, known.keep):
            return Concentrated(known.theta, known.keep, known.scale, nfev, steps)
        if keep is not None and np.array_equal(k, keep):
            break
        if k.sum() < need:
            break
        keep = k
        theta, n = polish(model, theta, u[keep])
        nfev += n
    r = model.residuals(theta, u)
    keep = inliers(r, c, groups)
    return Concentrated(theta, keep, _scale_of_deviations(deviations(r, groups)), nfev, steps)


def cauchy_rounds(model: MagnitudeModel, theta, u, rounds: int = CAUCHY_ROUNDS):
    """Cauchy-weighted least squares (weights 1 / (1 + (r / s)^2), s the
    robust sd of the residuals, re-estimated each round), each round the LM
    polish with the weights fixed.  Returns (theta, nfev)."""
    u = np.asarray(u, float)
    theta = np.asarray(theta, float)
    nfev = 0
    for _ in range(rounds):
        r = model.residuals(theta, u)
        s = robust_sd(r)
        if not s > 0:
            break
        w = 1.0 / (1.0 + ((r - np.median(r)) / s) ** 2)
        theta, n = polish(model, theta, u, w=w)
        nfev += n
    return theta, nfev


def local_fit(model: MagnitudeModel, u, theta0=None, groups=None) -> Concentrated:
    """The local robust route: least squares from ``theta0`` (default the
    nominal point), Cauchy rounds (sweeps only: with poses, a reading is
    judged within its pose, and the poses' own misfit must not be
    down-weighted), then ``concentrate``."""
    u = np.asarray(u, float)
    th, n0 = polish(model, nominal_start(model, u) if theta0 is None else theta0, u)
    n1 = 0
    if groups is None:
        th, n1 = cauchy_rounds(model, th, u)
    out = concentrate(model, th, u, groups=groups)
    out.nfev += n0 + n1
    return out


# ---------------------------------------------------------------------------
# the project's method: the GA on the robust scale, then the finish
# ---------------------------------------------------------------------------
@dataclass
class RobustFit:
    """A robust fit: the statistics of the readings kept (``fit``: its
    ``mse``, standard deviations and identifiability are of those), which
    readings were set aside, and how it was found."""
    fit: FitResult
    keep: np.ndarray                 # per reading: used (False: set aside)
    scale: float                     # robust sd of the residuals, model's unit
    route: str                       # "ga" or "local": the candidate with the lower robust scale
    scales: dict                     # candidate -> robust scale of the relative residuals
    mse_all: float                   # mean squared residual over every reading

    @property
    def theta(self):
        return self.fit.theta

    @property
    def set_aside(self) -> int:
        return int((~self.keep).sum())


def _bounded(model, theta, u, lo, hi, groups=None):
    """The candidate kept within 3x the prior box (a sphere fit can run off
    towards a plane on a partial sweep): least squares on its kept readings,
    bounded."""
    from scipy.optimize import least_squares
    from .fit import LM_TOL
    c, h = 0.5 * (lo + hi), 0.5 * (hi - lo)
    k = inliers(model.residuals(theta, u), groups=groups)
    x0 = np.clip(theta, c - 3 * h, c + 3 * h)
    res = least_squares(model.residuals, x0, jac=model.jacobian, args=(u[k],), method="trf",
                        bounds=(c - 3 * h, c + 3 * h), xtol=LM_TOL, ftol=LM_TOL, gtol=1e-15)
    r = model.residuals(res.x, u)
    return Concentrated(res.x, inliers(r, groups=groups),
                        _scale_of_deviations(deviations(r, groups)), res.nfev, 1)


def ga_fit(model: MagnitudeModel, u, label=None, *, seed=None,
           options: _ga.GAOptions = _ga.GAOptions(), local: bool = True) -> RobustFit:
    """The GA over the prior box on the robust scale of the reduction
    (``fit.reduce_samples``), then ``concentrate`` from its best; and the
    local route (``local``).  Of the two fixed points the one with the lower
    robust scale on every reading is kept (so never worse, on the objective,
    than either alone; a tie goes to the GA's).  The GA starts from its own
    random population: seeded with the local result, that individual won
    every tournament and the stop rule ended the search at once."""
    u = np.asarray(u, float)
    groups = None if label is None or not np.any(np.asarray(label) >= 1) else label
    lo, hi = model.prior_box(u)
    cands = {}
    if local:
        cands["local"] = local_fit(model, u, groups=groups)
    red = reduce_samples(u, label)

    def refine(x):                         # a few concentration steps on the reduction
        th = concentrate(model, x, red.u, max_steps=REFINE_STEPS).theta
        return th if np.all(np.isfinite(th)) else x
    g = _ga.minimize(lambda P: population_scale(model, P, red.u, red.w), lo, hi, seed=seed,
                     options=options, refine=refine, refine_k=REFINE_K)
    cands["ga"] = concentrate(model, g.x, u, groups=groups, known=cands.get("local"))
    note = ""
    for k, cnd in list(cands.items()):
        if escaped(cnd.theta, lo, hi) or not np.all(np.isfinite(cnd.theta)):
            cands[k] = _bounded(model, cnd.theta if np.all(np.isfinite(cnd.theta)) else g.x,
                                u, lo, hi, groups)
            note = "a fit left the prior ranges; refitted within 3x the ranges"
    scales = {k: scale_of(model, cnd.theta, u) for k, cnd in cands.items()}
    route = min(scales, key=lambda k: (scales[k], k != "ga"))
    best = cands[route]
    fr = finish(model, best.theta, u[best.keep], trace=g.trace, ga_generations=g.generations,
                ga_evaluations=g.evaluations, ga_stop=g.stop, seed=seed,
                polish_nfev=sum(cnd.nfev for cnd in cands.values()))
    fr.note = note
    r = model.residuals(best.theta, u)
    return RobustFit(fr, best.keep, best.scale, route, scales, float(np.mean(r * r)))


def lm_fit(model: MagnitudeModel, u, label=None) -> RobustFit:
    """The local route alone (the reference the GA is compared with)."""
    u = np.asarray(u, float)
    groups = None if label is None or not np.any(np.asarray(label) >= 1) else label
    loc = local_fit(model, u, groups=groups)
    fr = finish(model, loc.theta, u[loc.keep], polish_nfev=loc.nfev)
    r = model.residuals(loc.theta, u)
    return RobustFit(fr, loc.keep, loc.scale, "local", {"local": scale_of(model, loc.theta, u)},
                     float(np.mean(r * r)))


# ---------------------------------------------------------------------------
# what was set aside, in the user's terms
# ---------------------------------------------------------------------------
STRETCH_GAP = 3             # readings set aside at most this many readings apart form one stretch
STRETCH_MIN = 5             # a stretch has at least this many readings; fewer are single readings
MAX_STRETCH_S = 5.0         # the gate's limit on one stretch set aside (bench_robust shows 0-3 s)


def runs(mask) -> list[tuple[int, int]]:
    """(first index, length) of each run of True in ``mask``."""
    m = np.asarray(mask, bool).astype(np.int8)
    d = np.diff(np.r_[0, m, 0])
    starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1)
    return [(int(a), int(b - a)) for a, b in zip(starts, ends)]


def set_aside_record(keep, t=None, rows=None, scale: float | None = None,
                     threshold_sd: float = REJECT_SD, rel=None) -> dict:
    """What a fit set aside, for ``cal.json`` and the summary: how many of
    how many, the threshold, the stretches (readings set aside at most
    ``STRETCH_GAP`` readings apart -- at most two kept between them, so
    glitches even at 20 % of the readings rarely chain --, at least
    ``STRETCH_MIN``: start and end in s, count, and -- given ``rel``, each
    reading's relative magnitude error -- their median relative error) and
    the single readings' count,
    the longest stretch (s), and the session rows set aside as runs
    ``[first row, count]`` (``rows``: the session row of each reading;
    default the reading's index)."""
    keep = np.asarray(keep, bool)
    n = len(keep)
    out_idx = np.flatnonzero(~keep)
    t = np.arange(n, dtype=float) if t is None else np.asarray(t, float)
    rows = np.arange(n) if rows is None else np.asarray(rows)
    stretches, singles = [], 0
    if len(out_idx):
        tt = t[out_idx]
        cut = np.flatnonzero(np.diff(out_idx) > STRETCH_GAP) + 1
        for grp in np.split(np.arange(len(out_idx)), cut):
            if len(grp) >= STRETCH_MIN:
                st = [float(tt[grp[0]]), float(tt[grp[-1]]), int(len(grp))]
                if rel is not None:
                    st.append(float(np.median(np.asarray(rel)[out_idx[grp]])))
                stretches.append(st)
            else:
                singles += len(grp)
    drop = np.zeros(int(rows.max()) + 1 if n else 0, bool)
    drop[rows[out_idx]] = True
    return {"count": int(len(out_idx)), "of": int(n),
            "fraction": float(len(out_idx) / n) if n else 0.0,
            "threshold_sd": float(threshold_sd),
            "robust_sd": None if scale is None else float(scale),
            "stretches_s": stretches, "single": int(singles),
            "longest_s": max((b - a for a, b, *_ in stretches), default=0.0),
            "rows": [[a, k] for a, k in runs(drop)]}


def set_aside_text(rec: dict, unit: str = "") -> str:
    """One line: 'set aside 152 of 5000 readings (3.0 %) beyond 3.5 robust
    sd (0.0021 gauss): a stretch 12.3-13.3 s (125), 27 single readings'."""
    if not rec or not rec.get("count"):
        return (f"nothing set aside (every reading within {rec.get('threshold_sd', REJECT_SD):g} "
                "robust sd)") if rec else ""
    sd = rec.get("robust_sd")
    parts = []
    st = rec.get("stretches_s") or []
    for a, b, k, *rel in st[:4]:
        parts.append(f"{a:.1f}-{b:.1f} s ({k}" + (f", {100 * rel[0]:+.0f} %" if rel else "") + ")")
    if len(st) > 4:
        parts.append(f"{len(st) - 4} more stretches ({sum(s[2] for s in st[4:])})")
    if rec.get("single"):
        parts.append(f"{rec['single']} single readings")
    what = ("a stretch " if len(st) == 1 else f"{len(st)} stretches " if st else "") + ", ".join(parts)
    return (f"set aside {rec['count']} of {rec['of']} readings ({100 * rec['fraction']:.1f} %) "
            f"beyond {rec['threshold_sd']:g} robust sd"
            + (f" ({sd:.3g} {unit})" if sd is not None else "") + f": {what}")


TRIM = 0.1                 # the central sd: the deviations between these quantiles ...
TRIM_SD = 0.6617           # ... have this sd for normal noise of sd 1


def central_sd(e) -> float:
    """The standard deviation of normal noise from the deviations ``e``
    between their 10th and 90th percentiles (corrected by ``TRIM_SD``): a
    reading's raw axes are whole counts, and with a noise of one or two
    counts the MAD jumps between whole values (1.48 counts for a noise of
    2, set aside 1 % of a clean pose's readings at 4 sd); up to 10 % wild
    values on either side do not move it."""
    e = np.asarray(e, float)
    if len(e) < 5:
        return 0.0
    lo, hi = np.quantile(e, [TRIM, 1 - TRIM])
    mid = e[(e >= lo) & (e <= hi)]
    return float(np.std(mid) / TRIM_SD) if len(mid) > 2 else 0.0


def inliers_3d(x, groups=None, c: float = REJECT_SD) -> np.ndarray:
    """Rows of x (n, 3) -- raw axes: a gyroscope's still rates, a pose's
    readings -- within ``c`` sd (``central_sd``, per axis) of their group's
    median on every axis."""
    x = np.asarray(x, float)
    ok = np.ones(len(x), bool)
    for a in range(x.shape[1]):
        e = deviations(x[:, a], groups)
        s = central_sd(e)
        if s > 0:
            ok &= np.abs(e) <= c * s
    return ok
