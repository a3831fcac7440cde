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
    """The same board kept at ``t_ref`` degrees C (and without noise).  All
    its chips are at ``t_ref`` (a lag changes nothing at a constant
    temperature); a ``temperature_hysteresis`` is on its warming branch
    (``state0`` +1): the board as the calibration saw it, warmed up to
    where it is."""
    d = copy.deepcopy(board.to_json())
    d["terms"] = [t for t in d["terms"] if t["term"] != "thermal"] + [
        {"term": "thermal", "ambient_c": float(t_ref)}]
    for s in ("accel", "gyro", "mag"):
        if not noise:
            d[s]["noise"] = [0.0, 0.0, 0.0]
        for t in d[s]["terms"]:
            if t["term"] == "temperature_hysteresis":
                t["state0"] = 1.0
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
    v = sc.apply(raw[:, s], temp if compensated else None, t)
    v0 = sc.apply(tw[:, s])
    n = int(board.rate_hz)
    k = len(t) // n
    d = (v[:k * n] - v0[:k * n]).reshape(k, n, 3).mean(axis=1)
    return float(np.sqrt(np.mean(d ** 2)))


def noise_floor(board, sensor: str) -> float:
    """rms over axes of the white noise of a 1 s average, in the unit."""
    sig = np.asarray(board.sensors[sensor].noise, float) / K_NOMINAL[sensor]
    return float(np.sqrt(np.mean(sig ** 2)) / np.sqrt(board.rate_hz))


# ---------------------------------------------------------------------------
# planted boards for the diagnosis' ``temperature`` cause
# ---------------------------------------------------------------------------
SPAN = 3.0
HOLD_S = 300.0


def _base(thermal: dict, sensor=None, term=None) -> SimModel:
    d = load_model("paper").to_json()
    d["defaults"]["terms"] = [dict({"term": "thermal"}, **thermal)]
    if term is not None:
        d["defaults"][sensor]["terms"].append(term)
    return SimModel.from_json(d, "paper+thermal" + (f"+{sensor}-{term['term']}" if term else ""))


def plant_temperature(sensor: str, rng, scale: float = 1.0) -> dict:
    """A board warming up (rise 6-12 C, time constant 3-8 min) with a
    temperature term on ``sensor`` of size threshold x log-uniform[1, SPAN]:
    gyro offset (one axis) in static80, accel offset (one axis) or mag
    sensitivity (all axes) in a 5-minute hold."""
    from motecal.diagnose.causes import THERMAL_THRESHOLDS
    kind, thr, _ = THERMAL_THRESHOLDS[("temperature", sensor)]
    poses = sensor.endswith("-poses")           # accel-poses: the 80 static poses
    sensor = sensor.split("-")[0]
    size = thr * float(np.exp(rng.uniform(0, np.log(SPAN)))) * scale
    sgn = float(rng.choice([-1.0, 1.0]))
    thermal = {"rise_c": round(float(rng.uniform(6, 12)), 3),
               "tau_s": round(float(rng.uniform(180, 480)), 1)}
    if sensor == "mag":
        term = {"term": "temperature", "scale_per_c": [sgn * size] * 3}
    else:
        v = [0.0, 0.0, 0.0]
        v[int(rng.integers(3))] = sgn * size
        term = {"term": "temperature", "offset_per_c": v}
    static = sensor == "gyro" or poses
    return {"cause": "temperature", "sensor": sensor, "size": size, "thermal": thermal,
            "term": term, "kind": "static80" if static else "idle",
            "duration": None if static else HOLD_S}


def plant_time_drift(sensor: str, rng, poses: bool = False) -> dict:
    """A drift that does not follow the temperature, on a warming board: the
    gyro's warm-up amplitude (5-15 counts) settling with 30-90 s in a static80
    whose temperature settles with 5-8 min; an accel or mag slope (0.015-0.045
    counts/s) in a 5-minute hold (``poses``: the accelerometer's static80)
    whose temperature settles within 40-100 s."""
    v = [0.0, 0.0, 0.0]
    a = int(rng.integers(3))
    sgn = float(rng.choice([-1.0, 1.0]))
    if sensor == "gyro":
        v[a] = sgn * 5.0 * float(np.exp(rng.uniform(0, np.log(SPAN))))
        term = {"term": "bias_drift", "amplitude": v, "tau_s": round(float(rng.uniform(30, 90)), 1)}
        thermal = {"rise_c": round(float(rng.uniform(6, 12)), 3),
                   "tau_s": round(float(rng.uniform(300, 480)), 1)}
    else:
        v[a] = sgn * 0.015 * float(np.exp(rng.uniform(0, np.log(SPAN))))
        term = {"term": "bias_drift", "slope": v}
        thermal = {"rise_c": round(float(rng.uniform(6, 12)), 3),
                   "tau_s": round(float(rng.uniform(40, 100)), 1)}
    static = sensor == "gyro" or poses
    return {"cause": "bias_drift", "sensor": sensor, "thermal": thermal, "term": term,
            "kind": "static80" if static else "idle", "duration": None if static else HOLD_S}


