"""Closing the loop: calibration error with and without the diagnosis' terms
(``calibrate --diagnosis``), per cause, on planted boards against the truth,
and on the shared measured data on held-out data (prints figures next to the
goals; exit 0).

Planted boards (the simulator's 'general' board: 1-2 % cross-axis coupling;
``tests/plant.py``), for the causes the calibration can use: clipped
accelerometer poses (saturation), repeated accelerometer readings (stale
samples), and wild single readings in a magnetometer sweep (0.5 % of the
readings off by 20-70 % of the field, as in the metal-hull recording).  Per
board, four calibrations, each judged by its vector error on 2000 fresh
directions against the simulator's true map (``tests/synthetic.py``):

* paper -- the paper's model (offsets + scales) on the data;
* full -- the full model on the data;
* full + diagnosis -- the full model with what ``diagnose`` found applied
  (``calib.terms.apply_diagnosis``);
* true -- the full model on the same session simulated without the planted
  effect (same seed and noise): what a calibration reaches when the effect is
  accounted for perfectly.

Goals (issue 13): with the diagnosis terms, the error within 10 % of the
true model's, and never worse than without them.

Measured data: for the sweeps whose diagnosis names outliers, the held-out
magnitude error (5 folds of interleaved 2 s chunks; every reading of the
held-out chunks, outliers included: rms and 95th percentile of |error|)
without and with the diagnosis terms.
"""
import os

import benchenv  # noqa: F401,E402  (one BLAS thread a process; host/, tests/, bench/ on the path)

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from multiprocessing import Pool  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = benchenv.ROOT

import numpy as np  # noqa: E402

import plant as P  # noqa: E402
from motecal.calib.board import calibrate_board  # noqa: E402
from motecal.calib.extra_terms import apply_nonlinearity, gyro_rate_bias  # noqa: E402
from motecal.calib.loop import calibrate_with_diagnosis  # noqa: E402
from motecal.calib.terms import Treatment, apply_diagnosis, drop_rows  # noqa: E402
from motecal.diagnose.causes import THRESHOLDS  # noqa: E402
from motecal.diagnose.engine import diagnose  # noqa: E402
from results import record  # noqa: E402
from synthetic import true_affine  # noqa: E402

BASE = "general"
CAUSES = ["saturation-accel", "stale_samples-accel", "nonlinearity-accel", "outliers-mag",
          "spans-mag", "field_disturbance-mag-rotation", "g_sensitivity-gyro", "bias_drift-gyro"]
# a field wandering over the whole sweep: no term calibrate can fit (a time-varying
# field cannot be told reliably from the directions' shape in one 40 s sweep);
# calibrated through.  Shown as context, in the never-worse goal, not in the 10 % goal.
CONTEXT = ("field_disturbance-mag-rotation",)
TERMS = ("nonlinearity", "g_sensitivity", "bias_drift")     # model terms: the reference is
                                                            # that term fitted (oracle)
UNITS = {"accel": "mg", "mag": "mgauss", "gyro": "deg/s"}


