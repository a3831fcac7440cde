"""Hidden effects for testing the diagnosis: plant one cause (or several) in
a simulated board at a random size above its detectability threshold, with a
random seed, and simulate a session.  Used by ``tests/test_diagnose*.py``
and ``bench/bench_diagnose.py``; the diagnosis is never told what was planted.

Each planted term goes where the diagnosis' forward chain has it (see
``extend``): ``cross_axis`` before the paper's ``scale_offset``, the others
after it, ``field_disturbance`` first, so the truth is exactly representable.

``causes.THRESHOLDS`` are the documented detectability thresholds: sizes are
drawn log-uniformly from [threshold, SPAN x threshold].
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field

import numpy as np

from motecal.diagnose.causes import THRESHOLDS  # noqa: F401 - the documented thresholds live with the vocabulary
from motecal.sessions.session import SessionData
from motecal.sim.model import SimModel, load_model
from motecal.sim.physics import K_NOMINAL
from motecal.sim.trajectory import make_trajectory

SPAN = 3.0



@dataclass
class Plant:
    cause: str
    sensor: str                    # accel | gyro | mag (motion: accel)
    kind: str                      # session kind it is planted in
    size: float                    # in THRESHOLDS' unit
    term: dict                     # simulator term
    level: str = "sensor"          # or "board"
    truth: dict = field(default_factory=dict)


def _sym_coupling(rng, m):
    C = rng.normal(0, 1, (3, 3))
    np.fill_diagonal(C, 0)
    S = 0.5 * (C + C.T)
    return (C * m / np.abs(S).max()).round(6)


def make_plant(cause: str, sensor_key: str, rng: np.random.Generator,
               scale: float = 1.0) -> Plant:
    """One planted effect of ``cause`` for ``sensor_key`` (a THRESHOLDS key's
    sensor part), size = threshold x log-uniform[1, SPAN] x ``scale``."""
    kind, thr, _ = THRESHOLDS[(cause, sensor_key)]
    sensor = sensor_key.split("-")[0]
    size = thr * float(np.exp(rng.uniform(0, np.log(SPAN)))) * scale
    a = int(rng.integers(3))
    sgn = float(rng.choice([-1.0, 1.0]))
    if cause == "cross_axis":
        term = {"term": "cross_axis", "C": _sym_coupling(rng, size).tolist()}
    elif cause == "nonlinearity":
        which = str(rng.choice(["q", "c3", "a"]))
        v = [0.0, 0.0, 0.0]
        v[a] = sgn * size
        term = {"term": "nonlinearity", which: v}
    elif cause == "bias_drift":
        v = [0.0, 0.0, 0.0]
        if sensor_key == "gyro-idle":
            term = {"term": "bias_drift", "sigma": [size] * 3}
        elif sensor == "gyro":
            v[a] = sgn * size
            term = {"term": "bias_drift", "amplitude": v,
                    "tau_s": float(rng.uniform(60, 300))}
        else:
            v[a] = sgn * size
            term = {"term": "bias_drift", "slope": v}
    elif cause == "g_sensitivity":
        G = rng.normal(0, 1, (3, 3))
        term = {"term": "g_sensitivity", "G": (G * size / np.abs(G).max()).round(6).tolist()}
    elif cause == "saturation":
        # the limit is set below the axis' largest reading when simulating
        # (``simulate``): depth = size (g / gauss) or size x peak (gyro)
        term = {"term": "saturation", "low": [-32768.0] * 3, "high": [32767.0] * 3}
        if sensor == "mag" and rng.random() < 0.5:
            term["overflow_code"] = -4096.0
        return Plant(cause, sensor, kind, size, term, truth={"axis": a, "side": sgn})
    elif cause == "stale_samples":
        term = {"term": "stale_samples", "update_hz": round(125.0 * (1.0 - min(size, 0.7)), 3)}
    elif cause == "motion":
        term = {"term": "motion", "rms_deg": round(size, 5),
                "bandwidth_hz": round(float(rng.uniform(1.5, 5.0)), 3)}
        return Plant(cause, "accel", kind, size, term, "board")
    elif cause == "field_disturbance":
        if sensor_key == "mag-rotation":
            term = {"term": "field_disturbance", "rms_gauss": round(size, 6),
                    "tau_s": round(float(rng.uniform(5, 15)), 3)}
        else:
            term = {"term": "field_disturbance", "pose_rms_gauss": round(size, 6)}
    else:
        raise ValueError(cause)
    return Plant(cause, sensor, kind, size, term)


def planted_model(plants: list[Plant], base: str = "paper") -> SimModel:
    """The base model with the planted terms in the diagnosis' chain order."""
    d = copy.deepcopy(load_model(base).to_json())
    tpl = d["defaults"]
    for p in plants:
        if p.level == "board":
            tpl.setdefault("terms", []).append(p.term)
            continue
        terms = tpl[p.sensor]["terms"]
        if p.cause == "field_disturbance":
            terms.insert(0, p.term)
        elif p.cause == "cross_axis":
            i = next(i for i, t in enumerate(terms) if t["term"] in ("scale_offset", "linear"))
            terms.insert(i, p.term)
        else:
            order = ["nonlinearity", "g_sensitivity", "bias_drift", "saturation", "stale_samples"]
            terms.append(p.term)
            terms.sort(key=lambda t: order.index(t["term"]) + 1 if t["term"] in order else 0)
        tpl[p.sensor]["terms"] = terms
    names = "+".join(f"{p.sensor}-{p.cause}" for p in plants) or "clean"
    return SimModel.from_json(d, f"{base}+{names}")


