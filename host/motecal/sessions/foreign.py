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
from pathlib import Path

import numpy as np

from . import floatlog as F
from ..errors import UserError
from ..inputs import check_input_file, read_input_text
from .importer import _fail, _finish, _read_text_lines, _session, add_note, input_paths
from .session import LABEL_ROT, SENSOR_SLICES, UNITS
from .still import StillThresholds, segment_recording

STEADY = StillThresholds(gyro_rule="rate")

FORMATS = ("imucal-annotated", "imucal-session", "float-log", "motioncal")
FACES = ("x_p", "x_a", "y_p", "y_a", "z_p", "z_a")
ROTATIONS = ("x_rot", "y_rot", "z_rot")
SECTIONS = FACES + ROTATIONS
POSE_OF = {f: i for i, f in enumerate(FACES, start=1)}
FERRARIS_ANGLE_DEG = 360.0       # imucal's default rotation (sign from the data)
IMUCAL_FRAME = "as recorded: imucal's sensor frame (x_p: the x axis reads +1 g)"
FLOAT_FRAME = "as recorded: the logger's sensor axes"
ACC_COLS = ("acc_x", "acc_y", "acc_z")
GYR_COLS = ("gyr_x", "gyr_y", "gyr_z")


def _need_rate(rate_hz, fmt):
    if rate_hz is None:
        raise UserError(f"{fmt}: the file has no times: give the sample rate with --rate-hz "
                        f"(imucal's examples: 204.8 Hz annotated, 102.4 Hz session)")
    rate_hz = float(rate_hz)
    if not np.isfinite(rate_hz) or rate_hz <= 0:
        raise UserError("--rate-hz must be a positive number")
    return rate_hz


def _convert(path, vals: dict, units: dict, scales: dict, chip_scales: dict, gravity, meta,
             line_of=None):
    """{sensor: (n, 3) floats} -> raw (n, 9) counts; roundings noted in meta."""
    n = len(next(iter(vals.values())))
    raw = np.full((n, 9), np.nan)
    rounding = {}
    lsbs = {}
    for s, x in vals.items():
        unit = units.get(s, F.SI_UNITS[s])
        lsb, frm = scales.get(s), "declared"
        if lsb is None and s in chip_scales:
            lsb, frm = chip_scales[s], "chip"
        counts, rnd = F.to_counts(x, s, unit, lsb=lsb, scale_from=frm, gravity=gravity,
                                  where=f"{path}: ", line_of=line_of)
        raw[:, SENSOR_SLICES[s]] = counts
        rounding[s] = rnd.text()
        lsbs[s] = rnd.lsb_per_unit
        meta.setdefault("scale_from", {})[s] = rnd.scale_from
        if unit != "counts" and np.all(x == np.rint(x)):
            add_note(meta, f"every {s} value is a whole number of {unit}: raw counts? "
                           f"(then give --units {s}=counts and its --scale)")
        if rnd.step_counts is not None and abs(rnd.step_counts - 1) > F.STEP_MISMATCH:
            add_note(meta, rnd.text())
    meta["units_in"] = {s: units.get(s, F.SI_UNITS[s]) for s in vals}
    meta["rounding"] = rounding
    meta["gravity_mss"] = gravity
    return raw, lsbs


def _chip_scales(chip) -> dict:
    from .importer import parse_chip_overrides
    return {s: sc for s, (_, sc) in parse_chip_overrides(chip).items()}


def _apply_scales(data, lsbs: dict, chip):
    from .importer import parse_chip_overrides
    names = {s: n for s, (n, _) in parse_chip_overrides(chip).items()}
    source = data.meta.get("scale_from", {})
    for s in SENSOR_SLICES:
        if s in lsbs:
            data.scales[s] = float(lsbs[s])
            data.chips[s] = names.get(s, "the file's step" if source.get(s) == "file step"
                                      else "declared scale")
        else:
            data.chips[s] = None


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

