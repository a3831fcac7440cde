"""Readers of other calibration tools' recordings (see docs/interop.md):

* ``imucal-annotated``: imucal's annotated Ferraris CSV, header
  ``part,samples,acc_x,acc_y,acc_z,gyr_x,gyr_y,gyr_z`` (raw counts; ``part``
  names the section: ``x_p`` .. ``z_a`` static faces, ``x_rot`` .. ``z_rot``
  rotations);
* ``imucal-session``: imucal's continuous Ferraris session CSV (an index
  column then ``gyr_*`` / ``acc_*``, floats in the units given, imucal's
  example: m/s^2 and deg/s) with its section list (JSON ``{"x_p": {"start":
  i, "end": j}, ...}``: the file given beside it, or ``<stem>_list.json``);
* ``float-log``: FreeIMU-cal's text logs and any headerless float log (3, 6
  or 9 numbers a line; sensor from ``columns`` or the file name), SI units
  unless told (``--units``); with a turntable rate (``--rate-dps``/``--rpm``)
  the steady turns are labelled ``rot`` and the rests are poses.

Faces become poses 1..6 (``x_p`` 1, ``x_a`` 2, ``y_p`` 3, ``y_a`` 4, ``z_p``
5, ``z_a`` 6; ``meta["pose_names"]``); rotation rows are ``rot`` and
``meta["rotations"]`` lists each one (name, axis, rows, angle), which the
gyroscope's scale fit (``calib.rotations``) uses.  Everything is read before
anything is stored; a bad line is one UserError naming file and line.
"""
from __future__ import annotations

import csv
import json
import re
from pathlib import Path

import numpy as np

from . import floatlog as F
from . import floatsession as S
from ..errors import UserError
from ..inputs import check_input_file, read_input_text
from . import ranges as R
from .cells import SEQ_MAX, T_MAX, Rows, _fail, _number, numbered_lines
from .imported import _session, add_note
from .importer import input_paths
from .labelling import _finish
from .session import LABEL_ROT, SENSOR_SLICES

FORMATS = ("imucal-annotated", "imucal-session", "float-log", "motioncal")
FACES = ("x_p", "x_a", "y_p", "y_a", "z_p", "z_a")
ROTATIONS = ("x_rot", "y_rot", "z_rot")
SECTIONS = FACES + ROTATIONS
POSE_OF = {f: i for i, f in enumerate(FACES, start=1)}
FERRARIS_ANGLE_DEG = 360.0       # imucal's default rotation (sign from the data)
IMUCAL_FRAME = "as recorded: imucal's sensor frame (x_p: the x axis reads +1 g)"
FLOAT_FRAME = S.FLOAT_FRAME
read_float_log = S.read_float_log      # the float-log reader lives with the floats
ACC_COLS = ("acc_x", "acc_y", "acc_z")
GYR_COLS = ("gyr_x", "gyr_y", "gyr_z")


def _rotations_meta(label_rows: dict, angle_deg: float) -> list:
    out = []
    for name in ROTATIONS:
        rows = label_rows.get(name)
        if rows is None:
            continue
        out.append({"name": name, "axis": name[0], "rows": [int(rows[0]), int(rows[1])],
                    "angle_deg": float(angle_deg)})
    return out


# ------------------------------------------------------------------ imucal annotated CSV

def _csv_rows(path):
    """The header cells of a CSV text file and an iterator of its data rows
    as ``(line number, cells)``, blank lines skipped; read in chunks."""
    lines = numbered_lines(path)
    first = next(lines, None)
    if first is None:
        raise _fail(path, 1, "empty file: no header")
    header = [h.strip() for h in next(csv.reader([first[1]]))]
    rest = (line for _, line in lines)
    reader = csv.reader(rest)

    def rows():
        while True:
            try:
                row = next(reader)
            except StopIteration:
                return
            except csv.Error as e:
                raise _fail(path, 1 + reader.line_num, f"not CSV: {e}") from None
            if not row or (len(row) == 1 and not row[0].strip()):
                continue
            yield 1 + reader.line_num, row
    return first[1], header, rows(), lambda: 1 + reader.line_num


