"""Stillness detection: is the board at rest?

One definition used live by the logger's guided flow (``TurnStillDetector``,
``live_detector``) and offline by the importer and diagnosis
(``segment_still``; ``segment_recording`` for a recording whose sensors may
run on separate clocks).

A window of ``window_s`` seconds is *still* when the board's orientation
stays put over it, judged by every sensor present:

* accelerometer: the standard deviation of each axis below ``accel_g``
  (default 0.02 g, a wander of the gravity direction of about 1.1 deg;
  ADXL345 noise is ~0.004 g rms),
* magnetometer: the same below ``mag_gauss`` (default 0.012 gauss, about
  1.4 deg of a 0.5 gauss field; HMC5883L noise ~2 LSB = 0.002 gauss) --
  catches turns about the vertical, which the accelerometer cannot see,
* gyroscope (offline ``still_mask``, ``segment_still``; live
  ``TurnStillDetector``): the standard
  deviation of the *integrated* rotation over the window below
  ``gyro_turn_deg`` (default 0.3 deg per axis).  The rate is integrated
  after removing its bias, a running median of the rate over the rows the
  other sensors call still (``BIAS_S`` blocks).  A hand's tremor (0.05-0.3
  deg rms at 1-8 Hz) turns the board at several deg/s but goes nowhere:
  the integrated angle stays within its amplitude, while a turn of 5 deg/s
  or more moves it beyond the threshold within one window.  Live
  (``TurnStillDetector``) the same, over trailing windows, bias and limit
  from the rows so far.
* gyroscope with ``gyro_rule="rate"`` (a turntable's steady turns,
  ``foreign``; live: ``StillDetector``): the
  standard deviation of the rate below ``gyro_dps`` (1.5 deg/s; ITG3200
  noise ~0.4 deg/s rms).

Thresholds work on spreads, not means, so an unknown gyroscope bias (up to
~15 deg/s on an uncalibrated ITG3200) does not matter; offline, it is taken
out before integrating (an error of 1 deg/s in it adds 0.12 deg of spread).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .session import NOMINAL_SCALES, SENSOR_SLICES


@dataclass(frozen=True)
class StillThresholds:
    window_s: float = 0.4
    accel_g: float = 0.02
    gyro_dps: float = 1.5
    mag_gauss: float = 0.012
    min_still_s: float = 1.0     # shortest segment segment_still() labels
    gyro_turn_deg: float = 0.3   # spread of the integrated rotation (deg per axis)
    gyro_rule: str = "turn"      # live and offline: "turn" (the board stays put) or "rate" (the rate
                                 # is steady: a turntable's constant turn counts, gyro_dps)


def window_rows(rate_hz: float, th: StillThresholds = StillThresholds()) -> int:
    """Rows in one stillness window at ``rate_hz`` (at least 3)."""
    return max(3, int(round(th.window_s * rate_hz)))


def _moving_std(x: np.ndarray, w: int) -> np.ndarray:
    """Std over the trailing window of w rows for each row >= w-1 (NaN before)."""
    n = len(x)
    out = np.full(x.shape, np.nan)
    if n < w:
        return out
    c1 = np.cumsum(np.vstack([np.zeros((1, x.shape[1])), x]), axis=0)
    c2 = np.cumsum(np.vstack([np.zeros((1, x.shape[1])), x * x]), axis=0)
    s1 = c1[w:] - c1[:-w]
    s2 = c2[w:] - c2[:-w]
    var = np.maximum(s2 / w - (s1 / w) ** 2, 0.0)
    out[w - 1:] = np.sqrt(var)
    return out


BIAS_S = 10.0      # the gyro bias for the integrated rotation: median per block this long


def _centred_ok(x: np.ndarray, w: int, lim: float) -> np.ndarray:
    """Per row: every axis' spread over the window of w rows centred on it is
    below ``lim`` (a recording shorter than the window has no full window:
    nothing is still)."""
    n = len(x)
    sd = _moving_std(x, w)
    half = w // 2
    centred = np.full(sd.shape, np.nan)
    centred[:max(0, n - half)] = sd[half:]
    return np.nan_to_num(centred, nan=np.inf).max(axis=1) < lim


def gyro_bias(g_dps: np.ndarray, rate_hz: float, quiet: np.ndarray | None = None) -> np.ndarray:
    """(n, 3) the gyroscope's bias per row: the median rate of each
    ``BIAS_S`` block over its ``quiet`` rows (those the other sensors call
    still; all rows when too few are), with the blocks beside it, spread to
    every row.  Tremor and noise are symmetric about the bias; moves are
    left out by ``quiet``."""
    n = len(g_dps)
    if quiet is None or quiet.sum() < max(3, 0.05 * n):
        quiet = np.ones(n, bool)
    nb = max(1, int(round(BIAS_S * rate_hz)))
    starts = np.arange(0, n, nb)
    med = np.zeros((len(starts), 3))
    for i, a in enumerate(starts):
        lo, hi = max(0, a - nb), min(n, a + 2 * nb)
        q = quiet[lo:hi]
        rows = g_dps[lo:hi][q] if q.sum() >= 3 else g_dps[lo:hi]
        med[i] = np.median(rows, axis=0)
    return np.repeat(med, nb, axis=0)[:n]


TREMOR_K = 4.0     # the spread limit is at least this many times the quiet rows' ...
TREMOR_Q = 0.25    # ... lower quartile of the spread (the hand's tremor in its holds)


def tremor_limit(lim_deg: float, quiet_spreads: np.ndarray) -> float:
    """The integrated-rotation limit for a hand that trembles: ``lim_deg``,
    or ``TREMOR_K`` x the ``TREMOR_Q`` quantile of the spreads seen over quiet
    rows (the holds' tremor), whichever is larger (``turn_spread_ok``'s rule)."""
    q = np.asarray(quiet_spreads, float)
    q = q[np.isfinite(q)]
    if not len(q):
        return float(lim_deg)
    return max(float(lim_deg), TREMOR_K * float(np.quantile(q, TREMOR_Q)))


def turn_spread_ok(g_dps: np.ndarray, rate_hz: float, w: int, lim_deg: float,
                   quiet: np.ndarray | None = None) -> np.ndarray:
    """Per row: the rotation the gyroscope integrates (bias removed,
    ``gyro_bias``) spreads by less than ``lim_deg`` per axis over the window
    of w rows centred on it -- or, for a hand that trembles, by less than
    ``TREMOR_K`` x the lower quartile of that spread over the ``quiet`` rows
    (the holds' tremor; moves' slow parts cannot raise a lower quartile)."""
    theta = np.cumsum(g_dps - gyro_bias(g_dps, rate_hz, quiet), axis=0) / rate_hz
    n = len(theta)
    sd = _moving_std(theta, w)
    half = w // 2
    spread = np.full(n, np.inf)
    spread[:max(0, n - half)] = np.nan_to_num(sd[half:], nan=np.inf).max(axis=1)
    q = spread[quiet] if quiet is not None and quiet.any() else spread
    return spread < tremor_limit(lim_deg, q)


def still_mask(raw: np.ndarray, rate_hz: float, scales: dict | None = None,
               th: StillThresholds = StillThresholds()) -> np.ndarray:
    """Per-row bool: the window centred on this row is still (the module doc:
    accelerometer and magnetometer spreads, the gyroscope's integrated
    rotation).

    ``raw`` is (n, 9) counts with NaN for missing sensors; a sensor that is
    entirely missing is ignored.  Rows are assumed evenly spaced at rate_hz.
    """
    scales = scales or NOMINAL_SCALES
    w = window_rows(rate_hz, th)
    n = len(raw)
    ok = np.ones(n, bool)
    x = {}
    for name, sl in (("accel", slice(0, 3)), ("gyro", slice(3, 6)), ("mag", slice(6, 9))):
        v = raw[:, sl] / scales[name]
        if not np.isnan(v).all():
            x[name] = np.where(np.isnan(v), np.nanmean(v, axis=0), v)
    for name, lim in (("accel", th.accel_g), ("mag", th.mag_gauss)):
        if name in x:
            ok &= _centred_ok(x[name], w, lim)
    if "gyro" in x and th.gyro_rule == "rate":
        ok &= _centred_ok(x["gyro"], w, th.gyro_dps)
    elif "gyro" in x:
        quiet = ok.copy() if ("accel" in x or "mag" in x) else None
        ok &= turn_spread_ok(x["gyro"], rate_hz, w, th.gyro_turn_deg, quiet)
    return ok


def segment_still(raw: np.ndarray, rate_hz: float, scales: dict | None = None,
                  th: StillThresholds = StillThresholds(), trim_s: float = 0.0) -> np.ndarray:
    """Label still segments 1, 2, 3, ... in time order; moving rows get 0.

    ``trim_s`` seconds are left out at both ends of every segment (the slow
    start and end of a smooth move pass the thresholds); segments shorter
    than ``th.min_still_s`` after that are dropped.
    """
    mask = still_mask(raw, rate_hz, scales, th)
    labels = np.zeros(len(raw), np.int32)
    if not mask.any():
        return labels
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    k = 0
    min_len = int(round(th.min_still_s * rate_hz))
    trim = int(round(trim_s * rate_hz))
    for start, stop in zip(edges[::2], edges[1::2]):
        start, stop = start + trim, stop - trim
        if stop - start >= max(min_len, 1):
            k += 1
            labels[start:stop] = k
    return labels


SEPARATE_CLOCKS_GRID_HZ = 100.0     # grid for stillness of sensors on separate clocks
GRID_ROWS_PER_ROW = 4               # a longer grid than this per row is split at pauses ...
GRID_PAUSE_S = 1.0                  # ... longer than this (seconds without a row)


def segment_recording(raw: np.ndarray, t: np.ndarray, rate_hz: float,
                      scales: dict | None = None, th: StillThresholds = StillThresholds(),
                      trim_s: float = 0.0) -> np.ndarray:
    """Labels 1..K of still segments of one recording (rows in time order),
    judged on every sensor present at once (``segment_still``).

    Sensors sampled together (every row has every present sensor): the rows
    go to ``segment_still`` as they are, at ``rate_hz``.  Sensors on separate
    clocks (rows with NaN for the other sensors): each sensor is held (last
    value) on a ``SEPARATE_CLOCKS_GRID_HZ`` grid of the times ``t``, the grid
    goes to ``segment_still`` and every row takes the label of its grid point.
    """
    raw = np.asarray(raw, float)
    t = np.asarray(t, float)
    n = len(raw)
    if n == 0:
        return np.zeros(0, np.int32)
    present = [s for s, sl in SENSOR_SLICES.items() if not np.isnan(raw[:, sl]).all()]
    complete = all((~np.isnan(raw[:, SENSOR_SLICES[s]])).all() for s in present)
    if complete or not np.isfinite(t).all():
        return segment_still(raw, rate_hz, scales, th, trim_s)
    t0 = t.min()
    hz = SEPARATE_CLOCKS_GRID_HZ
    ng = int(np.floor((t.max() - t0) * hz)) + 1
    if ng > GRID_ROWS_PER_ROW * n + 1000:
        # a grid far longer than the rows (pauses of hours, or absurd times): one
        # grid per stretch without a pause, so memory follows the rows, not the span
        cut = np.flatnonzero(np.diff(t) > GRID_PAUSE_S) + 1
        if len(cut):
            out, k = np.zeros(n, np.int32), 0
            for a, b in zip(np.r_[0, cut], np.r_[cut, n]):
                lab = segment_recording(raw[a:b], t[a:b], rate_hz, scales, th, trim_s)
                out[a:b] = np.where(lab > 0, lab + k, 0)
                k += int(lab.max(initial=0))
            return out
    grid_t = t0 + np.arange(ng) / hz
    grid = np.full((ng, 9), np.nan)
    for s in present:
        sl = SENSOR_SLICES[s]
        rows = np.flatnonzero(~np.isnan(raw[:, sl]).any(axis=1))
        ts = t[rows]
        j = np.clip(np.searchsorted(ts, grid_t, side="right") - 1, 0, len(rows) - 1)
        grid[:, sl] = raw[rows[j], sl]
    glab = segment_still(grid, hz, scales, th, trim_s)
    gi = np.clip(np.round((t - t0) * hz).astype(np.int64), 0, ng - 1)
    return glab[gi]


class StillDetector:
    """Streaming form for live data of one mote: push rows, ask ``still``.

    Keeps the last window of rows; ``push`` returns True while the latest
    window is still.
    """

    def __init__(self, rate_hz: float, scales: dict | None = None,
                 th: StillThresholds = StillThresholds()):
        self.th = th
        self.scales = scales or NOMINAL_SCALES
        self.w = window_rows(rate_hz, th)
        self._buf = np.full((self.w, 9), np.nan)
        self._n = 0

    def reset(self):
        self._n = 0
        self._buf[:] = np.nan

    def push(self, rows: np.ndarray) -> bool:
        rows = np.asarray(rows, float).reshape(-1, 9)
        if len(rows) >= self.w:
            self._buf[:] = rows[-self.w:]
        else:
            self._buf = np.vstack([self._buf[len(rows):], rows])
        self._n += len(rows)
        return self.still

    @property
    def still(self) -> bool:
        if self._n < self.w:
            return False
        for name, sl, lim in (("accel", slice(0, 3), self.th.accel_g),
                              ("gyro", slice(3, 6), self.th.gyro_dps),
                              ("mag", slice(6, 9), self.th.mag_gauss)):
            x = self._buf[:, sl] / self.scales[name]
            if np.isnan(x).all():
                continue
            if np.isnan(x).any() or (x.std(axis=0) >= lim).any():
                return False
        return True

    def push_many(self, rows: np.ndarray) -> np.ndarray:
        """Push rows; per row, what ``push`` would return had the rows come one
        at a time (the trailing window ending at that row is still).  Vectorised
        (running sums, as ``still_mask``) for the logger, which sees thousands
        of rows per read."""
        rows = np.asarray(rows, float).reshape(-1, 9)
        n = len(rows)
        if n == 0:
            return np.zeros(0, bool)
        w = self.w
        x_all = np.vstack([self._buf[1:], rows])          # w-1 previous rows + new ones
        ok = (self._n + np.arange(1, n + 1)) >= w
        for name, sl, lim in (("accel", slice(0, 3), self.th.accel_g),
                              ("gyro", slice(3, 6), self.th.gyro_dps),
                              ("mag", slice(6, 9), self.th.mag_gauss)):
            absent, still = _window_ok(x_all[:, sl] / self.scales[name], w, lim)
            if absent.all():                                # sensor absent throughout
                continue
            ok &= absent | still
        self._buf = x_all[-w:].copy()
        self._n += n
        return ok


TREMOR_LIVE_S = 60.0   # live: the tremor's quartile is taken over the quiet rows of this span


def _window_ok(x: np.ndarray, w: int, lim: float | None):
    """Trailing windows of w rows over x (n + w - 1, 3): per window, (absent,
    ok) -- absent: every value NaN (the sensor is not there); ok: no NaN and
    every axis' std below ``lim`` (``lim`` None: only the NaN rule)."""
    isnan = np.isnan(x)
    nans = np.concatenate([[0], np.cumsum(isnan.sum(axis=1))])
    nans = nans[w:] - nans[:-w]
    absent = nans == 3 * w
    if lim is None:
        return absent, nans == 0
    ref = np.nanmean(x, axis=0) if not isnan.all() else np.zeros(3)
    xc = np.where(isnan, 0.0, x - np.nan_to_num(ref))       # centred: no cancellation
    sd = _moving_std(xc, w)[w - 1:]
    return absent, (nans == 0) & (sd < lim).all(axis=1)


