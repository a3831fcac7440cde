"""Temperature in the simulator: the board's temperature after power-on
(``thermal``), each chip's own temperature (``chip_lag``), and what it does
to a sensor's output (``temperature``, linear; ``temperature_curve``,
quadratic; ``temperature_hysteresis``, an offset that differs between
warming and cooling).

``BoardModel.temperature_c`` (sim.model) is the one definition of the
board's temperature as a function of time: the ITG3200's die, which its
TEMP_OUT reads.  ``BoardModel.chip_temperature_c`` gives each chip's own
(the ADXL345 and the HMC5883L lag the ITG3200's die with a ``chip_lag``
term, else they are at the same temperature); the sensor terms read their
chip's from ``Ctx.temp_c``.  The lag is exact (``lagged_c``: the
first-order response to the analytic T(t), the chips at one temperature at
power-on), so samples do not depend on how times are split into blocks.
"""
from __future__ import annotations

import numpy as np

from .termbase import DEFAULT_TEMP_C, Param, Term

HYSTERESIS_STEP_S = 0.5   # the history of a chip's temperature is followed on this grid


class Thermal(Term):
    """The board's temperature (what the ITG3200's sensor reads and every
    chip on the board follows): a warm-up after power-on plus slow room
    changes.  t = seconds since power-on (the session's start)."""
    id = "thermal"
    level = "board"
    sensors = ()
    summary = ("board temperature T(t) = ambient_c + rise_c (1 - exp(-t/tau_s)) "
               "+ room_slope_c_per_h t/3600 + room_amp_c sin(2 pi t/room_period_s); "
               "t = s since power-on (session start)")
    params = (Param("ambient_c", (), DEFAULT_TEMP_C, "degC", "room temperature at power-on"),
              Param("rise_c", (), 0.0, "degC", "warm-up: self-heating rise after power-on"),
              Param("tau_s", (), 300.0, "s", "warm-up time constant", positive=True),
              Param("room_slope_c_per_h", (), 0.0, "degC/h", "slow linear room change"),
              Param("room_amp_c", (), 0.0, "degC", "amplitude of a slow room cycle"),
              Param("room_period_s", (), 3600.0, "s", "period of that cycle", positive=True))

    def is_null(self):
        return not (float(self.p["rise_c"]) or float(self.p["room_slope_c_per_h"])
                    or float(self.p["room_amp_c"])) and \
            float(self.p["ambient_c"]) == DEFAULT_TEMP_C

    def temperature_c(self, t) -> np.ndarray:
        t = np.maximum(np.asarray(t, float), 0.0)
        p = self.p
        return (float(p["ambient_c"]) + float(p["rise_c"]) * (1.0 - np.exp(-t / float(p["tau_s"])))
                + float(p["room_slope_c_per_h"]) * t / 3600.0
                + float(p["room_amp_c"]) * np.sin(2 * np.pi * t / float(p["room_period_s"])))

    def lagged_c(self, t, lag_s: float) -> np.ndarray:
        """The temperature of a body that follows T(t) through a first-order
        lag of time constant ``lag_s`` (dy/dt = (T - y) / lag_s), at T(0) at
        power-on: each part of T(t) has a closed form (the warm-up's two
        exponentials, the ramp's delay, the cycle's damped, delayed copy and
        its transient).  ``lag_s`` 0 is T(t) itself."""
        lam = float(lag_s)
        if lam <= 0.0:
            return self.temperature_c(t)
        t = np.maximum(np.asarray(t, float), 0.0)
        p = self.p
        tau, rise = float(p["tau_s"]), float(p["rise_c"])
        el = np.exp(-t / lam)
        if abs(tau - lam) > 1e-9 * max(tau, lam):
            warm = 1.0 - (tau * np.exp(-t / tau) - lam * el) / (tau - lam)
        else:
            warm = 1.0 - (1.0 + t / tau) * np.exp(-t / tau)
        k = float(p["room_slope_c_per_h"]) / 3600.0
        w = 2 * np.pi / float(p["room_period_s"])
        wl = w * lam
        cyc = (np.sin(w * t) - wl * np.cos(w * t) + wl * el) / (1.0 + wl * wl)
        return (float(p["ambient_c"]) + rise * warm + k * (t - lam * (1.0 - el))
                + float(p["room_amp_c"]) * cyc)