def _sample_number(tok: str, path, lineno) -> int:
    """imucal's ``samples`` cell: a whole number within +-``SEQ_MAX`` (it
    becomes the row's sequence number)."""
    v = _number(tok, path, lineno, "samples")
    if v != int(v):
        raise _fail(path, lineno, f"samples is not a whole number: {tok.strip()[:40]!r}")
    if abs(v) > SEQ_MAX:
        raise _fail(path, lineno, f"samples out of range -{SEQ_MAX}..{SEQ_MAX}: {tok.strip()[:40]}")
    return int(v)


def read_imucal_annotated(path, *, rate_hz=None, chip=None, scale=None, units=None,
                          gravity=F.G0, angle_deg=FERRARIS_ANGLE_DEG, kind="auto"):
    """imucal's annotated session (``example_data/annotated_session.csv``): raw
    counts unless ``units`` say otherwise; rows sorted by ``samples``
    (t = samples / rate)."""
    rate = S.need_rate(rate_hz, "imucal-annotated")
    gravity, angle_deg = R.check_gravity(gravity), R.check_angle(angle_deg)
    first, header, rows, last_line = _csv_rows(path)
    need = ("part", "samples") + ACC_COLS + GYR_COLS
    if sorted(header) != sorted(need):
        raise _fail(path, 1, f"bad header {first.strip()[:80]!r}: expected "
                    f"{','.join(need)}")
    col = {h: i for i, h in enumerate(header)}
    vcols = [col[c] for c in ACC_COLS + GYR_COLS]
    nums = Rows(len(vcols) + 3, np.float64)        # values, section code, samples, line
    for lineno, row in rows:
        if len(row) != len(header):
            raise _fail(path, lineno, f"expected {len(header)} columns, found {len(row)}")
        part = row[col["part"]].strip()
        if part not in SECTIONS:
            raise _fail(path, lineno, f"unknown section {part!r} (expected one of "
                        f"{', '.join(SECTIONS)})")
        k = _sample_number(row[col["samples"]], path, lineno)
        nums.add([_number(row[j], path, lineno, c) for j, c in zip(vcols, ACC_COLS + GYR_COLS)]
                 + [SECTIONS.index(part), k, lineno])
    x = nums.array()
    if not len(x):
        raise _fail(path, last_line(), "no samples after the header")
    codes = x[:, 6].astype(np.int64)
    missing = [s for j, s in enumerate(SECTIONS) if s in FACES and not (codes == j).any()]
    if missing:
        raise _fail(path, last_line(), f"section(s) {', '.join(missing)} missing: a Ferraris "
                    f"session has the six faces x_p .. z_a")
    # samples up to SEQ_MAX are exact in float64
    samples, lines_of = x[:, 7].astype(np.int64), x[:, 8].astype(np.int64)
    order = np.argsort(samples, kind="stable")
    dup = np.flatnonzero(np.diff(samples[order]) == 0)
    if len(dup):
        i = order[dup[0] + 1]
        raise _fail(path, lines_of[i], f"sample {samples[i]} appears twice")
    far = int(np.argmax(np.abs(samples)))
    if abs(samples[far]) / rate > T_MAX:
        raise _fail(path, lines_of[far], f"sample {samples[far]} at {rate:g} Hz is "
                    f"{abs(samples[far]) / rate:.3g} s from the start, beyond {T_MAX:g} s "
                    f"(is --rate-hz right?)")
    vals, codes = x[order, :6], codes[order]
    lines_sorted, samples = lines_of[order], samples[order]
    del x
    meta = {"format": "imucal-annotated", "source": str(path),
            "rate_hz": rate, "rates_hz": {"accel": rate, "gyro": rate},
            "clocks": f"shared: t = samples / {rate:g} Hz", "axis_frame": IMUCAL_FRAME}
    units = F.parse_units(units) or {"accel": "counts", "gyro": "counts"}
    scales = F.parse_scales(scale)
    raw, lsbs, keep = S.convert(path, {"accel": vals[:, 0:3], "gyro": vals[:, 3:6]}, units,
                                scales, S.chip_scales(chip), gravity, meta,
                                line_of=lambda i: f"{path}: line {lines_sorted[i]}")
    meta["files"] = [{"file": str(path), "rows": [0, len(raw)], "samples": len(raw)}]
    return _labelled(path, raw, samples[keep], codes[keep], rate, meta, lsbs, chip, angle_deg,
                     kind)


