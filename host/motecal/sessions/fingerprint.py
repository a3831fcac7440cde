"""The fingerprint of a session's rows: what a result made from them (a kept
diagnosis) remembers, so that a later command can tell whether it still
describes the same data (a live session that grew, a session imported again
under the same name).

``data_key(data)`` = ``"<rows>:<sha256 prefix>"`` over the mote, sequence
number, time, label and the nine readings of every row (NaN included), in
row order, and the temperature when the session has one.  Pure function; equal data give equal keys in any process.
"""
from __future__ import annotations

import hashlib

import numpy as np

from .session import SessionData


def data_key(data: SessionData) -> str:
    """See the module doc."""
    h = hashlib.sha256()
    for a, dt in ((data.mote, "<i8"), (data.seq, "<i8"), (data.t, "<f8"), (data.label, "<i8"),
                  (data.raw, "<f8")):
        arr = np.ascontiguousarray(np.asarray(a).astype(dt))
        h.update(str(arr.shape).encode())
        h.update(arr.tobytes())
    if getattr(data, "temp", None) is not None:
        h.update(np.ascontiguousarray(np.asarray(data.temp, "<f8")).tobytes())
    return f"{len(data)}:{h.hexdigest()[:24]}"


def rows_of(key: str | None) -> int | None:
    """The row count a key records (None for a key that is not one)."""
    try:
        return int(str(key).split(":", 1)[0])
    except (TypeError, ValueError):
        return None
