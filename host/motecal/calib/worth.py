"""What a calibration is worth in the user's terms (issue 25): the tilt an
accelerometer reading gives and the heading a magnetometer reading gives,
and how far off they are after this calibration.

Two parts, both rms over directions:

* **one reading**: the readings kept scatter about the calibrated gravity or
  field by the fit's robust sd (``quality.robust_sd_rel``, a fraction of 1 g
  or of the field); taken as isotropic, a reading's direction is off by that
  many radians; a heading uses the field's horizontal part, ``cos(dip)`` of
  it, so it is off by ``robust_sd_rel / cos(dip)`` rad;
* **the calibration itself**: its parameters' uncertainty
  (``SensorCalibration.affine_cov``), propagated to the calibrated vector of
  2000 fresh directions (``DRAWS`` draws), the part across the direction;
  for a heading divided by ``cos(dip)`` again.

The dip (the field's angle below the horizon) is not known from a sweep:
``DIP_DEG`` (60 deg, mid-latitudes) is assumed and said; where the dip is d,
the heading figures scale by ``cos 60 / cos d``.  Pure functions; the
result goes to ``quality["worth"]`` and a note.
"""
from __future__ import annotations

import numpy as np

from ..maths.sphere import fibonacci_sphere

DIP_DEG = 60.0
DRAWS = 64


def _own_error(sc, magnitude: float, n_dirs: int = 500) -> float | None:
    """rms (over directions and draws of the parameters) of the calibrated
    vector's error across its direction, relative to ``magnitude``."""
    cov = getattr(sc, "affine_cov", None)
    if cov is None or not np.all(np.isfinite(cov)):
        return None
    A, c = np.asarray(sc.A, float), np.asarray(sc.c, float)
    v = magnitude * fibonacci_sphere(n_dirs)
    raw = np.linalg.solve(A, (v - c).T).T                    # counts giving those vectors
    w, V = np.linalg.eigh(0.5 * (cov + cov.T))
    L = V * np.sqrt(np.clip(w, 0, None))
    rng = np.random.default_rng(12345)
    d = rng.standard_normal((DRAWS, len(w))) @ L.T           # draws of (A row-major, c)
    dA = d[:, :9].reshape(-1, 3, 3)
    dc = d[:, 9:12]
    dv = np.einsum("kij,nj->kni", dA, raw) + dc[:, None, :]
    u = v / magnitude
    across = dv - np.sum(dv * u, axis=-1, keepdims=True) * u
    return float(np.sqrt(np.mean(np.sum(across * across, axis=-1)) / 2)) / magnitude


def assess(sc, dip_deg: float = DIP_DEG) -> dict | None:
    """``{"what", "reading_deg", "calibration_deg", "dip_deg"}`` for an
    accelerometer (tilt) or magnetometer (heading) calibration, or None."""
    q = sc.quality or {}
    sd = q.get("robust_sd_rel")
    if sd is None or sc.sensor not in ("accel", "mag"):
        return None
    mag = 1.0 if sc.sensor == "accel" else float(sc.field_gauss or 0.0)
    if not mag > 0:
        return None
    own = _own_error(sc, mag)
    k = 1.0 if sc.sensor == "accel" else 1.0 / np.cos(np.radians(dip_deg))
    out = {"what": "tilt" if sc.sensor == "accel" else "heading",
           "reading_deg": float(np.degrees(sd * k)),
           "calibration_deg": None if own is None else float(np.degrees(own * k))}
    if sc.sensor == "mag":
        out["dip_deg"] = dip_deg
    return out


def text(w: dict, sd_rel: float) -> str:
    own = w.get("calibration_deg")
    if w["what"] == "tilt":
        where = f"the readings kept scatter {100 * sd_rel:.2g} % of 1 g (robust sd)"
    else:
        where = (f"the readings kept scatter {100 * sd_rel:.2g} % of the field (robust sd); at a "
                 f"dip of {w['dip_deg']:g} deg (assumed: a sweep does not give it; where it is "
                 f"d, multiply by cos {w['dip_deg']:g} / cos d)")
    return (f"worth: a {w['what']} from one reading is off by about {w['reading_deg']:.2g} deg "
            f"rms ({where})" + (f"; the calibration itself adds about {own:.2g} deg (from its "
                                "parameters' standard deviations, which take the readings as "
                                "independent: more where they are correlated in time)"
                                if own is not None else ""))


def attach(board) -> None:
    """Every accelerometer and magnetometer calibration of the board gets
    ``quality["worth"]`` and the note."""
    for name, sc in board.sensors():
        w = assess(sc)
        if w is None:
            continue
        sc.quality["worth"] = w
        sc.quality["worth_text"] = text(w, sc.quality["robust_sd_rel"])
        sc.notes.append(sc.quality["worth_text"])
