"""Floats of a session: the physical values of a float file (a FreeIMU-cal
float log, imucal's session CSV) turned into a session's counts
(``floatlog.to_counts``), with every scale, rate and gravity in its physical
range (``ranges``), readings no chip gives left out and named, and runs of
exact zeros refused; and the reader of plain float logs (``read_float_log``).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import UserError
from . import ranges as R
from .chips import parse_chip_overrides
from .floatlog import (G0, SI_UNITS, STEP_MISMATCH, file_step, label_turntable, parse_float_log,
                       parse_scales, parse_units, sensors_of_file, to_counts, turntable_rates_dps,
                       turntable_segments, unit_factor)
from .imported import SOURCE_SEP, _session, add_note
from .labelling import _finish
from .session import SENSOR_SLICES
from .still import StillThresholds, segment_recording

FLOAT_FRAME = "as recorded: the logger's sensor axes"
STEADY = StillThresholds(gyro_rule="rate")


def need_rate(rate_hz, fmt):
    """``--rate-hz`` of a file without times, within ``ranges.RATE_HZ``."""
    if rate_hz is None:
        raise UserError(f"{fmt}: the file has no times: give the sample rate with --rate-hz "
                        f"(imucal's examples: 204.8 Hz annotated, 102.4 Hz session)")
    try:
        rate_hz = float(rate_hz)
    except (TypeError, ValueError):
        rate_hz = float("nan")
    if not np.isfinite(rate_hz) or rate_hz <= 0:
        raise UserError("--rate-hz must be a positive number")
    return R.check_rate(rate_hz)


def check_options(opts: dict) -> None:
    """The float options of an import (``--rate-hz``, ``--gravity``,
    ``--angle-deg``, ``--scale``, ``--rate-dps``/``--rpm``, ``--units``), each
    in its range (``ranges``), before any file is read: one line otherwise,
    also for an option the format does not use."""
    if opts.get("rate_hz") is not None:
        need_rate(opts["rate_hz"], "")
    if opts.get("gravity") is not None:
        R.check_gravity(opts["gravity"])
    if opts.get("angle_deg") is not None:
        R.check_angle(opts["angle_deg"])
    parse_scales(opts.get("scale"))
    parse_units(opts.get("units"))
    turntable_rates_dps(opts.get("rate_dps"), opts.get("rpm"))


def _beyond(vals: dict, units: dict, gravity: float) -> dict:
    """Per sensor of float readings: its rows with a reading beyond
    ``ranges.READING_MAX`` (a glitch no chip gives, e.g. ``1e20 0.1 9.8``)."""
    out = {}
    for s, x in vals.items():
        unit = units.get(s, SI_UNITS[s])
        if unit != "counts":                 # counts are checked as counts (int16)
            with np.errstate(over="ignore", invalid="ignore"):
                out[s] = ~(np.abs(x * unit_factor(unit, gravity))
                           <= R.READING_MAX[s].hi).all(axis=1)
    return out


def _any_row(beyond: dict, n: int) -> np.ndarray:
    bad = np.zeros(n, bool)
    for rows in beyond.values():
        bad |= rows
    return bad


def _leave_out(beyond: dict, vals: dict, units: dict, line_of, meta) -> np.ndarray:
    """Rows to keep: the lines beyond (``_beyond``) are left out and named in
    a note, unless they are more than ``ranges.ABSURD_MAX_FRACTION`` of the
    rows: then one line (a wrong unit, or not this sensor's log)."""
    n = len(next(iter(vals.values())))
    bad = _any_row(beyond, n)
    k = int(bad.sum())
    if not k:
        return ~bad
    i = int(np.flatnonzero(bad)[0])
    s = next(s for s, rows in beyond.items() if rows[i])
    unit = units.get(s, SI_UNITS[s])
    what = (f"{s} reading {', '.join(f'{v:g}' for v in vals[s][i])} {unit} is beyond any "
            f"{R.SENSOR_WORDS[s]}'s (|value| <= {R.READING_MAX[s].hi:g} {R.READING_MAX[s].unit})")
    if k > R.ABSURD_MAX_FRACTION * n:
        raise UserError(f"{line_of(i)}: {what}, and so are {k} of the {n} lines (more than "
                        f"{R.ABSURD_MAX_FRACTION:.0%}): is the unit right (--units)?")
    lines = [line_of(j) for j in np.flatnonzero(bad)[:5]]
    add_note(meta, f"{k} line{'s' if k != 1 else ''} with a reading no chip gives left out "
             f"(not used for the scale either): {', '.join(lines)}{', ...' if k > 5 else ''} "
             f"(the first: {what})")
    return ~bad


def convert(path, vals: dict, units: dict, scales: dict, chip_scales: dict, gravity, meta,
            line_of=None):
    """{sensor: (n, 3) floats} -> (raw (m, 9) counts, LSB per unit, kept rows:
    a mask of the n rows, lines no chip gives left out); roundings noted in meta."""
    gravity = R.check_gravity(gravity)
    n = len(next(iter(vals.values())))
    line_of = line_of or (lambda i: f"{path}: row {i + 1}")
    keep = _leave_out(_beyond(vals, units, gravity), vals, units, line_of, meta)
    kept = np.flatnonzero(keep)
    if not len(kept):
        raise UserError(f"{path}: no samples")
    m = len(kept)
    raw = np.full((m, 9), np.nan)
    rounding = {}
    lsbs = {}
    for s, x in vals.items():
        x = x[keep] if m < n else x
        unit = units.get(s, SI_UNITS[s])
        lsb, frm = scales.get(s), "declared"
        if lsb is None and s in chip_scales:
            lsb, frm = chip_scales[s], "chip"
        counts, rnd = to_counts(x, s, unit, lsb=lsb, scale_from=frm, gravity=gravity,
                                where=f"{path}: ", line_of=lambda i: line_of(int(kept[i])))
        raw[:, SENSOR_SLICES[s]] = counts
        rounding[s] = rnd.text()
        lsbs[s] = rnd.lsb_per_unit
        meta.setdefault("scale_from", {})[s] = rnd.scale_from
        if unit != "counts" and np.all(x == np.rint(x)):
            add_note(meta, f"every {s} value is a whole number of {unit}: raw counts? "
                           f"(then give --units {s}=counts and its --scale)")
        if rnd.step_counts is not None and abs(rnd.step_counts - 1) > STEP_MISMATCH:
            add_note(meta, rnd.text())
    meta["units_in"] = {s: units.get(s, SI_UNITS[s]) for s in vals}
    meta["rounding"] = rounding
    meta["gravity_mss"] = gravity
    return raw, lsbs, keep


def chip_scales(chip) -> dict:
    return {s: sc for s, (_, sc) in parse_chip_overrides(chip).items()}


def apply_scales(data, lsbs: dict, chip):
    names = {s: n for s, (n, _) in parse_chip_overrides(chip).items()}
    source = data.meta.get("scale_from", {})
    for s in SENSOR_SLICES:
        if s in lsbs:
            data.scales[s] = float(lsbs[s])
            data.chips[s] = names.get(s, "the file's step" if source.get(s) == "file step"
                                      else "declared scale")
        else:
            data.chips[s] = None


# ------------------------------------------------------------------ float logs (FreeIMU-cal)

def _same_steps(paths, blocks, sensors):
    """Files of one session must share each sensor's step (resolution): a
    file in other units (deg/s beside rad/s) or at another range is refused."""
    if len(blocks) < 2:
        return
    for i, s in enumerate(sensors):
        steps = [(p, file_step(x[:, 3 * i:3 * i + 3])) for p, x in zip(paths, blocks)]
        known = [(p, q) for p, q in steps if q]
        for p, q in known[1:]:
            p0, q0 = known[0]
            if abs(q / q0 - 1) > STEP_MISMATCH:
                raise UserError(f"{p}: line 1: {s} values step by {q:.6g}, but {p0} steps by "
                                f"{q0:.6g} ({q / q0:.4g}x): mixed units or ranges in one session")


def read_float_log(paths, *, columns=None, rate_hz=None, chip=None, scale=None, units=None,
                   gravity=G0, rate_dps=None, rpm=None, kind="auto"):
    """Headerless float logs, one sensor per file unless ``columns`` name
    several (FreeIMU-cal: ``...acc.txt`` m/s^2, ``...gyr.txt`` rad/s,
    ``...mag.txt`` uT; ``units`` overrides).  Several files of one sensor
    are one session, one recording each.  ``rate_hz`` (default 100, noted)
    sets t = row / rate (a left-out line keeps its row: later rows keep
    their times).  With a turntable rate, steady turns at that rate are
    ``rot`` (``meta["turntable"]``) and rests are poses."""
    if isinstance(paths, (str, Path)):
        paths = [paths]
    paths = [Path(p) for p in paths]
    notes = []
    if rate_hz is None:
        rate = 100.0
        notes.append("no sample rate given (--rate-hz): t = row / 100 assumed")
    else:
        rate = need_rate(rate_hz, "float-log")
    gravity = R.check_gravity(gravity)
    turn_dps = turntable_rates_dps(rate_dps, rpm)
    units = parse_units(units)
    scales = parse_scales(scale)
    blocks, lines, sizes, sensors_all = [], [], [], None
    for p in paths:
        sensors = sensors_of_file(p, columns)
        if sensors_all is not None and sensors != sensors_all:
            raise UserError(f"{p}: holds {', '.join(sensors)}, but {paths[0]} holds "
                            f"{', '.join(sensors_all)}: one sensor set per session")
        sensors_all = sensors
        x, where = parse_float_log(p, 3 * len(sensors))
        blocks.append(x)
        lines.append(where)
        sizes.append(len(x))
    starts = np.cumsum([0] + sizes)
    line_no = np.concatenate(lines)

    def line_of(i):
        f = int(np.searchsorted(starts, i, side="right")) - 1
        return f"{paths[f]}: line {int(line_no[i])}"

    x = blocks[0] if len(blocks) == 1 else np.vstack(blocks)
    del blocks
    meta = {"format": "float-log", "source": SOURCE_SEP.join(map(str, paths)),
            "rate_hz": rate, "rates_hz": {s: rate for s in sensors_all},
            "clocks": f"shared: t = row / {rate:g} Hz", "axis_frame": FLOAT_FRAME}
    for note in notes:
        add_note(meta, note)
    vals = {s: x[:, 3 * i:3 * i + 3] for i, s in enumerate(sensors_all)}
    beyond = _beyond(vals, units, gravity)
    bad = _any_row(beyond, len(x))
    # files in other units first (a deg/s file beside rad/s reads beyond any gyroscope)
    _same_steps(paths, [x[a:b][~bad[a:b]] for a, b in zip(starts[:-1], starts[1:])],
                sensors_all)
    keep = _leave_out(beyond, vals, units, line_of, meta)
    kept = np.flatnonzero(keep)
    for s in sensors_all:
        R.check_zero_runs(vals[s][keep], s, lambda j: line_of(int(kept[j])))
    if len(kept) < len(x):
        vals = {s: v[keep] for s, v in vals.items()}
    raw, lsbs, _ = convert(paths[0], vals, units, scales, chip_scales(chip), gravity, meta,
                           line_of=lambda j: line_of(int(kept[j])))
    n = len(raw)
    counts = np.diff(np.searchsorted(kept, starts))
    pos = np.concatenate(([0], np.cumsum(counts)))
    meta["files"] = [{"file": str(p), "rows": [int(a), int(b)], "samples": int(b - a)}
                     for p, a, b in zip(paths, pos[:-1], pos[1:])]
    data = _session(paths[0].stem if len(paths) == 1 else paths[0].parent.name or paths[0].stem,
                    raw, kept / rate, seq=kept, meta=meta)
    apply_scales(data, lsbs, chip)
    parts = [(int(a), int(b)) for a, b in zip(pos[:-1], pos[1:]) if b > a]
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
    turns, rests = turntable_segments(data.physical("gyro"), seg, turn_dps)
    if not turns:
        raise UserError(f"{paths[0]}: no steady turn at {', '.join(f'{r:g}' for r in turn_dps)} "
                        f"deg/s found (is the rate "
                        f"or the gyroscope's unit right? units in: {meta['units_in']['gyro']})")
    segs = label_turntable(data.label, turns, rests)
    data.meta["turntable"] = {"rates_dps": turn_dps, "segments": segs,
                              "segment_rates_dps": [r for _, r in turns]}
    data.meta["rotations"] = [{"name": f"turn{i}", "axis": None, "rows": seg, "rate_dps": r}
                              for i, (seg, (_, r)) in enumerate(zip(segs, turns), start=1)]
    return _finish(data, None, kind, None, has_labels=True)
