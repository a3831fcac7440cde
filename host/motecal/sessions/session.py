"""The in-memory form of a recorded session, shared by store, importer, calib,
diagnose and report: plain numpy arrays plus the metadata needed to read them.

Conventions
-----------
* ``raw`` is ``(n, 9)`` float64 in sensor counts, columns ``ax ay az gx gy gz
  mx my mz``; NaN where a sensor has no value in that row (imported data whose
  sensors run on separate clocks, magnetometer-only sweeps).
* ``label`` is int32: 1..80 (or more) = index of a static orientation,
  ``LABEL_ROT`` (-1) = rotation capture, ``LABEL_NONE`` (0) = unlabelled.
  In CSV and in the database the same labels are written ``"1".."80"``,
  ``"rot"`` and ``""`` (see ``label_to_text`` / ``label_from_text``).
* ``t`` is seconds from the session start (NaN where unknown).
* ``temp`` is the board temperature in degrees C per row (NaN where
  unknown), or None when the session carries no temperature at all (images
  and imports without it).  Loggers get it from the mote's temperature
  messages (interpolated to sample times), importers from a temperature
  column.
* ``scales`` gives LSB per unit for each sensor: accel in LSB/g, gyro in
  LSB/(deg/s), mag in LSB/gauss.  Defaults are the 9DOF board's nominal
  datasheet values.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..line.protocol import NINEDOF_RATE_HZ

COLUMNS = ("ax", "ay", "az", "gx", "gy", "gz", "mx", "my", "mz")
SENSOR_SLICES = {"accel": slice(0, 3), "gyro": slice(3, 6), "mag": slice(6, 9)}
UNITS = {"accel": "g", "gyro": "deg/s", "mag": "gauss"}

# Nominal scales of the 9DOF board (datasheets)
ADXL345_LSB_PER_G = 256.0          # full resolution, 3.9 mg/LSB
ITG3200_LSB_PER_DPS = 14.375       # FS_SEL=3, +-2000 deg/s
HMC5883L_LSB_PER_GAUSS = 1090.0    # default gain (CRB GN=001)
NOMINAL_SCALES = {"accel": ADXL345_LSB_PER_G, "gyro": ITG3200_LSB_PER_DPS,
                  "mag": HMC5883L_LSB_PER_GAUSS}
NOMINAL_CHIPS = {"accel": "ADXL345", "gyro": "ITG3200", "mag": "HMC5883L"}

# The chips' output ranges and overflow code, in counts: the one definition
# (issue 24.5) that the simulator's chip stage, the importer's full-scale
# rule, the diagnosis' screens and the mote's correction read.
# tests/test_chip_limits.py checks it against the C headers' macros
# (ninedof_board.h NINEDOF_HMC5883L_OVERFLOW, ninedof_correct.h
# NINEDOF_MAG_OVERFLOW).
INT16_MIN, INT16_MAX = -32768, 32767
CHIP_RANGES = {"ADXL345": (-4096, 4095),           # full resolution +-16 g: 13 bits
               "ITG3200": (INT16_MIN, INT16_MAX),  # all 16 bits
               "HMC5883L": (-2048, 2047)}          # 12 bits per axis
CHIP_LIMITS = {s: CHIP_RANGES[c] for s, c in NOMINAL_CHIPS.items()}
HMC5883L_OVERFLOW = -4096          # data output register value (all axes) on overflow

LABEL_NONE = 0
LABEL_ROT = -1
LABEL_MAX = 65535           # pose labels are 1..LABEL_MAX (int32 arrays, text in the store)

RATE_PAUSE_S = 1.0       # a longer step between rows is a pause, not a sample interval
BATCHED_FRACTION = 0.2   # more steps than this that are not positive: batch receive times


def batch_times(t) -> bool:
    """Rows' times ``t`` (in row order) are batch receive times: rows of one
    batch share the time it reached the host, so more than
    ``BATCHED_FRACTION`` of the steps between rows are not positive."""
    t = np.asarray(t, float)
    dt = np.diff(t[np.isfinite(t)])
    return len(dt) > 0 and float(np.mean(dt <= 0)) > BATCHED_FRACTION


def rate_from_times(t, seq=None) -> float | None:
    """Sample rate (Hz) of one clock from its rows in order: samples per second
    over the steps between rows, steps longer than ``RATE_PAUSE_S`` (pauses)
    left out.  With ``seq`` (sample numbers) the samples of a step are
    counted by seq, so lost samples count and rows that share a batch
    receive time are counted, not timed; without it, one per step ((n - 1) /
    duration).  None when the times span no time."""
    t = np.asarray(t, float)
    ok = np.isfinite(t)
    dt = np.diff(t[ok])
    ds = np.diff(np.asarray(seq, float)[ok]) if seq is not None else np.ones(len(dt))
    keep = (dt >= 0) & (dt <= RATE_PAUSE_S) & (ds > 0)
    if not keep.any() or dt[keep].sum() <= 0:
        return None
    return float(ds[keep].sum() / dt[keep].sum())


def label_to_text(label: int) -> str:
    if label == LABEL_ROT:
        return "rot"
    if label == LABEL_NONE:
        return ""
    return str(int(label))


def label_from_text(text: str) -> int:
    """Inverse of label_to_text; raises ValueError on anything else."""
    text = (text or "").strip()
    if text == "":
        return LABEL_NONE
    if text == "rot":
        return LABEL_ROT
    v = int(text)
    if not 1 <= v <= LABEL_MAX:
        raise ValueError(f"pose label must be 1..{LABEL_MAX}, 'rot' or empty, not {text!r}")
    return v


@dataclass
class SessionData:
    """Samples of one session (possibly several motes)."""
    name: str
    raw: np.ndarray                      # (n, 9) float64 counts, NaN = missing
    mote: np.ndarray                     # (n,) int32
    seq: np.ndarray                      # (n,) int64, unwrapped sequence numbers (or row index)
    t: np.ndarray                        # (n,) float64 seconds
    label: np.ndarray                    # (n,) int32
    flags: np.ndarray                    # (n,) uint8 sample-message flags (0 for imports)
    kind: str = "static80"               # static80 | rotation | idle | free | imported
    scales: dict = field(default_factory=lambda: dict(NOMINAL_SCALES))
    chips: dict = field(default_factory=lambda: dict(NOMINAL_CHIPS))
    meta: dict = field(default_factory=dict)   # source, rate_hz, notes, ...
    temp: np.ndarray | None = None       # (n,) float64 degrees C, NaN = unknown; None = no temperature

    def __post_init__(self):
        n = len(self.raw)
        if self.temp is not None:
            self.temp = np.asarray(self.temp, dtype=np.float64).reshape(-1)
            if self.temp.shape != (n,):
                raise ValueError(f"temp must have shape ({n},), not {self.temp.shape}")
        self.raw = np.asarray(self.raw, dtype=np.float64).reshape(n, 9)
        for name, dt in (("mote", np.int32), ("seq", np.int64), ("t", np.float64),
                         ("label", np.int32), ("flags", np.uint8)):
            arr = np.asarray(getattr(self, name), dtype=dt)
            if arr.shape != (n,):
                raise ValueError(f"{name} must have shape ({n},), not {arr.shape}")
            setattr(self, name, arr)

    def __len__(self) -> int:
        return len(self.raw)

    @property
    def motes(self) -> list[int]:
        return sorted(int(m) for m in np.unique(self.mote))

    def sensor(self, name: str) -> np.ndarray:
        """(n, 3) counts of one sensor: 'accel', 'gyro' or 'mag'."""
        return self.raw[:, SENSOR_SLICES[name]]

    def physical(self, name: str) -> np.ndarray:
        """(n, 3) in g, deg/s or gauss using the session's nominal scales."""
        return self.sensor(name) / self.scales[name]

    def has(self, name: str) -> np.ndarray:
        """Rows where that sensor has all three values."""
        return ~np.isnan(self.sensor(name)).any(axis=1)

    def rate(self, sensor: str | None = None) -> float:
        """Sample rate (Hz) of one sensor, or of the session: ``meta["rates_hz"]
        [sensor]``, else ``meta["rate_hz"]``, else measured from the times of
        the rows holding that sensor, per mote (``rate_from_times``, with the
        sequence numbers when the sensor is in every row of the mote) and the
        median over motes, else the firmware's 125 Hz."""
        meta = self.meta or {}
        rates = meta.get("rates_hz")
        if sensor and isinstance(rates, dict) and rates.get(sensor):
            return float(rates[sensor])
        if meta.get("rate_hz"):
            return float(meta["rate_hz"])
        rows = self.has(sensor) if sensor else np.ones(len(self), bool)
        found = []
        for m in np.unique(self.mote[rows]):
            mine = self.mote == m
            sel = rows & mine
            every = sel.sum() == mine.sum()    # seq numbers this sensor's samples
            r = rate_from_times(self.t[sel], self.seq[sel] if every else None)
            if r:
                found.append(r)
        return float(np.median(found)) if found else float(NINEDOF_RATE_HZ)

    def sample_times(self) -> np.ndarray:
        """Per row, when the sample was taken (s): ``t`` when it is that.  A
        logged session's ``t`` is when the host received the sample's batch
        (rows of a batch share it, and it is compressed when the simulator
        runs faster than real time); the mote samples at exactly its rate, so
        ``(seq - first seq of that mote) / rate`` is then the sample time."""
        t = np.asarray(self.t, float)
        if len(t) < 2:
            return np.nan_to_num(t)
        seq_t = np.zeros(len(t))
        rate = self.rate()
        for m in np.unique(self.mote):
            sel = self.mote == m
            seq_t[sel] = (self.seq[sel] - self.seq[sel].min()) / rate
        if not np.all(np.isfinite(t)):
            return seq_t
        one = [np.diff(self.seq[self.mote == m]) for m in np.unique(self.mote)]
        if batch_times(t) and all(np.all(d > 0) for d in one):
            return seq_t
        return t

    def select(self, mask) -> "SessionData":
        mask = np.asarray(mask)
        return SessionData(self.name, self.raw[mask], self.mote[mask], self.seq[mask],
                           self.t[mask], self.label[mask], self.flags[mask], self.kind,
                           dict(self.scales), dict(self.chips), dict(self.meta),
                           None if self.temp is None else self.temp[mask])

    def for_mote(self, mote: int) -> "SessionData":
        return self.select(self.mote == mote)

    @property
    def has_temp(self) -> bool:
        """The session carries a temperature for at least one row."""
        return self.temp is not None and bool(np.isfinite(self.temp).any())

    def poses(self) -> list[int]:
        """Static pose labels present, sorted."""
        return sorted(int(v) for v in np.unique(self.label) if v >= 1)

    def pose_means(self, name: str) -> np.ndarray:
        """(poses, 3) mean of each static pose of sensor ``name`` in physical
        units at the session's scales, in the order of ``poses()``."""
        x = self.physical(name)
        return np.array([np.nanmean(x[self.label == k], axis=0) for k in self.poses()]
                        ).reshape(-1, 3)

    def pose_magnitudes(self) -> dict:
        """Per mote: the number of static poses, |accel| (g) and |mag| (gauss)
        of each pose's mean at the session's scales, and every sample's flags
        (what `make demo` and the release check print before and after an
        upload)."""
        out = {}
        for m in self.motes:
            d = self.for_mote(m)
            out[m] = {"poses": len(d.poses()), "flags": np.asarray(d.flags),
                      "acc": np.linalg.norm(d.pose_means("accel"), axis=1),
                      "mag": np.linalg.norm(d.pose_means("mag"), axis=1)}
        return out
