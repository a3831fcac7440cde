"""Float inputs with a declared scale: physical values (m/s^2, rad/s, uT, ...)
back to the integer counts a session holds; the lines of plain float logs
(FreeIMU-cal's text logs: three numbers a line, one sensor a file) and the
turns of turntable recordings at a known rate.  ``floatsession`` puts these
together into sessions (and reads the float logs).

Converting
----------
A value ``v`` in unit ``u`` becomes ``counts = v * f_u * lsb`` where ``f_u``
converts ``u`` to motecal's unit of that sensor (g, deg/s, gauss; m/s^2 ->
g divides by ``gravity``, 9.80665 unless given) and ``lsb`` is the LSB per
motecal unit: declared with ``--scale SENSOR=LSB`` or a chip (``--chip``),
else the file's own resolution (its smallest recurring step, so the counts
are the integers the logger saw).  Counts are rounded to integers (the store
keeps int16); :class:`Rounding` says how far the rounding moved them: at
most half a count, and about 0 when the file holds scaled integers.  A
declared scale that does not match the file's step is reported (the
rounding then adds up to half a count of quantisation, sd 0.29 count).

Every scale, rate and gravity, given or inferred, lies in its physical range
(``ranges``), or the import stops with one line.  A line whose reading no
chip gives (beyond ``ranges.READING_MAX``: a serial glitch such as
``1e20 0.1 9.8``) is left out of the session and of the inferred scale, and
named in the notes, up to ``ranges.ABSURD_MAX_FRACTION`` of the lines.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from itertools import chain
from pathlib import Path

import numpy as np

from ..errors import UserError
from . import ranges as R
from .cells import Rows, _fail, _number, text_chunks
from .options import option_parts
from .session import LABEL_ROT, SENSOR_SLICES, UNITS

G0 = 9.80665                 # standard gravity, m/s^2 per g
SENSORS = tuple(SENSOR_SLICES)
# unit -> (sensor, factor to motecal's unit); m/s^2 is handled with ``gravity``
UNIT_FACTORS = {
    "g": ("accel", 1.0), "mg": ("accel", 1e-3), "m/s^2": ("accel", None), "m/s2": ("accel", None),
    "deg/s": ("gyro", 1.0), "dps": ("gyro", 1.0), "rad/s": ("gyro", 180.0 / np.pi),
    "gauss": ("mag", 1.0), "mgauss": ("mag", 1e-3), "mg_mag": ("mag", 1e-3),
    "ut": ("mag", 1e-2), "nt": ("mag", 1e-5), "t": ("mag", 1e4),
}
SI_UNITS = {"accel": "m/s^2", "gyro": "rad/s", "mag": "uT"}
INTEGRAL_TOL = 0.05          # |value/step - integer| below this: the file holds integers
STEP_MISMATCH = 0.01         # declared scale vs the file's step: relative difference noted
ALIASES = {"accel": "accel", "acc": "accel", "a": "accel", "gyro": "gyro", "gyr": "gyro",
           "g": "gyro", "mag": "mag", "magn": "mag", "m": "mag", "magnetometer": "mag"}


def _sensor(name: str, what: str) -> str:
    s = ALIASES.get(str(name).strip().lower())
    if s is None:
        raise UserError(f"{what} {name!r}: sensor must be accel, gyro or mag")
    return s


def parse_units(units) -> dict:
    """``"si"``, ``"counts"`` or ``"gyro=deg/s,accel=m/s^2"`` (a list of such, or a
    dict) -> ``{sensor: unit}``; ``counts`` maps every sensor to ``"counts"``."""
    out = {}
    for part in option_parts(units):
        if part.lower() in ("si", "counts"):
            for s in SENSORS:
                out.setdefault(s, SI_UNITS[s] if part.lower() == "si" else "counts")
            continue
        if "=" not in part:
            raise UserError(f"--units {part}: expected si, counts or SENSOR=UNIT "
                            f"(units: {', '.join(sorted(UNIT_FACTORS))}, counts)")
        s, _, u = part.partition("=")
        s = _sensor(s, "--units")
        u = u.strip()
        if u.lower() != "counts" and u.lower() not in UNIT_FACTORS:
            raise UserError(f"--units {part}: unknown unit {u!r} "
                            f"(known: {', '.join(sorted(UNIT_FACTORS))}, counts)")
        if u.lower() != "counts" and UNIT_FACTORS[u.lower()][0] != s:
            raise UserError(f"--units {part}: {u} is not a unit of the {s}")
        out[s] = u if u.lower() == "counts" else u.lower().replace("m/s2", "m/s^2")
    return out


def parse_scales(scales) -> dict:
    """``["accel=2048", "gyro=14.375"]`` (LSB per g, deg/s, gauss) -> ``{sensor: float}``."""
    out = {}
    for part in option_parts(scales):
        s, eq, v = part.partition("=")
        if not eq:
            raise UserError(f"--scale {part}: expected SENSOR=LSB_PER_UNIT, e.g. accel=2048")
        s = _sensor(s, "--scale")
        try:
            val = float(v)
        except ValueError:
            val = float("nan")
        if not np.isfinite(val) or val <= 0:
            raise UserError(f"--scale {part}: the scale must be a positive number of LSB per "
                            f"{UNITS[s]}")
        out[s] = R.check_scale(s, val, f"--scale {part}")
    return out


def unit_factor(unit: str, gravity: float = G0) -> float:
    """Factor from ``unit`` to motecal's unit of its sensor (g, deg/s, gauss)."""
    sensor, f = UNIT_FACTORS[unit.lower()]
    return 1.0 / gravity if f is None else f