def _spikes(ses, seed, frac=0.005):
    """Wild single readings in the sweep: 0.5 % of them off by 20-70 % of the
    field in a random direction."""
    rng = np.random.default_rng([seed, 0x5B])
    raw = ses.raw.copy()
    n = len(raw)
    idx = rng.choice(n, max(1, int(frac * n)), replace=False)
    d = rng.normal(size=(len(idx), 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    raw[idx, 6:9] += np.round(d * rng.uniform(0.2, 0.7, (len(idx), 1)) * 0.48 * 1090.0)
    out = ses.select(np.ones(n, bool))
    out.raw = raw
    return out


def _disturbed_spans(ses, seed, pt):
    """Two spans of 2-4 s of the sweep in a field 3-8 % stronger or weaker (a
    magnet or a steel object passing): the readings' true field scaled about
    the true hard-iron offset."""
    rng = np.random.default_rng([seed, 0x5C])
    raw = ses.raw.copy()
    t = ses.sample_times()
    b = np.asarray(pt["mag"]["b"], float)
    where = np.zeros(len(raw), bool)
    for k in range(2):
        t0 = rng.uniform(t[0] + 2 + 18 * k, t[0] + 14 + 18 * k)
        m = (t >= t0) & (t < t0 + rng.uniform(2.0, 4.0))
        f = 1.0 + rng.choice([-1.0, 1.0]) * rng.uniform(0.03, 0.08)
        raw[m, 6:9] = np.round(b + (raw[m, 6:9] - b) * f)
        where |= m
    out = ses.select(np.ones(len(raw), bool))
    out.raw = raw
    return out, where


def _dirs():
    d = np.random.default_rng(12345).standard_normal((2000, 3))
    return d / np.linalg.norm(d, axis=1)[:, None]


def _raw_of(pt, sensor, u, nl=None):
    """Noise-free counts of true vectors u, through the planted nonlinearity
    (the simulator's term, after the affine map) when given."""
    A_t, c_t = true_affine(pt, sensor)
    raw = np.linalg.solve(A_t, (u - c_t).T).T
    if nl:
        K = float(pt[sensor]["K"])
        q, c3, a = (np.asarray(nl.get(k, [0.0] * 3), float) for k in ("q", "c3", "a"))
        r = raw / K
        raw = raw + K * (q * r * r + c3 * r * r * r)
        raw = raw * (1.0 + a * np.sign(raw))
    return raw


def _accel_error(sc, pt, dirs, nl):
    """Vector error (g) on fresh directions of 1 g, after the best rotation
    (a magnitude fitness determines the map up to one)."""
    from scipy.spatial.transform import Rotation
    v = apply_nonlinearity(sc, _raw_of(pt, "accel", dirs, nl))
    R, _ = Rotation.align_vectors(dirs, v)
    e = R.apply(v) - dirs
    return float(np.sqrt(np.mean(np.sum(e * e, axis=1))))


def _mag_error(sc, pt, dirs):
    """Vector error of a magnetometer calibration in gauss on fresh field
    directions, its magnitude scaled to the true field (the det gauge fixes
    the scale only as well as the datasheet gain)."""
    from scipy.spatial.transform import Rotation
    B = 0.48
    u = B * dirs
    v = sc.apply(_raw_of(pt, "mag", u)) * (B / sc.field_gauss)
    R, _ = Rotation.align_vectors(u, v)
    e = R.apply(v) - u
    return float(np.sqrt(np.mean(np.sum(e * e, axis=1))))


def _gyro_error(board, pt, dirs, drift, t_end):
    """The still rate the calibration predicts (its bias, with a
    g-sensitivity for the orientation) against the true one, at the end of
    the session (after the warm-up), rms over fresh orientations (deg/s)."""
    sc = board.gyro
    K = float(pt["gyro"]["K"])
    true = (np.asarray(pt["gyro"]["b"], float) / K
            + dirs @ np.asarray(pt["gyro"].get("G", np.zeros((3, 3))), float).T)
    if drift:
        amp = np.asarray(drift.get("amplitude", [0.0] * 3), float)
        slope = np.asarray(drift.get("slope", [0.0] * 3), float)
        true = true + (amp * (1 - np.exp(-t_end / float(drift.get("tau_s", 300.0))))
                       + slope * t_end) / K
    a_cal = board.accel.apply(_raw_of(pt, "accel", dirs)) if board.accel is not None else dirs
    e = gyro_rate_bias(sc, a_cal) - true
    return float(np.sqrt(np.mean(np.sum(e * e, axis=1))))


def run_case(case, lean=False):
    """One planted board of ``case`` = (cause, seed): the error of each
    calibration against the truth (``lean``: without the paper model and
    the every-treatment arm, for the tests)."""
    cause, seed = case
    rng = np.random.default_rng([seed, 31])
    c, key = cause.split("-", 1)
    sensor = key.split("-")[0]
    if c in ("outliers", "spans"):
        plants, kind = [], "rotation"
    else:
        plants = [P.make_plant(c, key, rng)]
        kind = THRESHOLDS[(c, key)][0]
        kind = "static80" if kind == "idle" else kind
    ses = P.simulate(plants, kind, seed, base=BASE)
    twin = P.simulate([], kind, seed, base=BASE)
    pt = P.planted_model(plants, BASE).board(1, seed).physical_truth()
    pt0 = P.planted_model([], BASE).board(1, seed).physical_truth()
    if c == "outliers":
        ses = _spikes(ses, seed)
    elif c == "spans":
        ses, planted_rows = _disturbed_spans(ses, seed, pt)
    d = diagnose(ses, simulate=False)
    kw = dict(seed=1, kfold=0, gyro_matrix=False)

    def cal(x):
        return calibrate_board(x, **kw)
    full_diag, rep = calibrate_with_diagnosis(ses, d.to_json(), cal)
    if c in TERMS:      # the true model: the planted term's family fitted, no held-out check
        true, _ = calibrate_with_diagnosis(ses, {"findings": [{"sensor": sensor, "cause": c}]},
                                           cal, z_accept=-np.inf)
    elif c == "spans":  # the same session without exactly the planted spans
        true = cal(drop_rows(ses, [Treatment("mag", "spans", "", drop=planted_rows)]))
        if true.mag is None:                 # they leave too little of the sphere
            true = cal(twin)
    else:               # the same session without the planted readings
        true = cal(twin)
    cals = {"full": cal(ses), "full + diagnosis": full_diag, "true": true,
            "no effect": true if c not in TERMS + ("spans",) else cal(twin)}
    if not lean:
        cals["paper"] = calibrate_board(ses, model="paper", groups=("offsets", "scales"), **kw)
        cals["every treatment"] = cal(apply_diagnosis(ses, d.to_json())[0])
    dirs = _dirs()
    term = plants[0].term if plants else {}
    lab = np.flatnonzero(ses.label >= 1)
    t = ses.sample_times()
    t_end = float(t[ses.label == ses.label[lab[-1]]].mean() - t[0]) if len(lab) else 0.0
    err = {}
    for k, b in cals.items():
        sc = getattr(b, sensor)
        clean = k == "no effect" or (k == "true" and c not in TERMS + ("spans",))
        truth = pt0 if clean else pt
        if sc is None:
            err[k] = np.nan
        elif sensor == "accel":
            nl = term if (c == "nonlinearity" and not clean) else None
            err[k] = _accel_error(sc, truth, dirs, nl) * 1e3                  # mg
        elif sensor == "mag":
            err[k] = _mag_error(sc, truth, dirs) * 1e3                        # mgauss
        else:
            drift = term if (c == "bias_drift" and not clean) else None
            err[k] = _gyro_error(b, truth, dirs, drift, t_end)                # deg/s
    return {"cause": cause, "seed": seed, "err": err, "used": rep["used"],
            "not_used": rep["not_used"], "named": sorted(d.causes())}


MEASURED_SETS = [
    ("sensorstick-mag-sweep/magnetom.float", None),
    ("metal-hull-sweep/magnetom.float", None),
    ("hmc5843-disturbed-sweep/magnetom.float", "mag=hmc5843"),
    ("sensorstick-boards/razor1/razor1_acc_*.raw", None),
    ("sensorstick-boards/razor2/razor2_acc_*.raw", None),
    ("sensorstick-boards/razor1/razor1_gyr_xyz.raw", None),
    ("sensorstick-boards/razor2/razor2_gyr_xyz.raw", None),
    ("mpu6050-hmc5883l-timestamped/full-sphere", None),
    ("mpu6050-hmc5883l-timestamped/unmoved-with-x-pointing-forward", None),
    ("mpu6050-hmc5883l-timestamped/rotate-ccw-around-z-pointing-up", None),
]


def _gate(board):
    from motecal.calib.gate import decide
    d = decide(board)
    return "accepted" if d.accepted else "refused"


def measured_case(item):
    """One measured data set: diagnosed, calibrated without and with the
    diagnosis (the paper model with offsets + scales for six-pose boards,
    as their documentation says; the full model otherwise)."""
    from conftest import MEASURED
    from motecal.sessions.importer import read_any
    rel, chip = item
    paths = sorted(MEASURED.glob(rel)) if "*" in rel else [MEASURED / rel]
    data = read_any([str(p) for p in paths], chip=chip)
    d = diagnose(data, simulate=False)
    six = "razor" in rel and "acc" in rel
    kw = dict(seed=1, kfold=5)
    if six:
        kw.update(model="paper", groups=("offsets", "scales"))

    def cal(x):
        return calibrate_board(x, **kw)
    plain = cal(data)
    g0 = _gate(plain)
    board, rep = calibrate_with_diagnosis(data, d.to_json(), cal)
    g1 = _gate(board)
    name = rel.replace("/magnetom.float", "").replace("mpu6050-hmc5883l-timestamped/", "mpu6050 ")
    name = name.replace("sensorstick-boards/", "").replace("_*.raw", "").replace(".raw", "")
    return {"name": name, "named": sorted(f"{s} {c}" for s, c in d.causes()),
            "gate": (g0, g1), "rep": rep,
            "sensors": [n for n, _ in board.sensors()]}


def measured_section(jobs):
    with Pool(jobs) as pool:
        return pool.map(measured_case, MEASURED_SETS, chunksize=1)


def _fmt_dec(x):
    if x.get("why"):
        return f"{x['sensor']} {x['what']}: not judged ({x['why']})"
    u = "%" if x["unit"] == "relative" else x["unit"]
    k = 100.0 if x["unit"] == "relative" else 1.0
    return (f"{x['sensor']} {x['what']}: {k * x['heldout_rms_before']:.3g} -> "
            f"{k * x['heldout_rms_after']:.3g} {u} ({'used' if x['used'] else 'not used'}, "
            f"z {x['z']:+.1f})")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--boards", type=int, default=6, help="boards per cause (6)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--no-measured", action="store_true", help="planted boards only")
    ap.add_argument("--measured-only", action="store_true", help="the measured data only")
    a = ap.parse_args(argv)
    if a.measured_only:
        return measured_table(a.jobs)
    cs = [(c, a.seed * 100000 + 1000 * i + j) for i, c in enumerate(CAUSES)
          for j in range(a.boards)]
    t0 = time.time()
    with Pool(a.jobs) as pool:
        res = pool.map(run_case, cs, chunksize=1)
    print(f"closing the loop: {len(res)} planted boards in {time.time() - t0:.0f} s wall "
          f"(command: .venv/bin/python bench/bench_diagnose_loop.py)")
    print()
    print("calibration error against the truth, median over boards: vector error on 2000 fresh "
          "directions (accel mg, mag mgauss), the still rate's error at the end of the session "
          "over 2000 fresh orientations (gyro deg/s):")
    print(f"{'cause':<31}{'paper':>8}{'full':>8}{'full+diag':>10}{'true':>8}{'no effect':>10}"
          f"   {'full+diag / true':>17}  {'never worse':>11}  {'used':>6}")
    worst_ratio, all_never_worse, worst_vs_full = 0.0, True, 0.0
    context = ("", float("nan"), float("nan"))
    for c in CAUSES:
        rs = [r for r in res if r["cause"] == c]
        e = {k: np.array([r["err"][k] for r in rs]) for k in rs[0]["err"]}
        ratio = e["full + diagnosis"] / e["true"]
        never = e["full + diagnosis"] <= e["full"] * 1.0001
        if c not in CONTEXT:
            worst_ratio = max(worst_ratio, float(np.nanmedian(ratio)))
        else:
            context = (c, float(np.nanmedian(e["full + diagnosis"])),
                       float(np.nanmedian(e["no effect"])))
        all_never_worse &= bool(never.all())
        worst_vs_full = max(worst_vs_full, float(np.nanmax(e["full + diagnosis"] / e["full"])))
        n_used = sum(bool(r["used"]) for r in rs)
        print(f"{c:<31}{np.nanmedian(e['paper']):8.3f}{np.nanmedian(e['full']):8.3f}"
              f"{np.nanmedian(e['full + diagnosis']):10.3f}{np.nanmedian(e['true']):8.3f}"
              f"{np.nanmedian(e['no effect']):10.3f}   "
              f"{np.nanmedian(ratio):8.3f} (max {np.nanmax(ratio):.2f})  "
              f"{int(never.sum()):>6} of {len(rs):<2}  {n_used:>3} of {len(rs)}"
              + ("   (context: no term)" if c in CONTEXT else ""))
    print()
    print("true: for a model term (nonlinearity, g-sensitivity, drift) that term fitted without "
          "the held-out check; for readings left out, the same session simulated without the "
          "planted readings (= no effect). used: boards where a treatment or term was used.")
    print(f"context: {context[0]}, a field wandering over the whole sweep, has no term "
          "calibrate can fit (a time-varying field cannot be told from the direction's in one "
          f"sweep): calibrated through, {context[1]:.3g} mgauss against {context[2]:.3g} "
          "without the wander.")
    print("goals: full + diagnosis within 10 % of the true model (median per cause, worst "
          f"{worst_ratio:.3f}); never worse than without the terms "
          f"({'held' if all_never_worse else 'NOT held'} on every board; worst full + diagnosis "
          f"/ full {worst_vs_full:.3f})")
    record("calibration with the diagnosis terms / the true model's error",
           "<= 1.10 (#13)", worst_ratio, "", worst_ratio <= 1.10, digits=3,
           note=f"worst cause's median over {a.boards} planted boards; causes: "
                + ", ".join(c for c in CAUSES if c not in CONTEXT))
    record("  a field wandering over a whole sweep (no term): full + diagnosis, vector error",
           "-", context[1], "mgauss", None, digits=3,
           note=f"calibrated through; {context[2]:.3g} mgauss without the wander (median over "
                f"{a.boards} boards)")
    record("calibration with the diagnosis terms never worse than without", "every board (#13)",
           "held" if all_never_worse else "not held", "", all_never_worse,
           note=f"{len(res)} planted boards; worst full + diagnosis / full "
                f"{worst_vs_full:.3f}")
    if a.no_measured:
        return 0
    return measured_table(a.jobs)


def measured_table(jobs):
    print()
    print("measured data (../shared/data/measured): gate without -> with the diagnosis, what was "
          "used, held-out rms before -> after of each treatment or term tried (the same held-out "
          "poses or 1 s chunks for both; % of the target for accel/mag):")
    print()
    print("| data set | diagnosis named | gate: plain -> with the diagnosis | used | held-out rms "
          "before -> after | not tried, and why |")
    print("| --- | --- | --- | --- | --- | --- |")
    for r in measured_section(jobs):
        used = [u.split(":")[0] for u in r["rep"]["used"]] or ["nothing"]
        decs = "; ".join(_fmt_dec(x) for x in r["rep"]["decisions"]) or "-"
        why = "; ".join(u for u in r["rep"]["not_used"]
                        if "held-out" not in u and "cross_axis" not in u) or "-"
        print(f"| {r['name']} | {', '.join(r['named']) or 'clean'} | {r['gate'][0]} -> "
              f"{r['gate'][1]} | {', '.join(used)} | {decs} | {why} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
