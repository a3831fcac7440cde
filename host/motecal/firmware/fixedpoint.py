"""From a calibration in physical units to the fixed-point set the mote applies.

A calibration gives, per sensor, ``calibrated = A @ raw_counts + c`` in g,
deg/s or gauss.  The mote works in the sensor's nominal counts (K = 256 LSB/g,
14.375 LSB/(deg/s), 1090 LSB/gauss, ``session.NOMINAL_SCALES``), so the
counts-domain correction is ``M = K * A`` (about the identity) and
``off = K * c`` (counts).  ``M`` and ``off`` are quantised with ``shift``
fractional bits (the largest of 8..14 that fits int16 / int32) into the
``ninedof_cal_sensor`` of ``tinyos/NineDofMsg.h``, and the mote computes

    out = sat((a_q @ raw + c_q + r + 2**(shift-1)) >> shift)

with error feedback: per axis, r is what the last rounding dropped
(``tinyos/ninedof_correct.c``), so each output is within 1 LSB of the exact
value and the mean over a run follows the exact mean (``feedback_round``,
``feedback_correct``: the same rule in integers, with the state carried
from block to block).  ``reference_correct`` is the arithmetic in float64
(no rounding) that the C code is tested against; ``rounding_report`` says
how far the quantised set can be from the physical calibration.

A sensor with a temperature model (``calib.result.TempModel``: calibrated =
(1 + s dT) (A raw) + c + o dT, dT = clip(T, lo, hi) - t_ref) gets temperature
terms in counts per raw ITG-3200 TEMP_OUT count (``FixedTemp``: t_ref, t_lo,
t_hi as TEMP_OUT, ``o`` in Q(oshift), ``g`` in Q(gshift), int16), and the set
becomes the 164-byte ``ninedof_calset_temp`` (format 1).  A set without any
temperature model stays the 102-byte plain set, byte for byte.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from ..errors import QualityError
from ..line import protocol as P
from ..sessions.session import (CHIP_LIMITS, HMC5883L_OVERFLOW, INT16_MAX, NOMINAL_SCALES,
                                SENSOR_SLICES, UNITS)

SHIFT_MIN, SHIFT_MAX = 8, 14
INT32_MAX = 2**31 - 1
# the corrected magnetometer saturates at +-4095: -4096 stays the overflow code
MAG_LIMIT = -HMC5883L_OVERFLOW - 1

# Largest raw magnitude each chip can output, for the worst-case error
# (sessions.session.CHIP_LIMITS: ADXL345 13 bits, ITG3200 16, HMC5883L 12).
INPUT_RANGE = {s: -lo for s, (lo, hi) in CHIP_LIMITS.items()}


OSHIFT_MIN, OSHIFT_MAX = 14, 40      # ninedof_calset.h: NINEDOF_OSHIFT_MIN/MAX
GSHIFT_MIN, GSHIFT_MAX = 16, 46      # NINEDOF_GSHIFT_MIN/MAX
GAIN_LIMIT_Q30 = 1 << 27             # |g dT| <= 1/8 over the range (NINEDOF_LIMIT_GAIN_Q30)
INT16_MIN = -32768


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
class FixedTemp:
    """One sensor's temperature terms as the mote stores them
    (``ninedof_cal_temp``): temperatures in raw TEMP_OUT counts, ``o`` (3,)
    counts per TEMP_OUT count in Q(oshift), ``g`` (3,) relative gain per
    TEMP_OUT count in Q(gshift)."""
    t_ref: int
    t_lo: int
    t_hi: int
    o: np.ndarray
    g: np.ndarray
    oshift: int
    gshift: int

    def __post_init__(self):
        for name in ("o", "g"):
            v = np.array(getattr(self, name), dtype=np.int64).reshape(3)
            v.flags.writeable = False
            object.__setattr__(self, name, v)
        for name in ("t_ref", "t_lo", "t_hi", "oshift", "gshift"):
            object.__setattr__(self, name, int(getattr(self, name)))

    def dt(self, temp_raw) -> np.ndarray:
        """clamp(T, t_lo, t_hi) - t_ref in TEMP_OUT counts."""
        return np.clip(np.asarray(temp_raw, np.int64), self.t_lo, self.t_hi) - self.t_ref

    @property
    def offset_per_count(self) -> np.ndarray:
        return np.asarray(self.o, np.float64) / 2.0**self.oshift

    @property
    def gain_per_count(self) -> np.ndarray:
        return np.asarray(self.g, np.float64) / 2.0**self.gshift

    def __eq__(self, other):
        return (isinstance(other, FixedTemp) and
                (self.t_ref, self.t_lo, self.t_hi, self.oshift, self.gshift) ==
                (other.t_ref, other.t_lo, other.t_hi, other.oshift, other.gshift)
                and np.array_equal(self.o, other.o) and np.array_equal(self.g, other.g))


NO_TEMP = FixedTemp(0, 0, 0, np.zeros(3), np.zeros(3), OSHIFT_MIN, GSHIFT_MIN)


@dataclass(frozen=True)
class Calset:
    """A decoded ``ninedof_calset``: only the corrected sensors are in ``sensors``,
    the temperature terms of those that have them in ``temps``."""
    mote: int
    version: int
    sensors: dict          # name -> FixedSensor
    stored: dict           # name -> FixedSensor for all three (what the bytes hold)
    temps: dict = field(default_factory=dict)     # name -> FixedTemp
    format: int = P.CALSET_PLAIN

    @property
    def mask(self) -> int:
        return sum(1 << P.SENSORS.index(n) for n in self.sensors)

    @property
    def temp_mask(self) -> int:
        return sum(1 << P.SENSORS.index(n) for n in self.temps)


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


def _quantise16(v: np.ndarray, lo: int, hi: int, what: str) -> tuple[np.ndarray, int]:
    """int16 values of ``v`` with the largest shift in lo..hi that fits."""
    for shift in range(hi, lo - 1, -1):
        q = np.rint(v * 2.0**shift)
        if np.all(np.abs(q) <= INT16_MAX):
            return q.astype(np.int64), shift
    raise NotRepresentable(f"temperature {what} up to {np.abs(v).max():.3g} per TEMP_OUT "
                           f"count do not fit the mote's int16 even with {lo} fractional bits")


def temp_counts(sensor: str, tm) -> tuple[np.ndarray, np.ndarray]:
    """A TempModel's coefficients per raw TEMP_OUT count: offset (3,) in
    counts, relative gain (3,).  A coefficient that was not fitted (NaN) is 0."""
    per = P.ITG3200_TEMP_LSB_PER_C
    o = np.nan_to_num(np.asarray(tm.offset_per_c, float), nan=0.0) * NOMINAL_SCALES[sensor]
    g = np.nan_to_num(np.asarray(tm.scale_per_c, float), nan=0.0)
    return o / per, g / per


def fixed_temp(sensor: str, tm) -> FixedTemp:
    """A ``calib.result.TempModel`` as the mote's temperature terms."""
    o, g = temp_counts(sensor, tm)
    if not (np.all(np.isfinite(o)) and np.all(np.isfinite(g))):
        raise NotRepresentable("temperature coefficients are infinite")
    t_ref, t_lo, t_hi = (int(np.rint(P.temp_raw(v)))
                         for v in (tm.t_ref_c, *tm.range_c))
    if not (-32768 <= t_lo <= t_hi <= 32767):
        raise NotRepresentable(f"temperature range {tm.range_c} C is outside the "
                               "ITG-3200's TEMP_OUT")
    oq, oshift = _quantise16(o, OSHIFT_MIN, OSHIFT_MAX, "offsets")
    gq, gshift = _quantise16(g, GSHIFT_MIN, GSHIFT_MAX, "gains")
    return FixedTemp(t_ref, t_lo, t_hi, oq, gq, oshift, gshift)


