"""The physical ranges of what ``motecal import`` is told (options) or infers
from a file (a scale from the file's step, a rate from its times): one table
per quantity, each with why.  A value outside its range is not a property
of a board on Earth but a mistake (a unit, a typo, a glitch) and stops the
import with one line (UserError, exit 2) before anything is stored.
``motecal import --help`` and docs/import.md print these tables.

The chips the importer knows (``chips.CHIP_SCALES``) sit well inside every
range; the margins admit the other chips a float log or ``--chip NAME:LSB``
may come from.
"""
from __future__ import annotations

import math
import textwrap
from dataclasses import dataclass

import numpy as np

from ..errors import UserError


@dataclass(frozen=True)
class Range:
    lo: float
    hi: float
    unit: str
    why: str

    def holds(self, v: float) -> bool:
        return isinstance(v, (int, float)) and math.isfinite(v) and self.lo <= v <= self.hi

    def text(self) -> str:
        return f"{self.lo:g}..{self.hi:g} {self.unit}"


# LSB per g, deg/s, gauss: a scale given (--scale, --chip NAME:LSB) or inferred
SCALE = {
    "accel": Range(1.0, 32767.0, "LSB/g",
                   "1 g must fit the 16-bit counts a session keeps (at most 32767 LSB/g; "
                   "MPU6050 at +-2 g: 16384); the coarsest accelerometers (H3LIS331, ADXL375 "
                   "at +-200..400 g) give 5..20 LSB/g"),
    "gyro": Range(0.5, 4096.0, "LSB/(deg/s)",
                  "the widest gyroscope ranges (+-4000 deg/s, 16 bits: 8.2; +-2000 deg/s "
                  "in 12 bits: 1) to the finest (ICM-42688 at +-15.6 deg/s: 2097; "
                  "ITG3200 14.375, MPU6050 131)"),
    "mag": Range(50.0, 50000.0, "LSB/gauss",
                 "the Earth's field (0.25..0.65 gauss) must be at least a dozen counts "
                 "(HMC5883L's widest gain: 230) and fit 16 bits (QMC5883L's finest: 12000)"),
}
RATE_HZ = Range(0.01, 100000.0, "Hz",
                "output data rates of the chips: ADXL345 0.1..3200 Hz, HMC5883L 0.75..75 Hz, "
                "ITG3200 and MPU6050 up to 8 kHz, the fastest MEMS gyroscopes 32 kHz")
GRAVITY = Range(9.5, 10.0, "m/s^2",
                "gravity on the Earth's surface is 9.76..9.84 m/s^2 (latitude, height); "
                "loggers use 9.80665, 9.81, 9.8 or 10")
ANGLE_DEG = Range(10.0, 3600.0, "degrees",
                  "the size of a turn by hand or on a rig, a part of a turn up to ten turns "
                  "(sign free: imucal writes -360 for clockwise); a turn given in radians "
                  "(2 pi = 6.28) is below it")
TURN_DPS = Range(1.0, 4000.0, "deg/s",
                 "a turntable's speed (--rate-dps; --rpm x 6): faster than the Earth's turn "
                 "and the gyroscope's bias, within the widest gyroscope range (+-4000 deg/s)")
# |reading| per axis, in g, deg/s and gauss: beyond it no chip reads it
READING_MAX = {
    "accel": Range(0.0, 1000.0, "g", "the widest accelerometers read +-400 g (H3LIS331)"),
    "gyro": Range(0.0, 10000.0, "deg/s", "the widest gyroscopes read +-4000 deg/s"),
    "mag": Range(0.0, 1000.0, "gauss", "the widest magnetometers read +-500 gauss (MLX90393)"),
}
ABSURD_MAX_FRACTION = 0.01      # lines beyond READING_MAX: left out up to 1 % of a file's rows
ZERO_RUN = 25                   # accel or mag samples of exactly (0, 0, 0) in a row: not a reading
SENSOR_WORDS = {"accel": "accelerometer", "gyro": "gyroscope", "mag": "magnetometer"}


def _fmt(v) -> str:
    try:
        return f"{float(v):g}"
    except (TypeError, ValueError):
        return repr(v)


