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

import contextlib
import csv
import re
from dataclasses import asdict
from pathlib import Path

import numpy as np

from ..errors import UserError
from ..inputs import check_input_file, read_input_bytes
from ..line.protocol import (ITG3200_TEMP_AT_OFFSET_C, ITG3200_TEMP_LSB_PER_C,
                             ITG3200_TEMP_OFFSET, NINEDOF_RATE_HZ)
from .options import option_parts
from .session import (ADXL345_LSB_PER_G, CHIP_RANGES, COLUMNS, HMC5883L_LSB_PER_GAUSS,
                      HMC5883L_OVERFLOW, INT16_MAX, ITG3200_LSB_PER_DPS, LABEL_MAX, LABEL_NONE, LABEL_ROT, NOMINAL_CHIPS, NOMINAL_SCALES,
                      SENSOR_SLICES, UNITS, SessionData, batch_times, label_from_text,
                      label_to_text, rate_from_times)
from .still import StillThresholds, segment_recording, window_rows

FORMATS = ("csv", "razor-text", "razor-float", "timestamped-csv")
KINDS = ("auto", "static", "rotation", "idle")
CSV_HEADER = ("mote",) + ("seq", "t", "label") + COLUMNS
CSV_TEMP = "temp"               # optional last column: board temperature, degrees C
TEMP_RANGE_C = (-100.0, 200.0)  # what an ITG3200-style sensor can report (int16 raw: -82..199)
RAZOR_RATE_HZ = 50.0            # Razor AHRS firmware output: one sample every 20 ms
IMPORT_MOTE = 1                 # mote id given to rows of formats without one
AUTO_ROTATION_BELOW = 0.5       # auto kind: rotation when the still fraction is lower
SOURCE_SEP = "; "                # meta["source"]: the files, one text

# LSB per unit (accel LSB/g, gyro LSB/(deg/s), mag LSB/gauss), datasheet nominal
CHIP_SCALES = {
    "accel": {"ADXL345": ADXL345_LSB_PER_G,          # full resolution
              "MPU6050": 16384.0},                   # +-2 g
    "gyro": {"ITG3200": ITG3200_LSB_PER_DPS,         # FS_SEL=3
             "ITG3205": ITG3200_LSB_PER_DPS,
             "MPU6050": 131.0},                      # +-250 deg/s
    "mag": {"HMC5883L": HMC5883L_LSB_PER_GAUSS,      # default gain
            "HMC5843": 1300.0},                      # default gain
}
# a reading at or beyond this many counts (absolute) is the sensor's full scale
CLIP_COUNTS = {"MPU6050": INT16_MAX, "ITG3205": INT16_MAX,
               **{chip: hi for chip, (lo, hi) in CHIP_RANGES.items() if chip != "HMC5883L"}}
SENSOR_ALIASES = {"accel": "accel", "acc": "accel", "a": "accel",
                  "gyro": "gyro", "gyr": "gyro", "g": "gyro",
                  "mag": "mag", "m": "mag", "magnetometer": "mag"}

RAZOR_FRAME = ("as recorded: Razor AHRS firmware board frame (accel x = chip y, "
               "accel y = chip x; gyroscope and magnetometer sign flips)")
RAZOR_FLOAT_FRAME = "as recorded: Razor AHRS firmware board frame (magnetometer x, y, z)"
TIMESTAMPED_FRAME = "as recorded: chip axes of each sensor as written in the file"
CSV_FRAME = "as recorded: motecal sample frame (the mote's sensor axes)"


# ------------------------------------------------------------------ chips

def normalise_chip(name: str) -> str:
    return re.sub(r"[^A-Z0-9]", "", str(name).upper())


