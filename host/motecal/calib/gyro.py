"""Gyroscope calibration.

Bias: the per-axis mean of the still rates (``mean_bias``), with an honest
standard error: the larger of sample sd / sqrt(n) and the scatter of the
pose means (a bias that moves between poses is not known better than that
scatter says).  The paper's way (``ga_bias``: the GA minimises eq. 6 over
still data, then the exact minimiser of ``eq6.Eq6Table`` polishes it) stays
as the paper's method for Table II and is reported next to the calibration:
gyroscope counts are integers, and the minimiser of eq. 6 sits on a kink of
its piecewise quadratic, so it locks onto whole counts (0.07 deg/s steps) --
an error many times the standard error of the mean of thousands of samples.

Scale and misalignment (what the paper left open), imu_tk style: between two
consecutive still poses the board turns; integrating the calibrated rate
``G (w - b)`` over the move must turn the gravity direction measured by the
calibrated accelerometer at the first pose into the one at the next pose.
``G`` is a general 3x3 matrix (scales, cross-axis terms and the rotation of
the gyro relative to the accelerometer frame), fitted by least squares over
all moves.  Calibrated rate in deg/s = ``G (counts / LSB_PER_DPS - b)``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from . import eq6
from . import ga as _ga
from .fit import reduce_samples
from .robust import MAX_CONCENTRATE, inliers

PRIOR_BIAS_DPS = 40.0            # ITG3200 zero-rate offset, datasheet +-40 deg/s
MAX_MOVE_S = 10.0                # longer gaps between still poses are not integrated
MIN_MOVES = 6                    # fewer moves: no scale fit
MAX_RMS_DEG = 1.0                # matrix fit used only below this rms gravity-direction error
MAX_G_DEVIATION = 0.3            # ... and with every |G - I| entry below this
GYRO_CLIP_COUNTS = 32000         # |raw| beyond this may be clipped: move not used


@dataclass
class BiasFit:
    """The paper's bias: the minimiser of eq. 6 (no standard error: on integer
    counts it is not a smooth function of the data, see the module doc)."""
    b: np.ndarray                 # deg/s, eq. 6 minimiser
    e6: float                     # eq. 6 at b, (deg/s)^2
    e6_before: float              # eq. 6 at b = 0
    n: int
    trace: list = field(default_factory=list)
    ga_generations: int = 0
    ga_stop: str = ""
    seed: int | None = None


@dataclass
class BiasMean:
    """The calibration's bias: the mean of the still rates."""
    b: np.ndarray                 # deg/s, per-axis mean
    std: np.ndarray               # its standard error: max(std_white, std_poses)
    sd: np.ndarray                # per-axis sample sd, deg/s
    std_white: np.ndarray         # sd / sqrt(n)
    std_poses: np.ndarray         # from the scatter of the pose means (NaN: < 2 poses)
    n: int
    n_poses: int


def mean_bias(g: np.ndarray, label=None) -> BiasMean:
    """Bias from still rates g (n, 3) in deg/s, with ``label`` the pose of
    each row (>= 1, static poses): the mean, and as its standard error the larger of sd / sqrt(n)
    (white noise) and the cluster-robust standard error over poses,
    ``sqrt(P / (P - 1) sum_p n_p^2 (m_p - m)^2) / n`` (pose means m_p of n_p
    rows): drift or orientation-dependent offsets between poses make the
    pose means scatter more than white noise says."""
    g = np.asarray(g, float)
    n = len(g)
    m = g.mean(axis=0)
    sd = g.std(axis=0, ddof=1) if n > 1 else np.zeros(3)
    white = sd / np.sqrt(max(n, 1))
    poses = np.full(3, np.nan)
    P = 0
    if label is not None:
        red = reduce_samples(g, label)                    # pose means m_p and counts n_p
        P = len(red.w)
        if P >= 2:
            dev = red.w[:, None] * (red.u - m)             # n_p (m_p - m)
            poses = np.sqrt(P / (P - 1) * (dev * dev).sum(axis=0)) / n
    std = np.fmax(white, poses)
    return BiasMean(m, std, sd, white, poses, n, P)


