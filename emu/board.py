"""Board tables for the emulator harness (emu/board.h): the true raw counts
of one simulated 9DOF board over time, from the project's simulator (its
error model and the rig's trajectory, motecal.sim), for
`ninedof-emu --mote ELF,board=FILE`.

    python3 emu/board.py --out board1.txt --mote 1 --session static80 --seed 1 --seconds 60

The table holds what the chips' converters see (the model's counts at the
chips' settings, noise included) at `--rate` rows per second; the chip
models take the row of each data-ready instant.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

HEADER = "# motecal-emu-board rate_hz={rate}"


def counts(mote_id: int, *, seconds: float, session: str = "static80", seed: int = 1,
           model=None, rate_hz: float = 1000.0) -> np.ndarray:
    """(n, 9) int counts ax..mz of board mote_id at i / rate_hz, i < seconds * rate_hz."""
    from motecal.sim.model import load_model
    from motecal.sim.trajectory import make_trajectory
    m = load_model(model)
    traj = make_trajectory(session, seed, duration=seconds, rate_hz=m.rate_hz)
    sampler = m.board(mote_id, seed).sampler(traj, seed)
    t = np.arange(int(round(seconds * rate_hz))) / rate_hz
    return np.asarray(sampler.read(t), dtype=np.int64)


def write(path, table: np.ndarray, rate_hz: float) -> None:
    with open(path, "w") as f:
        f.write(HEADER.format(rate=repr(float(rate_hz))) + "\n")
        np.savetxt(f, table, fmt="%d")


def read(path) -> tuple[float, np.ndarray]:
    """(rate_hz, (n, 9) counts) of a table."""
    with open(path) as f:
        first = f.readline().strip()
    rate = float(first.split("rate_hz=")[1])
    return rate, np.loadtxt(path, dtype=np.int64, comments="#", ndmin=2)[:, :9]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--mote", type=int, default=1)
    ap.add_argument("--session", default="static80")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--model", default=None, help="error model file or name (motecal sim --model)")
    ap.add_argument("--seconds", type=float, default=60)
    ap.add_argument("--rate", type=float, default=1000, help="rows per second (default 1000)")
    a = ap.parse_args(argv)
    if not (0 < a.seconds <= 3600 and 1 <= a.rate <= 20000 and a.mote >= 1):
        print("board: --seconds must be in (0, 3600], --rate in [1, 20000], --mote >= 1",
              file=sys.stderr)
        return 2
    try:
        table = counts(a.mote, seconds=a.seconds, session=a.session, seed=a.seed, model=a.model,
                       rate_hz=a.rate)
    except Exception as e:     # the simulator's own checks (UserError, bad model file)
        print(f"board: {e}", file=sys.stderr)
        return 2
    write(Path(a.out), table, a.rate)
    return 0


if __name__ == "__main__":
    sys.exit(main())