def parse_chip_overrides(chip) -> dict:
    """``{"mag": "hmc5843"}``, ``"mag=hmc5843"``, ``["mag=hmc5843", "gyro=itg3205"]``
    or ``"mag=mychip:1234"`` (explicit LSB per unit) -> ``{sensor: (CHIP, scale)}``.
    A bare chip name (``"hmc5843"``) applies to the sensor it belongs to."""
    out = {}
    for part in option_parts(chip):
        if "=" in part:
            sensor, _, name = part.partition("=")
            sensor = SENSOR_ALIASES.get(sensor.strip().lower())
            if sensor is None:
                raise UserError(f"--chip {part}: sensor must be accel, gyro or mag")
        else:
            sensor, name = None, part
        name, _, scale_text = name.partition(":")
        chipname = normalise_chip(name)
        if scale_text:
            try:
                scale = float(scale_text)
            except ValueError:
                scale = float("nan")
            if not np.isfinite(scale) or scale <= 0:
                raise UserError(f"--chip {part}: scale must be a positive number of LSB per unit")
            if sensor is None:
                raise UserError(f"--chip {part}: give the sensor, e.g. mag={name}:{scale_text}")
            out[sensor] = (chipname, scale)
            continue
        owners = [s for s, chips in CHIP_SCALES.items() if chipname in chips]
        if sensor is None:
            if len(owners) != 1:
                raise UserError(f"--chip {part}: say which sensor, e.g. mag={name}")
            sensor = owners[0]
        if chipname not in CHIP_SCALES[sensor]:
            known = ", ".join(c.lower() for c in CHIP_SCALES[sensor])
            raise UserError(f"--chip {part}: unknown {sensor} chip (known: {known}; "
                            f"or give the scale: {sensor}={name}:LSB_PER_UNIT)")
        out[sensor] = (chipname, CHIP_SCALES[sensor][chipname])
    return out


def _chips_for(names: dict) -> tuple[dict, dict]:
    chips = dict(NOMINAL_CHIPS)
    scales = dict(NOMINAL_SCALES)
    for sensor, name in names.items():
        chips[sensor] = name
        scales[sensor] = CHIP_SCALES[sensor][name]
    return chips, scales


def add_note(meta: dict, note: str) -> None:
    """``meta["notes"]`` is one text (a database column): notes joined by '; '."""
    meta["notes"] = f"{meta['notes']}; {note}" if meta.get("notes") else note


# ------------------------------------------------------------------ errors and parsing

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
    if not np.isfinite(v):
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


# ------------------------------------------------------------------ stillness and labels

def _longest_segment(seg: np.ndarray) -> int:
    if not (seg > 0).any():
        return 0
    counts = np.bincount(seg[seg > 0])
    return int(np.argmax(counts))


def assign_labels(data: SessionData, kind: str = "auto", parts=None, pose_per_part=False,
                  th: StillThresholds = StillThresholds()) -> SessionData:
    """Label the rows of ``data`` in place from stillness and set ``data.kind``.

    ``parts`` is a list of ``(start, stop)`` row ranges recorded separately
    (files, motes); each is segmented on its own and its still segments are
    numbered 1..K.  With ``pose_per_part`` (several files of one pose each),
    part i (1-based) is pose i instead: its longest still segment.
    Records the decision in ``meta["kind_decision"]`` and ``meta["still_fraction"]``.
    """
    if kind not in KINDS:
        raise UserError(f"kind must be one of {', '.join(KINDS)}, not {kind!r}")
    n = len(data)
    parts = parts or [(0, n)]
    rate = data.rate()
    seg = np.zeros(n, np.int32)
    per_part = np.zeros(n, np.int32)
    missing, n_segments, max_segments = [], 0, 0
    for i, (a, b) in enumerate(parts, start=1):
        s = segment_recording(data.raw[a:b], data.t[a:b], rate, data.scales, th)
        seg[a:b] = s
        k_max = int(s.max()) if len(s) else 0
        n_segments += k_max
        max_segments = max(max_segments, k_max)
        k = _longest_segment(s)
        if k:
            per_part[a:b][s == k] = i
        else:
            missing.append(i)
    still_fraction = float((seg > 0).mean()) if n else 0.0
    short = [i for i, (a, b) in enumerate(parts, start=1) if b - a < window_rows(rate, th)]
    if short:
        which = ("the recording is" if len(parts) == 1
                 else f"recordings {', '.join(map(str, short))} are")
        add_note(data.meta, f"{which} shorter than the stillness window ({th.window_s:g} s): "
                 "no row can be judged still")
    if pose_per_part and len(parts) > 1:
        labels, n_poses = per_part, len(parts) - len(missing)
        how = f"one pose per file, {n_poses} of {len(parts)} files have a still part"
    else:
        labels, n_poses = seg, max_segments
        how = f"{n_segments} still segment{'s' if n_segments != 1 else ''}"
        if len(parts) > 1:
            how += f" in {len(parts)} recordings"
    if kind == "auto":
        if still_fraction < AUTO_ROTATION_BELOW:
            chosen = "rotation"
            why = f"{still_fraction:.1%} of rows still < {AUTO_ROTATION_BELOW:.0%}"
        else:
            chosen = "static" if n_poses >= 2 else "idle"
            why = f"{still_fraction:.1%} of rows still, {how}"
        decision = f"auto: {chosen} ({why})"
    else:
        chosen = kind
        decision = f"given: {kind} ({still_fraction:.1%} of rows still, {how})"
    files = data.meta.get("files")
    if chosen == "rotation":
        data.label[:] = LABEL_ROT
    else:
        data.label[:] = labels
        if pose_per_part and len(parts) > 1:
            if files and len(files) == len(parts):
                for i, f in enumerate(files, start=1):
                    f["pose"] = None if i in missing else i
            if missing:
                names = [str(files[i - 1]["file"]) if files else f"part {i}" for i in missing]
                add_note(data.meta,
                    f"no still part in {', '.join(names)}: pose label(s) "
                    f"{', '.join(map(str, missing))} absent")
    data.kind = chosen
    data.meta["kind_decision"] = decision
    data.meta["still_fraction"] = round(still_fraction, 4)
    data.meta["still_thresholds"] = asdict(th)
    return data


