"""Benchmark of the calibration engine (prints figures next to the goals; exit 0).

1. Whole-board calibration of a paper-sized simulated board (16000 accel +
   16000 gyro + 5000 magnetometer samples): the project's GA (+ polish)
   against the analytic-Jacobian Levenberg-Marquardt reference and
   scipy.optimize.differential_evolution with default settings, on the same
   data and the same objectives (accel and mag: mean squared magnitude error
   over every sample, full model; gyro: the paper's eq. 6).
   Goals: GA within 1e-9 relative of the LM optimum in 100 of 100 seeds, at
   most 3x the LM time, at least 10x faster than DE.  These are the paper's
   least-squares objective (``fit.ga_optimize``: what Tables I-III and the
   diagnosis fit); calibrate's default fit is robust since issue 25, and its
   GA is benched against LM + Huber, its local route, DE and the algebraic
   ellipsoid fit in bench/bench_robust.py.
2. The paper's Tables I-III for simulated boards.
3. Accuracy on fresh directions (goal <= 0.55 mg rms, full model, 10 mg noise),
   on the matching model ('general') and on the mismatch suite ('mismatch':
   a board warming during the poses, its accelerometer lagging the ITG3200's
   temperature, bending and hysteretic with it, nonlinear; sim.mismatch),
   each of the suite's blocks also alone to say which one breaks the goal.
   The GA's gap to the LM optimum is measured on a suite board too.

BLAS runs single-threaded so that the timings of small matrix work are not
dominated by thread hand-offs on a shared machine.
"""
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import sys  # noqa: E402
from multiprocessing import Pool  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "host"))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))   # test helpers

import numpy as np  # noqa: E402
from scipy.optimize import differential_evolution  # noqa: E402

from motecal.calib import eq6, fit, gyro, tables  # noqa: E402
from motecal.calib.board import calibrate_board  # noqa: E402
from motecal.calib.models import make_model  # noqa: E402
from synthetic import board_of, paper_sized_session, vector_error, vector_error_at  # noqa: E402
from motecal.sim import mismatch  # noqa: E402
from motecal.sessions.session import LABEL_ROT  # noqa: E402
from results import record  # noqa: E402


def best_time(f, reps=5):
    ts, out = [], None
    for _ in range(reps):
        t = time.perf_counter()
        out = f()
        ts.append(time.perf_counter() - t)
    return min(ts), out


def board_problems(d):
    acc = (d.label >= 1) & d.has("accel")
    ua, la = d.sensor("accel")[acc] / d.scales["accel"], d.label[acc]
    gyr = (d.label >= 1) & d.has("gyro")
    g = d.sensor("gyro")[gyr] / d.scales["gyro"]
    mag = (d.label == LABEL_ROT) & d.has("mag")
    um = d.sensor("mag")[mag] / d.scales["mag"]
    return ua, la, g, um


def ga_gaps(d, n_seeds):
    """Worst relative gap of the GA (+ polish) to the LM optimum over seeds, per
    sensor, and the seeds within 1e-9 on the whole board."""
    ua, la, g, um = board_problems(d)
    ma, mm = make_model("accel", "full"), make_model("mag", "full")
    T = eq6.Eq6Table(g)
    obj = {"accel": lambda th: fit.mse_of(ma, th, ua), "gyro": lambda b: float(T(b)),
           "mag": lambda th: fit.mse_of(mm, th, um)}
    ref = {"accel": obj["accel"](fit.lm_optimize(ma, ua)[0]),
           "gyro": obj["gyro"](gyro.lm_bias(g)[0]), "mag": obj["mag"](fit.lm_optimize(mm, um)[0])}
    gap = {k: [] for k in ref}
    for s in range(n_seeds):
        x = {"accel": fit.ga_optimize(ma, ua, la, seed=s).theta, "gyro": gyro.ga_bias(g, seed=s).b,
             "mag": fit.ga_optimize(mm, um, None, seed=s).theta}
        for k in ref:
            gap[k].append((obj[k](x[k]) - ref[k]) / ref[k])
    ok = np.all([np.array(gap[k]) <= 1e-9 for k in gap], axis=0)
    return gap, int(ok.sum())


