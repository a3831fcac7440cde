"""The simulator's model file: environment, per-board error terms, truth files.

A model is JSON (``motecal sim --model FILE`` or a built-in name)::

    {"format": "motecal-sim-model", "version": 1, "name": "...", "rate_hz": 125.0,
     "environment": {"gravity_g": 1.0, "field_gauss": 0.48,
                     "inclination_deg": 60, "declination_deg": 0},
     "defaults": BOARD,              # template for boards not listed
     "boards": {"1": BOARD, ...}}    # explicit boards by mote id

    BOARD  = {"clock_ppm": V, "terms": [board terms], "accel": SENSOR,
              "gyro": SENSOR, "mag": SENSOR}
    SENSOR = {"noise": V3, "terms": [{"term": ID, PARAM: V, ...}, ...]}

Any value V may be a number, a list of the parameter's shape, or a
distribution ``{"uniform": [lo, hi]}`` / ``{"normal": [mean, sd]}`` (drawn per
element, deterministically from the run seed and the mote id).  A
``"comment"`` key is allowed (and ignored) in every object.  Terms and their
parameters are defined in ``physics.py`` (see docs/simulator-model.md).
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..errors import UserError
from ..line import protocol as P
from .physics import (DEFAULT_TEMP_C, K_NOMINAL, REQUIRED, SENSORS, TERMS, BoardSampler,
                      Environment, GSensitivity, Saturation, StaleSamples, Term, Thermal,
                      seed_key)
from . import mismatch
from .thermal import ChipLag
from .trajectory import Trajectory
from . import contamination  # noqa: F401,E402 - registers glitch and disturbed_stretch in TERMS

MODEL_FORMAT = "motecal-sim-model"
MODEL_VERSION = 1
MODELS_DIR = Path(__file__).resolve().parent / "models"
DEFAULT_MODEL = "general"
_DRAW_SALT = 0xB0A2D
CLOCK_PPM_MAX = 1000.0     # a 32 kHz crystal is off by tens of ppm; beyond this is a typo
_DISTS = ("uniform", "normal")


def builtin_models() -> list[str]:
    """The model files of ``models/`` and the mismatch suite's models (sim.mismatch)."""
    return sorted([p.stem for p in MODELS_DIR.glob("*.json")] + list(mismatch.NAMES))


class _Invalid(Exception):
    """Internal: a validation failure at ``where``."""

    def __init__(self, where: str, msg: str):
        super().__init__(f"{where}: {msg}" if where else msg)


# --------------------------------------------------------------------------
# values and distributions
# --------------------------------------------------------------------------
def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _check_spec(v, shape: tuple, where: str, nullable: bool = False):
    """Validate a value spec for a parameter of that shape (no drawing)."""
    if v is None:
        if nullable:
            return
        raise _Invalid(where, "must not be null")
    if _is_number(v):
        return
    if isinstance(v, dict):
        keys = [k for k in v if k != "comment"]
        if len(keys) != 1 or keys[0] not in _DISTS:
            raise _Invalid(where, 'a distribution is {"uniform": [lo, hi]} or '
                                  '{"normal": [mean, sd]}')
        a = v[keys[0]]
        if not (isinstance(a, list) and len(a) == 2 and all(_is_number(x) for x in a)):
            raise _Invalid(where, f"{keys[0]} needs two numbers")
        if keys[0] == "uniform" and a[0] > a[1]:
            raise _Invalid(where, "uniform needs lo <= hi")
        if keys[0] == "normal" and a[1] < 0:
            raise _Invalid(where, "normal needs sd >= 0")
        return
    if isinstance(v, list):
        if not shape:
            raise _Invalid(where, "must be a number, not a list")
        if len(v) != shape[0]:
            raise _Invalid(where, f"must have {shape[0]} elements, not {len(v)}")
        for i, e in enumerate(v):
            _check_spec(e, shape[1:], f"{where}[{i}]")
        return
    raise _Invalid(where, f"must be a number, a list or a distribution, not {v!r}")


def _draw(v, shape: tuple, rng: np.random.Generator):
    """A value spec (already checked) -> float array of that shape (or None)."""
    if v is None:
        return None
    if _is_number(v):
        return np.full(shape, float(v)) if shape else np.float64(v)
    if isinstance(v, dict):
        kind = next(k for k in v if k != "comment")
        a, b = v[kind]
        x = rng.uniform(a, b, shape) if kind == "uniform" else rng.normal(a, b, shape)
        return x if shape else np.float64(x)
    return np.array([_draw(e, shape[1:], rng) for e in v], float)