# --------------------------------------------------------------------------
# Wire format
# --------------------------------------------------------------------------
def _sensor_bytes(fs: FixedSensor) -> bytes:
    return P.CAL_SENSOR.pack(a=[int(v) for v in np.asarray(fs.a).reshape(9)],
                             c=[int(v) for v in np.asarray(fs.c).reshape(3)],
                             shift=int(fs.shift), reserved=0)


def _temp_bytes(ft: FixedTemp) -> bytes:
    return P.CAL_TEMP.pack(t_ref=ft.t_ref, t_lo=ft.t_lo, t_hi=ft.t_hi,
                           o=[int(v) for v in ft.o], g=[int(v) for v in ft.g],
                           oshift=ft.oshift, gshift=ft.gshift)


def pack_calset(mote: int, version: int, sensors: Mapping[str, FixedSensor],
                temps: Mapping[str, FixedTemp] | None = None) -> bytes:
    """``ninedof_calset`` bytes: the given sensors corrected, the others raw
    (stored as the Q14 identity with their bit clear).  With ``temps`` (a
    FixedTemp for some of the corrected sensors) the 164-byte
    ``ninedof_calset_temp``; without, the 102-byte plain set."""
    temps = dict(temps or {})
    unknown = (set(sensors) | set(temps)) - set(P.SENSORS)
    if unknown:
        raise ValueError(f"unknown sensors {sorted(unknown)}; expected {P.SENSORS}")
    if set(temps) - set(sensors):
        raise ValueError(f"temperature terms for uncorrected sensors {sorted(set(temps) - set(sensors))}")
    if not 1 <= version <= 0xFFFF:
        raise ValueError("version must be 1..65535")
    mask = sum(1 << i for i, n in enumerate(P.SENSORS) if n in sensors)
    fmt = P.CALSET_TEMP if temps else P.CALSET_PLAIN
    out = P.CALSET_HEADER.pack(mote=mote & 0xFFFF, version=version, sensors=mask, format=fmt)
    for name in P.SENSORS:
        out += _sensor_bytes(sensors.get(name, IDENTITY))
    if temps:
        tmask = sum(1 << i for i, n in enumerate(P.SENSORS) if n in temps)
        out += P.CALSET_TEMP_HEADER.pack(temp_sensors=tmask, reserved=0)
        for name in P.SENSORS:
            out += _temp_bytes(temps.get(name, NO_TEMP))
    assert len(out) == P.CALSET_SIZES[fmt]
    return out


