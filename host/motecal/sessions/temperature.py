"""The board temperature of every sample row, from temperature readings.

A mote sends its temperature every ``NINEDOF_TEMP_PERIOD_MS`` (1 s) as the
sum of one ITG3200 TEMP_OUT reading per sample over the period
(``ninedof_mote_temp_msg``: ``seq`` = the newest sample in the sum, ``count``
= readings summed); the store keeps one row per reading (mean in degrees C,
``count``), an import one per row that has a temperature (``count`` 1).

``rows_from_readings`` gives each sample row its temperature by the sequence
numbers of the same mote: a reading stands at the middle of the samples it
averages (``seq - (count - 1) / 2``), rows between two readings are
interpolated linearly, rows before the first or after the last reading (or
in a gap of more than ``GAP_S`` between two) take the nearest reading if it
is within ``EDGE_S`` seconds (at the session's sample rate), else NaN.
"""
from __future__ import annotations

import numpy as np

EDGE_S = 2.0      # nearest reading within this at the ends of the readings
GAP_S = 10.0      # readings further apart than this are not interpolated between


def reading_centres(seq, count) -> np.ndarray:
    """Where a reading stands in sequence numbers: the middle of the samples
    it averages (one reading per sample, the newest at ``seq``)."""
    count = np.maximum(np.asarray(count, float), 1.0)
    return np.asarray(seq, float) - (count - 1.0) / 2.0


def interpolate(x, xp, fp, edge: float, gap: float) -> np.ndarray:
    """Values at ``x`` from points ``(xp, fp)`` (``xp`` increasing, unique):
    linear between neighbours at most ``gap`` apart, the nearest point within
    ``edge`` elsewhere, NaN beyond.  Exact at the points themselves."""
    x = np.asarray(x, float)
    out = np.full(len(x), np.nan)
    if not len(xp):
        return out
    i = np.searchsorted(xp, x, side="right")     # xp[i-1] <= x < xp[i]
    left = i - 1
    has_l = left >= 0
    has_r = i < len(xp)
    li = np.clip(left, 0, len(xp) - 1)
    ri = np.clip(i, 0, len(xp) - 1)
    dl = np.where(has_l, x - xp[li], np.inf)
    dr = np.where(has_r, xp[ri] - x, np.inf)
    inside = has_l & has_r & (xp[ri] - xp[li] <= gap)
    out[inside] = np.interp(x[inside], xp, fp)
    near_l = ~inside & (dl <= dr) & (dl <= edge)
    near_r = ~inside & (dr < dl) & (dr <= edge)
    out[near_l] = fp[li][near_l]
    out[near_r] = fp[ri][near_r]
    return out


def rows_from_readings(row_mote, row_seq, r_mote, r_seq, r_temp, r_count,
                       rate_hz: float) -> np.ndarray | None:
    """(n,) degrees C per sample row (NaN unknown) from the readings of the
    same mote; None when there are no readings at all."""
    r_mote = np.asarray(r_mote)
    if not len(r_mote):
        return None
    row_mote = np.asarray(row_mote)
    row_seq = np.asarray(row_seq, float)
    r_temp = np.asarray(r_temp, float)
    x = reading_centres(r_seq, r_count)
    out = np.full(len(row_mote), np.nan)
    edge, gap = EDGE_S * rate_hz, GAP_S * rate_hz
    for m in np.unique(r_mote):
        sel = (r_mote == m) & np.isfinite(r_temp)
        rows = row_mote == m
        if not sel.any() or not rows.any():
            continue
        xp, fp = x[sel], r_temp[sel]
        order = np.argsort(xp, kind="stable")
        xp, fp = xp[order], fp[order]
        keep = np.concatenate([[True], np.diff(xp) > 0])    # one reading per place
        out[rows] = interpolate(row_seq[rows], xp[keep], fp[keep], edge, gap)
    return out