def _check_clock(ppm: float, where: str) -> None:
    if not abs(ppm) <= CLOCK_PPM_MAX:
        raise _Invalid(where, f"must be within +-{CLOCK_PPM_MAX:g} ppm (a crystal's error), "
                              f"not {ppm:g}")


def _default_value(prm):
    if prm.default is None:
        return None
    if prm.default == "zeros":
        return np.zeros(prm.shape)
    if prm.default == "identity":
        return np.eye(3)
    return np.full(prm.shape, float(prm.default)) if prm.shape else np.float64(prm.default)


def _obj(d, where, allowed, what="object"):
    if not isinstance(d, dict):
        raise _Invalid(where, f"must be a JSON {what}")
    extra = [k for k in d if k not in allowed and k != "comment"]
    if extra:
        raise _Invalid(where, f"unknown key {extra[0]!r} (expected {', '.join(allowed)})")
    return d


# --------------------------------------------------------------------------
# templates: parsed, checked JSON that draws concrete boards
# --------------------------------------------------------------------------
class _TermTemplate:
    def __init__(self, d, level: str, sensor: str | None, where: str):
        if not isinstance(d, dict) or not isinstance(d.get("term"), str):
            raise _Invalid(where, 'a term is an object {"term": ID, ...}')
        tid = d["term"]
        where = f"{where} ({tid})"
        cls = TERMS.get(tid)
        if cls is None:
            raise _Invalid(where, f"unknown term (expected one of {', '.join(TERMS)})")
        if cls.level != level:
            raise _Invalid(where, "is a board-level term: list it in the board's \"terms\""
                           if cls.level == "board" else
                           "is a sensor term: list it under accel, gyro or mag")
        if sensor is not None and sensor not in cls.sensors:
            raise _Invalid(where, f"applies to {', '.join(cls.sensors)} only, not {sensor}")
        names = [p.name for p in cls.params]
        for k in d:
            if k not in names and k not in ("term", "comment"):
                raise _Invalid(where, f"unknown parameter {k!r} (expected "
                                      f"{', '.join(names) or 'none'})")
        for prm in cls.params:
            if prm.name in d:
                _check_spec(d[prm.name], prm.shape, f"{where}.{prm.name}", prm.nullable)
            elif prm.default is REQUIRED:
                raise _Invalid(where, f"missing parameter {prm.name!r}")
        self.cls, self.d, self.where = cls, d, where

    def draw(self, rng) -> Term:
        vals = {}
        for prm in self.cls.params:
            v = _draw(self.d[prm.name], prm.shape, rng) if prm.name in self.d \
                else _default_value(prm)
            if v is not None and prm.positive and not np.all(np.asarray(v) > 0):
                raise _Invalid(f"{self.where}.{prm.name}", "must be > 0")
            vals[prm.name] = v
        try:
            return self.cls(vals)
        except ValueError as e:
            raise _Invalid(self.where, str(e)) from None


class _SensorTemplate:
    def __init__(self, d, sensor: str, where: str):
        d = _obj({} if d is None else d, where, ("noise", "terms"))
        _check_spec(d.get("noise", 0.0), (3,), f"{where}.noise")
        terms = d.get("terms", [])
        if not isinstance(terms, list):
            raise _Invalid(f"{where}.terms", "must be a list")
        self.terms = [_TermTemplate(t, "sensor", sensor, f"{where}.terms[{i}]")
                      for i, t in enumerate(terms)]
        if sum(t.cls is StaleSamples for t in self.terms) > 1:
            raise _Invalid(f"{where}.terms", "at most one stale_samples term")
        self.d = d
        self.where = where

    def draw(self, rng) -> "SensorModel":
        noise = _draw(self.d.get("noise", 0.0), (3,), rng)
        if np.any(noise < 0):
            raise _Invalid(f"{self.where}.noise", "must be >= 0")
        return SensorModel(noise, [t.draw(rng) for t in self.terms])