def unpack_calset(data: bytes) -> Calset:
    data = bytes(data)
    if len(data) not in P.CALSET_SIZES.values():
        raise ValueError(f"calibration set is {len(data)} bytes, expected {P.CALSET_SIZE} "
                         f"(or {P.CALSET_TEMP_SIZE} with temperature terms)")
    hdr = P.CALSET_HEADER.unpack(data[:P.CALSET_HEADER.size])
    if P.CALSET_SIZES.get(hdr["format"]) != len(data):
        raise ValueError(f"calibration set of format {hdr['format']} is not {len(data)} bytes")
    stored = {}
    for i, name in enumerate(P.SENSORS):
        lo = P.CALSET_HEADER.size + i * P.CAL_SENSOR.size
        s = P.CAL_SENSOR.unpack(data[lo:lo + P.CAL_SENSOR.size])
        stored[name] = FixedSensor(np.array(s["a"], np.int64).reshape(3, 3),
                                   np.array(s["c"], np.int64), s["shift"])
    enabled = {n: stored[n] for i, n in enumerate(P.SENSORS) if hdr["sensors"] >> i & 1}
    temps = {}
    if hdr["format"] == P.CALSET_TEMP:
        lo = P.CALSET_SIZE
        th = P.CALSET_TEMP_HEADER.unpack(data[lo:lo + P.CALSET_TEMP_HEADER.size])
        lo += P.CALSET_TEMP_HEADER.size
        for i, name in enumerate(P.SENSORS):
            t = P.CAL_TEMP.unpack(data[lo + i * P.CAL_TEMP.size:lo + (i + 1) * P.CAL_TEMP.size])
            if th["temp_sensors"] >> i & 1:
                temps[name] = FixedTemp(t["t_ref"], t["t_lo"], t["t_hi"], t["o"], t["g"],
                                        t["oshift"], t["gshift"])
    return Calset(hdr["mote"], hdr["version"], enabled, stored, temps, hdr["format"])


def without_temperature(data: bytes) -> bytes:
    """The plain set of the same corrections (what an image without
    temperature terms accepts): byte for byte the set built without them."""
    cs = unpack_calset(data)
    return pack_calset(cs.mote, cs.version, cs.sensors)


