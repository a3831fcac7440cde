"""Issue 15, case 6: two loggers appending to one session (two BaseStations
hearing the same motes) keep every distinct sample; true duplicates are
counted, different values under one key are kept aside and counted."""
import threading

import numpy as np

from motecal.capture.link import LinkTracker
from motecal.capture.logger import Logger
from motecal.line import sources as S
from motecal.sessions.store import open_store
from test_logger_streams import sample_frames

N = 2000


def two_stations(tmp_path, seed=0):
    """Station A hears motes 1 and 2, station B motes 2 and 3.  Both hear
    mote 2's samples 0..N-1; B got 40 of them with other values (damage a
    CRC let through).  Returns the recordings and the planted truth."""
    rng = np.random.default_rng(seed)
    raw = {m: rng.integers(-3000, 3000, (N, 9)).astype(np.int16) for m in (1, 2, 3)}
    other = raw[2].copy()
    differ = np.sort(rng.choice(np.arange(5, N // 5) * 5, 8, replace=False))
    rows = (differ[:, None] + np.arange(5)).ravel()            # whole messages of 5
    other[rows, 4] ^= 0x155
    recs = {}
    for k, raws in (("A", {1: raw[1], 2: raw[2]}), ("B", {2: other, 3: raw[3]})):
        frames, _ = sample_frames(raws)
        recs[k] = tmp_path / f"{k}.bin"
        recs[k].write_bytes(b"".join(frames))
    return recs, raw, other, rows


def log_together(target, recs, session="x"):
    """Both stations log into one session at once, as two `log --append` do."""
    with open_store(target, create=True) as st:
        st.open_session(session, kind="free").mark_ended()
    writers, errors = {}, []
    go = threading.Barrier(len(recs))

    def station(k):
        try:
            with open_store(target) as st:
                w = st.open_session(session, kind="free", append=True, commit_every=0.01,
                                    meta={"source": f"station {k}"})
                writers[k] = w
                go.wait(10)
                Logger(S.parse_port(str(recs[k])), w, LinkTracker()).run()
        except Exception as e:                   # surfaced below
            errors.append(e)

    threads = [threading.Thread(target=station, args=(k,)) for k in recs]
    for t in threads:
        t.start()
    for t in threads:
        t.join(120)
    assert not errors, errors
    return writers


def check_model(target, writers, raw, other, rows, session="x"):
    with open_store(target) as st:
        d = st.load_session(session)
        conf = st.conflicts(session)
        rows_w = st.writers(session)
    # every distinct (mote, seq) once
    for m in (1, 2, 3):
        dm = d.for_mote(m)
        np.testing.assert_array_equal(dm.seq, np.arange(N))
    np.testing.assert_array_equal(d.for_mote(1).raw, raw[1])
    np.testing.assert_array_equal(d.for_mote(3).raw, raw[3])
    same = np.setdiff1d(np.arange(N), rows)
    np.testing.assert_array_equal(d.for_mote(2).raw[same], raw[2][same])
    # each differing key: one version stored, the other kept in sample_conflicts
    assert set(conf.mote.tolist()) == {2}
    np.testing.assert_array_equal(conf.seq, rows)
    stored2 = d.for_mote(2).raw[rows]
    for i in range(len(rows)):
        pair = {tuple(stored2[i]), tuple(conf.raw[i])}
        assert pair == {tuple(raw[2][rows[i]].astype(float)),
                        tuple(other[rows[i]].astype(float))}
    # the counts: duplicates = the identical overlap, conflicts = the rest
    assert len(rows_w) == 2
    assert sum(r["duplicates"] for r in rows_w) == N - len(rows)
    assert sum(r["conflicts"] for r in rows_w) == len(rows)
    assert sum(r["stored"] for r in rows_w) == 3 * N
    assert {r["source"] for r in rows_w} == {"station A", "station B"}
    assert all(r["ended"] for r in rows_w)
    assert sum(w.duplicates for w in writers.values()) == N - len(rows)


def test_case6_two_loggers_one_session_sqlite(tmp_path):
    recs, raw, other, rows = two_stations(tmp_path)
    db = str(tmp_path / "two.db")
    writers = log_together(db, recs)
    check_model(db, writers, raw, other, rows)


def test_case6_the_summary_says_so(tmp_path):
    recs, raw, other, rows = two_stations(tmp_path, seed=1)
    db = str(tmp_path / "two.db")
    writers = log_together(db, {"A": recs["A"]})
    with open_store(db) as st:
        w = st.open_session("x", kind="free", append=True)
        lg = Logger(S.parse_port(str(recs["B"])), w, LinkTracker())
        lg.run()
    text = "\n".join(lg.summary_lines())
    assert f"{N - len(rows)} samples they had stored already" in text
    assert f"{len(rows)} stored with other values" in text
