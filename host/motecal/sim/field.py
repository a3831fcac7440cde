"""The local magnetic field the magnetometer reads, as simulator terms:
``field_disturbance`` (a field that differs between static poses and wanders
within them) and ``field_drift`` (the field drifting slowly over the whole
session, in direction and magnitude).  Everything here acts in the world
frame (the field itself), so a term's effect on the readings turns with the
board.
"""
from __future__ import annotations

import numpy as np

from .termbase import NormalStream, Param, SineProcess, Term

DRIFT_STEP_S = 1.0     # the field's random walk is drawn on this grid, linear in between


class FieldDisturbance(Term):
    id = "field_disturbance"
    sensors = ("mag",)
    summary = ("mag only: the local field differs between poses (random world vector per pose) "
               "and wanders slowly within them (smooth random process, correlation tau_s)")
    params = (Param("pose_rms_gauss", (), 0.0, "gauss",
                    "rms per world axis of the per-pose field change"),
              Param("rms_gauss", (), 0.0, "gauss", "rms per world axis of the slow wander"),
              Param("tau_s", (), 10.0, "s", "correlation time of the wander", positive=True))

    def is_null(self):
        return not (float(self.p["pose_rms_gauss"]) or float(self.p["rms_gauss"]))

    def runtime(self, key, trajectory, board):
        return _FieldDisturbanceRun(self, key, trajectory)


class _FieldDisturbanceRun:
    def __init__(self, term, key, trajectory):
        rng = np.random.default_rng(key)
        n = max(1, trajectory.n_poses) + 1
        self.per_pose = rng.normal(0.0, float(term.p["pose_rms_gauss"]), (n, 3))
        k = 16
        # frequencies of an exponentially correlated process: |Cauchy(0, 1/(2 pi tau))|
        f = np.abs(rng.standard_cauchy((3, k))) / (2 * np.pi * float(term.p["tau_s"]))
        self.wander = SineProcess(rng, float(term.p["rms_gauss"]), f)

    def disturbance(self, t, pose):
        p = np.clip(pose, 0, len(self.per_pose) - 1)
        lo = np.floor(p).astype(int)
        hi = np.minimum(lo + 1, len(self.per_pose) - 1)
        fr = (p - lo)[:, None]
        return self.per_pose[lo] * (1 - fr) + self.per_pose[hi] * fr + self.wander(t)

    def apply(self, x, ctx):
        d = self.disturbance(ctx.t, ctx.motion.pose)          # world, gauss
        return x + ctx.K * np.einsum("nji,nj->ni", ctx.motion.R, d)


class FieldDrift(Term):
    id = "field_drift"
    sensors = ("mag",)
    summary = ("mag only: the local field (world frame) drifts over the session: "
               "d(t) = rate_gauss_per_h t/3600 + a random walk (sigma_gauss_per_sqrt_h per "
               "world axis); x += K R^T d; t = s since power-on")
    params = (Param("rate_gauss_per_h", (3,), 0.0, "gauss/h",
                    "steady change of the field per hour (world x north, y west, z up)"),
              Param("sigma_gauss_per_sqrt_h", (), 0.0, "gauss/sqrt(h)",
                    "random-walk intensity per world axis"))

    def is_null(self):
        return not (np.any(self.p["rate_gauss_per_h"]) or float(self.p["sigma_gauss_per_sqrt_h"]))

    def runtime(self, key, trajectory, board):
        return _FieldDriftRun(self, key)


class _FieldDriftRun:
    """The walk's value at grid point k is the sum of the first k steps
    (counter-based normals, cached), linear in between: a pure function of
    time, the same samples for any split of the reads."""

    def __init__(self, term, key):
        self.rate = np.asarray(term.p["rate_gauss_per_h"], float) / 3600.0
        self.step = float(term.p["sigma_gauss_per_sqrt_h"]) * np.sqrt(DRIFT_STEP_S / 3600.0)
        self.stream = NormalStream(key, 3)
        self.walk = np.zeros((1, 3))

    def drift(self, t) -> np.ndarray:
        t = np.maximum(np.asarray(t, float), 0.0)
        u = t / DRIFT_STEP_S
        k = np.floor(u).astype(np.int64)
        need = int(k.max()) + 2 if len(k) else 1
        n = len(self.walk)
        if need > n and self.step:
            inc = self.step * self.stream.get(np.arange(n - 1, need - 1))
            self.walk = np.vstack([self.walk, self.walk[-1] + np.cumsum(inc, axis=0)])
        out = self.rate * t[:, None]
        if self.step:
            fr = (u - k)[:, None]
            out = out + self.walk[k] * (1 - fr) + self.walk[k + 1] * fr
        return out

    def apply(self, x, ctx):
        return x + ctx.K * np.einsum("nji,nj->ni", ctx.motion.R, self.drift(ctx.t))