# --------------------------------------------------------------------------
# Reference correction (float64)
# --------------------------------------------------------------------------
def reference_correct(calset, raw, temp_raw=None) -> np.ndarray:
    """What the mote computes, in float64 and before its final rounding.

    ``calset`` is bytes or a ``Calset``; ``raw`` (n, 9) counts.  Corrected
    sensors: ``matrix @ raw + offset`` clipped to int16 (magnetometer to
    +-4095; a magnetometer sample with any axis at -4096 stays -4096 on all
    three).  The mote's int16 output is this value rounded half up with
    error feedback (``feedback_round``): within 1 LSB of it, unbiased.  A
    sensor with temperature terms, at board temperature ``temp_raw`` (raw
    TEMP_OUT, one value or one per row; None: each sensor at its t_ref):
    ``(1 + g dT) (matrix @ raw) + offset + o dT`` with the stored
    coefficients exactly; the mote is within ``TEMP_BOUND_LSB`` (< 1 LSB)
    of it (ninedof_correct.h).
    """
    cs = unpack_calset(calset) if isinstance(calset, (bytes, bytearray)) else calset
    raw = np.asarray(raw, np.float64).reshape(-1, 9)
    out = raw.copy()
    for name, fs in cs.sensors.items():
        sl = SENSOR_SLICES[name]
        y = raw[:, sl] @ fs.matrix.T
        ft = cs.temps.get(name)
        if ft is not None and temp_raw is not None:
            dt = np.broadcast_to(ft.dt(temp_raw), (len(raw),)).astype(np.float64)[:, None]
            y = y * (1.0 + ft.gain_per_count * dt) + fs.offset + ft.offset_per_count * dt
        else:
            y = y + fs.offset
        if name == "mag":
            y = np.clip(y, -MAG_LIMIT, MAG_LIMIT)
            over = np.any(raw[:, sl] == HMC5883L_OVERFLOW, axis=1)
            y[over] = HMC5883L_OVERFLOW
        else:
            y = np.clip(y, -32768, INT16_MAX)
        out[:, sl] = y
    return out


# --------------------------------------------------------------------------
# The mote's rounding: half up with error feedback (ninedof_correct.c shape_q14)
# --------------------------------------------------------------------------
Q14 = 14
OUTPUT_ROUNDING_LSB = 1.0           # |output - exact| < 1 with error feedback


# The temperature path (ninedof_correct.h): G = g dT / 2^gshift in Q30, O in Q14,
# the gain term t = floor((ph gh 2^16 + ph gl + pl gh) / 2^14), and on the
# gain path the residual kept within 1/2 - e, e = TEMP_MARGIN / 2^14 LSB.
TEMP_MARGIN = 16                    # NINEDOF_TEMP_MARGIN, Q14 units: e = 2^-10 LSB
GAIN_SAT_Q30 = 1 << 28              # G saturates here (sets that fail validation only)
# The mote's output against reference_correct for any valid set with
# temperature terms, any temperature and input (ninedof_correct.h proves it):
# |out - ref| <= 1 - e + d with d < 6.25 / 2^14 (the gain and offset terms'
# own rounding), so strictly below this:
TEMP_BOUND_LSB = 1.0 - 2.0**-11


def _round_shift(v, n: int):
    """round(v / 2^n) half up, as the C round_shift (arithmetic shift)."""
    v = np.asarray(v, np.int64)
    return v if n == 0 else (v + (1 << (n - 1))) >> n


def temp_terms(ft: FixedTemp, temp_raw) -> tuple[np.ndarray, np.ndarray]:
    """G (3,) in Q30 and O (3,) in Q14 of one sensor at raw temperature
    ``temp_raw`` (None: dT = 0), exactly as ``ninedof_cal_set_temp``."""
    dt = 0 if temp_raw is None else int(ft.dt(temp_raw))
    if abs(dt) > 32767:                 # never for a valid set
        dt = 0
    gd = np.asarray(ft.g, np.int64) * dt
    if ft.gshift >= 30:
        G = _round_shift(gd, ft.gshift - 30)
    else:
        lim = GAIN_SAT_Q30 >> (30 - ft.gshift)
        G = np.clip(gd, -lim, lim) << (30 - ft.gshift)
    G = np.clip(G, -GAIN_SAT_Q30, GAIN_SAT_Q30)
    O = _round_shift(np.asarray(ft.o, np.int64) * dt, ft.oshift - Q14)
    return G, O


