"""The seed paper's Tables I-III computed from one board's session (for
``motecal report`` and the benchmark).

* ``table1`` -- accelerometer: error (MSE of the magnitude, g^2) and
  lowest/highest magnitude before and after, for every parameter subset of
  the paper model and for the full model.
* ``table2`` -- gyroscope: eq. 6 before and after, the biases (deg/s).
* ``table3`` -- magnetometer, per data set (O: static poses, R: rotation):
  fitted field (gauss), error with offsets only and with all parameters
  (paper model) and with the full model, in gauss^2.

Each returns a list of dicts (one per row); ``markdown`` formats them.
"""
from __future__ import annotations

import numpy as np

from ..session import SessionData
from . import fit as _fit
from . import gyro as _gyro
from .board import mag_sets
from .models import make_model

ACCEL_ROWS = (("offsets",), ("scales",), ("offsets", "scales"),
              ("offsets", "scales", "angles"))


def _mag_stats(model, theta, u):
    A, c, H = model.affine(theta)
    m = np.linalg.norm(u @ A.T + c, axis=1)
    return float(np.mean((m - H) ** 2)), float(m.min()), float(m.max()), float(H)


def table1(data: SessionData, seed=0) -> list[dict]:
    rows = (data.label >= 1) & data.has("accel")
    u = data.sensor("accel")[rows] / data.scales["accel"]
    label = data.label[rows]
    m0 = np.linalg.norm(u, axis=1)
    out = [{"parameters": "before", "error": float(np.mean((m0 - 1) ** 2)),
            "min": float(m0.min()), "max": float(m0.max())}]
    for groups in ACCEL_ROWS + (None,):
        mdl = make_model("accel", "full" if groups is None else "paper", groups)
        s = _fit.ga_optimize(mdl, u, label, seed=seed)
        e, lo, hi, _ = _mag_stats(mdl, s.theta, u)
        out.append({"parameters": "full model" if groups is None else " + ".join(groups),
                    "error": e, "min": lo, "max": hi})
    return out


def table2(data: SessionData, seed=0) -> list[dict]:
    rows = (data.label >= 1) & data.has("gyro")
    g = data.sensor("gyro")[rows] / data.scales["gyro"]
    bf = _gyro.ga_bias(g, seed=seed)
    return [{"error_before": bf.e6_before, "error_after": bf.e6,
             "b_x": float(bf.b[0]), "b_y": float(bf.b[1]), "b_z": float(bf.b[2])}]


def table3(data: SessionData, seed=0) -> list[dict]:
    out = []
    for name, rows in mag_sets(data).items():
        u = data.sensor("mag")[rows] / data.scales["mag"]
        label = data.label[rows] if name == "O" else None
        row = {"set": name, "n": int(rows.sum())}
        for key, fam, groups in (("offsets", "paper", ("offsets",)),
                                 ("all", "paper", ("offsets", "scales", "angles")),
                                 ("full", "full", None)):
            mdl = make_model("mag", fam, groups)
            s = _fit.ga_optimize(mdl, u, label, seed=seed)
            e, _, _, H = _mag_stats(mdl, s.theta, u)
            row[f"error_{key}"] = e
            row[f"field_{key}"] = H
        out.append(row)
    return out


def markdown(rows: list[dict], fmt: dict | None = None) -> str:
    if not rows:
        return "(no rows)\n"
    fmt = fmt or {}
    keys = list(rows[0])
    lines = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    for r in rows:
        cells = []
        for k in keys:
            v = r.get(k)
            cells.append(format(v, fmt.get(k, ".6g")) if isinstance(v, float) else str(v))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"