def _labelled(path, raw, samples, codes, rate, meta, lsbs, chip, angle_deg, kind):
    """Rows labelled from their section codes (indices into ``SECTIONS``, -1
    for none): faces are poses 1..6, rotations ``rot`` (one block each)."""
    lut = np.array([POSE_OF.get(s, LABEL_ROT) for s in SECTIONS] + [0], np.int32)
    label = lut[codes]                                 # code -1: the last entry, 0
    rows = {}
    for j, name in enumerate(SECTIONS):
        if name not in ROTATIONS:
            continue
        idx = np.flatnonzero(codes == j)
        if len(idx):
            if idx[-1] - idx[0] + 1 != len(idx):
                raise UserError(f"{path}: section {name} is not one contiguous block")
            rows[name] = (int(idx[0]), int(idx[-1]) + 1)
    meta["pose_names"] = {str(v): k for k, v in POSE_OF.items()}
    meta["rotations"] = _rotations_meta(rows, angle_deg)
    data = _session(Path(path).stem, raw, samples / rate, seq=samples, label=label, meta=meta)
    S.apply_scales(data, lsbs, chip)
    return _finish(data, None, kind, None, has_labels=True)


# ------------------------------------------------------------------ imucal session + list

def _section_list(path) -> dict:
    try:
        d = json.loads(read_input_text(path))
    except (json.JSONDecodeError, RecursionError) as e:
        line = getattr(e, "lineno", 1)
        raise _fail(path, line, f"not a JSON section list: {e}") from None
    if not isinstance(d, dict):
        raise _fail(path, 1, "a section list is a JSON object {section: {start, end}}")
    out = {}
    for k, v in d.items():
        if k not in SECTIONS:
            raise _fail(path, 1, f"unknown section {k!r} (expected {', '.join(SECTIONS)})")
        try:
            a, b = int(v["start"]), int(v["end"])
        except (TypeError, KeyError, ValueError, OverflowError):
            raise _fail(path, 1, f"section {k}: expected {{\"start\": i, \"end\": j}}") from None
        if not 0 <= a < b:
            raise _fail(path, 1, f"section {k}: start {a} must be below end {b}")
        out[k] = (a, b)
    missing = [s for s in FACES if s not in out]
    if missing:
        raise _fail(path, 1, f"section(s) {', '.join(missing)} missing")
    return out


def is_section_list(head: str) -> bool:
    try:
        d = json.loads(head)
    except json.JSONDecodeError:
        return False
    return isinstance(d, dict) and bool(d) and set(d) <= set(SECTIONS)


def find_section_list(path) -> Path | None:
    p = Path(path)
    cand = p.with_name(p.stem + "_list.json")
    return cand if cand.is_file() else None


