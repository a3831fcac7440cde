"""imucal's calibration JSON (``FerrarisCalibrationInfo``, format 2.0).

imucal applies ``acc = inv(R_a) inv(K_a) (raw - b_a)`` (m/s^2) and ``gyr =
inv(R_g) inv(K_g) (raw - K_ga acc - b_g)`` (deg/s), raw in counts
(``from_acc_unit`` / ``from_gyr_unit`` "a.u."), ``K`` diagonal and the rows
of ``R`` of unit length (as its Ferraris fit makes them).  motecal's affine
maps fit exactly: ``K R = inv(g A)`` with ``K`` the row norms, ``b = -inv(A)
c``, ``K_ga = 0`` (motecal does not model the gyroscope's g-sensitivity).
m/s^2 uses imucal's default g = 9.81.  imucal has no magnetometer.
"""
from __future__ import annotations

import json

import numpy as np

from .common import Export, ExportOptions, Target

GRAV = 9.81                   # imucal's FerrarisCalibration default


def _kr(M):
    K = np.linalg.norm(M, axis=1)
    return np.diag(K), M / K[:, None]


def info(board) -> dict:
    d = {"acc_unit": "m/s^2", "gyr_unit": "deg/s", "from_acc_unit": "a.u.",
         "from_gyr_unit": "a.u.",
         "comment": f"motecal calibration for mote {board.mote}, session '{board.session}' "
                    f"({board.created}); g = {GRAV}"}
    if board.accel is not None:
        A, c = board.accel.A, board.accel.c
        K, R = _kr(np.linalg.inv(GRAV * A))
        d.update(K_a=K.tolist(), R_a=R.tolist(), b_a=(-np.linalg.solve(A, c)).tolist())
    if board.gyro is not None:
        A, c = board.gyro.A, board.gyro.c
        K, R = _kr(np.linalg.inv(A))
        d.update(K_g=K.tolist(), R_g=R.tolist(), K_ga=np.zeros((3, 3)).tolist(),
                 b_g=(-np.linalg.solve(A, c)).tolist())
    d.update(cal_type="Ferraris", _format_version="2.0")
    return d


def apply_fns(d: dict) -> dict:
    """imucal's formulas on its JSON fields (what the package computes), in g and deg/s."""
    out = {}
    if "K_a" in d:
        Ma = np.linalg.inv(np.array(d["R_a"])) @ np.linalg.inv(np.array(d["K_a"]))
        ba = np.array(d["b_a"])
        out["accel"] = lambda raw, ba=ba, Ma=Ma: (np.asarray(raw, float) - ba) @ Ma.T / GRAV
    if "K_g" in d:
        Mg = np.linalg.inv(np.array(d["R_g"])) @ np.linalg.inv(np.array(d["K_g"]))
        bg = np.array(d["b_g"])
        out["gyro"] = lambda raw, bg=bg, Mg=Mg: (np.asarray(raw, float) - bg) @ Mg.T
    return out


def write(board, opts: ExportOptions = ExportOptions()) -> Export:
    d = info(board)
    text = json.dumps(d, indent=4) + "\n"
    lost = {}
    if board.mag is not None:
        lost["mag"] = ["not held: imucal calibrates accelerometer and gyroscope only"]
    if board.accel is not None and board.gyro is not None:
        lost["gyro"] = ["held whole (K_ga, the g-sensitivity imucal can hold, is 0: motecal "
                        "does not fit it)"]
    return Export("imucal", text, apply_fns(json.loads(text)), lost,
                  {s: "JSON floats (17 digits): exact" for s in ("accel", "gyro")
                   if getattr(board, s) is not None},
                  frame="as the calibration's (imucal's sensor frame is the data's)")


TARGETS = (Target("imucal", "imucal's FerrarisCalibrationInfo JSON (format 2.0)", write),)
