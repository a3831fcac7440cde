"""Fitting a magnitude model: the GA on a per-pose reduction of the data,
then a least-squares polish (scipy, analytic Jacobian) on every sample.

The objective is always the paper's: the mean over *all samples* of
``(|A u + c| - H)^2``.  The GA searches on a cheap surrogate -- the mean of
each static pose (or a strided subsample of sweep data), weighted by its
number of samples -- which has nearly the same optimum; the polish then
minimises the exact objective from the GA's best.  ``lm_fit`` is the plain
Levenberg-Marquardt reference from the model's nominal point.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from . import ga as _ga
from .identify import Identifiability, independent_columns
from .models import MagnitudeModel

MAX_SWEEP_POINTS = 250      # surrogate size for unlabelled (rotation) data


@dataclass
class Reduction:
    """Points and weights the GA evaluates instead of every sample."""
    u: np.ndarray               # (m, 3) nominal units
    w: np.ndarray               # (m,) sample counts


def reduce_samples(u: np.ndarray, label: np.ndarray | None = None) -> Reduction:
    """Per-pose means for labelled static data (label >= 1); a strided
    subsample for the remaining (rotation / unlabelled) rows."""
    u = np.asarray(u, float)
    if label is None:
        label = np.zeros(len(u), np.int32)
    label = np.asarray(label)
    pts, ws = [], []
    static = label >= 1
    if static.any():
        labs, inv, cnt = np.unique(label[static], return_inverse=True, return_counts=True)
        sums = np.zeros((len(labs), 3))
        np.add.at(sums, inv, u[static])
        pts.append(sums / cnt[:, None])
        ws.append(cnt.astype(float))
    rest = u[~static]
    if len(rest):
        step = max(1, int(np.ceil(len(rest) / MAX_SWEEP_POINTS)))
        sub = rest[::step]
        pts.append(sub)
        ws.append(np.full(len(sub), float(step)))
    return Reduction(np.vstack(pts), np.concatenate(ws))


@dataclass
class FitResult:
    model: MagnitudeModel
    theta: np.ndarray
    mse: float                      # exact objective at theta (all samples)
    n: int                          # samples
    std: np.ndarray                 # per-parameter standard deviation (nan = not identifiable)
    ident: Identifiability
    cov: np.ndarray | None = None   # sigma^2 (J^T J)^+, (d, d)
    trace: list = field(default_factory=list)     # GA best fitness per generation (surrogate)
    ga_generations: int = 0
    ga_evaluations: int = 0
    ga_stop: str = ""
    seed: int | None = None
    polish_nfev: int = 0
    note: str = ""

    @property
    def affine(self):
        return self.model.affine(self.theta)


def mse_of(model: MagnitudeModel, theta, u) -> float:
    r = model.residuals(theta, u)
    return float(np.mean(r * r))


def nominal_start(model: MagnitudeModel, u) -> np.ndarray:
    """The prior's nominal point, with the field set to the mean magnitude."""
    x0 = model.default.copy()
    if model.free_field:
        x0[-1] = float(np.clip(np.mean(np.linalg.norm(u, axis=1)),
                               model.lo[-1], model.hi[-1]))
    return x0


LM_TOL = 1e-12


def polish_limit(d: int) -> int:
    """The polish's bound on residual evaluations for ``d`` parameters."""
    return 60 * (d + 1)


