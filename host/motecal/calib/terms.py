"""Closing the loop (issue 13): what a diagnosis found, applied to the data a
calibration is fitted on (``motecal calibrate --diagnosis diagnosis.json``).

Pure functions on a ``SessionData`` and the diagnosis' JSON (the form
``motecal diagnose --json`` writes: ``{"clean", "findings", "model"}``).
Each finding is either *used* -- the readings it makes wrong are left out of
that sensor's fit, and the user is told how many -- or *not used*, with the
reason:

* ``stale_samples``: repeated readings (equal on all axes to the previous
  one) carry no new information and bias the noise: dropped;
* ``saturation``: readings at a clipped limit (or an overflow code) are not
  the true value: dropped;
* ``unexplained`` with outlier readings (a sweep): dropped at the listed
  times (a trimmed fit), counted;
* ``field_disturbance`` the diagnosis judged not calibratable: the
  magnetometer is refused with that reason (the same rule as the gate);
  a smaller one is calibrated through (the gate's residual limit holds it);
* terms the calibration has no parameter for (nonlinearity, g-sensitivity,
  drift, cross-axis already in the full model, motion): not used, and said.
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np

from ..errors import UserError
from ..sessions.session import SENSOR_SLICES, SessionData

TIME_MATCH_S = 0.03        # an outlier time matches the reading within this


def load_diagnosis(path) -> dict:
    """The diagnosis JSON, or one line of UserError."""
    try:
        d = json.loads(Path(path).read_text())
    except FileNotFoundError:
        raise UserError(f"--diagnosis: no such file: {path}") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise UserError(f"--diagnosis: {path} is not a diagnosis JSON ({e})") from None
    if not isinstance(d, dict) or not isinstance(d.get("findings"), list):
        raise UserError(f"--diagnosis: {path} has no 'findings' list (write it with "
                        f"motecal diagnose --json)")
    return d


def _repeats(x: np.ndarray) -> np.ndarray:
    rep = np.zeros(len(x), bool)
    if len(x) > 1:
        rep[1:] = np.all(x[1:] == x[:-1], axis=1) & np.all(np.isfinite(x[1:]), axis=1)
    return rep


def apply_diagnosis(data: SessionData, diagnosis: dict) -> tuple[SessionData, list, list, dict]:
    """(data with the readings the findings make wrong left out, lines used,
    lines not used, {sensor: reason the magnetometer cannot be calibrated})."""
    raw = data.raw.astype(float).copy()
    used, unused, refuse = [], [], {}
    t = data.sample_times()
    for f in diagnosis.get("findings", []):
        s, c = f.get("sensor"), f.get("cause")
        if s not in SENSOR_SLICES:
            continue
        sl = SENSOR_SLICES[s]
        x = raw[:, sl]
        ev, params = f.get("evidence") or {}, f.get("params") or {}
        if c == "stale_samples":
            rep = _repeats(x)
            raw[rep, sl] = np.nan
            used.append(f"{s} stale_samples: {int(rep.sum())} repeated readings left out")
        elif c == "saturation":
            bad = np.zeros(len(x), bool)
            for h in ev.get("limits", []):
                a = "xyz".index(h["axis"])
                bad |= x[:, a] == float(h["limit_counts"])
            if "overflow_code" in params:
                bad |= np.all(x == float(params["overflow_code"]), axis=1)
            # a static pose with clipped readings: its other readings are a
            # truncated sample (their mean is biased), so the whole pose goes
            poses = np.unique(data.label[bad & (data.label >= 1)])
            whole = np.isin(data.label, poses) & (data.label >= 1)
            raw[bad | whole, sl] = np.nan
            used.append(f"{s} saturation: {int(bad.sum())} clipped readings left out"
                        + (f" ({len(poses)} poses with them, whole)" if len(poses) else ""))
        elif c == "unexplained" and ev.get("outlier_times_s"):
            times = np.asarray(ev["outlier_times_s"], float)
            idx = np.searchsorted(t, times)
            bad = np.zeros(len(x), bool)
            for i, tt in zip(idx, times):
                near = [j for j in (i - 1, i) if 0 <= j < len(t)]
                j = min(near, key=lambda j: abs(t[j] - tt)) if near else None
                if j is not None and abs(t[j] - tt) <= TIME_MATCH_S:
                    bad[j] = True
            raw[bad, sl] = np.nan
            used.append(f"{s} outliers: {int(bad.sum())} readings left out (a trimmed fit)")
        elif c == "field_disturbance":
            if ev.get("untrustworthy"):
                refuse[s] = ("the diagnosis found the field disturbed beyond what a "
                             "calibration can go through" + (f" ({ev['gate']})" if ev.get("gate")
                                                             else ""))
                used.append(f"{s} field_disturbance: magnetometer not calibratable")
            else:
                unused.append(f"{s} field_disturbance: small enough to calibrate through "
                              "(the gate's residual limit holds it)")
        elif c == "cross_axis":
            unused.append(f"{s} cross_axis: already in the full model (--model full)")
        elif c == "temperature":
            unused.append(f"{s} temperature: calibrate fits it itself when the session carries "
                          "the temperature (calib.thermal)")
        else:
            unused.append(f"{s} {c}: the calibration has no {c} term")
    return dataclasses.replace(data, raw=raw), used, unused, refuse
