"""Measured vs simulated: the same session simulated with a fitted model, and
the statistics of both side by side.

Simulating "the same session"
-----------------------------
The board's orientation at every row is estimated from the data: the
calibrated accelerometer gives the gravity direction, the calibrated
magnetometer the field direction (TRIAD when both; the smallest turn from
the last orientation when only one), averaged over each still segment and
lightly smoothed while moving.  ``SampledTrajectory`` holds each still
segment and turns at a constant rate between successive rows, so the
simulator reads the board at exactly the measured times, with the measured
labels, rates and sample counts.

Statistics (``session_stats``), per sensor
------------------------------------------
noise (white, per sample), low-frequency ratio (batch-mean sd / white sd),
repeated readings, readings at the range limits, within-pose sd; for the
accelerometer and magnetometer the paper-model residual (rms of pose means,
5 % / 95 % quantiles of every reading), its dependence on direction (R^2 on
products and cubes of the direction components) and on time (R^2 on a time
basis), the dip angle's scatter across poses; for the gyroscope the scatter
of still means across blocks, their dependence on the specific force, and
the Allan deviation at 1 s.

``distance``: rms over statistics of |log((|measured| + e) / (|simulated| +
e))|, with a floor e per statistic (so that two values both within noise
count as equal).  The statistics gain of an extension is the distance of the
starting model's simulation over the extended model's, both fitted on one
half of the poses/time blocks and compared on the other half.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from ..maths.sphere import angle_deg, unit
from ..maths.stats import allan_deviation
from ..sessions.session import NOMINAL_CHIPS, NOMINAL_SCALES, SessionData
from ..sim.model import SimModel
from ..sim.trajectory import Trajectory, up_to_rotation
from . import fitting as F
from . import screens as SC
from . import structure as ST
from .prepare import SensorObs, all_obs, sample_times
from .regimes import accel_for_blocks, regime

SMOOTH_S = 0.08
CHUNK_S = 4.0


# ---------------------------------------------------------------------------
# the trajectory
# ---------------------------------------------------------------------------
class SampledTrajectory(Trajectory):
    """Keyframes (t, R): holds between two equal keyframes, constant-rate turns
    between different ones."""

    type_name = "sampled"

    def __init__(self, kind, t_key, R_key, label_key, pose_key, rate_hz):
        t_key = np.asarray(t_key, float)
        super().__init__(kind, 0, float(t_key[-1]), rate_hz, lever_m=(0.0, 0.0, 0.0))
        self.t_key = t_key
        self.R_key = np.asarray(R_key, float)
        self.label_key = np.asarray(label_key, np.int32)
        self.pose_key = np.asarray(pose_key, float)
        rel = np.einsum("nji,njk->nik", self.R_key[:-1], self.R_key[1:])      # R_i^T R_{i+1}
        self.rotvec = Rotation.from_matrix(rel).as_rotvec() if len(rel) else np.zeros((0, 3))
        self.dt = np.maximum(np.diff(t_key), 1e-9)
        npose = int(self.label_key.max()) if len(self.label_key) and self.label_key.max() > 0 else 0
        self.poses = [np.eye(3)] * npose

    def _idx(self, t):
        """Segment of each time; a time on a keyframe that ends a hold belongs to
        the hold (the row that ends a still segment reads no turn)."""
        i = np.clip(np.searchsorted(self.t_key, t, side="right") - 1, 0,
                    max(len(self.t_key) - 2, 0))
        on_key = (self.t_key[i] == t) & (i >= 1)
        prev_hold = np.zeros(len(t), bool)
        prev_hold[on_key] = ~np.any(self.rotvec[i[on_key] - 1] != 0, axis=1)
        return np.where(prev_hold, i - 1, i)

    def _label(self, t):
        return self.label_key[np.clip(np.searchsorted(self.t_key, t, side="right") - 1,
                                      0, len(self.t_key) - 1)]

    def _kin(self, t):
        n = len(t)
        if len(self.t_key) < 2:
            R = np.repeat(self.R_key[:1], n, axis=0)
            return R, np.zeros((n, 3)), np.zeros((n, 3)), np.zeros(n)
        i = self._idx(t)
        tau = np.clip((t - self.t_key[i]) / self.dt[i], 0.0, 1.0)
        v = self.rotvec[i]
        R = self.R_key[i] @ Rotation.from_rotvec(tau[:, None] * v).as_matrix()
        w = v / self.dt[i][:, None]
        pose = self.pose_key[i] + tau * (self.pose_key[np.minimum(i + 1, len(self.t_key) - 1)]
                                         - self.pose_key[i])
        return R, w, np.zeros((n, 3)), pose

    def _params_json(self):
        return {"keyframes": int(len(self.t_key))}


def _calibrated(o: SensorObs, st) -> np.ndarray:
    """Calibrated readings of a magnitude sensor (its starting fit), or nominal."""
    fit = None
    if st is not None and isinstance(st.fit0, F.MagnitudeFit):
        fit = st.fit0
    if fit is None:
        return o.x / o.K
    return fit.calibrate(o.x, o.t)


def _per_row(data: SessionData, o: SensorObs, v: np.ndarray, t_all: np.ndarray) -> np.ndarray:
    """A vector known on the sensor's rows, on every row (interpolated in time),
    still segments replaced by their mean, moving rows smoothed."""
    v = v.copy()
    if o.segs is not None:
        for g in o.segs.rows:
            v[g] = v[g].mean(axis=0)
    w = max(1, int(round(SMOOTH_S * o.rate)))
    if w > 1 and o.moving is not None and o.moving.any():
        k = np.ones(w) / w
        sm = np.column_stack([np.convolve(v[:, a], k, mode="same") for a in range(3)])
        v[o.moving] = sm[o.moving]
    out = np.column_stack([np.interp(t_all, o.t, v[:, a]) for a in range(3)])
    return unit(out)


def trajectory_like(data: SessionData, diag) -> tuple[SampledTrajectory, np.ndarray]:
    """The rig's trajectory estimated from the data; returns it and the
    simulator times of the rows (seconds from the first row)."""
    rate = data.rate()
    t = sample_times(data)
    order = np.argsort(t, kind="stable")
    if np.any(order != np.arange(len(t))):
        raise ValueError("rows must be in time order")
    t_sim = t - t[0]
    env = diag.model["environment"]
    inc = np.radians(env.get("inclination_deg", 60.0))
    Bw = np.array([np.cos(inc), 0.0, -np.sin(inc)])
    obs = diag.obs
    g_b = b_b = None
    if "accel" in obs:
        g_b = _per_row(data, obs["accel"], unit(_calibrated(obs["accel"],
                                                            diag.structures.get("accel"))),
                       t_sim + t[0])
    if "mag" in obs:
        b_b = _per_row(data, obs["mag"], unit(_calibrated(obs["mag"],
                                                          diag.structures.get("mag"))),
                       t_sim + t[0])
    n = len(t)
    # every row of a pose sees the pose's directions
    lab0 = data.label
    for p in np.unique(lab0[lab0 >= 1]):
        m = lab0 == p
        for v in (g_b, b_b):
            if v is not None:
                v[m] = unit(v[m].mean(axis=0))
    if g_b is not None and b_b is not None:
        # TRIAD: body (g, g x b) <-> world (z, z x B)
        ez = np.array([0.0, 0.0, 1.0])
        t2w = unit(np.cross(ez, Bw))
        W = np.column_stack([ez, t2w, np.cross(ez, t2w)])
        t2b = unit(np.cross(g_b, b_b))
        Bm = np.stack([g_b, t2b, np.cross(g_b, t2b)], axis=2)      # columns
        R = W[None] @ np.transpose(Bm, (0, 2, 1))
    elif g_b is not None:
        R = np.array([up_to_rotation(gv, 0.0) for gv in g_b[:: max(1, n // 20000)]])
        if len(R) != n:
            idx = np.minimum(np.arange(n) // max(1, n // 20000), len(R) - 1)
            R = R[idx]
    elif b_b is not None:
        R = np.empty((n, 3, 3))
        for i in range(n):
            R[i] = Rotation.align_vectors(Bw[None], b_b[i][None])[0].as_matrix()
    else:
        R = np.repeat(np.eye(3)[None], n, axis=0)
    # keyframes: one per distinct time; holds keep their orientation
    lab = data.label.astype(np.int32)
    keep = np.ones(n, bool)
    keep[1:] = np.diff(t_sim) > 0
    tk, Rk, lk = t_sim[keep], R[keep], lab[keep]
    pose = np.where(lk >= 1, lk, np.nan).astype(float)
    if np.isfinite(pose).any():
        ok = np.isfinite(pose)
        pose = np.interp(tk, tk[ok], pose[ok])
    else:
        pose = np.zeros(len(tk))
    traj = SampledTrajectory(data.kind, tk, Rk, lk, pose, rate)
    return traj, t_sim


JITTER_CV = 0.5       # sample intervals this irregular are arrival times, not sample times


def read_times(data: SessionData, t_sim: np.ndarray) -> np.ndarray:
    """The times the simulator reads each row at: the row times, except that a
    sensor on its own clock whose intervals are very irregular (coefficient of
    variation > JITTER_CV: times the host received bursts, not when the chip
    sampled) is read evenly at its mean rate over the same span."""
    out = t_sim.copy()
    present = np.column_stack([data.has(s) for s in ("accel", "gyro", "mag")])
    for k in range(3):
        own = present[:, k] & (present.sum(axis=1) == 1)
        idx = np.flatnonzero(own)
        if len(idx) < 10:
            continue
        dt = np.diff(t_sim[idx])
        if dt.mean() > 0 and dt.std() / dt.mean() > JITTER_CV:
            out[idx] = np.linspace(t_sim[idx[0]], t_sim[idx[-1]], len(idx))
    return out


def simulate_like(data: SessionData, model_json: dict, traj, t_sim, seed: int = 0) -> SessionData:
    """The session simulated with ``model_json`` along ``traj`` at the rows'
    read times (``read_times``).  A session with temperature (``data.temp``)
    gives the twin's board the session's measured temperature (interpolated
    between its readings) instead of the model's own curve, and the twin
    carries it: a drift that follows the temperature is simulated as it
    happened (by a model with the temperature term), not missed."""
    model = SimModel.from_json(model_json, model_json.get("name", "<diagnosis>"))
    mote = data.motes[0]
    board = model.board(mote, seed)
    tr = read_times(data, t_sim)
    order = np.argsort(tr, kind="stable")
    sampler = board.sampler(traj, seed)
    temp = None
    if data.has_temp:
        temp = data.temp.copy()
        ok = np.isfinite(temp[order])
        t_known, T_known = tr[order][ok], temp[order][ok]
        sampler.temperature_c = lambda t: np.interp(np.asarray(t, float), t_known, T_known)
    raw = np.empty((len(tr), 9))
    raw[order] = sampler.read(tr[order]).astype(float)
    for s, sl in (("accel", slice(0, 3)), ("gyro", slice(3, 6)), ("mag", slice(6, 9))):
        miss = ~data.has(s)
        raw[miss, sl] = np.nan
    meta = {k: v for k, v in (data.meta or {}).items() if k in ("rate_hz", "rates_hz", "files")}
    meta["source"] = "sim"
    return SessionData(data.name + "-sim", raw, data.mote.copy(), data.seq.copy(),
                       data.t.copy(), data.label.copy(), np.zeros(len(data), np.uint8),
                       data.kind, dict(NOMINAL_SCALES), dict(NOMINAL_CHIPS), meta, temp=temp)


# ---------------------------------------------------------------------------
# statistics
# ---------------------------------------------------------------------------
STAT_FLOORS = {"ratio": 0.05, "fraction": 0.005, "r2": 0.05, "deg": 0.05}


def _r2(y, X):
    X = np.column_stack([np.ones(len(y)), X])
    if len(y) <= X.shape[1] + 2:
        return np.nan
    b, *_ = np.linalg.lstsq(X, y, rcond=None)
    r = y - X @ b
    d = y - y.mean()
    return float(1 - (r @ r) / (d @ d)) if d @ d > 0 else 0.0


def _allan(runs: list, rate: float, tau_s: float) -> float:
    """Overlapping Allan deviation at ``tau_s`` (rms over the axes) pooled over
    the still runs long enough for it (``stats.allan_deviation`` passes over
    the shorter ones); NaN when none is."""
    _, adev, _ = allan_deviation(runs, rate, m=[int(round(tau_s * rate))])
    return float(np.sqrt(np.mean(adev[0] ** 2))) if len(adev) else np.nan


def session_stats(data: SessionData) -> dict:
    """{sensor: {statistic: (value, kind)}} -- kind: unit | ratio | fraction | r2 | deg."""
    obs = all_obs(data)
    out = {}
    cal = {}
    for s, o in obs.items():
        st = {}
        sig = o.sigma / o.K
        st["noise"] = (float(np.nanmean(sig)), "unit")
        if o.segs is not None:
            st["lowfreq_ratio"] = (float(np.nanmean(o.sigma_eff / o.sigma)), "ratio")
            st["within_sd"] = (float(np.median(o.segs.sd.mean(axis=1))) / o.K, "unit")
        same = np.all(o.x[1:] == o.x[:-1], axis=1) & (o.part[1:] == o.part[:-1])
        st["repeat_fraction"] = (float(same.mean()) if len(same) else 0.0, "fraction")
        sat = SC.saturation(o)
        st["at_limits"] = (float(sat.effect) if sat is not None and sat.practical else 0.0,
                           "fraction")
        r = regime(o)
        if s in ("accel", "mag") and r in ("poses", "sweep"):
            pts = ST.magnitude_points(o, r)
            X, T = pts["X"], pts["T"]
            fit = F.fit_magnitude(s, o.K, X, T, np.ones(len(X)))
            res = fit.residuals(X, T)
            st["resid_rms"] = (float(np.sqrt(np.mean(res ** 2))), "unit")
            rows = np.concatenate(o.segs.rows) if r == "poses" else np.flatnonzero(~o.overflow)
            rs = fit.residuals(o.x[rows], o.t[rows])
            q = np.percentile(rs, [5, 95])
            st["resid_q05"] = (float(q[0]), "unit")
            st["resid_q95"] = (float(q[1]), "unit")
            u = unit(fit.calibrate(X, T))
            D = np.column_stack([u[:, 0] * u[:, 1], u[:, 0] * u[:, 2], u[:, 1] * u[:, 2],
                                 u[:, 0] ** 3, u[:, 1] ** 3, u[:, 2] ** 3])
            st["r2_direction"] = (_r2(res, D), "r2")
            # against the reading's size per axis (even in the reading: a +/- scale
            # asymmetry or a scale that grows with the reading)
            st["r2_reading"] = (_r2(res, np.abs(u)), "r2")
            st["r2_time"] = (_r2(res, F.time_basis(T, T.min(), T.max(), 4)), "r2")
            if r == "poses":
                cal[s] = (fit, o)
        if s == "gyro" and o.blocks is not None and len(o.blocks) >= 3:
            st["between_sd"] = (float(np.mean(o.blocks.mean.std(axis=0))) / o.K, "unit")
            st["allan_1s"] = (_allan([o.x[r] / o.K for r in o.segs.rows], o.rate, 1.0), "unit")
        out[s] = st
    if "gyro" in obs and "accel" in obs and obs["gyro"].blocks is not None:
        g = obs["gyro"]
        a = accel_for_blocks(g, None, obs["accel"])
        if a is not None and len(a) >= 6:
            out["gyro"]["r2_accel"] = (float(np.mean([_r2(g.blocks.mean[:, k], a)
                                                      for k in range(3)])), "r2")
    if "accel" in cal and "mag" in cal:
        (fa, oa), (fm, om) = cal["accel"], cal["mag"]
        g, b, _, idx = ST.pose_vectors(oa, fa, om, fm)
        angs = angle_deg(g, b)
        if len(angs) >= 4:
            out["mag"]["dip_sd_deg"] = (float(np.std(angs)), "deg")
        if len(idx) >= 12:
            # each sensor's magnitude residual against the other's direction, pose by pose
            tm = om.segs.t[idx]
            ra = np.linalg.norm(g, axis=1) - fa.target(tm)
            rm = np.linalg.norm(b, axis=1) - fm.target(tm)
            out["accel"]["r2_mag"] = (_r2(ra, unit(b)), "r2")
            out["mag"]["r2_accel"] = (_r2(rm, unit(g)), "r2")
    return out


def distance(meas: dict, sim: dict) -> tuple[float, dict]:
    """rms log-distance over the statistics present in both (see module doc)."""
    per = {}
    for s, st in meas.items():
        if s not in sim:
            continue
        unit_floor = 0.2 * abs(st["noise"][0]) / 10.0 if "noise" in st else 1e-6
        for k, (m, kind) in st.items():
            if k not in sim[s]:
                continue
            v = sim[s][k][0]
            if not (np.isfinite(m) and np.isfinite(v)):
                continue
            e = unit_floor if kind == "unit" else STAT_FLOORS[kind]
            if kind == "unit" and k.startswith("resid_q"):
                m, v = abs(m), abs(v)
            per[f"{s}.{k}"] = float(abs(np.log((abs(m) + e) / (abs(v) + e))))
    if not per:
        return 0.0, per
    return float(np.sqrt(np.mean(np.square(list(per.values()))))), per


# ---------------------------------------------------------------------------
# halves for the held-out comparison
# ---------------------------------------------------------------------------
def halves(data: SessionData) -> np.ndarray:
    """Bool mask of half A: even poses, and even CHUNK_S stretches of the
    other rows (see below); half B is the rest."""
    lab = data.label
    rate = data.rate()
    t = sample_times(data)
    chunk = np.floor((t - t[0]) / CHUNK_S).astype(int)
    a = chunk % 2 == 0
    pose = lab >= 1
    a[pose] = lab[pose] % 2 == 0
    # a single pose (idle), or poses that are separate recordings (files: their
    # times are not one clock), are split by time inside each instead
    files = (data.meta or {}).get("files") or []
    if len(np.unique(lab[pose])) < 4 or len(files) > 1:
        a[pose] = chunk[pose] % 2 == 0
    return a


def _table(meas, start, ext=None):
    rows = []
    for s, st in meas.items():
        for k, (m, kind) in st.items():
            row = {"sensor": s, "statistic": k, "kind": kind, "measured": m,
                   "simulated_paper": start.get(s, {}).get(k, (None,))[0]}
            if ext is not None:
                row["simulated_extended"] = ext.get(s, {}).get(k, (None,))[0]
            rows.append(row)
    return rows


def comparison(data: SessionData, diag, seed: int = 0, *, rediagnose) -> dict:
    """Question 1 (whole session: measured vs the paper model's simulation)
    and question 4's statistics (held-out half: measured vs the paper and the
    extended model fitted on the other half, by ``rediagnose``: the engine's
    ``diagnose``)."""
    out = {}
    try:
        traj, t_sim = trajectory_like(data, diag)
    except ValueError as e:
        return {"note": f"no simulation: {e}"}
    meas = session_stats(data)
    sim0 = simulate_like(data, diag.start_model, traj, t_sim, seed)
    st0 = session_stats(sim0)
    d0, per0 = distance(meas, st0)
    out["whole"] = {"distance_paper": d0, "per_stat": per0, "table": _table(meas, st0)}
    a = halves(data)
    b = ~a
    if diag.findings and a.sum() > 50 and b.sum() > 50:
        try:
            half = rediagnose(data.select(a), alpha=diag.alpha, seed=seed, simulate=False,
                              force=diag.causes())
        except Exception as e:                      # noqa: BLE001 - reported, not fatal
            out["heldout"] = {"note": f"half-data refit failed: {e}"}
            return out
        sa = simulate_like(data, half.start_model, traj, t_sim, seed + 1)
        se = simulate_like(data, half.model, traj, t_sim, seed + 1)
        mb = session_stats(data.select(b))
        sb0 = session_stats(sa.select(b))
        sbe = session_stats(se.select(b))
        db, perb = distance(mb, sb0)
        da, pera = distance(mb, sbe)
        out["heldout"] = {"distance_paper": db, "distance_extended": da,
                          "gain": (db / da) if da > 0 else None,
                          "per_stat_paper": perb, "per_stat_extended": pera,
                          "table": _table(mb, sb0, sbe)}
    return out
