"""From a calibration in physical units to the fixed-point set the mote applies.

A calibration gives, per sensor, ``calibrated = A @ raw_counts + c`` in g,
deg/s or gauss.  The mote works in the sensor's nominal counts (K = 256 LSB/g,
14.375 LSB/(deg/s), 1090 LSB/gauss, ``session.NOMINAL_SCALES``), so the
counts-domain correction is ``M = K * A`` (about the identity) and
``off = K * c`` (counts).  ``M`` and ``off`` are quantised with ``shift``
fractional bits (the largest of 8..14 that fits int16 / int32) into the
``ninedof_cal_sensor`` of ``tinyos/NineDofMsg.h``, and the mote computes

    out = sat((a_q @ raw + c_q + 2**(shift-1)) >> shift)

(``tinyos/ninedof_cal.c``).  ``reference_correct`` is the same arithmetic in
float64 (no rounding) that the C code is tested against; ``rounding_report``
says how far the quantised set can be from the physical calibration.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from ..errors import QualityError
from ..line import protocol as P
from ..sessions.session import HMC5883L_OVERFLOW, NOMINAL_SCALES, SENSOR_SLICES, UNITS

SHIFT_MIN, SHIFT_MAX = 8, 14
INT16_MAX, INT32_MAX = 32767, 2**31 - 1
MAG_LIMIT = 4095                    # corrected magnetometer saturates at +-4095

# Largest raw magnitude each chip can output, for the worst-case error:
# ADXL345 full resolution +-16 g is 13 bits; ITG3200 uses all 16 bits;
# HMC5883L data registers span -2048..2047 (-4096 = overflow).
INPUT_RANGE = {"accel": 4096, "gyro": 32768, "mag": 2048}


class NotRepresentable(QualityError):
    """A calibration that no Q8..Q14 fixed-point set can hold."""


@dataclass(frozen=True)
class FixedSensor:
    """One sensor's correction as the mote stores it."""
    a: np.ndarray       # (3, 3) int, Q(shift), row-major on the wire
    c: np.ndarray       # (3,) int, counts in Q(shift)
    shift: int

    def __post_init__(self):
        a = np.array(self.a, dtype=np.int64).reshape(3, 3)
        c = np.array(self.c, dtype=np.int64).reshape(3)
        a.flags.writeable = c.flags.writeable = False
        object.__setattr__(self, "a", a)
        object.__setattr__(self, "c", c)
        object.__setattr__(self, "shift", int(self.shift))

    @property
    def matrix(self) -> np.ndarray:
        """Counts-domain matrix the mote applies (float64, exact)."""
        return np.asarray(self.a, np.float64) / 2.0**self.shift

    @property
    def offset(self) -> np.ndarray:
        """Counts-domain offset the mote applies (float64, exact)."""
        return np.asarray(self.c, np.float64) / 2.0**self.shift

    def __eq__(self, other):
        return (isinstance(other, FixedSensor) and self.shift == other.shift
                and np.array_equal(self.a, other.a) and np.array_equal(self.c, other.c))


IDENTITY = FixedSensor(np.eye(3, dtype=np.int64) << SHIFT_MAX, np.zeros(3, np.int64),
                       SHIFT_MAX)


@dataclass(frozen=True)
class Calset:
    """A decoded ``ninedof_calset``: only the corrected sensors are in ``sensors``."""
    mote: int
    version: int
    sensors: dict          # name -> FixedSensor
    stored: dict           # name -> FixedSensor for all three (what the bytes hold)

    @property
    def mask(self) -> int:
        return sum(1 << P.SENSORS.index(n) for n in self.sensors)


# --------------------------------------------------------------------------
# Physical -> counts -> fixed point
# --------------------------------------------------------------------------
def counts_domain(sensor: str, A, c) -> tuple[np.ndarray, np.ndarray]:
    """``M = K A`` and ``off = K c`` for a physical-unit calibration."""
    k = NOMINAL_SCALES[sensor]
    A = np.asarray(A, np.float64).reshape(3, 3)
    c = np.asarray(c, np.float64).reshape(3)
    return k * A, k * c


