"""Closing the loop (issue 13): what each finding of a diagnosis (the JSON
``motecal diagnose`` writes or keeps with the session: ``{"clean",
"findings", "model"}``) asks of a calibration, as a ``Treatment``:

* ``stale_samples``: the repeated readings (equal on all axes to the
  sensor's previous reading) to leave out;
* ``saturation``: the readings at a clipped limit (or an overflow code) to
  leave out, a static pose with any of them whole;
* ``unexplained`` with outlier readings (a sweep): those readings (a
  trimmed fit);
* ``field_disturbance``: beyond what a calibration can go through (the
  gate's rule), the magnetometer refused; else the disturbed time spans of
  the sweep (a term ``calib.loop`` finds and cuts);
* ``nonlinearity`` (accel), ``g_sensitivity`` and ``bias_drift`` (gyro):
  terms ``calib.extra_terms`` fits;
* anything else (cross-axis, already in the full model; drift of the
  accelerometer or magnetometer; motion): not used, and the reason.

Whether a treatment or term is then used is ``calib.loop``'s decision, on
held-out data.  ``apply_diagnosis`` applies every row-dropping treatment at
once (the bench's 'every treatment' arm).  Pure functions on a
``SessionData`` and the diagnosis' JSON.
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
    """Rows whose reading equals the sensor's previous reading on all axes
    (rows without a reading of this sensor in between are skipped: a sensor
    read more slowly than the rows come)."""
    rep = np.zeros(len(x), bool)
    idx = np.flatnonzero(np.all(np.isfinite(x), axis=1))
    if len(idx) > 1:
        rep[idx[1:]] = np.all(x[idx[1:]] == x[idx[:-1]], axis=1)
    return rep


@dataclasses.dataclass
class Treatment:
    """What one finding does to the data a calibration is fitted on."""
    sensor: str
    cause: str
    text: str                          # what the user is told
    drop: np.ndarray | None = None     # rows whose readings of ``sensor`` are left out
    refuse: str | None = None          # the sensor cannot be calibrated (this reason)
    term: str | None = None            # a model term to fit (calib.extra_terms)
    used: bool = True                  # False: not used (``text`` says why)


def treatments(data: SessionData, diagnosis: dict) -> list:
    """One ``Treatment`` per finding of the diagnosis (see the module doc)."""
    raw = data.raw.astype(float)
    out = []
    t = data.sample_times()
    for f in diagnosis.get("findings", []):
        s, c = f.get("sensor"), f.get("cause")
        if s not in SENSOR_SLICES:
            continue
        x = raw[:, SENSOR_SLICES[s]]
        ev, params = f.get("evidence") or {}, f.get("params") or {}
        if c == "stale_samples":
            rep = _repeats(x)
            out.append(Treatment(s, c, f"{s} stale_samples: {int(rep.sum())} repeated readings", drop=rep))
        elif c == "saturation":
            bad = np.zeros(len(x), bool)
            for h in ev.get("limits", []):
                try:
                    a = "xyz".index(h["axis"])
                    bad |= x[:, a] == float(h["limit_counts"])
                except (KeyError, ValueError, TypeError):
                    continue
            if "overflow_code" in params:
                bad |= np.all(x == float(params["overflow_code"]), axis=1)
            # a static pose with clipped readings: its other readings are a
            # truncated sample (their mean is biased), so the whole pose goes
            poses = np.unique(data.label[bad & (data.label >= 1)])
            whole = np.isin(data.label, poses) & (data.label >= 1)
            out.append(Treatment(s, c, f"{s} saturation: {int(bad.sum())} clipped readings" + (f" ({len(poses)} poses with them, whole)"
                                                if len(poses) else ""), drop=bad | whole))
        elif c == "unexplained" and ev.get("outlier_times_s"):
            times = np.asarray(ev["outlier_times_s"], float)
            idx = np.searchsorted(t, times)
            bad = np.zeros(len(x), bool)
            for i, tt in zip(idx, times):
                near = [j for j in (i - 1, i) if 0 <= j < len(t)]
                j = min(near, key=lambda j: abs(t[j] - tt)) if near else None
                if j is not None and abs(t[j] - tt) <= TIME_MATCH_S:
                    bad[j] = True
            out.append(Treatment(s, "outliers", f"{s} outliers: {int(bad.sum())} readings far off", drop=bad))
        elif c == "field_disturbance":
            if ev.get("untrustworthy"):
                why = ("the diagnosis found the field disturbed beyond what a calibration can "
                       "go through" + (f" ({ev['gate']})" if ev.get("gate") else ""))
                out.append(Treatment(s, c, f"{s} field_disturbance: magnetometer not "
                                           "calibratable", refuse=why))
            else:
                out.append(Treatment(s, c, f"{s} field_disturbance: the disturbed time spans "
                                           "left out", term="disturbed_spans"))
        elif c == "cross_axis":
            out.append(Treatment(s, c, f"{s} cross_axis: already in the full model "
                                       "(--model full)", used=False))
        elif c == "temperature":
            out.append(Treatment(s, c, f"{s} temperature: calibrate fits it itself when the "
                                       "session carries the temperature (calib.thermal)",
                                 used=False))
        elif (s, c) in FITTED_TERMS:
            out.append(Treatment(s, c, f"{s} {c}: fitted", term=c))
        else:
            out.append(Treatment(s, c, f"{s} {c}: the calibration has no {c} term", used=False))
    return out


# (sensor, cause) the calibration can fit as a term of its own (calib.extra_terms)
FITTED_TERMS = {("accel", "nonlinearity"), ("gyro", "g_sensitivity"), ("gyro", "bias_drift")}


def drop_rows(data: SessionData, items) -> SessionData:
    """A copy of ``data`` with the readings the treatments ``items`` leave out
    set to NaN (for their sensor only)."""
    raw = data.raw.astype(float).copy()
    for tr in items:
        if tr.drop is not None:
            raw[tr.drop, SENSOR_SLICES[tr.sensor]] = np.nan
    return dataclasses.replace(data, raw=raw)


def apply_diagnosis(data: SessionData, diagnosis: dict) -> tuple[SessionData, list, list, dict]:
    """Every row-dropping treatment applied at once, without the held-out
    check of ``calib.loop`` (the bench's 'all of them' arm): (data with the
    readings the findings make wrong left out, lines used, lines not used,
    {sensor: reason it cannot be calibrated})."""
    items = treatments(data, diagnosis)
    used = [tr.text + (" left out" if tr.drop is not None else "") for tr in items
            if tr.used and tr.term is None]
    unused = [tr.text for tr in items if not tr.used]
    refuse = {tr.sensor: tr.refuse for tr in items if tr.refuse}
    return drop_rows(data, items), used, unused, refuse
