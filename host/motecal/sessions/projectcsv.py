"""The project CSV: what ``motecal export`` writes and ``motecal import`` reads
(``motecal.sessions.importer``).
"""
from __future__ import annotations

import contextlib
import csv
from itertools import chain
from pathlib import Path

import numpy as np

from ..line.protocol import NINEDOF_RATE_HZ
from .cells import (CHUNK_ROWS, CSV_TEMP, SEQ_MAX, T_MAX, TEMP_RANGE_C, Rows, _count, _fail,
                    _integer, _number, temperature_cell, text_chunks)
from .labelling import _finish
from .ranges import check_rate
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

    The file is read in chunks of ``cells.CHUNK_ROWS`` rows, each checked and
    kept as arrays, so memory grows with the samples, not the text.
    """
    chunks = text_chunks(path)
    h, head, rest = 0, None, []
    for first, lines in chunks:
        for i, line in enumerate(lines):
            if line.strip() and not line.lstrip().startswith("#"):
                h, head, rest = first + i, line, lines[i + 1:]
                break
        else:
            h = first + len(lines) - 1
            continue
        break
    if head is None:
        raise _fail(path, h + 1 if h else 1, "empty file: no CSV header")
    header = [c.strip() for c in next(csv.reader([head]))]
    has_temp = tuple(header) == CSV_HEADER + (CSV_TEMP,)
    if tuple(header) != CSV_HEADER and not has_temp:
        raise _fail(path, h, f"bad header {head.strip()[:80]!r}, expected "
                    f"{','.join(CSV_HEADER)!r} (and optionally ,{CSV_TEMP})")
    ncol = len(header)
    ints, nums = Rows(4, np.int64), Rows(ncol - 3)      # mote, seq, label, line | t, values
    limit, last = csv.field_size_limit(), h
    pieces = chain([(h + 1, rest)], chunks)
    for first, lines in pieces:
        if any('"' in line for line in lines) or max(map(len, lines), default=0) > limit:
            # quoting (or a field of megabytes): the csv module reads the rest
            last = _quoted_rows(path, chain(lines, chain.from_iterable(ls for _, ls in pieces)),
                                first, ncol, has_temp, ints, nums)
            break
        rows = [line.split(",") for line in lines]
        keep = [i for i, r in enumerate(rows) if len(r) > 1 or r[0].strip()]
        if len(keep) < len(rows):
            rows = [rows[i] for i in keep]
        _csv_block(path, rows, np.asarray(keep, np.int64) + first, ncol, has_temp, ints, nums)
        last = first + len(lines) - 1
    if not len(ints):
        raise _fail(path, last, "no samples after the header")
    i4, x = ints.array(), nums.array()
    mote, seq, label, lines_of = i4[:, 0], i4[:, 1], i4[:, 2].astype(np.int32), i4[:, 3]
    t = x[:, 0].copy()
    raw = x[:, 1:10].copy()
    temp = x[:, 10].copy() if has_temp else None
    del i4, x, ints, nums
    n = len(mote)
    if mote.min() < 0 or mote.max() > 0xFFFF:
        bad = int(np.flatnonzero((mote < 0) | (mote > 0xFFFF))[0])
        raise _fail(path, lines_of[bad], f"mote id out of range 0..65535: {mote[bad]}")
    order = np.lexsort((np.arange(n), seq, mote))
    dup = (mote[order][1:] == mote[order][:-1]) & (seq[order][1:] == seq[order][:-1])
    if dup.any():
        bad = order[1:][dup].min()
        raise _fail(path, lines_of[bad], f"mote {mote[bad]} has sequence number {seq[bad]} twice")
    rates = {}
    for m in np.unique(mote):
        sel = np.flatnonzero(mote == m)
        sel = sel[np.argsort(seq[sel], kind="stable")]
        r = rate_from_times(t[sel], seq[sel])
        if r is not None:
            check_rate(r, f"{path}: mote {int(m)}: the rate its times give",
                       "(is t in seconds?)")
        rates[int(m)] = round(r, 3) if r else float(NINEDOF_RATE_HZ)
    rate = float(np.median(list(rates.values())))
    meta = {"format": "csv", "source": str(path),
            "files": [{"file": str(path), "rows": [0, n]}],
            "rate_hz": rate, "rates_hz": {s: rate for s in SENSOR_SLICES},
            "rates_by_mote_hz": {str(k): v for k, v in rates.items()},
            "clocks": "shared", "axis_frame": CSV_FRAME}
    data = SessionData(name=Path(path).stem, raw=raw, mote=mote, seq=seq, t=t, label=label,
                       flags=np.zeros(n, np.uint8), kind="imported", meta=meta,
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


def _quoted_rows(path, lines, first, ncol, has_temp, ints: Rows, nums: Rows) -> int:
    """Rows through the csv module (quoted fields, fields too long for it),
    ``lines`` numbered from ``first``; returns the last line's number."""
    reader = csv.reader(lines)
    block, where = [], []
    while True:
        try:
            row = next(reader)
        except StopIteration:
            break
        except csv.Error as e:                      # e.g. a field of megabytes
            raise _fail(path, first - 1 + reader.line_num, f"not CSV: {e}") from None
        if not row or (len(row) == 1 and not row[0].strip()):
            continue
        block.append(row)
        where.append(first - 1 + reader.line_num)
        if len(block) >= CHUNK_ROWS:
            _csv_block(path, block, where, ncol, has_temp, ints, nums)
            block, where = [], []
    _csv_block(path, block, where, ncol, has_temp, ints, nums)
    return first - 1 + reader.line_num