def read_imucal_annotated(path, *, rate_hz=None, chip=None, scale=None, units=None,
                          gravity=F.G0, angle_deg=FERRARIS_ANGLE_DEG, kind="auto"):
    """imucal's annotated session (``example_data/annotated_session.csv``): raw
    counts unless ``units`` say otherwise; rows sorted by ``samples``
    (t = samples / rate)."""
    rate = _need_rate(rate_hz, "imucal-annotated")
    lines = _read_text_lines(path)
    if not lines:
        raise _fail(path, 1, "empty file: no header")
    header = [h.strip() for h in next(csv.reader([lines[0]]))]
    need = ("part", "samples") + ACC_COLS + GYR_COLS
    if sorted(header) != sorted(need):
        raise _fail(path, 1, f"bad header {lines[0].strip()[:80]!r}: expected "
                    f"{','.join(need)}")
    col = {h: i for i, h in enumerate(header)}
    parts, samples, vals, lines_of = [], [], [], []
    for lineno, row in enumerate(csv.reader(lines[1:]), start=2):
        if not row or (len(row) == 1 and not row[0].strip()):
            continue
        if len(row) != len(header):
            raise _fail(path, lineno, f"expected {len(header)} columns, found {len(row)}")
        part = row[col["part"]].strip()
        if part not in SECTIONS:
            raise _fail(path, lineno, f"unknown section {part!r} (expected one of "
                        f"{', '.join(SECTIONS)})")
        try:
            k = int(float(row[col["samples"]]))
        except ValueError:
            raise _fail(path, lineno, f"samples is not a number: {row[col['samples']]!r}") from None
        v = []
        for c in ACC_COLS + GYR_COLS:
            tok = row[col[c]].strip()
            try:
                x = float(tok)
            except ValueError:
                raise _fail(path, lineno, f"{c} is not a number: {tok!r}") from None
            if not np.isfinite(x):
                raise _fail(path, lineno, f"{c} is not a finite number: {tok!r}")
            v.append(x)
        parts.append(part)
        samples.append(k)
        vals.append(v)
        lines_of.append(lineno)
    if not vals:
        raise _fail(path, len(lines), "no samples after the header")
    missing = [s for s in FACES if s not in parts]
    if missing:
        raise _fail(path, len(lines), f"section(s) {', '.join(missing)} missing: a Ferraris "
                    f"session has the six faces x_p .. z_a")
    samples = np.array(samples)
    order = np.argsort(samples, kind="stable")
    dup = np.flatnonzero(np.diff(samples[order]) == 0)
    if len(dup):
        i = order[dup[0] + 1]
        raise _fail(path, lines_of[i], f"sample {samples[i]} appears twice")
    vals = np.array(vals)[order]
    parts = [parts[i] for i in order]
    lines_sorted = [lines_of[i] for i in order]
    samples = samples[order]
    meta = {"format": "imucal-annotated", "source": str(path),
            "files": [{"file": str(path), "rows": [0, len(samples)], "samples": len(samples)}],
            "rate_hz": rate, "rates_hz": {"accel": rate, "gyro": rate},
            "clocks": f"shared: t = samples / {rate:g} Hz", "axis_frame": IMUCAL_FRAME}
    units = F.parse_units(units) or {"accel": "counts", "gyro": "counts"}
    scales = F.parse_scales(scale)
    raw, lsbs = _convert(path, {"accel": vals[:, 0:3], "gyro": vals[:, 3:6]}, units, scales,
                         _chip_scales(chip), gravity, meta,
                         line_of=lambda i: f"{path}: line {lines_sorted[i]}")
    return _labelled(path, raw, samples, parts, rate, meta, lsbs, chip, angle_deg, kind)


