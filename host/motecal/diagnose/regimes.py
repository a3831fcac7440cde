"""What a sensor's observations allow (its regime: poses, a sweep, a single
pose, still blocks), the candidate causes each regime can test (the plan of
tests), and the accelerometer's specific force during the gyroscope's still
blocks: shared by the diagnosis (``engine``) and the statistics of the
comparison (``compare``)."""
from __future__ import annotations

import numpy as np

from ..calib.content import ORIENTATIONS_NEEDED, judge_poses, judge_sweep
from . import structure as ST
from .prepare import SensorObs

MIN_SWEEP_ROWS = 200

# the causes each regime's observations can test (structure.analyse_*)
CANDIDATES = {
    "poses": ["cross_axis", "nonlinearity", "bias_drift"],
    "sweep": ["cross_axis", "field_disturbance"],
    "single": ["bias_drift"],
    "still": ["g_sensitivity", "bias_drift"],
}


def regime(obs: SensorObs) -> str | None:
    """The sensor's regime.  ``poses``: still segments whose means determine
    the full model by calibrate's own judgement (``calib.content.judge_poses``:
    distinct orientations around the centre, the Jacobian's rank), with at
    least ``structure.MIN_POSES`` of them (the full model's 9 and room for the
    tests); ``sweep``: magnetometer readings that determine it as a sweep
    (``judge_sweep``); else ``single`` with any still segment."""
    s = obs.sensor
    nseg = 0 if obs.segs is None else len(obs.segs)
    if s == "gyro":
        return "still" if obs.blocks is not None else None
    if nseg >= max(ST.MIN_POSES, ORIENTATIONS_NEEDED["full"]):
        j = judge_poses(s, obs.segs.mean / obs.K)
        if j.determines("full") and j.orientations >= ST.MIN_POSES:
            return "poses"
    if s == "mag" and obs.moving is not None and obs.moving.sum() >= MIN_SWEEP_ROWS \
            and sweep_surrounds(obs):
        return "sweep"
    if nseg >= 1:
        return "single"
    return None


def sweep_reasons(obs: SensorObs) -> list:
    """Why the readings cannot determine a magnetometer model as a sweep, by
    the very rule ``calibrate`` applies (``calib.content.judge_sweep``:
    directions from the best-fitting sphere's centre must surround it, hull
    depth >= 0.3, fill >= 80 % of the sphere's equal-area cells, and the
    sphere be larger than the readings' noise); empty when they can.  A turn
    about one axis (a circle), a cap, a few poses' worth of readings or a
    hold cannot: no calibration term is then tested or claimed."""
    x = obs.x[~obs.overflow]
    if len(x) < 10:
        return ["fewer than 10 readings"]
    return list(judge_sweep("mag", x / obs.K).reasons.get("full", []))


def sweep_surrounds(obs: SensorObs) -> bool:
    return not sweep_reasons(obs)


def shared_rows(a: SensorObs | None, b: SensorObs | None) -> bool:
    return a is not None and b is not None and len(a.rows) == len(b.rows) and \
        np.array_equal(a.rows, b.rows)


def accel_for_blocks(g: SensorObs, acc_st, acc: SensorObs | None):
    """Specific force (g) during each gyro block, from the calibrated
    accelerometer (its starting model when fitted, else nominal scale)."""
    if acc is None:
        return None
    out = np.full((len(g.blocks), 3), np.nan)
    shared = shared_rows(acc, g)
    for i, rows in enumerate(g.blocks.rows):
        if shared:
            xa = acc.x[rows]
        else:
            t0, t1 = g.t[rows[0]], g.t[rows[-1]]
            m = (acc.t >= t0) & (acc.t <= t1)
            if m.sum() < 3:
                continue
            xa = acc.x[m]
        out[i] = xa.mean(axis=0)
    if np.isnan(out).any():
        return None
    if acc_st is not None and acc_st.regime == "poses":
        fit = acc_st.fit0
        return fit.calibrate(out, np.zeros(len(out)))
    return out / acc.K


def plan_tests(obs: dict) -> list:
    """Every (sensor, cause) the observations allow testing: the screens on
    every sensor, each regime's candidates and its leftover scatter
    (``excess``), and ``motion`` when accelerometer and gyroscope share a
    clock.  Their count sets the Bonferroni level."""
    plan = []
    for s, o in obs.items():
        plan += [(s, "stale_samples"), (s, "saturation")]
        r = regime(o)
        if r:
            cands = list(CANDIDATES[r])
            if s == "gyro" and "accel" not in obs:
                cands.remove("g_sensitivity")
            plan += [(s, c) for c in cands]
            plan.append((s, "excess"))
    if shared_rows(obs.get("accel"), obs.get("gyro")) and obs["accel"].segs is not None:
        plan.append(("accel", "motion"))
    return plan
