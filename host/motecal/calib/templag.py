"""The lag of a chip behind the temperature the session records (issue 26,
item 5): the ITG3200 reads its own die (TEMP_OUT), the ADXL345 and the
HMC5883L follow the board through packages of their own, so during a
warm-up their dies lag that reading by seconds to tens of seconds.

``lag_filter`` gives a chip's temperature from the recorded one for a time
constant: a first-order lag, dy/dt = (T - y) / lag, at the first reading
when a recording starts (the chips at one temperature at power-on), exact
for a temperature linear between samples.  ``choose_lag`` is how
``calib.thermal`` decides on it: the sensor's temperature term is fitted
against the lagged temperature for each time constant of ``LAGS_S`` and
the best one refined; a lag is used only when it predicts held-out blocks
better than none by more than ``Z_ACCEPT`` standard errors (the blocks in
groups of ``GROUP`` consecutive ones, so that neighbouring blocks' shared
errors are not counted as independent).  The gyroscope reads the die the
temperature comes from: it gets no lag.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import minimize_scalar
from scipy.signal import lfilter, lfilter_zi

from .extra_terms import Z_ACCEPT

LAGS_S = (0.0, 4.0, 8.0, 16.0, 32.0, 60.0)    # time constants tried (s)
LAG_MAX_S = 60.0            # a package's lag is seconds to tens of seconds: no longer
GRID_S = 0.1                # the recorded temperature is filtered on this grid
GROUP = 1                   # consecutive held-out observations judged together
SENSORS = ("accel", "mag")  # the chips that lag the ITG3200's die


def lag_filter(temp, t, lag_s: float, part=None) -> np.ndarray:
    """The temperature of a chip that follows the recorded ``temp`` (per row,
    at times ``t`` in s) through a first-order lag of ``lag_s``; each
    recording (``part`` per row) starts at its first reading; NaN readings
    are bridged (linear in time), rows of a recording without any stay NaN.
    ``lag_s`` <= 0 gives ``temp`` unchanged."""
    temp = np.asarray(temp, float)
    if lag_s <= 0 or not len(temp):
        return temp.copy()
    t = np.asarray(t, float)
    part = np.zeros(len(temp), np.int64) if part is None else np.asarray(part)
    out = np.full(len(temp), np.nan)
    a = np.exp(-GRID_S / lag_s)
    wb = 1.0 / (1.0 - a) - lag_s / GRID_S            # weight of the newer grid point
    b = np.array([(1 - a) * wb, (1 - a) * (1 - wb)])
    for p in np.unique(part):
        rows = np.flatnonzero(part == p)
        ok = rows[np.isfinite(temp[rows]) & np.isfinite(t[rows])]
        if not len(ok):
            continue
        order = ok[np.argsort(t[ok], kind="stable")]
        tk, Tk = t[order], temp[order]
        grid = np.arange(tk[0], tk[-1] + GRID_S, GRID_S)
        Tg = np.interp(grid, tk, Tk)
        yg, _ = lfilter(b, [1.0, -a], Tg, zi=lfilter_zi(b, [1.0, -a]) * Tg[0])
        tr = t[rows]
        out[rows] = np.where(np.isfinite(tr), np.interp(tr, grid, yg), np.nan)
    return out


def _groups(n_per_set) -> np.ndarray:
    """Group of each observation: GROUP consecutive ones within a set."""
    out, base = [], 0
    for n in n_per_set:
        g = np.arange(n) // GROUP
        out.append(base + g)
        base += int(g.max()) + 1 if n else 0
    return np.concatenate(out) if out else np.zeros(0, np.int64)


def paired_z(e0: np.ndarray, e1: np.ndarray, groups: np.ndarray) -> float:
    """How many standard errors the held-out squared error falls from ``e0``
    to ``e1`` (the same observations), over groups of observations."""
    d = e0 ** 2 - e1 ** 2
    ok = np.isfinite(d)
    if not ok.any():
        return float("nan")
    g = np.unique(groups[ok], return_inverse=True)[1]
    s = np.bincount(g, weights=d[ok])
    if len(s) < 3:
        return float("nan")
    se = np.std(s, ddof=1) / np.sqrt(len(s))
    return float(np.mean(s) / se) if se > 0 else float("inf") * np.sign(np.mean(s))


def choose_lag(fit_at) -> dict:
    """The lag to use, from ``fit_at(lag_s) -> res`` (``thermal.fit_sensor``'s
    result for the temperature lagged by ``lag_s``, with ``heldout_errors``
    and ``heldout_sizes``).  ``{"lag_s", "res" (the fit at it), "tried":
    {lag: held-out rms}, "z", "why"}``; ``lag_s`` 0 unless a lag beats none
    by ``Z_ACCEPT`` standard errors."""
    cache = {}

    def at(lag):
        lag = float(round(lag, 2))
        if lag not in cache:
            cache[lag] = fit_at(lag)
        return cache[lag]

    def score(lag):
        r = at(lag)
        return r["heldout_rms_after"] if r.get("why") is None else np.inf

    base = at(0.0)
    out = {"lag_s": 0.0, "res": base, "z": None}
    if base.get("why") is not None:
        out["why"] = "no temperature term without a lag to compare with"
        out["tried"] = {0.0: None}
        return out
    scores = [score(lag) for lag in LAGS_S]
    i = int(np.argmin(scores))
    best = LAGS_S[i]
    if i > 0:
        lo = LAGS_S[i - 1]
        hi = LAGS_S[i + 1] if i + 1 < len(LAGS_S) else LAG_MAX_S
        r = minimize_scalar(score, bounds=(lo, hi), method="bounded",
                            options={"xatol": 0.05 * best, "maxiter": 8})
        if np.isfinite(r.fun) and r.fun < scores[i]:
            best = float(round(r.x, 2))
    out["tried"] = {k: (v if np.isfinite(v) else None) for k, v in
                    sorted((k, score(k)) for k in cache)}
    if best == 0.0:
        out["why"] = "no lag predicts held-out blocks better than none"
        return out
    if best >= 0.95 * LAG_MAX_S:
        out["why"] = (f"the best lag is the longest tried ({best:g} s): something slower than "
                      "a package's lag (a drift, a bend with temperature), not a lag")
        return out
    cand = at(best)
    e0, e1 = base["heldout_errors"], cand["heldout_errors"]
    if len(e0) != len(e1) or base["heldout_sizes"] != cand["heldout_sizes"]:
        out["why"] = f"the lag of {best:g} s changes which data can be used"
        return out
    z = paired_z(e0, e1, _groups(base["heldout_sizes"]))
    out["z"] = z
    if not z > Z_ACCEPT:
        out["why"] = (f"the best lag, {best:g} s, predicts held-out blocks better by "
                      f"{z:+.1f} standard errors only (at least {Z_ACCEPT:g})")
        return out
    out.update(lag_s=best, res=cand, why=None)
    return out