def _labelled(path, raw, samples, parts, rate, meta, lsbs, chip, angle_deg, kind):
    n = len(raw)
    label = np.zeros(n, np.int32)
    rows = {}
    for i, p in enumerate(parts):
        label[i] = POSE_OF.get(p, LABEL_ROT if p in ROTATIONS else 0)
        if p in ROTATIONS:
            a, b = rows.get(p, (i, i + 1))
            if i != b and p in rows:
                raise UserError(f"{path}: section {p} is not one contiguous block")
            rows[p] = (min(a, i), i + 1)
    meta["pose_names"] = {str(v): k for k, v in POSE_OF.items()}
    meta["rotations"] = _rotations_meta(rows, angle_deg)
    data = _session(Path(path).stem, raw, samples / rate, seq=samples, label=label, meta=meta)
    _apply_scales(data, lsbs, chip)
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
        except (TypeError, KeyError, ValueError):
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
    rate = _need_rate(rate_hz, "imucal-session")
    sections_path = sections_path or find_section_list(path)
    if sections_path is None:
        raise UserError(f"{path}: imucal session without its section list: give the JSON "
                        f"file too (or put it beside as {Path(path).stem}_list.json)")
    sections = _section_list(sections_path)
    lines = _read_text_lines(path)
    if not lines:
        raise _fail(path, 1, "empty file: no header")
    header = [h.strip() for h in next(csv.reader([lines[0]]))]
    cols = header[1:]
    if sorted(cols) != sorted(ACC_COLS + GYR_COLS):
        raise _fail(path, 1, f"bad header {lines[0].strip()[:80]!r}: expected an index column "
                    f"then gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z")
    vals, lines_of = [], []
    for lineno, row in enumerate(csv.reader(lines[1:]), start=2):
        if not row or (len(row) == 1 and not row[0].strip()):
            continue
        if len(row) != len(header):
            raise _fail(path, lineno, f"expected {len(header)} columns, found {len(row)}")
        lines_of.append(lineno)
        v = []
        for name, tok in zip(cols, row[1:]):
            try:
                x = float(tok)
            except ValueError:
                raise _fail(path, lineno, f"{name} is not a number: {tok.strip()!r}") from None
            if not np.isfinite(x):
                raise _fail(path, lineno, f"{name} is not a finite number: {tok.strip()!r}")
            v.append(x)
        vals.append(v)
    if not vals:
        raise _fail(path, len(lines), "no samples after the header")
    vals = np.array(vals)
    n = len(vals)
    over = {k: ab for k, ab in sections.items() if ab[1] > n}
    if over:
        k, (a, b) = next(iter(over.items()))
        raise _fail(sections_path, 1, f"section {k} ends at row {b}, but {path} has {n} rows "
                    f"(truncated file or wrong list?)")
    idx = {c: i for i, c in enumerate(cols)}
    acc = vals[:, [idx[c] for c in ACC_COLS]]
    gyr = vals[:, [idx[c] for c in GYR_COLS]]
    parts = [""] * n
    taken = np.zeros(n, bool)
    for k, (a, b) in sorted(sections.items(), key=lambda kv: kv[1]):
        if taken[a:b].any():
            raise _fail(sections_path, 1, f"section {k} overlaps another section")
        taken[a:b] = True
        for i in range(a, b):
            parts[i] = k
    meta = {"format": "imucal-session", "source": f"{path}{'; '}{sections_path}",
            "files": [{"file": str(path), "rows": [0, n], "samples": n},
                      {"file": str(sections_path), "sections": len(sections)}],
            "rate_hz": rate, "rates_hz": {"accel": rate, "gyro": rate},
            "clocks": f"shared: t = row / {rate:g} Hz", "axis_frame": IMUCAL_FRAME}
    units = F.parse_units(units) or {"accel": "m/s^2", "gyro": "deg/s"}
    raw, lsbs = _convert(path, {"accel": acc, "gyro": gyr}, units, F.parse_scales(scale),
                         _chip_scales(chip), gravity, meta,
                         line_of=lambda i: f"{path}: line {lines_of[i]}")
    return _labelled(path, raw, np.arange(n), parts, rate, meta, lsbs, chip, angle_deg, kind)


# ------------------------------------------------------------------ float logs (FreeIMU-cal)