def file_step(values: np.ndarray) -> float | None:
    """The step between the values of a quantised signal (its resolution):
    the smallest difference between values that recurs, refined by least
    squares over the values on its grid; None when the values show no common
    step (more than 1 % of them off every multiple by ``INTEGRAL_TOL``).  A
    few values off the grid (a glitch) move neither the step nor the test."""
    x = np.asarray(values, float)
    v, count = np.unique(x[np.isfinite(x)], return_counts=True)
    if len(v) < 3:
        return None
    d = np.diff(v)
    span = float(v[-1] - v[0])
    d = d[d > span * 1e-9]
    if not len(d):
        return None
    # the smallest difference that recurs (within 5 %): a value off the grid
    # makes two odd differences, once each (a handful of values: the smallest)
    ds = np.sort(d)
    need = 1 if len(ds) < 10 else max(2, int(0.01 * len(ds)))
    near = np.searchsorted(ds, ds * (1 + INTEGRAL_TOL), side="right") - np.arange(len(ds))
    common = np.flatnonzero(near >= need)
    if not len(common):
        return None
    q0 = float(ds[common[0]])
    k = np.round(d / q0)
    small = (k >= 1) & (k <= 50)
    if not small.any():
        return None
    q = float(np.median(d[small] / k[small]))
    # refine: v ~ q * integer over the values on the grid, small values first
    # (their integers are sure), then wider
    limit, top = 50.0, float(np.abs(v).max())
    while True:
        sel = v[np.abs(v) <= limit * q]
        nk = np.round(sel / q)
        on = np.abs(sel / q - nk) < INTEGRAL_TOL
        if np.any(nk[on]):
            q = float(sel[on] @ nk[on] / (nk[on] @ nk[on]))
        if limit * q >= top:
            break
        limit *= 4
    resid = np.abs(v / q - np.round(v / q))
    if count[resid > INTEGRAL_TOL].sum() > 0.01 * count.sum():
        return None
    return q


@dataclass
class Rounding:
    """How a float column became counts."""
    sensor: str
    unit: str
    lsb_per_unit: float          # LSB per motecal unit used
    scale_from: str              # "declared" | "chip" | "file step"
    max_counts: float            # largest |rounding| (counts)
    rms_counts: float
    step_counts: float | None    # the file's step in counts (1 when lossless)

    def text(self) -> str:
        u = "counts" if self.unit == "counts" else self.unit
        per = UNITS[self.sensor] if "/" not in UNITS[self.sensor] else f"({UNITS[self.sensor]})"
        s = (f"{self.sensor}: {u} -> counts at {self.lsb_per_unit:.6g} LSB/{per} "
             f"({self.scale_from}); rounding to integers moved values by at most "
             f"{self.max_counts:.3g} count (rms {self.rms_counts:.2g})")
        if self.step_counts is not None and abs(self.step_counts - 1) > STEP_MISMATCH:
            s += (f"; the file's step is {self.step_counts:.4g} counts at this scale, so the "
                  f"declared scale does not match the file's resolution")
        return s


