"""The guided logger's live stillness under a trembling hand: the rate's
spread (the old live rule, ``gyro_rule="rate"``) against the gyroscope's
integrated rotation (the offline rule, ``sessions.still.TurnStillDetector``).

A simulated person (``sim.person``: reactions, minimum-jerk moves, holds
with hand tremor of the given rms per axis) follows ``--guided static80``
for 10 poses of 200 samples on a general board (``run_guided``, no radio),
for at most 120 s.  Per tremor and rule: poses captured (of 10, over the
seeds), person-time per captured pose, and pose rows lying in the person's
moves (truth: the person's own trajectory).  No goal of an issue: context.
"""

import benchenv  # noqa: F401,E402  (one BLAS thread a process; host/, tests/, bench/ on the path)

import argparse  # noqa: E402

import numpy as np  # noqa: E402

from motecal.capture.guide import PoseCapture  # noqa: E402
from motecal.sessions.still import StillThresholds  # noqa: E402
from motecal.sim import load_model  # noqa: E402
from motecal.sim.person import PersonTrajectory, run_guided  # noqa: E402
from results import record  # noqa: E402

POSES = 10
MAX_S = 120.0


def one(seed, tremor, rule, model):
    traj = PersonTrajectory(seed, model.rate_hz, tremor_deg=tremor)
    cap = PoseCapture(1, poses=POSES, samples=200, rate_hz=model.rate_hz,
                      thresholds=StillThresholds(gyro_rule=rule))
    data, fig = run_guided(cap, model, seed, trajectory=traj, max_s=MAX_S, step_s=0.2)
    moving = np.asarray(traj.dur)[traj._seg(data.t)] > 0
    return fig["poses"], fig["time_s"], int((moving & (data.label > 0)).sum())


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    a = ap.parse_args()
    model = load_model("general")
    print(f"{'tremor':>7} {'rule':>5} {'poses':>9} {'s/pose':>7} {'rows in moves':>14}")
    for tremor in (0.04, 0.1, 0.2, 0.3):
        for rule in ("rate", "turn"):
            res = [one(s, tremor, rule, model) for s in range(1, a.seeds + 1)]
            poses = sum(r[0] for r in res)
            t = sum(r[1] for r in res)
            per = t / poses if poses else float("inf")
            moves = sum(r[2] for r in res)
            print(f"{tremor:7.2f} {rule:>5} {poses:4d}/{POSES * a.seeds:<4d} {per:7.2f} {moves:14d}")
            name = f"live stillness, tremor {tremor} deg rms, {rule} rule"
            record(name + ": poses captured", f"context ({POSES} poses x {a.seeds} seeds, "
                   f"{MAX_S:.0f} s each)", poses / (POSES * a.seeds) * 100, "%")
            record(name + ": person-time per pose", "context",
                   per if poses else "no pose captured", "s" if poses else "")


if __name__ == "__main__":
    main()
