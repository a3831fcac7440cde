"""The project CSV: what ``motecal export`` writes and ``motecal import`` reads
(``motecal.sessions.importer``).
"""
from __future__ import annotations

import contextlib
import csv
from pathlib import Path

import numpy as np

from ..line.protocol import NINEDOF_RATE_HZ
from .cells import (CSV_TEMP, SEQ_MAX, T_MAX, _count, _fail, _integer, _number, _read_text_lines,
                    temperature_cell)
from .labelling import _finish
from .session import (COLUMNS, LABEL_MAX, LABEL_NONE, SENSOR_SLICES, SessionData, batch_times,
                      label_from_text, label_to_text, rate_from_times)

CSV_HEADER = ("mote",) + ("seq", "t", "label") + COLUMNS
CSV_FRAME = "as recorded: motecal sample frame (the mote's sensor axes)"


def read_csv(path, chip=None, kind="auto") -> SessionData:
    """The project CSV (what ``motecal export`` writes).

    Header ``mote,seq,t,label,ax,...,mz``; empty cells = missing values (t may be
    empty); label ``1``.. / ``rot`` / empty.  Lines starting with ``#`` before the
    header are comments.  Labels in the file are kept; a file with no label at
    all is labelled from stillness (per mote) as described in the module doc.
    Scales are the 9DOF board's nominal ones unless ``chip`` overrides them.
    """
    lines = _read_text_lines(path)
    i = 0
    while i < len(lines) and (not lines[i].strip() or lines[i].lstrip().startswith("#")):
        i += 1
    if i == len(lines):
        raise _fail(path, i + 1 if lines else 1, "empty file: no CSV header")
    header = [h.strip() for h in next(csv.reader([lines[i]]))]
    has_temp = tuple(header) == CSV_HEADER + (CSV_TEMP,)
    if tuple(header) != CSV_HEADER and not has_temp:
        raise _fail(path, i + 1, f"bad header {lines[i].strip()[:80]!r}, expected "
                    f"{','.join(CSV_HEADER)!r} (and optionally ,{CSV_TEMP})")
    ncol = len(header)
    rows = []
    reader = csv.reader(lines[i + 1:])
    while True:
        try:
            row = next(reader)
        except StopIteration:
            break
        except csv.Error as e:                      # e.g. a field of megabytes
            raise _fail(path, i + 1 + reader.line_num, f"not CSV: {e}") from None
        lineno = i + 1 + reader.line_num
        if not row or (len(row) == 1 and not row[0].strip()):
            continue
        if len(row) != ncol:
            raise _fail(path, lineno, f"expected {ncol} columns, found {len(row)}")
        # ranges checked here, before numpy or the database see a value
        mote = _integer(row[0], path, lineno, "mote", 0, 0xFFFF)
        seq = _integer(row[1], path, lineno, "seq", -SEQ_MAX, SEQ_MAX)
        t = _number(row[2], path, lineno, "t", allow_empty=True)
        if abs(t) > T_MAX:
            raise _fail(path, lineno, f"t must be within +-{T_MAX:g} s, not {row[2].strip()!r}")
        try:
            label = label_from_text(row[3])
        except ValueError:
            raise _fail(path, lineno, f"label must be 1..{LABEL_MAX}, 'rot' or empty, not "
                        f"{row[3][:40]!r}") from None
        vals = [_count(v, path, lineno, name, allow_empty=True)
                for v, name in zip(row[4:], COLUMNS)]
        if has_temp:
            vals.append(temperature_cell(row[13], path, lineno))
        rows.append((mote, seq, t, label, vals, lineno))
    if not rows:
        raise _fail(path, len(lines), "no samples after the header")
    mote = np.array([r[0] for r in rows], np.int64)
    seq = np.array([r[1] for r in rows], np.int64)
    t = np.array([r[2] for r in rows], float)
    label = np.array([r[3] for r in rows], np.int32)
    raw = np.array([r[4] for r in rows], float).reshape(len(rows), ncol - 4)
    temp = raw[:, 9].copy() if has_temp else None
    raw = raw[:, :9]
    lines_of = np.array([r[5] for r in rows])
    if mote.min() < 0 or mote.max() > 0xFFFF:
        bad = int(np.flatnonzero((mote < 0) | (mote > 0xFFFF))[0])
        raise _fail(path, lines_of[bad], f"mote id out of range 0..65535: {mote[bad]}")
    order = np.lexsort((np.arange(len(rows)), seq, mote))
    dup = (mote[order][1:] == mote[order][:-1]) & (seq[order][1:] == seq[order][:-1])
    if dup.any():
        bad = order[1:][dup].min()
        raise _fail(path, lines_of[bad], f"mote {mote[bad]} has sequence number {seq[bad]} twice")
    rates = {}
    for m in np.unique(mote):
        sel = np.flatnonzero(mote == m)
        sel = sel[np.argsort(seq[sel], kind="stable")]
        r = rate_from_times(t[sel], seq[sel])
        rates[int(m)] = round(r, 3) if r else float(NINEDOF_RATE_HZ)
    rate = float(np.median(list(rates.values())))
    meta = {"format": "csv", "source": str(path),
            "files": [{"file": str(path), "rows": [0, len(rows)]}],
            "rate_hz": rate, "rates_hz": {s: rate for s in SENSOR_SLICES},
            "rates_by_mote_hz": {str(k): v for k, v in rates.items()},
            "clocks": "shared", "axis_frame": CSV_FRAME}
    data = SessionData(name=Path(path).stem, raw=raw, mote=mote, seq=seq, t=t, label=label,
                       flags=np.zeros(len(rows), np.uint8), kind="imported", meta=meta,
                       temp=temp)
    has_labels = bool((label != LABEL_NONE).any())
    if has_labels:
        return _finish(data, chip, kind, None, has_labels=True)
    # unlabelled: one recording per mote, rows of a mote in time order
    order = np.lexsort((np.nan_to_num(t, nan=0.0), seq, mote))
    data = data.select(order)
    parts = []
    for m in data.motes:
        idx = np.flatnonzero(data.mote == m)
        parts.append((int(idx[0]), int(idx[-1]) + 1))
    return _finish(data, chip, kind, parts)


def write_csv(data: SessionData, path) -> None:
    """Write ``data`` in the project CSV format (the inverse of :func:`read_csv`)
    to a file path or an open text file.

    ``t`` is when each sample was taken: ``SessionData.sample_times`` when the
    stored ``t`` is batch receive times (a logged session: rows of a batch
    share the time the host got it, compressed when the line is read faster
    than real time), else ``t`` as stored, empty where unknown.  A session
    with a temperature (``data.temp`` not None) gets the ``temp`` column
    (degrees C, empty where unknown) after the nine sensor columns."""
    times = data.sample_times() if batch_times(data.t) else data.t
    temp = data.temp
    if hasattr(path, "write"):          # an open text file (motecal.outputs.open_output)
        f = contextlib.nullcontext(path)
    else:
        f = open(path, "w", newline="")
    with f as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(CSV_HEADER + ((CSV_TEMP,) if temp is not None else ()))
        for i in range(len(data)):
            vals = ["" if np.isnan(v) else (str(int(v)) if float(v).is_integer() else repr(float(v)))
                    for v in data.raw[i]]
            if temp is not None:
                vals.append("" if np.isnan(temp[i]) else repr(float(temp[i])))
            t = "" if np.isnan(times[i]) else f"{times[i]:.6f}"
            w.writerow([int(data.mote[i]), int(data.seq[i]), t, label_to_text(int(data.label[i]))]
                       + vals)