class _BoardTemplate:
    def __init__(self, d, where: str):
        d = _obj(d, where, ("clock_ppm", "terms") + SENSORS)
        clock = d.get("clock_ppm", 0.0)
        _check_spec(clock, (), f"{where}.clock_ppm")
        bounds = [clock] if _is_number(clock) else \
            clock.get("uniform", clock.get("normal", [0.0])[:1])
        for v in bounds:
            _check_clock(v, f"{where}.clock_ppm")
        terms = d.get("terms", [])
        if not isinstance(terms, list):
            raise _Invalid(f"{where}.terms", "must be a list")
        self.terms = [_TermTemplate(t, "board", None, f"{where}.terms[{i}]")
                      for i, t in enumerate(terms)]
        self.sensors = {s: _SensorTemplate(d.get(s), s, f"{where}.{s}") for s in SENSORS}
        self.d = d
        self.where = where

    def draw(self, mote_id: int, seed: int, env: Environment, rate_hz: float) -> "BoardModel":
        rng = np.random.default_rng(seed_key(_DRAW_SALT, seed, mote_id))
        clock = float(_draw(self.d.get("clock_ppm", 0.0), (), rng))
        _check_clock(clock, f"{self.where}.clock_ppm")       # a normal draw's tail
        bterms = [t.draw(rng) for t in self.terms]
        sensors = {s: self.sensors[s].draw(rng) for s in SENSORS}
        return BoardModel(mote_id, clock, bterms, sensors, env, rate_hz)


# --------------------------------------------------------------------------
# concrete boards
# --------------------------------------------------------------------------
class SensorModel:
    def __init__(self, noise, terms: list[Term]):
        self.noise = np.asarray(noise, float).reshape(3)
        self.terms = list(terms)

    def to_json(self) -> dict:
        return {"noise": self.noise.tolist(), "terms": [t.to_json() for t in self.terms]}


class BoardModel:
    """One simulated board with concrete parameters."""

    def __init__(self, mote_id: int, clock_ppm: float, board_terms: list[Term],
                 sensors: dict[str, SensorModel], environment: Environment,
                 rate_hz: float = 125.0):
        self.mote_id = int(mote_id)
        self.clock_ppm = float(clock_ppm)
        self.board_terms = list(board_terms)
        self.sensors = sensors
        self.environment = environment
        self.rate_hz = float(rate_hz)

    @property
    def thermal(self) -> Thermal | None:
        """The board's ``thermal`` term (its temperature), None without one."""
        return next((t for t in self.board_terms if isinstance(t, Thermal)), None)

    def temperature_c(self, t) -> np.ndarray:
        """The board temperature (degrees C) at ``t`` seconds since power-on
        (the session's start): its ``thermal`` term, else a constant 25 C."""
        th = self.thermal
        t = np.asarray(t, float)
        return th.temperature_c(t) if th is not None else np.full(t.shape, DEFAULT_TEMP_C)

    @property
    def chip_lag(self) -> ChipLag | None:
        """The board's ``chip_lag`` term (each chip's own lag), None without one."""
        return next((t for t in self.board_terms if isinstance(t, ChipLag)), None)

    def chip_temperature_c(self, sensor: str, t) -> np.ndarray:
        """The temperature of ``sensor``'s chip at ``t``: the ITG3200's die is
        the board temperature (``temperature_c``); the ADXL345 and the
        HMC5883L follow it through their ``chip_lag`` time constants (the
        same temperature without that term)."""
        lag = self.chip_lag
        tau = lag.tau(sensor) if lag is not None else 0.0
        th = self.thermal
        if th is None or tau <= 0.0:
            return self.temperature_c(t)
        return th.lagged_c(np.asarray(t, float), tau)

    def temperature_reading_c(self, t) -> np.ndarray:
        """What the ITG3200's temperature sensor reads at ``t``: the board
        temperature rounded to its raw TEMP_OUT counts (280 LSB per degree C),
        in degrees C (protocol.temp_c of the integer reading)."""
        return P.temp_c(np.rint(P.temp_raw(self.temperature_c(t))))

    def sampler(self, trajectory: Trajectory, seed: int) -> BoardSampler:
        return BoardSampler(self, trajectory, seed)

    def sample_times(self, duration: float, start: float = 0.0) -> np.ndarray:
        """True times (s since session start) of the mote's nominal rate_hz samples
        from ``start`` up to ``duration``: a mote whose clock runs ``clock_ppm``
        fast takes sample i at start + i / (rate_hz (1 + clock_ppm 1e-6))."""
        eff = self.rate_hz * (1.0 + self.clock_ppm * 1e-6)
        n = max(0, int(math.ceil((duration - start) * eff - 1e-9)))
        return start + np.arange(n) / eff

    def to_json(self) -> dict:
        d = {"clock_ppm": self.clock_ppm, "terms": [t.to_json() for t in self.board_terms]}
        d.update({s: self.sensors[s].to_json() for s in SENSORS})
        return d

    def physical_truth(self) -> dict:
        """Per sensor the equivalent linear map ``raw = M K u + b`` of its affine
        terms (scale_offset, paper_angles, cross_axis, linear), composed in
        list order.  For the gyro ``G`` (deg/s per g) is the g-sensitivity as
        it appears at the output: ``raw = M K w + b + K G a``.  ``exact`` is
        False when a term that is not affine and not null is present (listed
        in ``nonaffine``); saturation and stale samples do not count."""
        out = {}
        for s in SENSORS:
            K = K_NOMINAL[s]
            A, c, Gc = np.eye(3), np.zeros(3), np.zeros((3, 3))
            nonaff = []
            for t in self.sensors[s].terms:
                aff = t.affine()
                if aff is not None:
                    At, ct = aff
                    A, c, Gc = At @ A, At @ c + ct, At @ Gc
                elif isinstance(t, GSensitivity):
                    Gc = Gc + K * t.p["G"]
                elif not isinstance(t, (Saturation, StaleSamples)) and not t.is_null():
                    nonaff.append(t.id)
            d = {"K": K, "M": A.tolist(), "b": c.tolist(), "exact": not nonaff,
                 "nonaffine": nonaff, "noise": self.sensors[s].noise.tolist()}
            if s == "gyro":
                d["G"] = (Gc / K).tolist()
            out[s] = d
        return out

    def __repr__(self):
        return f"<BoardModel mote={self.mote_id} clock_ppm={self.clock_ppm:+.1f}>"


