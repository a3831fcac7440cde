"""Paper-sized simulated boards for tests and the benchmark, and the accuracy
measure on fresh directions.

``paper_sized_session`` runs the simulator (``motecal.sim``) for one board:
80 static poses of 200 samples at 125 Hz (16000 accelerometer and gyroscope
samples, as in the paper) followed by a 5000-sample rotation, merged into one
session (the rotation labelled ``LABEL_ROT``).  ``accel_noise_mg`` overrides
the accelerometer white noise of the chosen simulator model.

``vector_error`` is the accuracy figure: rms over fresh, evenly spread
directions of |calibrated - true| for noise-free readings, compared in the
frame the calibration defines (the true map is decomposed with the same
lower-triangular gauge, so an arbitrary rotation of the sensor frame is not
counted as error).
"""
from __future__ import annotations

import copy

import numpy as np

from motecal.calib.models import lower_factor
from motecal.maths.sphere import unit
from motecal.sessions.session import SessionData

PAPER_POSES = 80
PAPER_PER_POSE = 200
PAPER_SWEEP = 5000


def _model(name: str, accel_noise_mg: float | None):
    from motecal.sim import SimModel, load_model
    m = load_model(name)
    if accel_noise_mg is None:
        return m
    d = copy.deepcopy(m.to_json()) if hasattr(m, "to_json") else None
    if d is None:
        raise ValueError("simulator model cannot be modified")
    d.setdefault("defaults", {}).setdefault("accel", {})["noise"] = \
        float(accel_noise_mg) * 1e-3 * 256.0
    return SimModel.from_json(d, f"{name} (accel noise {accel_noise_mg:g} mg)")


def paper_sized_session(seed: int = 0, model: str = "general", *,
                        accel_noise_mg: float | None = 10.0, rotation: bool = True,
                        n_poses: int = PAPER_POSES, per_pose: int = PAPER_PER_POSE,
                        mote: int = 1) -> SessionData:
    """One simulated board, paper-sized (see the module doc)."""
    from motecal.sim import make_trajectory
    sm = _model(model, accel_noise_mg)
    board = sm.board(mote, seed)
    traj = make_trajectory("static80", seed, n_poses=n_poses, still_s=per_pose / sm.rate_hz,
                           rate_hz=sm.rate_hz)
    t = board.sample_times(traj.duration)
    raw = board.sampler(traj, seed).read(t)
    label = traj.label_at(t)
    # exactly per_pose samples per pose (the clock drift may give one more)
    keep = np.ones(len(t), bool)
    for p in np.unique(label[label >= 1]):
        idx = np.flatnonzero(label == p)
        keep[idx[per_pose:]] = False
        label[idx[per_pose:]] = 0
    label[~keep] = 0
    parts_raw, parts_t, parts_label, parts_temp = [raw], [t], [label], [t]
    if rotation:
        rt = make_trajectory("rotation", seed, rate_hz=sm.rate_hz)
        t2 = board.sample_times(rt.duration)[:PAPER_SWEEP]
        raw2 = board.sampler(rt, seed + 1).read(t2)
        parts_raw.append(raw2)
        parts_t.append(t2 + t[-1] + 1.0)
        parts_label.append(rt.label_at(t2))
        parts_temp.append(t2)        # its own sampler: the board was switched on again
    raw = np.vstack(parts_raw).astype(float)
    # a board with a thermal term (model 'thermal') carries its temperature reading
    temp = (np.concatenate([board.temperature_reading_c(tt) for tt in parts_temp])
            if board.thermal is not None else None)
    n = len(raw)
    return SessionData(
        name=f"paper-sized-{model}-seed{seed}", raw=raw, mote=np.full(n, mote, np.int32),
        seq=np.arange(n, dtype=np.int64), t=np.concatenate(parts_t),
        label=np.concatenate(parts_label).astype(np.int32), flags=np.zeros(n, np.uint8),
        kind="static80",
        meta={"source": "sim", "rate_hz": sm.rate_hz, "seed": int(seed), "model": sm.name,
              "truth": board.to_json(), "physical_truth": board.physical_truth()},
        temp=temp)


def true_affine(physical_truth: dict, sensor: str):
    """(A, c) with true vector = A @ raw_counts + c, from the simulator's
    ``raw = M K u + b``."""
    d = physical_truth[sensor]
    A = np.linalg.inv(np.array(d["M"], float) * float(d["K"]))
    return A, -A @ np.array(d["b"], float)


def fresh_directions(n: int = 2000, seed: int = 12345) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return unit(rng.standard_normal((n, 3)))


