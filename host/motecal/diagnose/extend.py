"""The extended model as a simulator model file (``motecal sim --model``).

Each sensor's terms, in the order of the diagnosis' forward chain::

    field_disturbance (mag) -> cross_axis -> scale_offset (the paper's model)
    -> nonlinearity -> bias_drift -> saturation ; stale_samples ; white noise

plus the board's ``motion`` term, and the environment (field magnitude, dip)
found in the data.  The gyroscope's paper model is a constant bias
(``linear`` b), then ``g_sensitivity`` and ``bias_drift``.

Units: the file describes the measured board *as if its chips had the
simulator's nominal sensitivities* (256 LSB/g, 14.375 LSB/(deg/s),
1090 LSB/gauss): counts of other chips (MPU6050, HMC5843) are rescaled by
K_sim / K_chip, so a simulated session reproduces the measured statistics in
physical units.  Noise is the white noise without the rounding (the
simulator rounds itself).

``models`` builds both files of a diagnosis: the paper's starting model
fitted to the session, and that model extended by the findings.
"""
from __future__ import annotations

import numpy as np

from ..maths.sphere import unit
from ..sessions.session import CHIP_LIMITS
from ..sim.model import MODEL_FORMAT, MODEL_VERSION
from ..sim.physics import K_NOMINAL
from . import fitting as F
from . import structure as ST
from . import thermal as TH
from .prepare import SensorObs
from .regimes import MIN_SWEEP_ROWS, sweep_surrounds

TAU_GRID_S = (5.0, 15.0, 50.0, 150.0, 500.0, 1500.0)
SIM_LIMITS = {s: (float(lo), float(hi)) for s, (lo, hi) in CHIP_LIMITS.items()}


def _r(x, nd=6):
    if x is None:
        return None
    a = np.asarray(x, float)
    if a.ndim == 0:
        return float(f"{float(a):.{nd}g}")
    return [_r(v, nd) for v in a]


def sim_scale(sensor: str, K_data: float) -> float:
    return K_NOMINAL[sensor] / float(K_data)


def white_noise(sigma_counts, scale: float) -> list:
    """White noise for the simulator (sim counts) from the measured per-axis
    sigma (data counts, rounding included)."""
    s2 = np.asarray(sigma_counts, float) ** 2 - 1.0 / 12.0
    s = np.sqrt(np.clip(s2, 0.01, None)) * scale
    return _r(s, 4)


def affine_terms(A, c, K_sim: float, cross: bool) -> tuple[list, np.ndarray, np.ndarray]:
    """Terms for u = A raw/K + c (nominal units):  raw_sim = K_sim M u - K_sim M c
    with M = A^-1 = diag(1/s) (I + C).  Returns (terms, M, b_sim)."""
    M = np.linalg.inv(np.asarray(A, float))
    b = -K_sim * M @ np.asarray(c, float)
    if not cross:
        M = np.diag(np.diag(M))
    D = np.diag(M)
    C = M / D[:, None] - np.eye(3)
    np.fill_diagonal(C, 0.0)
    terms = []
    if cross:
        terms.append({"term": "cross_axis", "C": _r(C)})
    terms.append({"term": "scale_offset", "s": _r(1.0 / D), "o": _r(-b)})
    return terms, M, b


def drift_params(curve_t: np.ndarray, curve: np.ndarray, rough: bool, J: int) -> tuple[dict, np.ndarray]:
    """Simulator bias_drift parameters (counts, per axis) for a fitted offset
    curve (n, 3) at times curve_t (s since the start): amplitude (1 -
    exp(-t/tau)) + slope t, tau from a grid; a random-walk sigma from the
    curve's wander around that when the fine (random-walk) basis was chosen.
    Returns (params, value at t = 0 to fold into the offset)."""
    t = np.asarray(curve_t, float)
    y = np.asarray(curve, float) - curve[0]
    best = None
    for tau in TAU_GRID_S:
        X = np.column_stack([1.0 - np.exp(-t / tau), t])
        coef, *_ = np.linalg.lstsq(X, y, rcond=None)
        sse = float(np.sum((y - X @ coef) ** 2))
        if best is None or sse < best[0]:
            best = (sse, tau, coef)
    _, tau, coef = best
    resid = y - np.column_stack([1.0 - np.exp(-t / tau), t]) @ coef
    sigma = np.zeros(3)
    if rough and len(t) > 2 * J:
        span = t[-1] - t[0]
        dt = span / J
        grid = np.linspace(t[0], t[-1], J + 1)
        rg = np.array([np.interp(grid, t, resid[:, a]) for a in range(3)]).T
        sigma = np.sqrt(np.mean(np.diff(rg, axis=0) ** 2, axis=0) / dt)
    return ({"amplitude": _r(coef[0]), "tau_s": _r(tau), "slope": _r(coef[1]),
             "sigma": _r(sigma)}, np.asarray(curve[0], float))


