"""What a sensor's observations allow (its regime: poses, a sweep, a single
pose, still blocks) and the accelerometer's specific force during the
gyroscope's still blocks: shared by the diagnosis (``engine``) and the
statistics of the comparison (``compare``)."""
from __future__ import annotations

import numpy as np

from ..calib.gate import hull_depth
from ..maths.sphere import distinct_directions
from . import structure as ST
from .prepare import SensorObs

MIN_SWEEP_ROWS = 200


def regime(obs: SensorObs) -> str | None:
    s = obs.sensor
    nseg = 0 if obs.segs is None else len(obs.segs)
    if s == "gyro":
        return "still" if obs.blocks is not None else None
    if nseg >= ST.MIN_POSES and distinct_directions(obs.segs.mean) >= ST.MIN_POSES:
        return "poses"
    if s == "mag" and obs.moving is not None and obs.moving.sum() >= MIN_SWEEP_ROWS \
            and sweep_surrounds(obs):
        return "sweep"
    if nseg >= 1:
        return "single"
    return None


MIN_SWEEP_HULL = 0.2    # a sweep's directions must surround its centre this deep


def sweep_surrounds(obs: SensorObs) -> bool:
    """Do the readings' directions (from the mid-range centre) surround it?
    A turn about one axis draws a circle: offsets and scales along that axis
    are then not identifiable and no calibration term can be tested."""
    x = obs.x[~obs.overflow]
    if len(x) < 10:
        return False
    c = 0.5 * (np.percentile(x, 1, axis=0) + np.percentile(x, 99, axis=0))
    return hull_depth((x - c)[:: max(1, len(x) // 2000)]) >= MIN_SWEEP_HULL


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