def _fits(a: np.ndarray, c: np.ndarray) -> bool:
    if np.any(np.abs(a) > INT16_MAX) or np.any(np.abs(c) > INT32_MAX):
        return False
    # the accumulator a @ raw + c cannot overflow int32 for any int16 input
    return bool(np.all(np.abs(a).sum(axis=1) * 32768 + np.abs(c) < 2**31))


def quantise(M, off) -> FixedSensor:
    """Counts-domain ``M`` (3x3) and ``off`` (3,) to the largest shift that fits."""
    M = np.asarray(M, np.float64).reshape(3, 3)
    off = np.asarray(off, np.float64).reshape(3)
    if not (np.all(np.isfinite(M)) and np.all(np.isfinite(off))):
        raise NotRepresentable("calibration contains NaN or infinite values")
    for shift in range(SHIFT_MAX, SHIFT_MIN - 1, -1):
        a = np.rint(M * 2.0**shift)
        c = np.rint(off * 2.0**shift)
        if _fits(a, c):
            return FixedSensor(a.astype(np.int64), c.astype(np.int64), shift)
    raise NotRepresentable(
        f"calibration does not fit the mote's fixed point even with {SHIFT_MIN} "
        f"fractional bits (matrix entries up to {np.abs(M).max():.3g}, "
        f"offsets up to {np.abs(off).max():.3g} counts)")


def fixed_from_physical(sensor: str, A, c) -> FixedSensor:
    return quantise(*counts_domain(sensor, A, c))


# --------------------------------------------------------------------------
# Wire format
# --------------------------------------------------------------------------
def _sensor_bytes(fs: FixedSensor) -> bytes:
    return P.CAL_SENSOR.pack(a=[int(v) for v in np.asarray(fs.a).reshape(9)],
                             c=[int(v) for v in np.asarray(fs.c).reshape(3)],
                             shift=int(fs.shift), reserved=0)


def pack_calset(mote: int, version: int, sensors: Mapping[str, FixedSensor]) -> bytes:
    """``ninedof_calset`` bytes: the given sensors corrected, the others raw
    (stored as the Q14 identity with their bit clear)."""
    unknown = set(sensors) - set(P.SENSORS)
    if unknown:
        raise ValueError(f"unknown sensors {sorted(unknown)}; expected {P.SENSORS}")
    if not 1 <= version <= 0xFFFF:
        raise ValueError("version must be 1..65535")
    mask = sum(1 << i for i, n in enumerate(P.SENSORS) if n in sensors)
    out = P.CALSET_HEADER.pack(mote=mote & 0xFFFF, version=version, sensors=mask,
                               reserved=0)
    for name in P.SENSORS:
        out += _sensor_bytes(sensors.get(name, IDENTITY))
    assert len(out) == P.CALSET_SIZE
    return out


def unpack_calset(data: bytes) -> Calset:
    data = bytes(data)
    if len(data) != P.CALSET_SIZE:
        raise ValueError(f"calibration set is {len(data)} bytes, expected {P.CALSET_SIZE}")
    hdr = P.CALSET_HEADER.unpack(data[:P.CALSET_HEADER.size])
    stored = {}
    for i, name in enumerate(P.SENSORS):
        lo = P.CALSET_HEADER.size + i * P.CAL_SENSOR.size
        s = P.CAL_SENSOR.unpack(data[lo:lo + P.CAL_SENSOR.size])
        stored[name] = FixedSensor(np.array(s["a"], np.int64).reshape(3, 3),
                                   np.array(s["c"], np.int64), s["shift"])
    enabled = {n: stored[n] for i, n in enumerate(P.SENSORS) if hdr["sensors"] >> i & 1}
    return Calset(hdr["mote"], hdr["version"], enabled, stored)