def magnitude_sensor_terms(fit: F.MagnitudeFit, sensor: str, K_data: float, t0: float,
                           trange) -> tuple[list, dict]:
    """Terms of an accelerometer/magnetometer from a magnitude fit (data
    units), in simulator counts.  Returns (terms, info)."""
    scale = sim_scale(sensor, K_data)
    A, c, H = fit.affine()
    cross = fit.family == "full"
    tb, parts = fit.split()
    extras = dict(zip([type(e) for e in fit.extras], zip(fit.extras, parts)))
    terms, M, b = affine_terms(A, c, K_NOMINAL[sensor], cross)
    info = {"field": H, "M": M, "b": b}
    if F.NonlinearityExtra in extras:
        _, p = extras[F.NonlinearityExtra]
        terms.append({"term": "nonlinearity", "q": _r(p[0:3]), "c3": _r(p[3:6]),
                      "a": _r(p[6:9])})
    if F.DriftExtra in extras:
        e, p = extras[F.DriftExtra]
        tt = np.linspace(trange[0], trange[1], 200)
        curve = e.offset(tt, p) * scale
        dp, d0 = drift_params(tt - t0, curve, e.J > F.DRIFT_J, e.J)
        # the curve's value at the first time goes into the offset (x / s - o)
        so = terms[-1] if terms[-1]["term"] == "scale_offset" else \
            next(t for t in terms if t["term"] == "scale_offset")
        so["o"] = _r(np.asarray(so["o"], float) - d0)
        terms.append({"term": "bias_drift", **dp})
        info["drift_range"] = float(np.ptp(curve, axis=0).max()) / scale
    return terms, info


def gyro_terms(lin: F.LinearFit, K_data: float, t0: float, trange) -> tuple[list, dict]:
    scale = sim_scale("gyro", K_data)
    beta = lin.beta
    cg = lin.groups.get("const", [0])
    bias = beta[cg].mean(axis=0)                   # counts (data)
    terms = []
    info = {"bias_counts": bias}
    extra_b = np.zeros(3)
    drift = None
    if "bias_drift" in lin.groups:
        cols = lin.groups["bias_drift"]
        J = len(cols)
        tt = np.linspace(trange[0], trange[1], 200)
        Phi = F.time_basis(tt, trange[0], trange[1], J)
        curve = Phi @ beta[cols] * scale
        dp, d0 = drift_params(tt - t0, curve, J > F.DRIFT_J, J)
        extra_b = d0
        drift = {"term": "bias_drift", **dp}
        info["drift_range"] = float(np.ptp(curve, axis=0).max()) / scale
    terms.append({"term": "linear", "b": _r(bias * scale + extra_b)})
    if "g_sensitivity" in lin.groups:
        G = beta[lin.groups["g_sensitivity"]].T / K_data        # deg/s per g, row = gyro axis
        terms.append({"term": "g_sensitivity", "G": _r(G)})
        info["G"] = G
    if drift is not None:
        terms.append(drift)
    return terms, info


def saturation_term(params: dict, sensor: str, K_data: float) -> dict:
    scale = sim_scale(sensor, K_data)
    lo_chip, hi_chip = SIM_LIMITS[sensor]
    low = [max(lo_chip, v * scale) if v > -32768 else -32768.0 for v in params["low"]]
    high = [min(hi_chip, v * scale) if v < 32767 else 32767.0 for v in params["high"]]
    d = {"term": "saturation", "low": _r(low), "high": _r(high)}
    if params.get("overflow_code") is not None:
        d["overflow_code"] = float(params["overflow_code"])
    return d


def model_json(name: str, mote: int, rate_hz: float, environment: dict, sensors: dict,
               board_terms: list, description: str) -> dict:
    """The model file: one explicit board (the measured one) that is also the
    template for any other mote id."""
    board = {"clock_ppm": 0.0, "terms": board_terms}
    for s in ("accel", "gyro", "mag"):
        if s in sensors:
            board[s] = sensors[s]
    return {"format": MODEL_FORMAT, "version": MODEL_VERSION, "name": name,
            "description": description, "rate_hz": _r(rate_hz),
            "environment": environment, "defaults": board, "boards": {str(int(mote)): board}}


