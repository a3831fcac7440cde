"""How the store writes values that are not numbers: times (unix seconds in
the database, ISO 8601 text in and out), documents (JSON text: session
metadata, calibrations, diagnoses) and labels (text as in CSV: ``"1".."80"``,
``"rot"`` or ``""``); and what sample rows it takes (``check_rows``).
"""
from __future__ import annotations

import datetime as _dt
import json

import numpy as np

from ..errors import UserError
from .session import label_from_text, label_to_text


def iso(ts: float | None) -> str | None:
    """Unix seconds as ISO 8601 text in UTC, to the millisecond (``...Z``)."""
    if ts is None:
        return None
    return _dt.datetime.fromtimestamp(ts, _dt.timezone.utc).isoformat(timespec="milliseconds") \
        .replace("+00:00", "Z")


def from_iso(value) -> float | None:
    """ISO 8601 text (UTC when it names no zone) or seconds as unix seconds;
    None for none; UserError for anything else."""
    if value is None or value == "":
        return None
    if isinstance(value, (int, float)):
        return float(value)
    try:
        d = _dt.datetime.fromisoformat(str(value).replace("Z", "+00:00"))
    except ValueError:
        raise UserError(f"bad time {value!r} in session metadata (want ISO 8601)") from None
    if d.tzinfo is None:
        d = d.replace(tzinfo=_dt.timezone.utc)
    return d.timestamp()


def _json_default(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    raise TypeError(f"{type(o).__name__} is not JSON serialisable")


def dumps(obj) -> str:
    """JSON text, numpy arrays and scalars as lists and numbers, keys sorted."""
    return json.dumps(obj, default=_json_default, sort_keys=True)


def document(obj, what: str) -> str:
    """``obj`` as stored JSON text; one line (UserError) naming ``what`` when
    it is not JSON-able."""
    try:
        return dumps(obj)
    except (TypeError, ValueError) as e:
        raise UserError(f"{what} is not JSON: {e}") from None


def label_texts(label: np.ndarray) -> list[str]:
    """int labels -> their text form (session.label_to_text), vectorised."""
    uniq, inv = np.unique(np.asarray(label), return_inverse=True)
    texts = np.array([label_to_text(int(u)) for u in uniq], dtype=object)
    return texts[inv].tolist()


def labels_from_texts(texts: list[str]) -> np.ndarray:
    """Stored label texts -> int labels (session.label_from_text), vectorised."""
    uniq, inv = np.unique(np.asarray(texts, dtype=object).astype(str), return_inverse=True)
    vals = np.array([label_from_text(u) for u in uniq], dtype=np.int32)
    return vals[inv] if len(texts) else np.zeros(0, np.int32)


def check_rows(data, lo: int, hi: int) -> None:
    """Sample rows the store takes: integer counts within ``lo..hi`` (NaN =
    missing), each (mote, seq) once; UserError otherwise."""
    raw = np.asarray(data.raw, float)
    finite = np.isfinite(raw)
    if np.isinf(raw).any():
        raise UserError(f"session {data.name!r}: infinite sample values")
    vals = raw[finite]
    if vals.size and (np.any(vals != np.round(vals)) or vals.min() < lo or vals.max() > hi):
        raise UserError(f"session {data.name!r}: samples must be integer counts within {lo}..{hi}")
    order = np.lexsort((data.seq, data.mote))
    m, s = data.mote[order], data.seq[order]
    dup = (m[1:] == m[:-1]) & (s[1:] == s[:-1])
    if dup.any():
        i = int(np.flatnonzero(dup)[0])
        raise UserError(f"session {data.name!r}: mote {int(m[i])} has sequence number "
                        f"{int(s[i])} twice")