def read_imucal_session(path, sections_path=None, *, rate_hz=None, chip=None, scale=None,
                        units=None, gravity=F.G0, angle_deg=FERRARIS_ANGLE_DEG, kind="auto"):
    """imucal's continuous Ferraris session with its section list.  Rows are
    the file's rows (index = the first column); sections select rows by
    position [start, end) as imucal's ``ferraris_regions_from_section_list``
    does; rows outside every section are unlabelled."""
    rate = S.need_rate(rate_hz, "imucal-session")
    sections_path = sections_path or find_section_list(path)
    if sections_path is None:
        raise UserError(f"{path}: imucal session without its section list: give the JSON "
                        f"file too (or put it beside as {Path(path).stem}_list.json)")
    sections = _section_list(sections_path)
    gravity, angle_deg = R.check_gravity(gravity), R.check_angle(angle_deg)
    first, header, rows, last_line = _csv_rows(path)
    cols = header[1:]
    if sorted(cols) != sorted(ACC_COLS + GYR_COLS):
        raise _fail(path, 1, f"bad header {first.strip()[:80]!r}: expected an index column "
                    f"then gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z")
    nums = Rows(len(cols) + 1, np.float64)             # values, line
    for lineno, row in rows:
        if len(row) != len(header):
            raise _fail(path, lineno, f"expected {len(header)} columns, found {len(row)}")
        nums.add([_number(tok, path, lineno, name) for name, tok in zip(cols, row[1:])]
                 + [lineno])
    vals = nums.array()
    if not len(vals):
        raise _fail(path, last_line(), "no samples after the header")
    lines_of = vals[:, -1].astype(np.int64)
    n = len(vals)
    over = {k: ab for k, ab in sections.items() if ab[1] > n}
    if over:
        k, (a, b) = next(iter(over.items()))
        raise _fail(sections_path, 1, f"section {k} ends at row {b}, but {path} has {n} rows "
                    f"(truncated file or wrong list?)")
    idx = {c: i for i, c in enumerate(cols)}
    acc = vals[:, [idx[c] for c in ACC_COLS]]
    gyr = vals[:, [idx[c] for c in GYR_COLS]]
    del vals
    codes = np.full(n, -1, np.int64)
    for k, (a, b) in sorted(sections.items(), key=lambda kv: kv[1]):
        if (codes[a:b] >= 0).any():
            raise _fail(sections_path, 1, f"section {k} overlaps another section")
        codes[a:b] = SECTIONS.index(k)
    meta = {"format": "imucal-session", "source": f"{path}{'; '}{sections_path}",
            "rate_hz": rate, "rates_hz": {"accel": rate, "gyro": rate},
            "clocks": f"shared: t = row / {rate:g} Hz", "axis_frame": IMUCAL_FRAME}
    units = F.parse_units(units) or {"accel": "m/s^2", "gyro": "deg/s"}
    raw, lsbs, keep = S.convert(path, {"accel": acc, "gyro": gyr}, units, F.parse_scales(scale),
                                S.chip_scales(chip), gravity, meta,
                                line_of=lambda i: f"{path}: line {lines_of[i]}")
    meta["files"] = [{"file": str(path), "rows": [0, len(raw)], "samples": len(raw)},
                     {"file": str(sections_path), "sections": len(sections)}]
    return _labelled(path, raw, np.flatnonzero(keep), codes[keep], rate, meta, lsbs, chip,
                     angle_deg, kind)


# ------------------------------------------------------------------ MotionCal's Raw: lines

# What the sketches that feed MotionCal print (Adafruit's sensor calibration
# examples): accel m/s^2 * 8192 / 9.8, gyro deg/s * 16, mag uT * 10.
MOTIONCAL_SCALES = {"accel": 8192.0 * F.G0 / 9.8, "gyro": 16.0, "mag": 1000.0}
RAW_LINE = re.compile(r"Raw:\s*-?\d")           # a Raw: message, behind any log prefix