def section_speed(n_seeds):
    d = paper_sized_session(0)
    ua, la, g, um = board_problems(d)
    print(f"data: accel {len(ua)} samples ({len(np.unique(la))} poses), gyro {len(g)} still "
          f"samples, mag {len(um)} rotation samples (simulated 'general' board, seed 0)")
    ma = make_model("accel", "full")
    mm = make_model("mag", "full")
    T = eq6.Eq6Table(g)                                  # exact eq. 6 evaluator (checks only)
    objective = {"accel": lambda th: fit.mse_of(ma, th, ua),
                 "gyro": lambda b: float(T(b)),
                 "mag": lambda th: fit.mse_of(mm, th, um)}

    # LM reference
    lm_t, lm_x = {}, {}
    lm_t["accel"], (lm_x["accel"], _) = best_time(lambda: fit.lm_optimize(ma, ua))
    lm_t["gyro"], (lm_x["gyro"], _) = best_time(lambda: gyro.lm_bias(g))
    lm_t["mag"], (lm_x["mag"], _) = best_time(lambda: fit.lm_optimize(mm, um))
    lm_f = {k: objective[k](lm_x[k]) for k in lm_x}

    # GA + polish, n_seeds seeds
    ga_t = {k: [] for k in lm_x}
    gap = {k: [] for k in lm_x}
    for s in range(n_seeds):
        t = time.perf_counter()
        xa = fit.ga_optimize(ma, ua, la, seed=s).theta
        t1 = time.perf_counter()
        xg = gyro.ga_bias(g, seed=s).b
        t2 = time.perf_counter()
        xm = fit.ga_optimize(mm, um, None, seed=s).theta
        t3 = time.perf_counter()
        for k, x, dt in (("accel", xa, t1 - t), ("gyro", xg, t2 - t1), ("mag", xm, t3 - t2)):
            ga_t[k].append(dt)
            gap[k].append((objective[k](x) - lm_f[k]) / lm_f[k])

    # differential evolution, default settings, one run
    de_t, de_f = {}, {}
    for k, mdl, u in (("accel", ma, ua), ("mag", mm, um)):
        lo, hi = mdl.prior_box(u)
        t = time.perf_counter()
        r = differential_evolution(objective[k], list(zip(lo, hi)), seed=0)
        de_t[k], de_f[k] = time.perf_counter() - t, objective[k](r.x)
    t = time.perf_counter()
    r = differential_evolution(objective["gyro"], [(-gyro.PRIOR_BIAS_DPS, gyro.PRIOR_BIAS_DPS)] * 3,
                               seed=0)
    de_t["gyro"], de_f["gyro"] = time.perf_counter() - t, objective["gyro"](r.x)

    print(f"\n{'':7}{'LM time':>9} {'LM optimum':>15} | {'GA median':>9} {'GA max':>8} "
          f"{'worst rel gap':>13} {'seeds ok':>8} | {'DE time':>8} {'DE rel gap':>11}")
    ok_all = np.ones(n_seeds, bool)
    for k in ("accel", "gyro", "mag"):
        gk = np.array(gap[k])
        ok = gk <= 1e-9
        ok_all &= ok
        print(f"{k:7}{lm_t[k] * 1e3:7.1f}ms {lm_f[k]:15.9e} | {np.median(ga_t[k]) * 1e3:7.1f}ms "
              f"{max(ga_t[k]) * 1e3:6.1f}ms {gk.max():13.2e} {ok.sum():5d}/{n_seeds} | "
              f"{de_t[k]:7.2f}s {(de_f[k] - lm_f[k]) / lm_f[k]:11.2e}")
    lm_board = sum(lm_t.values())
    ga_board = np.median(np.sum([ga_t[k] for k in ga_t], axis=0))
    de_board = sum(de_t.values())
    print(f"{'board':7}{lm_board * 1e3:7.1f}ms {'':15} | {ga_board * 1e3:7.1f}ms {'':8} {'':13} "
          f"{ok_all.sum():5d}/{n_seeds} | {de_board:7.2f}s")
    print(f"\nwhole board: GA within 1e-9 of LM in {ok_all.sum()}/{n_seeds} seeds (goal "
          f"{n_seeds}/{n_seeds}); GA/LM time {ga_board / lm_board:.2f}x (goal <= 3x); "
          f"DE/GA time {de_board / ga_board:.0f}x (goal >= 10x)")
    record("GA within 1e-9 of the LM optimum", f"{n_seeds}/{n_seeds} seeds (#4)",
           f"{ok_all.sum()}/{n_seeds}", "seeds", bool(ok_all.all()),
           note="the paper's least-squares objective (Tables I-III; calibrate's robust fit: "
                "bench_robust); whole board: "
                + ", ".join(f"{k} worst gap {max(gap[k]):.1e}" for k in gap),
           world="matching")
    dm = paper_sized_session(0, model="mismatch")
    gap_m, ok_m = ga_gaps(dm, n_seeds)
    print(f"on a 'mismatch' board (seed 0): GA within 1e-9 of LM in {ok_m}/{n_seeds} seeds; "
          + ", ".join(f"{k} worst gap {max(gap_m[k]):.1e}" for k in gap_m))
    record("GA within 1e-9 of the LM optimum", f"{n_seeds}/{n_seeds} seeds (#4)",
           f"{ok_m}/{n_seeds}", "seeds", ok_m == n_seeds,
           note="the paper's least-squares objective; whole 'mismatch' board (warming, nonlinear, ...): "
                + ", ".join(f"{k} worst gap {max(gap_m[k]):.1e}" for k in gap_m),
           world="mismatch")
    record("GA time / LM time, whole board", "<= 3x (#4)", ga_board / lm_board, "x",
           ga_board / lm_board <= 3, digits=3,
           note=f"GA {ga_board * 1e3:.0f} ms (median of seeds), LM {lm_board * 1e3:.0f} ms")
    record("DE time / GA time, whole board", ">= 10x (#4)", de_board / ga_board, "x",
           de_board / ga_board >= 10, digits=3,
           note=f"scipy differential_evolution, default settings: {de_board:.1f} s")
    print("(relative gap = (F - F_LM) / F_LM of the exact objective; negative: lower than LM. "
          "LM on eq. 6 stops at a kink of the piecewise-quadratic fitness, the GA's exact "
          "minimiser does not.)")