def gain_term(p, G) -> np.ndarray:
    """The mote's t ~ p G / 2^30 (Q14) for p = A raw (int, Q14) and G (Q30):
    floor((ph gh 2^16 + ph gl + pl gh) / 2^14), the halves of p and G as
    16-bit words (ninedof_correct.c gain_term); p G / 2^30 - 5 < t <= p G / 2^30."""
    p = np.asarray(p, np.int64)
    G = np.asarray(G, np.int64)
    ph, pl = p >> 16, p & 0xFFFF
    gh, gl = G >> 16, G & 0xFFFF
    return ((ph * gh << 16) + ph * gl + pl * gh) >> 14


def feedback_round(x_q14, resid, limit: int = INT16_MAX, margin: int = 0) -> np.ndarray:
    """Round exact Q14 values ``x_q14`` ((n, 3) integers, one row per sample
    in sampling order) to whole counts as the mote does: per axis
    ``y = floor((x + r + 2^13) / 2^14)``, ``r = x + r - y 2^14`` (the residual,
    in [-2^13, 2^13)); with ``margin`` m (the temperature gain path:
    TEMP_MARGIN) r is then clipped to [-(2^13 - m), 2^13 - m].  A sample
    that saturates (outside int16, or beyond +-``limit`` for the
    magnetometer's 4095) is clipped and sets its axis's residual to 0.
    ``resid`` ((3,) int64) is updated in place."""
    x = np.asarray(x_q14, np.int64).reshape(-1, 3)
    y = np.empty_like(x)
    r = resid
    half = 1 << (Q14 - 1)
    for i in range(len(x)):
        v = x[i] + r + half
        yi = v >> Q14
        r[:] = v - half - (yi << Q14)
        if margin:
            np.clip(r, margin - half, half - margin, out=r)
        sat = (yi < -32768) | (yi > INT16_MAX)
        yi = np.clip(yi, -32768, INT16_MAX)
        if limit < INT16_MAX:
            sat |= (yi < -limit) | (yi > limit)
            yi = np.clip(yi, -limit, limit)
        r[sat] = 0
        y[i] = yi
    return y


def feedback_correct(calset, raw, resid=None, temp_raw=None) -> np.ndarray:
    """The mote's int16 output, exactly (integers; ``ninedof_correct_block``):
    ``a @ raw + c`` rescaled to Q14, then ``feedback_round``; a magnetometer
    sample with an axis at -4096 is (-4096,) * 3 and resets the
    magnetometer's residuals.  ``resid`` ((9,) int64, updated in place)
    carries the residuals from block to block; None: a freshly applied set
    (all 0).  A sensor with temperature terms at ``temp_raw`` (the
    temperature put in force before this block, ``ninedof_cal_set_temp``;
    None: none yet, each sensor at its t_ref) adds O, and where a gain G is
    not 0 the gain term ``gain_term(A raw, G)`` with the residual kept
    within 1/2 - e (clipped on entry, as set_temp does, and after every
    rounding)."""
    cs = unpack_calset(calset) if isinstance(calset, (bytes, bytearray)) else calset
    raw = np.asarray(raw, np.int64).reshape(-1, 9)
    resid = np.zeros(9, np.int64) if resid is None else resid
    out = raw.copy()
    for name, fs in cs.sensors.items():
        sl = SENSOR_SLICES[name]
        p = raw[:, sl] @ np.asarray(fs.a, np.int64).T
        x = (p + np.asarray(fs.c, np.int64)) << (Q14 - fs.shift)
        r = resid[sl]
        margin = 0
        ft = cs.temps.get(name)
        if ft is not None and temp_raw is not None:
            G, O = temp_terms(ft, temp_raw)
            x = x + O
            if np.any(G != 0):
                x = x + gain_term(p, G)
                margin = TEMP_MARGIN
                np.clip(r, margin - (1 << (Q14 - 1)), (1 << (Q14 - 1)) - margin, out=r)
        if name == "mag":
            y = np.empty_like(x)
            over = np.any(raw[:, sl] == HMC5883L_OVERFLOW, axis=1)
            for i in range(len(x)):             # the overflow code resets the residuals
                if over[i]:
                    y[i] = HMC5883L_OVERFLOW
                    r[:] = 0
                else:
                    y[i] = feedback_round(x[i:i + 1], r, MAG_LIMIT, margin)[0]
        else:
            y = feedback_round(x, r, margin=margin)
        resid[sl] = r
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
    temp: FixedTemp | None = None      # temperature terms, if the sensor has a model
    temp_offset_error: float = 0.0     # max |o_q dT - o dT| over the range, counts
    temp_gain_error: float = 0.0       # max |g_q dT - g dT| over the range, relative

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
    # |dM raw + doff| <= ..., then the output rounding (error feedback: < 1 LSB)
    worst = dM.sum(axis=1) * R + doff + OUTPUT_ROUNDING_LSB
    return SensorRounding(sensor, fs, float(dM.max()), float(doff.max()), worst, R)


