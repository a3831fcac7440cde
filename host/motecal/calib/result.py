"""Calibration results: one ``SensorCalibration`` per sensor, one
``BoardCalibration`` per board (mote), and their JSON form (``cal.json``).

For every sensor ``calibrated = A @ raw_counts + c`` in the sensor's unit
(g, deg/s, gauss).  A sensor calibrated against temperature also carries a
``TempModel`` (format_version 2): with ``dT = clip(T, lo, hi) - t_ref``,
``calibrated = (1 + scale_per_c * dT) * (A @ raw_counts) + c + offset_per_c * dT``
(element-wise per axis; the scale term is zero where it was not identifiable).  Everything else (parameters with names, standard
deviations and units, errors before/after, magnitude ranges, validation, GA
trace, quality metrics) documents how that map was obtained.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import UserError
from ..jsonable import finite as _num, jsonable as _jsonable
from .templag import lag_filter

FORMAT_VERSION = 2      # 2: optional per-sensor temperature model (1 files still read)
SENSORS = ("accel", "gyro", "mag")


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
        return y * (1.0 + tm.scale_per_c * dt) + self.c + tm.offset_per_c * dt

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
    def from_json(cls, d: dict) -> "BoardCalibration":
        if not isinstance(d, dict) or "format_version" not in d:
            raise UserError("not a motecal calibration (no format_version)")
        if int(d["format_version"]) > FORMAT_VERSION:
            raise UserError(f"calibration format_version {d['format_version']} is newer than "
                            f"this motecal understands ({FORMAT_VERSION})")
        kw = {s: SensorCalibration.from_json(d[s]) if d.get(s) else None for s in SENSORS}
        return cls(mote=int(d["mote"]), session=d.get("session", ""), created=d.get("created", ""),
                   mag_sets=d.get("mag_sets", {}), gate=d.get("gate", {}),
                   settings=d.get("settings", {}), tool=d.get("tool", ""),
                   format_version=int(d["format_version"]), **kw)

    @classmethod
    def loads(cls, text: str) -> "BoardCalibration":
        try:
            d = json.loads(text)
        except json.JSONDecodeError as e:
            raise UserError(f"calibration file is not JSON: {e}") from None
        try:
            return cls.from_json(d)
        except (KeyError, TypeError, ValueError) as e:
            raise UserError(f"calibration file is malformed: {e!r}") from None

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