def _same_steps(paths, blocks, sensors):
    """Files of one session must share each sensor's step (resolution): a
    file in other units (deg/s beside rad/s) or at another range is refused."""
    if len(blocks) < 2:
        return
    for i, s in enumerate(sensors):
        steps = [(p, F.file_step(x[:, 3 * i:3 * i + 3])) for p, x in zip(paths, blocks)]
        known = [(p, q) for p, q in steps if q]
        for p, q in known[1:]:
            p0, q0 = known[0]
            if abs(q / q0 - 1) > F.STEP_MISMATCH:
                raise UserError(f"{p}: line 1: {s} values step by {q:.6g}, but {p0} steps by "
                                f"{q0:.6g} ({q / q0:.4g}x): mixed units or ranges in one session")


def read_float_log(paths, *, columns=None, rate_hz=None, chip=None, scale=None, units=None,
                   gravity=F.G0, rate_dps=None, rpm=None, kind="auto"):
    """Headerless float logs, one sensor per file unless ``columns`` name
    several (FreeIMU-cal: ``...acc.txt`` m/s^2, ``...gyr.txt`` rad/s,
    ``...mag.txt`` uT; ``units`` overrides).  Several files of one sensor
    are one session, one recording each.  ``rate_hz`` (default 100, noted)
    sets t = row / rate.  With a turntable rate, steady turns at that rate
    are ``rot`` (``meta["turntable"]``) and rests are poses."""
    if isinstance(paths, (str, Path)):
        paths = [paths]
    paths = [Path(p) for p in paths]
    notes = []
    if rate_hz is None:
        rate = 100.0
        notes.append("no sample rate given (--rate-hz): t = row / 100 assumed")
    else:
        rate = _need_rate(rate_hz, "float-log")
    turn_dps = F.turntable_rates_dps(rate_dps, rpm)
    units = F.parse_units(units)
    blocks, files, sensors_all, pos, line_at = [], [], None, 0, []
    for p in paths:
        sensors = F.sensors_of_file(p, columns)
        if sensors_all is not None and sensors != sensors_all:
            raise UserError(f"{p}: holds {', '.join(sensors)}, but {paths[0]} holds "
                            f"{', '.join(sensors_all)}: one sensor set per session")
        sensors_all = sensors
        lines = _read_text_lines(p)
        x, where = F.parse_float_log(p, lines, 3 * len(sensors), _fail)
        line_at += [(p, k) for k in where]
        blocks.append(x)
        files.append({"file": str(p), "rows": [pos, pos + len(x)], "samples": len(x)})
        pos += len(x)
    _same_steps(paths, blocks, sensors_all)
    x = np.vstack(blocks)
    meta = {"format": "float-log", "source": "; ".join(map(str, paths)), "files": files,
            "rate_hz": rate, "rates_hz": {s: rate for s in sensors_all},
            "clocks": f"shared: t = row / {rate:g} Hz", "axis_frame": FLOAT_FRAME}
    for note in notes:
        add_note(meta, note)
    vals = {s: x[:, 3 * i:3 * i + 3] for i, s in enumerate(sensors_all)}
    raw, lsbs = _convert(paths[0], vals, units, F.parse_scales(scale), _chip_scales(chip),
                         gravity, meta, line_of=lambda i: f"{line_at[i][0]}: line {line_at[i][1]}")
    n = len(raw)
    data = _session(paths[0].stem if len(paths) == 1 else paths[0].parent.name or paths[0].stem,
                    raw, np.arange(n) / rate, meta=meta)
    _apply_scales(data, lsbs, chip)
    parts = [tuple(f["rows"]) for f in files]
    if not turn_dps:
        return _finish(data, None, kind, parts, pose_per_part=len(parts) > 1)
    if "gyro" not in lsbs:
        raise UserError(f"{paths[0]}: a turntable rate needs gyroscope data")
    seg = np.zeros(n, np.int32)
    k0 = 0
    for a, b in parts:
        # steady stretches, turning or not: the rate's spread (a constant turn
        # is not still, but it is what a turntable segment is)
        s = segment_recording(raw[a:b], data.t[a:b], rate, data.scales, STEADY)
        seg[a:b] = np.where(s > 0, s + k0, 0)
        k0 += int(s.max(initial=0))
    turns, rests = F.turntable_segments(data.physical("gyro"), seg, turn_dps)
    if not turns:
        raise UserError(f"{paths[0]}: no steady turn at {', '.join(f'{r:g}' for r in turn_dps)} "
                        f"deg/s found (is the rate "
                        f"or the gyroscope's unit right? units in: {meta['units_in']['gyro']})")
    segs = F.label_turntable(data.label, turns, rests)
    data.meta["turntable"] = {"rates_dps": turn_dps, "segments": segs,
                              "segment_rates_dps": [r for _, r in turns]}
    data.meta["rotations"] = [{"name": f"turn{i}", "axis": None, "rows": seg, "rate_dps": r}
                              for i, (seg, (_, r)) in enumerate(zip(segs, turns), start=1)]
    return _finish(data, None, kind, None, has_labels=True)


