"""The gyroscope's still blocks with the board's own turn taken out: a hand
holding a board still has tremor, and a hold's mean rate then carries the
net turn of the tremor over the hold (a few tenths of a degree over 1-2 s:
0.1-0.3 deg/s, many times the noise of the mean), which reads as a bias that
moves from hold to hold (a false drift, a g-sensitivity lost in it).

The accelerometer and magnetometer see that turn: a small rotation phi of
the board moves a fixed world vector v (gravity, the field) in the body
frame by dv = v x phi.  The gyroscope draws the turn's path itself, bias
included: theta(t), its integrated rate.  So per block every reading of
the two (calibrated, unit directions u_k) is fitted as
u_k = c + [u0]x (theta(t_k) - b (t_k - tm)), with a constant c per sensor
and the bias b unknown, by weighted least squares (a complementary
smoother over the block: the gyroscope gives the shape of the tremor, the
directions where it leads).  Gravity shows the turn across itself, the field
the turn about gravity.  Using the whole path rather than the directions at
the block's two ends, and the hold's edges beyond the still stretch, is what makes the estimate
useful: a slope over T is known as T^-1.5.  An unlabelled session's still
stretches are cut well inside the holds (1.1 of 1.7 s in the bench's fast
hand sessions): the accelerometer's span is widened while the gyroscope's
turn from the block's end stays within the turn the tremor made inside
the block, less ``BACK_S`` (the accelerometer reads a move's own
acceleration -- the sensor sits off the turning point: angular acceleration
times the lever arm -- from the move's first instant, before the board has
turned by a tenth of a degree); the magnetometer, which feels no
acceleration, is followed further, into the moves' first degrees
(``MAG_EXTEND_DEG``).  The
estimate's variance (the gyroscope's white noise, plus the directions'
noise through the least squares, scaled by the paths' own leftovers)
replaces the block mean's, so the tests downstream weigh each block by what
it is known to; a block too short to be measured is left out (NaN variance)
rather than trusted with its tremor inside.

Used by the diagnosis when the board moved inside its still segments (the
``motion`` screen kept): otherwise the plain block mean is the better
estimate (the directions' noise costs about 2x the variance)."""
from __future__ import annotations

import dataclasses

import numpy as np

from .prepare import SensorObs

MIN_ROWS = 20            # readings of a reference sensor a block needs
MIN_PATH_S = 0.5         # shorter blocks: no turn measured, left out
EXTEND_S = 0.5           # a block's accelerometer span reaches at most this far into the
                         # neighbouring moving readings (a still stretch is cut 0.2-0.3 s
                         # inside its hold: the stillness is judged over windows) ...
BACK_S = 0.05            # ... and stops this long before the board leaves the tremor's reach
MAG_EXTEND_S = 0.8       # the magnetometer's readings are used further, into the moves' first
MAG_EXTEND_DEG = 3.0     # degrees: it feels no acceleration (the accelerometer reads the
                         # moves' own, a lever arm times the angular acceleration)
NW_LAGS = 16           # readings (0.13 s at 125 Hz) over which leftovers may be correlated
MAX_CHI2 = 4.0          # the sensors' turns must agree (median chi-square per dof of the blocks)


def _skew(v):
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def _gyro_turn(gyr: SensorObs, t0: float, t1: float):
    """The gyroscope's integrated rate (rad, bias included) over [t0, t1]:
    (times, (n, 3) turn from t0), or None if too few readings."""
    sel = np.flatnonzero((gyr.t >= t0) & (gyr.t <= t1))
    if len(sel) < 10:
        return None
    tg = gyr.t[sel]
    w = gyr.x[sel] / gyr.K
    # the rate is an instantaneous reading: trapezoids (a rectangle rule
    # delays the turn by half a sample, which matters where the board turns)
    th = np.zeros_like(w)
    th[1:] = np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(tg)[:, None], axis=0)
    return tg, np.radians(th)