# --------------------------------------------------------------------------
# the model
# --------------------------------------------------------------------------
class SimModel:
    """A parsed model file: environment, defaults template, explicit boards."""

    def __init__(self, name: str, rate_hz: float, environment: Environment,
                 defaults: _BoardTemplate | None, boards: dict[int, _BoardTemplate]):
        self.name = name
        self.rate_hz = float(rate_hz)
        self.environment = environment
        self._defaults = defaults
        self._boards = boards

    def board(self, mote_id: int, seed: int) -> BoardModel:
        """The board on mote ``mote_id``: explicit if listed, else drawn from
        ``defaults`` with (seed, mote_id)."""
        tpl = self._boards.get(int(mote_id), self._defaults)
        if tpl is None:
            raise UserError(f"model {self.name}: no board {mote_id} and no \"defaults\" "
                            f"to draw it from")
        try:
            return tpl.draw(int(mote_id), int(seed), self.environment, self.rate_hz)
        except _Invalid as e:
            raise UserError(f"model {self.name}: {e}") from None

    def to_json(self) -> dict:
        d = {"format": MODEL_FORMAT, "version": MODEL_VERSION, "name": self.name,
             "rate_hz": self.rate_hz, "environment": self.environment.to_json()}
        if self._defaults is not None:
            d["defaults"] = self._defaults.d
        d["boards"] = {str(k): self._boards[k].d for k in sorted(self._boards)}
        return d

    def with_boards(self, boards: dict) -> "SimModel":
        """A copy with these explicit boards added or replaced: mote id ->
        BoardModel or board JSON (values or distributions)."""
        d = self.to_json()
        d["boards"] = dict(d["boards"])
        for m, b in boards.items():
            d["boards"][str(int(m))] = b.to_json() if isinstance(b, BoardModel) else b
        return SimModel.from_json(d, self.name)

    @classmethod
    def from_json(cls, d, source: str = "<model>") -> "SimModel":
        try:
            return cls._from_json(d, source)
        except _Invalid as e:
            raise UserError(f"model {source}: {e}") from None

    @classmethod
    def _from_json(cls, d, source):
        _obj(d, "", ("format", "version", "name", "description", "rate_hz", "environment",
                     "defaults", "boards", "truth"))
        if d.get("format") != MODEL_FORMAT:
            raise _Invalid("format", f"must be {MODEL_FORMAT!r}")
        if d.get("version") != MODEL_VERSION:
            raise _Invalid("version", f"must be {MODEL_VERSION}, not {d.get('version')!r}")
        rate = d.get("rate_hz", 125.0)
        if not _is_number(rate) or rate <= 0:
            raise _Invalid("rate_hz", "must be a number > 0")
        e = _obj(d.get("environment", {}), "environment",
                 ("gravity_g", "field_gauss", "inclination_deg", "declination_deg"))
        for k, v in e.items():
            if k != "comment" and not _is_number(v):
                raise _Invalid(f"environment.{k}", "must be a number")
        env = Environment(**{k: float(v) for k, v in e.items() if k != "comment"})
        if not -90 <= env.inclination_deg <= 90:
            raise _Invalid("environment.inclination_deg", "must be within -90..90")
        if env.gravity_g < 0 or env.field_gauss < 0:
            raise _Invalid("environment", "gravity_g and field_gauss must be >= 0")
        defaults = (_BoardTemplate(d["defaults"], "defaults") if d.get("defaults") is not None
                    else None)
        boards = {}
        braw = d.get("boards", {})
        if not isinstance(braw, dict):
            raise _Invalid("boards", "must be an object keyed by mote id")
        for k, v in braw.items():
            if k == "comment":
                continue
            try:
                mote = int(k)
            except (TypeError, ValueError):
                raise _Invalid("boards", f"key {k!r} is not a mote id") from None
            if not 0 <= mote <= 0xFFFF:
                raise _Invalid("boards", f"mote id {mote} outside 0..65535")
            boards[mote] = _BoardTemplate(v, f"boards.{k}")
        if defaults is None and not boards:
            raise _Invalid("", "needs \"defaults\" or at least one board in \"boards\"")
        name = d.get("name", source)
        if not isinstance(name, str):
            raise _Invalid("name", "must be a string")
        model = cls(name, rate, env, defaults, boards)
        # draw once so that value errors (e.g. a scale <= 0) show at load time
        for m, tpl in list(boards.items()) + ([(1, defaults)] if defaults else []):
            tpl.draw(m, 0, env, rate)
        return model


