"""Optimal design of a static-pose session: how well the poses so far
determine the calibration, which pose to take next, and when to stop
(issue 19; ``capture.guide.AdaptiveCapture`` asks, ``motecal calibrate``
reports the poses a finished session needed).  Pure numpy/scipy on the
per-pose means; the design note is docs/adaptive-design.md.

The observation is a pose *mean* (accelerometer, magnetometer in nominal
units), not a sample: samples within a pose share whatever is different
about that pose (tremor, the local field, what the model cannot represent),
so the per-sample ``sigma^2 (J^T J)^-1`` would be optimistic by about the
square root of the samples per pose.  Pose k's magnitude residual has

    var_k = s_w^2 / n_k + tau^2

with ``s_w`` the pooled within-pose noise per axis and ``tau`` the
pose-to-pose scatter the within-pose noise does not explain (estimated from
the residuals).  The fit is the ``full`` model (``models.FullModel``) by
weighted least squares on the pose means; its covariance is
``phi (J^T W J)^-1`` where ``phi`` >= 1 is the leave-one-pose-out check: the
held-out residuals (``r_k / (1 - h_kk)``, the hat matrix of the weighted
fit) against the variance the model assumes.

**Predicted error on fresh directions.**  A calibrated vector on direction
``d`` (magnitude ``H``) is off by ``B(d) dtheta``; over an even spread of
fresh directions the mean squared error is ``tr(M C)`` with
``M = mean_d B(d)^T B(d)``.  For the magnetometer the error is of the
vector divided by the fitted field (the shape: the det(A) = 1 gauge leaves
the overall scale to the datasheet).  The error is a random quadratic form
``sum lambda_i chi2_1`` (``lambda`` the eigenvalues of ``M C``), and the
variance behind it is partly estimated (``tau^2`` from ``K - p`` pose
residuals), so the promise is an upper bound at ``CONFIDENCE``: the
Satterthwaite chi-square of the form, as an F quantile with the effective
degrees of freedom of the variance estimate.  A stop on a false promise is
worse than a long session.

**Next pose.**  For each candidate gravity direction (an even spread, less
those within the guide's minimum angle of a taken pose) the rank-one update
of the covariance gives the predicted error after adding it; the candidate
with the smallest sum over sensors of (error after / target)^2 wins.  The
magnetometer's direction depends on the heading the person chooses, which
the suggestion leaves free: its gain is averaged over headings, with the
field's dip estimated from the poses.

**Samples per pose.**  ``s_w^2 / tau^2`` samples make the within-pose noise
of a pose mean as large as the scatter no averaging removes; more is wasted
holding, fewer wastes the move.  Clipped to ``[min, max]``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares
from scipy.stats import chi2, f as f_dist

from ..maths.sphere import angle_deg, fibonacci_sphere, unit
from .content import judge_poses
from .models import MagnitudeModel, make_model

CONFIDENCE = 0.9              # the promised error is this quantile of the true error
FRESH = fibonacci_sphere(256)  # fresh directions the error is averaged over
CANDIDATES = fibonacci_sphere(400)
HEADINGS = 8                  # headings the magnetometer's gain is averaged over
MIN_POSES = 12                # fewer poses: no prediction (9 parameters + 3 dof)
CURVE_POINTS = 16             # poses_needed's curve: the promise at this many numbers of poses
TARGET_ACCEL_G = 0.0005       # 0.5 mg rms on fresh directions
TARGET_MAG_REL = 0.003        # 0.3 % of the field (shape)
TARGET_GYRO_DPS = 0.05        # gyroscope bias, deg/s rms over axes
MIN_POSE_SAMPLES = 100
MAX_POSE_SAMPLES = 1000
SENSORS = ("accel", "mag")


# --------------------------------------------------------------------------
# per-pose statistics
# --------------------------------------------------------------------------
@dataclass
class PoseStats:
    """Per static pose: mean and per-axis sample sd of the nine channels
    (raw counts; NaN where a sensor is missing) and the number of samples."""
    mean: np.ndarray      # (K, 9)
    sd: np.ndarray        # (K, 9)
    n: np.ndarray         # (K,)
    labels: np.ndarray = field(default_factory=lambda: np.zeros(0, int))

    def __len__(self):
        return len(self.n)

    def take(self, idx) -> "PoseStats":
        idx = np.asarray(idx, int)
        return PoseStats(self.mean[idx], self.sd[idx], self.n[idx],
                         self.labels[idx] if len(self.labels) else self.labels)


def pose_stats(raw: np.ndarray, label: np.ndarray) -> PoseStats:
    """PoseStats of the labelled poses (label >= 1) of raw counts (n, 9), in
    the order the poses were taken (first row of each)."""
    raw = np.asarray(raw, float)
    label = np.asarray(label)
    labs = []
    for lab in label[label >= 1]:
        if not labs or labs[-1] != lab:
            labs.append(int(lab))
    labs = list(dict.fromkeys(labs))
    mean = np.full((len(labs), 9), np.nan)
    sd = np.full((len(labs), 9), np.nan)
    n = np.zeros(len(labs))
    for i, lab in enumerate(labs):
        x = raw[label == lab]
        n[i] = len(x)
        with np.errstate(invalid="ignore"):
            mean[i] = np.nanmean(x, axis=0) if len(x) else np.nan
            sd[i] = np.nanstd(x, axis=0, ddof=1) if len(x) > 1 else np.nan
    return PoseStats(mean, sd, n, np.array(labs, int))


# --------------------------------------------------------------------------
# one sensor: fit, covariance, predicted error
# --------------------------------------------------------------------------
@dataclass
class SensorDesign:
    """How well the poses determine one magnitude sensor."""
    sensor: str
    model: MagnitudeModel
    theta: np.ndarray
    u: np.ndarray               # (K, 3) pose means, nominal units
    n: np.ndarray               # (K,) samples per pose
    s_w2: float                 # within-pose variance per axis (nominal units^2)
    tau2: float                 # pose-to-pose scatter beyond it
    phi: float                  # held-out (leave-one-pose-out) scale, >= 1
    cov: np.ndarray             # (d, d) parameter covariance, phi included
    M: np.ndarray               # (d, d): mean squared fresh-direction error = tr(M cov)
    dof: float                  # effective degrees of freedom of the variance estimate
    rms: float                  # expected rms error on fresh directions (unit; mag: relative)
    bound: float                # CONFIDENCE upper bound of it
    determined: bool = True     # the poses determine the full model (content.judge_poses)

    def var_new(self, n_samples: float) -> float:
        return self.s_w2 / max(n_samples, 1.0) + self.tau2

    def rows(self, u: np.ndarray) -> np.ndarray:
        """Jacobian rows of the magnitude residual at readings u (m, 3)."""
        return self.model.jacobian(self.theta, np.atleast_2d(u))

    def reading(self, d: np.ndarray) -> np.ndarray:
        """Nominal-unit readings (m, 3) whose calibrated vectors point along
        unit directions d (m, 3) with the fitted magnitude."""
        A, c, H = self.model.affine(self.theta)
        return np.linalg.solve(A, (float(H) * np.atleast_2d(d) - c).T).T

    def gain(self, rows: np.ndarray, n_samples: float) -> np.ndarray:
        """Decrease of the mean squared fresh-direction error from one more
        pose with each Jacobian row (m, d): the rank-one update of cov."""
        CJ = rows @ self.cov                                   # (m, d)
        num = np.einsum("md,de,me->m", CJ, self.M, CJ)
        den = self.var_new(n_samples) * self.phi + np.einsum("md,md->m", CJ, rows)
        return num / den


def error_matrix(model: MagnitudeModel, theta, dirs: np.ndarray = FRESH) -> np.ndarray:
    """M (d, d) with tr(M C) the mean squared error of the calibrated vector
    over unit directions ``dirs`` (accelerometer: in g at 1 g; magnetometer:
    of the vector over the fitted field, so relative), for parameter
    covariance C."""
    theta = np.asarray(theta, float)
    A, c, H = model.affine(theta)
    H = float(H)
    u = np.linalg.solve(A, (H * dirs - c).T).T                 # readings on those directions
    J = model.affine_jacobian(theta)                           # (13, d)
    # dv = dA u + dc  ->  B(d) = kron(I, u^T) J[:9] + J[9:12]
    B = np.einsum("ij,nk->nijk", np.eye(3), u).reshape(len(u), 3, 9) @ J[:9] + J[9:12]
    if model.free_field:                                       # the shape: v / H
        B = (B - dirs[:, :, None] * J[12][None, None, :]) / H
    return np.einsum("nid,nie->de", B, B) / len(dirs)


def upper_bound(M: np.ndarray, cov: np.ndarray, dof: float, q: float = CONFIDENCE) -> tuple:
    """(expected rms, q-quantile of the rms) of the error sqrt(e^T M e) for
    e ~ N(0, cov) whose scale was estimated with ``dof`` degrees of freedom
    (inf: known): Satterthwaite's scaled chi-square for the quadratic form,
    an F quantile for the estimated scale."""
    lam = np.clip(np.real(np.linalg.eigvals(M @ cov)), 0.0, None)
    s1, s2 = float(lam.sum()), float((lam * lam).sum())
    if s1 <= 0:
        return 0.0, 0.0
    nu = s1 * s1 / s2
    ratio = (chi2.ppf(q, nu) / nu if not np.isfinite(dof) or dof > 1e6
             else f_dist.ppf(q, nu, dof))
    return float(np.sqrt(s1)), float(np.sqrt(s1 * ratio))


def _weighted_fit(model, theta0, u, w):
    sw = np.sqrt(w)
    res = least_squares(lambda th: sw * model.residuals(th, u), theta0,
                        jac=lambda th: sw[:, None] * model.jacobian(th, u), method="lm",
                        xtol=1e-12, ftol=1e-12, max_nfev=200)
    return res.x


def _start(model: MagnitudeModel, u: np.ndarray) -> np.ndarray:
    """A starting point: the sphere through the pose means (centre, radius),
    identity shape."""
    x0 = model.default.copy()
    Aq = np.hstack([2 * u, np.ones((len(u), 1))])
    sol, *_ = np.linalg.lstsq(Aq, (u * u).sum(axis=1), rcond=None)
    centre = sol[:3]
    r = float(np.sqrt(max(sol[3] + centre @ centre, 1e-12)))
    x0[0:3] = -centre
    if model.free_field:
        x0[-1] = r
    else:
        s = 1.0 / r
        x0[3:5] = s
        if not model.derived_scale:
            x0[5] = s
    return x0


def design_sensor(sensor: str, stats: PoseStats, lsb: float, theta0=None,
                  dirs: np.ndarray = FRESH, q: float = CONFIDENCE) -> SensorDesign | None:
    """Fit the full model to the pose means of ``sensor`` (``lsb`` counts per
    nominal unit) and predict its fresh-direction error (module doc).  None
    with fewer than ``MIN_POSES`` usable poses.  ``determined`` says whether
    the poses determine the full model (``content.judge_poses``, the
    judgement calibrate uses): only then is its error promised (``assess``);
    the fit still tells the next pose where the poses are lacking."""
    sl = slice(0, 3) if sensor == "accel" else slice(6, 9)
    ok = np.isfinite(stats.mean[:, sl]).all(axis=1) & (stats.n >= 2)
    if sensor == "mag":
        ok &= (stats.mean[:, sl] > -4000).all(axis=1)       # overflowed poses
    model = make_model(sensor, "full")
    d = model.d
    if ok.sum() < max(MIN_POSES, d + 1):
        return None
    u = stats.mean[ok, sl] / lsb
    n = stats.n[ok].astype(float)
    sdv = stats.sd[ok, sl] / lsb
    s_w2 = float(np.nansum((n[:, None] - 1) * sdv ** 2) / max(np.sum(n - 1) * 3, 1))
    K = len(u)
    theta = _start(model, u) if theta0 is None else np.asarray(theta0, float)
    tau2 = 0.0
    for _ in range(3):                      # weights <-> scatter, a few rounds
        var = s_w2 / n + tau2
        theta = _weighted_fit(model, theta, u, 1.0 / var)
        r = model.residuals(theta, u)
        tau2 = max(0.0, float(r @ r) / (K - d) - float(np.mean(s_w2 / n)))
    var = s_w2 / n + tau2
    J = model.jacobian(theta, u)
    Jw = J / np.sqrt(var)[:, None]
    info = Jw.T @ Jw
    cov_unit = np.linalg.pinv(info)
    h = np.einsum("kd,de,ke->k", Jw, cov_unit, Jw)          # leverages
    r = model.residuals(theta, u)
    loo = r * r / np.maximum(1.0 - h, 1e-3) / var            # held-out, in units of var
    phi = max(1.0, float(np.mean(loo)))
    cov = cov_unit * phi
    # effective dof of the variance: the within part is measured on every
    # sample (known), tau^2 on K - d pose residuals (Satterthwaite)
    known = float(np.mean(s_w2 / n))
    dof = np.inf if tau2 <= 0 else (K - d) * ((known + tau2) / tau2) ** 2
    if phi > 1.0:                           # the held-out check raised the scale:
        dof = min(dof, float(K - d))        # it is as uncertain as the residuals
    M = error_matrix(model, theta, dirs)
    rms, bound = upper_bound(M, cov, dof, q)
    return SensorDesign(sensor, model, theta, u, n, s_w2, tau2, phi, cov, M, dof, rms, bound,
                        judge_poses(sensor, u).determines("full"))


def gyro_bias_bound(stats: PoseStats, lsb: float, q: float = CONFIDENCE) -> float | None:
    """Upper bound (rms over axes, deg/s) of the gyroscope bias error from the
    still poses: the standard error of ``gyro.mean_bias`` (the larger of
    sd / sqrt(n) and the cluster-robust error over poses), from the pose
    statistics, as a chi-square quantile with 3 degrees of freedom."""
    ok = np.isfinite(stats.mean[:, 3:6]).all(axis=1) & (stats.n >= 2)
    if ok.sum() < 2:
        return None
    m_p = stats.mean[ok, 3:6] / lsb
    n_p = stats.n[ok].astype(float)
    N = n_p.sum()
    m = (n_p[:, None] * m_p).sum(axis=0) / N
    within = ((n_p[:, None] - 1) * (stats.sd[ok, 3:6] / lsb) ** 2).sum(axis=0)
    between = (n_p[:, None] * (m_p - m) ** 2).sum(axis=0)
    sd = np.sqrt((within + between) / max(N - 1, 1))
    P = len(n_p)
    poses = np.sqrt(P / (P - 1) * ((n_p[:, None] * (m_p - m)) ** 2).sum(axis=0)) / N
    std = np.fmax(sd / np.sqrt(N), poses)
    return float(np.sqrt(np.mean(std ** 2) * chi2.ppf(q, 3) / 3))


# --------------------------------------------------------------------------
# the whole board: where it stands, what next
# --------------------------------------------------------------------------
@dataclass
class Targets:
    accel_g: float = TARGET_ACCEL_G
    mag_rel: float = TARGET_MAG_REL
    gyro_dps: float = TARGET_GYRO_DPS

    def of(self, sensor: str) -> float:
        return {"accel": self.accel_g, "mag": self.mag_rel, "gyro": self.gyro_dps}[sensor]


@dataclass
class Assessment:
    """Where the calibration stands after the poses so far."""
    poses: int
    designs: dict                 # sensor -> SensorDesign (accel, mag)
    bounds: dict                  # sensor -> promised error (CONFIDENCE bound) or None
    met: dict                     # sensor -> bool
    samples: int                  # samples the next pose should have
    next_up: np.ndarray | None    # suggested gravity direction (raw accelerometer frame)

    @property
    def all_met(self) -> bool:
        return bool(self.met) and all(self.met.values())

    def text(self, targets: Targets) -> str:
        """'accel 0.82 mg (0.5), mag 0.21 % (0.3) ok, gyro 0.012 deg/s (0.05) ok'"""
        fmt = {"accel": (1e3, "mg"), "mag": (1e2, "%"), "gyro": (1.0, "deg/s")}
        parts = []
        for s in ("accel", "mag", "gyro"):
            if s not in self.bounds:
                continue
            k, unit_ = fmt[s]
            b = self.bounds[s]
            val = "?" if b is None else f"{b * k:.3g}"
            parts.append(f"{s} {val} {unit_} (target {targets.of(s) * k:g})"
                         + (" ok" if self.met.get(s) else ""))
        return ", ".join(parts)


def field_dip(acc: SensorDesign, mag: SensorDesign) -> float:
    """Angle (rad) of the field below the horizontal, from the poses: the
    mean angle between the calibrated up direction and the field, less 90 deg."""
    K = min(len(acc.u), len(mag.u))
    A1, c1, _ = acc.model.affine(acc.theta)
    A2, c2, _ = mag.model.affine(mag.theta)
    a = unit(acc.u[:K] @ A1.T + c1)
    m = unit(mag.u[:K] @ A2.T + c2)
    return float(np.radians(np.mean(angle_deg(a, m))) - np.pi / 2)


def mag_rows_for_up(mag: SensorDesign, up: np.ndarray, dip: float,
                    headings: int = HEADINGS) -> np.ndarray:
    """Magnetometer Jacobian rows (len(up), headings, d) of poses whose up
    direction is each row of ``up`` (calibrated frame) at evenly spread
    headings: the field is cos(dip) horizontal minus sin(dip) up."""
    up = unit(np.atleast_2d(up))
    ref = np.where(np.abs(up[:, :1]) < 0.9, np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]]))
    e1 = unit(np.cross(up, ref))
    e2 = np.cross(up, e1)
    psi = 2 * np.pi * np.arange(headings) / headings
    f = (np.cos(dip) * (np.cos(psi)[None, :, None] * e1[:, None] + np.sin(psi)[None, :, None]
                        * e2[:, None]) - np.sin(dip) * up[:, None])
    u = mag.reading(f.reshape(-1, 3))
    return mag.rows(u).reshape(len(up), headings, -1)


def pose_samples(designs: dict, targets: Targets, met: dict,
                 lo: int = MIN_POSE_SAMPLES, hi: int = MAX_POSE_SAMPLES) -> int:
    """Samples for the next pose (module doc): s_w^2 / tau^2 of the sensors
    still short of their target, the largest, within [lo, hi]."""
    want = []
    for s, dsg in designs.items():
        if dsg is None or met.get(s):
            continue
        want.append(hi if dsg.tau2 <= 0 else dsg.s_w2 / dsg.tau2)
    if not want:
        want = [lo]
    return int(np.clip(np.ceil(max(want)), lo, hi))


def assess(stats: PoseStats, scales: dict, targets: Targets = Targets(), *,
           min_angle_deg: float = 15.0, candidates: np.ndarray = CANDIDATES,
           lo_samples: int = MIN_POSE_SAMPLES, hi_samples: int = MAX_POSE_SAMPLES,
           q: float = CONFIDENCE, suggest: bool = True) -> Assessment:
    """Where the board stands after the poses ``stats`` (raw counts, scales =
    LSB per unit per sensor) and the next pose to take (module doc)."""
    designs = {s: design_sensor(s, stats, scales[s], q=q) for s in SENSORS}
    bounds, met = {}, {}
    for s, dsg in designs.items():       # a promise only where the poses determine it
        bounds[s] = None if dsg is None or not dsg.determined else dsg.bound
        met[s] = bounds[s] is not None and dsg.bound <= targets.of(s)
    has_mag = np.isfinite(stats.mean[:, 6:9]).any() if len(stats) else False
    if not has_mag:
        designs.pop("mag"); bounds.pop("mag"); met.pop("mag")
    g = gyro_bias_bound(stats, scales["gyro"], q) if np.isfinite(
        stats.mean[:, 3:6]).any() else None
    if len(stats) and np.isfinite(stats.mean[:, 3:6]).any():
        bounds["gyro"] = g
        met["gyro"] = g is not None and g <= targets.gyro_dps
    n_next = pose_samples({k: v for k, v in designs.items()}, targets, met, lo_samples,
                          hi_samples)
    nxt = None
    acc = designs.get("accel")
    if suggest and acc is not None:
        taken = unit(stats.mean[:, 0:3])
        free = angle_deg(candidates[:, None, :], taken[None, :, :]).min(axis=1) >= min_angle_deg
        cand = candidates[free] if free.any() else candidates
        # candidates are calibrated up directions; the person sees raw ones
        score = np.zeros(len(cand))
        for s, dsg in designs.items():
            if dsg is None:
                continue
            now = dsg.rms ** 2
            if s == "accel":
                after = now - dsg.gain(dsg.rows(dsg.reading(cand)), n_next)
            else:
                mag_d = designs.get("mag")
                rows = mag_rows_for_up(mag_d, cand, field_dip(acc, mag_d))
                after = now - dsg.gain(rows.reshape(-1, rows.shape[-1]), n_next) \
                    .reshape(len(cand), -1).mean(axis=1)
            score += np.maximum(after, 0.0) / targets.of(s) ** 2
        best = cand[int(np.argmin(score))]
        nxt = unit(acc.reading(best[None])[0])
    return Assessment(len(stats), designs, bounds, met, n_next, nxt)


# --------------------------------------------------------------------------
# a finished session: how many of its poses were needed
# --------------------------------------------------------------------------
def poses_needed(stats: PoseStats, scales: dict, targets: Targets = Targets(), *,
                 sensors=("accel", "mag", "gyro"), q: float = CONFIDENCE) -> dict:
    """For the poses of a finished session (in the order taken): the fewest
    of them, in that order, after which every sensor's promised error meets
    its target (``in_order``), and the fewest that do in the best subset a
    greedy design finds (``best_subset``, the pose labels in ``subset``);
    None where even all the poses do not.  Only ``sensors`` are judged (the
    magnetometer is left out when its calibration came from a sweep).

    ``curve`` keeps the promise at ``CURVE_POINTS`` numbers of poses ``k``
    from ``MIN_POSES`` to all of them (the report draws it): per sensor the
    promised error of the first k poses in the order taken (``in_order``)
    and of the first k of the greedy selection (``best_subset``; the
    selection runs to every pose, ``order`` the labels in the order it chose
    them)."""
    K = len(stats)
    out = {"poses": K, "targets": {"accel_g": targets.accel_g, "mag_rel": targets.mag_rel,
                                   "gyro_dps": targets.gyro_dps},
           "confidence": q, "sensors": list(sensors), "in_order": None, "best_subset": None,
           "subset": [], "bounds_all": {}}
    memo = {}

    def ok(idx) -> tuple[bool, dict]:
        key = tuple(idx)
        if key not in memo:
            a = assess(stats.take(list(idx)), scales, targets, q=q, suggest=False)
            bs = {s: a.bounds.get(s) for s in sensors if s in a.bounds}
            memo[key] = (all(a.met.get(s, False) for s in bs) and bool(bs), bs)
        return memo[key]

    met_all, b_all = ok(range(K))
    out["bounds_all"] = b_all
    if K < MIN_POSES:
        return out
    ks = sorted(set(np.linspace(MIN_POSES, K, CURVE_POINTS).round().astype(int).tolist()))
    if met_all:
        # in the order taken: the bound is not monotone in k, so the first k
        # from which it holds for good is searched from the end
        first = K
        for k in range(K - 1, MIN_POSES - 1, -1):
            if not ok(range(k))[0]:
                break
            first = k
        out["in_order"] = first
    curve = {"k": ks, "in_order": {s: [ok(range(k))[1].get(s) for k in ks] for s in b_all},
             "best_subset": {s: [] for s in b_all}, "order": []}
    out["curve"] = curve
    # best subset: greedy A-optimal selection on the full session's fit
    full = {s: design_sensor(s, stats, scales[s], q=q) for s in ("accel", "mag")
            if s in sensors}
    full = {s: d for s, d in full.items() if d is not None}
    if not full:
        return out
    rows = {}
    for s, dsg in full.items():
        sl = slice(0, 3) if s == "accel" else slice(6, 9)
        rows[s] = dsg.rows(stats.mean[:, sl] / scales[s])
    chosen: list[int] = []
    info = {s: np.eye(dsg.model.d) * 1e-9 for s, dsg in full.items()}
    best = None
    while len(chosen) < K:
        left = np.array([i for i in range(K) if i not in chosen])
        scores = np.zeros(len(left))
        for s, dsg in full.items():
            var = (dsg.s_w2 / stats.n[left] + dsg.tau2) * dsg.phi
            r = rows[s][left]
            I = info[s] + r[:, :, None] * r[:, None, :] / var[:, None, None]
            scores += np.trace(dsg.M @ np.linalg.pinv(I), axis1=1, axis2=2) / targets.of(s) ** 2
        if "gyro" in sensors:
            scores -= 1e-12 * stats.n[left]
        i = int(left[int(np.argmin(scores))])
        chosen.append(i)
        for s, dsg in full.items():
            var = (dsg.s_w2 / stats.n[i] + dsg.tau2) * dsg.phi
            info[s] = info[s] + np.outer(rows[s][i], rows[s][i]) / var
        n = len(chosen)
        if n >= MIN_POSES and met_all and best is None and ok(sorted(chosen))[0]:
            best = n
            out["subset"] = [int(x) for x in sorted(chosen)]
        if n in ks:
            for s in b_all:
                curve["best_subset"][s].append(ok(sorted(chosen))[1].get(s))
    labs = stats.labels if len(stats.labels) else np.arange(1, K + 1)
    out["subset"] = [int(labs[j]) for j in out["subset"]]
    curve["order"] = [int(labs[j]) for j in chosen]
    out["best_subset"] = best
    return out


# --------------------------------------------------------------------------
# what the guided flow asks (capture.guide.AdaptiveCapture's planner)
# --------------------------------------------------------------------------
@dataclass
class Advice:
    all_met: bool
    text: str
    next_up: np.ndarray | None
    samples: int
    assessment: Assessment


class Planner:
    """``planner(mean (K, 9), sd (K, 9), n (K,)) -> Advice`` for
    ``capture.guide.AdaptiveCapture``: raw-count pose statistics in, where
    the calibration stands and the next pose out."""

    def __init__(self, scales: dict, targets: Targets = Targets(), *,
                 min_angle_deg: float = 15.0, lo_samples: int = MIN_POSE_SAMPLES,
                 hi_samples: int = MAX_POSE_SAMPLES, q: float = CONFIDENCE):
        self.scales = dict(scales)
        self.targets = targets
        self.min_angle = float(min_angle_deg)
        self.lo, self.hi, self.q = int(lo_samples), int(hi_samples), float(q)

    def __call__(self, mean, sd, n) -> Advice:
        st = PoseStats(np.asarray(mean, float), np.asarray(sd, float), np.asarray(n, float))
        a = assess(st, self.scales, self.targets, min_angle_deg=self.min_angle,
                   lo_samples=self.lo, hi_samples=self.hi, q=self.q)
        return Advice(a.all_met, a.text(self.targets), a.next_up, a.samples, a)


def session_poses_needed(board, data, targets: Targets = Targets(),
                         q: float = CONFIDENCE, keep: bool = True) -> dict | None:
    """``poses_needed`` for a calibrated board (``calibrate_board``'s result)
    and its session (one mote): judged on the sensors its static poses
    calibrated (the magnetometer only when its calibration came from the
    poses, set O, not from a sweep).  Kept in ``cal.json`` under the
    accelerometer's ``quality["poses_needed"]`` (``keep``: the report asks
    without keeping); None without an accelerometer calibration from poses."""
    if board.accel is None or not (data.label >= 1).any():
        return None
    sensors = ["accel"]
    if board.mag is not None and board.mag.dataset == "O":
        sensors.append("mag")
    if board.gyro is not None:
        sensors.append("gyro")
    st = pose_stats(data.raw, data.label)
    out = poses_needed(st, data.scales, targets, sensors=tuple(sensors), q=q)
    if keep:
        board.accel.quality["poses_needed"] = out
    return out


def describe_poses_needed(pn: dict) -> list[str]:
    """The text ``motecal calibrate`` prints for ``poses_needed``."""
    t = pn["targets"]
    names = {"accel": f"accel {t['accel_g'] * 1e3:g} mg", "mag": f"mag {t['mag_rel'] * 1e2:g} %",
             "gyro": f"gyro bias {t['gyro_dps']:g} deg/s"}
    fmt = {"accel": lambda b: f"accel {b * 1e3:.3g} mg", "mag": lambda b: f"mag {b * 1e2:.3g} %",
           "gyro": lambda b: f"gyro {b:.3g} deg/s"}
    want = ", ".join(names[s] for s in pn["sensors"])
    have = ", ".join(fmt[s](pn["bounds_all"][s]) for s in pn["sensors"]
                     if pn["bounds_all"].get(s) is not None)     # one order, also from JSON
    lines = [f"  poses needed (promised error at {pn['confidence']:.0%} on fresh directions, "
             f"targets {want}):"]
    if pn["in_order"] is None:
        why = (f"fewer than {MIN_POSES} poses" if pn["poses"] < MIN_POSES
               else f"all {pn['poses']} poses promise {have}")
        lines.append(f"    the targets are not met ({why})")
        return lines
    lines.append(f"    all {pn['poses']} poses promise {have}")
    lines.append(f"    in the order taken: the first {pn['in_order']} of {pn['poses']}")
    if pn["best_subset"] is not None:
        lines.append(f"    best subset found: {pn['best_subset']} poses ("
                     + " ".join(str(x) for x in pn["subset"]) + ")")
    return lines
