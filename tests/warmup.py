"""Boards that warm up (issue 16), for tests and bench/bench_temperature.py.

``warmup_session``: one simulated board switched on and held still for a
warm-up (``hold_s``, labelled pose 1), then turned through the 80 static
poses (poses 2..81), with the ITG3200's temperature reading per row.

``thermal_error``: how far a calibration's output is, over a fresh warm-up
hold of the same board (switched on again, new noise), from what the same
board would give through the same calibration if its temperature had stayed
at the calibration's reference ``t_ref`` (and without noise): the
temperature's share of the error plus the noise of a 1 s average, per 1 s
block (the static calibration's own error at ``t_ref`` is in both and cancels).  Without compensation that is the drift;
with a perfect temperature model it is the noise floor
(``noise_floor``: the white noise of a 1 s average).  The truth comes from
what was planted (the twin board), never from the calibration.
"""
from __future__ import annotations

import copy

import numpy as np

from motecal.sessions.session import SessionData
from motecal.sim import SimModel, load_model, make_trajectory
from motecal.sim.physics import K_NOMINAL
from motecal.sim.trajectory import SequenceTrajectory

SL = {"accel": slice(0, 3), "gyro": slice(3, 6), "mag": slice(6, 9)}


def thermal_board(seed: int, mote: int = 1, model: str = "thermal", **thermal):
    """(model, board) drawn from the built-in ``thermal`` model, with the
    board's ``thermal`` term parameters overridden by ``thermal``."""
    m = load_model(model)
    b = m.board(mote, seed)
    if thermal:
        d = b.to_json()
        for t in d["terms"]:
            if t["term"] == "thermal":
                t.update(thermal)
        m = m.with_boards({mote: d})
        b = m.board(mote, seed)
    return m, b


def _session(board, traj, seed, name, kind="static80") -> SessionData:
    t = board.sample_times(traj.duration)
    raw = board.sampler(traj, seed).read(t).astype(float)
    n = len(t)
    return SessionData(name=name, raw=raw, mote=np.full(n, board.mote_id, np.int32),
                       seq=np.arange(n, dtype=np.int64), t=t, label=traj.label_at(t),
                       flags=np.zeros(n, np.uint8), kind=kind,
                       meta={"source": "sim", "rate_hz": board.rate_hz, "seed": int(seed),
                             "truth": board.to_json()},
                       temp=board.temperature_reading_c(t))


def warmup_session(board, seed: int, hold_s: float = 1200.0, n_poses: int = 80) -> SessionData:
    hold = make_trajectory("idle", seed, duration=hold_s)
    poses = make_trajectory("static80", seed + 1, n_poses=n_poses)
    traj = SequenceTrajectory("idle,static80", seed, None, board.rate_hz, parts=[hold, poses])
    return _session(board, traj, seed, f"warmup-seed{seed}")


def hold_session(board, seed: int, hold_s: float = 1200.0) -> SessionData:
    return _session(board, make_trajectory("idle", seed, duration=hold_s), seed,
                    f"hold-seed{seed}", kind="idle")


def twin(model: SimModel, board, t_ref: float, noise: bool = False):
    """The same board kept at ``t_ref`` degrees C (and without noise)."""
    d = copy.deepcopy(board.to_json())
    d["terms"] = [t for t in d["terms"] if t["term"] != "thermal"] + [
        {"term": "thermal", "ambient_c": float(t_ref)}]
    for s in ("accel", "gyro", "mag"):
        if not noise:
            d[s]["noise"] = [0.0, 0.0, 0.0]
    return model.with_boards({board.mote_id: d}).board(board.mote_id, 0)


def thermal_error(sc, model, board, seed: int, t_ref: float, hold_s: float = 1200.0,
                  compensated: bool = True) -> float:
    """rms over 1 s blocks and axes of (calibrated fresh hold) - (calibrated
    twin kept at ``t_ref``, no noise), in the sensor's unit."""
    traj = make_trajectory("idle", seed, duration=hold_s)
    t = board.sample_times(hold_s)
    raw = board.sampler(traj, seed).read(t).astype(float)
    tw = twin(model, board, t_ref).sampler(traj, seed).read_detail(t).pre_chip
    temp = board.temperature_reading_c(t)
    s = SL[sc.sensor]
    v = sc.apply(raw[:, s], temp if compensated else None)
    v0 = sc.apply(tw[:, s])
    n = int(board.rate_hz)
    k = len(t) // n
    d = (v[:k * n] - v0[:k * n]).reshape(k, n, 3).mean(axis=1)
    return float(np.sqrt(np.mean(d ** 2)))


def noise_floor(board, sensor: str) -> float:
    """rms over axes of the white noise of a 1 s average, in the unit."""
    sig = np.asarray(board.sensors[sensor].noise, float) / K_NOMINAL[sensor]
    return float(np.sqrt(np.mean(sig ** 2)) / np.sqrt(board.rate_hz))
