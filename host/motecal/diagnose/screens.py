"""Detectors that look at the raw readings rather than at a calibration fit:
repeated readings (``stale_samples``), readings piled up at a range limit
(``saturation``) and poses that were not still (``motion``).  Each returns a
``Screen`` with a p-value under the starting model (white noise, no repeats,
no clipping, a still board), the evidence numbers, the fitted simulator
parameters and per-block statistics for the held-out gain.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from ..sessions.session import CHIP_LIMITS, HMC5883L_OVERFLOW, INT16_MAX
from .prepare import SensorObs, unique_updates

# practical floors: below these an effect is not reported even when significant
STALE_MIN_EXCESS = 0.02        # repeated-reading fraction above chance
SAT_MIN_COUNT = 10             # readings at an arbitrary limit
SAT_MIN_COUNT_FULL_SCALE = 3   # readings at a chip's full-scale code
# the chips' range ends, -32767 (an int16 clipped symmetrically) and the overflow code
FULL_SCALE_CODES = tuple(sorted({float(v) for lo, hi in CHIP_LIMITS.values() for v in (lo, hi)}
                                | {float(-INT16_MAX), float(HMC5883L_OVERFLOW)}))
MOTION_SLOPE = (0.3, 3.0)      # a real turn moves the accelerometer ~1x the gyro's prediction
SAT_MIN_RATIO = 4.0            # count at the limit / mean count of the 20 values inside it
SAT_NEIGHBOURS = 20
MOTION_LAG_S = 0.064           # accelerometer change over this lag is compared with the gyro's
MOTION_LAGS_S = (MOTION_LAG_S, 0.256)   # ... and over this one (slow tremor; Bonferroni over both)


@dataclass
class Screen:
    sensor: str
    cause: str
    p: float                        # p-value under the starting model
    effect: float                   # size in the cause's own unit (see evidence)
    evidence: dict
    params: dict                    # simulator term parameters
    # held-out gain: per block, the measured statistic and its prediction
    # before (starting model) and after (with the fitted term, from other blocks)
    block_stat: np.ndarray = field(default_factory=lambda: np.zeros(0))
    pred_before: np.ndarray = field(default_factory=lambda: np.zeros(0))
    pred_after: np.ndarray = field(default_factory=lambda: np.zeros(0))
    gain_unit: str = ""
    practical: bool = True          # above the practical floor

    fixed_gain: tuple | None = None     # (gain, rms before, rms after) measured elsewhere

    def gain(self) -> float | None:
        if self.fixed_gain is not None:
            return self.fixed_gain[0]
        if not len(self.block_stat):
            return None
        b = np.sqrt(np.mean((self.block_stat - self.pred_before) ** 2))
        a = np.sqrt(np.mean((self.block_stat - self.pred_after) ** 2))
        if a <= 0:
            return float("inf") if b > 0 else 1.0
        return float(b / a)

    def rms(self):
        if self.fixed_gain is not None:
            return self.fixed_gain[1], self.fixed_gain[2]
        if not len(self.block_stat):
            return None, None
        return (float(np.sqrt(np.mean((self.block_stat - self.pred_before) ** 2))),
                float(np.sqrt(np.mean((self.block_stat - self.pred_after) ** 2))))


def _chunks(obs: SensorObs, seconds: float = 4.0, still: bool = True) -> list[np.ndarray]:
    """Row groups for per-block statistics: the time blocks of still segments
    (``still``), or consecutive stretches of about ``seconds`` (same
    recording)."""
    if still and obs.blocks is not None and len(obs.blocks) >= 4:
        return [g for g in obs.blocks.rows if len(g) > 4]
    n = max(8, int(round(seconds * obs.rate)))
    out = []
    for p in np.unique(obs.part):
        idx = np.flatnonzero((obs.part == p) & ~obs.overflow)
        for i in range(0, len(idx), n):
            g = idx[i:i + n]
            if len(g) > 4:
                out.append(g)
    return out


def _folds(k: int, nfold: int = 2) -> np.ndarray:
    return np.arange(k) % nfold


# ---------------------------------------------------------------------------
# stale samples
# ---------------------------------------------------------------------------
def _chance_equal(sigma: np.ndarray) -> float:
    """Probability that two independent readings of a still sensor with white
    noise sigma (counts, per axis) round to the same integers on all axes."""
    p = 1.0
    for s in np.asarray(sigma, float):
        if not np.isfinite(s):
            return np.nan
        s2 = np.sqrt(2.0) * max(s, 1e-6)            # difference of two readings
        # P(round(a) == round(b)) for a continuous difference d ~ N(0, s2^2):
        # triangular kernel (1 - |d|) on |d| < 1
        d = np.linspace(-1, 1, 401)
        p *= float(np.trapezoid((1 - np.abs(d)) * stats.norm.pdf(d, scale=s2), d))
    return p


def stale_samples(obs: SensorObs, rate_hz: float) -> Screen | None:
    """Readings identical on all three axes to the previous one, beyond what
    the same readings two and three steps apart show (which stale updates do
    not repeat when the sensor updates faster than half the read rate) and
    beyond chance.

    Test: McNemar-type sign test on rows equal to the previous reading but not
    to the one before it vs the reverse; the repeated fraction above chance
    must also exceed ``STALE_MIN_EXCESS``."""
    if obs.n < 50:
        return None
    x = obs.x
    ok = ~obs.overflow
    same_part = np.ones(obs.n, bool)
    same_part[1:] = obs.part[1:] == obs.part[:-1]
    e1 = np.zeros(obs.n, bool)
    e1[1:] = np.all(x[1:] == x[:-1], axis=1)
    e1 &= same_part & ok
    e2 = np.zeros(obs.n, bool)
    e2[2:] = np.all(x[2:] == x[:-2], axis=1)
    e2 &= same_part & ok
    valid = ok.copy()
    valid[:2] = False
    n10 = int(np.sum(e1 & ~e2 & valid))
    n01 = int(np.sum(~e1 & e2 & valid))
    nv = int(valid.sum())
    f1 = float(e1[valid].mean())
    f2 = float(e2[valid].mean())
    if n10 + n01 == 0:
        p = 1.0
    else:
        p = float(stats.binomtest(n10, n10 + n01, 0.5, alternative="greater").pvalue)
    # chance of a fresh reading equal to the last: noise of the unique updates
    keep = unique_updates(x)
    sig = obs.sigma
    if obs.segs is not None:
        from .prepare import noise_sigma
        sig = noise_sigma(obs, list(obs.segs.rows), dedup=True)
    pc = _chance_equal(sig) if obs.segs is not None else min(f2, f1)
    if not np.isfinite(pc):
        pc = f2
    pc = float(min(pc, f2 + 1e-9)) if obs.segs is None else float(pc)
    excess = f1 - max(pc, 0.0)
    # fraction of reads that are fresh updates: f1 = (1 - rho) + rho pc
    rho = float(np.clip((1.0 - f1) / max(1.0 - pc, 1e-9), 1e-3, 1.0))
    update_hz = rho * rate_hz
    # per-block statistics
    groups = _chunks(obs)
    stat = np.array([e1[g[1:]].mean() for g in groups]) if groups else np.zeros(0)
    before = np.full(len(stat), pc)
    after = np.zeros(len(stat))
    fold = _folds(len(stat))
    for f in np.unique(fold):
        tr = fold != f
        f1_tr = float(np.mean(stat[tr])) if tr.any() else f1
        rho_tr = np.clip((1.0 - f1_tr) / max(1.0 - pc, 1e-9), 1e-3, 1.0)
        after[fold == f] = (1 - rho_tr) + rho_tr * pc
    ev = {"repeat_fraction": round(f1, 5), "repeat_fraction_lag2": round(f2, 5),
          "chance_fraction": round(pc, 5), "excess": round(excess, 5),
          "rows_equal_prev_not_prev2": n10, "rows_equal_prev2_not_prev": n01,
          "read_rate_hz": round(rate_hz, 3), "update_rate_hz": round(update_hz, 3),
          "unique_fraction": round(float(keep[ok].mean()), 5)}
    return Screen(obs.sensor, "stale_samples", p, excess, ev,
                  {"update_hz": round(update_hz, 3)}, stat, before, after,
                  "repeated-reading fraction per block", excess >= STALE_MIN_EXCESS)


# ---------------------------------------------------------------------------
# saturation
# ---------------------------------------------------------------------------
def _pileup(v: np.ndarray, side: int):
    """Count at the extreme value vs the mean count of the values just inside."""
    L = v.max() if side > 0 else v.min()
    c = int(np.sum(v == L))
    inside = L - side * np.arange(1, SAT_NEIGHBOURS + 1)
    vals, counts = np.unique(v, return_counts=True)
    lut = dict(zip(vals.tolist(), counts.tolist()))
    neigh = np.array([lut.get(float(q), 0) for q in inside], float)
    return float(L), c, float(neigh.mean())


def saturation(obs: SensorObs, chip_limits: tuple | None = None) -> Screen | None:
    """Readings piled up at the largest/smallest value of an axis (clipping)
    or overflow codes.

    Test per axis and side: under a smooth distribution the count at the
    extreme value is comparable to the counts just inside it; the p-value is
    Poisson with twice the neighbours' mean count as the expectation (a
    conservative allowance for the slope of the distribution, at least 1).
    Clipping also needs ``SAT_MIN_RATIO`` times the neighbours' mean and at
    least ``SAT_MIN_COUNT`` readings (``SAT_MIN_COUNT_FULL_SCALE`` at a chip's
    full-scale code); any overflow code is direct evidence."""
    x = obs.x[~obs.overflow]
    if obs.n < 20 or len(x) < 20:
        return None
    hits = []
    best_p = 1.0
    for a in range(3):
        for side in (1, -1):
            L, c, lam = _pileup(x[:, a], side)
            lam2 = max(2.0 * lam, 1.0)
            p = float(stats.poisson.sf(c - 1, lam2)) if c > 0 else 1.0
            ratio = c / max(lam, 0.25)
            need = SAT_MIN_COUNT_FULL_SCALE if L in FULL_SCALE_CODES else SAT_MIN_COUNT
            if c >= need and ratio >= SAT_MIN_RATIO:
                hits.append({"axis": "xyz"[a], "side": "high" if side > 0 else "low",
                             "limit_counts": L, "count": c, "neighbour_mean": round(lam, 3),
                             "p": p})
                best_p = min(best_p, p)
    n_over = int(obs.overflow.sum())
    if n_over:
        best_p = 0.0
    if not hits and not n_over:
        # report the most extreme candidate's p-value for the record
        return Screen(obs.sensor, "saturation", 1.0, 0.0, {"overflow_rows": 0}, {},
                      practical=False)
    low = [None, None, None]
    high = [None, None, None]
    for h in hits:
        i = "xyz".index(h["axis"])
        if h["side"] == "high":
            high[i] = h["limit_counts"]
        else:
            low[i] = h["limit_counts"]
    lo_def, hi_def = chip_limits or (-32768.0, 32767.0)
    params = {"low": [lo_def if v is None else v for v in low],
              "high": [hi_def if v is None else v for v in high]}
    if n_over:
        params["overflow_code"] = float(obs.x[obs.overflow][0, 0])
    n_clip = sum(h["count"] for h in hits) + n_over
    # per-block fraction of clipped readings
    clipped = obs.overflow.copy()
    for h in hits:
        i = "xyz".index(h["axis"])
        clipped |= obs.x[:, i] == h["limit_counts"]
    groups = _chunks(obs, still=False)
    if not groups or len(groups) < 2:
        groups = [np.arange(obs.n)]
    stat = np.array([clipped[g].mean() for g in groups])
    fold = _folds(len(stat))
    after = np.zeros(len(stat))
    for f in np.unique(fold):
        tr = fold != f
        after[fold == f] = stat[tr].mean() if tr.any() else stat.mean()
    ev = {"clipped_readings": int(n_clip), "clipped_fraction": round(n_clip / obs.n, 6),
          "overflow_rows": n_over, "limits": hits}
    return Screen(obs.sensor, "saturation", best_p, n_clip / obs.n, ev, params, stat,
                  np.zeros(len(stat)), after, "clipped fraction per block", True)


# ---------------------------------------------------------------------------
# motion: the accelerometer turns the way the gyroscope says
# ---------------------------------------------------------------------------
def _motion_slope(acc: SensorObs, gyr: SensorObs, L: int):
    """The accelerometer's change over L rows regressed on the turn the gyro
    measured over the same rows, inside each still segment: (slope, its
    standard error, z, L, per-segment (df, pred)), or None."""
    rate = acc.rate
    Kg = gyr.K
    ys, zs = [], []
    seg_stats = []
    for g in acc.segs.rows:
        if len(g) < 3 * L:
            continue
        f = acc.x[g]
        w = gyr.x[g]
        fbar = f.mean(axis=0)
        wr = np.radians((w - w.mean(axis=0)) / Kg) / rate        # rad per sample
        k = (len(g) - 1) // L                                     # whole intervals
        m = k * L
        dth = wr[:m].reshape(k, L, 3).sum(axis=1)                # turn over [iL, (i+1)L)
        df = f[L:m + 1:L] - f[0:m:L]                              # f((i+1)L) - f(iL)
        pred = -np.cross(dth, fbar)
        ys.append(df.ravel())
        zs.append(pred.ravel())
        seg_stats.append((df, pred))
    if not ys:
        return None
    y = np.concatenate(ys)
    z = np.concatenate(zs)
    szz = float(z @ z)
    if szz <= 0:
        return None
    beta = float(z @ y / szz)
    resid = y - beta * z
    se = float(np.sqrt((resid @ resid) / max(len(y) - 1, 1) / szz))
    zstat = beta / se if se > 0 else 0.0
    return beta, se, zstat, L, seg_stats


def _detrend(x: np.ndarray) -> np.ndarray:
    """x less its least-squares line in the row index, per column."""
    n = len(x)
    if n < 3:
        return x - x.mean(axis=0)
    t = np.arange(n) - (n - 1) / 2.0
    return x - x.mean(axis=0) - np.outer(t, t @ x) / float(t @ t)


def _motion_path(acc: SensorObs, gyr: SensorObs):
    """The accelerometer's path inside each still block regressed on the
    path the gyroscope's turn predicts (-theta x f, theta the rate
    integrated; both less their straight line, which takes out the gyro's
    bias and a slow drift): every reading counts, so a slow or small tremor
    that barely moves the reading within 64 ms still shows.  The standard
    error is cluster-robust over the blocks (correlated noise, repeats,
    leftovers of drift inside a block do not count as evidence).  Returns
    (slope, its standard error, z, 0, []), or None."""
    if acc.blocks is None or len(acc.blocks) < 3:
        return None
    rate = acc.rate
    Kg = gyr.K
    P, Y = [], []
    for g in acc.blocks.rows:
        if len(g) < 10:
            continue
        f = acc.x[g]
        theta = np.cumsum(np.radians(gyr.x[g] / Kg) / rate, axis=0)
        P.append(-np.cross(_detrend(theta), f.mean(axis=0)).ravel())
        Y.append(_detrend(f).ravel())
    if len(P) < 3:
        return None
    szz = float(sum(p @ p for p in P))
    if not szz > 0:
        return None
    beta = float(sum(p @ y for p, y in zip(P, Y))) / szz
    sc = np.array([p @ (y - beta * p) for p, y in zip(P, Y)])
    B = len(P)
    se = float(np.sqrt(np.sum(sc ** 2) * B / (B - 1))) / szz
    zstat = beta / se if se > 0 else 0.0
    return beta, se, zstat, 0, []


def motion(acc: SensorObs | None, gyr: SensorObs | None, seg_rows_shared: bool) -> Screen | None:
    """Board motion inside "still" segments.

    Evidence that cannot come from noise or drift: inside each still segment
    the change of the accelerometer reading over each of ``MOTION_LAGS_S`` is
    regressed on the change the gyroscope predicts for a turn of the board
    (d f = -dtheta x f, dtheta = the bias-free rate integrated over the same
    interval).  Under the starting model (independent white noise) the slope
    is 0; a shaking board gives slope ~1.  One-sided z-test on the slope.
    Size: rms tremor angle (from the accelerometer's excess variance across
    the gravity direction) and bandwidth (rate / angle)."""
    if acc is None or gyr is None or acc.segs is None or gyr.blocks is None \
            or not seg_rows_shared:
        return None
    if len(acc.x) != len(gyr.x) or not np.array_equal(acc.rows, gyr.rows):
        return None
    rate = acc.rate
    best = None
    tries = [_motion_slope(acc, gyr, max(2, int(round(lag * rate)))) for lag in MOTION_LAGS_S]
    tries.append(_motion_path(acc, gyr))
    for r in tries:
        if r is not None and (best is None or abs(r[2]) > abs(best[2])):
            best = r
    if best is None:
        return None
    beta, se, zstat, L, seg_stats = best
    Kg = gyr.K
    # two-sided (the sign depends on how the two sensors' axes are wired), the
    # best of the lags and the whole path: Bonferroni over them
    p = min(1.0, len(tries) * float(2.0 * stats.norm.sf(abs(zstat))))
    # size: rate excess of the gyro, angle excess of the accelerometer
    sig_g = gyr.sigma
    gvar = np.array([gyr.x[gg].var(axis=0, ddof=1) for gg in gyr.blocks.rows])
    rate_var = np.clip(gvar - sig_g ** 2, 0, None).mean()             # counts^2 per axis
    rate_rms_dps = float(np.sqrt(rate_var)) / Kg
    # accelerometer excess variance across the gravity direction
    Ka = np.linalg.norm(acc.segs.mean, axis=1)
    u = acc.segs.mean / Ka[:, None]
    avar = np.array([acc.x[gg].var(axis=0, ddof=1) for gg in acc.segs.rows])
    excess = avar - acc.sigma ** 2                                   # (k, 3)
    design = (Ka[:, None] ** 2) * (1 - u ** 2)                       # counts^2 per rad^2
    th2 = float(np.sum(excess * design) / max(np.sum(design * design), 1e-12))
    angle_deg = float(np.degrees(np.sqrt(th2))) if th2 > 0 else 0.0
    # bandwidth from rate / angle: f_rms = sqrt(E f^2), f ~ U(0.1, B)
    if angle_deg > 0 and rate_rms_dps > 0:
        f_rms = rate_rms_dps / (2 * np.pi * angle_deg)
        B = float(np.clip(np.sqrt(3.0) * f_rms, 0.2, 0.45 * rate))
    else:
        B = 3.0
    if angle_deg <= 0 and rate_rms_dps > 0:
        f_rms = B / np.sqrt(3.0)
        angle_deg = rate_rms_dps / (2 * np.pi * f_rms)
    # per-block statistic: gyro rate excess (counts^2); predicted 0 before,
    # the other fold's mean after
    stat = np.clip(gvar - sig_g ** 2, 0, None).mean(axis=1)
    fold = _folds(len(stat))
    after = np.zeros(len(stat))
    for f_ in np.unique(fold):
        tr = fold != f_
        after[fold == f_] = stat[tr].mean() if tr.any() else stat.mean()
    ev = {"slope_accel_on_gyro": round(beta, 4), "z": round(zstat, 2),
          "lag_s": round(L / rate, 4) if L else "whole path", "segments": len(acc.segs),
          "tremor_rate_rms_dps": round(rate_rms_dps, 4),
          "tremor_angle_rms_deg": round(angle_deg, 4)}
    plausible = MOTION_SLOPE[0] < abs(beta) < MOTION_SLOPE[1]
    return Screen("accel+gyro", "motion", p, angle_deg, ev,
                  {"rms_deg": round(angle_deg, 5), "bandwidth_hz": round(B, 3)},
                  stat, np.zeros(len(stat)), after, "gyro rate variance above noise per "
                  "still block (counts^2)", plausible)
