"""Sessions people really record by hand (issue 13 part 3), for tests and the
bench (``import hand``): static poses held briefly (the paper's 1.6 s) with
moves between them that take *longer* than the holds, slow or fast, with or
without tremor; and a long one-orientation hold.  Built from the simulator's
own pieces (minimum-jerk moves between holds), then sampled like
``plant.simulate``."""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

import plant as P

from motecal.sessions.session import LABEL_ROT, SessionData
from motecal.sim.trajectory import PiecewiseTrajectory, _static_poses


def hand_trajectory(seed: int, n_poses: int = 24, hold_s: float = 1.6,
                    move_s: tuple = (2.0, 4.0), rate_hz: float = 125.0):
    """Holds of ``hold_s`` and moves of ``move_s`` (uniform, longer than the
    holds: "slow" 3-5 s, "fast" 0.6-1.0 s) between ``n_poses`` orientations
    spread over the sphere."""
    rng = np.random.default_rng([0x4A4D, seed])
    poses = _static_poses(rng, n_poses)
    t0, R0, rotvec, label, pose0, pose1 = [], [], [], [], [], []
    t = 0.0
    for k, Rk in enumerate(poses, start=1):
        hold = hold_s * float(rng.uniform(0.9, 1.2))
        t0.append(t); R0.append(Rk); rotvec.append(np.zeros(3)); label.append(k)
        pose0.append(k); pose1.append(k)
        t += hold
        if k < len(poses):
            v = Rotation.from_matrix(Rk.T @ poses[k]).as_rotvec()
            t0.append(t); R0.append(Rk); rotvec.append(v); label.append(0)
            pose0.append(k); pose1.append(k + 1)
            t += float(rng.uniform(*move_s))
    return PiecewiseTrajectory("static80", seed, t, rate_hz, t0=t0, R0=R0, rotvec=rotvec,
                               label=label, pose0=pose0, pose1=pose1, poses=poses)


def simulate(plants: list, traj, seed: int, *, labelled: bool = False, base: str = "paper",
             rot_labels: bool = False) -> SessionData:
    """One mote's session along ``traj`` with the planted effects (no
    saturation plants).  ``labelled``: the holds carry pose labels;
    ``rot_labels``: every row is labelled a rotation, as the importer's
    still-fraction rule labels such a recording."""
    model = P.planted_model(plants, base)
    board = model.board(1, seed)
    t = board.sample_times(traj.duration)
    raw = board.sampler(traj, seed).read(t).astype(float)
    n = len(t)
    label = traj.label_at(t) if labelled else np.zeros(n, np.int32)
    if rot_labels:
        label = np.full(n, LABEL_ROT, np.int32)
    return SessionData(
        name=f"hand-{model.name}-seed{seed}", raw=raw, mote=np.ones(n, np.int32),
        seq=np.arange(n, dtype=np.int64), t=t, label=label, flags=np.zeros(n, np.uint8),
        kind="static80" if labelled else "free",
        meta={"source": "sim", "rate_hz": model.rate_hz, "seed": int(seed), "model": model.name,
              "holds": len(traj.poses),
              "planted": [{"cause": p.cause, "sensor": p.sensor, "term": p.term}
                          for p in plants]})


HAND_KINDS = {
    # name: (hold_s, move_s, poses)
    "hand-slow": (1.6, (3.0, 5.0), 24),
    "hand-fast": (1.6, (0.6, 1.0), 30),
}


def session(kind: str, plants: list, seed: int, labelled: bool = False) -> SessionData:
    hold, move, n = HAND_KINDS[kind]
    return simulate(plants, hand_trajectory(seed, n, hold, move), seed, labelled=labelled)
