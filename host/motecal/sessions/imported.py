"""An imported session as :class:`motecal.sessions.session.SessionData`: built
from a reader's arrays, its notes, samples per sensor and clipped samples
(``motecal.sessions.importer``).
"""
from __future__ import annotations

import math

import numpy as np

from ..errors import UserError
from . import ranges as R
from .cells import SEQ_MAX, T_MAX, TEMP_RANGE_C
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


def _bad_number(value, path="meta"):
    """Where in ``value`` (meta: dicts, lists, numbers) a number is NaN or
    infinite (a session's metadata is JSON), or None."""
    if isinstance(value, float) and not math.isfinite(value):
        return path
    if isinstance(value, dict):
        items = value.items()
    elif isinstance(value, (list, tuple)):
        items = enumerate(value)
    else:
        return None
    for k, v in items:
        where = _bad_number(v, f"{path}[{k!r}]")
        if where:
            return where
    return None


def check_imported(data: SessionData) -> None:
    """The last word before a reader's session goes to the store: everything
    motecal's own export writes and import reads back -- times, sequence
    numbers, motes, counts, temperatures, the scales and rates in their
    physical ranges (``ranges``), a metadata without NaN -- or one line
    naming the source.  The readers check each cell where they read it;
    this catches what they could only see together (a rate times a row)."""
    src = data.meta.get("source") or data.name
    t = np.asarray(data.t, float)
    with np.errstate(invalid="ignore"):
        far = np.abs(t) > T_MAX
    if np.isinf(t).any() or far.any():
        i = int(np.flatnonzero(np.isinf(t) | far)[0])
        raise UserError(f"{src}: row {i + 1}: t = {t[i]:.6g} s is beyond +-{T_MAX:g} s "
                        f"(is the rate right?)")
    if len(data.seq) and np.abs(np.asarray(data.seq)).max() > SEQ_MAX:
        raise UserError(f"{src}: a sequence number beyond +-{SEQ_MAX}")
    if len(data.mote) and (np.min(data.mote) < 0 or np.max(data.mote) > 0xFFFF):
        raise UserError(f"{src}: a mote id outside 0..65535")
    raw = np.asarray(data.raw, float)
    with np.errstate(invalid="ignore"):
        bad = np.isinf(raw) | (raw < -32768) | (raw > 32767) | ((raw != np.round(raw)) & ~np.isnan(raw))
    if bad.any():
        i = int(np.flatnonzero(bad.any(axis=1))[0])
        raise UserError(f"{src}: row {i + 1}: values that are not 16-bit counts")
    if data.temp is not None:
        tc = np.asarray(data.temp, float)
        with np.errstate(invalid="ignore"):
            off = ~np.isnan(tc) & ~((tc >= TEMP_RANGE_C[0]) & (tc <= TEMP_RANGE_C[1]))
        if off.any():
            raise UserError(f"{src}: a temperature outside {TEMP_RANGE_C[0]:g}..{TEMP_RANGE_C[1]:g} "
                            "degrees C")
    present = data.meta.get("samples") or _sensor_counts(raw)
    for s in SENSOR_SLICES:
        if present.get(s):
            R.check_scale(s, data.scales.get(s), f"{src}: {s} scale")
    rates = dict(data.meta.get("rates_hz") or {})
    if data.meta.get("rate_hz") is not None:
        rates["session"] = data.meta["rate_hz"]
    for s, r in rates.items():
        R.check_rate(r, f"{src}: {s} rate")
    where = _bad_number(data.meta)
    if where:
        raise UserError(f"{src}: {where} is not a finite number")