def load_model(path_or_name: str | Path | None) -> SimModel:
    """A built-in model by name (``paper``, ``general``, ``full``, ``thermal``,
    the mismatch suite's ``mismatch`` and ``mismatch-<block>``) or a model
    file; None gives ``general``.  Raises UserError with one line on a
    missing, unreadable or invalid file."""
    if path_or_name is None:
        path_or_name = DEFAULT_MODEL
    src = str(path_or_name)
    path = Path(src)
    if not path.exists() and src in mismatch.NAMES:
        return SimModel.from_json(mismatch.model_json(src), src)
    if not path.exists() and src in builtin_models():
        path = MODELS_DIR / f"{src}.json"
    if not path.is_file():
        raise UserError(f"model {src!r}: no such file and not a built-in model "
                        f"({', '.join(builtin_models())})")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise UserError(f"model {src}: cannot read: {getattr(e, 'strerror', None) or e}") \
            from None
    try:
        d = json.loads(text)
    except json.JSONDecodeError as e:
        raise UserError(f"model {src}: invalid JSON: {e.msg} at line {e.lineno} "
                        f"column {e.colno}") from None
    return SimModel.from_json(d, src)


def write_truth(path, model: SimModel, boards: dict[int, BoardModel],
                trajectory: Trajectory, seed: int) -> dict:
    """Write the truth of a simulated run: the model with every simulated board
    written out explicitly (so the file is itself a valid ``--model`` that
    reproduces the same boards) plus ``truth``: seed, trajectory and each
    board's physical_truth().  Returns the JSON written."""
    d = model.to_json()
    d["boards"] = dict(d["boards"])
    for m, b in sorted(boards.items()):
        d["boards"][str(int(m))] = b.to_json()
    d["truth"] = {"seed": int(seed), "trajectory": trajectory.to_json(),
                  "physical_truth": {str(int(m)): b.physical_truth()
                                     for m, b in sorted(boards.items())}}
    try:
        Path(path).write_text(json.dumps(d, indent=1) + "\n", encoding="utf-8")
    except OSError as e:
        raise UserError(f"cannot write truth file {path}: {e.strerror or e}") from None
    return d
