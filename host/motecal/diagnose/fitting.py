"""Nested models for the diagnosis: the paper's starting model plus extra
terms, fitted by weighted least squares, and the tests between them.

Magnitude sensors (accelerometer, magnetometer)
-----------------------------------------------
The base is calib's magnitude model (``motecal.calib.models``): the paper
model (offsets + scales; the magnetometer's field magnitude free, det gauge)
or, with ``cross_axis``, calib's full model (bias + lower-triangular matrix).
Extra terms are the simulator's terms, undone on the raw counts before the
base calibration, in the order the extended model file lists them after
``scale_offset`` (see ``extend.py``):

    raw  = drift(t) + NL( M K u + b )            (forward, as simulated)
    u    = A NL^-1( raw - drift(t) ) / K + c     (what is fitted)
    r    = |u| - H - field(t)                    (residual, sensor unit)

* ``nonlinearity``: the simulator's q, c3, a per axis (r = x/K:
  x += K (q r^2 + c3 r^3), then x *= 1 + a sign(x)); inverted by fixed-point
  iteration.
* ``bias_drift``: an offset per axis that moves with time, a smooth basis
  (linear + ``DRIFT_J - 1`` cosines over the session).
* ``field`` (magnetometer sweeps): the field magnitude moves with time
  (a disturbance in the world frame changes |B| by B^.d).

Gyroscope and single-orientation data: linear
---------------------------------------------
Per axis, segment means m = b + K G a + drift(t): ordinary weighted linear
least squares (``fit_linear``).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from ..calib.fit import polish
from ..calib.models import MagnitudeModel, make_model, theta_from_affine
from ..maths.sphere import unit

DRIFT_J = 4          # drift basis functions per axis


# ---------------------------------------------------------------------------
# time bases
# ---------------------------------------------------------------------------
def time_basis(t: np.ndarray, t_lo: float, t_hi: float, J: int) -> np.ndarray:
    """(n, J): linear, then cos(pi j tau) for j = 1..J-1, tau in [0, 1]."""
    span = max(t_hi - t_lo, 1e-9)
    tau = (np.asarray(t, float) - t_lo) / span
    cols = [tau - 0.5]
    for j in range(1, J):
        cols.append(np.cos(np.pi * j * tau))
    return np.column_stack(cols)


# ---------------------------------------------------------------------------
# extra terms of a magnitude model
# ---------------------------------------------------------------------------
class Extra:
    """An extra term: ``n`` parameters, undone on raw counts."""
    cause = ""
    n = 0

    def names(self) -> list[str]:
        return []

    def undo(self, x, t, p, K):
        return x

    def field(self, t, p):
        return 0.0


class NonlinearityExtra(Extra):
    cause = "nonlinearity"
    n = 9

    def names(self):
        return [f"{g}_{a}" for g in ("q", "c3", "a") for a in "xyz"]

    @staticmethod
    def forward(y, p, K):
        q, c3, a = p[0:3], p[3:6], p[6:9]
        r = y / K
        y = y + K * (q * r * r + c3 * r * r * r)
        return y * (1.0 + a * np.sign(y))

    def undo(self, x, t, p, K):
        """Newton on y + K (q r^2 + c3 r^3) = x / (1 + a sign(x)), r = y / K
        (the sign of the output is the sign of the reading)."""
        q, c3, a = p[0:3], p[3:6], p[6:9]
        x = np.asarray(x, float)
        y0 = x / (1.0 + a * np.sign(x))
        y = y0.copy()
        for _ in range(8):
            r = y / K
            f = y + K * (q * r * r + c3 * r * r * r) - y0
            d = 1.0 + 2 * q * r + 3 * c3 * r * r
            d = np.where(np.abs(d) < 0.2, np.sign(d) + (d == 0), d)   # stay on the monotone branch
            step = f / d
            y = y - np.clip(step, -0.5 * K, 0.5 * K)
            if np.all(np.abs(step) < 1e-9 * K):
                break
        return y

    def jac(self, y, p, K):
        """At the undone value y: (dNL/dy (n,3), dNL/dp (n,3,9))."""
        q, c3, a = p[0:3], p[3:6], p[6:9]
        r = y / K
        pre = y + K * (q * r * r + c3 * r * r * r)
        sg = np.sign(pre)
        fa = 1.0 + a * sg
        dy = (1.0 + 2 * q * r + 3 * c3 * r * r) * fa
        dp = np.zeros(y.shape + (9,))
        for i in range(3):
            dp[:, i, i] = K * r[:, i] ** 2 * fa[:, i]
            dp[:, i, 3 + i] = K * r[:, i] ** 3 * fa[:, i]
            dp[:, i, 6 + i] = pre[:, i] * sg[:, i]
        return dy, dp


class DriftExtra(Extra):
    cause = "bias_drift"

    def __init__(self, t_lo, t_hi, J=DRIFT_J):
        self.t_lo, self.t_hi, self.J = float(t_lo), float(t_hi), int(J)
        self.n = 3 * self.J

    def names(self):
        return [f"d{j}_{a}" for a in "xyz" for j in range(self.J)]

    def offset(self, t, p):
        Phi = time_basis(t, self.t_lo, self.t_hi, self.J)
        return Phi @ p.reshape(3, self.J).T            # (n, 3) counts

    def undo(self, x, t, p, K):
        return x - self.offset(t, p)


class FieldExtra(Extra):
    """Field magnitude moving with time (gauss, relative to H)."""
    cause = "field_disturbance"

    def __init__(self, t_lo, t_hi, J):
        self.t_lo, self.t_hi, self.J = float(t_lo), float(t_hi), int(J)
        self.n = self.J

    def names(self):
        return [f"f{j}" for j in range(self.J)]

    def field(self, t, p):
        return time_basis(t, self.t_lo, self.t_hi, self.J) @ p


# ---------------------------------------------------------------------------
# least squares
# ---------------------------------------------------------------------------
def least_squares_fit(fun, jac, x0, *, max_nfev: int = 100) -> np.ndarray:
    """scipy's ``least_squares`` (trust-region reflective, Jacobian-scaled
    variables, the analytic Jacobian): the minimiser of sum(fun(x)^2) from x0.
    (The diagnosis used to carry its own Levenberg-Marquardt; scipy's is the
    one the rest of the code uses.)  Unlike MINPACK's LM it is well defined
    on a singular Jacobian, and ``max_nfev`` bounds the work of the held-out
    refits that start at the full fit."""
    from scipy.optimize import least_squares
    x0 = np.asarray(x0, float)
    if not np.all(np.isfinite(fun(x0))):
        return x0
    sol = least_squares(fun, x0, jac=jac, method="trf", x_scale="jac", max_nfev=max_nfev,
                        ftol=1e-10, xtol=1e-10, gtol=1e-10)
    return sol.x


# ---------------------------------------------------------------------------
# magnitude model
# ---------------------------------------------------------------------------
@dataclass
class MagnitudeFit:
    sensor: str
    family: str                 # "paper" or "full"
    extras: tuple               # Extra instances
    base: MagnitudeModel
    theta: np.ndarray           # base params then extras
    K: float
    rss: float = np.nan         # weighted
    n_obs: int = 0
    ok: bool = True

    @property
    def p(self) -> int:
        return len(self.theta)

    @property
    def names(self) -> list[str]:
        out = list(self.base.names)
        for e in self.extras:
            out += [f"{e.cause}.{n}" for n in e.names()]
        return out

    def new_param_index(self, cause: str) -> np.ndarray:
        """Indices of the parameters a cause adds (cross_axis: the k_ terms)."""
        if cause == "cross_axis":
            return np.array([i for i, n in enumerate(self.names) if n.startswith("k_")], int)
        return np.array([i for i, n in enumerate(self.names) if n.startswith(cause + ".")], int)

    @property
    def causes(self) -> list[str]:
        out = [e.cause for e in self.extras]
        if self.family == "full":
            out.insert(0, "cross_axis")
        return out

    def split(self, theta=None):
        theta = self.theta if theta is None else theta
        d = self.base.d
        parts, i = [], d
        for e in self.extras:
            parts.append(theta[i:i + e.n])
            i += e.n
        return theta[:d], parts

    def undo(self, x, t, theta=None):
        tb, parts = self.split(theta)
        y = np.asarray(x, float)
        for e, pe in zip(reversed(self.extras), reversed(parts)):
            y = e.undo(y, t, pe, self.K)
        return y

    def calibrate(self, x, t, theta=None):
        """Calibrated vectors (sensor unit)."""
        tb, _ = self.split(theta)
        A, c, H = self.base.affine(tb)
        return (self.undo(x, t, theta) / self.K) @ A.T + c

    def target(self, t, theta=None):
        tb, parts = self.split(theta)
        _, _, H = self.base.affine(tb)
        f = 0.0
        for e, pe in zip(self.extras, parts):
            f = f + e.field(t, pe)
        return H + f

    def residuals(self, x, t, theta=None):
        v = self.calibrate(x, t, theta)
        return np.linalg.norm(v, axis=1) - self.target(t, theta)

    def jacobian(self, x, t, theta=None):
        """Analytic d residuals / d theta: calib's base Jacobian, chained
        through the undone extras."""
        theta = self.theta if theta is None else theta
        tb, parts = self.split(theta)
        x = np.asarray(x, float)
        # undo step by step, remembering what each extra saw
        ys = [x]
        y = x
        for e, pe in zip(reversed(self.extras), reversed(parts)):
            y = e.undo(y, t, pe, self.K)
            ys.append(y)
        u = y / self.K
        Jb = self.base.jacobian(tb, u)
        A, c, H = self.base.affine(tb)
        v = u @ A.T + c
        nv = unit(v)
        g = (nv @ A) / self.K                        # d r / d y (counts), (n, 3)
        cols = [Jb]
        # walk outwards: the extra undone last (first in forward order) is innermost
        blocks = {}
        G = g
        rev = list(reversed(self.extras))
        rparts = list(reversed(parts))
        for idx in range(len(rev) - 1, -1, -1):
            e, pe = rev[idx], rparts[idx]
            y_out = ys[idx + 1]                      # value after undoing e
            if isinstance(e, NonlinearityExtra):
                dy, dp = e.jac(y_out, pe, self.K)
                blocks[id(e)] = -np.einsum("na,nap->np", G / dy, dp)
                G = G / dy                            # d r / d (input of NL^-1)
            elif isinstance(e, DriftExtra):
                Phi = time_basis(t, e.t_lo, e.t_hi, e.J)
                blocks[id(e)] = -(G[:, :, None] * Phi[:, None, :]).reshape(len(x), -1)
            elif isinstance(e, FieldExtra):
                blocks[id(e)] = -time_basis(t, e.t_lo, e.t_hi, e.J)
            else:
                blocks[id(e)] = np.zeros((len(x), e.n))
        for e in self.extras:
            cols.append(blocks[id(e)])
        return np.hstack(cols)

    def field_magnitude(self) -> float:
        _, _, H = self.base.affine(self.split()[0])
        return float(H)

    def affine(self):
        A, c, H = self.base.affine(self.split()[0])
        return A, c, float(H)


def base_model(sensor: str, family: str) -> MagnitudeModel:
    if family == "full":
        return make_model(sensor, "full")
    return make_model(sensor, "paper", groups=("offsets", "scales"))


def start_theta(base: MagnitudeModel, A, c, H) -> np.ndarray:
    """Base parameters of ``base`` representing an affine map (A, c)."""
    A = np.asarray(A, float)
    c = np.asarray(c, float)
    if base.family != "full":
        A = np.diag(np.diag(A))             # paper: the scales (diagonal) only
    if base.derived_scale:                   # det gauge: det(A) = 1, rescale c and H
        k = abs(np.linalg.det(A)) ** (1.0 / 3.0)
        A, c, H = A / k, c / k, H / k
    return theta_from_affine(base, A, c, field=H)


def fit_magnitude(sensor: str, K: float, x, t, w, *, family="paper", extras=(),
                  start: MagnitudeFit | None = None, polish_base=True,
                  max_nfev: int | None = None) -> MagnitudeFit:
    """Weighted least squares of the magnitude model on points x (counts) at
    times t with weights w (1/sd of each residual)."""
    x = np.asarray(x, float)
    t = np.asarray(t, float)
    w = np.asarray(w, float)
    base = base_model(sensor, family)
    extras = tuple(extras)
    if start is not None:
        A, c, H = start.affine()
        th_b = start_theta(base, A, c, H)
        old = {type(e): pe for e, pe in zip(start.extras, start.split()[1])}
    else:
        th_b = None
        old = {}
    if th_b is None:
        # calib's LM fit of the base model on the (unweighted) points
        from ..calib.fit import nominal_start
        u = x / K
        th_b, _ = polish(base, nominal_start(base, u), u)
    th_e = []
    for e in extras:
        prev = old.get(type(e))
        th_e.append(prev if prev is not None and len(prev) == e.n else np.zeros(e.n))
    theta0 = np.concatenate([th_b] + th_e) if th_e else np.asarray(th_b, float)
    fit = MagnitudeFit(sensor, family, extras, base, theta0, K, n_obs=len(x))

    def res(theta):
        return w * fit.residuals(x, t, theta)

    def jac(theta):
        return w[:, None] * fit.jacobian(x, t, theta)

    if not extras and family == "paper" and polish_base is False:
        theta = theta0
    else:
        theta = least_squares_fit(res, jac, theta0, max_nfev=max_nfev or 100)
    fit.theta = np.asarray(theta, float)
    rr = res(fit.theta)
    fit.rss = float(rr @ rr)
    fit.ok = bool(np.isfinite(fit.rss))
    return fit


# ---------------------------------------------------------------------------
# linear model (gyroscope, one-orientation data)
# ---------------------------------------------------------------------------
@dataclass
class LinearFit:
    """Per axis y = X beta (weighted); the three axes share the design."""
    names: list                 # column names of X
    groups: dict                # cause -> column indices
    beta: np.ndarray            # (p, 3)
    rss: float                  # weighted, summed over axes
    n_obs: int                  # rows * 3
    X: np.ndarray = field(repr=False, default=None)

    @property
    def p(self) -> int:
        return self.beta.size


def fit_linear(X: np.ndarray, Y: np.ndarray, W: np.ndarray, names, groups) -> LinearFit:
    """Weighted least squares per axis: Y (k, 3), weights W (k, 3) = 1/sd."""
    beta = np.zeros((X.shape[1], 3))
    rss = 0.0
    for a in range(3):
        Xa = X * W[:, a:a + 1]
        ya = Y[:, a] * W[:, a]
        b, *_ = np.linalg.lstsq(Xa, ya, rcond=None)
        beta[:, a] = b
        r = ya - Xa @ b
        rss += float(r @ r)
    return LinearFit(list(names), dict(groups), beta, rss, Y.size, X)


# ---------------------------------------------------------------------------
# tests
# ---------------------------------------------------------------------------
def f_test(rss0: float, rss1: float, q: int, dof1: int):
    """Nested least squares: F statistic and p-value for q extra parameters
    (the residual variance estimated from the larger model)."""
    if q <= 0 or dof1 <= 0 or not (rss1 > 0):
        return 0.0, 1.0
    F = max(rss0 - rss1, 0.0) / q / (rss1 / dof1)
    return float(F), float(stats.f.sf(F, q, dof1))


def chi2_excess(rss: float, dof: int):
    """Weighted residuals larger than their noise: chi-square upper tail."""
    if dof <= 0:
        return 1.0, 1.0
    return float(rss / dof), float(stats.chi2.sf(rss, dof))


def delta_bic(rss0: float, rss1: float, q: int, n: int) -> float:
    """BIC(larger) - BIC(smaller) for Gaussian least squares (negative favours
    the larger model)."""
    if rss0 <= 0 or rss1 <= 0 or n <= 0:
        return 0.0
    return float(n * np.log(rss1 / rss0) + q * np.log(n))


def robust_wald(fit: MagnitudeFit, x, t, w, idx: np.ndarray, clusters: np.ndarray):
    """Wald test that the parameters ``idx`` are 0, with a cluster-robust
    (sandwich) covariance: scores summed within clusters of consecutive
    readings, so that residuals correlated inside a cluster are not counted
    as independent.  Returns (F = W / q, p) with F(q, G - 1), G clusters."""
    q = len(idx)
    G = len(np.unique(clusters))
    if q == 0 or G < 10 * q:          # too few clusters for a q x q robust covariance
        return None
    J = w[:, None] * fit.jacobian(x, t)
    r = w * fit.residuals(x, t)
    A = J.T @ J
    try:
        Ainv = np.linalg.pinv(A)
    except np.linalg.LinAlgError:
        return None
    sc = J * r[:, None]
    _, inv = np.unique(clusters, return_inverse=True)
    Sb = np.zeros((G, J.shape[1]))
    np.add.at(Sb, inv, sc)
    meat = Sb.T @ Sb * G / (G - 1)
    cov = Ainv @ meat @ Ainv
    b = fit.theta[idx]
    C = cov[np.ix_(idx, idx)]
    try:
        W = float(b @ np.linalg.solve(C, b))
    except np.linalg.LinAlgError:
        return None
    Fv = W / q
    return Fv, float(stats.f.sf(Fv, q, G - 1))