def plant_clean(kind: str, rng) -> dict:
    """A warming board with no temperature coefficient and no drift."""
    return {"cause": None, "sensor": None, "term": None, "kind": kind,
            "thermal": {"rise_c": round(float(rng.uniform(6, 12)), 3),
                        "tau_s": round(float(rng.uniform(180, 480)), 1)},
            "duration": None if kind == "static80" else HOLD_S}


def simulate_plant(p: dict, seed: int) -> SessionData:
    m = _base(p["thermal"], p["sensor"], p["term"])
    b = m.board(1, seed)
    traj = make_trajectory(p["kind"], seed, duration=p["duration"])
    ses = _session(b, traj, seed, f"{m.name}-{p['kind']}-seed{seed}", kind=p["kind"])
    ses.meta["planted"] = p
    ses.meta["board"] = b
    ses.meta["trajectory_obj"] = traj
    return ses


def true_coef(ses: SessionData, sensor: str) -> np.ndarray:
    """The planted temperature slope of the still readings (counts/C per
    axis): the offset, plus the gain times the noise-free reading (from the
    planted board and the trajectory, not from the data)."""
    p = ses.meta["planted"]
    b = ses.meta["board"]
    term = p["term"]
    o = np.asarray(term.get("offset_per_c", [0.0] * 3), float)
    k = np.asarray(term.get("scale_per_c", [0.0] * 3), float)
    if not np.any(k):
        return o
    pt = b.physical_truth()[sensor]
    traj = ses.meta["trajectory_obj"]
    m = traj.at(np.array([ses.t[len(ses.t) // 2]]), b.environment.gravity_g)
    u = {"accel": m.specific_force[0], "gyro": m.omega[0],
         "mag": m.R[0].T @ b.environment.field_world()}[sensor]
    x = np.asarray(pt["M"]) @ (pt["K"] * u) + np.asarray(pt["b"])
    return o + k * x


def hold_errors(bc, model, board, seed: int, hold_s: float = 1200.0, mote_c=None) -> dict:
    """``thermal_error`` for every sensor of ``bc`` with a temperature model
    on one fresh hold: ``{sensor: {"uncompensated", "compensated", "floor",
    "mote" (the C correction, when ``mote_c(bc, raw, temp_raw_per_row)``
    is given: its output in the unit; from the second second on, once the
    mote has its first second's mean -- the first second, at single
    readings, is ``mote_first_s``)}}``.  The twin is kept at each
    sensor's ``t_ref``."""
    traj = make_trajectory("idle", seed, duration=hold_s)
    t = board.sample_times(hold_s)
    raw = board.sampler(traj, seed).read(t).astype(float)
    temp = board.temperature_reading_c(t)
    n = int(board.rate_hz)
    k = len(t) // n
    twins = {}
    mote = mote_c(bc, raw, temp) if mote_c is not None else None
    out = {}
    for name, sc in bc.sensors():
        if sc.temperature is None:
            continue
        tr = round(sc.temperature.t_ref_c, 6)
        if tr not in twins:
            twins[tr] = twin(model, board, tr).sampler(traj, seed).read_detail(t).pre_chip
        s = SL[name]
        v0 = sc.apply(twins[tr][:, s])

        def err(v, first=0, last=k):
            d = (v[:k * n] - v0[:k * n]).reshape(k, n, 3).mean(axis=1)[first:last]
            return float(np.sqrt(np.mean(d ** 2)))
        has_mote = mote is not None and name in mote
        out[name] = {"uncompensated": err(sc.apply(raw[:, s])),
                     "compensated": err(sc.apply(raw[:, s], temp, t)),
                     "floor": noise_floor(board, name),
                     "mote": err(mote[name], 1) if has_mote else None,
                     "mote_first_s": err(mote[name], 0, 1) if has_mote else None}
    return out