class ChipLag(Term):
    """Each chip's own temperature: the ITG3200's die is the board
    temperature (``thermal``; its TEMP_OUT reads it), the ADXL345's and the
    HMC5883L's dies follow it through a first-order lag of their own."""
    id = "chip_lag"
    level = "board"
    sensors = ()
    summary = ("the ADXL345 and the HMC5883L follow the ITG3200's die temperature (the board's, "
               "which TEMP_OUT reads) through first-order lags: dT_chip/dt = (T - T_chip) / tau")
    params = (Param("accel_tau_s", (), 0.0, "s", "the ADXL345's time constant (0: no lag)"),
              Param("mag_tau_s", (), 0.0, "s", "the HMC5883L's time constant (0: no lag)"))

    def check(self):
        for k in ("accel_tau_s", "mag_tau_s"):
            if not float(self.p[k]) >= 0.0:
                raise ValueError(f"{k} must be >= 0")

    def tau(self, sensor: str) -> float:
        """The chip's lag behind the ITG3200's die (s); the gyro's is 0."""
        return float(self.p.get(f"{sensor}_tau_s", 0.0))

    def is_null(self):
        return not (float(self.p["accel_tau_s"]) or float(self.p["mag_tau_s"]))


class Temperature(Term):
    id = "temperature"
    summary = ("x = x (1 + scale_per_c dT) + offset_per_c dT, dT = board temperature - t_ref_c "
               "(the board's ``thermal`` term; 25 C without one)")
    params = (Param("offset_per_c", (3,), 0.0, "counts/degC",
                    "offset (zero-rate / zero-g) change per degree C"),
              Param("scale_per_c", (3,), 0.0, "1/degC", "relative sensitivity change per degree C"),
              Param("t_ref_c", (), DEFAULT_TEMP_C, "degC", "temperature where the term is zero"))

    def apply(self, x, ctx):
        T = ctx.temp_c if ctx.temp_c is not None else np.full(len(x), DEFAULT_TEMP_C)
        dT = (T - float(self.p["t_ref_c"]))[:, None]
        return x * (1.0 + self.p["scale_per_c"] * dT) + self.p["offset_per_c"] * dT

    def is_null(self):
        return not (np.any(self.p["offset_per_c"]) or np.any(self.p["scale_per_c"]))


def _dT(ctx, t_ref) -> np.ndarray:
    T = ctx.temp_c if ctx.temp_c is not None else np.full(len(ctx.t), DEFAULT_TEMP_C)
    return (T - float(t_ref))[:, None]


class TemperatureCurve(Term):
    id = "temperature_curve"
    summary = ("x = x (1 + scale_per_c2 dT^2) + offset_per_c2 dT^2, dT = the chip's temperature "
               "- t_ref_c: the bend of an offset or gain over temperature (listed with "
               "``temperature``)")
    params = (Param("offset_per_c2", (3,), 0.0, "counts/degC^2", "offset's curvature"),
              Param("scale_per_c2", (3,), 0.0, "1/degC^2", "relative sensitivity's curvature"),
              Param("t_ref_c", (), DEFAULT_TEMP_C, "degC", "temperature where the term is zero"))

    def apply(self, x, ctx):
        d2 = _dT(ctx, self.p["t_ref_c"]) ** 2
        return x * (1.0 + self.p["scale_per_c2"] * d2) + self.p["offset_per_c2"] * d2

    def is_null(self):
        return not (np.any(self.p["offset_per_c2"]) or np.any(self.p["scale_per_c2"]))


