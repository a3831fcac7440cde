"""Forward sensor physics of the simulator: terms, noise, chip stage, sampler.

Per sensor and sample::

    u  physical input        accel: specific force (g, body)
                             gyro:  angular rate (deg/s, body)
                             mag:   Earth field (gauss, body) = R.T @ B_world
    x = K * u                nominal counts (K from motecal.sessions.session)
    x = term_n(...term_1(x)) the sensor's terms, in list order
    x += noise * N(0, 1)     white noise, per-axis sigma in counts (added just
                             before the first ``saturation`` term if there is one,
                             so that clipping includes the noise)
    raw = chip(x)            round, datasheet range / overflow code -> int16

Every term is a small class with its parameters (name, shape, default,
unit): the sensors' static and motion terms below, the temperature terms in
``thermal``, the magnetic field's in ``field``, all on the base of
``termbase`` and collected in ``TERMS``.  ``model.py`` reads them from
JSON; this module runs them, vectorised over samples.  Terms that need
random numbers draw them from counter-based streams (``NormalStream``) keyed
by the run seed, the mote and the term's position, so a ``BoardSampler``
gives the same samples however the times are split into blocks.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from ..sessions.session import CHIP_LIMITS, HMC5883L_OVERFLOW, SENSOR_SLICES
from .field import FieldDisturbance, FieldDrift
from .termbase import (DEFAULT_TEMP_C, K_NOMINAL, REQUIRED, SENSORS, Ctx,  # noqa: F401
                       NormalStream, Param, SineProcess, Term, seed_key)
from .thermal import (ChipLag, GridLag, Temperature, TemperatureCurve, TemperatureHysteresis,
                      Thermal)
from .trajectory import Motion, Trajectory

_SALT = 0x5E5A0B
_INTERNAL_BLOCK = 16384            # samples evaluated at once (bounds memory)


# --------------------------------------------------------------------------
# environment
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class Environment:
    """Where the rig is.  World frame x north, y west, z up."""
    gravity_g: float = 1.0          # magnitude of the gravity reaction, g
    field_gauss: float = 0.48       # total Earth field, gauss
    inclination_deg: float = 60.0   # dip below the horizon (positive: field points down)
    declination_deg: float = 0.0    # east of true north (positive: towards -y)

    def field_world(self) -> np.ndarray:
        inc, dec = np.radians(self.inclination_deg), np.radians(self.declination_deg)
        h = self.field_gauss * np.cos(inc)
        return np.array([h * np.cos(dec), -h * np.sin(dec), -self.field_gauss * np.sin(inc)])

    def to_json(self) -> dict:
        return {"gravity_g": self.gravity_g, "field_gauss": self.field_gauss,
                "inclination_deg": self.inclination_deg,
                "declination_deg": self.declination_deg}


def _diag3(v):
    return np.diag(np.asarray(v, float))


class ScaleOffset(Term):
    id = "scale_offset"
    summary = "the seed paper's model X = (X' + o) s, forward x' = x / s - o"
    params = (Param("s", (3,), 1.0, "1", "scale factor per axis (about 1)", positive=True),
              Param("o", (3,), 0.0, "counts", "offset per axis"))

    def apply(self, x, ctx):
        return x / self.p["s"] - self.p["o"]

    def affine(self):
        return _diag3(1.0 / self.p["s"]), -self.p["o"]

    def is_null(self):
        return np.all(self.p["s"] == 1) and not np.any(self.p["o"])


class PaperAngles(Term):
    id = "paper_angles"
    summary = ("the seed paper's angles (eqs. 1-5): y' = y / cos(aZY), "
               "z' = z / (cos(aXZ) cos(aYZ)); only a re-parametrisation of scale")
    params = (Param("aZY", (), 0.0, "deg", "angle between Z and Y axes (divides y)"),
              Param("aXZ", (), 0.0, "deg", "angle between X and Z axes (divides z)"),
              Param("aYZ", (), 0.0, "deg", "angle between Y and Z axes (divides z)"))

    def check(self):
        for k in ("aZY", "aXZ", "aYZ"):
            if not abs(float(self.p[k])) < 80.0:
                raise ValueError(f"{k} must be within +-80 deg")

    def _d(self):
        c = np.cos(np.radians([self.p["aZY"], self.p["aXZ"], self.p["aYZ"]]))
        return np.array([1.0, 1.0 / c[0], 1.0 / (c[1] * c[2])])

    def apply(self, x, ctx):
        return x * self._d()

    def affine(self):
        return np.diag(self._d()), np.zeros(3)

    def is_null(self):
        return not any(float(self.p[k]) for k in ("aZY", "aXZ", "aYZ"))


class CrossAxis(Term):
    id = "cross_axis"
    summary = "x = (I + C) x, C off-diagonal: non-orthogonality, soft iron"
    params = (Param("C", (3, 3), "zeros", "1",
                    "coupling: row = output axis, column = input axis; diagonal ignored (0)"),)

    def check(self):
        C = np.array(self.p["C"], float)
        np.fill_diagonal(C, 0.0)
        self.p["C"] = C

    def apply(self, x, ctx):
        return x + x @ self.p["C"].T

    def affine(self):
        return np.eye(3) + self.p["C"], np.zeros(3)

    def is_null(self):
        return not np.any(self.p["C"])


class Linear(Term):
    id = "linear"
    summary = "x = M x + b: any 3x3 map plus offset"
    params = (Param("M", (3, 3), "identity", "1", "matrix (row = output axis)"),
              Param("b", (3,), 0.0, "counts", "offset added after M"))

    def apply(self, x, ctx):
        return x @ self.p["M"].T + self.p["b"]

    def affine(self):
        return np.array(self.p["M"], float), np.array(self.p["b"], float)

    def is_null(self):
        return np.array_equal(self.p["M"], np.eye(3)) and not np.any(self.p["b"])


class Nonlinearity(Term):
    id = "nonlinearity"
    summary = ("per axis with r = x/K: x += K (q r^2 + c3 r^3), then x *= 1 + a sign(x)")
    params = (Param("q", (3,), 0.0, "1", "quadratic coefficient (in units of full reading)"),
              Param("c3", (3,), 0.0, "1", "cubic coefficient"),
              Param("a", (3,), 0.0, "1", "asymmetric scale: +a for x > 0, -a for x < 0"))

    def apply(self, x, ctx):
        r = x / ctx.K
        x = x + ctx.K * (self.p["q"] * r * r + self.p["c3"] * r * r * r)
        return x * (1.0 + self.p["a"] * np.sign(x))

    def is_null(self):
        return not (np.any(self.p["q"]) or np.any(self.p["c3"]) or np.any(self.p["a"]))


class BiasDrift(Term):
    id = "bias_drift"
    summary = ("x += amplitude (1 - exp(-t/tau_s)) + slope t + random walk "
               "(sigma counts/sqrt(s)); t = s since session start")
    params = (Param("amplitude", (3,), 0.0, "counts", "settling (warm-up) amplitude"),
              Param("tau_s", (), 300.0, "s", "settling time constant", positive=True),
              Param("slope", (3,), 0.0, "counts/s", "linear drift"),
              Param("sigma", (3,), 0.0, "counts/sqrt(s)", "random-walk intensity"))

    def is_null(self):
        return not (np.any(self.p["amplitude"]) or np.any(self.p["slope"])
                    or np.any(self.p["sigma"]))

    def runtime(self, key, trajectory, board):
        return _BiasDriftRun(self, key)


class _BiasDriftRun:
    def __init__(self, term, key):
        self.term = term
        self.p = term.p
        self.stream = NormalStream(key, 3)
        self.t_last = 0.0
        self.w = np.zeros(3)

    def apply(self, x, ctx):
        t = np.maximum(ctx.t, 0.0)
        dt = np.diff(np.concatenate([[self.t_last], t])).clip(min=0.0)
        w = self.w + np.cumsum(self.p["sigma"] * np.sqrt(dt)[:, None]
                               * self.stream.get(ctx.index), axis=0)
        self.w = w[-1].copy()
        self.t_last = max(self.t_last, float(t[-1]))
        det = (self.p["amplitude"] * (1.0 - np.exp(-t / self.p["tau_s"]))[:, None]
               + self.p["slope"] * t[:, None])
        return x + det + w


class GSensitivity(Term):
    id = "g_sensitivity"
    sensors = ("gyro",)
    summary = "gyro only: x += K_gyro G a (a = specific force in g, body)"
    params = (Param("G", (3, 3), "zeros", "deg/s per g", "row = gyro axis, column = accel axis"),)

    def apply(self, x, ctx):
        return x + ctx.K * ctx.motion.specific_force @ self.p["G"].T

    def is_null(self):
        return not np.any(self.p["G"])


class Saturation(Term):
    id = "saturation"
    summary = ("clip to [low, high] counts per axis; optional overflow_code on all three "
               "axes when any clips; the white noise is added just before the first "
               "saturation term, so a clipped axis reads exactly its limit")
    params = (Param("low", (3,), -32768.0, "counts", "lowest value per axis"),
              Param("high", (3,), 32767.0, "counts", "highest value per axis"),
              Param("overflow_code", (), None, "counts",
                    "value written on all three axes when any axis clips (null: none)",
                    nullable=True))

    def check(self):
        if np.any(self.p["low"] > self.p["high"]):
            raise ValueError("low must be <= high")

    def apply(self, x, ctx):
        lo, hi = self.p["low"], self.p["high"]
        clipped = (x < lo) | (x > hi)
        x = np.clip(x, lo, hi)
        code = self.p["overflow_code"]
        if code is not None:
            x[clipped.any(axis=1)] = float(code)
        return x

    def is_null(self):
        return False


class StaleSamples(Term):
    id = "stale_samples"
    summary = ("sample-and-hold: the sensor updates at update_hz (own phase); reads in "
               "between repeat the last value; acts on the whole sensor, wherever listed")
    params = (Param("update_hz", (), REQUIRED, "Hz", "output data rate of the sensor",
                    positive=True),
              Param("phase_s", (), None, "s",
                    "time of the first update after t=0 (null: random from the run seed)",
                    nullable=True))

    def check(self):
        ph = self.p["phase_s"]
        if ph is not None and not 0.0 <= float(ph) < 1.0 / float(self.p["update_hz"]):
            raise ValueError("phase_s must be in [0, 1/update_hz)")


class MotionTerm(Term):
    id = "motion"
    level = "board"
    sensors = ()
    summary = ("board tremor: the board turns by a small random angle about each body axis "
               "(rms_deg, band 0..bandwidth_hz) on top of the rig's motion; all sensors see it")
    params = (Param("rms_deg", (), 0.0, "deg", "rms tremor angle about each body axis"),
              Param("bandwidth_hz", (), 3.0, "Hz", "tremor frequencies are uniform in "
                    "(0.1, bandwidth_hz]", positive=True))

    def is_null(self):
        return not float(self.p["rms_deg"])

    def runtime(self, key, trajectory, board):
        rng = np.random.default_rng(key)
        k = 8
        fmax = float(self.p["bandwidth_hz"])
        freqs = rng.uniform(min(0.1, fmax / 2), fmax, (3, k))
        return _Tremor(SineProcess(rng, np.radians(float(self.p["rms_deg"])), freqs))


class _Tremor:
    def __init__(self, proc):
        self.proc = proc

    def apply_motion(self, m: Motion, t) -> Motion:
        """Board motion = rig motion followed by a small body rotation exp([phi]x)."""
        phi, dphi = self.proc(t, deriv=True)
        D = Rotation.from_rotvec(phi).as_matrix()                 # body' -> body
        DT = np.transpose(D, (0, 2, 1))
        R = m.R @ D
        w = np.radians(m.omega)
        # right Jacobian to first order: I - [phi]x / 2
        wd = dphi - 0.5 * np.cross(phi, dphi)
        omega = np.einsum("nij,nj->ni", DT, w) + wd
        f = np.einsum("nij,nj->ni", DT, m.specific_force)
        return Motion(R=R, omega=np.degrees(omega), label=m.label, specific_force=f,
                      pose=m.pose)


TERMS = {cls.id: cls for cls in (ScaleOffset, PaperAngles, CrossAxis, Linear, Nonlinearity,
                                 BiasDrift, GSensitivity, Saturation, StaleSamples, MotionTerm,
                                 FieldDisturbance, FieldDrift, Thermal, ChipLag, Temperature,
                                 TemperatureCurve, TemperatureHysteresis)}


# --------------------------------------------------------------------------
# chip stage
# --------------------------------------------------------------------------
def chip_stage(sensor: str, x: np.ndarray) -> np.ndarray:
    """Datasheet output: round to integer counts; ADXL345 full resolution +-16 g
    (-4096..4095), ITG3200 int16, HMC5883L -2048..2047 per axis and -4096 on
    all three axes when any axis is out of range."""
    x = np.rint(x)
    lo, hi = CHIP_LIMITS[sensor]
    if sensor == "mag":
        bad = ((x < lo) | (x > hi)).any(axis=1) | np.isnan(x).any(axis=1)
        x = np.where(bad[:, None], HMC5883L_OVERFLOW, x)
    else:
        x = np.clip(np.nan_to_num(x, nan=0.0), lo, hi)
    return x.astype(np.int16)


def physical_input(sensor: str, m: Motion, field_world: np.ndarray) -> np.ndarray:
    if sensor == "accel":
        return m.specific_force
    if sensor == "gyro":
        return m.omega
    return np.einsum("nji,j->ni", m.R, field_world)


# --------------------------------------------------------------------------
# the sampler
# --------------------------------------------------------------------------
@dataclass
class SampleDetail:
    counts: np.ndarray      # (n, 9) int16, what the mote reads
    pre_chip: np.ndarray    # (n, 9) float counts after terms and noise
    nominal: np.ndarray     # (n, 9) float K*u (ideal sensor)
    motion: Motion          # the board's motion (with tremor) at the read times


class BoardSampler:
    """Reads one board along a trajectory.  ``read(t)`` takes true times
    (seconds since session start), non-decreasing over successive calls."""

    def __init__(self, board, trajectory: Trajectory, seed: int):
        self.board = board
        self.trajectory = trajectory
        self.env: Environment = board.environment
        self.field_world = self.env.field_world()
        base = seed_key(_SALT, seed, board.mote_id)
        self.tremor = None
        # the board temperature (the ITG3200's die): replaceable by a measured one
        # (diagnose.compare's twin), which the chips then follow through their lags
        self.temperature_c = self._own_temperature_c = board.temperature_c
        self._given = (None, {})
        for j, term in enumerate(board.board_terms):
            if isinstance(term, MotionTerm) and not term.is_null():
                self.tremor = term.runtime(base + [9, j], trajectory, board)
        self.chain = {}
        for si, name in enumerate(SENSORS):
            sm = board.sensors[name]
            runs, stale = [], None
            for j, term in enumerate(sm.terms):
                if isinstance(term, StaleSamples):
                    ph = term.p["phase_s"]
                    f = float(term.p["update_hz"])
                    if ph is None:
                        ph = np.random.default_rng(base + [si, 100 + j]).uniform(0, 1 / f)
                    stale = (f, float(ph))
                elif not term.is_null():
                    runs.append(term.runtime(base + [si, 1 + j], trajectory, board))
            self.chain[name] = (runs, stale, NormalStream(base + [si, 0], 3),
                                np.asarray(sm.noise, float))
        self._n = 0
        self._t_last = -np.inf

    def chip_temperature(self, sensor: str):
        """t -> the temperature of ``sensor``'s chip: the board's own
        (``BoardModel.chip_temperature_c``), or, once ``temperature_c`` has
        been given a measured temperature, that one through the chip's lag
        (``thermal.GridLag``)."""
        f = self.temperature_c
        if f is self._own_temperature_c:
            own = getattr(self.board, "chip_temperature_c", None)
            return (lambda t: own(sensor, t)) if own is not None else f
        if self._given[0] is not f:
            self._given = (f, {})
        lags = self._given[1]
        if sensor not in lags:
            lag = getattr(self.board, "chip_lag", None)
            tau = lag.tau(sensor) if lag is not None else 0.0
            lags[sensor] = GridLag(f, tau) if tau > 0 else f
        return lags[sensor]

    def _motion(self, t) -> Motion:
        m = self.trajectory.at(t, self.env.gravity_g)
        if self.tremor is not None:
            m = self.tremor.apply_motion(m, t)
        return m

    def read(self, t) -> np.ndarray:
        """(n, 9) int16 counts ax ay az gx gy gz mx my mz at true times t."""
        return self.read_detail(t).counts

    def read_detail(self, t) -> SampleDetail:
        """Like read(), also returning the float stages (advances the same state)."""
        t = np.atleast_1d(np.asarray(t, np.float64))
        if len(t) and (t[0] < self._t_last or np.any(np.diff(t) < 0)):
            raise ValueError("read() times must not decrease")
        if not len(t):
            e9 = np.empty((0, 9))
            return SampleDetail(np.empty((0, 9), np.int16), e9, e9,
                                Motion(np.empty((0, 3, 3)), np.empty((0, 3)),
                                       np.empty(0, np.int32), np.empty((0, 3)), np.empty(0)))
        parts = [self._read_block(t[i:i + _INTERNAL_BLOCK])
                 for i in range(0, len(t), _INTERNAL_BLOCK)]
        if len(parts) == 1:
            return parts[0]
        cat = lambda name: np.concatenate([getattr(p, name) for p in parts])  # noqa: E731
        ms = [p.motion for p in parts]
        motion = Motion(*(np.concatenate([getattr(m, f) for m in ms])
                          for f in ("R", "omega", "label", "specific_force", "pose")))
        return SampleDetail(cat("counts"), cat("pre_chip"), cat("nominal"), motion)

    def _read_block(self, t) -> SampleDetail:
        n = len(t)
        counts = np.empty((n, 9), np.int16)
        pre = np.empty((n, 9))
        nominal = np.empty((n, 9))
        m_now = self._motion(t)
        read_index = self._n + np.arange(n)
        for name in SENSORS:
            runs, stale, stream, sigma = self.chain[name]
            if stale is None:
                ts, idx, m, expand = t, read_index, m_now, slice(None)
            else:
                # evaluate once per sensor update; reads in between repeat it
                f, ph = stale
                k = np.floor((t - ph) * f)
                uk, expand = np.unique(k, return_inverse=True)
                ts = ph + uk / f
                idx = (uk + 1).astype(np.int64)
                m = self._motion(ts)
            K = K_NOMINAL[name]
            x = K * physical_input(name, m, self.field_world)
            sl = SENSOR_SLICES[name]
            nominal[:, sl] = x[expand]
            temp_of = self.chip_temperature(name)
            ctx = Ctx(sensor=name, K=K, t=ts, index=idx, motion=m, field_world=self.field_world,
                      temp_c=temp_of(ts), temp_of=temp_of)
            noised = not np.any(sigma)
            for run in runs:
                if not noised and isinstance(run, Saturation):
                    x = x + sigma * stream.get(idx)          # the noise is clipped too
                    noised = True
                x = run.apply(x, ctx)
            if not noised:
                x = x + sigma * stream.get(idx)
            pre[:, sl] = x[expand]
            counts[:, sl] = chip_stage(name, x)[expand]
        self._n += n
        if n:
            self._t_last = float(t[-1])
        return SampleDetail(counts, pre, nominal, m_now)