def _csv_row(path, row, lineno, ncol, has_temp) -> tuple[list, list]:
    """One data row, each cell checked (one line naming file, line and
    field): ([mote, seq, label, line], [t, 9 counts (, temp)])."""
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
    return [mote, seq, label, lineno], [t] + vals


def _csv_block(path, block, where, ncol, has_temp, ints: Rows, nums: Rows) -> None:
    """A chunk of rows into ``ints`` and ``nums``: converted at once when
    every cell is clean (``_fast_block``), else row by row (``_csv_row``),
    whose first error is the one the file gets."""
    if not block:
        return
    fast = _fast_block(block, ncol, has_temp)
    if fast is None:
        pairs = [_csv_row(path, r, k, ncol, has_temp) for r, k in zip(block, where)]
        fast = (np.array([p[0] for p in pairs], np.int64), np.array([p[1] for p in pairs]))
    else:
        fast[0][:, 3] = where
    ints.extend(fast[0])
    nums.extend(fast[1])


def _floats(col) -> np.ndarray | None:
    """A column's cells as floats, NaN for an empty cell; None when a cell is
    not a number or not finite (then ``_csv_row`` says which)."""
    try:
        v = np.fromiter(map(float, col), float, len(col))
    except ValueError:                               # empty cells, or not numbers
        try:
            v = np.array([float(c) if c else np.nan for c in col])
        except ValueError:
            return None
    odd = np.flatnonzero(~np.isfinite(v))
    if len(odd) and any(col[i] for i in odd):        # 'nan', 'inf' written out
        return None
    return v


def _fast_block(block, ncol, has_temp):
    """(ints, nums) of a chunk whose every cell ``_csv_row`` would accept,
    with the same values; None when any cell is doubtful (never an error)."""
    if any(len(r) != ncol for r in block):
        return None
    cols = list(zip(*block))
    try:
        mote = np.fromiter(map(int, cols[0]), np.int64, len(block))
        seq = np.fromiter(map(int, cols[1]), np.int64, len(block))
        labels = {c: label_from_text(c) for c in set(cols[3])}
    except (ValueError, OverflowError):
        return None
    if mote.min() < 0 or mote.max() > 0xFFFF or np.abs(seq).max() > SEQ_MAX:
        return None
    nums = np.empty((len(block), ncol - 3))
    for j in range(2, ncol):
        if j == 3:
            continue
        v = _floats(cols[j])
        if v is None:
            return None
        ok = v[np.isfinite(v)]
        if j == 2:
            bad = np.abs(ok) > T_MAX
        elif j < 13:
            bad = (ok != np.rint(ok)) | (np.abs(ok) > 32768)
        else:
            bad = (ok < TEMP_RANGE_C[0]) | (ok > TEMP_RANGE_C[1])
        if bad.any():
            return None
        nums[:, j - 2 if j == 2 else j - 3] = v
    ints = np.empty((len(block), 4), np.int64)
    ints[:, 0], ints[:, 1] = mote, seq
    ints[:, 2] = [labels[c] for c in cols[3]]
    return ints, nums


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