def section_tables(n_boards):
    print("\nThe paper's Table I (accelerometer; error = MSE of the magnitude, g^2), "
          f"{n_boards} simulated 'general' boards (paper-sized, seed = board):")
    t1 = {b: tables.table1(paper_sized_session(b, rotation=False)) for b in range(1, n_boards + 1)}
    names = [r["parameters"] for r in t1[1]]
    head = "".join(f"{'board ' + str(b):>26}" for b in t1)
    print(f"{'parameters':26}{head}")
    for i, n in enumerate(names):
        cells = "".join(f"{t1[b][i]['error']:10.6f} {t1[b][i]['min']:.3f}-{t1[b][i]['max']:.3f}"
                        .rjust(26) for b in t1)
        print(f"{n:26}{cells}")
    print("\nTable II (gyroscope, eq. 6 in (deg/s)^2) and Table III (magnetometer, gauss^2):")
    for b in range(1, n_boards + 1):
        d = paper_sized_session(b)
        t2 = tables.table2(d)[0]
        print(f"board {b}: gyro {t2['error_before']:.1f} -> {t2['error_after']:.3f}, bias "
              f"({t2['b_x']:.2f}, {t2['b_y']:.2f}, {t2['b_z']:.2f}) deg/s")
        for r in tables.table3(d):
            print(f"         mag {r['set']}: field {r['field_all']:.3f} gauss, error offsets only "
                  f"{r['error_offsets']:.6f} -> all paper parameters {r['error_all']:.6f} "
                  f"-> full model {r['error_full']:.2e}")


def accuracy_case(case):
    """Vector errors (mg) of one paper-sized board of ``model``: full model in
    its gauge frame through the board's whole model at the session's end
    (``vector_error_at``), full model up to a rotation and the paper model
    (affine truth: ``vector_error``), and what the temperature fit did."""
    model, b = case
    d = paper_sized_session(b, model=model, rotation=False)
    bc = calibrate_board(d, seed=b, kfold=0, gyro_matrix=False)
    full = bc.accel
    paper = calibrate_board(d, seed=b, kfold=0, model="paper", groups=("offsets", "scales"),
                            gyro_matrix=False).accel
    board, pt = board_of(d), d.meta["physical_truth"]
    t_end = float(d.t[-1])
    temp = None if d.temp is None else float(d.temp[-1])
    return {"model": model, "board": b,
            "full": vector_error_at(full, board, t_end, temp) * 1e3,
            "rotation": vector_error(full, pt, align="rotation") * 1e3,
            "paper": vector_error_at(paper, board, t_end, temp) * 1e3,
            "temperature": (full.temperature is not None),
            "lag": full.temperature.lag_s if full.temperature is not None else None}