class TemperatureHysteresis(Term):
    """An offset that depends on where the chip's temperature came from: a
    play (backlash) operator of width ``band_c`` on the chip's temperature
    history gives the state s in [-1, 1] (+1 once the chip has warmed by
    ``band_c`` since it last cooled, -1 once it has cooled by as much), and
    x += offset_c s."""
    id = "temperature_hysteresis"
    summary = ("x += offset_c s, s in [-1, 1] the play operator (width band_c) on the chip's "
               "temperature history: +1 warming, -1 cooling; state0 = s at power-on")
    params = (Param("offset_c", (3,), 0.0, "counts",
                    "half the difference between the offsets on the warming and the cooling "
                    "branch"),
              Param("band_c", (), 2.0, "degC",
                    "the temperature change that takes the offset from one branch to the other",
                    positive=True),
              Param("state0", (), -1.0, "1", "s at power-on: -1 a board that cooled down "
                    "since it was last used, +1 one that warmed up to where it is"))

    def check(self):
        if not -1.0 <= float(self.p["state0"]) <= 1.0:
            raise ValueError("state0 must be within -1..1")

    def is_null(self):
        return not np.any(self.p["offset_c"])

    def runtime(self, key, trajectory, board):
        return _HysteresisRun(self, board)


class _HysteresisRun:
    """The play operator followed on a grid of ``HYSTERESIS_STEP_S`` from
    power-on (a pure function of time: the same samples for any split)."""

    def __init__(self, term, board):
        self.p = term.p
        self.w = 0.5 * float(term.p["band_c"])
        self.z = None            # the play's centre at grid points 0, 1, ...
        self.temp_of = None

    def _temp(self, t):
        f = self.temp_of
        return f(t) if f is not None else np.full(np.shape(t), DEFAULT_TEMP_C)

    def _grid(self, k_max):
        if self.z is None:
            T0 = float(self._temp(np.zeros(1))[0])
            self.z = [T0 - float(self.p["state0"]) * self.w]
        n = len(self.z)
        if k_max < n:
            return
        T = self._temp(np.arange(n, k_max + 1) * HYSTERESIS_STEP_S)
        z, w = self.z[-1], self.w
        for Tk in T:
            z = min(max(z, Tk - w), Tk + w)
            self.z.append(z)

    def state(self, t, temp_of=None) -> np.ndarray:
        """s at times ``t`` for the chip temperature ``temp_of`` (t -> C; the
        first one given is kept)."""
        if self.temp_of is None:
            self.temp_of = temp_of
        t = np.maximum(np.asarray(t, float), 0.0)
        k = np.floor(t / HYSTERESIS_STEP_S).astype(np.int64)
        self._grid(int(k.max()) if len(k) else 0)
        T = self._temp(t)
        z = np.clip(np.asarray(self.z)[k], T - self.w, T + self.w)
        return (T - z) / self.w

    def apply(self, x, ctx):
        return x + self.p["offset_c"] * self.state(ctx.t, ctx.temp_of)[:, None]


class GridLag:
    """A first-order lag (time constant ``lag_s``) of any temperature
    function ``f`` (t -> C; e.g. a measured one), at f(0) at power-on:
    followed on a grid of ``step_s`` (exact for f linear between grid
    points, cached) and interpolated."""

    def __init__(self, f, lag_s: float, step_s: float = 0.25):
        self.f, self.lag, self.h = f, float(lag_s), float(step_s)
        self.y = None

    def __call__(self, t) -> np.ndarray:
        t = np.maximum(np.asarray(t, float), 0.0)
        if not len(t):
            return np.zeros(0)
        u = t / self.h
        k = np.floor(u).astype(np.int64)
        need = int(k.max()) + 2
        if self.y is None:
            self.T = np.asarray(self.f(np.zeros(1)), float).reshape(1)
            self.y = self.T.copy()
        n = len(self.y)
        if need > n:
            T = np.concatenate([self.T, np.asarray(self.f(np.arange(n, need) * self.h), float)])
            a = np.exp(-self.h / self.lag)
            b = 1.0 / (1.0 - a) - self.lag / self.h        # weight of the newer point
            y = list(self.y)
            for i in range(n, need):
                y.append(a * y[-1] + (1 - a) * ((1 - b) * T[i - 1] + b * T[i]))
            self.T, self.y = T, np.asarray(y)
        fr = u - k
        return self.y[k] * (1 - fr) + self.y[k + 1] * fr