class TurnStillDetector:
    """Live stillness on the offline rule (``still_mask`` with
    ``gyro_rule="turn"``), incremental over the trailing window of one mote:
    push rows, ask ``still``.

    A row is still when the trailing window of ``window_rows`` rows ending at
    it is still by the accelerometer and magnetometer spreads (the offline
    limits) -- the row is then *quiet* -- and by the gyroscope's integrated
    rotation: the spread over the window of ``cumsum(rate - bias) / rate_hz``
    below ``tremor_limit(gyro_turn_deg, spreads of the quiet rows of the last
    TREMOR_LIVE_S)``.  The bias is the median rate of the quiet rows of the
    last ``BIAS_S`` (``gyro_bias``'s rule, looking back only; while fewer than
    max(3, 5 %) are quiet, as at the start, the median of the last window's
    rows).  Bias and limit are brought up to
    date every ``window_rows`` rows, counted from the first row, so the
    decisions do not depend on how the rows are chunked (``push_many`` =
    ``push`` row by row), the first after ``window_rows - 1`` rows (the first
    full window is judged with a bias).  Before the first full window nothing
    is still.
    """

    def __init__(self, rate_hz: float, scales: dict | None = None,
                 th: StillThresholds = StillThresholds()):
        self.th = th
        self.rate = float(rate_hz)
        self.scales = scales or NOMINAL_SCALES
        self.w = window_rows(rate_hz, th)
        self.nb = max(3, int(round(BIAS_S * rate_hz)))
        self.nt = max(self.w, int(round(TREMOR_LIVE_S * rate_hz)))
        self.reset()

    def reset(self):
        self._buf = np.full((self.w - 1, 9), np.nan)      # the last w-1 rows (counts)
        self._n = 0
        self._g = np.zeros((0, 3))                          # rates since the last update ...
        self._q = np.zeros(0, bool)                         # ... and whether quiet
        self._sp = np.zeros(0)                              # their spreads where quiet
        self._hist_g = np.zeros((0, 3))                     # last BIAS_S of rates, quiet flags
        self._hist_q = np.zeros(0, bool)
        self._hist_sp = np.zeros(0)                         # last TREMOR_LIVE_S quiet spreads
        self.bias = np.zeros(3)
        self.limit = float(self.th.gyro_turn_deg)
        self._last = False

    def _update(self) -> None:
        """Bring bias and limit up to date with the rows since the last update."""
        self._hist_g = np.vstack([self._hist_g, self._g])[-self.nb:]
        self._hist_q = np.concatenate([self._hist_q, self._q])[-self.nb:]
        self._hist_sp = np.concatenate([self._hist_sp, self._sp])[-self.nt:]
        self._g, self._q, self._sp = np.zeros((0, 3)), np.zeros(0, bool), np.zeros(0)
        g, q = self._hist_g, self._hist_q
        rows = g[q] if q.sum() >= max(3, 0.05 * len(q)) else g[-self.w:]
        rows = rows[np.isfinite(rows).all(axis=1)]
        if len(rows):
            self.bias = np.median(rows, axis=0)
        self.limit = tremor_limit(self.th.gyro_turn_deg, self._hist_sp)

    def push(self, rows: np.ndarray) -> bool:
        """Push rows; True while the window ending at the last one is still."""
        self.push_many(rows)
        return self.still

    @property
    def still(self) -> bool:
        return self._last

    def push_many(self, rows: np.ndarray) -> np.ndarray:
        """Push rows; per row, whether the trailing window ending at it is still."""
        rows = np.asarray(rows, float).reshape(-1, 9)
        n = len(rows)
        if n == 0:
            return np.zeros(0, bool)
        w = self.w
        raw_all = np.vstack([self._buf, rows])
        x_all = np.empty_like(raw_all)
        for name, sl in (("accel", slice(0, 3)), ("gyro", slice(3, 6)), ("mag", slice(6, 9))):
            x_all[:, sl] = raw_all[:, sl] / self.scales[name]
        full = (self._n + np.arange(1, n + 1)) >= w
        quiet = full.copy()
        for sl, lim in ((slice(0, 3), self.th.accel_g), (slice(6, 9), self.th.mag_gauss)):
            absent, ok = _window_ok(x_all[:, sl], w, lim)
            quiet &= absent | ok
        g_absent, g_whole = _window_ok(x_all[:, 3:6], w, None)
        out = np.zeros(n, bool)
        a = 0
        while a < n:
            # rows a .. c-1 share the bias and limit; updates come after every
            # w rows, the first after w - 1 (the first full window has a bias)
            d = (w - 1 - self._n) % w or w
            c = min(n, a + d)
            g = x_all[a:c + w - 1, 3:6] - self.bias
            theta = np.cumsum(np.where(np.isnan(g), 0.0, g), axis=0) / self.rate
            theta -= theta[0]
            spread = _moving_std(theta, w)[w - 1:].max(axis=1)
            spread = np.where(g_whole[a:c], spread, np.inf)
            gyro_ok = g_absent[a:c] | (spread < self.limit)
            out[a:c] = quiet[a:c] & gyro_ok
            self._g = np.vstack([self._g, rows[a:c, 3:6] / self.scales["gyro"]])
            self._q = np.concatenate([self._q, quiet[a:c]])
            self._sp = np.concatenate([self._sp, spread[quiet[a:c] & g_whole[a:c]]])
            self._n += c - a
            if self._n % w == w - 1:
                self._update()
            a = c
        self._buf = raw_all[-(w - 1):].copy()
        self._last = bool(out[-1])
        return out


def live_detector(rate_hz: float, scales: dict | None = None,
                  th: StillThresholds = StillThresholds()):
    """The live detector for ``th.gyro_rule``: ``TurnStillDetector`` ("turn",
    the offline rule), ``StillDetector`` ("rate", the rate's spread)."""
    if th.gyro_rule == "rate":
        return StillDetector(rate_hz, scales, th)
    return TurnStillDetector(rate_hz, scales, th)
