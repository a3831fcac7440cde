"""A drift in one orientation: the board tilting, or a bias drift?

In one orientation an accelerometer bias drift across gravity turns the
reading without changing its length, exactly as a slow tilt does.  A tilt
turns the magnetometer with it; a bias drift does not.  ``tilt_of_blocks``
measures how the accelerometer's block means move inside each still segment
(vector, length, direction), ``tilt_in_mag`` whether the magnetometer turned
the same way (the slope of its change on the turn the accelerometer
predicts: 1 a tilt, 0 a drift), and ``is_tilt`` decides
(docs/diagnosis-method.md, "Drift in a hold")."""
from __future__ import annotations

import numpy as np

from ..maths.sphere import angle_deg, unit
from .prepare import SensorObs

TILT_RATIO = 0.3        # length change / vector change below which a drift may be a tilt
TILT_MAG_SE = 0.2       # the magnetometer's tilt slope must be known this well to decide


def is_tilt(tilt: dict) -> bool:
    """An accelerometer drift in one orientation is a slow tilt only when the
    magnetometer turned with it.  Its length staying put is necessary but not
    enough: a bias drift across gravity also turns the reading without
    changing its length.  Without a magnetometer that says so, it stays a
    bias drift (the note says a tilt cannot be ruled out)."""
    if tilt["length_to_vector_change"] >= TILT_RATIO:
        return False
    b, se = tilt.get("mag_tilt_slope"), tilt.get("mag_tilt_slope_se")
    if b is None or se is None or not se < TILT_MAG_SE:
        return False
    return b > 0.5


def tilt_in_mag(acc: SensorObs, mag: SensorObs | None) -> dict:
    """Did the magnetometer turn the way the accelerometer did?  Per still
    segment, each accelerometer block's turn away from the segment's mean
    direction (phi = u x du, the part of the turn that gravity shows) predicts
    the field's change phi x m (the turn about gravity, which gravity does not
    show, is projected out of both); the slope of the field's measured change
    on that prediction is 1 for a tilt and 0 for an accelerometer bias drift."""
    if mag is None or acc.blocks is None or mag.n < 10:
        return {}
    b = acc.blocks
    P, M = [], []
    for si in np.unique(b.seg):
        idx = np.flatnonzero(b.seg == si)
        if len(idx) < 3:
            continue
        mm, keep = [], []
        for k in idx:
            sel = (mag.t >= b.t0[k]) & (mag.t <= b.t1[k]) & ~mag.overflow
            if sel.sum() >= 3:
                mm.append(mag.x[sel].mean(axis=0))
                keep.append(k)
        if len(keep) < 3:
            continue
        mm = np.array(mm)
        u = unit(b.mean[keep])
        ub = unit(u.mean(axis=0))
        mb = mm.mean(axis=0)
        phi = np.cross(ub, u - u.mean(axis=0))
        pred = np.cross(phi, mb)
        dm = mm - mb
        e = np.cross(ub, mb)
        if not np.linalg.norm(e) > 0:
            continue
        e = e / np.linalg.norm(e)
        pred = pred - np.outer(pred @ e, e)
        dm = dm - np.outer(dm @ e, e)
        P.append(pred.ravel())
        M.append(dm.ravel())
    if not P:
        return {}
    P, M = np.concatenate(P), np.concatenate(M)
    den = float(P @ P)
    if not den > 0 or len(P) < 6:
        return {}
    beta = float(P @ M) / den
    r = M - beta * P
    se = float(np.sqrt(max(r @ r, 1e-30) / max(len(P) - 1, 1) / den))
    return {"mag_tilt_slope": beta, "mag_tilt_slope_se": se}


def tilt_of_blocks(o: SensorObs) -> dict:
    """How the block means move inside each still segment: rms change of the
    vector, of its length, and of its direction (deg)."""
    b = o.blocks
    dv, dl, ang, span = [], [], [], []
    for si in np.unique(b.seg):
        m = b.seg == si
        if m.sum() < 3:
            continue
        v = b.mean[m]
        c = v.mean(axis=0)
        dv.append(np.sum((v - c) ** 2, axis=1))
        L = np.linalg.norm(v, axis=1)
        dl.append((L - L.mean()) ** 2)
        ang.append(angle_deg(v, c) ** 2)
        span.append(b.t[m].max() - b.t[m].min())
    if not dv:
        return {"length_to_vector_change": 1.0, "angle_rms_deg": 0.0, "segment_s": 1.0}
    vec = np.sqrt(np.mean(np.concatenate(dv)))
    length = np.sqrt(np.mean(np.concatenate(dl)))
    return {"length_to_vector_change": float(length / vec) if vec > 0 else 1.0,
            "angle_rms_deg": float(np.sqrt(np.mean(np.concatenate(ang)))),
            "segment_s": float(np.median(span))}
