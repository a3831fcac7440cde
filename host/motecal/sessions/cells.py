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
from ..inputs import MAX_DATA_BYTES, check_input_file

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
        raise _fail(path, line, f"{what} is not a number: {tok[:40]!r}") from None
    if not math.isfinite(v):
        raise _fail(path, line, f"{what} is not a finite number: {tok[:40]!r}")
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


BLOCK_BYTES = 1 << 22           # a file is read 4 MiB at a time
MAX_LINE_BYTES = 64 << 20       # a longer line is not a line of a text log
CHUNK_ROWS = 1 << 16            # rows parsed (and checked) together


def byte_blocks(path, block: int = BLOCK_BYTES):
    """A data file's bytes, ``block`` at a time: memory bounded by the block,
    not the file.  A directory, a device or FIFO, an unreadable file or one
    over ``inputs.MAX_DATA_BYTES`` is one line (``inputs.check_input_file``)."""
    if Path(path).is_dir():
        raise UserError(f"{path}: is a directory, expected a file")
    p = check_input_file(path)
    total = 0
    try:
        with open(p, "rb") as f:
            while True:
                buf = f.read(block)
                if not buf:
                    return
                total += len(buf)
                if total > MAX_DATA_BYTES:
                    raise UserError(f"cannot read {p}: more than the {MAX_DATA_BYTES} bytes "
                                    "such a file may have")
                yield buf
    except OSError as e:
        raise UserError(f"cannot read {p}: {e.strerror or e}") from None


def text_chunks(path, block: int = BLOCK_BYTES):
    """A text file as ``(number of its first line, lines)`` chunks, lines as
    ``str.splitlines`` gives them and numbered as in the whole file; each
    chunk holds whole lines of about ``block`` bytes, so memory stays bounded
    by the block whatever the file's size.  Not UTF-8, a NUL byte, or a line
    longer than ``MAX_LINE_BYTES``: one line naming the file and the line."""
    carry, first, newlines, start = b"", 1, 0, True
    blocks = byte_blocks(path, block)
    while True:
        buf = next(blocks, None)
        if buf is None:                       # the end: what is left is the last line
            chunk, carry = carry, b""
        else:
            data = carry + buf
            cut = data.rfind(b"\n") + 1
            if cut == 0:                      # no line ends in it yet
                if len(data) > MAX_LINE_BYTES:
                    raise _fail(path, newlines + 1, f"a line longer than {MAX_LINE_BYTES} "
                                "bytes: not a text file")
                carry = data
                continue
            chunk, carry = data[:cut], data[cut:]
        if chunk:
            try:
                text = chunk.decode("utf-8-sig" if start else "utf-8")
            except UnicodeDecodeError as e:
                line = newlines + chunk[:e.start].count(b"\n") + 1
                raise _fail(path, line, "not a text file (undecodable bytes)") from None
            if "\x00" in text:
                line = newlines + text[:text.index("\x00")].count("\n") + 1
                raise _fail(path, line, "not a text file (NUL byte)")
            lines = text.splitlines()
            start = False
            newlines += chunk.count(b"\n")
            yield first, lines
            first += len(lines)
        if buf is None:
            return


def numbered_lines(path, block: int = BLOCK_BYTES):
    """``(line number, line)`` of a text file, read in chunks (``text_chunks``)."""
    for first, lines in text_chunks(path, block):
        yield from enumerate(lines, start=first)


class Rows:
    """Rows of numbers gathered as a reader goes, kept as numpy arrays of
    ``CHUNK_ROWS`` rows (a Python list of floats takes four times the memory)."""

    def __init__(self, width: int, dtype=float):
        self.width, self.dtype, self.parts, self.cur = width, dtype, [], []

    def add(self, row) -> None:
        self.cur.append(row)
        if len(self.cur) >= CHUNK_ROWS:
            self.flush()

    def extend(self, block: np.ndarray) -> None:
        self.flush()
        if len(block):
            self.parts.append(np.asarray(block, self.dtype).reshape(len(block), self.width))

    def flush(self) -> None:
        if self.cur:
            self.parts.append(np.array(self.cur, self.dtype).reshape(len(self.cur), self.width))
            self.cur = []

    def __len__(self) -> int:
        return sum(map(len, self.parts)) + len(self.cur)

    def array(self) -> np.ndarray:
        self.flush()
        if not self.parts:
            return np.empty((0, self.width), self.dtype)
        out = self.parts[0] if len(self.parts) == 1 else np.concatenate(self.parts)
        self.parts = [out]
        return out