# ------------------------------------------------------------------ metadata

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


def _finish(data: SessionData, chip, kind, parts, has_labels=False,
            pose_per_part=False) -> SessionData:
    """Apply --chip overrides, fill counts/clipping, label (unless labelled)."""
    over = data.raw == 32768
    if over.any():
        data.raw[over] = 32767
        add_note(data.meta, f"{int(over.sum())} values of 32768 (one past the 16-bit full scale) "
                 f"stored as 32767")
    overrides = parse_chip_overrides(chip)
    for sensor, (name, scale) in overrides.items():
        data.chips[sensor] = name
        data.scales[sensor] = float(scale)
    if overrides:
        data.meta["chips_from"] = "--chip " + ", ".join(
            f"{s}={n}" for s, (n, _) in sorted(overrides.items()))
    data.meta["samples"] = _sensor_counts(data.raw)
    data.meta["clipped"] = _clipped(data.raw, data.chips)
    data.meta["units"] = dict(UNITS)
    if has_labels:
        rot = bool((data.label == LABEL_ROT).any())
        poses = data.poses()
        if kind == "auto":
            data.kind = "rotation" if rot and not poses else ("static" if poses else "free")
            data.meta["kind_decision"] = f"auto: {data.kind} (labels from the file)"
        else:
            data.kind = kind
            data.meta["kind_decision"] = f"given: {kind} (labels from the file)"
    else:
        assign_labels(data, kind, parts, pose_per_part=pose_per_part)
    return data


def _session(name, raw, t, mote=None, seq=None, label=None, chips=None, meta=None):
    n = len(raw)
    chips_, scales_ = _chips_for(chips or {})
    return SessionData(
        name=name, raw=raw, mote=np.full(n, IMPORT_MOTE) if mote is None else mote,
        seq=np.arange(n) if seq is None else seq, t=t,
        label=np.zeros(n, np.int32) if label is None else label,
        flags=np.zeros(n, np.uint8), kind="imported", scales=scales_, chips=chips_,
        meta=meta or {})


# ------------------------------------------------------------------ project CSV

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


# ------------------------------------------------------------------ Razor AHRS text

_RAZOR_LINE = re.compile(r"^#([AMG])-R=(.*)$")
_RAZOR_ORDER = ("A", "M", "G")
_RAZOR_COLS = {"A": slice(0, 3), "G": slice(3, 6), "M": slice(6, 9)}


