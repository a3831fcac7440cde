"""Gyroscope scale (and misalignment where the data allow) from known
rotations: a Ferraris-style turn by a known angle (360 degrees) about each
axis, or a turntable at a known rate.

A session lists them in ``meta["rotations"]`` (``{"name", "rows": [a, b],
"angle_deg"}`` or ``{"name", "rows", "rate_dps"}``; the importer fills it for
imucal sessions and turntable runs).  With the bias ``b`` (deg/s in nominal
units, from the still poses) each one gives a measured vector in nominal
units:

* a turn by a known angle: ``v = sum((w - b) dt)`` over its rows (deg), the
  truth ``theta = angle * u``;
* a turntable segment: ``v = mean(w - b)`` (deg/s), the truth ``rate * u``.

``u`` is the turn's axis.  A board turned flat on a table or a platter turns
about the vertical, which the calibrated accelerometer measures (its mean
over the rows, unit length); the sign (clockwise or not) is read from the
data, only the size of the angle or rate is taken as known.  When every
observation has an axis and the axes span three directions, ``G`` (3x3, the
gyroscope's matrix into the accelerometer's frame, ``w_cal = G (w - b)``) is
the least-squares solution of ``G v_j = theta_j``: scale and misalignment.
Without the accelerometer only the sizes are known, and three scales are
fitted to ``|diag(k) v_j| = |theta_j|`` instead.

Uncertainty: the solution is differentiated (central differences) with
respect to every input, each moved by its standard deviation: the bias's
(``b_std``), the white noise integrated over each observation, the axis
direction (accelerometer noise over the rows) and the size of the turn
(``angle_sd_deg``, 1 degree for a turn by hand against an edge; a
turntable's speed ``rate_sd_rel``, 0.2 %): assumptions stated with the fit.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

ANGLE_SD_DEG = 1.0          # a hand turn back against the same edge
RATE_SD_REL = 0.002         # a turntable's speed (33 1/3, 45 rpm)
MIN_AXIS_SPREAD = 0.2       # smallest singular value of the unit axes for a full matrix


@dataclass
class Observation:
    name: str
    kind: str                      # "angle" (deg) | "rate" (deg/s)
    v: np.ndarray                  # measured, nominal units, bias removed
    size: float                    # |truth|: angle (deg) or rate (deg/s)
    size_sd: float
    axis: np.ndarray | None        # unit axis in the accelerometer frame (signed)
    axis_sd: np.ndarray            # (3,) rad, per component of the axis
    v_sd: np.ndarray               # (3,) white-noise sd of v
    bias_weight: float             # dv/db: -T (angle) or -1 (rate)
    n: int

    @property
    def truth(self) -> np.ndarray:
        return self.size * self.axis


@dataclass
class RotationFit:
    G: np.ndarray                  # (3, 3): w_cal = G (w_nominal - b)
    std: np.ndarray                # (3, 3)
    model: str                     # "matrix" | "scales"
    observations: list
    residual_rms: float            # of |G v| - size (deg or deg/s), relative
    assumptions: dict = field(default_factory=dict)
    std_from: dict = field(default_factory=dict)

    def table(self) -> list[dict]:
        out = []
        for o in self.observations:
            got = float(np.linalg.norm(self.G @ o.v))
            out.append({"name": o.name, "kind": o.kind, "rows": o.n, "size": o.size,
                        "raw_size": float(np.linalg.norm(o.v)), "calibrated_size": got})
        return out


def _unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def observations(data, gyro_b: np.ndarray, accel=None, *, angle_sd_deg=ANGLE_SD_DEG,
                 rate_sd_rel=RATE_SD_REL, still_sd=None, axes="gravity") -> list[Observation]:
    """The session's ``meta["rotations"]`` as observations (see module doc).
    ``gyro_b`` in nominal deg/s; ``accel`` a SensorCalibration or None;
    ``still_sd`` (3,) white-noise sd of the gyro in nominal deg/s (else from
    the static poses).  ``axes="nominal"`` takes each turn's axis as the
    sensor axis it is named after (imucal's assumption: the fixture's faces
    are exact) instead of the measured vertical."""
    rot = (data.meta or {}).get("rotations") or []
    lsb = data.scales["gyro"]
    w = data.sensor("gyro") / lsb
    rate = data.rate("gyro")
    if still_sd is None:
        sds = [w[data.label == p].std(axis=0) for p in data.poses()
               if (data.label == p).sum() > 10]
        still_sd = np.median(sds, axis=0) if sds else np.full(3, 0.1)
    acc = data.sensor("accel") if accel is not None else None
    out = []
    for r in rot:
        a, b = int(r["rows"][0]), int(r["rows"][1])
        rows = np.arange(a, b)
        rows = rows[np.isfinite(w[rows]).all(axis=1)]
        n = len(rows)
        if n < 3:
            continue
        if "angle_deg" in r:
            kind, size = "angle", abs(float(r["angle_deg"]))
            v = (w[rows] - gyro_b).sum(axis=0) / rate
            v_sd = still_sd * np.sqrt(n) / rate
            bias_weight, size_sd = -n / rate, angle_sd_deg
        else:
            kind, size = "rate", abs(float(r["rate_dps"]))
            v = (w[rows] - gyro_b).mean(axis=0)
            v_sd = w[rows].std(axis=0) / np.sqrt(n)
            bias_weight, size_sd = -1.0, rate_sd_rel * size
        axis, axis_sd = None, np.zeros(3)
        if axes == "nominal" and r.get("axis") in ("x", "y", "z"):
            e = np.eye(3)["xyz".index(r["axis"])]
            axis = e * (1.0 if float(v @ e) >= 0 else -1.0)
        elif acc is not None:
            ok = rows[np.isfinite(acc[rows]).all(axis=1)]
            if len(ok) >= 3:
                g = accel.apply(acc[ok])
                m = g.mean(axis=0)
                up = _unit(m)
                axis = up * (1.0 if float(v @ up) >= 0 else -1.0)
                # the vertical's error: accelerometer noise over the rows and the
                # calibration's own offset error (g; the direction moves by it / |g|)
                axis_sd = np.sqrt((g.std(axis=0) / np.sqrt(len(ok))) ** 2
                                  + _offset_sd(accel) ** 2) / np.linalg.norm(m)
        out.append(Observation(r.get("name", f"rotation{len(out) + 1}"), kind, v, size, size_sd,
                               axis, axis_sd, v_sd, bias_weight, n))
    return out


def _solve(obs: list[Observation], model: str) -> np.ndarray:
    if model == "matrix":
        V = np.array([o.v for o in obs]).T          # 3 x m
        T = np.array([o.truth for o in obs]).T
        # G V = T in least squares: G^T from lstsq(V^T, T^T)
        return np.linalg.lstsq(V.T, T.T, rcond=None)[0].T
    V = np.array([o.v for o in obs])
    S = np.array([o.size for o in obs])
    k0 = np.array([S[np.argmax(np.abs(V[:, i]))] / max(abs(V[np.argmax(np.abs(V[:, i])), i]), 1e-12)
                   for i in range(3)])
    k0 = np.where(np.isfinite(k0) & (k0 > 0), k0, 1.0)
    res = least_squares(lambda k: (np.linalg.norm(V * k, axis=1) - S) / S, k0, method="lm")
    return np.diag(res.x)


def choose_model(obs: list[Observation]) -> str:
    if obs and all(o.axis is not None for o in obs):
        U = np.array([o.axis for o in obs])
        if len(obs) >= 3 and np.linalg.svd(U, compute_uv=False)[-1] > MIN_AXIS_SPREAD:
            return "matrix"
    return "scales"


def fit(obs: list[Observation], b_std=None, model: str | None = None) -> RotationFit:
    """Scale (and misalignment) from the observations; see the module doc."""
    if not obs:
        raise ValueError("no rotation observations")
    model = model or choose_model(obs)
    if model == "scales":
        V = np.abs(np.array([o.v for o in obs]))
        covered = (V / V.sum(axis=1, keepdims=True)).max(axis=0)
        if (covered < 0.5).any():
            raise ValueError("the rotations do not turn about every axis: scales of axes "
                             f"{''.join('xyz'[i] for i in np.flatnonzero(covered < 0.5))} "
                             "are not determined")
    G = _solve(obs, model)
    b_std = np.zeros(3) if b_std is None else np.asarray(b_std, float)

    # inputs moved one at a time by their sd -> d G
    parts = {"noise": np.zeros((3, 3)), "bias": np.zeros((3, 3)), "size": np.zeros((3, 3)),
             "axis": np.zeros((3, 3))}

    def moved(fn):
        plus = _solve(fn(+1), model)
        minus = _solve(fn(-1), model)
        return (plus - minus) / 2

    def with_obs(j, **kw):
        def f(sign):
            out = list(obs)
            o = obs[j]
            new = Observation(**{**o.__dict__})
            if "dv" in kw:
                new.v = o.v + sign * kw["dv"]
            if "dsize" in kw:
                new.size = o.size + sign * kw["dsize"]
            if "daxis" in kw and o.axis is not None:
                new.axis = _unit(o.axis + sign * kw["daxis"])
            out[j] = new
            return out
        return f

    for j, o in enumerate(obs):
        for i in range(3):
            e = np.eye(3)[i]
            parts["noise"] += moved(with_obs(j, dv=e * o.v_sd[i])) ** 2
            if o.axis is not None and o.axis_sd[i] > 0:
                parts["axis"] += moved(with_obs(j, daxis=e * o.axis_sd[i])) ** 2
        parts["size"] += moved(with_obs(j, dsize=o.size_sd)) ** 2
    for i in range(3):                               # the bias is shared by all
        def f(sign, i=i):
            out = []
            for o in obs:
                new = Observation(**{**o.__dict__})
                new.v = o.v + sign * o.bias_weight * b_std[i] * np.eye(3)[i]
                out.append(new)
            return out
        parts["bias"] += moved(f) ** 2
    std = np.sqrt(sum(parts.values()))
    sizes = np.array([o.size for o in obs])
    got = np.array([np.linalg.norm(G @ o.v) for o in obs])
    return RotationFit(G=G, std=std, model=model, observations=obs,
                       residual_rms=float(np.sqrt(np.mean(((got - sizes) / sizes) ** 2))),
                       std_from={k: np.sqrt(v) for k, v in parts.items()})


def from_session(data, gyro_cal, accel_cal=None, **kw) -> RotationFit | None:
    """Fit from a session and its gyroscope (bias) calibration; None when
    the session lists no rotations."""
    if not (data.meta or {}).get("rotations"):
        return None
    lsb = data.scales["gyro"]
    Gb = gyro_cal.A * lsb                               # nominal matrix in use
    b = -np.linalg.solve(Gb, gyro_cal.c)                # nominal deg/s
    b_std = np.array([_param_std(gyro_cal, f"b_{a}") for a in "xyz"])
    obs = observations(data, b, accel_cal, **kw)
    if not obs:
        return None
    return fit(obs, b_std)


def _offset_sd(accel) -> np.ndarray:
    """The accelerometer calibration's offset standard deviations (g)."""
    out = np.zeros(3)
    for i, a in enumerate("xyz"):
        out[i] = _param_std(accel, f"o_{a}")
    return out