def bias_table(g: np.ndarray) -> eq6.Eq6Table:
    return eq6.Eq6Table(g)


def ga_bias(g: np.ndarray, *, seed=None, table: eq6.Eq6Table | None = None,
            options: _ga.GAOptions = _ga.GAOptions()) -> BiasFit:
    """Bias from still rates g (n, 3) in deg/s: GA on eq. 6 + exact minimiser."""
    g = np.asarray(g, float)
    T = table if table is not None else eq6.Eq6Table(g)
    lo = np.full(3, -PRIOR_BIAS_DPS)
    hi = np.full(3, PRIOR_BIAS_DPS)
    res = _ga.minimize(T, lo, hi, seed=seed, x0=np.zeros(3), options=options)
    b, e = T.exact_minimum(res.x)
    return _bias_fit(g, T, b, e, trace=res.trace, ga_generations=res.generations,
                     ga_stop=res.stop, seed=seed)


def lm_bias(g: np.ndarray):
    """Reference: Levenberg-Marquardt on the residuals of eq. 6 from b = 0."""
    g = np.asarray(g, float)
    r = least_squares(eq6.residuals, np.zeros(3), jac=eq6.jacobian, args=(g,), method="lm",
                      xtol=1e-15, ftol=1e-15, gtol=1e-15)
    return r.x, float(np.mean(r.fun ** 2))


def _bias_fit(g, T, b, e, **kw) -> BiasFit:
    return BiasFit(np.asarray(b, float), float(e), float(T(np.zeros(3))), len(g), **kw)


# ---------------------------------------------------------------------------
# scale and misalignment from moves between still poses
# ---------------------------------------------------------------------------
@dataclass
class Move:
    """One move between consecutive still poses."""
    a0: np.ndarray                # unit gravity direction (calibrated accel frame) before
    a1: np.ndarray                # ... after
    w: np.ndarray                 # (m, 3) raw rates in deg/s (nominal), first..last sample
    dt: np.ndarray                # (m - 1,) seconds
    pose0: int
    pose1: int


def find_moves(label, t, seq, w_dps, raw_gyro, gravity: dict, rate_hz: float,
               part=None) -> list[Move]:
    """Moves between consecutive still poses in time order (rows between the
    last sample of one pose and the first of the next), when the rows are
    contiguous (no lost samples), in the same recording (``part``: one id per
    row, e.g. the file an imported row came from), short and not clipped.
    ``gravity`` maps a pose label to its unit gravity direction in the
    calibrated accel frame."""
    label = np.asarray(label)
    idx = np.flatnonzero(label >= 1)
    if len(idx) < 2:
        return []
    moves = []
    # runs of the same label
    brk = np.flatnonzero(np.diff(label[idx]) != 0) + 1
    starts = np.concatenate([[0], brk])
    ends = np.concatenate([brk, [len(idx)]]) - 1
    for k in range(len(starts) - 1):
        i0 = idx[ends[k]]
        i1 = idx[starts[k + 1]]
        p0, p1 = int(label[i0]), int(label[i1])
        if p0 == p1 or p0 not in gravity or p1 not in gravity:
            continue
        if part is not None and part[i0] != part[i1]:
            continue
        if np.any(label[i0 + 1:i1] >= 1) or np.any(label[i0 + 1:i1] < 0):
            continue
        s = seq[i0:i1 + 1]
        if np.any(np.diff(s) != 1):
            continue
        tt = t[i0:i1 + 1]
        dt = np.diff(tt) if np.all(np.isfinite(tt)) else np.full(i1 - i0, 1.0 / rate_hz)
        if np.any(dt <= 0) or dt.sum() > MAX_MOVE_S:
            continue
        w = w_dps[i0:i1 + 1]
        if np.isnan(w).any() or np.any(np.abs(raw_gyro[i0:i1 + 1]) >= GYRO_CLIP_COUNTS):
            continue
        moves.append(Move(gravity[p0], gravity[p1], w, dt, p0, p1))
    return moves