def read_motioncal(path, *, rate_hz=None, scale=None, chip=None, kind="auto"):
    """MotionCal's serial log: ``Raw:ax,ay,az,gx,gy,gz,mx,my,mz`` integer lines
    (scales above unless ``scale`` says otherwise).  As MotionCal itself,
    ``Raw:`` is found anywhere in a line, so a sender's log prefix (ESP-IDF's
    ``I (123) TAG: Raw:...``) is read; lines without it (``Uni:``,
    ``Cal1:``, a sender's other log lines) are skipped and counted in a note."""
    rows, skipped, last = Rows(10, np.float64), 0, 0             # 9 values, the line
    for lineno, line in numbered_lines(path):
        last = lineno
        at = line.find("Raw:")
        if at < 0:
            skipped += bool(line.strip())
            continue
        parts = line[at + 4:].split(",")
        if len(parts) != 9:
            raise _fail(path, lineno, f"expected 9 values after Raw:, found {len(parts)}")
        vals = []
        for j, tok in enumerate(parts, start=1):
            try:
                v = int(tok.strip())
            except ValueError:
                raise _fail(path, lineno, f"value {j} is not an integer count: "
                            f"{tok.strip()[:40]!r}") from None
            if not -32768 <= v <= 32768:
                raise _fail(path, lineno, f"value {j} = {v} is outside 16 bits")
            vals.append(v)
        rows.add(vals + [lineno])
    raw = rows.array()
    if not len(raw):
        raise _fail(path, last or 1, "no Raw: line")
    lines_of, raw = raw[:, 9].astype(np.int64), raw[:, :9]
    for s in ("accel", "mag"):
        R.check_zero_runs(raw[:, SENSOR_SLICES[s]], s, lambda i: f"{path}: line {lines_of[i]}")
    rate = 100.0 if rate_hz is None else S.need_rate(rate_hz, "motioncal")
    n = len(raw)
    meta = {"format": "motioncal", "source": str(path),
            "files": [{"file": str(path), "rows": [0, n], "samples": n}],
            "rate_hz": rate, "rates_hz": {s: rate for s in SENSOR_SLICES},
            "clocks": f"shared: t = row / {rate:g} Hz", "axis_frame": FLOAT_FRAME}
    if rate_hz is None:
        add_note(meta, "no sample rate given (--rate-hz): t = row / 100 assumed")
    if skipped:
        add_note(meta, f"{skipped} non-Raw lines skipped")
    data = _session(Path(path).stem, raw, np.arange(n) / rate, meta=meta)
    lsbs = dict(MOTIONCAL_SCALES)
    lsbs.update(S.chip_scales(chip))
    lsbs.update(F.parse_scales(scale))
    S.apply_scales(data, lsbs, chip)
    data.chips = {s: "MotionCal Raw" for s in SENSOR_SLICES}
    return _finish(data, None, kind, None)


# ------------------------------------------------------------------ detection and dispatch

SECTIONS_FORMAT = "imucal-sections"      # a section list: read with its session CSV


def detect_text(lines: list[str], text: str = "") -> str | None:
    """The foreign format of a text file from its first lines, or None."""
    if text.lstrip().startswith("{") and is_section_list(text):
        return SECTIONS_FORMAT
    first = next((s.strip() for s in lines if s.strip()), "")
    cols = [c.strip() for c in first.split(",")]
    if cols and cols[0] == "part" and set(ACC_COLS + GYR_COLS) <= set(cols):
        return "imucal-annotated"
    if len(cols) == 7 and sorted(cols[1:]) == sorted(ACC_COLS + GYR_COLS):
        return "imucal-session"
    if F.looks_like_float_log(lines):
        return "float-log"
    if any(RAW_LINE.search(s) for s in lines[:50]):      # anywhere, as MotionCal finds it
        return "motioncal"
    return None