def _path_bias(gyr: SensorObs, refs: list, t0: float, t1: float, spans: dict | None = None):
    """The gyro's bias over [t0, t1] from the whole path: every reading of
    the reference sensors (calibrated directions u_k) against the gyro's
    integrated turn theta(t) less the bias b: u_k = c + [u0]x (theta(t_k) -
    b (t_k - tm)), with a constant c per sensor and b (rad/s) unknown,
    solved by weighted least squares.  ``spans``: a narrower time span per
    sensor name (the accelerometer's, where the board did not move).  Returns (b rad/s, its covariance
    from the directions, sum of squared weighted residuals, their degrees
    of freedom, the time span) or None."""
    g = _gyro_turn(gyr, t0, t1)
    if g is None:
        return None
    tg, theta = g
    cols, ys, ws, nref = [], [], [], 0
    tm = 0.5 * (t0 + t1)
    rows_b = []
    for r, cal in refs:
        a, z = (spans or {}).get(r.sensor, (t0, t1))
        sel = np.flatnonzero((r.t >= a) & (r.t <= z) & ~r.overflow)
        if len(sel) < MIN_ROWS:
            continue
        m = np.asarray(cal(r.x[sel], r.t[sel]), float)
        L = np.linalg.norm(m, axis=1)
        Lr = float(np.linalg.norm(r.x[sel].mean(axis=0)))
        if not (np.all(L > 0) and Lr > 0):
            continue
        u = m / L[:, None]
        u0 = u.mean(axis=0)
        u0 /= np.linalg.norm(u0)
        th = np.column_stack([np.interp(r.t[sel], tg, theta[:, a]) for a in range(3)])
        S = _skew(u0)
        y = u - th @ S.T                      # u - [u0]x theta = c - [u0]x b (t - tm)
        dt = r.t[sel] - tm
        var = float(np.mean(r.sigma ** 2)) / Lr ** 2
        for j in range(3):
            ys.append(y[:, j])
            ws.append(np.full(len(sel), 1.0 / var))
            cols.append((nref, j, len(sel)))
            rows_b.append(-S[j][None, :] * dt[:, None])
        nref += 1
    if not nref:
        return None
    n = sum(c[2] for c in cols)
    A = np.zeros((n, 3 * nref + 3))
    k = 0
    for (ri, j, m), rb in zip(cols, rows_b):
        A[k:k + m, 3 * ri + j] = 1.0
        A[k:k + m, 3 * nref:] = rb
        k += m
    y = np.concatenate(ys)
    w = np.concatenate(ws)
    N = A.T @ (A * w[:, None])
    if np.linalg.cond(N) > 1e12:
        return None
    cov = np.linalg.inv(N)
    beta = cov @ (A.T @ (w * y))
    e = y - A @ beta
    # a unit direction moves only across itself: of each reading's three
    # components two carry noise (the one along u0 is ~0 to first order),
    # and of each sensor's constant two are fitted to it
    dof = 2 * (n // 3) - 2 * nref - 3
    cb = cov[3 * nref:, 3 * nref:]
    if np.linalg.cond(cb) > 1e8:
        return None
    # readings' leftovers about the turn are correlated over short lags (the
    # sensors' filters, the tremor seen a little apart in time): the
    # long-run variance of the leftovers, per series (Bartlett weights)
    ew = e * np.sqrt(w)
    ac = np.zeros(NW_LAGS + 1)
    k = 0
    for (ri, j, m) in cols:
        x = ew[k:k + m]
        k += m
        for lag in range(NW_LAGS + 1):
            ac[lag] += float(x[lag:] @ x[:len(x) - lag]) if lag < len(x) else 0.0
    return beta[3 * nref:], cb, float(e @ (w * e)), max(1, dof), float(tg[-1] - tg[0]), ac


def _walk(gyr: SensorObs, end: int, step: int, rate_mean: np.ndarray, reach_deg: float,
          reach_s: float) -> int:
    """The last moving reading from ``end`` in direction ``step`` (-1 or +1)
    whose turn from ``end`` (the gyroscope less ``rate_mean``) stays within
    ``reach_deg`` and whose time within ``reach_s``; ``end`` if none."""
    k = end
    ang = np.zeros(3)
    while True:
        j = k + step
        if j < 0 or j >= gyr.n or not gyr.moving[j] or abs(gyr.t[j] - gyr.t[end]) > reach_s:
            return k
        ang = ang + (gyr.x[j] - rate_mean) / gyr.K * abs(gyr.t[j] - gyr.t[k])
        if float(np.linalg.norm(ang)) > reach_deg:
            return k
        k = j


def _extended(gyr: SensorObs, rows: np.ndarray, rate_mean: np.ndarray,
              reach_s: float = MAG_EXTEND_S, reach_deg: float = MAG_EXTEND_DEG):
    """The block's time span for the magnetometer, widened over the
    neighbouring moving readings while the board stays within ``reach_deg``
    of its orientation at the block's end (the gyroscope's integrated turn,
    less the block's mean rate as its rough bias), at most ``reach_s`` each
    way: the slope that gives the bias is known as T^-1.5, and the small-angle
    model holds to a few degrees."""
    t0, t1 = float(gyr.t[rows[0]]), float(gyr.t[rows[-1]])
    if gyr.moving is None or reach_s <= 0:
        return t0, t1
    out = []
    for end, step in ((rows[0], -1), (rows[-1], 1)):
        k = _walk(gyr, end, step, rate_mean, reach_deg, reach_s)
        out.append(float(gyr.t[k]))
    return out[0], out[1]


def _still_span(gyr: SensorObs, rows: np.ndarray, rate_mean: np.ndarray,
                back_s: float = BACK_S, reach_s: float = EXTEND_S):
    """The hold's still span around a block: widened over the neighbouring
    moving readings while the gyroscope's turn from the block's end stays
    within the turn the tremor made inside the block, then pulled back by
    ``back_s`` (a move's acceleration starts before its turn leaves the
    tremor's reach)."""
    t0, t1 = float(gyr.t[rows[0]]), float(gyr.t[rows[-1]])
    if gyr.moving is None or reach_s <= 0:
        return t0, t1
    out = []
    for end, step in ((rows[0], -1), (rows[-1], 1)):
        # the tremor's reach inside the block, seen from this end
        inner = rows[::-step]
        dt_in = np.abs(np.diff(gyr.t[inner], prepend=gyr.t[inner[0]]))
        path = np.cumsum((gyr.x[inner] - rate_mean) / gyr.K * dt_in[:, None], axis=0)
        reach = float(np.max(np.linalg.norm(path, axis=1)))
        k = _walk(gyr, end, step, rate_mean, reach, reach_s)
        te = float(gyr.t[k]) - step * back_s
        out.append(min(te, t0) if step < 0 else max(te, t1))
    return out[0], out[1]


def turn_corrected(gyr: SensorObs, refs: list) -> SensorObs | None:
    """A copy of ``gyr`` whose block means are the bias over each block with
    the board's turn (measured by the sensors ``refs``: (observations,
    calibration) of the accelerometer and magnetometer, the calibration a
    function (counts, t) -> calibrated vectors) taken out, with each block's
    variance; None when no block can be corrected (then the caller keeps the
    plain means)."""
    refs = [(r, c) for r, c in refs if r is not None and r.n >= 10]
    b = gyr.blocks
    if b is None or not refs or not len(b):
        return None
    sols = {}
    for i, rows in enumerate(b.rows):
        t0, t1 = _still_span(gyr, rows, b.mean[i])
        if t1 - t0 < MIN_PATH_S:
            continue
        m0, m1 = _extended(gyr, rows, b.mean[i])
        m0, m1 = min(m0, t0), max(m1, t1)
        sol = _path_bias(gyr, refs, m0, m1, {"accel": (t0, t1)})
        if sol is not None:
            sols[i] = sol
    if not sols:
        return None
    # the directions' noise from the paths' own leftovers (pooled over the
    # blocks): a reading's noise about the turn the gyroscope drew
    rss = sum(s[2] for s in sols.values())
    dof = sum(s[3] for s in sols.values())
    ac = sum(s[5] for s in sols.values())
    lags = np.arange(1, NW_LAGS + 1)
    kappa = 1.0
    if ac[0] > 0:
        kappa = max(1.0, 1.0 + 2.0 * float(np.sum((1.0 - lags / (NW_LAGS + 1.0)) * ac[1:] / ac[0])))
    scale = rss / dof * kappa
    chi2 = [s[2] / s[3] for s in sols.values()]
    if float(np.median(chi2)) > MAX_CHI2:
        return None          # the sensors disagree with the gyroscope about the turn
    # a block whose turn cannot be measured keeps the tremor's turn in its
    # mean: it is left out (NaN variance), not trusted as a still block
    mean = b.mean.copy()
    var = np.full(b.mean.shape, np.nan)
    K = gyr.K
    for i, (bb, cb, _, _, T, _) in sols.items():
        mean[i] = np.degrees(bb) * K
        # gyro white noise: the slope of its integral over T (6/5 of a mean's)
        var[i] = 1.2 * gyr.sigma ** 2 / (T * gyr.rate) + \
            scale * np.degrees(np.sqrt(np.diag(cb))) ** 2 * K ** 2
    blocks = dataclasses.replace(b, mean=mean, var=var)
    out = dataclasses.replace(gyr, blocks=blocks)
    out.turn_corrected = len(sols)
    out.turn_left_out = len(b) - len(sols)
    return out