def temp_rounding(sensor: str, tm, ft: FixedTemp) -> tuple[float, float]:
    """Largest error of the quantised temperature terms over the range:
    offset (counts) and relative gain."""
    o, g = temp_counts(sensor, tm)
    dt = float(max(abs(ft.t_lo - ft.t_ref), abs(ft.t_hi - ft.t_ref)))
    return (float(np.abs(ft.offset_per_count - o).max() * dt),
            float(np.abs(ft.gain_per_count - g).max() * dt))


def build_calset(mote: int, version: int, physical: Mapping[str, tuple],
                 temps: Mapping | None = None) -> tuple[bytes, dict]:
    """Calset bytes and per-sensor ``SensorRounding`` from ``{sensor: (A, c)}``
    and, for sensors with a temperature model, ``temps`` ``{sensor: TempModel}``
    (the 164-byte set; without any, the plain 102-byte set)."""
    report = {name: rounding_report(name, A, c) for name, (A, c) in physical.items()}
    fixed_temps = {}
    for name, tm in (temps or {}).items():
        if tm is None or name not in report:
            continue
        if report[name].fixed.shift != SHIFT_MAX:
            raise NotRepresentable(f"{name}: temperature terms need the Q14 correction, "
                                   f"and this one needs Q{report[name].fixed.shift}")
        ft = fixed_temp(name, tm)
        oe, ge = temp_rounding(name, tm, ft)
        report[name] = dataclasses.replace(report[name], temp=ft, temp_offset_error=oe,
                                           temp_gain_error=ge)
        fixed_temps[name] = ft
    return pack_calset(mote, version, {n: r.fixed for n, r in report.items()},
                       fixed_temps), report


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
        if r.temp is not None:
            lines += temp_lines(name, r.temp)
            lines.append(f"  temperature rounding over the range: offset <= "
                         f"{r.temp_offset_error:.2e} counts, gain <= {r.temp_gain_error:.2e}")
    return lines


def temp_lines(name: str, ft: FixedTemp) -> list[str]:
    """A sensor's temperature terms, stored and in physical units."""
    per = P.ITG3200_TEMP_LSB_PER_C
    k, unit = NOMINAL_SCALES[name], UNITS[name]
    t = [float(P.temp_c(v)) for v in (ft.t_ref, ft.t_lo, ft.t_hi)]
    return [f"  temperature: t_ref {t[0]:.2f} C, clamped to {t[1]:.2f}..{t[2]:.2f} C "
            f"(TEMP_OUT {ft.t_ref}, {ft.t_lo}..{ft.t_hi})",
            f"    offset o = {np.asarray(ft.o).tolist()} Q{ft.oshift} per TEMP_OUT count = "
            "[" + ", ".join(f"{v * per / k:+.4g}" for v in ft.offset_per_count)
            + f"] {unit}/C",
            f"    gain g = {np.asarray(ft.g).tolist()} Q{ft.gshift} per TEMP_OUT count = "
            "[" + ", ".join(f"{v * per:+.4g}" for v in ft.gain_per_count) + "] /C"]
