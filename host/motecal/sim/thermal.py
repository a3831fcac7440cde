"""Temperature in the simulator: the board's temperature after power-on
(``thermal``) and what it does to a sensor's output (``temperature``).

``BoardModel.temperature_c`` (sim.model) is the one definition of the
board's temperature as a function of time; the sensor terms read it from
their ``Ctx.temp_c``.
"""
from __future__ import annotations

import numpy as np

from .termbase import DEFAULT_TEMP_C, Param, Term


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