def to_counts(values: np.ndarray, sensor: str, unit: str, *, lsb: float | None = None,
              scale_from: str = "declared", gravity: float = G0,
              where: str = "", line_of=None) -> tuple[np.ndarray, Rounding]:
    """``values`` (n, 3) in ``unit`` -> integer counts (n, 3) and the rounding.

    ``lsb`` is LSB per motecal unit; None: the file's own step (lossless when
    the file holds scaled integers; a UserError when it shows no step)."""
    x = np.asarray(values, float)
    if unit == "counts":
        if lsb is None:
            raise UserError(f"{where}{sensor}: counts need a scale (--scale or --chip)")
        frac = np.abs(x - np.rint(x)) > 1e-6
        if frac.any():
            i = int(np.flatnonzero(frac.any(axis=1))[0])
            at = f"{line_of(i)}: " if line_of else f"{where}row {i + 1}: "
            raise UserError(f"{at}{sensor} value {float(x[i][frac[i]][0]):g} is not an integer "
                            f"count (mixed units? give --units {sensor}=UNIT)")
        x, f, lsb_in = x / lsb, 1.0, lsb          # counts -> unit, and back below
    else:
        f, lsb_in = unit_factor(unit, gravity), lsb
    step = file_step(x * f)
    lsb = lsb_in
    if lsb is None:
        if step is None:
            raise UserError(f"{where}{sensor} values ({unit}) show no common step: give the "
                            f"scale, --scale {sensor}=LSB_PER_{UNITS[sensor].upper()} or --chip")
        lsb, scale_from = 1.0 / step, "file step"
        R.check_scale(sensor, lsb, f"{where}{sensor}", f"(the scale the file's step of "
                      f"{step:.4g} {UNITS[sensor]} gives; declare it: --scale {sensor}=LSB or "
                      f"--chip)")
    else:
        R.check_scale(sensor, lsb, f"{where}{sensor} ({scale_from} scale)")
    c = x * f * lsb
    r = np.rint(c)
    ok = np.isfinite(c)
    if (np.abs(r[ok]) > 32768).any():
        big = float(np.abs(c[ok]).max())
        i = int(np.flatnonzero((np.abs(r) > 32768).any(axis=1))[0])
        at = f"{line_of(i)}: " if line_of else f"{where}row {i + 1}: "
        raise UserError(f"{at}{sensor}: {big:.0f} counts at {lsb:g} LSB/{UNITS[sensor]} is "
                        f"outside the 16-bit range of raw counts: is the scale or the unit right?")
    d = np.abs(r - c)[ok]
    rnd = Rounding(sensor, unit, float(lsb), scale_from,
                   float(d.max()) if d.size else 0.0,
                   float(np.sqrt(np.mean(d ** 2))) if d.size else 0.0,
                   None if step is None else float(step * lsb))
    r = np.where(r == 32768, 32767, r)
    return r, rnd


# ------------------------------------------------------------------ plain float logs

_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
FLOAT_LINE = re.compile(rf"^\s*{_NUM}(?:(?:\s*[,;\t ]\s*){_NUM})+\s*$")
FILE_SENSOR = (("acc", "accel"), ("gyr", "gyro"), ("mag", "mag"))


def looks_like_float_log(lines: list[str]) -> bool:
    """Every non-empty line of the head holds 3, 6 or 9 numbers and no header."""
    seen = 0
    for line in lines[:50]:
        s = line.strip()
        if not s:
            continue
        if not FLOAT_LINE.match(s):
            return False
        if len(re.split(r"[\s,;]+", s)) not in (3, 6, 9):
            return False
        seen += 1
    return seen > 0


def sensors_of_file(path, columns=None) -> list[str]:
    """The sensors of a float log's columns: ``columns`` (``"gyro"``,
    ``"accel,gyro"``) or from the file name (``...acc...``, ``...gyr...``,
    ``...mag...``, as FreeIMU-cal names them)."""
    if columns:
        items = columns if isinstance(columns, (list, tuple)) else str(columns).split(",")
        out = [_sensor(c, "--columns") for c in items if str(c).strip()]
        if len(set(out)) != len(out):
            raise UserError(f"--columns {columns}: a sensor named twice")
        return out
    name = Path(path).name.lower()
    found = [s for key, s in FILE_SENSOR if key in name]
    if len(found) != 1:
        raise UserError(f"{path}: say which sensor the columns hold (--columns accel, gyro or "
                        f"mag); the file name does not tell")
    return found


_SEPARATORS = re.compile(r"[\s,;]+")


