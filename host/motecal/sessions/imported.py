"""An imported session as :class:`motecal.sessions.session.SessionData`: built
from a reader's arrays, its notes, samples per sensor and clipped samples
(``motecal.sessions.importer``).
"""
from __future__ import annotations

import numpy as np

from .chips import CLIP_COUNTS, _chips_for
from .session import HMC5883L_OVERFLOW, SENSOR_SLICES, SessionData

IMPORT_MOTE = 1                 # mote id given to rows of formats without one
SOURCE_SEP = "; "                # meta["source"]: the files, one text


def add_note(meta: dict, note: str) -> None:
    """``meta["notes"]`` is one text (a database column): notes joined by '; '."""
    meta["notes"] = f"{meta['notes']}; {note}" if meta.get("notes") else note


def _sensor_counts(raw) -> dict:
    return {s: int((~np.isnan(raw[:, sl]).any(axis=1)).sum()) for s, sl in SENSOR_SLICES.items()}


def _clipped(raw, chips) -> dict:
    out = {}
    for s, sl in SENSOR_SLICES.items():
        x = raw[:, sl]
        ok = ~np.isnan(x).any(axis=1)
        if not ok.any():
            continue
        if s == "mag":
            bad = (x[ok] == HMC5883L_OVERFLOW).any(axis=1)
        else:
            lim = CLIP_COUNTS.get(chips.get(s))
            if lim is None:
                continue
            bad = (np.abs(x[ok]) >= lim).any(axis=1)
        if bad.any():
            out[s] = int(bad.sum())
    return out


def _session(name, raw, t, mote=None, seq=None, label=None, chips=None, meta=None):
    n = len(raw)
    chips_, scales_ = _chips_for(chips or {})
    return SessionData(
        name=name, raw=raw, mote=np.full(n, IMPORT_MOTE) if mote is None else mote,
        seq=np.arange(n) if seq is None else seq, t=t,
        label=np.zeros(n, np.int32) if label is None else label,
        flags=np.zeros(n, np.uint8), kind="imported", scales=scales_, chips=chips_,
        meta=meta or {})
