"""Timestamped CSV runs: one file per sensor, each on its own time base
(``hmc5883l_counts.csv`` + ``mpu6050_counts.csv``; ``motecal.sessions.importer``).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import UserError
from ..line.protocol import ITG3200_TEMP_AT_OFFSET_C, ITG3200_TEMP_LSB_PER_C, ITG3200_TEMP_OFFSET
from .cells import T_MAX, Rows, _count, _fail, _number, numbered_lines, temperature_cell
from .chips import CHIP_SCALES, normalise_chip
from .imported import SOURCE_SEP, _session, add_note
from .labelling import _finish
from .ranges import check_rate
from .session import NOMINAL_CHIPS, NOMINAL_SCALES, SENSOR_SLICES, SessionData, rate_from_times

TIMESTAMPED_FRAME = "as recorded: chip axes of each sensor as written in the file"


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
    lines = numbered_lines(path)
    first = next(lines, None)
    if first is None or not first[1].strip():
        raise _fail(path, 1, "empty file: no header")
    idx, sensors, chips, temp = _timestamped_header(path, first[1])
    ncol = 1 + len(idx) + (temp is not None)
    rows, last = Rows(ncol), 1                       # t, the counts (, degrees C)
    for lineno, line in lines:
        last = lineno
        if not line.strip():
            continue
        parts = line.split(",")
        if len(parts) != ncol:
            raise _fail(path, lineno, f"expected {ncol} columns, found {len(parts)}")
        t = _number(parts[0], path, lineno, "t_s")
        if abs(t) > T_MAX:
            raise _fail(path, lineno, f"t_s must be within +-{T_MAX:g} s, not {parts[0].strip()!r}")
        parts = parts[1:]
        cells = []
        if temp is not None:
            col, name, (factor, offset), _ = temp
            cells = [temperature_cell(parts.pop(col), path, lineno, name, factor, offset)]
        rows.add([t] + [_count(p, path, lineno, f"column {j + 2}") for j, p in enumerate(parts)]
                 + cells)
    x = rows.array()
    if not len(x):
        raise _fail(path, last, "no samples after the header")
    raw = np.full((len(x), 9), np.nan)
    raw[:, idx] = x[:, 1:1 + len(idx)]
    celsius = x[:, -1].copy() if temp is not None else None
    return x[:, 0].copy(), raw, sensors, chips, celsius, (temp[3] if temp else None)


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
            rates[s] = round(check_rate(r, f"{f}: the rate its times give",
                                        "(is t_s in seconds?)"), 3)
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
