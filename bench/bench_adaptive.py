"""The adaptive guided session against the fixed protocols (issue 19): poses
and person-time to reach 0.5 mg rms accelerometer error on fresh directions
and 0.3 % magnetometer shape error, and the achieved error against the truth
(prints figures next to the goals; exit 0).

Boards: the simulator's 'general' model (offsets, scales, 1-2 % cross-axis
coupling, white noise), one board per seed.  A person (``sim.person``)
follows each flow's suggestions: a reaction of 1-2 s, a minimum-jerk move of
1.0-1.5 s, the board placed 6 deg rms off the suggested gravity direction at
a heading of its own, hand tremor of 0.04 deg rms while holding.  The same
state machines as ``motecal log`` (``capture.guide``), fed straight from the
board's samples (no radio: ``sim.person.run_guided``).  Protocols:

* adaptive -- ``--guided adaptive`` with its defaults (targets 0.5 mg,
  0.3 %, 0.05 deg/s; 12 seed poses of 400 samples; 100-1000 samples a pose);
* fixed 80 -- ``--guided static80``: 80 poses of 200 samples;
* 6 faces + sweep -- the six +-axis faces (200 samples each; the
  accelerometer gets offsets + scales, as ArduPilot's 6-face calibration;
  the full model is not identifiable from six faces) and a magnetometer sweep
  (``--guided rotation``: the simulator's rotation until 90 % coverage or
  5000 samples), the magnetometer from the sweep.

Every session is calibrated by ``calib.calibrate_board`` (what ``motecal
calibrate`` runs) and judged on 2000 fresh directions against the planted
map (``tests/synthetic.py``): accelerometer rms |calibrated - true| in its
gauge frame, magnetometer rms |calibrated / fitted field - true / field| (the
shape).  Person-time: from the start until the flow is done (reactions,
moves, holds, refused placements; for 6 + sweep also one move to the sweep
and the sweep).

Goals: the accuracy asked (0.5 mg, 0.3 %) as the 80 fixed poses reach it,
with at most a third of their poses (median over boards); and the promised
error at the stop not optimistic by more than 20 % (true <= 1.2 x promised)
in at least 90 % of boards.
"""

import benchenv  # noqa: F401,E402  (one BLAS thread a process; host/, tests/, bench/ on the path)

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from multiprocessing import Pool  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = benchenv.ROOT

import numpy as np  # noqa: E402

from motecal.calib.board import calibrate_board  # noqa: E402
from motecal.calib.design import Planner, TARGET_ACCEL_G, TARGET_MAG_REL  # noqa: E402
from motecal.capture.guide import (AdaptiveCapture, PoseCapture,  # noqa: E402
                                   RotationCapture)
from motecal.sessions.session import LABEL_ROT, NOMINAL_SCALES, SessionData  # noqa: E402
from motecal.sim import load_model, simulate_session  # noqa: E402
from motecal.sim.person import REACTION_S, run_guided  # noqa: E402
from motecal.sim.trajectory import move_duration  # noqa: E402
from results import record  # noqa: E402
from synthetic import fresh_directions, true_affine, vector_error  # noqa: E402
from motecal.calib.models import lower_factor  # noqa: E402

MODEL = "general"
RATE = 125.0
FACES = np.array([[0, 0, 1.0], [0, 0, -1], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0]])


def shape_error(sc, pt, field: float) -> float:
    """rms over fresh directions of |calibrated / fitted field - true / field|,
    the true vectors in the calibration's gauge frame (the planted map)."""
    A_t, c_t = true_affine(pt, "mag")
    u_true = field * fresh_directions()
    raw = np.linalg.solve(A_t, (u_true - c_t).T).T
    v = sc.apply(raw)
    L = lower_factor(A_t)
    target = u_true @ (A_t @ np.linalg.inv(L))
    err = v / sc.field_gauss - target / field
    return float(np.sqrt(np.mean(np.sum(err * err, axis=1))))


