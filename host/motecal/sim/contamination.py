"""Contamination terms of the simulator: readings a calibration must not
believe (issue 25).  Real sweeps and poses are never clean: a few readings
glitch (an I2C read that raced the conversion, a bit flip), and for a
second or two the board is somewhere else than the model says (a desk leg
or a phone near the magnetometer, a knock on the accelerometer).

* ``glitch`` (any sensor): a fraction ``rate`` of the readings is off by a
  vector of random direction whose length is drawn uniformly from
  ``[size_min, size_max]`` (the sensor's unit: g, deg/s, gauss).  Which
  readings, and by how much, is a pure function of the run seed, the mote,
  the term's position and the reading's index (counter-based streams), so a
  session gives the same glitches however it is read in blocks.
* ``disturbed_stretch`` (any sensor): during ``[start_s, start_s +
  duration_s)`` the reading is off by a constant vector of length ``size``
  (the sensor's unit), with raised-cosine edges of ``ramp_s``.  For the
  magnetometer it is a field in the world frame (a magnet or a steel object
  near the place: it does not turn with the board); without a ``direction``
  it lies along the local field with a random sign, so ``size`` is the
  change of the field's magnitude -- the case a magnitude fit cannot tell
  from the direction.  For the accelerometer and gyroscope it is in the body
  frame (a bump, a knock), in a random direction unless given.
  ``start_s`` null: drawn uniformly over the trajectory.

Both are registered in ``physics.TERMS`` when this module is imported
(``sim.model`` imports it), documented in docs/simulator-model.md.  Neither
is affine: a board with one non-null has ``exact`` False in its physical
truth, whose ``M`` and ``b`` are still the map of its affine terms -- the
truth a robust calibration is judged against.
"""
from __future__ import annotations

import numpy as np
from scipy.special import ndtr

from .physics import NormalStream, Param, TERMS, Term


class Glitch(Term):
    id = "glitch"
    summary = ("a fraction `rate` of the readings off by a vector of random direction and a "
               "length uniform in [size_min, size_max] (sensor unit)")
    params = (Param("rate", (), 0.0, "1", "fraction of the readings that glitch (0..1)"),
              Param("size_min", (), 0.0, "unit", "smallest glitch (g, deg/s or gauss)"),
              Param("size_max", (), 0.0, "unit", "largest glitch (g, deg/s or gauss)"),
              Param("radial", (), 0.0, "1",
                    "1: along the reading with a random sign (its magnitude is off by the "
                    "size: the hardest case for a magnitude fit); 0: a random direction"))

    def check(self):
        if not 0.0 <= float(self.p["rate"]) <= 1.0:
            raise ValueError("rate must be within 0..1")
        if not 0.0 <= float(self.p["size_min"]) <= float(self.p["size_max"]):
            raise ValueError("need 0 <= size_min <= size_max")
        if float(self.p["radial"]) not in (0.0, 1.0):
            raise ValueError("radial must be 0 or 1")

    def is_null(self):
        return not (float(self.p["rate"]) and float(self.p["size_max"]))

    def runtime(self, key, trajectory, board):
        return _GlitchRun(self, key)


class _GlitchRun:
    def __init__(self, term, key):
        self.p = term.p
        self.stream = NormalStream(key, 5)       # pick, size, direction (3)

    def which(self, index, x=None) -> tuple[np.ndarray, np.ndarray]:
        """(glitched?, offset in the sensor's unit) per reading index (radial:
        along the readings ``x``)."""
        z = self.stream.get(index)
        hit = ndtr(z[:, 0]) < float(self.p["rate"])
        lo, hi = float(self.p["size_min"]), float(self.p["size_max"])
        size = lo + (hi - lo) * ndtr(z[:, 1])
        if float(self.p["radial"]) and x is not None:
            n = np.linalg.norm(x, axis=1, keepdims=True)
            d = np.sign(z[:, 2:3]) * np.divide(x, n, out=np.zeros_like(x), where=n > 0)
        else:
            d = z[:, 2:5] / np.linalg.norm(z[:, 2:5], axis=1, keepdims=True)
        return hit, np.where(hit[:, None], d * size[:, None], 0.0)

    def apply(self, x, ctx):
        _, off = self.which(ctx.index, x)
        return x + ctx.K * off


class DisturbedStretch(Term):
    id = "disturbed_stretch"
    summary = ("during [start_s, start_s + duration_s) the reading is off by a constant vector "
               "of length `size` (mag: a field, world frame; accel/gyro: body frame)")
    params = (Param("size", (), 0.0, "unit", "length of the disturbance (g, deg/s or gauss)"),
              Param("duration_s", (), 1.0, "s", "how long it lasts", positive=True),
              Param("start_s", (), None, "s",
                    "when it starts (null: drawn uniformly over the trajectory)", nullable=True),
              Param("ramp_s", (), 0.0, "s", "raised-cosine rise and fall inside the stretch"),
              Param("direction", (3,), None, "1",
                    "its direction (world frame for mag, body frame otherwise; null: mag along "
                    "the field with a random sign, else random)", nullable=True))

    def check(self):
        if float(self.p["ramp_s"]) < 0 or 2 * float(self.p["ramp_s"]) > float(self.p["duration_s"]):
            raise ValueError("need 0 <= 2 ramp_s <= duration_s")
        d = self.p["direction"]
        if d is not None and not np.linalg.norm(d) > 0:
            raise ValueError("direction must not be zero")

    def is_null(self):
        return not float(self.p["size"])

    def runtime(self, key, trajectory, board):
        return _StretchRun(self, key, trajectory, board)


class _StretchRun:
    def __init__(self, term, key, trajectory, board):
        p = term.p
        rng = np.random.default_rng(key)
        self.dur = float(p["duration_s"])
        self.ramp = float(p["ramp_s"])
        start = p["start_s"]
        u = rng.random()
        self.start = (float(start) if start is not None
                      else u * max(float(trajectory.duration) - self.dur, 0.0))
        d = p["direction"]
        sign = rng.choice([-1.0, 1.0])
        rnd = rng.standard_normal(3)
        self.direction = None if d is None else np.asarray(d, float) / np.linalg.norm(d)
        self.sign, self.rnd = float(sign), rnd / np.linalg.norm(rnd)
        self.size = float(p["size"])

    def window(self, t) -> np.ndarray:
        """0..1 per time: the stretch's profile."""
        s = (np.asarray(t, float) - self.start)
        inside = (s >= 0) & (s < self.dur)
        w = inside.astype(float)
        if self.ramp > 0:
            edge = np.minimum(s, self.dur - s) / self.ramp
            w = np.where(inside & (edge < 1), 0.5 - 0.5 * np.cos(np.pi * np.clip(edge, 0, 1)), w)
        return w

    def apply(self, x, ctx):
        w = self.window(ctx.t)
        if not w.any():
            return x
        if ctx.sensor == "mag":
            d = self.direction if self.direction is not None else \
                self.sign * ctx.field_world / np.linalg.norm(ctx.field_world)
            body = np.einsum("nji,j->ni", ctx.motion.R, d)         # world -> body
        else:
            body = np.broadcast_to(self.direction if self.direction is not None else self.rnd,
                                   x.shape)
        return x + ctx.K * self.size * w[:, None] * body


TERMS.update({cls.id: cls for cls in (Glitch, DisturbedStretch)})
