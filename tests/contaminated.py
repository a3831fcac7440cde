"""Contaminated simulated sessions for the robust fit's tests and
bench/bench_robust.py (issue 25): a board of a built-in model with the
simulator's ``glitch`` and ``disturbed_stretch`` terms (sim/contamination.py)
planted, and its clean twin (the same board, trajectory and noise without
them).  The truth is the planted board's physical truth and the planted
readings as the terms give them, never a fit's.

* ``sweep``: a magnetometer sweep (the simulator's rotation, ``n`` readings
  at 125 Hz, labelled a rotation), glitches of ``size`` (a fraction of the
  field, radial: the magnitude is off by exactly that) in a fraction ``rate``
  of the readings, and a stretch of ``stretch_s`` seconds in a field off by
  ``stretch`` of its magnitude;
* ``poses``: a paper-sized static session (80 poses of 200 samples, no
  sweep) whose accelerometer has ``bumps`` stretches of ``bump_s`` seconds
  off by ``bump_g`` (a knock in a pose), and whose gyroscope has glitches.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np

from motecal.sessions.session import LABEL_ROT, SessionData
from motecal.sim import SimModel, load_model, make_trajectory
from motecal.sim.physics import K_NOMINAL

RATE_HZ = 125.0


@dataclass
class Planted:
    data: SessionData
    truth: dict                  # the board's physical truth (affine maps)
    field: float                 # gauss
    glitched: np.ndarray         # per row: a planted glitch (the sensor it is planted in)
    stretched: np.ndarray        # per row: inside a planted stretch


def _model(base: str, sensor_terms: dict) -> SimModel:
    d = copy.deepcopy(load_model(base).to_json())
    for sensor, (first, last) in sensor_terms.items():
        t = d["defaults"][sensor]["terms"]
        d["defaults"][sensor]["terms"] = list(first) + t + list(last)
    return SimModel.from_json(d, f"{base}+contaminated")


def _planted_rows(board, traj, seed, t, sensor):
    """Rows each contamination term of ``sensor`` changes (the terms' own
    draws, read back from the simulator: the truth of what was planted)."""
    s = board.sampler(traj, seed)
    runs = s.chain[sensor][0]
    idx = np.arange(len(t))
    glitched = np.zeros(len(t), bool)
    stretched = np.zeros(len(t), bool)
    for run in runs:
        if type(run).__name__ == "_GlitchRun":
            glitched |= run.which(idx)[0]
        elif type(run).__name__ == "_StretchRun":
            stretched |= run.window(t) > 0
    return glitched, stretched


def sweep(seed: int, rate: float = 0.03, size=(0.1, 0.5), stretch_s: float = 1.0,
          stretch: float = 0.12, n: int = 5000, base: str = "general",
          clean: bool = False) -> Planted:
    """A magnetometer sweep with glitches and a disturbed stretch (module
    doc); ``clean``: the same board and readings without them."""
    B = load_model(base).environment.field_gauss
    first = []
    if not clean and stretch_s > 0 and stretch:
        first.append({"term": "disturbed_stretch", "size": stretch * B,
                      "duration_s": float(stretch_s)})
    if not clean and rate > 0:
        first.append({"term": "glitch", "rate": float(rate), "size_min": size[0] * B,
                      "size_max": size[1] * B, "radial": 1})
    model = _model(base, {"mag": (first, [])})
    board = model.board(1, seed)
    traj = make_trajectory("rotation", seed, duration=n / model.rate_hz, rate_hz=model.rate_hz)
    t = board.sample_times(traj.duration)[:n]
    raw = board.sampler(traj, seed).read(t).astype(float)
    raw[:, :6] = np.nan                                    # a magnetometer sweep
    g, s = _planted_rows(board, traj, seed, t, "mag")
    m = len(t)
    data = SessionData(
        name=f"sweep-seed{seed}", raw=raw, mote=np.ones(m, np.int32),
        seq=np.arange(m, dtype=np.int64), t=t, label=np.full(m, LABEL_ROT, np.int32),
        flags=np.zeros(m, np.uint8), kind="rotation",
        meta={"source": "sim", "rate_hz": model.rate_hz, "seed": int(seed)})
    return Planted(data, board.physical_truth(), B, g, s)


def poses(seed: int, bumps: int = 3, bump_s: float = 0.3, bump_g: float = 0.4,
          gyro_rate: float = 0.0, gyro_size_dps=(20.0, 80.0), n_poses: int = 80,
          per_pose_s: float = 1.6, base: str = "general", clean: bool = False,
          move_knock=None) -> Planted:
    """A static session (no sweep) with knocks in some poses' accelerometer
    readings and glitches in the gyroscope's (module doc); ``move_knock``
    (deg/s, s): the gyroscope off by that much for that long in the middle
    of the move after pose ``n_poses // 2`` (a knock while turning); ``clean``:
    the same board and readings without them."""
    traj = make_trajectory("static80", seed, n_poses=n_poses, still_s=per_pose_s,
                           rate_hz=RATE_HZ)
    acc_first = []
    gyro_last = []
    if not clean:
        rng = np.random.default_rng([seed, 0xB0B])
        still = [p for p in range(1, n_poses + 1)]
        for p in rng.choice(still, bumps, replace=False):
            t0 = float(traj.t0[2 * (p - 1)]) if hasattr(traj, "t0") else None
            acc_first.append({"term": "disturbed_stretch", "size": bump_g, "duration_s": bump_s,
                              "start_s": t0 + 0.3 * per_pose_s})
        if gyro_rate > 0:
            gyro_last.append({"term": "glitch", "rate": gyro_rate, "size_min": gyro_size_dps[0],
                              "size_max": gyro_size_dps[1]})
        if move_knock is not None:
            k = n_poses // 2
            t_move = 0.5 * (float(traj.t0[2 * k - 1]) + float(traj.t0[2 * k]))
            gyro_last.append({"term": "disturbed_stretch", "size": float(move_knock[0]),
                              "duration_s": float(move_knock[1]), "start_s": t_move})
    model = _model(base, {"accel": (acc_first, []), "gyro": ([], gyro_last)})
    board = model.board(1, seed)
    t = board.sample_times(traj.duration)
    raw = board.sampler(traj, seed).read(t).astype(float)
    ga, sa = _planted_rows(board, traj, seed, t, "accel")
    gg, _ = _planted_rows(board, traj, seed, t, "gyro")
    m = len(t)
    data = SessionData(
        name=f"poses-seed{seed}", raw=raw, mote=np.ones(m, np.int32),
        seq=np.arange(m, dtype=np.int64), t=t, label=traj.label_at(t),
        flags=np.zeros(m, np.uint8), kind="static80",
        meta={"source": "sim", "rate_hz": model.rate_hz, "seed": int(seed)})
    return Planted(data, board.physical_truth(), 1.0, gg, sa)


def field_counts(field: float) -> float:
    return field * K_NOMINAL["mag"]
