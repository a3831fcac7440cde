"""The gyroscope's still blocks with the board's own turn taken out: a hand
holding a board still has tremor, and a hold's mean rate then carries the
net turn of the tremor over the hold (a few tenths of a degree over 1-2 s:
0.1-0.3 deg/s, many times the noise of the mean), which reads as a bias that
moves from hold to hold (a false drift, a g-sensitivity lost in it).

The accelerometer and magnetometer see that turn: a small rotation phi of
the board moves a fixed world vector v (gravity, the field) in the body
frame by dv = v x phi.  Per block, the mean directions over ``END_S`` at its
start and end give phi by weighted least squares (gravity shows the turn
across it, the field the turn about gravity), and the gyroscope's bias over
the block is its integrated rate between the same two windows less phi,
over the time between them.  The estimate's variance (gyro white noise plus
the directions' noise through the least squares) replaces the block mean's,
so the tests downstream weigh each block by what it is known to.

Used by the diagnosis when the board moved inside its still segments (the
``motion`` screen kept): otherwise the plain block mean is the better
estimate (the directions' noise costs about 2x the variance)."""
from __future__ import annotations

import dataclasses

import numpy as np

from .prepare import SensorObs

END_S = 0.25            # the direction at a block's start and end: mean over this long
MIN_END_ROWS = 5
MAX_CHI2 = 4.0          # the sensors' turns must agree (median chi-square per dof of the blocks)


def _end_means(o: SensorObs, cal, t0: float, t1: float):
    """Mean unit direction (calibrated by ``cal``) and mean time of ``o``'s
    readings in [t0, t1], and the variance of each component of that
    direction; None if too few."""
    sel = np.flatnonzero((o.t >= t0) & (o.t <= t1) & ~o.overflow)
    if len(sel) < MIN_END_ROWS:
        return None
    raw = o.x[sel].mean(axis=0)
    m = np.asarray(cal(raw[None, :], o.t[sel][:1]), float)[0]
    L = float(np.linalg.norm(m))
    Lr = float(np.linalg.norm(raw))
    if not (L > 0 and Lr > 0):
        return None
    var = float(np.mean(o.sigma ** 2)) / len(sel) / Lr ** 2
    return m / L, float(o.t[sel].mean()), var


def _skew(v):
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


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
    mean = b.mean.copy()
    var = gyr.var_of_mean(b.n).copy()
    K = gyr.K
    done = 0
    chi2 = []
    for i, rows in enumerate(b.rows):
        t0, t1 = gyr.t[rows[0]], gyr.t[rows[-1]]
        if t1 - t0 < 4 * END_S:
            continue
        A, y, w = [], [], []
        for r, cal in refs:
            e0 = _end_means(r, cal, t0, t0 + END_S)
            e1 = _end_means(r, cal, t1 - END_S, t1)
            if e0 is None or e1 is None:
                continue
            (u0, _, v0), (u1, _, v1) = e0, e1
            A.append(_skew(u0))            # u1 - u0 = u0 x phi = [u0]x phi
            y.append(u1 - u0)
            w.append(np.full(3, 1.0 / (v0 + v1)))
        if not A:
            continue
        A, y, w = np.vstack(A), np.concatenate(y), np.concatenate(w)
        N = A.T @ (A * w[:, None])
        if np.linalg.cond(N) > 1e8:
            continue
        cov = np.linalg.inv(N)
        phi = cov @ (A.T @ (w * y))                           # rad, body frame
        if len(y) > 3:
            e = y - A @ phi
            chi2.append(float(e @ (w * e)) / (len(y) - 3))
        # the gyro's turn between the same windows: its integrated rate,
        # averaged over each window (the directions are window averages too)
        sel = np.flatnonzero((gyr.t >= t0) & (gyr.t <= t1))
        if len(sel) < 10:
            continue
        tg = gyr.t[sel]
        dt = np.diff(tg, prepend=tg[0])
        theta = np.cumsum(gyr.x[sel] / K * dt[:, None], axis=0)      # deg, bias included
        w0, w1 = tg <= t0 + END_S, tg >= t1 - END_S
        if w0.sum() < MIN_END_ROWS or w1.sum() < MIN_END_ROWS:
            continue
        T = float(tg[w1].mean() - tg[w0].mean())
        if not T > 0:
            continue
        turn = theta[w1].mean(axis=0) - theta[w0].mean(axis=0)
        bias = (turn - np.degrees(phi)) / T                           # deg/s
        mean[i] = bias * K
        var[i] = gyr.sigma ** 2 / (T * gyr.rate) + \
            np.degrees(np.sqrt(np.diag(cov))) ** 2 / T ** 2 * K ** 2
        done += 1
    if not done:
        return None
    if chi2 and float(np.median(chi2)) > MAX_CHI2:
        return None          # the two sensors disagree about the turn (their frames?)
    blocks = dataclasses.replace(b, mean=mean, var=var)
    out = dataclasses.replace(gyr, blocks=blocks)
    out.turn_corrected = done
    return out
