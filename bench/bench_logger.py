"""Logger throughput: serial bytes -> decoded, sequence-checked, committed rows.

Goal (issue 3): >= 200000 frames/s on one core.  A recorded stream of 3 motes
is replayed as fast as possible through the real path of `motecal log`
(FileSource -> protocol.FrameDecoder -> decode_sample_frames -> LinkTracker ->
SessionWriter, sqlite in WAL, a transaction every 0.25 s) and timed until the
session is ended with everything committed.  Also timed separately: the
decoding part alone and the sqlite insert part alone.  The 5-record stream
is timed again with each mote's temperature message (ninedof_mote_temp_msg,
one per 125 records: once a second at 125 Hz) among the samples, as a new
image sends it: the temperature must not slow the sample path measurably.
Prints figures; never fails on timing.
"""
from __future__ import annotations

import os
import sys
import tempfile
import time

import numpy as np

from motecal.capture.link import LinkTracker
from motecal.capture.logger import Logger
from motecal.line import protocol as P
from motecal.line import sources as S
from motecal.line.samples import decode_sample_frames
from motecal.sessions.store import open_store
from results import record

GOAL = 200_000


TEMP_EVERY = round(P.NINEDOF_RATE_HZ * P.NINEDOF_TEMP_PERIOD_MS / 1000)   # records


def stream(n_rows: int, batch: int, motes=(1, 2, 3), seed=0, temps: bool = False) -> bytes:
    rng = np.random.default_rng(seed)
    out = []
    per = n_rows // len(motes)
    raws = {m: rng.integers(-4000, 4000, (per, 9)).astype(np.int16) for m in motes}
    for i in range(0, per, batch):
        for m in motes:
            out.append(P.encode_am(P.AMPacket(0xFFFF, m, 0x22, P.AM_NINEDOF_SAMPLES_MSG,
                                              P.pack_samples(i, 0, raws[m][i:i + batch]))))
            last = min(i + batch, per) - 1
            if temps and (last + 1) % TEMP_EVERY < batch:
                out.append(P.message_frame(P.MOTE_TEMP, dest=0xFFFF, src=m, seq=last & 0xFFFF,
                                           count=TEMP_EVERY, reserved=0,
                                           temp_sum=-12000 * TEMP_EVERY))
    return b"".join(out), len(out)


def run(n_rows: int, batch: int, tmp: str, temps: bool = False):
    data, n_frames = stream(n_rows, batch, temps=temps)
    rec = os.path.join(tmp, f"rec{batch}{'t' if temps else ''}.bin")
    with open(rec, "wb") as f:
        f.write(data)
    # decoding only
    t0 = time.perf_counter()
    dec = P.FrameDecoder()
    tr = LinkTracker()
    rows = 0
    for i in range(0, len(data), S.READ_SIZE):
        b, _ = decode_sample_frames(dec.feed(data[i:i + S.READ_SIZE]))
        rows += len(tr.samples(b))
    t_dec = time.perf_counter() - t0
    # the whole logger
    db = os.path.join(tmp, f"b{batch}{'t' if temps else ''}.db")
    with open_store(db, create=True) as st:
        w = st.open_session("bench", kind="free")
        lg = Logger(S.parse_port(rec), w, LinkTracker())
        t0 = time.perf_counter()
        lg.run()
        t_all = time.perf_counter() - t0
        stored = st.sessions()[0]["samples"]
        commits = w.commits
        n_temps = len(st.temps("bench"))
    assert n_temps == (n_frames - rows // batch if temps else 0), (n_temps, n_frames)
    assert stored == rows == n_rows // 3 * 3, (stored, rows, n_rows)
    # sqlite inserts only (the same rows, already decoded)
    db = os.path.join(tmp, f"i{batch}{'t' if temps else ''}.db")
    rng = np.random.default_rng(1)
    raw = rng.integers(-4000, 4000, (rows, 9)).astype(np.int16)
    with open_store(db, create=True) as st:
        w = st.open_session("ins", kind="free")
        t0 = time.perf_counter()
        step = 50_000
        for i in range(0, rows, step):
            k = min(step, rows - i)
            w.add_samples(np.full(k, 1), np.arange(i, i + k), np.zeros(k), np.zeros(k, int),
                          raw[i:i + k])
            w.commit()
        t_ins = time.perf_counter() - t0
    return n_frames, rows, t_dec, t_all, commits, t_ins


def main() -> int:
    os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})   # one core
    n_rows = int(sys.argv[1]) if len(sys.argv) > 1 else 600_000
    print(f"logger throughput, {n_rows} records from 3 motes, one core, sqlite (WAL)")
    print(f"{'records/frame':>13} {'frames':>8} {'decode frames/s':>16} "
          f"{'insert rows/s':>14} {'end-to-end frames/s':>20} {'records/s':>10} "
          f"{'commits':>8}  goal")
    with tempfile.TemporaryDirectory() as tmp:
        plain = {}
        for batch, temps in ((P.NINEDOF_BATCH, False), (1, False), (P.NINEDOF_BATCH, True)):
            n = n_rows if batch > 1 else n_rows // 3
            n_frames, rows, t_dec, t_all, commits, t_ins = run(n, batch, tmp, temps)
            print(f"{batch:>13} {n_frames:>8} {n_frames / t_dec:>16.0f} {rows / t_ins:>14.0f} "
                  f"{n_frames / t_all:>20.0f} {rows / t_all:>10.0f} {commits:>8}  "
                  f">= {GOAL} frames/s" + ("  (with temperature messages)" if temps else ""))
            fps = n_frames / t_all
            if temps:
                before = plain[batch]
                record(f"logger end to end, {batch} records/frame + a temperature message "
                       "per mote per second", "no measurable slow-down (#16)", rows / t_all,
                       "records/s", None, digits=3,
                       note=f"{before:.0f} records/s without them in the same run "
                            f"({(rows / t_all) / before - 1:+.1%}); one core, timing noise "
                            "of a shared machine included")
                continue
            plain[batch] = rows / t_all
            record(f"logger end to end, {batch} record(s)/frame", f">= {GOAL} frames/s (#3)",
                   fps, "frames/s", fps >= GOAL, digits=3,
                   note=f"{rows / t_all:.0f} records/s; bytes to committed sqlite rows, one core")
            record(f"  of which decoding alone, {batch} record(s)/frame", "", n_frames / t_dec,
                   "frames/s", None, digits=3)
            record(f"  of which sqlite inserts alone, {batch} record(s)/frame", "", rows / t_ins,
                   "rows/s", None, digits=3)
    print("decode = FrameDecoder + vectorised sample decoding + sequence checks; insert = "
          "sqlite executemany of decoded rows; end-to-end = both, timed until the "
          "session is committed and ended.  A real line carries at most ~1000 records/s.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