def errors(board, pt, field):
    acc = vector_error(board.accel, pt) if board.accel is not None else np.nan
    mag = shape_error(board.mag, pt, field) if board.mag is not None else np.nan
    return acc, mag


def one_board(args) -> dict:
    seed, model_name = args
    model = load_model(model_name)
    field = model.environment.field_gauss
    out = {"seed": seed}
    # adaptive
    cap = AdaptiveCapture(1, planner=Planner(NOMINAL_SCALES), rate_hz=RATE)
    data, fig = run_guided(cap, model, seed)
    pt = data.meta["physical_truth"]
    b = calibrate_board(data, seed=1, kfold=0, gyro_matrix=False)
    a = cap.advice.assessment if cap.advice is not None else None
    out["adaptive"] = dict(fig, met=cap.met, err=errors(b, pt, field),
                           promised=(a.bounds.get("accel"), a.bounds.get("mag")) if a else None)
    # fixed 80
    cap = PoseCapture(1, poses=80, samples=200, rate_hz=RATE)
    data, fig = run_guided(cap, model, seed)
    b = calibrate_board(data, seed=1, kfold=0, gyro_matrix=False)
    out["fixed80"] = dict(fig, err=errors(b, pt, field))
    # 6 faces + sweep
    cap = PoseCapture(1, poses=6, samples=200, rate_hz=RATE, min_angle_deg=15.0)
    cap.targets = FACES
    data, fig = run_guided(cap, model, seed)
    sweep = simulate_session("rotation", seed=seed, model=model)[1]
    rot = RotationCapture(1)
    rot.update(sweep.seq, sweep.raw)
    k = rot.count
    n0 = len(data)
    both = SessionData(
        name="six+sweep", raw=np.vstack([data.raw, sweep.raw[:k]]),
        mote=np.ones(n0 + k, np.int32), seq=np.arange(n0 + k, dtype=np.int64),
        t=np.concatenate([data.t, data.t[-1] + 5.0 + sweep.t[:k]]),
        label=np.concatenate([data.label, np.full(k, LABEL_ROT, np.int32)]),
        flags=np.zeros(n0 + k, np.uint8), kind="static80", meta=dict(data.meta))
    b_acc = calibrate_board(both, model="paper", groups=("offsets", "scales"), seed=1, kfold=0,
                            gyro_matrix=False)
    b_mag = calibrate_board(both, seed=1, kfold=0, gyro_matrix=False)
    move = np.mean(REACTION_S) + move_duration(np.pi / 2)
    out["six"] = dict(poses=fig["poses"], time_s=fig["time_s"] + move + k / RATE,
                      err=(vector_error(b_acc.accel, pt), shape_error(b_mag.mag, pt, field)))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--boards", type=int, default=30)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--model", default=MODEL,
                    help="simulator model (default general; 'full' adds nonlinearity and the "
                         "rest as context: figures printed, nothing recorded)")
    args = ap.parse_args()
    t0 = time.time()
    seeds = list(range(100, 100 + args.boards))
    with Pool(args.jobs) as pool:
        res = pool.map(one_board, [(s, args.model) for s in seeds])
    wall = time.time() - t0

    def col(proto, key):
        return np.array([r[proto][key] for r in res], float)

    def errs(proto, i):
        return np.array([r[proto]["err"][i] for r in res], float)

    rms = lambda x: float(np.sqrt(np.nanmean(np.asarray(x) ** 2)))  # noqa: E731
    print(f"{len(res)} '{args.model}' boards, person with 6 deg placement error and 0.04 deg "
          f"tremor ({wall:.0f} s wall, {args.jobs} processes)\n")
    print(f"{'protocol':<18}{'poses':>14}{'person-time s':>18}{'accel mg (rms, max)':>24}"
          f"{'mag shape % (rms, max)':>26}")
    rows = {}
    for proto, name in (("adaptive", "adaptive"), ("fixed80", "fixed 80"),
                        ("six", "6 faces + sweep")):
        p, t = col(proto, "poses"), col(proto, "time_s")
        ea, em = errs(proto, 0) * 1e3, errs(proto, 1) * 1e2
        rows[proto] = dict(poses=np.median(p), time=np.median(t), acc=rms(ea), mag=rms(em),
                           acc_max=np.nanmax(ea), mag_max=np.nanmax(em))
        print(f"{name:<18}{np.median(p):>6.0f} ({p.min():.0f}-{p.max():.0f}){np.median(t):>10.0f}"
              f" ({t.min():.0f}-{t.max():.0f}){rms(ea):>12.3f}, {np.nanmax(ea):6.3f}"
              f"{rms(em):>14.3f}, {np.nanmax(em):6.3f}")
    met = np.array([r["adaptive"]["met"] for r in res])
    acc_true = errs("adaptive", 0)
    promised = np.array([r["adaptive"]["promised"][0] if r["adaptive"]["promised"] else np.nan
                         for r in res], float)
    mag_true = errs("adaptive", 1)
    mag_prom = np.array([r["adaptive"]["promised"][1] if r["adaptive"]["promised"] else np.nan
                         for r in res], float)
    ratio = acc_true / promised
    ratio_m = mag_true / mag_prom
    honest = float(np.mean(ratio <= 1.2))
    honest_m = float(np.mean(ratio_m <= 1.2))
    print(f"\nadaptive: targets met on {met.sum()} of {len(met)} boards; true / promised error "
          f"at the stop: accel median {np.median(ratio):.2f} (max {ratio.max():.2f}, "
          f"<= 1.2 on {honest:.0%}), mag median {np.median(ratio_m):.2f} (max "
          f"{ratio_m.max():.2f}, <= 1.2 on {honest_m:.0%})")
    print("seeds and figures per board (adaptive poses, time, accel true / promised mg):")
    for r in res:
        a = r["adaptive"]
        print(f"  seed {r['seed']}: {a['poses']:2d} poses {a['time_s']:5.0f} s  "
              f"{a['err'][0] * 1e3:.3f} / {a['promised'][0] * 1e3:.3f} mg  "
              f"fixed80 {r['fixed80']['err'][0] * 1e3:.3f} mg")
    if args.model != MODEL:
        return                                   # context only: the goals are on 'general'
    ad, fx, sx = rows["adaptive"], rows["fixed80"], rows["six"]
    third = ad["poses"] <= 80 / 3
    same = (ad["acc"] <= TARGET_ACCEL_G * 1e3 and ad["mag"] <= TARGET_MAG_REL * 1e2
            and bool(met.all()))
    record("adaptive session: poses to the accuracy asked",
           "<= 1/3 of the 80 fixed poses (26.7), reaching 0.5 mg and 0.3 % as 80 poses do",
           ad["poses"], "poses (median)", bool(third and same),
           note=f"{len(res)} general boards; accel rms {ad['acc']:.3f} mg (fixed 80: "
                f"{fx['acc']:.3f}, 6 faces + sweep: {sx['acc']:.3f}); mag shape rms "
                f"{ad['mag']:.3f} % (fixed 80: {fx['mag']:.3f}, 6 + sweep: {sx['mag']:.3f}); "
                f"targets met on {met.sum()} of {len(met)}")
    record("adaptive session: person-time", "context (fixed 80, 6 faces + sweep alongside)",
           ad["time"], "s (median)", None,
           note=f"fixed 80: {fx['time']:.0f} s, 6 faces + sweep: {sx['time']:.0f} s "
                "(reactions, moves, holds)")
    record("adaptive session: promised error at the stop not optimistic",
           "true <= 1.2 x promised in >= 90 % of boards", honest * 100, "% of boards (accel)",
           honest >= 0.9, note=f"median true / promised {np.median(ratio):.2f}; mag "
                               f"{honest_m:.0%} of boards")


if __name__ == "__main__":
    main()