def _qmul(p, q):
    w1, x1, y1, z1 = np.moveaxis(p, -1, 0)
    w2, x2, y2, z2 = np.moveaxis(q, -1, 0)
    return np.stack([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
                     w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                     w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2], axis=-1)


def _rotvec_quat(rv):
    ang = np.linalg.norm(rv, axis=-1, keepdims=True)
    half = 0.5 * ang
    k = np.where(ang > 1e-12, np.sin(half) / np.where(ang > 0, ang, 1.0), 0.5)
    return np.concatenate([np.cos(half), rv * k], axis=-1)


def _rotate_inv(q, a):
    """Vectors a (n, 3) rotated by the inverse of the unit quaternions q (n, 4)."""
    w, v = q[:, :1], q[:, 1:]
    t = 2.0 * np.cross(v, a)
    return a - w * t + np.cross(v, t)


class MoveSet:
    """All moves padded to one array so a rotation is integrated for every
    move at once (pairwise product tree over the samples)."""

    def __init__(self, moves: list[Move]):
        self.moves = moves
        L = max(len(m.dt) for m in moves)
        self.L = 1 << int(np.ceil(np.log2(max(L, 1))))
        n = len(moves)
        self.wm = np.zeros((n, self.L, 3))     # trapezoid mean raw rate per step
        self.dt = np.zeros((n, self.L))
        for i, m in enumerate(moves):
            k = len(m.dt)
            self.wm[i, :k] = 0.5 * (m.w[1:] + m.w[:-1])
            self.dt[i, :k] = m.dt
        self.a0 = np.array([m.a0 for m in moves])
        self.a1 = np.array([m.a1 for m in moves])

    def rotations(self, G, b):
        """Body rotation over each move (quaternion, body_start -> body_end)."""
        rate = (self.wm - b) @ G.T                           # deg/s, padded rows: ignored by dt=0
        rv = np.deg2rad(rate) * self.dt[..., None]
        q = _rotvec_quat(rv)                                 # (n, L, 4)
        while q.shape[1] > 1:                                # ordered product q1 q2 ... qL
            q = _qmul(q[:, 0::2], q[:, 1::2])
        return q[:, 0]

    def residuals(self, G, b):
        # gravity (fixed in the world) seen from the body after the move: R^T a0
        return (_rotate_inv(self.rotations(G, b), self.a0) - self.a1).ravel()

    def direction_jacobian(self, G, b, dirs: dict) -> np.ndarray:
        """d residuals / d phi (3 n_moves, q) for pose gravity directions that
        depend on parameters phi: ``dirs`` maps a pose to d a_pose / d phi
        (3, q).  A residual is R^T a0 - a1, linear in both directions."""
        q = self.rotations(G, b)
        out = []
        for k, m in enumerate(self.moves):
            D0, D1 = dirs[m.pose0], dirs[m.pose1]
            out.append(_rotate_inv(np.repeat(q[k:k + 1], D0.shape[1], axis=0), D0.T).T - D1)
        return np.vstack(out)


@dataclass
class MatrixFit:
    G: np.ndarray                 # 3x3
    std: np.ndarray               # (3, 3), every source below
    rms_before: float             # rms direction error (rad) with G = I
    rms_after: float
    n_moves: int
    rank: int
    nfev: int
    std_parts: dict = field(default_factory=dict)   # (3, 3) per source: moves, accel, bias


def _psd(C):
    """Nearest positive semi-definite matrix (negative eigenvalues set to 0)."""
    C = 0.5 * (C + C.T)
    w, V = np.linalg.eigh(C)
    return (V * np.maximum(w, 0.0)) @ V.T


