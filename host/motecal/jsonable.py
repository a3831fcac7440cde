"""Values with numpy inside made plain JSON: the one conversion that writes
cal.json and the diagnosis.

``jsonable(x, number=finite)``: dicts (keys as strings), lists, tuples,
arrays, numpy scalars and dataclass instances become JSON types, recursively;
every float goes through ``number`` (``finite``: NaN and infinities, which
JSON cannot hold, become null).
"""
from __future__ import annotations

import math
from dataclasses import asdict, is_dataclass

import numpy as np


def finite(x) -> float | None:
    """A JSON-safe float: None for None, NaN and infinities."""
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


def jsonable(x, number=finite):
    """x with every container and numpy value turned into JSON types."""
    if isinstance(x, dict):
        return {str(k): jsonable(v, number) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v, number) for v in x]
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist(), number)
    if isinstance(x, (np.bool_, bool)):
        return bool(x)
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, (float, np.floating)):
        return number(x)
    if is_dataclass(x) and not isinstance(x, type):
        return jsonable(asdict(x), number)
    return x