# ------------------------------------------------------------------ MotionCal's Raw: lines

# What the sketches that feed MotionCal print (Adafruit's sensor calibration
# examples): accel m/s^2 * 8192 / 9.8, gyro deg/s * 16, mag uT * 10.
MOTIONCAL_SCALES = {"accel": 8192.0 * F.G0 / 9.8, "gyro": 16.0, "mag": 1000.0}


def read_motioncal(path, *, rate_hz=None, scale=None, chip=None, kind="auto"):
    """MotionCal's serial log: ``Raw:ax,ay,az,gx,gy,gz,mx,my,mz`` integer lines
    (scales above unless ``scale`` says otherwise); other ``Word:`` lines
    (``Uni:``, ``Cal1:``) are skipped and counted in a note."""
    lines = _read_text_lines(path)
    rows, skipped = [], 0
    for lineno, line in enumerate(lines, start=1):
        s = line.strip()
        if not s:
            continue
        if not s.startswith("Raw:"):
            head = s.split(":", 1)[0]
            if ":" in s and head.isalpha():
                skipped += 1
                continue
            raise _fail(path, lineno, f"not a MotionCal line (Raw:...): {s[:60]!r}")
        parts = s[4:].split(",")
        if len(parts) != 9:
            raise _fail(path, lineno, f"expected 9 values after Raw:, found {len(parts)}")
        vals = []
        for j, tok in enumerate(parts, start=1):
            try:
                v = int(tok.strip())
            except ValueError:
                raise _fail(path, lineno, f"value {j} is not an integer count: "
                            f"{tok.strip()!r}") from None
            if not -32768 <= v <= 32768:
                raise _fail(path, lineno, f"value {j} = {v} is outside 16 bits")
            vals.append(v)
        rows.append(vals)
    if not rows:
        raise _fail(path, len(lines) or 1, "no Raw: line")
    rate = 100.0 if rate_hz is None else _need_rate(rate_hz, "motioncal")
    raw = np.array(rows, float)
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
    lsbs.update(_chip_scales(chip))
    lsbs.update(F.parse_scales(scale))
    _apply_scales(data, lsbs, chip)
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
    if any(s.strip().startswith("Raw:") for s in lines[:50]):
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
    paths = input_paths(paths)
    given = {k: v for k, v in opts.items() if v not in (None, [], ())}
    if fmt == "auto":
        found = {p: detect(p) for p in paths}
        if all(f is None for f in found.values()):
            fmt = "native"
        elif any(f is None for f in found.values()):
            # native and other tools' files together: each group by its own
            # reader, put together as separate recordings (sessions.combine)
            from .combine import combine
            native = [p for p, f in found.items() if f is None]
            other = {p: f for p, f in found.items() if f is not None}
            return combine([read_native(native, fmt="auto", chip=chip, kind=kind),
                            read_any(list(other), other, chip=chip, kind=kind, **given)])
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
