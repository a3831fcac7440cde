"""The one numpy -> JSON conversion (motecal.jsonable) of cal.json and the diagnosis."""
import json
from dataclasses import dataclass

import numpy as np

from motecal.jsonable import finite, jsonable


@dataclass
class _P:
    name: str
    value: float


def test_containers_numpy_values_and_non_finite_numbers():
    x = {1: np.arange(3), "f": np.float32(0.5), "b": np.bool_(True), "n": float("nan"),
         "t": (np.int64(7), [np.inf, -1.25]), "p": _P("o_x", np.float64(2.0)), "s": "ok",
         "none": None}
    out = jsonable(x)
    assert out == {"1": [0, 1, 2], "f": 0.5, "b": True, "n": None, "t": [7, [None, -1.25]],
                   "p": {"name": "o_x", "value": 2.0}, "s": "ok", "none": None}
    json.dumps(out, allow_nan=False)
    assert finite(None) is None and finite(np.float32(3)) == 3.0 and finite(-np.inf) is None


def test_a_number_policy_applies_to_every_float():
    out = jsonable({"a": [1 / 3, np.nan], "k": 3}, number=lambda v: round(float(v), 2))
    assert out["a"][0] == 0.33 and out["k"] == 3 and np.isnan(out["a"][1])
