"""What the diagnosis works on: per sensor, its rows, still segments (poses),
time blocks and noise level.  Pure functions on a ``SessionData``.

* A **segment** is one still orientation: a static pose (label >= 1) or, in
  data without pose labels, a still stretch found by ``motecal.sessions.still`` on
  every sensor at once (``calib.content.still_stretches``), with 0.2 s left
  out at both ends: the slow start and end of a smooth move pass the
  stillness thresholds of one 0.4 s window but are not still (judged per
  sensor and untrimmed, they made the motion screen name ``motion`` on 12 of
  14 clean unguided logs).
  Calibration-type questions (does the magnitude depend on direction?) use
  one mean per segment.
* A **block** is a stretch of ``BLOCK_S`` seconds inside a segment (a
  segment shorter than two blocks is one block).  Time-type questions (does
  the bias move?) and held-out time blocks use blocks.
* Noise: per axis, from differences of successive readings inside still
  segments (``sigma``), and the *effective* per-sample variance of a mean
  (``sigma_eff``: batch means, so that correlated samples -- repeats, slow
  wander -- are not counted as independent).

Rows with an overflow code (HMC5883L -4096 on all axes) are kept in ``x``
but flagged and left out of segments.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..calib.content import recording_parts, still_stretches
from ..sessions.session import HMC5883L_OVERFLOW, LABEL_ROT, SessionData

SENSORS = ("accel", "gyro", "mag")
BLOCK_S = 2.0              # time block length (s)
MIN_SEG_SAMPLES = 20       # shorter still stretches are not used
N_BATCH = 8                # batches for the variance of a segment mean
QUANT_SIGMA = 1.0 / np.sqrt(12.0)   # rounding to whole counts: the least noise a reading has
# chips whose value at that code means "overflow" (all three axes)
OVERFLOW_CODES = {"mag": HMC5883L_OVERFLOW}


@dataclass
class Table:
    """One row per segment (or block)."""
    mean: np.ndarray            # (k, 3) counts
    n: np.ndarray               # (k,) samples
    t: np.ndarray               # (k,) mid time, s
    t0: np.ndarray              # (k,) first time
    t1: np.ndarray              # (k,) last time
    seg: np.ndarray             # (k,) segment index (for blocks: the segment it is in)
    rows: list                  # per row of the table: indices into SensorObs.x
    sd: np.ndarray              # (k, 3) within sd, counts
    n_bad: np.ndarray | None = None   # (k,) overflow readings inside (left out of the mean)
    var: np.ndarray | None = None     # (k, 3) variance of each mean when not sigma_eff^2 / n
                                      # (gyro blocks with the board's turn taken out: turns)

    def __len__(self):
        return len(self.n)


@dataclass
class SensorObs:
    sensor: str
    chip: str | None
    K: float                    # LSB per unit (g, deg/s, gauss)
    x: np.ndarray               # (n, 3) counts
    t: np.ndarray               # (n,) s
    label: np.ndarray           # (n,) session labels
    part: np.ndarray            # (n,) recording part (file) index
    rows: np.ndarray            # (n,) row indices into the session
    rate: float                 # Hz (this sensor)
    overflow: np.ndarray        # (n,) bool
    segs: Table | None = None
    blocks: Table | None = None
    sigma: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    sigma_eff: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    labelled_poses: bool = False    # segments are the session's static poses
    moving: np.ndarray | None = None  # (n,) bool rows outside any segment

    @property
    def n(self) -> int:
        return len(self.x)

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0]) if self.n > 1 else 0.0

    def var_of_mean(self, n) -> np.ndarray:
        """(k, 3) variance of a segment mean of n samples (counts^2)."""
        return self.sigma_eff[None, :] ** 2 / np.asarray(n, float)[:, None]


def sample_times(data: SessionData) -> np.ndarray:
    """Per row, when the sample was taken (SessionData.sample_times)."""
    return data.sample_times()


def _table(obs: SensorObs, groups: list[np.ndarray], seg_of: list[int]) -> Table:
    k = len(groups)
    mean = np.zeros((k, 3))
    sd = np.zeros((k, 3))
    n = np.zeros(k)
    t = np.zeros(k)
    t0 = np.zeros(k)
    t1 = np.zeros(k)
    for i, g in enumerate(groups):
        xs = obs.x[g]
        mean[i] = xs.mean(axis=0)
        sd[i] = xs.std(axis=0, ddof=1) if len(g) > 1 else 0.0
        n[i] = len(g)
        t0[i], t1[i] = obs.t[g[0]], obs.t[g[-1]]
        t[i] = 0.5 * (t0[i] + t1[i])
    return Table(mean, n, t, t0, t1, np.asarray(seg_of, int), list(groups), sd)


def still_labels(data: SessionData) -> np.ndarray:
    """Per row, the still stretch 1..K it is in (0: moving) for data without
    pose labels: the one judgement ``calibrate`` uses too
    (``calib.content.still_stretches``: every sensor at once, trimmed at both
    ends and while the gyroscope still turns)."""
    return still_stretches(data)


def _segments(obs: SensorObs, data_label: np.ndarray, still: np.ndarray) -> tuple[list, bool]:
    """Row-index groups of still segments (and whether they are labelled poses);
    ``still`` is ``still_labels`` of the session's rows, used without poses."""
    ok = ~obs.overflow
    groups = []
    poses = np.unique(data_label[(data_label >= 1) & ok])
    if len(poses):
        obs.bad_in_pose = []
        for p in poses:
            idx = np.flatnonzero((data_label == p) & ok)
            # a pose split across recordings or long gaps stays one pose
            if len(idx) >= MIN_SEG_SAMPLES:
                groups.append(idx)
                obs.bad_in_pose.append(int(np.sum((data_label == p) & ~ok)))
        return groups, True
    # no pose labels: the session's still stretches (every sensor at once)
    lab = still[obs.rows]
    for s in np.unique(lab[lab > 0]):
        idx = np.flatnonzero((lab == s) & ok)
        if len(idx) >= MIN_SEG_SAMPLES:
            groups.append(idx)
    return groups, False