# ---------------------------------------------------------------------------
# the models: the fitted start model and its extension by the findings
# ---------------------------------------------------------------------------
def models(data, obs, sobs, structures, findings, screens, mot):
    kept = {(f.sensor, f.cause): f for f in findings}
    rate = data.rate()
    sensors_start, sensors_ext = {}, {}
    env = {"gravity_g": 1.0, "field_gauss": 0.48, "inclination_deg": 60.0,
           "declination_deg": 0.0}
    for s in ("accel", "gyro", "mag"):
        o = sobs.get(s)
        if o is None:
            continue
        st = structures.get(s)
        scale = sim_scale(s, o.K)
        t0 = float(o.t[0])
        noise = white_noise(o.sigma, scale) if np.all(np.isfinite(o.sigma)) else [0, 0, 0]
        start_terms, ext_terms = [], []
        if s in ("accel", "mag"):
            fit0, fitx = _magnitude_fits(o, st)
            if fit0 is not None:
                trange = (float(o.t.min()), float(o.t.max()))
                start_terms, info0 = magnitude_sensor_terms(fit0, s, o.K, t0, trange)
                ext_terms, info = magnitude_sensor_terms(fitx, s, o.K, t0,
                                                           st.points["trange"] if st else trange)
                if s == "mag":
                    env["field_gauss"] = round(float(info["field"]), 6)
        else:
            if st is not None:
                start_terms, _ = gyro_terms(st.fit0, o.K, t0, st.points["trange"])
                ext_terms, _ = gyro_terms(st.fit, o.K, t0, st.points["trange"])
            else:
                b = np.median(o.x, axis=0) * scale
                start_terms = ext_terms = [{"term": "linear", "b": _r(b)}]
        if (s, "bias_drift") in kept and s in ("accel", "mag") and st is not None \
                and st.regime == "single":
            ext_terms.append({"term": "bias_drift", **kept[(s, "bias_drift")].params})
        if (s, "bias_drift") in kept:
            # the random walk measured on top of the smooth drift
            for t in ext_terms:
                if t["term"] == "bias_drift":
                    t["sigma"] = kept[(s, "bias_drift")].params.get("sigma", t["sigma"])
            if not any(t["term"] == "bias_drift" for t in ext_terms):
                ext_terms.append({"term": "bias_drift", **kept[(s, "bias_drift")].params})
        if s == "mag" and (s, "field_disturbance") in kept:
            ext_terms = [{"term": "field_disturbance",
                          **kept[(s, "field_disturbance")].params}] + ext_terms
        if (s, "temperature") in kept:
            tp = kept[(s, "temperature")].params
            ext_terms.append({"term": "temperature", "t_ref_c": tp["t_ref_c"],
                              "offset_per_c": _r(np.asarray(tp["offset_per_c"]) * scale)})
        if (s, "saturation") in kept:
            ext_terms.append(saturation_term(kept[(s, "saturation")].params, s, o.K))
        if (s, "stale_samples") in kept:
            ext_terms.append({"term": "stale_samples", **kept[(s, "stale_samples")].params})
        sensors_start[s] = {"noise": noise, "terms": start_terms}
        sensors_ext[s] = {"noise": noise, "terms": ext_terms}
    incl = _inclination(structures, sobs)
    if incl is not None:
        env["inclination_deg"] = round(incl, 3)
    board_terms = []
    if ("accel", "motion") in kept:
        board_terms.append({"term": "motion", **kept[("accel", "motion")].params})
    if any(c == "temperature" for _, c in kept):
        board_terms.append(TH.thermal_term(data))
    mote = data.motes[0]
    start = model_json(f"{data.name}-paper", mote, rate, dict(env), sensors_start, [],
                         f"the paper's starting model fitted to session {data.name}")
    causes_txt = ", ".join(f"{f.sensor} {f.cause}" for f in findings) or "nothing"
    ext = model_json(f"{data.name}-extended", mote, rate, dict(env), sensors_ext, board_terms,
                       f"session {data.name}: the paper's model extended by motecal diagnose "
                       f"({causes_txt})")
    return start, ext


def _magnitude_fits(o: SensorObs, st):
    """(start fit, final fit) for the model files: the structure's when there
    is one; else a paper fit on whatever still means exist (>= 6)."""
    if st is not None and isinstance(st.fit, F.MagnitudeFit):
        return st.fit0, st.fit
    if o.segs is not None and len(o.segs) >= 6:
        f = F.fit_magnitude(o.sensor, o.K, o.segs.mean, o.segs.t, np.ones(len(o.segs)))
        return f, f
    if o.sensor == "mag" and o.moving is not None and o.moving.sum() >= MIN_SWEEP_ROWS \
            and sweep_surrounds(o):
        x = o.x[~o.overflow]
        f = F.fit_magnitude(o.sensor, o.K, x, o.t[~o.overflow], np.ones(len(x)))
        return f, f
    return None, None


def _inclination(structures, sobs):
    a, m = structures.get("accel"), structures.get("mag")
    acc, mag = sobs.get("accel"), sobs.get("mag")
    if a is None or m is None or a.regime != "poses" or m.regime != "poses":
        return None
    g, b, _, _ = ST.pose_vectors(acc, a.fit, mag, m.fit, m.points["group"])
    if not len(g):
        return None
    dots = np.sum(unit(g) * unit(b), axis=1)
    return float(np.degrees(np.arcsin(np.clip(-np.mean(dots), -1, 1))))