def _parse_razor_text(path) -> tuple[np.ndarray, int | None]:
    lines = _read_text_lines(path)
    samples = []
    cur = np.full(9, np.nan)
    expect = 0                        # index into A, M, G
    start_line = None
    for lineno, line in enumerate(lines, start=1):
        s = line.strip()
        if not s:
            continue
        m = _RAZOR_LINE.match(s)
        if not m:
            raise _fail(path, lineno, f"not a Razor AHRS raw line (#A-R=, #M-R=, #G-R=): "
                        f"{s[:60]!r}")
        key, rest = m.group(1), m.group(2)
        if key != _RAZOR_ORDER[expect]:
            raise _fail(path, lineno, f"expected #{_RAZOR_ORDER[expect]}-R= (samples are A, M, G "
                        f"lines in turn), found #{key}-R=")
        parts = rest.split(",")
        if len(parts) != 3:
            raise _fail(path, lineno, f"expected 3 values after #{key}-R=, found {len(parts)}")
        vals = [_count(p, path, lineno, f"#{key}-R value {j + 1}") for j, p in enumerate(parts)]
        if expect == 0:
            start_line = lineno
        cur[_RAZOR_COLS[key]] = vals
        expect += 1
        if expect == 3:
            samples.append(cur)
            cur = np.full(9, np.nan)
            expect = 0
    if not samples:
        raise _fail(path, 1, "no complete Razor AHRS sample (#A-R=, #M-R=, #G-R= lines)")
    raw = np.array(samples)
    # an incomplete last sample (capture stopped mid-sample) is dropped, noted by caller
    return raw, (start_line if expect else None)


def read_razor_text(paths, chip=None, kind="auto") -> SessionData:
    """Razor AHRS raw text logs: ``#A-R=``, ``#M-R=``, ``#G-R=`` lines, one sample
    = A, M, G; 50 Hz without timestamps, so ``t = row / 50``.

    Several files form one session (rows in the order given); each file is a
    separate recording for stillness, and with a static kind one pose per file.
    Chips: ADXL345, ITG3205, HMC5883L (SparkFun 9DOF Sensor Stick).
    """
    if isinstance(paths, (str, Path)):
        paths = [paths]
    paths = list(paths)
    if not paths:
        raise UserError("no Razor AHRS text file given")
    blocks, files, notes, pos = [], [], [], 0
    for p in paths:
        raw, partial = _parse_razor_text(p)
        if partial:
            notes.append(f"{p}: incomplete last sample from line {partial} dropped")
        blocks.append(raw)
        files.append({"file": str(p), "rows": [pos, pos + len(raw)], "samples": len(raw)})
        pos += len(raw)
    raw = np.vstack(blocks)
    n = len(raw)
    meta = {"format": "razor-text", "source": SOURCE_SEP.join(map(str, paths)), "files": files,
            "rate_hz": RAZOR_RATE_HZ, "rates_hz": {s: RAZOR_RATE_HZ for s in SENSOR_SLICES},
            "clocks": "shared (one A, M, G sample every 20 ms; t = row / 50)",
            "axis_frame": RAZOR_FRAME}
    for note in notes:
        add_note(meta, note)
    data = _session(Path(paths[0]).stem if len(paths) == 1 else Path(paths[0]).parent.name
                    or Path(paths[0]).stem, raw, np.arange(n) / RAZOR_RATE_HZ,
                    chips={"accel": "ADXL345", "gyro": "ITG3205", "mag": "HMC5883L"}, meta=meta)
    return _finish(data, chip, kind, [tuple(f["rows"]) for f in files], pose_per_part=True)


# ------------------------------------------------------------------ Razor float (magnetometer)

def _be_float32(buf: bytes) -> np.ndarray:
    """Big-endian float32 values of ``buf`` as float64; any bit pattern (a
    signalling NaN in random bytes warns when cast) without a warning."""
    with np.errstate(invalid="ignore"):
        return np.frombuffer(buf, ">f4").astype(np.float64)


def _float_values(path) -> np.ndarray:
    buf = _read_bytes(path)
    if len(buf) == 0:
        raise UserError(f"{path}: empty file: no float32 samples")
    whole = len(buf) // 12
    if len(buf) % 12:
        raise UserError(f"{path}: sample {whole + 1} (byte {whole * 12}): truncated float file, "
                        f"{len(buf)} bytes is not a whole number of 12-byte samples "
                        f"(3 big-endian float32)")
    x = _be_float32(buf).reshape(-1, 3)
    with np.errstate(invalid="ignore"):
        bad = ~np.isfinite(x).all(axis=1) | (np.abs(x) > 32768).any(axis=1) \
            | (x != np.round(x)).any(axis=1)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise UserError(f"{path}: sample {k + 1} (byte {k * 12}): not raw integer counts "
                        f"({', '.join(f'{v:g}' for v in x[k])}); not a big-endian float32 "
                        f"triplet file?")
    return x