def _blocks(obs: SensorObs, segs: list[np.ndarray]) -> tuple[list, list]:
    groups, seg_of = [], []
    nb_len = max(MIN_SEG_SAMPLES, int(round(BLOCK_S * obs.rate)))
    for si, g in enumerate(segs):
        nb = max(1, len(g) // nb_len)
        for b in np.array_split(g, nb):
            groups.append(b)
            seg_of.append(si)
    return groups, seg_of


def _diff_pairs(obs: SensorObs, groups: list[np.ndarray]):
    """Successive-reading differences inside groups (same recording)."""
    out = []
    for g in groups:
        if len(g) > 1:
            d = np.diff(obs.x[g], axis=0)
            same = np.diff(obs.part[g]) == 0
            out.append(d[same])
    return np.vstack(out) if out else np.zeros((0, 3))


def unique_updates(x: np.ndarray) -> np.ndarray:
    """Bool mask dropping readings identical (all three axes) to the previous one."""
    keep = np.ones(len(x), bool)
    if len(x) > 1:
        keep[1:] = np.any(np.diff(x, axis=0) != 0, axis=1)
    return keep


def noise_sigma(obs: SensorObs, groups: list[np.ndarray], dedup: bool = False) -> np.ndarray:
    """Per-axis white-noise sigma (counts) from successive differences in still
    groups; without still data, a robust estimate from second differences of
    all rows (motion is smooth, noise is not)."""
    if groups:
        gs = groups
        if dedup:
            gs = [g[unique_updates(obs.x[g])] for g in groups]
        d = _diff_pairs(obs, gs)
        if len(d) >= 10:
            return np.sqrt(np.mean(d * d, axis=0) / 2.0)
    x = obs.x[~obs.overflow]
    if dedup:
        x = x[unique_updates(x)]
    if len(x) < 10:
        return np.full(3, np.nan)
    d2 = x[2:] - 2 * x[1:-1] + x[:-2]
    mad = np.median(np.abs(d2 - np.median(d2, axis=0)), axis=0)
    return 1.4826 * mad / np.sqrt(6.0)


def effective_sigma(obs: SensorObs, groups: list[np.ndarray]) -> np.ndarray:
    """Per-axis sigma_eff with var(mean of n) = sigma_eff^2 / n, from batch
    means inside each group (pooled)."""
    num = np.zeros(3)
    den = 0.0
    for g in groups:
        if len(g) < 2 * N_BATCH:
            continue
        xs = obs.x[g]
        parts = np.array_split(np.arange(len(g)), N_BATCH)
        bm = np.array([xs[p].mean(axis=0) for p in parts])
        bn = np.array([len(p) for p in parts], float)
        m = xs.mean(axis=0)
        # var of the mean: sum bn^2 (bm - m)^2 / (n^2) * B/(B-1)
        v = (bn[:, None] ** 2 * (bm - m) ** 2).sum(axis=0) / len(g) ** 2 * N_BATCH / (N_BATCH - 1)
        num += v * len(g)
        den += 1.0
    if den == 0:
        return np.full(3, np.nan)
    return np.sqrt(num / den)


def session_still(data: SessionData) -> np.ndarray | None:
    """``still_labels`` of a session none of whose rows has a pose label (so
    that every sensor needs them), else None: worked out once per session for
    ``sensor_obs`` (it covers the whole session, not one sensor)."""
    return still_labels(data) if not (data.label >= 1).any() else None


def sensor_obs(data: SessionData, sensor: str, dedup: bool = False,
               still: np.ndarray | None = None) -> SensorObs | None:
    """The observations of one sensor, or None when the session has none.
    ``still``: the session's ``still_labels`` when the caller has them
    (``session_still``); else they are worked out here if the sensor's rows
    carry no pose label."""
    has = data.has(sensor)
    if not has.any():
        return None
    rows = np.flatnonzero(has)
    rate = data.rate(sensor)
    x = data.sensor(sensor)[rows].astype(float)
    code = OVERFLOW_CODES.get(sensor)
    overflow = np.all(x == code, axis=1) if code is not None else np.zeros(len(x), bool)
    obs = SensorObs(sensor=sensor, chip=(data.chips or {}).get(sensor), K=float(data.scales[sensor]),
                    x=x, t=sample_times(data)[rows], label=data.label[rows],
                    part=recording_parts(data)[rows], rows=rows, rate=rate, overflow=overflow)
    if dedup:
        keep = unique_updates(x) | overflow
        obs = SensorObs(sensor=sensor, chip=obs.chip, K=obs.K, x=x[keep], t=obs.t[keep],
                        label=obs.label[keep], part=obs.part[keep], rows=rows[keep],
                        rate=rate * keep.mean(), overflow=overflow[keep])
    label = obs.label.copy()
    label[label == LABEL_ROT] = 0
    if (label >= 1).any():
        still = None
    elif still is None:
        still = still_labels(data)
    groups, labelled = _segments(obs, label, still)
    obs.labelled_poses = labelled
    obs.sigma = noise_sigma(obs, groups)
    # batch means inside time blocks: short-range correlation (repeats, shaking)
    # counts, slow drift across a long segment does not
    obs.sigma_eff = effective_sigma(obs, _blocks(obs, groups)[0] if groups else [])
    if not np.all(np.isfinite(obs.sigma_eff)):
        obs.sigma_eff = obs.sigma.copy()
    # a reading is an integer count: even a stuck (constant) axis is known no
    # better than its rounding (1/sqrt(12) counts), so no weight is infinite
    obs.sigma = np.fmax(obs.sigma, QUANT_SIGMA)
    # a mean can never be better known than white noise says
    obs.sigma_eff = np.fmax(obs.sigma_eff, obs.sigma)
    moving = np.ones(obs.n, bool)
    if groups:
        obs.segs = _table(obs, groups, list(range(len(groups))))
        bad = getattr(obs, "bad_in_pose", None)
        obs.segs.n_bad = np.asarray(bad if bad is not None else np.zeros(len(groups)), float)
        bg, bs = _blocks(obs, groups)
        obs.blocks = _table(obs, bg, bs)
        for g in groups:
            moving[g] = False
    obs.moving = moving & ~obs.overflow
    return obs


def all_obs(data: SessionData, dedup: dict | None = None,
            still: np.ndarray | None = None) -> dict[str, SensorObs]:
    """``sensor_obs`` of every sensor the session has (``still``: as there;
    by default ``session_still``, worked out once for all)."""
    dedup = dedup or {}
    still = session_still(data) if still is None else still
    out = {}
    for s in SENSORS:
        o = sensor_obs(data, s, dedup=bool(dedup.get(s)), still=still)
        if o is not None:
            out[s] = o
    return out