def simulate(plants: list[Plant], kind: str, seed: int, *, n_poses: int = 80,
             still_s: float = 2.5, duration: float | None = None,
             base: str = "paper", labelled: bool = True) -> SessionData:
    """One mote's session of ``kind`` with the planted effects; with
    ``labelled=False`` no row carries a label (an unguided log, kind
    ``free``): the diagnosis finds the still stretches itself."""
    traj = make_trajectory(kind, seed, n_poses=n_poses, still_s=still_s, duration=duration)
    sat = [p for p in plants if p.cause == "saturation"]
    if sat:
        # place each limit below the largest reading of its axis without it
        pre = [p for p in plants if p.cause != "saturation"]
        m0 = planted_model(pre, base)
        b0 = m0.board(1, seed)
        raw0 = b0.sampler(traj, seed).read(b0.sample_times(traj.duration)).astype(float)
        for p in sat:
            sl = {"accel": 0, "gyro": 3, "mag": 6}[p.sensor] + p.truth["axis"]
            side = p.truth["side"]
            ext = raw0[:, sl].max() if side > 0 else raw0[:, sl].min()
            depth = p.size * abs(ext) if p.sensor == "gyro" else p.size * K_NOMINAL[p.sensor]
            L = float(round(ext - side * depth))
            p.term = dict(p.term, low=list(p.term["low"]), high=list(p.term["high"]))
            (p.term["high"] if side > 0 else p.term["low"])[p.truth["axis"]] = L
            p.truth["limit"] = L
    model = planted_model(plants, base)
    board = model.board(1, seed)
    t = board.sample_times(traj.duration)
    raw = board.sampler(traj, seed).read(t).astype(float)
    n = len(t)
    return SessionData(
        name=f"planted-{model.name}-{kind}{'' if labelled else '-unlabelled'}-seed{seed}",
        raw=raw,
        mote=np.ones(n, np.int32), seq=np.arange(n, dtype=np.int64), t=t,
        label=traj.label_at(t) if labelled else np.zeros(n, np.int32),
        flags=np.zeros(n, np.uint8), kind=kind if labelled else "free",
        meta={"source": "sim", "rate_hz": model.rate_hz, "seed": int(seed),
              "model": model.name, "truth": board.to_json(),
              "planted": [{"cause": p.cause, "sensor": p.sensor, "size": p.size,
                           "term": p.term} for p in plants]},
        temp=board.temperature_reading_c(t) if board.thermal is not None else None)


# ---------------------------------------------------------------------------
# the truth's gain
# ---------------------------------------------------------------------------
def truth_gain(diag, plant: Plant) -> float | None:
    """Held-out gain the true term would give, measured the same way as the
    finding's: for terms that change the mean, held-out rms of the starting
    model over the rms a perfect model leaves (the noise of the held-out
    means); for spread terms, the same held-out statistic with the true
    parameters in place of the fitted ones."""
    from motecal.diagnose import gain as G
    f = next((f for f in diag.findings if f.cause == plant.cause and f.sensor == plant.sensor),
             None)
    if f is None:
        return None
    ev = f.evidence
    if plant.cause in ("cross_axis", "nonlinearity", "bias_drift", "g_sensitivity") or \
            (plant.cause == "field_disturbance" and "rms_gauss" in plant.term):
        st = diag.structures[plant.sensor]
        before = st.heldout[plant.cause][0]
        return before / st.noise_floor
    if plant.cause == "stale_samples":
        sc = next(s for s in diag.screens if s.cause == "stale_samples"
                  and s.sensor == plant.sensor)
        rho = plant.term["update_hz"] / ev["read_rate_hz"]
        pc = ev["chance_fraction"]
        after = (1 - rho) + rho * pc
        b = np.sqrt(np.mean((sc.block_stat - sc.pred_before) ** 2))
        a = np.sqrt(np.mean((sc.block_stat - after) ** 2))
        return float(b / a) if a > 0 else None
    if plant.cause == "field_disturbance" and "pose_rms_gauss" in plant.term:
        st = diag.structures["mag"]
        X, T = st.points["X"], st.points["T"]
        r = st.fit.residuals(X, T)
        tau2 = plant.term["pose_rms_gauss"] ** 2
        g, _, _ = G.variance_gain(r, st.points["V"], st.points["fold"], lambda m: tau2)
        return g
    if plant.cause == "motion":
        sc = next(s for s in diag.screens if s.cause == "motion")
        B = plant.term["bandwidth_hz"]
        lo = min(0.1, B / 2)
        ef2 = (B ** 3 - lo ** 3) / (3 * (B - lo))
        rate_var = (plant.term["rms_deg"] * 2 * np.pi) ** 2 * ef2 * K_NOMINAL["gyro"] ** 2
        b = np.sqrt(np.mean((sc.block_stat - sc.pred_before) ** 2))
        a = np.sqrt(np.mean((sc.block_stat - rate_var) ** 2))
        return float(b / a) if a > 0 else None
    return f.gain
