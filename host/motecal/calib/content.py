"""What a session's rows contain, judged once for ``calibrate``, its gate and
``diagnose`` (issue 13): the still stretches and how many distinct
orientations they cover, whatever the labels say.

A recording's labels come from how it was made (the guided logger's poses)
or from the importer's still-fraction rule, which calls a recording a
rotation when most rows move.  People holding a board by hand take longer to
move between poses than to hold each (the paper's 1.6 s holds): such a
session is mostly moving, yet its still stretches are poses.  So the kind is
decided from the data: still stretches found on every sensor at once
(``still.segment_recording``), trimmed at both ends, and trimmed further
while the gyroscope still turns (the slow tail of a long, smooth move passes
a stillness test on the spread of readings); when they cover at least
``MIN_POSE_ORIENTATIONS`` distinct orientations, the session holds poses --
and it may hold a sweep too (the rows between them, judged by the gate's
coverage rule).  An unlabelled recording whose still stretches cover fewer
orientations is a hold: its stretches are labelled too, for the gyroscope's
bias and the temperature terms (issue 31).

What each sensor's data determine -- the richest model its poses or its
sweep can fit, or nothing -- is judged in ``calib.determine``, which this
module owns (``judge_poses``, ``judge_sweep``, ``magnetometer_sets``,
``pose_means``): one judgement for calibrate, its gate, the adaptive planner
and the diagnosis.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..maths.sphere import distinct_directions
from ..sessions.session import HMC5883L_OVERFLOW, LABEL_NONE, LABEL_ROT, SessionData
from ..sessions.still import StillThresholds, gyro_bias, segment_recording
from .determine import (MODELS, ORIENTATIONS_NEEDED, Judgement, judge_poses,  # noqa: F401
                        judge_sweep, model_key)
from .gate import LIMITS, GateLimits, hull_depth

TRIM_S = 0.2               # left out at both ends of a still stretch
MIN_STILL_S = 0.6          # shortest still stretch kept (hand-held poses of 1.6 s, trimmed)
MIN_SEG_SAMPLES = 20       # and at least this many rows
TURN_AVG_S = 0.5           # the turn the gyro integrates over this long ...
TURN_DEG = 0.25            # ... must stay within this (deg; 0.5 deg/s over 0.5 s) ...
TURN_TREMOR_K = 4.0        # ... or this many times the turn in the stretch's quietest ...
TURN_QUIET_Q = 0.25        # ... quarter (tremor; the slow end of a move cannot raise it)
ARRIVE_DEG = 0.1           # a stretch's ends within this of its median orientation (deg) ...
ARRIVE_K = 3.0             # ... or this many times the median offset from it (tremor)
MIN_POSE_ORIENTATIONS = 6  # still stretches covering this many orientations are poses


def recording_parts(data: SessionData) -> np.ndarray:
    """Per row, the recording (file) it came from: rows of different files are
    never joined into one stretch."""
    part = np.zeros(len(data), np.int64)
    for i, f in enumerate((data.meta or {}).get("files") or []):
        rows = f.get("rows") if isinstance(f, dict) else None
        if rows and len(rows) == 2:
            part[int(rows[0]):int(rows[1])] = i + 1
    return part


def still_stretches(data: SessionData) -> np.ndarray:
    """Per row, the still stretch 1..K it is in (0: moving), see the module doc."""
    lab = np.zeros(len(data), np.int32)
    if not len(data):
        return lab
    part = recording_parts(data)
    t = data.sample_times()
    th = StillThresholds(min_still_s=MIN_STILL_S)
    for p in np.unique(part):
        m = np.flatnonzero(part == p)
        sub = segment_recording(data.raw[m], t[m], data.rate(), data.scales, th, trim_s=TRIM_S)
        sub = trim_turning(sub, data.raw[m], data.rate(), data.scales)
        sub[sub > 0] += lab.max()
        lab[m] = sub
    return lab


def trim_turning(lab: np.ndarray, raw: np.ndarray, rate: float, scales) -> np.ndarray:
    """Keep the parts of each stretch where the board does not turn: the
    rotation the gyroscope integrates over ``TURN_AVG_S`` (the rate less its
    bias: the running median over every stretch, ``still.gyro_bias``, so
    that a stretch that is all the slow end of a move shows its turn) must
    stay within ``TURN_DEG`` or
    ``TURN_TREMOR_K`` times the turn over that time in the stretch's
    quietest quarter (``TURN_QUIET_Q``; a hand's tremor turns the board back
    and forth by a few tenths of a degree and goes nowhere, the slow start
    or end of a move keeps going).  A
    stretch broken by a turn becomes two; parts shorter than
    ``MIN_SEG_SAMPLES`` are dropped; numbers stay 1..K."""
    g = raw[:, 3:6]
    if np.isnan(g).all() or not (lab > 0).any():
        return lab
    K = float((scales or {}).get("gyro", 14.375))
    w = max(1, int(round(TURN_AVG_S * rate)))
    gd = g / K
    bias = gyro_bias(np.where(np.isnan(gd), np.nanmedian(gd, axis=0), gd), rate, lab > 0)
    out = np.zeros_like(lab)
    k = 0
    for s in np.unique(lab[lab > 0]):
        idx = np.flatnonzero(lab == s)
        x = gd[idx]
        if np.isnan(x).any() or len(idx) < 2 * w:
            parts = [idx]
        else:
            ok = steady(x - bias[idx], rate, w)
            edges = np.flatnonzero(np.diff(np.concatenate([[0], ok.astype(np.int8), [0]])))
            parts = [idx[a:b] for a, b in zip(edges[::2], edges[1::2])]
        for keep in parts:
            if len(keep) >= MIN_SEG_SAMPLES:
                k += 1
                out[keep] = k
    return out


def steady(x: np.ndarray, rate: float, w: int) -> np.ndarray:
    """Per row of one stretch's bias-free gyro rates ``x`` (deg/s): the turn
    over the ``w`` rows around it is within the stretch's noise and tremor
    (see ``trim_turning``)."""
    n = len(x)
    theta = np.vstack([np.zeros(3), np.cumsum(x, axis=0) / rate])
    lo = np.clip(np.arange(n) - w // 2, 0, n - w)
    turn = np.linalg.norm(theta[lo + w] - theta[lo], axis=1)
    ok = turn <= max(TURN_DEG, TURN_TREMOR_K * float(np.quantile(turn, TURN_QUIET_Q)))
    # the ends: still arriving at (or leaving) the hold's orientation -- the
    # last tenths of a degree of a move, within one window's turn limit
    # but one-way -- are trimmed while the board is off the orientation it
    # holds (the stretch's median) by more than ARRIVE_DEG or ARRIVE_K times
    # its median offset (tremor)
    off = np.linalg.norm(theta[1:] - np.median(theta[1:], axis=0), axis=1)
    near = off <= max(ARRIVE_DEG, ARRIVE_K * float(np.median(off)))
    if near.any():
        a, b = int(np.argmax(near)), n - int(np.argmax(near[::-1]))
        ok[:a] = False
        ok[b:] = False
    return ok


def stretch_orientations(data: SessionData, lab: np.ndarray) -> int:
    """Distinct orientations (gravity directions >= 10 deg apart) that the
    stretches ``lab`` cover; 0 without an accelerometer."""
    acc = data.has("accel")
    ks = [k for k in np.unique(lab[lab > 0]) if (acc & (lab == k)).any()]
    if not ks:
        return 0
    x = data.sensor("accel")
    means = np.array([x[acc & (lab == k)].mean(axis=0) for k in ks])
    return int(distinct_directions(means))


def describe(data: SessionData, lab: np.ndarray) -> str:
    """What a session without pose labels holds, in words, from its still
    stretches ``lab`` (``still_stretches``): poses (at least
    ``MIN_POSE_ORIENTATIONS`` distinct orientations), a hold (one or a few),
    or no still data; the rows between them are judged as a sweep per sensor
    (the gate's coverage rule), so a recording can be both."""
    k = int(lab.max()) if len(lab) else 0
    n = stretch_orientations(data, lab) if k else 0
    what = ("static poses" if n >= MIN_POSE_ORIENTATIONS else
            "a hold in one orientation" if n == 1 else
            f"a hold in {n} orientations" if n else "no still data")
    moving = float(np.mean(lab == 0)) if len(lab) else 1.0
    return (f"{k} still stretch{'es' if k != 1 else ''} found on the board's orientation, "
            f"covering {n} distinct orientation{'s' if n != 1 else ''}: {what}; "
            f"{moving:.0%} of the rows move (judged as a sweep by the coverage they reach)")


def poses_from_stillness(data: SessionData) -> tuple[SessionData, str | None]:
    """A session without pose labels whose still stretches cover at least
    ``MIN_POSE_ORIENTATIONS`` distinct orientations holds static poses: a
    copy with those stretches labelled 1..K (rows labelled a rotation keep
    that label between them, so a recording can be both), and a note saying
    so.  An unlabelled session (no rotation label either) whose stretches
    cover fewer orientations is a hold: they are labelled too (the
    gyroscope's still data; ``judge_poses`` then finds what, if anything,
    they determine for the others), and the note says so.  Anything else is
    returned as it is, with None."""
    if not len(data) or (data.label >= 1).any():
        return data, None
    lab = still_stretches(data)
    n = stretch_orientations(data, lab)
    was = "a rotation" if (data.label == LABEL_ROT).any() else "unlabelled"
    if not (lab > 0).any() or (n < MIN_POSE_ORIENTATIONS and was != "unlabelled"):
        return data, None
    label = data.label.copy()
    label[lab > 0] = lab[lab > 0]
    k = int(lab.max())
    if n < MIN_POSE_ORIENTATIONS:
        what = "one orientation" if n <= 1 else f"{n} orientations"
        note = (f"a hold found in the data: {k} still stretch{'es' if k != 1 else ''} in "
                f"{what} (the recording was unlabelled): still data for the gyroscope")
        return dataclasses.replace(data, label=label,
                                   meta=dict(data.meta or {}, still_found="hold")), note
    note = (f"static poses found in the data: {k} still stretches covering {n} "
            f"distinct orientations (the recording was labelled {was}); the rows between "
            f"them stay {'the sweep' if was == 'a rotation' else 'unlabelled'}")
    return dataclasses.replace(data, label=label), note


def labelled_poses(data: SessionData) -> bool:
    """The session's poses are poses: labelled when recorded or imported (a
    guided log, an import's one pose per file) or found in six or more
    orientations, not a hold ``poses_from_stillness`` found in an unlabelled
    recording.  Data meant for the accelerometer, which a calibrate that
    cannot use them refuses rather than skips."""
    return bool((data.label >= 1).any()) and (data.meta or {}).get("still_found") != "hold"


def pose_means(data: SessionData, sensor: str, rows=None) -> tuple[np.ndarray, np.ndarray]:
    """(labels, mean reading per static pose in nominal units (K, 3)) of
    ``sensor`` over ``rows`` (default: every row with it), poses label >= 1
    (overflowed magnetometer readings left out)."""
    x = data.sensor(sensor)
    ok = data.has(sensor) & (data.label >= 1) & (True if rows is None else rows)
    if sensor == "mag":
        ok &= ~(x == HMC5883L_OVERFLOW).any(axis=1)
    labs, inv = np.unique(data.label[ok], return_inverse=True)
    if not len(labs):
        return labs, np.zeros((0, 3))
    sums = np.zeros((len(labs), 3))
    np.add.at(sums, inv, x[ok])
    return labs, sums / np.bincount(inv, minlength=len(labs))[:, None] / data.scales[sensor]


def magnetometer_sets(data: SessionData, limits: GateLimits = LIMITS) -> dict:
    """Every magnetometer data set of the session and what it determines,
    ``{"R": (mask, Judgement), "O": (mask, Judgement)}``: R = the rotation
    rows (every row of a session without labels), O = the static poses;
    overflowed readings (-4096) left out, sets under 10 rows dropped.  R is
    judged as a sweep (``judge_sweep``), O by its pose means
    (``judge_poses``, asking the gate's hull depth: a set of poses the gate
    would call too clustered is not fitted)."""
    ok = data.has("mag") & ~(data.sensor("mag") == HMC5883L_OVERFLOW).any(axis=1)
    sets = {}
    if (data.label == LABEL_ROT).any():
        sets["R"] = ok & (data.label == LABEL_ROT)
    elif not (data.label >= 1).any():
        sets["R"] = ok & (data.label == LABEL_NONE)
    if (data.label >= 1).any():
        sets["O"] = ok & (data.label >= 1)
    out = {}
    for name, rows in sets.items():
        if rows.sum() < 10:
            continue
        if name == "R":
            j = judge_sweep("mag", data.sensor("mag")[rows] / data.scales["mag"], limits)
        else:
            # poses not meant for the magnetometer (the six faces) are fitted
            # only when the gate could accept them: its own surround limit
            j = judge_poses("mag", pose_means(data, "mag", rows)[1], limits,
                            surround=limits.min_hull_depth)
        out[name] = (rows, j)
    return out


# What a session's static poses can determine beyond the affine map (issue
# 13, the terms a diagnosis asks calibrate to fit): one judgement, used by
# calib.loop before any such term is fitted.
MIN_ORIENTATIONS_TERM = {"g_sensitivity": 6, "nonlinearity": 24}
MIN_DRIFT_POSES = 6
MIN_DRIFT_SPAN_S = 60.0


def term_support(term: str, directions: np.ndarray, times: np.ndarray | None = None) -> str | None:
    """Why the static poses (their mean gravity ``directions``, and mid-times
    ``times`` in s) cannot determine ``term``, or None when they can:
    ``g_sensitivity`` needs the gravity directions to surround the origin
    with at least 6 distinct orientations (3 x 3 coefficients besides the
    bias); ``nonlinearity`` at least 24 distinct orientations (9 terms on
    top of the 9 of the full model, with room to hold poses out);
    ``bias_drift`` at least 6 poses spread over at least 60 s."""
    d = np.asarray(directions, float)
    n = int(distinct_directions(d)) if len(d) else 0
    if term in MIN_ORIENTATIONS_TERM:
        need = MIN_ORIENTATIONS_TERM[term]
        if n < need:
            return f"too few distinct orientations: {n} (at least {need} for {term})"
        if term == "g_sensitivity" and hull_depth(d) < LIMITS.min_hull_depth:
            return "the poses' gravity directions do not surround the origin"
        return None
    if term == "bias_drift":
        if times is None or len(times) < MIN_DRIFT_POSES:
            return f"fewer than {MIN_DRIFT_POSES} still poses"
        span = float(np.ptp(times))
        if span < MIN_DRIFT_SPAN_S:
            return f"the poses span {span:.0f} s (at least {MIN_DRIFT_SPAN_S:g} s for a drift)"
        return None
    return f"no {term} term in the calibration"


# --------------------------------------------------------------------------
# temperature (issue 16): what a session's temperature can determine
# --------------------------------------------------------------------------
MIN_TEMP_SPAN_C = 2.0      # still data must cover this span for a temperature term
HOLD_MIN_S = 30.0          # a still pose at least this long is a hold (a warm-up, say)


@dataclasses.dataclass
class TempContent:
    """The temperature a session carries, judged once for calibrate and
    diagnose: its range over the still rows (static poses and holds), the
    labels of the holds (poses of at least ``HOLD_MIN_S``) and the
    temperature span that the holds and the other poses each cover."""
    has_temp: bool
    lo: float = float("nan")
    hi: float = float("nan")
    holds: tuple = ()               # pose labels that are holds
    hold_span_c: float = 0.0        # the largest span within one hold
    pose_span_c: float = 0.0        # span of the other poses' mean temperatures
    why: str | None = None          # why no temperature term can be determined (None: one can)

    @property
    def span_c(self) -> float:
        return 0.0 if not self.has_temp else float(self.hi - self.lo)


def hold_labels(data: SessionData) -> list[int]:
    """Pose labels whose still rows last at least ``HOLD_MIN_S`` seconds."""
    t = data.sample_times()
    out = []
    for p in np.unique(data.label[data.label >= 1]):
        m = data.label == p
        if t[m].max() - t[m].min() >= HOLD_MIN_S:
            out.append(int(p))
    return out


def temperature_content(data: SessionData) -> TempContent:
    """See ``TempContent``.  ``why`` is None when the still data span at
    least ``MIN_TEMP_SPAN_C``, within a hold or across the poses."""
    if not data.has_temp:
        return TempContent(False, why="the session carries no temperature")
    still = (data.label >= 1) & np.isfinite(data.temp)
    if not still.any():
        return TempContent(True, why="no still rows with a temperature (static poses or holds)")
    T = data.temp
    holds = hold_labels(data)
    hold_span = max((float(np.ptp(T[still & (data.label == h)])) for h in holds), default=0.0)
    others = [p for p in np.unique(data.label[still]) if p not in holds]
    pm = [float(np.mean(T[still & (data.label == p)])) for p in others]
    pose_span = float(np.ptp(pm)) if len(pm) >= 2 else 0.0
    c = TempContent(True, float(T[still].min()), float(T[still].max()), tuple(holds),
                    hold_span, pose_span)
    if max(hold_span, pose_span) < MIN_TEMP_SPAN_C:
        c.why = (f"the still data span {max(hold_span, pose_span):.2f} C within a hold or "
                 f"across the poses (at least {MIN_TEMP_SPAN_C:g} C: a warm-up hold of several "
                 f"minutes after power-on, or poses across a span)")
    return c