def read_razor_float(path, chip="hmc5883l", kind="auto") -> SessionData:
    """Headerless big-endian float32 triplets (x, y, z magnetometer counts), the
    Razor AHRS ``magnetom.float`` logs: 50 Hz, no timestamps (t = row / 50).
    ``chip`` is the magnetometer (``hmc5883l`` 1090 LSB/gauss, ``hmc5843`` 1300)
    or any override accepted by ``--chip``.  Accelerometer and gyroscope are NaN."""
    x = _float_values(path)
    n = len(x)
    raw = np.full((n, 9), np.nan)
    raw[:, 6:9] = x
    meta = {"format": "razor-float", "source": str(path),
            "files": [{"file": str(path), "rows": [0, n], "samples": n}],
            "rate_hz": RAZOR_RATE_HZ, "rates_hz": {"mag": RAZOR_RATE_HZ},
            "clocks": "magnetometer only, 50 Hz stream (t = row / 50)",
            "axis_frame": RAZOR_FLOAT_FRAME}
    data = _session(Path(path).parent.name or Path(path).stem, raw, np.arange(n) / RAZOR_RATE_HZ,
                    meta=meta)
    data.chips = {"accel": None, "gyro": None, "mag": "HMC5883L"}
    if chip is None:
        chip = "hmc5883l"
    if isinstance(chip, str) and "=" not in chip:
        chip = f"mag={chip}"
    return _finish(data, chip, kind, None)


# ------------------------------------------------------------------ timestamped CSV pairs

_TS_COLUMNS = {"acc_x": 0, "acc_y": 1, "acc_z": 2, "gyr_x": 3, "gyr_y": 4, "gyr_z": 5,
               "mag_x": 6, "mag_y": 7, "mag_z": 8}
# A temperature column (MPU6050-style logs carry the chip's die temperature),
# its unit in its name: degrees C = value * factor + offset.
_TS_TEMP = {"temp_c": (1.0, 0.0), "temp_f": (5.0 / 9.0, -32.0 * 5.0 / 9.0), "temp_raw": None}
# raw TEMP_OUT -> degrees C of the chips that have one (datasheets; the ITG3200's is protocol's)
TEMP_RAW_C = {"MPU6050": (1.0 / 340.0, 36.53),
              "ITG3200": (1.0 / ITG3200_TEMP_LSB_PER_C,
                          ITG3200_TEMP_AT_OFFSET_C - ITG3200_TEMP_OFFSET / ITG3200_TEMP_LSB_PER_C)}
TEMP_RAW_C["ITG3205"] = TEMP_RAW_C["ITG3200"]


