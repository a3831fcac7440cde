"""Cells of an imported file, each checked before numpy or the database sees it:
numbers, raw counts, integers and temperatures, and the file's bytes or text
lines.  A bad one is one UserError naming the file and the line
(``motecal.sessions.importer``).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..errors import UserError
from ..inputs import read_input_bytes

CSV_TEMP = "temp"               # optional last column: board temperature, degrees C
TEMP_RANGE_C = (-100.0, 200.0)  # what an ITG3200-style sensor can report (int16 raw: -82..199)


def _where(path, line=None) -> str:
    return f"{path}: line {line}" if line is not None else f"{path}"


def _fail(path, line, message) -> UserError:
    return UserError(f"{_where(path, line)}: {message}")


def _number(tok: str, path, line, what: str, allow_empty=False) -> float:
    tok = tok.strip()
    if tok == "" and allow_empty:
        return float("nan")
    try:
        v = float(tok)
    except ValueError:
        raise _fail(path, line, f"{what} is not a number: {tok!r}") from None
    if not math.isfinite(v):
        raise _fail(path, line, f"{what} is not a finite number: {tok!r}")
    return v


def _count(tok: str, path, line, what: str, allow_empty=False) -> float:
    """A raw sensor count: an integer within int16 (32768, one past full scale as
    written by some converters, is accepted and later stored as 32767)."""
    v = _number(tok, path, line, what, allow_empty)
    if v != v:
        return v
    if v != round(v):
        raise _fail(path, line, f"{what} is not an integer count: {tok.strip()!r}")
    if not -32768 <= v <= 32768:
        raise _fail(path, line, f"{what} = {tok.strip()} is outside the 16-bit range of raw counts")
    return v


def temperature_cell(tok: str, path, line, what: str = CSV_TEMP, factor: float = 1.0,
                     offset: float = 0.0) -> float:
    """A temperature cell in degrees C (empty: unknown, NaN); ``factor`` and
    ``offset`` convert a file's own unit (C = value * factor + offset).  Not
    a number, not finite or outside ``TEMP_RANGE_C``: one line naming file
    and line."""
    v = _number(tok, path, line, what, allow_empty=True)
    if v != v:
        return v
    c = v * factor + offset
    lo, hi = TEMP_RANGE_C
    if not lo <= c <= hi:
        raise _fail(path, line, f"{what} = {tok.strip()[:40]} is {c:g} degrees C, outside "
                    f"{lo:g}..{hi:g}")
    return c


SEQ_MAX = 2 ** 53 - 1      # sequence numbers: exact as float64 too
T_MAX = 1e10               # seconds


def _integer(tok: str, path, line, what: str, lo: int | None = None,
             hi: int | None = None) -> int:
    tok = tok.strip()
    try:
        v = int(tok)
    except ValueError:
        raise _fail(path, line, f"{what} is not an integer: {tok[:40]!r}") from None
    if (lo is not None and v < lo) or (hi is not None and v > hi):
        raise _fail(path, line, f"{what} out of range {lo}..{hi}: {tok[:40]}")
    return v


def _read_bytes(path) -> bytes:
    """A file's bytes; a directory, a device or FIFO (``/dev/zero`` would never
    end), an unreadable or oversized file is a UserError (``inputs``)."""
    if Path(path).is_dir():
        raise UserError(f"{path}: is a directory, expected a file")
    return read_input_bytes(path)


def _read_text_lines(path) -> list[str]:
    data = _read_bytes(path)
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        line = data[:e.start].count(b"\n") + 1
        raise _fail(path, line, "not a text file (undecodable bytes)") from None
    if "\x00" in text:
        line = text[:text.index("\x00")].count("\n") + 1
        raise _fail(path, line, "not a text file (NUL byte)")
    return text.splitlines()