def vector_error(sc, physical_truth: dict, magnitude: float = 1.0,
                 dirs: np.ndarray | None = None, align: str = "gauge") -> float:
    """rms |calibrated - true| over fresh directions of the given magnitude
    (noise-free readings), in the sensor's unit.

    ``align="gauge"``: the true vectors expressed in the calibration's
    lower-triangular gauge (the frame it defines); ``"rotation"``: after the
    best rotation of the calibrated vectors onto the true ones (a magnitude
    fitness determines the map only up to a rotation)."""
    A_t, c_t = true_affine(physical_truth, sc.sensor)
    dirs = fresh_directions() if dirs is None else dirs
    u_true = magnitude * dirs
    raw = np.linalg.solve(A_t, (u_true - c_t).T).T          # noise-free counts
    v = sc.apply(raw)
    if align == "gauge":
        L = lower_factor(A_t)
        Q = A_t @ np.linalg.inv(L)                            # A_t = Q L
        target = u_true @ Q                                   # Q^T u
    elif align == "rotation":
        from scipy.spatial.transform import Rotation
        R, _ = Rotation.align_vectors(u_true, v)
        v = R.apply(v)
        target = u_true
    else:
        raise ValueError(align)
    err = v - target
    return float(np.sqrt(np.mean(np.sum(err * err, axis=1))))


def shape_error(A, c, physical_truth: dict, sensor: str = "mag", field: float = 1.0,
                dirs: np.ndarray | None = None) -> float:
    """The shape error of a map ``calibrated = A @ raw_counts + c`` (any
    scale: a Razor transform, a det-gauge calibration): the rms over fresh
    directions of ``|s R v - u| / |u|`` for noise-free readings of true
    vectors ``u`` of magnitude ``field``, after the best rotation R and
    scale s (all a magnitude fit determines, and all a compass needs).  A
    fraction of the field; the one definition the benches and tests use."""
    from scipy.spatial.transform import Rotation
    A_t, c_t = true_affine(physical_truth, sensor)
    dirs = fresh_directions() if dirs is None else dirs
    u = field * dirs
    raw = np.linalg.solve(A_t, (u - c_t).T).T
    v = raw @ np.asarray(A, float).T + np.asarray(c, float)
    R, _ = Rotation.align_vectors(u, v)
    w = R.apply(v)
    s = float(np.sum(w * u) / np.sum(w * w))
    e = s * w - u
    return float(np.sqrt(np.mean(np.sum(e * e, axis=1)))) / field


def board_of(ses: SessionData, model: str = "general"):
    """The simulated board of a session (``meta["truth"]``, its mote), in the
    environment of the built-in ``model`` (every built-in model's field and
    gravity are the same)."""
    from motecal.sim import load_model
    mote = int(ses.mote[0]) if len(ses.mote) else 1
    return load_model(model).with_boards({mote: ses.meta["truth"]}).board(mote, 0)


def true_reading(board, sensor: str, u: np.ndarray, t: float) -> np.ndarray:
    """Noise-free counts (before rounding) of ``board``'s ``sensor`` for the
    physical inputs ``u`` (n, 3: g, deg/s or gauss, body frame) at ``t``
    seconds after power-on, the board still: every term of the board's
    model (nonlinearity, temperature -- each chip at its own, lagged
    temperature, a hysteresis after its history up to ``t`` --, ...), the
    random ones (noise, random walks) left out."""
    from motecal.sim import make_trajectory
    from motecal.sim.physics import K_NOMINAL, Ctx, Saturation, StaleSamples
    from motecal.sim.trajectory import Motion
    u = np.atleast_2d(np.asarray(u, float))
    n = len(u)
    K = K_NOMINAL[sensor]
    traj = make_trajectory("idle", 0, duration=max(float(t), 1.0))
    smp = board.sampler(traj, 0)
    temp_of = smp.chip_temperature(sensor)
    tt = np.full(n, float(t))
    force = u if sensor == "accel" else np.tile([0.0, 0.0, 1.0], (n, 1))
    motion = Motion(R=np.broadcast_to(np.eye(3), (n, 3, 3)).copy(), omega=np.zeros((n, 3)),
                    label=np.ones(n, np.int32), specific_force=force, pose=np.ones(n))
    ctx = Ctx(sensor=sensor, K=K, t=tt, index=np.arange(n), motion=motion,
              field_world=board.environment.field_world(), temp_c=temp_of(tt), temp_of=temp_of)
    x = K * u
    for j, term in enumerate(board.sensors[sensor].terms):
        if isinstance(term, (StaleSamples, Saturation)) or term.is_null():
            continue
        if term.id in ("bias_drift", "field_disturbance", "field_drift"):
            continue                        # random in time: not the calibration's to remove
        x = term.runtime([0, j], traj, board).apply(x, ctx)
    return x


def vector_error_at(sc, board, t: float, temp_c=None, magnitude: float = 1.0,
                    dirs: np.ndarray | None = None) -> float:
    """``vector_error`` through the board's whole model at ``t`` s after
    power-on (``true_reading``), calibrated at the temperature reading
    ``temp_c`` (None: without a temperature), compared in the calibration's
    gauge frame of the board's affine part.  On a board with affine terms
    only it is ``vector_error``."""
    A_t, c_t = true_affine(board.physical_truth(), sc.sensor)
    dirs = fresh_directions() if dirs is None else dirs
    u_true = magnitude * dirs
    raw = true_reading(board, sc.sensor, u_true, t)
    v = sc.apply(raw, temp_c)
    L = lower_factor(A_t)
    Q = A_t @ np.linalg.inv(L)
    err = v - u_true @ Q
    return float(np.sqrt(np.mean(np.sum(err * err, axis=1))))