def _tokens(s: str) -> list[str]:
    """A stripped line's numbers, split at white space, commas or semicolons
    (``str.split`` where there is no comma or semicolon: the same, faster)."""
    return s.split() if "," not in s and ";" not in s else _SEPARATORS.split(s)


def parse_float_log(path, ncol: int, fail=_fail) -> tuple[np.ndarray, np.ndarray]:
    """(n, ncol) floats and each row's line number, read in chunks (memory
    bounded by the chunk, not the file); a bad line -> ``fail(path, line,
    message)``.  A chunk is converted at once; only when that fails is it
    read again line by line, for the message naming the first bad line."""
    rows, where, last = Rows(ncol), Rows(1, np.int64), 0
    for first, lines in text_chunks(path):
        last = first + len(lines) - 1
        toks, nums = [], []
        for i, line in enumerate(lines):
            s = line.strip()
            if s:
                toks.append(_tokens(s))
                nums.append(first + i)
        if not toks:
            continue
        try:
            if any(len(tk) != ncol for tk in toks):
                raise ValueError
            x = np.fromiter(map(float, chain.from_iterable(toks)), float,
                            ncol * len(toks)).reshape(-1, ncol)
            if not np.isfinite(x).all():
                raise ValueError
        except ValueError:                 # line by line: the first bad line's message
            x = np.array([_float_row(path, tk, n, ncol, fail) for tk, n in zip(toks, nums)])
        rows.extend(x)
        where.extend(np.array(nums))
    if not len(rows):
        raise fail(path, last or 1, "no samples")
    return rows.array(), where.array()[:, 0]


def _float_row(path, toks, lineno, ncol, fail) -> list[float]:
    if len(toks) != ncol:
        raise fail(path, lineno, f"expected {ncol} numbers, found {len(toks)}")
    return [_number(tok, path, lineno, f"column {j}") for j, tok in enumerate(toks, start=1)]


# ------------------------------------------------------------------ turntable runs

def _rates(v) -> list:
    if v is None:
        return []
    items = v if isinstance(v, (list, tuple)) else [v]
    out = []
    for item in items:
        for tok in str(item).split(","):
            tok = tok.strip()
            if tok:
                try:
                    out.append(float(tok))
                except ValueError:
                    raise UserError(f"turntable rate {tok!r} is not a number") from None
    return out


def turntable_rates_dps(rate_dps=None, rpm=None) -> list:
    """The turntable's speeds in deg/s from ``--rate-dps`` and/or ``--rpm``
    (each a number, a comma list or a list: FreeIMU-cal's 33 1/3 and 45)."""
    rates = []
    for opt, given, factor in (("--rate-dps", rate_dps, 1.0), ("--rpm", rpm, 6.0)):
        for r in _rates(given):
            if not np.isfinite(r) or r <= 0:
                raise UserError("a turntable rate must be a positive number")
            rates.append(R.check(r * factor, R.TURN_DPS, f"{opt} {r:g}"))
    return sorted(set(rates))


def turntable_segments(gyro_dps: np.ndarray, segments: np.ndarray, rates_dps,
                       tol: float = 0.1) -> tuple[list, list]:
    """Split steady segments (labels 1..K from the stillness detector, which
    judges spreads, so a steady turn counts) into turns at one of
    ``rates_dps`` (|mean rate| within ``tol`` of it, bias included) and rests
    (|mean| below ``tol`` of the slowest).  Returns ``(turns, rests)``:
    turns as ``(rows, rate)``, rests as row index arrays."""
    rates = np.atleast_1d(np.asarray(rates_dps, float))
    turns, rests = [], []
    for k in range(1, int(segments.max(initial=0)) + 1):
        idx = np.flatnonzero(segments == k)
        if not len(idx):
            continue
        m = float(np.linalg.norm(np.nanmean(gyro_dps[idx], axis=0)))
        near = np.abs(m - rates) <= tol * rates
        if near.any():
            turns.append((idx, float(rates[np.argmin(np.abs(m - rates))])))
        elif m <= tol * rates.min():
            rests.append(idx)
    return turns, rests


def label_turntable(label: np.ndarray, turns: list, rests: list) -> dict:
    """Turn rows become ``rot``; rests become poses 1..; returns the
    ``meta["turntable"]["segments"]`` row ranges."""
    label[:] = 0
    for idx, _ in turns:
        label[idx] = LABEL_ROT
    for k, idx in enumerate(rests, start=1):
        label[idx] = k
    return [[int(i[0]), int(i[-1]) + 1] for i, _ in turns]
