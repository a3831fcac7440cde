"""The seed paper's Tables I-III computed from one board's session (for
``motecal report`` and the benchmark).

* ``table1`` -- accelerometer: error (MSE of the magnitude, g^2) and
  lowest/highest magnitude before and after, for every combination of the
  paper model's offsets, scales and angles (``ACCEL_ROWS``, as the paper
  tried) and for the full model.
* ``table2`` -- gyroscope: eq. 6 before and after, the biases (deg/s) that
  minimise it (the paper's method), and the mean of the still rates (the
  bias ``calibrate`` uses; the eq. 6 minimiser sits on whole counts); both
  on the still rates calibrate keeps (glitches set aside, ``robust``).
  Tables I and III are the paper's least squares over every sample.
* ``table3`` -- magnetometer, per data set (O: static poses, R: rotation):
  fitted field (gauss), error with offsets only and with all parameters
  (paper model) and with the full model, in gauss^2.  A set that cannot
  determine a model (``board.mag_data_sets``: the quality gate's limits) is
  not fitted; its row says why (``not_computable``).

Every fitted model carries its identifiability at the optimum (numerical
rank of the Jacobian, ``identify.analyse``): ``rank`` of ``params`` in
Table I, ``rank_<key>`` of ``params_<key>`` in Table III.  For the paper's
angles that is 6 of 9: they change nothing because they cannot.

Each returns a list of dicts (one per row); ``markdown`` formats them.
"""
from __future__ import annotations

import itertools

import numpy as np

from ..sessions.session import SessionData
from . import fit as _fit
from . import gyro as _gyro
from .board import mag_data_sets
from .models import PARAM_GROUPS, make_model
from .robust import inliers_3d

# every non-empty combination of the paper's parameter groups
ACCEL_ROWS = tuple(c for k in (1, 2, 3) for c in itertools.combinations(PARAM_GROUPS, k))
MAG_FITS = (("offsets", "paper", ("offsets",)),
            ("all", "paper", ("offsets", "scales", "angles")),
            ("full", "full", None))


def _mag_stats(model, theta, u):
    A, c, H = model.affine(theta)
    m = np.linalg.norm(u @ A.T + c, axis=1)
    return float(np.mean((m - H) ** 2)), float(m.min()), float(m.max()), float(H)


def _fit_row(mdl, u, label, seed):
    """GA + polish; (error, min, max, H, rank) at the optimum."""
    s = _fit.ga_optimize(mdl, u, label, seed=seed)
    rank = mdl.identifiability(s.theta, u).rank
    return _mag_stats(mdl, s.theta, u) + (rank,)


def table1(data: SessionData, seed=0) -> list[dict]:
    rows = (data.label >= 1) & data.has("accel")
    u = data.sensor("accel")[rows] / data.scales["accel"]
    label = data.label[rows]
    m0 = np.linalg.norm(u, axis=1)
    out = [{"parameters": "before", "error": float(np.mean((m0 - 1) ** 2)),
            "min": float(m0.min()), "max": float(m0.max()), "rank": None, "params": None}]
    for groups in ACCEL_ROWS + (None,):
        mdl = make_model("accel", "full" if groups is None else "paper", groups)
        e, lo, hi, _, rank = _fit_row(mdl, u, label, seed)
        out.append({"parameters": "full model" if groups is None else " + ".join(groups),
                    "error": e, "min": lo, "max": hi, "rank": rank, "params": mdl.d})
    return out


def table2(data: SessionData, seed=0) -> list[dict]:
    rows = (data.label >= 1) & data.has("gyro")
    g = data.sensor("gyro")[rows] / data.scales["gyro"]
    keep = inliers_3d(g, data.label[rows])          # the still rates calibrate keeps
    bf = _gyro.ga_bias(g[keep], seed=seed)
    bm = _gyro.mean_bias(g[keep], data.label[rows][keep])
    return [{"error_before": bf.e6_before, "error_after": bf.e6,
             "b_x": float(bf.b[0]), "b_y": float(bf.b[1]), "b_z": float(bf.b[2]),
             "mean_x": float(bm.b[0]), "mean_y": float(bm.b[1]), "mean_z": float(bm.b[2])}]


def table3(data: SessionData, seed=0) -> list[dict]:
    out = []
    for name, (rows, why) in mag_data_sets(data).items():
        row = {"set": name, "n": int(rows.sum())}
        u = data.sensor("mag")[rows] / data.scales["mag"]
        label = data.label[rows] if name == "O" else None
        for key, fam, groups in MAG_FITS:
            mdl = make_model("mag", fam, groups)
            if why is None:
                e, _, _, H, rank = _fit_row(mdl, u, label, seed)
            else:
                e = H = rank = None
            row[f"error_{key}"] = e
            row[f"field_{key}"] = H
            row[f"rank_{key}"] = rank
            row[f"params_{key}"] = mdl.d
        row["not_computable"] = why
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