def fit_matrix_robust(moves: list[Move], b: np.ndarray, **kw) -> tuple[MatrixFit, np.ndarray]:
    """``fit_matrix`` on the moves whose residual (the gravity direction
    error after the fit, every component) is within ``robust.REJECT_SD``
    robust sd of the median, refitted until the moves set aside no longer
    change: a move with a glitch or a knock in it integrates to a rotation
    off by far more than the others.  Returns (fit, kept per move)."""
    keep = np.ones(len(moves), bool)
    mf = fit_matrix(moves, b, **kw)
    for _ in range(MAX_CONCENTRATE):
        r = MoveSet(moves).residuals(mf.G, b).reshape(len(moves), 3)
        ok = inliers(r.ravel()).reshape(-1, 3).all(axis=1)
        if np.array_equal(ok, keep) or ok.sum() < max(MIN_MOVES, 9):
            break
        keep = ok
        mf = fit_matrix([m for m, k in zip(moves, keep) if k], b, **kw)
    return mf, keep


def fit_matrix(moves: list[Move], b: np.ndarray, *, b_cov=None, dirs=None,
               dirs_cov=None) -> MatrixFit:
    """G (3x3) from the moves, bias b fixed; Gauss-Newton/LM from G = I.

    Its covariance adds up what the fit's errors come from:

    * the moves: a sandwich ``B M B`` (``B = (J^T J)^+``) whose middle sums
      ``s_k s_l^T`` (``s_k = J_k^T r_k``, the score of move k) over every pair
      of moves that share a pose -- two moves with a pose between them share
      its measured gravity direction, so their errors are correlated -- scaled
      by ``n / (n - 9)`` for n moves;
    * the gravity directions, which come from the accelerometer's calibration:
      ``dirs`` maps each pose to d a_pose / d phi (3, q) for the accelerometer
      parameters phi, with covariance ``dirs_cov`` (q, q); G moves by
      ``-B J^T J_phi`` per unit of phi;
    * the bias b (covariance ``b_cov``), held fixed in the fit.
    """
    from .identify import analyse
    ms = MoveSet(moves)

    def fun(x):
        return ms.residuals(x.reshape(3, 3), b)

    x0 = np.eye(3).ravel()
    r0 = fun(x0)
    res = least_squares(fun, x0, method="lm", x_scale=1.0)
    G = res.x.reshape(3, 3)
    J = res.jac
    ident = analyse(J, [f"G_{i}{j}" for i in "xyz" for j in "xyz"])
    B = ident.cov_unit                                      # (J^T J)^+
    n = len(moves)
    Jk = J.reshape(n, 3, 9)
    scores = np.einsum("kij,ki->kj", Jk, res.fun.reshape(n, 3))
    poses, inv = np.unique([(m.pose0, m.pose1) for m in moves], return_inverse=True)
    S = np.zeros((n, len(poses)))                         # move k touches pose p
    S[np.repeat(np.arange(n), 2), inv.ravel()] = 1.0
    A = (S @ S.T) > 0                                     # moves k, l share a pose (k = l too)
    M = scores.T @ A @ scores
    parts = {"moves": _psd(B @ M @ B) * n / max(1, n - ident.rank)}
    if dirs is not None and dirs_cov is not None:
        Kphi = -B @ J.T @ ms.direction_jacobian(G, b, dirs)
        parts["accel"] = Kphi @ np.asarray(dirs_cov, float) @ Kphi.T
    if b_cov is not None:
        h = 1e-4
        Jb = np.column_stack([(ms.residuals(G, b + h * e) - ms.residuals(G, b - h * e)) / (2 * h)
                              for e in np.eye(3)])
        Kb = -B @ J.T @ Jb
        parts["bias"] = Kb @ np.asarray(b_cov, float) @ Kb.T
    cov = sum(parts.values())
    std = np.where(ident.identifiable, np.sqrt(np.maximum(np.diag(cov), 0.0)), np.nan)
    std_parts = {k: np.sqrt(np.maximum(np.diag(v), 0.0)).reshape(3, 3) for k, v in parts.items()}
    return MatrixFit(G, std.reshape(3, 3), float(np.sqrt(np.mean(r0 ** 2) * 3)),
                     float(np.sqrt(np.mean(res.fun ** 2) * 3)), n, ident.rank, res.nfev,
                     std_parts)
