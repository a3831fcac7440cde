"""The simulator: a rig trajectory, boards with error models, and (in the
transport modules) the motes, radio and BaseStation that carry their samples.

Sensor side (this package's ``trajectory``, ``physics``, ``model``)::

    traj = make_trajectory("static80", seed)          # one rig, all boards
    model = load_model("general")                     # or a file, or None
    board = model.board(mote_id, seed)                # explicit or drawn
    sampler = board.sampler(traj, seed)
    raw = sampler.read(board.sample_times(traj.duration))   # (n, 9) int16

``simulate_session`` does that for several motes without radio or loss.
"""
from __future__ import annotations

import numpy as np

from ..sessions.session import SessionData
from .model import (BoardModel, SimModel, builtin_models, load_model,  # noqa: F401
                    write_truth)
from .physics import Environment, BoardSampler, SampleDetail, chip_stage  # noqa: F401
from .trajectory import KINDS, Motion, Trajectory, make_trajectory  # noqa: F401


def simulate_session(kind: str, *, motes=(1,), seed: int = 0,
                     model: SimModel | str | None = None,
                     duration: float | None = None) -> dict[int, SessionData]:
    """Simulated sessions, one per mote, straight from the sensors (no radio,
    no loss): every nominal ``rate_hz`` sample of each mote (its clock drift
    applied: ``t`` is true time since session start), labels from the
    trajectory, raw counts.  ``seq`` = sample index, flags 0,
    ``meta["truth"]`` = the board's to_json(), plus ``physical_truth``,
    ``environment``, ``trajectory``, ``seed``, ``model`` and ``rate_hz``.
    A board with a ``thermal`` term also gives ``temp``: its temperature
    sensor's reading per row (``BoardModel.temperature_reading_c``); other
    boards' sessions have no temperature (None), as before."""
    if not isinstance(model, SimModel):
        model = load_model(model)
    traj = make_trajectory(kind, seed, duration=duration, rate_hz=model.rate_hz)
    traj_json = traj.to_json()
    out = {}
    for m in motes:
        board = model.board(int(m), seed)
        t = board.sample_times(traj.duration)
        raw = board.sampler(traj, seed).read(t)
        n = len(t)
        out[int(m)] = SessionData(
            name=f"sim-{kind}-seed{seed}-mote{int(m)}", raw=raw.astype(np.float64),
            mote=np.full(n, int(m), np.int32), seq=np.arange(n, dtype=np.int64), t=t,
            label=traj.label_at(t), flags=np.zeros(n, np.uint8), kind=kind,
            meta={"source": "sim", "rate_hz": model.rate_hz, "seed": int(seed),
                  "model": model.name, "truth": board.to_json(),
                  "physical_truth": board.physical_truth(),
                  "environment": model.environment.to_json(), "trajectory": traj_json},
            temp=board.temperature_reading_c(t) if board.thermal is not None else None)
    return out