def _timestamped_header(path, line: str):
    cols_part, _, comment = line.partition("(")
    cols = [c.strip() for c in cols_part.strip().split(",")]
    temps = [c for c in cols if c in _TS_TEMP or c.startswith("temp")]
    if any(c not in _TS_TEMP for c in temps):
        raise _fail(path, 1, f"temperature column {temps[0]!r}: name its unit "
                    f"({', '.join(_TS_TEMP)})")
    if len(temps) > 1:
        raise _fail(path, 1, f"more than one temperature column ({', '.join(temps)})")
    temp_col = cols.index(temps[0]) - 1 if temps else None
    cols = [c for c in cols if c not in temps]
    if not cols or cols[0] != "t_s" or len(cols) < 4 or any(c not in _TS_COLUMNS for c in cols[1:]) \
            or len(set(cols)) != len(cols):
        raise _fail(path, 1, f"bad header {line.strip()[:80]!r}: expected t_s followed by "
                    f"mag_x,mag_y,mag_z and/or acc_x..gyr_z columns (and optionally one of "
                    f"{', '.join(_TS_TEMP)})")
    idx = [_TS_COLUMNS[c] for c in cols[1:]]
    sensors = sorted({s for s, sl in SENSOR_SLICES.items() for j in idx
                      if sl.start <= j < sl.stop}, key=list(SENSOR_SLICES).index)
    for s in sensors:
        sl = SENSOR_SLICES[s]
        if sorted(j for j in idx if sl.start <= j < sl.stop) != list(range(sl.start, sl.stop)):
            raise _fail(path, 1, f"bad header: {s} needs all three axes")
    # chip from the header comment, else from the file name
    chips = {}
    for s in sensors:
        for where in (comment, Path(path).name):
            found = [c for c in CHIP_SCALES[s] if c in normalise_chip(where)]
            if found:
                chips[s] = max(found, key=len)
                break
    temp = None
    if temp_col is not None:
        unit = temps[0]
        conv = _TS_TEMP[unit]
        if conv is None:                  # raw counts: the conversion of the chip that has it
            chip = next((chips[s] for s in ("gyro", "accel") if chips.get(s) in TEMP_RAW_C), None)
            if chip is None:
                raise _fail(path, 1, f"{unit}: no chip with a known temperature sensor named in "
                            f"the header or file name ({', '.join(TEMP_RAW_C)}); give temp_c")
            conv = TEMP_RAW_C[chip]
            unit = f"{unit} ({chip}: C = raw * {conv[0]:.6g} + {conv[1]:.6g})"
        temp = (temp_col, temps[0], conv, unit)
    return idx, sensors, chips, temp


def _parse_timestamped(path):
    lines = _read_text_lines(path)
    if not lines or not lines[0].strip():
        raise _fail(path, 1, "empty file: no header")
    idx, sensors, chips, temp = _timestamped_header(path, lines[0])
    ncol = 1 + len(idx) + (temp is not None)
    t, vals, temps = [], [], []
    for lineno, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        parts = line.split(",")
        if len(parts) != ncol:
            raise _fail(path, lineno, f"expected {ncol} columns, found {len(parts)}")
        t.append(_number(parts[0], path, lineno, "t_s"))
        parts = parts[1:]
        if temp is not None:
            col, name, (factor, offset), _ = temp
            temps.append(temperature_cell(parts.pop(col), path, lineno, name, factor, offset))
        vals.append([_count(p, path, lineno, f"column {j + 2}") for j, p in enumerate(parts)])
    if not t:
        raise _fail(path, len(lines), "no samples after the header")
    raw = np.full((len(t), 9), np.nan)
    raw[:, idx] = np.array(vals)
    celsius = np.array(temps, float) if temp is not None else None
    return np.array(t), raw, sensors, chips, celsius, (temp[3] if temp else None)


def _timestamped_files(dir_or_files) -> list[Path]:
    if isinstance(dir_or_files, (str, Path)):
        dir_or_files = [dir_or_files]
    files = []
    for p in map(Path, dir_or_files):
        if p.is_dir():
            found = sorted(p.glob("*_counts.csv")) or sorted(p.glob("*.csv"))
            if not found:
                raise UserError(f"{p}: directory holds no timestamped CSV (*_counts.csv)")
            files += found
        else:
            files.append(p)
    if not files:
        raise UserError("no timestamped CSV file given")
    return files


