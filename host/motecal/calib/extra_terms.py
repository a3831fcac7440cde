"""Terms beyond the calibration's affine map that a diagnosis can ask for
(issue 13, closing the loop), each fitted from the session and judged on
held-out poses (``heldout_decision``): kept only when it lowers the error on
poses it was not fitted on, by more than chance.

* gyroscope ``g_sensitivity``: the still rate depends on the specific force,
  ``w = b + S a`` (S in deg/s per g, a from the calibrated accelerometer);
* gyroscope ``bias_drift``: the bias settles after power-on, ``b(t) = b0 +
  d (1 - exp(-t/tau)) + s t``; the delivered bias is the one at the end of
  the session (the board as it will be used, warmed up);
* accelerometer ``nonlinearity``: per axis, ``h(u) = u + q u^2 + c3 u^3 +
  a |u|`` (u in g) before the full model, ``v = A h(u) + c``, fitted jointly
  on the pose means; the affine part goes to the mote, h is applied on the
  host (``apply_nonlinearity``).

Pure functions on numpy arrays; what a session can determine is judged by
``calib.content.term_support``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from ..maths.heldout import interleaved, kfold_heldout

Z_ACCEPT = 2.5              # held-out improvement must exceed this many standard errors
TAU_GRID_S = (20.0, 60.0, 150.0, 400.0, 1000.0)


@dataclass
class Decision:
    """A held-out comparison of a calibration without and with a term."""
    accepted: bool
    before: float               # held-out rms without
    after: float                # held-out rms with
    groups: int                 # held-out groups (poses or chunks) compared
    z: float                    # improvement / its standard error
    why: str | None = None      # why it could not be judged

    def text(self, unit: str) -> str:
        if self.why:
            return f"cannot be judged on held-out data: {self.why}"
        return (f"held-out rms {self.before:.3g} -> {self.after:.3g} {unit} over {self.groups} "
                f"groups ({self.z:+.1f} standard errors)")


def heldout_decision(e_without: np.ndarray, e_with: np.ndarray,
                     z_accept: float = Z_ACCEPT) -> Decision:
    """Paired comparison of per-group held-out squared errors: the term is
    accepted when the mean improvement exceeds ``z_accept`` standard errors
    (the change a noise-only term makes is a coin toss; it is not taken)."""
    a = np.asarray(e_without, float)
    b = np.asarray(e_with, float)
    ok = np.isfinite(a) & np.isfinite(b)
    a, b = a[ok], b[ok]
    n = len(a)
    if n < 3:
        return Decision(False, float("nan"), float("nan"), n, 0.0)
    d = a - b
    se = float(np.std(d, ddof=1)) / np.sqrt(n)
    z = float(d.mean() / se) if se > 0 else (1e9 if d.mean() > 0 else 0.0)
    return Decision(bool(z > z_accept or z_accept == -np.inf), float(np.sqrt(a.mean())),
                    float(np.sqrt(b.mean())),
                    n, z)


def pose_folds(n_poses: int, k: int) -> np.ndarray:
    return interleaved(n_poses, max(2, k))


# ---------------------------------------------------------------------------
# gyroscope: bias as a linear model of the pose means
# ---------------------------------------------------------------------------
def warmup(t, tau):
    return 1.0 - np.exp(-np.asarray(t, float) / tau)


def gyro_design(n: int, a: np.ndarray | None, t: np.ndarray | None,
                tau: float | None) -> np.ndarray:
    """Columns of the pose-mean bias model for n poses: 1, [a_x a_y a_z],
    [warm-up, t]."""
    cols = [np.ones((n, 1))]
    if a is not None:
        cols.append(np.asarray(a, float))
    if t is not None:
        cols.append(np.column_stack([warmup(t, tau), t]))
    return np.hstack(cols)


def _wls(X, y, w):
    sw = np.sqrt(w)[:, None]
    coef, *_ = np.linalg.lstsq(X * sw, y * sw, rcond=None)
    return coef


def _gyro_fit(w, a, t, n, use_a, use_t):
    """Coefficients (and tau) of the bias model on poses (w rates, a specific
    force, t times, n samples per pose); tau from the grid by weighted SSE."""
    best = None
    for tau in (TAU_GRID_S if use_t else (None,)):
        X = gyro_design(len(w), a if use_a else None, t if use_t else None, tau)
        coef = _wls(X, w, n)
        sse = float(np.sum(n[:, None] * (w - X @ coef) ** 2))
        if best is None or sse < best[0]:
            best = (sse, tau, coef)
    return best[2], best[1]


def gyro_heldout(w, a, t, n, k, base: tuple, cand: tuple) -> tuple[Decision, np.ndarray,
                                                                   np.ndarray]:
    """Held-out squared rate error per pose (folds of poses) of the bias
    models ``base`` and ``cand`` = (use_a, use_t)."""
    fold = pose_folds(len(w), k)
    e = {}
    for key, (ua, ut) in (("base", base), ("cand", cand)):
        def score(model, te, ua=ua, ut=ut):
            coef, tau = model
            X = gyro_design(int(te.sum()), a[te] if ua else None, t[te] if ut else None, tau)
            return np.sum((w[te] - X @ coef) ** 2, axis=1)
        e[key] = kfold_heldout(fold, lambda tr, ua=ua, ut=ut: _gyro_fit(w[tr], a[tr], t[tr],
                                                                         n[tr], ua, ut), score)
    return heldout_decision(e["base"], e["cand"]), e["base"], e["cand"]


# ---------------------------------------------------------------------------
# accelerometer nonlinearity: joint fit on pose means
# ---------------------------------------------------------------------------
NL_NAMES = [f"{g}_{a}" for g in ("q", "c3", "a") for a in "xyz"]


def nl_h(u, p):
    """h(u) = u + q u^2 + c3 u^3 + a |u| per axis (u in nominal units)."""
    u = np.asarray(u, float)
    q, c3, a = p[0:3], p[3:6], p[6:9]
    return u + q * u * u + c3 * u * u * u + a * np.abs(u)


def _unpack(x):
    L = np.zeros((3, 3))
    L[0, 0], L[1, 1], L[2, 2], L[1, 0], L[2, 0], L[2, 1] = x[0:6]
    return L, x[6:9], x[9:18]


def _pack(A, c, p):
    return np.concatenate([[A[0, 0], A[1, 1], A[2, 2], A[1, 0], A[2, 0], A[2, 1]], c, p])


def nl_residuals(x, U, w, target=1.0, nl=True):
    A, c, p = _unpack(x)
    h = nl_h(U, p) if nl else U
    v = h @ A.T + c
    return np.sqrt(w) * (np.linalg.norm(v, axis=1) - target)


def nl_fit(U, w, A0, c0, nl=True):
    """Least squares (scipy, trf) of v = A h(U) + c with |v| = 1 on pose means
    U (nominal units) weighted by w, from the lower-triangular A0, c0.
    Returns (A, c, p, jacobian at the optimum)."""
    x0 = _pack(np.asarray(A0, float), np.asarray(c0, float), np.zeros(9))
    free = np.ones(18, bool) if nl else np.r_[np.ones(9, bool), np.zeros(9, bool)]

    def f(xf):
        x = x0.copy()
        x[free] = xf
        return nl_residuals(x, U, w, nl=nl)
    res = least_squares(f, x0[free], method="trf", x_scale="jac", xtol=1e-12, ftol=1e-12,
                        max_nfev=200)
    x = x0.copy()
    x[free] = res.x
    A, c, p = _unpack(x)
    return A, c, p, res.jac


def nl_rank(jac) -> int:
    s = np.linalg.svd(jac / np.maximum(np.linalg.norm(jac, axis=0), 1e-300), compute_uv=False)
    return int(np.sum(s > 1e-6 * s[0])) if len(s) else 0


def nl_heldout(U, w, A0, c0, k) -> tuple[Decision, np.ndarray, np.ndarray]:
    """Held-out squared magnitude error of the pose means (folds of poses),
    the full model alone against the full model with h."""
    fold = pose_folds(len(U), k)

    def fit(tr):
        return [nl_fit(U[tr], w[tr], A0, c0, nl=nl)[:3] for nl in (False, True)]

    def score(fits, te):
        return np.column_stack([nl_residuals(_pack(*f), U[te], np.ones(te.sum()), nl=nl) ** 2
                                for f, nl in zip(fits, (False, True))])
    e = kfold_heldout(fold, fit, score)
    return heldout_decision(e[:, 0], e[:, 1]), e[:, 0], e[:, 1]


def apply_nonlinearity(sc, raw_counts) -> np.ndarray:
    """A sensor calibration with its host-side nonlinearity (``extra
    ["nonlinearity"]``) applied: v = A_nominal h(raw / lsb) + c.  Without one,
    the affine map (``sc.apply``)."""
    nlx = (sc.extra or {}).get("nonlinearity")
    if not nlx:
        return sc.apply(raw_counts)
    p = np.array(nlx["q"] + nlx["c3"] + nlx["a"], float)
    u = np.asarray(raw_counts, float) / sc.lsb_per_unit
    A_nom = np.asarray(sc.A, float) * sc.lsb_per_unit
    return nl_h(u, p) @ A_nom.T + np.asarray(sc.c, float)


def gyro_rate_bias(sc, a=None) -> np.ndarray:
    """The gyroscope's still rate (deg/s, before its matrix) the calibration
    ``sc`` predicts: its bias (the b_ parameters: the session mean, or the
    end-of-session bias after a warm-up), plus with a g-sensitivity
    ``S (a - a_mean)`` for the specific force ``a`` (n, 3) in g."""
    b = np.array([p.value for p in sc.params[:3]], float)
    gs = (sc.extra or {}).get("g_sensitivity")
    if a is None:
        return b
    a = np.atleast_2d(np.asarray(a, float))
    if not gs:
        return np.broadcast_to(b, a.shape).copy()
    S = np.asarray(gs["S"], float)
    return b + (a - np.asarray(gs["a_mean"], float)) @ S.T
