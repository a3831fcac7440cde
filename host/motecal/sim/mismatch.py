"""The mismatch suite (issue 26): simulated worlds whose physics the fits do
not model, so that every headline figure measured on boards of the
matching model (``general``, ``thermal``) is measured on them too.

Each **block** is a set of simulator terms at a size taken from a datasheet
or the literature (docs/simulator-model.md, "The mismatch suite", gives the
source of each and says which are estimates):

==============  ===========================================================
``warmup``      a warming board: the ``thermal`` model's warm-up after
                power-on (6-12 C, 3-8 min) and its linear temperature
                coefficients, in every protocol (static80, adaptive,
                rotation sweep, hold) -- the world the temperature
                calibration assumes, and the static calibration does not
``lag``         the ADXL345 and the HMC5883L follow the ITG3200's die (which
                TEMP_OUT reads) with their own first-order lags (5-30 s)
``quadratic``   offsets and gains bend with temperature (``temperature_curve``)
``hysteresis``  offsets differ between warming and cooling, the board
                starting on its cooling branch (``temperature_hysteresis``)
``nonlinearity``  the ADXL345's nonlinearity (``nonlinearity``)
``gsens``       the ITG3200's sensitivity to linear acceleration
                (``g_sensitivity``)
``field``       the local field drifting slowly in direction and magnitude
                (``field_drift``)
==============  ===========================================================

The built-in models (``motecal sim --model NAME``, ``load_model(NAME)``):
``mismatch`` = ``general`` with every block; ``mismatch-<block>`` =
``general`` with ``warmup`` and that one block (``mismatch-warmup`` is
``general`` with ``warmup`` alone).  The benches measure a headline figure
on ``mismatch`` (``record(..., world="mismatch")``) and the single-block
models say which block breaks it.  The models are built here from
``general.json`` and ``thermal.json`` (the warm-up and the linear
coefficients are the ``thermal`` model's own), so a size lives in one place.
"""
from __future__ import annotations

import copy
import json
from pathlib import Path

MODELS_DIR = Path(__file__).resolve().parent / "models"
PREFIX = "mismatch"


def _u(lo, hi):
    return {"uniform": [lo, hi]}


def _n(sd):
    return {"normal": [0, sd]}


# block -> {"board": [terms], sensor: [(where, term)]}; where: "first", "last", or
# "after:<term id>" (after the first such term in the base model's list)
BLOCKS = {
    "warmup": None,          # the thermal model's terms (read from thermal.json)
    "lag": {"board": [{"term": "chip_lag",
                       "comment": "the package's own response time, 5-30 s (estimate; "
                                  "docs/simulator-model.md)",
                       "accel_tau_s": _u(5, 30), "mag_tau_s": _u(5, 30)}]},
    "quadratic": {
        "gyro": [("last", {"term": "temperature_curve",
                           "comment": "half the ITG-3200's ZRO variation (+-40 deg/s over "
                                      "-40..85 C) spent on a curve",
                           "offset_per_c2": _u(-0.075, 0.075)})],
        "accel": [("last", {"term": "temperature_curve",
                            "comment": "half the ADXL345's zero-g change (+-0.8 / +-4.5 mg/C) "
                                       "over +-62.5 C spent on a curve",
                            "offset_per_c2": [_u(-0.0016, 0.0016), _u(-0.0016, 0.0016),
                                              _u(-0.009, 0.009)]})],
        "mag": [("last", {"term": "temperature_curve",
                          "comment": "half the HMC5883L's -0.3 %/C over +-62.5 C as a curve",
                          "scale_per_c2": _u(-2.4e-5, 2.4e-5)})]},
    "hysteresis": {
        "gyro": [("last", {"term": "temperature_hysteresis",
                           "comment": "estimate: a few per cent of a 10 C warm-up's change",
                           "offset_c": _u(-1.0, 1.0), "band_c": _u(1.0, 3.0),
                           "state0": -1.0})],
        "accel": [("last", {"term": "temperature_hysteresis",
                            "comment": "estimate: a tenth of a 10 C warm-up's change",
                            "offset_c": [_u(-0.2, 0.2), _u(-0.2, 0.2), _u(-1.0, 1.0)],
                            "band_c": _u(1.0, 3.0), "state0": -1.0})]},
    "nonlinearity": {
        "accel": [("after:cross_axis", {"term": "nonlinearity",
                                        "comment": "ADXL345: nonlinearity +-0.5 % of full scale",
                                        "q": _n(0.002), "c3": _n(0.002), "a": _n(0.002)})]},
    "gsens": {
        "gyro": [("after:cross_axis", {"term": "g_sensitivity",
                                       "comment": "ITG-3200: linear acceleration sensitivity "
                                                  "0.1 deg/s/g",
                                       "G": _n(0.1)})]},
    "field": {
        "mag": [("first", {"term": "field_drift",
                           "comment": "estimate: moved steel a few metres away (0.1-1 uT); "
                                      "above the geomagnetic daily variation",
                           "rate_gauss_per_h": _n(0.003), "sigma_gauss_per_sqrt_h": 0.003})]},
}
SINGLE = tuple(f"{PREFIX}-{b}" for b in BLOCKS)
NAMES = (PREFIX,) + SINGLE


def _read(name: str) -> dict:
    return json.loads((MODELS_DIR / f"{name}.json").read_text(encoding="utf-8"))


def _warmup() -> dict:
    """The ``thermal`` model's board term and its sensors' temperature terms."""
    d = _read("thermal")["defaults"]
    out = {"board": [t for t in d["terms"] if t["term"] == "thermal"]}
    for s in ("accel", "gyro", "mag"):
        out[s] = [("last", t) for t in d[s]["terms"] if t["term"] == "temperature"]
    return out


def blocks_of(name: str) -> tuple:
    """The blocks of a suite model, in ``BLOCKS`` order."""
    if name == PREFIX:
        return tuple(BLOCKS)
    block = name[len(PREFIX) + 1:]
    if not name.startswith(PREFIX + "-") or block not in BLOCKS:
        raise KeyError(name)
    return ("warmup",) if block == "warmup" else ("warmup", block)


def _insert(terms: list, where: str, term: dict) -> None:
    if where == "first":
        terms.insert(0, term)
    elif where == "last":
        terms.append(term)
    else:
        after = where.split(":", 1)[1]
        i = next(i for i, t in enumerate(terms) if t["term"] == after)
        terms.insert(i + 1, term)


def model_json(name: str) -> dict:
    """The model file of suite model ``name`` (KeyError when it is not one)."""
    blocks = blocks_of(name)
    d = _read("general")
    d["name"] = name
    d["description"] = (f"The mismatch suite: 'general' with {', '.join(blocks)} "
                        "(sim.mismatch; docs/simulator-model.md, 'The mismatch suite').")
    dflt = d["defaults"]
    for b in blocks:
        spec = _warmup() if b == "warmup" else copy.deepcopy(BLOCKS[b])
        dflt.setdefault("terms", []).extend(spec.get("board", []))
        for s in ("accel", "gyro", "mag"):
            for where, term in spec.get(s, []):
                _insert(dflt[s]["terms"], where, term)
    return d