# --------------------------------------------------------------------------
# Reference correction (float64)
# --------------------------------------------------------------------------
def reference_correct(calset, raw) -> np.ndarray:
    """What the mote computes, in float64 and before its final rounding.

    ``calset`` is bytes or a ``Calset``; ``raw`` (n, 9) counts.  Corrected
    sensors: ``matrix @ raw + offset`` clipped to int16 (magnetometer to
    +-4095; a magnetometer sample with any axis at -4096 stays -4096 on all
    three).  The mote's int16 output is this value rounded half up.
    """
    cs = unpack_calset(calset) if isinstance(calset, (bytes, bytearray)) else calset
    raw = np.asarray(raw, np.float64).reshape(-1, 9)
    out = raw.copy()
    for name, fs in cs.sensors.items():
        sl = SENSOR_SLICES[name]
        y = raw[:, sl] @ fs.matrix.T + fs.offset
        if name == "mag":
            y = np.clip(y, -MAG_LIMIT, MAG_LIMIT)
            over = np.any(raw[:, sl] == HMC5883L_OVERFLOW, axis=1)
            y[over] = HMC5883L_OVERFLOW
        else:
            y = np.clip(y, -32768, INT16_MAX)
        out[:, sl] = y
    return out


def physical_correct(sensor: str, A, c, raw) -> np.ndarray:
    """The calibration itself applied in float64, result in counts (K * (A raw + c))."""
    M, off = counts_domain(sensor, A, c)
    return np.asarray(raw, np.float64).reshape(-1, 3) @ M.T + off


# --------------------------------------------------------------------------
# Rounding error
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class SensorRounding:
    """How far the fixed-point set can be from the physical calibration."""
    sensor: str
    fixed: FixedSensor
    matrix_error: float        # max |M_q - M| over the entries
    offset_error: float        # max |off_q - off|, counts
    worst_lsb: np.ndarray      # (3,) worst-case |out - K(A raw + c)| per axis over the
                               # chip's input range, counts, including output rounding
    input_range: int

    @property
    def worst_units(self) -> np.ndarray:
        """``worst_lsb`` in the sensor's unit (g, deg/s, gauss)."""
        return self.worst_lsb / NOMINAL_SCALES[self.sensor]


def rounding_report(sensor: str, A, c, fixed: FixedSensor | None = None) -> SensorRounding:
    M, off = counts_domain(sensor, A, c)
    fs = fixed if fixed is not None else quantise(M, off)
    dM = np.abs(fs.matrix - M)
    doff = np.abs(fs.offset - off)
    R = INPUT_RANGE[sensor]
    worst = dM.sum(axis=1) * R + doff + 0.5      # |dM raw + doff| <= ..., then rounding
    return SensorRounding(sensor, fs, float(dM.max()), float(doff.max()), worst, R)


def build_calset(mote: int, version: int, physical: Mapping[str, tuple]) -> tuple[bytes, dict]:
    """Calset bytes and per-sensor ``SensorRounding`` from ``{sensor: (A, c)}``."""
    report = {name: rounding_report(name, A, c) for name, (A, c) in physical.items()}
    return pack_calset(mote, version, {n: r.fixed for n, r in report.items()}), report


def format_report(report: Mapping[str, SensorRounding]) -> list[str]:
    """Lines for ``motecal upload --dry-run``: the fixed-point values and their error."""
    lines = []
    for name in P.SENSORS:
        r = report.get(name)
        if r is None:
            lines.append(f"{name}: not corrected (raw)")
            continue
        fs = r.fixed
        lines.append(f"{name}: Q{fs.shift}  matrix a = {np.asarray(fs.a).reshape(9).tolist()}"
                     f"  offset c = {np.asarray(fs.c).tolist()}")
        lines.append(f"  rounding: matrix <= {r.matrix_error:.2e}, offset <= "
                     f"{r.offset_error:.2e} counts; worst case over +-{r.input_range} counts "
                     f"incl. output rounding: "
                     + ", ".join(f"{v:.2f}" for v in r.worst_lsb)
                     + f" LSB (" + ", ".join(f"{v:.3g}" for v in r.worst_units)
                     + f" {UNITS[name]})")
    return lines
