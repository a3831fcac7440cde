"""Import at scale (issue 31, the import's part; issue 28 item 3): peak memory
and time of `motecal import` for a 4-hour recording (1.8 M samples) as a
FreeIMU-style float log and as the project CSV, and at a quarter of that size,
so that the growth shows (linear: 4x the samples, 4x the time and memory
above the interpreter's own).  Each import runs in a child process that
reports its own peak resident memory (ru_maxrss); the files are synthetic
(a board turned through poses every 20 s), written to a temporary folder.

    python bench/bench_import.py [--samples N]

Timings on a shared machine are noisy; memory is not.
"""
import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "host"))

import numpy as np  # noqa: E402

from results import record  # noqa: E402

GOAL_SAMPLES = 1_800_000          # 4 hours at 125 Hz
GOAL_MB = 2048.0
CHILD = ("import resource, sys, time; t0 = time.perf_counter(); "
         "from motecal.commands.main import main; "
         "rc = main(sys.argv[1:]); "
         "print('BENCH', rc, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, "
         "time.perf_counter() - t0)")


def write_float_log(path: Path, n: int, seed: int = 0) -> None:
    """FreeIMU-cal's accelerometer log: m/s^2 at 9.80665 / 2048 per count."""
    rng = np.random.default_rng(seed)
    with open(path, "w") as f:
        for a in range(0, n, 200_000):
            k = np.arange(a, min(n, a + 200_000)) // 2000
            counts = np.rint(_dirs(k, seed) * 2048 + rng.normal(0, 3, (len(k), 3)))
            np.savetxt(f, counts * 9.80665 / 2048, fmt="%.6f")


def _dirs(k: np.ndarray, seed: int) -> np.ndarray:
    """One direction per pose number (the board held still for 2000 rows)."""
    uniq = np.unique(k)
    d = np.random.default_rng([seed, int(uniq[0])]).normal(size=(len(uniq), 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return d[np.searchsorted(uniq, k)]


def write_project_csv(path: Path, n: int, seed: int = 0) -> None:
    """The project CSV of one mote at 125 Hz, all nine sensors."""
    rng = np.random.default_rng(seed)
    with open(path, "w") as f:
        f.write("mote,seq,t,label,ax,ay,az,gx,gy,gz,mx,my,mz\n")
        for a in range(0, n, 200_000):
            i = np.arange(a, min(n, a + 200_000))
            d = _dirs(i // 2500, seed)
            raw = np.column_stack([np.rint(d * 256 + rng.normal(0, 2, (len(i), 3))),
                                   np.rint(rng.normal(0, 5, (len(i), 3))),
                                   np.rint(d[:, ::-1] * 500 + rng.normal(0, 2, (len(i), 3)))])
            cols = np.column_stack([np.ones(len(i)), i, i / 125.0])
            for c, r in zip(cols, raw.astype(int)):
                f.write(f"1,{int(c[1])},{c[2]:.6f},," + ",".join(map(str, r)) + "\n")


def import_peak(path: Path, db: Path, *opts) -> tuple[float, float]:
    """(peak resident MB, seconds) of `motecal import path` in a child."""
    env = dict(os.environ, PYTHONPATH=str(ROOT / "host"), OPENBLAS_NUM_THREADS="1")
    t0 = time.perf_counter()
    res = subprocess.run([sys.executable, "-c", CHILD, "import", str(path), "--db", str(db),
                          "--session", "s", *opts], capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0
    line = next((ln for ln in res.stdout.splitlines() if ln.startswith("BENCH")), None)
    if line is None or line.split()[1] != "0":
        raise SystemExit(f"import of {path} failed: {res.stderr.strip()[-500:]}")
    _, _, kb, _ = line.split()
    return int(kb) / 1024, wall


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=GOAL_SAMPLES)
    n = ap.parse_args().samples
    with tempfile.TemporaryDirectory(prefix="motecal-bench-import-") as tmp:
        tmp = Path(tmp)
        for kind, writer, opts in (("float log", write_float_log, ("--rate-hz", "100")),
                                   ("project CSV", write_project_csv, ())):
            runs = {}
            for m in (n // 4, n):
                f = tmp / ("big_acc.txt" if kind == "float log" else "big.csv")
                writer(f, m)
                mb = f.stat().st_size / 2 ** 20
                peak, secs = import_peak(f, tmp / f"{kind[0]}{m}.db", *opts)
                runs[m] = (peak, secs)
                print(f"{kind}: {m} samples ({mb:.0f} MB file): peak {peak:.0f} MB, {secs:.1f} s",
                      flush=True)
                f.unlink()
            peak, secs = runs[n]
            q_peak, q_secs = runs[n // 4]
            record(f"import peak memory, {kind} of {n} samples", f"<= {GOAL_MB:g} MB for "
                   f"{GOAL_SAMPLES} samples (a 4-hour recording)", peak, "MB",
                   peak <= GOAL_MB if n >= GOAL_SAMPLES else None)
            record(f"import time, {kind} of {n} samples", "linear in the input (no goal of "
                   "its own)", secs, "s", None, note="wall clock on a shared machine: noisy")
            record(f"import growth, {kind}, 4x the samples", "about 4x (linear)",
                   f"time x{secs / q_secs:.2f}, memory x{peak / q_peak:.2f}", "", None,
                   note="memory includes the interpreter and numpy (~60 MB) at both sizes")


if __name__ == "__main__":
    main()