def read_timestamped(dir_or_files, chip=None, kind="auto") -> SessionData:
    """Timestamped CSV pairs (``hmc5883l_counts.csv`` + ``mpu6050_counts.csv``):
    header ``t_s,<axis columns>  (comment naming the chip)``, counts; one
    optional temperature column, its unit in its name (``temp_c``,
    ``temp_f``, or ``temp_raw``: the named chip's TEMP_OUT, ``TEMP_RAW_C``),
    becomes ``SessionData.temp`` in degrees C (NaN in the rows of files
    without one).

    Each sensor keeps its own time base: a row holds one sensor's sample (NaN
    for the others), ``t`` is the file's ``t_s``, rows sorted by time.  Rates
    are measured from the timestamps ((n - 1) / duration).
    """
    files = _timestamped_files(dir_or_files)
    ts, raws, chips, rates, owner, fileinfo = [], [], {}, {}, {}, []
    temps, temp_units = [], {}
    for f in files:
        t, raw, sensors, fchips, celsius, unit = _parse_timestamped(f)
        temps.append(np.full(len(t), np.nan) if celsius is None else celsius)
        if unit is not None:
            temp_units[str(f)] = unit
        for s in sensors:
            if s in owner:
                raise UserError(f"{f}: {s} already read from {owner[s]}; give one run "
                                f"(one file per sensor) per session")
            owner[s] = f
            r = rate_from_times(np.sort(t))
            if r is None:
                raise _fail(f, 2, "timestamps do not span any time: cannot measure the rate")
            rates[s] = round(r, 3)
        chips.update(fchips)
        ts.append(t)
        raws.append(raw)
        fileinfo.append({"file": str(f), "samples": len(t), "sensors": sensors,
                         "rate_hz": rates[sensors[0]]})
    t = np.concatenate(ts)
    raw = np.vstack(raws)
    temp = np.concatenate(temps)
    order = np.argsort(t, kind="stable")
    t, raw, temp = t[order], raw[order], temp[order]
    first = Path(files[0])
    meta = {"format": "timestamped-csv", "source": SOURCE_SEP.join(map(str, files)),
            "files": fileinfo,
            "rate_hz": max(rates.values()), "rates_hz": rates,
            "clocks": "separate: each sensor on its own time base, t from the files",
            "axis_frame": TIMESTAMPED_FRAME}
    if temp_units:
        meta["temp_from"] = temp_units
    data = _session(first.parent.name or first.stem, raw, t, meta=meta)
    if temp_units:
        data.temp = temp
    data.chips = {s: None for s in SENSOR_SLICES}
    for s in owner:
        name = chips.get(s, NOMINAL_CHIPS[s])
        data.chips[s] = name
        data.scales[s] = CHIP_SCALES[s].get(name, NOMINAL_SCALES[s])
        if s not in chips:
            add_note(data.meta,
                f"{owner[s]}: no chip named for {s}; assumed {name}")
    return _finish(data, chip, kind, None)


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


# ------------------------------------------------------------------ summary

def _fmt_scale(sensor, scale) -> str:
    return f"{scale:g} LSB/{UNITS[sensor] if sensor != 'gyro' else '(deg/s)'}"


def summary(data: SessionData) -> str:
    """One paragraph: samples per sensor, rates, kind and poses, chips/scales."""
    m = data.meta
    src = [f["file"] for f in m.get("files", [])] or ([m["source"]] if m.get("source") else [])
    counts = m.get("samples") or _sensor_counts(data.raw)
    rates = m.get("rates_hz", {})
    parts = []
    for s in SENSOR_SLICES:
        if counts.get(s):
            r = rates.get(s)
            parts.append(f"{s} {counts[s]}" + (f" at {r:.1f} Hz" if r else ""))
    poses = data.poses()
    if data.kind == "rotation":
        lab = f"{int((data.label == LABEL_ROT).sum())} rows labelled rot"
    elif poses:
        still = int((data.label >= 1).sum())
        lab = (f"{len(poses)} pose{'s' if len(poses) != 1 else ''} found "
               f"({', '.join(map(str, poses[:12]))}{', ...' if len(poses) > 12 else ''}; "
               f"{still} still rows)")
    else:
        lab = "no still pose found"
    chips = "; ".join(f"{s} {data.chips.get(s)} {_fmt_scale(s, data.scales[s])}"
                      for s in SENSOR_SLICES if counts.get(s))
    text = (f"Session '{data.name}': {len(data)} rows from {len(src)} "
            f"{m.get('format', '?')} file{'s' if len(src) != 1 else ''} "
            f"({', '.join(Path(s).name for s in src[:4])}{', ...' if len(src) > 4 else ''}); "
            f"samples {', '.join(parts)}; kind {data.kind} [{m.get('kind_decision', '')}]; "
            f"{lab}; chips {chips}; axes {m.get('axis_frame', 'as recorded')}.")
    clipped = m.get("clipped") or {}
    if clipped:
        text += " Clipped at full scale: " + ", ".join(
            f"{s} {k} samples" for s, k in clipped.items()) + "."
    if m.get("notes"):
        text += f" Notes: {m['notes']}."
    return text
