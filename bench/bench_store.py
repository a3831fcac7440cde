"""Insert rates of the store's three backends: sqlite, PostgreSQL and
MySQL/MariaDB (issue 14: MariaDB's next to sqlite's and PostgreSQL's).

The servers are started as the tests start them (tests/dbservers.py:
Debian's packages, a temporary folder, unix socket; PostgreSQL with
fsync=off, MariaDB flushing its log once a second, sqlite in WAL with
synchronous=NORMAL).  For each backend, the same rows of 3 motes:

- live writer: SessionWriter (what `motecal log` writes through), batches of
  50000 rows per commit (a logger catching up), and of 300 rows (what a full
  250000 baud line brings in the logger's 0.25 s between commits);
- import: save_session of a whole session in one transaction.

Prints rows/s; never fails on timing.  A server that cannot be started is
reported as not measured.
"""
from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))   # dbservers

import numpy as np  # noqa: E402

import dbservers  # noqa: E402
from motecal.sessions.session import SessionData  # noqa: E402
from motecal.sessions.store import open_store  # noqa: E402
from results import record  # noqa: E402

N_ROWS = 300_000
BIG, SMALL = 50_000, 300
SMALL_ROWS = 30_000           # rows written in 300-row commits
LINE_ROWS_S = 1150            # a 250000 baud line at most (docs/log.md)


def rows(n: int, seed: int = 1):
    rng = np.random.default_rng(seed)
    mote = np.tile([1, 2, 3], n // 3 + 1)[:n]
    seq = np.arange(n) // 3
    return mote, seq, rng.integers(-4000, 4000, (n, 9))


def writer_rate(target: str, name: str, n: int, per_commit: int) -> float:
    mote, seq, raw = rows(n)
    t = seq / 125.0
    with open_store(target, create=True) as st:
        w = st.open_session(name, kind="free")
        t0 = time.perf_counter()
        for i in range(0, n, per_commit):
            sl = slice(i, i + per_commit)
            w.add_samples(mote[sl], seq[sl], t[sl], np.zeros(len(seq[sl]), int), raw[sl])
            w.commit()
        w.end()
        dt = time.perf_counter() - t0
        assert st.sessions()[-1]["samples"] == n
    return n / dt


def import_rate(target: str, name: str, n: int) -> float:
    mote, seq, raw = rows(n, seed=2)
    label = np.where((seq // 500) % 2 == 1, (seq // 1000) % 80 + 1, 0)
    data = SessionData(name, raw.astype(float), mote.astype(np.int32), seq, seq / 125.0,
                       label, np.zeros(n, np.uint8), kind="static80")
    with open_store(target, create=True) as st:
        t0 = time.perf_counter()
        st.save_session(data)
        dt = time.perf_counter() - t0
    return n / dt


def measure(label: str, target: str) -> dict:
    big = writer_rate(target, "big", N_ROWS, BIG)
    small = writer_rate(target, "small", SMALL_ROWS, SMALL)
    imp = import_rate(target, "import", N_ROWS)
    print(f"{label:>11} {big:>16.0f} {small:>16.0f} {imp:>12.0f}", flush=True)
    return dict(big=big, small=small, imp=imp)


def main() -> int:
    print(f"store insert rates, {N_ROWS} rows of 3 motes (rows/s); a 250000 baud line "
          f"carries at most ~{LINE_ROWS_S} rows/s")
    print(f"{'backend':>11} {'writer 50k/commit':>16} {'writer 300/commit':>16} "
          f"{'import':>12}")
    figures = {}
    with tempfile.TemporaryDirectory() as tmp:
        figures["sqlite"] = measure("sqlite", str(Path(tmp) / "bench.db"))
    for label, start in (("PostgreSQL", dbservers.postgres_server),
                         ("MariaDB", dbservers.mariadb_server)):
        try:
            with start() as srv:
                figures[label] = measure(label, srv.url)
        except (dbservers.ServerError, ImportError) as e:
            print(f"{label:>11} not measured: {e}")
            figures[label] = None
    for label, f in figures.items():
        note = ("the server did not start (make sysdeps)" if f is None else
                f"{f['small']:.0f} rows/s in 300-row commits; import {f['imp']:.0f} rows/s")
        record(f"store inserts, {label} (live writer, 50000-row commits)", "",
               None if f is None else f["big"], "rows/s", None, note=note, digits=3)
    return 0


if __name__ == "__main__":
    sys.exit(main())