def _param_std(cal, name):
    try:
        v = cal.param(name).std
    except KeyError:
        return 0.0
    return float(v) if np.isfinite(v) else 0.0


def apply(gyro_cal, rf: RotationFit):
    """The gyroscope calibration with ``G`` from the rotations (bias kept)."""
    from .result import Param
    lsb = gyro_cal.lsb_per_unit
    Gb = gyro_cal.A * lsb
    b = -np.linalg.solve(Gb, gyro_cal.c)
    gyro_cal.A = rf.G / lsb
    gyro_cal.c = -rf.G @ b
    keep = [p for p in gyro_cal.params if not p.name.startswith("G_")]
    for i, ai in enumerate("xyz"):
        for j, aj in enumerate("xyz"):
            if rf.model == "matrix" or i == j:
                keep.append(Param(f"G_{ai}{aj}", float(rf.G[i, j]), float(rf.std[i, j])))
    gyro_cal.params = keep
    gyro_cal.model = f"bias+rotations({rf.model})"
    gyro_cal.notes = list(gyro_cal.notes) + [
        f"{'scale and misalignment' if rf.model == 'matrix' else 'scales'} from "
        f"{len(rf.observations)} known rotations ("
        + ", ".join(f"{o.name}: {o.size:g} {'deg' if o.kind == 'angle' else 'deg/s'}"
                    for o in rf.observations)
        + f"); size error after {rf.residual_rms:.2%} rms"]
    gyro_cal.extra = dict(gyro_cal.extra or {})
    gyro_cal.extra["rotations_fit"] = {
        "model": rf.model, "G": rf.G.tolist(), "std": rf.std.tolist(),
        "std_from": {k: v.tolist() for k, v in rf.std_from.items()},
        "residual_rms_rel": rf.residual_rms, "observations": rf.table(),
        "assumptions": {"angle_sd_deg": ANGLE_SD_DEG, "rate_sd_rel": RATE_SD_REL}}
    return gyro_cal


MAX_G_DEVIATION = 0.3       # as calib.gyro's matrix fit: a G further from I is refused


def refine_board(board, data) -> None:
    """``calibrate_board``'s hook: when the session lists known rotations,
    the gyroscope's scale (and misalignment) comes from them (notes and a
    gate warning say why when it cannot)."""
    if board.gyro is None or not (data.meta or {}).get("rotations"):
        return
    warn = board.gyro.quality.setdefault("warnings", [])
    try:
        rf = from_session(data, board.gyro, board.accel)
    except (ValueError, np.linalg.LinAlgError) as e:
        warn.append(f"known rotations not used: {e}")
        return
    if rf is None:
        warn.append("known rotations not used: none has enough rows")
        return
    if np.abs(rf.G - np.eye(3)).max() > MAX_G_DEVIATION:
        warn.append(f"known rotations not used: max |G - I| "
                    f"{np.abs(rf.G - np.eye(3)).max():.3f} (limit {MAX_G_DEVIATION:g})")
        return
    apply(board.gyro, rf)
    board.gyro.rank = 3 + (9 if rf.model == "matrix" else 3)