def check(value, rng: Range, what: str, hint: str = "") -> float:
    """``value`` as a float when it lies in ``rng``; else one line naming
    ``what`` (the option, or the file and how the value was found)."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise UserError(f"{what}: not a number: {value!r}") from None
    if not rng.holds(v):
        raise UserError(f"{what}: {_fmt(v)} {rng.unit} is outside {rng.text()}"
                        f"{' ' + hint if hint else ''} (motecal import --help: ranges)")
    return v


def check_scale(sensor: str, value, what: str, hint: str = "") -> float:
    return check(value, SCALE[sensor], what, hint)


def check_rate(value, what: str = "--rate-hz", hint: str = "") -> float:
    return check(value, RATE_HZ, what, hint)


def check_gravity(value, what: str = "--gravity") -> float:
    return check(value, GRAVITY, what, "(m/s^2 per g on Earth; for values in g give "
                                       "--units accel=g)")


def check_angle(value, what: str = "--angle-deg") -> float:
    """A turn's size: its magnitude in ``ANGLE_DEG`` (the sign is free)."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise UserError(f"{what}: not a number: {value!r}") from None
    if not ANGLE_DEG.holds(abs(v)):
        raise UserError(f"{what}: {_fmt(v)} degrees is outside +-{ANGLE_DEG.text()} "
                        "(motecal import --help: ranges)")
    return v


def check_zero_runs(x: np.ndarray, sensor: str, where) -> None:
    """Accelerometer or magnetometer samples of exactly (0, 0, 0) for
    ``ranges.ZERO_RUN`` rows in a row are no reading (gravity and the
    Earth's field never read zero): zero bytes or a logger's placeholder,
    one line naming where the run starts (``where(row)``)."""
    if sensor == "gyro" or len(x) < ZERO_RUN:
        return
    zero = (x == 0).all(axis=1).astype(np.int8)
    # a run of ZERO_RUN zero rows: the windowed sum reaches ZERO_RUN
    c = np.concatenate(([0], np.cumsum(zero, dtype=np.int64)))
    full = np.flatnonzero(c[ZERO_RUN:] - c[:-ZERO_RUN] == ZERO_RUN)
    if len(full):
        raise UserError(f"{where(int(full[0]))}: {ZERO_RUN} {sensor} samples of exactly 0, 0, 0 "
                        f"in a row: no {SENSOR_WORDS[sensor]} reads zero on Earth (zero bytes, "
                        f"or a logger's placeholder?)")


def tables() -> list[tuple[str, str, str]]:
    """(quantity, range, why) rows: ``--help``'s and docs/import.md's table."""
    rows = [(f"--scale / --chip NAME:LSB, {s}", r.text(), r.why) for s, r in SCALE.items()]
    rows += [("--rate-hz, and rates from a file's times", RATE_HZ.text(), RATE_HZ.why),
             ("--gravity", GRAVITY.text(), GRAVITY.why),
             ("--angle-deg (magnitude)", ANGLE_DEG.text(), ANGLE_DEG.why),
             ("--rate-dps (--rpm x 6)", TURN_DPS.text(), TURN_DPS.why)]
    rows += [(f"a float log's {s} reading", f"within +-{r.hi:g} {r.unit} per axis",
              r.why + f"; up to {ABSURD_MAX_FRACTION:.0%} of the lines beyond it are left "
              "out and named in the notes, more stop the import")
             for s, r in READING_MAX.items()]
    return rows


def help_text() -> str:
    """The ranges as ``--help`` prints them."""
    out = ["ranges (a value outside stops the import with one line):"]
    for what, rng, why in tables():
        out.append(f"  {what}: {rng}")
        out += textwrap.wrap(why, 78, initial_indent="      ", subsequent_indent="      ")
    out += textwrap.wrap(f"{ZERO_RUN} or more accelerometer or magnetometer samples of exactly "
                         "(0, 0, 0) in a row: not a recording (gravity and the Earth's field "
                         "never read zero)", 78, initial_indent="  ", subsequent_indent="      ")
    return "\n".join(out)
