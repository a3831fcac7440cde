"""The local magnetic field the magnetometer reads, as simulator terms:
``field_disturbance`` (a field that differs between static poses and wanders
within them).  Everything here acts in the world frame (the field itself),
so a term's effect on the readings turns with the board.
"""
from __future__ import annotations

import numpy as np

from .termbase import Param, SineProcess, Term


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