def section_accuracy(n_boards, block_boards, jobs):
    worlds = {"matching": "general", "mismatch": "mismatch"}
    cases = [(m, b) for m in worlds.values() for b in range(n_boards)]
    cases += [(m, b) for m in mismatch.SINGLE for b in range(block_boards)]
    with Pool(jobs) as pool:
        res = pool.map(accuracy_case, cases, chunksize=1)
    blocks = {}
    for m in mismatch.SINGLE:
        e = np.array([r["full"] for r in res if r["model"] == m])
        blocks[m.split("-", 1)[1]] = float(np.sqrt(np.mean(e ** 2)))
    print(f"\nthe suite's blocks one at a time ({block_boards} boards each, 'general' + warm-up + "
          "the block), full model, rms over boards: "
          + ", ".join(f"{k} {v:.3f} mg" for k, v in blocks.items()))
    for world, model in worlds.items():
        rs = [r for r in res if r["model"] == model]
        e = np.array([[r["full"], r["rotation"], r["paper"]] for r in rs])
        rms = np.sqrt(np.mean(e ** 2, axis=0))
        print(f"\nAccuracy on 2000 fresh directions, {n_boards} paper-sized '{model}' boards with "
              "10 mg accelerometer noise (goal: full model <= 0.55 mg rms)"
              + ("" if world == "matching" else
                 ", evaluated at the session's end through the board's whole model (its "
                 "temperature, lag, curve, hysteresis, nonlinearity)") + ":")
        print(f"  full model, in its gauge frame:   rms over boards {rms[0]:.3f} mg "
              f"(per board {e[:, 0].min():.3f}-{e[:, 0].max():.3f}; "
              f"{(e[:, 0] <= 0.55).sum()}/{n_boards} boards <= 0.55)")
        if world == "matching":
            print(f"  full model, up to a rotation:     rms over boards {rms[1]:.3f} mg "
                  f"(per board {e[:, 1].min():.3f}-{e[:, 1].max():.3f}; "
                  f"{(e[:, 1] <= 0.55).sum()}/{n_boards} boards <= 0.55)")
        print(f"  paper model (offsets + scales):   rms over boards {rms[2]:.2f} mg "
              "(cannot remove the cross-axis coupling)")
        if world == "matching":
            note = (f"over {n_boards} boards, gauge frame (per board {e[:, 0].min():.2f}-"
                    f"{e[:, 0].max():.2f} mg; {rms[1]:.3f} mg up to a rotation)")
        else:
            lags = [r["lag"] for r in rs if r["lag"]]
            worst = max(blocks, key=blocks.get)
            note = (f"over {n_boards} 'mismatch' boards at the session's end (per board "
                    f"{e[:, 0].min():.2f}-{e[:, 0].max():.2f} mg; temperature fitted from the "
                    f"poses on {sum(r['temperature'] for r in rs)}, a lag on {len(lags)}); "
                    f"each block alone with the warm-up, rms over {block_boards} boards: "
                    + ", ".join(f"{k} {v:.2f}" for k, v in blocks.items()) + " mg: "
                    + ("the warm-up during the poses alone is beyond the goal, "
                       if blocks.get("warmup", 0) > 0.55 else "")
                    + f"the {worst} most")
        record("accelerometer vector error, full model, 10 mg noise", "<= 0.55 mg rms (#4)",
               rms[0], "mg rms", rms[0] <= 0.55, digits=3, note=note, world=world)
        record("  the same with the paper model (offsets + scales)", "", rms[2], "mg rms", None,
               digits=3, note="cannot remove the cross-axis coupling", world=world)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=100)
    ap.add_argument("--boards", type=int, default=3)
    ap.add_argument("--accuracy-boards", type=int, default=20)
    ap.add_argument("--block-boards", type=int, default=8,
                    help="boards per single block of the mismatch suite (8)")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1,
                    help="processes for the accuracy section (after the timings)")
    a = ap.parse_args()
    section_speed(a.seeds)
    section_tables(a.boards)
    section_accuracy(a.accuracy_boards, a.block_boards, a.jobs)
    return 0


if __name__ == "__main__":
    sys.exit(main())