def polish(model: MagnitudeModel, theta0, u, max_nfev=None, w=None):
    """Levenberg-Marquardt (MINPACK, analytic Jacobian) on every sample
    (each residual weighted by ``sqrt(w)`` when weights ``w`` are given).
    Returns (theta, nfev).

    A model with redundant parameters (``model.redundant``: the paper's
    angles only multiply scales or each other, so its Jacobian is singular
    everywhere) is polished in a gauge: the parameters whose Jacobian columns
    at ``theta0`` add nothing (``identify.independent_columns``, in parameter
    order) are set to their nominal value -- the angles to 0, where the others
    still reach every fit the model can -- and only the rest move, unscaled
    (``x_scale=1``: the default column scaling crawls when an angle's optimum
    is 0, where its column vanishes).  This keeps the singular Jacobian out of
    MINPACK, whose steps on one read uninitialised memory: the same input gave
    results differing in the last bits from run to run."""
    theta0 = np.asarray(theta0, float)
    max_nfev = max_nfev or polish_limit(len(theta0))
    keep = independent_columns(model.jacobian(theta0, u)) if model.redundant else None
    sw = None if w is None else np.sqrt(np.asarray(w, float))
    res_f, jac_f = model.residuals, model.jacobian
    if sw is not None:
        def res_f(th, u):
            return sw * model.residuals(th, u)

        def jac_f(th, u):
            return sw[:, None] * model.jacobian(th, u)
    if keep is None or keep.all():
        res = least_squares(res_f, theta0, jac=jac_f, args=(u,),
                            method="lm", xtol=LM_TOL, ftol=LM_TOL, gtol=1e-15,
                            max_nfev=max_nfev)
        return res.x, res.nfev
    start = np.where(keep, theta0, model.default)
    if not keep.any():
        return start, 0

    def full(x):
        th = start.copy()
        th[keep] = x
        return th

    res = least_squares(lambda x: res_f(full(x), u), start[keep],
                        jac=lambda x: jac_f(full(x), u)[:, keep], method="lm",
                        xtol=LM_TOL, ftol=LM_TOL, gtol=1e-15, max_nfev=max_nfev, x_scale=1.0)
    return full(res.x), res.nfev


def escaped(theta, lo, hi) -> bool:
    """Far outside the prior box (sphere fits can run off towards a plane)."""
    c, h = 0.5 * (lo + hi), 0.5 * (hi - lo)
    return bool(np.any(np.abs(theta - c) > 3 * h + 1e-12))


@dataclass
class Search:
    """What the GA + polish produced (before statistics)."""
    theta: np.ndarray
    trace: list
    generations: int
    evaluations: int
    stop: str
    nfev: int
    seed: object
    note: str = ""


def ga_optimize(model: MagnitudeModel, u, label=None, *, seed=None,
                options: _ga.GAOptions = _ga.GAOptions()) -> Search:
    """The project's method: GA over the prior box on the reduction, then the
    LM polish on every sample.  A polish that runs far out of the prior box is
    redone bounded to three times the box."""
    u = np.asarray(u, float)
    red = reduce_samples(u, label)
    lo, hi = model.prior_box(u)
    g = _ga.minimize(lambda P: model.population_mse(P, red.u, red.w), lo, hi,
                     seed=seed, options=options)
    theta, nfev = polish(model, g.x, u)
    note = ""
    if escaped(theta, lo, hi) or not np.all(np.isfinite(theta)):
        c, h = 0.5 * (lo + hi), 0.5 * (hi - lo)
        res = least_squares(model.residuals, g.x, jac=model.jacobian, args=(u,),
                            method="trf", bounds=(c - 3 * h, c + 3 * h),
                            xtol=LM_TOL, ftol=LM_TOL, gtol=1e-15)
        theta, nfev = res.x, nfev + res.nfev
        note = "unbounded polish left the prior ranges; polished within 3x the ranges"
    return Search(theta, g.trace, g.generations, g.evaluations, g.stop, nfev, seed, note)


def finish(model, theta, u, **kw) -> FitResult:
    """Objective, standard deviations and identifiability at the optimum."""
    r = model.residuals(theta, u)
    ident = model.identifiability(theta, u)
    n = len(u)
    dof = max(1, n - ident.rank)
    sigma2 = float(r @ r) / dof
    std = ident.std(sigma2)
    return FitResult(model, np.asarray(theta, float), float(np.mean(r * r)), n, std, ident,
                     ident.cov_unit * sigma2, **kw)


def ga_fit(model: MagnitudeModel, u, label=None, *, seed=None,
           options: _ga.GAOptions = _ga.GAOptions()) -> FitResult:
    """GA + polish, with standard deviations and identifiability."""
    u = np.asarray(u, float)
    s = ga_optimize(model, u, label, seed=seed, options=options)
    fr = finish(model, s.theta, u, trace=s.trace, ga_generations=s.generations,
                ga_evaluations=s.evaluations, ga_stop=s.stop, seed=seed, polish_nfev=s.nfev)
    fr.note = s.note
    return fr


def lm_optimize(model: MagnitudeModel, u):
    """Reference: Levenberg-Marquardt from the nominal point, every sample.
    Returns (theta, nfev)."""
    u = np.asarray(u, float)
    return polish(model, nominal_start(model, u), u)


def lm_fit(model: MagnitudeModel, u) -> FitResult:
    theta, nfev = lm_optimize(model, u)
    return finish(model, theta, np.asarray(u, float), polish_nfev=nfev)
