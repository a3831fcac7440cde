"""Calibration results: one ``SensorCalibration`` per sensor, one
``BoardCalibration`` per board (mote), and their JSON form (``cal.json``).

For every sensor ``calibrated = A @ raw_counts + c`` in the sensor's unit
(g, deg/s, gauss).  A sensor calibrated against temperature also carries a
``TempModel`` (format_version 2): with ``dT = clip(T, lo, hi) - t_ref``,
``calibrated = (1 + scale_per_c * dT) * (A @ raw_counts) + c + offset_per_c * dT``
(element-wise per axis; the scale term is zero where it was not identifiable).  Everything else (parameters with names, standard
deviations and units, errors before/after, magnitude ranges, validation, GA
trace, quality metrics) documents how that map was obtained.

``read_document`` / ``check_document`` are the one validation of a cal.json
that every reader shares (``upload``, ``export-cal``, ``report``): types,
shapes, finite numbers, ranges, before numpy or a writer sees a value.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import UserError
from ..jsonable import finite as _num, jsonable as _jsonable
from .templag import lag_filter

FORMAT_VERSION = 2      # 2: optional per-sensor temperature model (1 files still read)
SENSORS = ("accel", "gyro", "mag")
UNITS = {"accel": "g", "gyro": "deg/s", "mag": "gauss"}
MOTE_MAX = 0xFFFF       # a mote id is a uint16 wherever it is written (sets, headers)
COND_MAX = 1e12         # an A more ill-conditioned than this is no calibration


def _unnum(x):
    return float("nan") if x is None else float(x)


@dataclass
class Param:
    name: str
    value: float
    std: float                  # NaN when not identifiable
    unit: str = ""
    identifiable: bool = True

    def to_json(self):
        return {"name": self.name, "value": _num(self.value), "std": _num(self.std),
                "unit": self.unit, "identifiable": bool(self.identifiable)}

    @classmethod
    def from_json(cls, d):
        return cls(d["name"], _unnum(d["value"]), _unnum(d.get("std")), d.get("unit", ""),
                   bool(d.get("identifiable", True)))


@dataclass
class TempModel:
    """How a sensor's calibrated output moves with the board temperature.

    ``offset_per_c`` (sensor unit per degree C) and ``scale_per_c`` (relative
    gain change per degree C), per axis, around ``t_ref_c``; only valid over
    ``range_c`` (the temperatures the fit saw): outside it the temperature is
    clamped to the range, never extrapolated.  ``lag_s`` > 0: the chip
    follows the recorded temperature (the ITG3200's) through a first-order
    lag of that time constant (``calib.templag``), which ``lagged`` applies
    to a recorded series; the coefficients are against the lagged one."""
    t_ref_c: float
    range_c: tuple                      # (lo, hi) degrees C covered by the data
    offset_per_c: np.ndarray            # (3,) unit/degC
    offset_per_c_std: np.ndarray        # (3,) NaN when not identifiable
    scale_per_c: np.ndarray = field(default_factory=lambda: np.zeros(3))       # (3,) 1/degC
    scale_per_c_std: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    notes: list = field(default_factory=list)
    extra: dict = field(default_factory=dict)    # fit details (samples, span, residual, ...)
    lag_s: float = 0.0                  # the chip's lag behind the recorded temperature (s)

    def __post_init__(self):
        lo, hi = (float(v) for v in self.range_c)
        if not lo <= self.t_ref_c <= hi:
            raise ValueError(f"t_ref_c {self.t_ref_c} outside range_c {lo}..{hi}")
        self.range_c = (lo, hi)
        for name in ("offset_per_c", "offset_per_c_std", "scale_per_c", "scale_per_c_std"):
            setattr(self, name, np.asarray(getattr(self, name), float).reshape(3))

    def lagged(self, temp_c, t_s=None, part=None) -> np.ndarray:
        """The chip's temperature from the recorded ``temp_c`` at times
        ``t_s`` (s; rows of one recording, or ``part`` per row): the
        recorded one itself without a lag or without times."""
        if not self.lag_s or t_s is None or np.ndim(temp_c) == 0:
            return np.asarray(temp_c, float)
        return lag_filter(temp_c, t_s, self.lag_s, part)

    def dt(self, temp_c) -> np.ndarray:
        """Clamped temperature minus the reference; 0 where ``temp_c`` is NaN."""
        t = np.asarray(temp_c, float)
        d = np.clip(t, *self.range_c) - self.t_ref_c
        return np.where(np.isfinite(d), d, 0.0)

    def to_json(self) -> dict:
        return {"t_ref_c": _num(self.t_ref_c), "range_c": [_num(v) for v in self.range_c],
                "offset_per_c": [_num(v) for v in self.offset_per_c],
                "offset_per_c_std": [_num(v) for v in self.offset_per_c_std],
                "scale_per_c": [_num(v) for v in self.scale_per_c],
                "scale_per_c_std": [_num(v) for v in self.scale_per_c_std],
                "notes": list(self.notes), "extra": _jsonable(self.extra),
                **({"lag_s": _num(self.lag_s)} if self.lag_s else {})}

    @classmethod
    def from_json(cls, d: dict) -> "TempModel":
        return cls(t_ref_c=float(d["t_ref_c"]), range_c=tuple(float(v) for v in d["range_c"]),
                   offset_per_c=[_unnum(v) for v in d["offset_per_c"]],
                   offset_per_c_std=[_unnum(v) for v in d.get("offset_per_c_std", [None] * 3)],
                   scale_per_c=[_unnum(v) for v in d.get("scale_per_c", [0, 0, 0])],
                   scale_per_c_std=[_unnum(v) for v in d.get("scale_per_c_std", [None] * 3)],
                   notes=list(d.get("notes", [])), extra=d.get("extra", {}),
                   lag_s=float(d.get("lag_s") or 0.0))


@dataclass
class SensorCalibration:
    sensor: str                  # accel | gyro | mag
    unit: str                    # g | deg/s | gauss
    chip: str
    lsb_per_unit: float          # nominal scale used for the parameters
    model: str                   # e.g. "full", "paper(offsets+scales)", "bias", "bias+matrix"
    params: list                 # [Param]
    A: np.ndarray                # (3, 3): calibrated = A @ raw_counts + c
    c: np.ndarray                # (3,)
    mse_before: float            # the paper's error column (unit^2)
    mse_after: float
    min_before: float            # lowest / highest magnitude (paper's table columns)
    max_before: float
    min_after: float
    max_after: float
    n_samples: int = 0
    n_poses: int = 0
    dataset: str = ""            # "O" (static poses), "R" (rotation), "still"
    rank: int = 0
    notes: list = field(default_factory=list)
    validation: dict = field(default_factory=dict)
    quality: dict = field(default_factory=dict)
    ga: dict = field(default_factory=dict)      # seed, generations, stop, trace
    field_gauss: float | None = None            # mag: fitted (or given) field magnitude
    field_std: float | None = None
    gauge: str | None = None
    extra: dict = field(default_factory=dict)
    temperature: TempModel | None = None        # format 2: the output against board temperature
    # readings the robust fit set aside (calib.robust.set_aside_record: count, of,
    # fraction, threshold_sd, robust_sd, stretches_s, single, rows as [first, count]);
    # empty in files written before it
    set_aside: dict = field(default_factory=dict)
    # covariance (12, 12) of (A row-major, c) from the fit, for what builds on
    # this calibration (the gyroscope's G on the accelerometer's gravity
    # directions); not written to cal.json
    affine_cov: np.ndarray | None = field(default=None, repr=False, compare=False)

    def __post_init__(self):
        self.A = np.asarray(self.A, float).reshape(3, 3)
        self.c = np.asarray(self.c, float).reshape(3)

    # -- use --------------------------------------------------------------------
    def apply(self, raw_counts, temp_c=None, t_s=None) -> np.ndarray:
        """Calibrated vectors (n, 3) in ``unit`` from raw counts (n, 3); with a
        temperature model and ``temp_c`` (per row, or one value), corrected
        for temperature (rows with NaN temperature at the reference).  A
        model with a lag (``TempModel.lag_s``) applies it when the rows'
        times ``t_s`` (s, one recording) are given, else takes ``temp_c`` as
        the chip's own."""
        y = np.asarray(raw_counts, float) @ self.A.T
        if self.temperature is None or temp_c is None:
            return y + self.c
        tm = self.temperature
        dt = np.broadcast_to(tm.dt(tm.lagged(temp_c, t_s)), y.shape[:-1])[..., None]
        # a coefficient that was not fitted (NaN, null in cal.json) is 0, as on the mote
        scale, offset = np.nan_to_num(tm.scale_per_c), np.nan_to_num(tm.offset_per_c)
        return y * (1.0 + scale * dt) + self.c + offset * dt

    def param(self, name: str) -> Param:
        for p in self.params:
            if p.name == name:
                return p
        raise KeyError(name)

    @property
    def not_identifiable(self) -> list:
        return [p.name for p in self.params if not p.identifiable]

    # -- JSON ---------------------------------------------------------------------
    def to_json(self) -> dict:
        d = {"sensor": self.sensor, "unit": self.unit, "chip": self.chip,
             "lsb_per_unit": self.lsb_per_unit, "model": self.model,
             "A": self.A.tolist(), "c": self.c.tolist(),
             "params": [p.to_json() for p in self.params],
             "mse_before": _num(self.mse_before), "mse_after": _num(self.mse_after),
             "min_before": _num(self.min_before), "max_before": _num(self.max_before),
             "min_after": _num(self.min_after), "max_after": _num(self.max_after),
             "n_samples": int(self.n_samples), "n_poses": int(self.n_poses),
             "dataset": self.dataset, "rank": int(self.rank), "notes": list(self.notes),
             "validation": _jsonable(self.validation), "quality": _jsonable(self.quality),
             "ga": _jsonable(self.ga)}
        if self.sensor == "mag":
            d["field_gauss"] = _num(self.field_gauss)
            d["field_std"] = _num(self.field_std)
            d["gauge"] = self.gauge
        if self.extra:
            d["extra"] = _jsonable(self.extra)
        if self.temperature is not None:
            d["temperature"] = self.temperature.to_json()
        if self.set_aside:
            d["set_aside"] = _jsonable(self.set_aside)
        return d

    @classmethod
    def from_json(cls, d: dict) -> "SensorCalibration":
        return cls(sensor=d["sensor"], unit=d["unit"], chip=d.get("chip", ""),
                   lsb_per_unit=float(d["lsb_per_unit"]), model=d["model"],
                   params=[Param.from_json(p) for p in d.get("params", [])],
                   A=np.array(d["A"], float), c=np.array(d["c"], float),
                   mse_before=_unnum(d.get("mse_before")), mse_after=_unnum(d.get("mse_after")),
                   min_before=_unnum(d.get("min_before")), max_before=_unnum(d.get("max_before")),
                   min_after=_unnum(d.get("min_after")), max_after=_unnum(d.get("max_after")),
                   n_samples=int(d.get("n_samples", 0)), n_poses=int(d.get("n_poses", 0)),
                   dataset=d.get("dataset", ""), rank=int(d.get("rank", 0)),
                   notes=list(d.get("notes", [])), validation=d.get("validation", {}),
                   quality=d.get("quality", {}), ga=d.get("ga", {}),
                   field_gauss=d.get("field_gauss"), field_std=d.get("field_std"),
                   gauge=d.get("gauge"), extra=d.get("extra", {}),
                   temperature=TempModel.from_json(d["temperature"])
                   if d.get("temperature") else None,
                   set_aside=d.get("set_aside") or {})


@dataclass
class BoardCalibration:
    mote: int
    session: str
    created: str                                   # ISO 8601 UTC
    accel: SensorCalibration | None = None
    gyro: SensorCalibration | None = None
    mag: SensorCalibration | None = None
    mag_sets: dict = field(default_factory=dict)   # data set -> summary of its fit
    gate: dict = field(default_factory=dict)       # accepted, forced, reasons, warnings
    settings: dict = field(default_factory=dict)   # model, params, seed, gauge, ...
    tool: str = ""
    format_version: int = FORMAT_VERSION

    def sensors(self):
        return [(s, getattr(self, s)) for s in SENSORS if getattr(self, s) is not None]

    def to_json(self) -> dict:
        # a file without a temperature model stays format 1, which older readers take
        temp = any(v.temperature is not None for _, v in self.sensors())
        d = {"format_version": FORMAT_VERSION if temp else 1, "mote": int(self.mote),
             "session": self.session, "created": self.created, "tool": self.tool,
             "settings": _jsonable(self.settings)}
        for s in SENSORS:
            v = getattr(self, s)
            d[s] = v.to_json() if v is not None else None
        d["mag_sets"] = _jsonable(self.mag_sets)
        d["gate"] = _jsonable(self.gate)
        return d

    def dumps(self) -> str:
        return json.dumps(self.to_json(), indent=1, allow_nan=False) + "\n"

    @classmethod
    def from_json(cls, d: dict, where: str = "calibration") -> "BoardCalibration":
        """A checked cal.json document (``check_document``, with each sensor's
        ``lsb_per_unit``) as a BoardCalibration; UserError, one line, if not."""
        check_document(d, where, need_scale=True)
        try:
            kw = {s: SensorCalibration.from_json({"sensor": s, "unit": UNITS[s], "model": "",
                                                  **d[s]}) if d.get(s) is not None else None
                  for s in SENSORS}
            return cls(mote=d["mote"], session=d.get("session") or "",
                       created=d.get("created") or "", mag_sets=d.get("mag_sets") or {},
                       gate=d.get("gate") or {}, settings=d.get("settings") or {},
                       tool=d.get("tool") or "", format_version=d["format_version"], **kw)
        except (KeyError, TypeError, ValueError, OverflowError, RecursionError) as e:
            raise UserError(f"{where} is malformed: {type(e).__name__}: "
                            f"{' '.join(str(e).split())[:200]}") from None

    @classmethod
    def loads(cls, text: str, where: str = "calibration file") -> "BoardCalibration":
        return cls.from_json(read_document(text, where), where)

    def save(self, path) -> Path:
        path = Path(path)
        try:
            path.write_text(self.dumps(), encoding="utf-8")
        except OSError as e:
            raise UserError(f"cannot write {path}: {e.strerror or e}") from None
        return path

    @classmethod
    def load(cls, path) -> "BoardCalibration":
        try:
            text = Path(path).read_text(encoding="utf-8")
        except OSError as e:
            raise UserError(f"cannot read {path}: {e.strerror or e}") from None
        return cls.loads(text)


# --------------------------------------------------------------------------
# The one validation of a cal.json (upload, export-cal, report)
# --------------------------------------------------------------------------
def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _numbers(v, depth: int = 0) -> bool:
    """Nested lists of JSON numbers only (a string "1.0" or true is not one)."""
    if isinstance(v, list):
        return depth < 3 and all(_numbers(x, depth + 1) for x in v)
    return _is_number(v)


def checked_array(d: dict, key: str, shape: tuple, where: str) -> np.ndarray:
    """``d[key]`` as a finite float array of ``shape``; UserError naming the field."""
    if key not in d:
        raise UserError(f"{where}: no {key!r}")
    if not _numbers(d[key]):
        raise UserError(f"{where}: {key!r} is not a list of numbers")
    try:
        a = np.array(d[key], dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise UserError(f"{where}: {key!r} is not a list of numbers") from None
    if a.shape != shape:
        raise UserError(f"{where}: {key!r} must be {'x'.join(map(str, shape))}, not "
                        f"{'x'.join(map(str, a.shape)) or 'a number'}")
    if not np.all(np.isfinite(a)):
        raise UserError(f"{where}: {key!r} holds a missing or infinite value")
    return a


def _positive(d: dict, key: str, where: str) -> None:
    v = d[key]
    if not _is_number(v) or not math.isfinite(v) or v <= 0:
        raise UserError(f"{where}: {key!r} must be a positive finite number, not {v!r:.40}")


def read_document(text: str, where: str = "calibration file") -> dict:
    """cal.json text -> its checked document (``check_document``)."""
    try:
        d = json.loads(text)
    except (json.JSONDecodeError, RecursionError, ValueError) as e:
        raise UserError(f"{where} is not JSON: {' '.join(str(e).split())[:200]}") from None
    check_document(d, where)
    return d


def check_document(d, where: str = "calibration", need_scale: bool = False) -> None:
    """The checks every reader of a cal.json relies on, each failure one
    line naming the field: a ``format_version`` this motecal reads (a whole
    number 1..FORMAT_VERSION, not text or true), a ``mote`` id 0..65535,
    ``session``/``created``/``tool`` as text, and per calibrated sensor (an
    object; null or absent: not calibrated) ``A`` (3x3) and ``c`` (3) of
    finite JSON numbers with ``A`` invertible, ``lsb_per_unit`` (required
    with ``need_scale``) and ``field_gauss`` positive and finite, and a
    temperature model whose numbers are finite."""
    if not isinstance(d, dict) or "format_version" not in d:
        raise UserError(f"{where} is not a motecal calibration (no format_version)")
    fv = d["format_version"]
    if isinstance(fv, bool) or not isinstance(fv, int) or not 1 <= fv <= FORMAT_VERSION:
        raise UserError(f"{where}: calibration format_version {fv!r:.40} is not one this "
                        f"motecal reads (1..{FORMAT_VERSION})")
    mote = d.get("mote")
    if isinstance(mote, bool) or not isinstance(mote, int) or not 0 <= mote <= MOTE_MAX:
        raise UserError(f"{where}: no mote id (\"mote\": an integer 0..{MOTE_MAX}, "
                        f"not {mote!r:.40})")
    for key in ("session", "created", "tool"):
        if d.get(key) is not None and not isinstance(d[key], str):
            raise UserError(f"{where}: {key!r} is not a text")
    for key in ("gate", "settings", "mag_sets"):
        if d.get(key) is not None and not isinstance(d[key], dict):
            raise UserError(f"{where}: {key!r} is not an object")
    calibrated = 0
    for name in SENSORS:
        s = d.get(name)
        if s is None:
            continue
        at = f"{where}: {name}"
        if not isinstance(s, dict):
            raise UserError(f"{at} is not an object")
        if s.get("sensor", name) != name:
            raise UserError(f"{at}: \"sensor\" says {s['sensor']!r:.40}")
        A = checked_array(s, "A", (3, 3), at)
        checked_array(s, "c", (3,), at)
        if not np.linalg.cond(A) < COND_MAX:
            raise UserError(f"{at}: 'A' is singular (not invertible): no calibration maps "
                            "counts so")
        if need_scale or "lsb_per_unit" in s:
            if "lsb_per_unit" not in s:
                raise UserError(f"{at}: no 'lsb_per_unit'")
            _positive(s, "lsb_per_unit", at)
        if s.get("field_gauss") is not None:
            _positive(s, "field_gauss", at)
        _check_temperature(s.get("temperature"), at)
        calibrated += 1
    if not calibrated:
        raise UserError(f"{where}: no calibrated sensor (accel, gyro or mag with A and c)")


def _check_temperature(t, where: str) -> None:
    if t is None:
        return
    if not isinstance(t, dict):
        raise UserError(f"{where}: \"temperature\" is not an object")
    at = f"{where}: temperature"
    for key in ("t_ref_c",):
        if key not in t:
            raise UserError(f"{at}: no {key!r}")
        if not _is_number(t[key]) or not math.isfinite(t[key]):
            raise UserError(f"{at}: {key!r} is not a finite number")
    checked_array(t, "range_c", (2,), at)
    if "offset_per_c" not in t:
        raise UserError(f"{at}: no 'offset_per_c'")
    for key in ("offset_per_c", "offset_per_c_std", "scale_per_c", "scale_per_c_std"):
        v = t.get(key)                      # null entries: not fitted (not identifiable)
        if v is not None and not (isinstance(v, list) and len(v) == 3 and all(
                x is None or _is_number(x) and math.isfinite(x) for x in v)):
            raise UserError(f"{at}: {key!r} is not 3 finite numbers (or nulls)")
    try:
        TempModel.from_json(t)
    except (KeyError, TypeError, ValueError) as e:
        raise UserError(f"{at}: {' '.join(str(e).split())[:200]}") from None
