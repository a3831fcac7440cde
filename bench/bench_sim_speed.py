"""Simulator speed: simulated seconds per wall second, 3 motes, static80 session.

The whole World (physics of 3 boards, motes with the firmware's C calibration
code, radio, BaseStation, serial line at 250000 baud) run as fast as possible
through the full static80 session, producing every serial byte.
Goal: >= 200x real time.

    .venv/bin/python bench/bench_sim_speed.py [--repeat 3]
"""
from __future__ import annotations

import argparse
import time

from motecal.sim.world import World
from results import record

GOAL = 200.0


def once(seed: int):
    w = World(motes=3, session="static80", seed=seed)
    n = 0
    wall0, cpu0 = time.perf_counter(), time.process_time()
    while not w.done:
        n += len(w.run_until(w.now + 1.0))
    wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
    return w.duration, wall, cpu, n


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    World(motes=1, session="idle", duration=1.0).run_until(1.0)     # warm imports, C build
    best_wall = best_cpu = 0.0
    print("run | simulated s | wall s | x real time (wall) | x real time (CPU) | bytes")
    for i in range(a.repeat):
        sim, wall, cpu, n = once(seed=i + 1)
        best_wall, best_cpu = max(best_wall, sim / wall), max(best_cpu, sim / cpu)
        print(f"{i + 1:3d} | {sim:11.1f} | {wall:6.2f} | {sim / wall:18.0f} | "
              f"{sim / cpu:17.0f} | {n}")
    print(f"GOAL: >= {GOAL:.0f}x real time for 3 motes static80: best {best_wall:.0f}x wall "
          f"({best_cpu:.0f}x CPU) -> {'MET' if best_wall >= GOAL else 'NOT MET'}"
          " (wall time depends on machine load)")
    record("simulator speed, 3 motes, static80", f">= {GOAL:.0f}x real time (#2)", best_wall,
           "x real time", best_wall >= GOAL, digits=3,
           note=f"best of {a.repeat} runs, wall time on one core ({best_cpu:.0f}x in CPU time)")


if __name__ == "__main__":
    main()
