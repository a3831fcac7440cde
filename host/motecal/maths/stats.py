"""Noise statistics shared by the report and the diagnosis (pure numpy).

``allan_deviation``: the overlapping Allan deviation of a rate signal (e.g. a
still gyroscope, deg/s), pooled over several runs.  With the integrated
signal theta_i = sum_{j < i} x_j / rate and an averaging time tau = m / rate,

    sigma^2(tau) = sum over runs and i of (theta_{i+2m} - 2 theta_{i+m} + theta_i)^2
                   / (2 tau^2 * number of terms),

every i of every run long enough for m (at least 2m + 1 samples).  White rate
noise falls as tau^-1/2 (its value at 1 s is the angle random walk), a rate
random walk rises as tau^+1/2.
"""
from __future__ import annotations

import numpy as np


def allan_deviation(runs, rate_hz: float, m=None, n_tau: int = 30):
    """Overlapping Allan deviation pooled over ``runs``, a list of (n_i, k) or
    (n_i,) rate arrays sampled at ``rate_hz``.

    ``m``: the cluster sizes (samples per average) to evaluate; default
    ``n_tau`` log-spaced sizes from 1 up to a quarter of the longest run (at
    least two independent averages; longer taus are mostly noise).  Sizes no
    run is long enough for are left out.  Returns ``(tau (T,), adev (T, k),
    terms (T,))``: the averaging times (s), the deviation per column, and how
    many second differences each rests on."""
    runs = [np.asarray(r, float) for r in runs]
    runs = [r[:, None] if r.ndim == 1 else r for r in runs]
    runs = [r for r in runs if len(r) >= 3]
    if not runs:
        return np.zeros(0), np.zeros((0, 3)), np.zeros(0, int)
    k = runs[0].shape[1]
    if m is None:
        m_max = max(1, (max(len(r) for r in runs) - 1) // 4)
        m = np.unique(np.round(np.logspace(0, np.log10(m_max), n_tau)).astype(int))
    ms = [int(v) for v in np.atleast_1d(m) if v >= 1]
    thetas = [np.vstack([np.zeros((1, k)), np.cumsum(r, axis=0)]) / rate_hz for r in runs]
    taus, adev, terms = [], [], []
    for mm in ms:
        tau = mm / rate_hz
        s = np.zeros(k)
        cnt = 0
        for th in thetas:
            if len(th) < 2 * mm + 1:
                continue
            d = th[2 * mm:] - 2 * th[mm:-mm] + th[:-2 * mm]
            s += (d * d).sum(axis=0)
            cnt += len(d)
        if cnt == 0:
            continue
        taus.append(tau)
        adev.append(np.sqrt(s / (2 * tau * tau * cnt)))
        terms.append(cnt)
    return np.array(taus), np.array(adev).reshape(-1, k), np.array(terms, int)
