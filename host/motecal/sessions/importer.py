"""Import measured data into a session: the project CSV and the real-data formats
of ``../shared/data/measured`` (Razor AHRS text and float logs, timestamped CSV pairs).

Readers are pure functions returning :class:`motecal.sessions.session.SessionData` in raw
counts, axes as recorded, with the chips, scales (LSB per unit), rates and sources
in ``scales`` / ``chips`` / ``meta``.  Unlabelled data gets labels from the
stillness detector (:func:`motecal.sessions.still.segment_still`):

* ``static``: still segments become poses 1..K in time order; when several files
  are read into one session each file is one pose (its longest still segment);
* ``idle``: same labelling (normally a single still segment), kind ``idle``;
* ``rotation``: every row is ``LABEL_ROT``;
* ``auto``: ``rotation`` when less than half of the rows are still
  (``AUTO_ROTATION_BELOW``), else ``static`` with two or more poses, else ``idle``.

``motecal import`` reads everything first and writes the session through the
store in one go, so a bad file leaves the database unchanged.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import UserError
from ..inputs import check_input_file
from .session import SessionData
# The readers and their parts live in one module each; they are all reachable
# from here, as before the split (callers use ``importer.read_csv`` etc.).
from .cells import (CSV_TEMP, SEQ_MAX, T_MAX, TEMP_RANGE_C, _count, _fail,  # noqa: F401
                    _integer, _number, _where, numbered_lines, temperature_cell, text_chunks)
from .chips import (CHIP_SCALES, CLIP_COUNTS, SENSOR_ALIASES, _chips_for,  # noqa: F401
                    normalise_chip, parse_chip_overrides)
from .imported import (IMPORT_MOTE, SOURCE_SEP, _clipped, _sensor_counts,  # noqa: F401
                       _session, add_note)
from .import_summary import _fmt_scale, summary  # noqa: F401
from .labelling import AUTO_ROTATION_BELOW, KINDS, _finish, _longest_segment, assign_labels  # noqa: F401
from .options import option_parts  # noqa: F401
from .projectcsv import CSV_FRAME, CSV_HEADER, read_csv, write_csv  # noqa: F401
from .razor import (RAZOR_FLOAT_FRAME, RAZOR_FRAME, RAZOR_RATE_HZ, _RAZOR_LINE,  # noqa: F401
                    _be_float32, _float_values, _parse_razor_text, read_razor_float,
                    read_razor_text)
from .timestamped import (TEMP_RAW_C, TIMESTAMPED_FRAME, _parse_timestamped,  # noqa: F401
                          _timestamped_files, _timestamped_header, read_timestamped)

FORMATS = ("csv", "razor-text", "razor-float", "timestamped-csv")


# ------------------------------------------------------------------ detection and dispatch

def _looks_like_text(head: bytes) -> bool:
    if not head:
        return True
    try:
        text = head.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        if e.start >= len(head) - 3:       # cut in the middle of a character
            return True
        return False
    return all(c.isprintable() or c in "\r\n\t" for c in text)


def detect_format(path) -> str:
    """Format of one file (or run directory) from its content."""
    p = Path(path)
    if p.is_dir():
        if list(p.glob("*_counts.csv")):
            return "timestamped-csv"
        raise UserError(f"{p}: directory is not a timestamped run (no *_counts.csv inside)")
    check_input_file(p)                   # not a FIFO or device: opening one would block
    try:
        with open(p, "rb") as f:
            head = f.read(4096)
        size = p.stat().st_size
    except OSError as e:
        raise UserError(f"{p}: cannot read: {e.strerror or e}") from None
    if size == 0:
        raise UserError(f"{p}: line 1: empty file, unknown format")
    if _looks_like_text(head):
        text = head.decode("utf-8-sig", errors="replace")
        lines = text.splitlines()
        for lineno, line in enumerate(lines, start=1):
            s = line.strip()
            if not s or (s.startswith("#") and not _RAZOR_LINE.match(s)):
                continue
            if _RAZOR_LINE.match(s):
                return "razor-text"
            if [h.strip() for h in s.split(",")] in (list(CSV_HEADER),
                                                     list(CSV_HEADER) + [CSV_TEMP]):
                return "csv"
            if s.startswith("t_s,"):
                return "timestamped-csv"
            raise UserError(f"{p}: line {lineno}: unknown format: {s[:60]!r} (expected the "
                            f"motecal CSV header, #A-R= Razor lines or a t_s,... header)")
        raise UserError(f"{p}: line 1: unknown format (no data line found)")
    # binary: big-endian float32 triplets of integer counts?
    n = min(len(head) // 4, 300)
    x = _be_float32(head[:n * 4])
    if n and np.isfinite(x).all() and (np.abs(x) < 1e5).all() and (x == np.round(x)).mean() > 0.9:
        return "razor-float"
    raise UserError(f"{p}: unknown binary format (not big-endian float32 counts)")


READERS = {"csv": read_csv, "razor-text": read_razor_text, "razor-float": read_razor_float,
           "timestamped-csv": read_timestamped}


def input_paths(paths) -> list[Path]:
    """The input files of an import (one path or several) as Paths, each of
    which must exist; one line (UserError) otherwise."""
    if isinstance(paths, (str, Path)):
        paths = [paths]
    paths = [Path(p) for p in paths]
    if not paths:
        raise UserError("no input file given")
    for p in paths:
        if not p.exists():
            raise UserError(f"{p}: no such file or directory")
    return paths


def read_any(paths, fmt: str = "auto", chip=None, kind: str = "auto") -> SessionData:
    """Read one session from ``paths`` (files, or a timestamped run directory).

    ``fmt`` is ``auto`` (detected from content) or one of ``FORMATS``; every file
    of a session must be in the same format.  ``chip`` overrides chips/scales
    (see :func:`parse_chip_overrides`); ``kind`` as in :func:`assign_labels`.
    """
    paths = input_paths(paths)
    if fmt not in ("auto",) + FORMATS:
        raise UserError(f"unknown format {fmt!r} (auto, {', '.join(FORMATS)})")
    if kind not in KINDS:
        raise UserError(f"unknown kind {kind!r} ({', '.join(KINDS)})")
    if fmt == "auto":
        found = {p: detect_format(p) for p in paths}
        kinds = sorted(set(found.values()))
        if len(kinds) > 1:
            listing = "; ".join(f"{p}: {f}" for p, f in found.items())
            raise UserError(f"files of different formats in one session ({listing})")
        fmt = kinds[0]
    if fmt == "csv":
        if len(paths) != 1:
            raise UserError("csv: import one CSV file per session")
        data = read_csv(paths[0], chip=chip, kind=kind)
    elif fmt == "razor-text":
        data = read_razor_text(paths, chip=chip, kind=kind)
    elif fmt == "razor-float":
        if len(paths) != 1:
            raise UserError("razor-float: import one float file per session")
        data = read_razor_float(paths[0], chip=chip, kind=kind)
    else:
        data = read_timestamped(paths, chip=chip, kind=kind)
    data.meta["format"] = fmt
    return data