def read_any(paths, found: dict, *, chip=None, kind="auto", **opts):
    """Read a session of foreign files; ``found`` maps each path to its format."""
    fmts = set(found.values())
    if fmts <= {"imucal-session", SECTIONS_FORMAT}:
        csvs = [p for p, f in found.items() if f == "imucal-session"]
        lists = [p for p, f in found.items() if f == SECTIONS_FORMAT]
        if len(csvs) != 1 or len(lists) > 1:
            raise UserError("imucal-session: give one session CSV (and at most one section "
                            "list JSON)")
        return read_imucal_session(csvs[0], lists[0] if lists else None, chip=chip, kind=kind,
                                   **_only(opts, "rate_hz", "scale", "units", "gravity",
                                           "angle_deg"))
    if len(fmts) > 1:
        listing = "; ".join(f"{p}: {f}" for p, f in found.items())
        raise UserError(f"files of different formats in one session ({listing})")
    fmt = fmts.pop()
    if fmt == SECTIONS_FORMAT:
        raise UserError("a section list alone: give the imucal session CSV with it")
    if fmt == "imucal-annotated":
        if len(found) != 1:
            raise UserError("imucal-annotated: import one file per session")
        return read_imucal_annotated(next(iter(found)), chip=chip, kind=kind,
                                     **_only(opts, "rate_hz", "scale", "units", "gravity",
                                             "angle_deg"))
    if fmt == "motioncal":
        if len(found) != 1:
            raise UserError("motioncal: import one log per session")
        return read_motioncal(next(iter(found)), chip=chip, kind=kind,
                              **_only(opts, "rate_hz", "scale"))
    return read_float_log(list(found), chip=chip, kind=kind,
                          **_only(opts, "columns", "rate_hz", "scale", "units", "gravity",
                                  "rate_dps", "rpm"))


def _only(opts: dict, *names) -> dict:
    return {k: v for k, v in opts.items() if k in names and v is not None}


FLOAT_OPTIONS = ("units", "scale", "gravity", "rate_hz", "rate_dps", "rpm", "columns",
                 "angle_deg")


def detect(path) -> str | None:
    """A foreign format of one file from its content, or None (a native
    format, or unknown: ``importer.detect_format`` says which)."""
    p = Path(path)
    if p.is_dir():
        return None
    check_input_file(p)                   # not a FIFO or device: opening one would block
    try:
        with open(p, "rb") as f:
            head = f.read(8192)
    except OSError as e:
        raise UserError(f"{p}: cannot read: {e.strerror or e}") from None
    try:
        text = head.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        if e.start < len(head) - 3:
            return None
        text = head[:e.start].decode("utf-8-sig")
    lines = text.splitlines()
    if len(head) == 8192 and lines:
        lines = lines[:-1]                    # the last line may be cut
    return detect_text(lines, text if len(head) < 8192 else "")


def read_session(paths, fmt: str = "auto", chip=None, kind: str = "auto", **opts):
    """``motecal import``'s reader: the native formats (``importer.read_any``)
    and the foreign ones, detected from content; options of float inputs
    (``FLOAT_OPTIONS``) are refused for formats that do not take them."""
    from .importer import FORMATS as NATIVE, read_any as read_native
    S.check_options(opts)
    paths = input_paths(paths)
    given = {k: v for k, v in opts.items() if v not in (None, [], ())}
    if fmt == "auto":
        found = {p: detect(p) for p in paths}
        if all(f is None for f in found.values()):
            fmt = "native"
        elif any(f is None for f in found.values()):
            from .importer import detect_format
            listing = "; ".join(f"{p}: {f or detect_format(p)}" for p, f in found.items())
            raise UserError(f"files of different formats in one session ({listing})")
    elif fmt in NATIVE:
        found, fmt = None, "native:" + fmt
    elif fmt in FORMATS:
        found = {p: (SECTIONS_FORMAT if fmt == "imucal-session" and detect(p) == SECTIONS_FORMAT
                     else fmt) for p in paths}
    else:
        raise UserError(f"unknown format {fmt!r}")
    if fmt.startswith("native"):
        if given:
            names = ", ".join("--" + k.replace("_", "-") for k in given)
            raise UserError(f"{names}: only for float inputs and other tools' formats "
                            f"(imucal, FreeIMU-cal, MotionCal)")
        return read_native(paths, fmt=fmt.partition(":")[2] or "auto", chip=chip, kind=kind)
    data = read_any(paths, found, chip=chip, kind=kind, **given)
    return data
