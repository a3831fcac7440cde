"""Logger pieces: vectorised decoding agrees with protocol.decode_message,
sequence tracking (wrap, gaps, duplicates, reordering, restarts), the guided
state machines, and whole in-process runs into sqlite."""
import numpy as np
import pytest

from motecal.capture.guide import GuidedFlow, PoseCapture, RotationCapture, describe_up, sketch_up
from motecal.capture.link import LinkTracker, MoteLink
from motecal.capture.logger import Logger
from motecal.line import protocol as P
from motecal.line import sources as S
from motecal.line.samples import decode_sample_frames
from motecal.maths.sphere import SphereCoverage, fibonacci_sphere
from motecal.sessions.session import LABEL_ROT
from motecal.sessions.store import open_store
from test_logger_streams import pose_trajectory, sample_frames


def _frames(data: bytes):
    return P.FrameDecoder().feed(data)


# --------------------------------------------------------------------------
# decoding
# --------------------------------------------------------------------------
def test_batch_decoding_equals_decode_message():
    rng = np.random.default_rng(4)
    stream = []
    for i in range(400):
        kind = rng.integers(0, 10)
        if kind < 7:                      # sample messages of any count
            n = int(rng.integers(1, 7))
            rec = rng.integers(-32768, 32768, (n, 9))
            stream.append(P.encode_am(P.AMPacket(0xFFFF, int(rng.integers(0, 65536)), 0x22,
                                                 P.AM_NINEDOF_SAMPLES_MSG,
                                                 P.pack_samples(int(rng.integers(0, 65536)),
                                                                int(rng.integers(0, 256)), rec))))
        elif kind == 7:                   # count disagrees with the length
            bad = P.pack_samples(5, 0, np.ones((3, 9))) + b"\x00"
            stream.append(P.encode_am(P.AMPacket(0xFFFF, 1, 0x22, P.AM_NINEDOF_SAMPLES_MSG, bad)))
        elif kind == 8:
            stream.append(P.message_frame(P.MOTE_STATUS, dest=0xFFFF, src=3, seq=9, dropped=2))
        else:
            stream.append(P.encode_frame(bytes((P.PROTO_PACKET_NOACK, 0x42)) + b"not an AM packet"))
    frames = _frames(b"".join(stream))
    batch, others = decode_sample_frames(frames)
    expect = []
    n_other = n_bad = 0
    for f in frames:
        am = f.am()
        if am is not None and am.am_type == P.AM_NINEDOF_SAMPLES_MSG:
            msg = P.decode_message(am)
            if msg is None:
                n_bad += 1
            else:
                expect.append((am.src, msg))
        else:
            n_other += 1
    assert len(batch) == len(expect) and batch.bad == n_bad > 0 and len(others) == n_other > 0
    assert batch.src.tolist() == [e[0] for e in expect]
    assert batch.seq.tolist() == [e[1].seq for e in expect]
    assert batch.flags.tolist() == [e[1].flags for e in expect]
    np.testing.assert_array_equal(batch.records, np.vstack([e[1].records for e in expect]))
    assert batch.records.dtype == np.int16
    tr = LinkTracker()
    tr.other(others)
    n_status = sum(1 for f in others if f.am() and f.am().am_type == P.AM_NINEDOF_MOTE_STATUS_MSG)
    assert tr.motes[3].c["status_msgs"] == n_status > 0 and tr.motes[3].c["mote_dropped"] == 2
    assert tr.line["unknown_msgs"] == len(others) - n_status > 0
    empty, rest = decode_sample_frames([])
    assert len(empty) == 0 and len(empty.records) == 0 and rest == []


# --------------------------------------------------------------------------
# sequence numbers
# --------------------------------------------------------------------------
def _accept(link, seqs, count=5):
    seqs = np.asarray(seqs) % 65536
    u, keep, released = link.accept(seqs, np.full(len(seqs), count), lambda i: ("msg", i))
    return u.tolist(), keep, [r[0] for r in released]


def test_wrap_gap_duplicate_reorder_restart():
    link = MoteLink(1)
    u, keep, rel = _accept(link, [65525, 65530, 65535, 4, 9])     # wraps at 65536
    assert u == [65525, 65530, 65535, 65540, 65545]
    # the first frame is held until the second confirms it, then released
    assert keep.tolist() == [False] * 5 + [True] * 20 and rel == [65525]
    assert link.c["samples"] == 25 and link.c["first_seq"] == 65525
    u, keep, rel = _accept(link, [24, 29])                         # 14, 19 lost
    assert u == [65560, 65565] and link.c["lost"] == 10 and keep is None and rel == []
    u, keep, _ = _accept(link, [19, 14, 24])    # late ones fill the gap; 24 is a duplicate
    assert u == [65555, 65550, 65560]
    assert keep.tolist() == [True] * 10 + [False] * 5
    assert (link.c["lost"], link.c["reordered"], link.c["duplicates"]) == (0, 10, 5)
    assert link.c["samples"] == 25 + 10 + 10 and link.c["last_seq"] == 65569
    assert link.c["frames"] == 10


def test_implausible_frames_wait_for_confirmation():
    link = MoteLink(2)
    _accept(link, [30000, 30005, 30010])
    # a frame far ahead (CRC-16 let a corrupted one through), then the stream goes on
    u, keep, rel = _accept(link, [50000, 30015, 30020])
    assert keep.tolist() == [False] * 5 + [True] * 10 and rel == []
    assert link.c["rejected"] == 1 and link.c["lost"] == 0 and link.end == 30025
    # a real outage of 20 s: the frame after the jump confirms it
    u, keep, rel = _accept(link, [32525, 32530])
    assert keep.tolist() == [False] * 5 + [True] * 5 and rel == [32525]
    assert link.c["lost"] == 2500 and link.end == 32535
    # a mote that reboots starts again from 0: its numbering is continued
    u, keep, rel = _accept(link, [0, 5, 10])
    assert rel == [32535] and keep.tolist() == [False] * 5 + [True] * 10
    assert link.c["restarts"] == 1 and link.end == 32550 and link.c["lost"] == 2500
    u, keep, rel = _accept(link, [15])
    assert u == [32550] and keep is None


def test_a_reboot_below_the_window_is_told_from_duplicates_by_the_records():
    rng = np.random.default_rng(3)
    old, new = (rng.integers(-999, 999, (100, 9)).astype(np.int16) for _ in range(2))
    link = MoteLink(4)

    def feed(seq0, rec):
        seqs = np.arange(seq0, seq0 + len(rec), 5)
        return link.accept(seqs, np.full(len(seqs), 5), lambda i: (0, rec[5 * i:5 * i + 5]), rec)

    feed(0, old[:60])                                  # 0..59 (the first frame waits, then goes)
    _, keep, _ = feed(40, old[40:70])                  # a repeat of 40..59, then 60..69 new
    assert keep.tolist() == [False] * 20 + [True] * 10 and link.c["duplicates"] == 20
    # the mote reboots at 70 and counts from 0 again: its records are new ones
    u, keep, rel = feed(0, new[:20])
    assert [r[0] for r in rel] == [70]
    assert keep.tolist() == [False] * 5 + [True] * 15 and u.tolist()[1:] == [75, 80, 85]
    c = link.c
    assert (c["restarts"], c["duplicates"], c["lost"], c["samples"]) == (1, 20, 0, 90)
    # a repeat of the rebooted stream is a duplicate again
    _, keep, _ = feed(15, new[15:25])
    assert keep.tolist() == [False] * 5 + [True] * 5 and link.c["duplicates"] == 25
    # a frame whose records differ but that nothing continues is dropped
    feed(25, new[25:30])
    _, keep, _ = feed(65536 - 60, old[10:15] + 1)     # at 10..14 (CRC-16 missed a corruption)
    assert keep.tolist() == [False] * 5
    _, keep, _ = feed(30, new[30:35])
    assert keep.tolist() == [True] * 5 and link.c["rejected"] == 1 and link.c["restarts"] == 1


def test_a_mote_seen_once_is_not_a_mote():
    tr = LinkTracker()
    frames, _ = sample_frames({7: np.ones((5, 9), np.int16)})
    rows = tr.samples(decode_sample_frames(_frames(b"".join(frames)))[0])
    assert len(rows) == 0 and tr.seen() == {}


def test_tracker_continues_an_appended_session():
    tr = LinkTracker(link={2: {"samples": 100, "lost": 3}}, last_seqs={2: 70004})
    assert tr.seen().keys() == {2}
    frames, _ = sample_frames({2: np.zeros((10, 9), np.int16)}, seq0={2: 70005 % 65536})
    rows = tr.samples(decode_sample_frames(_frames(b"".join(frames)))[0])
    assert rows.seq.tolist() == list(range(70005, 70015))
    assert tr.motes[2].c["samples"] == 110 and tr.motes[2].c["lost"] == 3


def test_appended_run_does_not_count_the_time_between_runs_as_lost():
    """motecal log --append after the logger (and perhaps the mote) stopped:
    the mote kept counting, or it rebooted and starts from 0 again."""
    kept = LinkTracker(link={1: {"samples": 37561}}, last_seqs={1: 37560})
    frames, _ = sample_frames({1: np.zeros((10, 9), np.int16)}, seq0={1: 50000})
    rows = kept.samples(decode_sample_frames(_frames(b"".join(frames)))[0])
    assert rows.seq.tolist() == list(range(50000, 50010))
    assert kept.motes[1].c["lost"] == 0
    rebooted = LinkTracker(link={1: {"samples": 37561}}, last_seqs={1: 37560})
    frames, _ = sample_frames({1: np.zeros((10, 9), np.int16)}, seq0={1: 0})    # 27976 on
    rows = rebooted.samples(decode_sample_frames(_frames(b"".join(frames)))[0])
    assert rows.seq.tolist() == list(range(65536, 65546))     # after the stored records
    c = rebooted.motes[1].c
    assert c["lost"] == 0 and c["samples"] == 37571
    # a mote restarted just behind the stored numbering
    back = LinkTracker(link={1: {"samples": 101}}, last_seqs={1: 100})
    frames, _ = sample_frames({1: np.zeros((5, 9), np.int16)}, seq0={1: 50})
    rows = back.samples(decode_sample_frames(_frames(b"".join(frames)))[0])
    assert rows.seq.tolist() == list(range(65586, 65591)) and back.motes[1].c["lost"] == 0
    # and later gaps still count
    frames, _ = sample_frames({1: np.zeros((10, 9), np.int16)}, seq0={1: 20})
    rebooted.samples(decode_sample_frames(_frames(b"".join(frames)))[0])
    assert rebooted.motes[1].c["lost"] == 10


def test_tracker_interleaved_motes_and_status():
    raw = {m: np.arange(60 * 9).reshape(60, 9).astype(np.int16) + m for m in (1, 2, 3)}
    frames, sent = sample_frames(raw, seq0={1: 65500, 2: 0, 3: 40000}, status_every=4)
    tr = LinkTracker()
    fr = _frames(b"".join(frames))
    batch, others = decode_sample_frames(fr)
    tr.other(others)
    rows = tr.samples(batch)
    for m in (1, 2, 3):
        sel = rows.mote == m
        assert rows.seq[sel].tolist() == sent[m][0].tolist()
        np.testing.assert_array_equal(rows.raw[sel], raw[m])
    assert tr.motes[1].c["status_msgs"] == 3 and tr.motes[1].c["mote_late"] == 2
    assert tr.motes[3].c["cal_version"] == 3 and tr.line["bs_status_msgs"] == 3


# --------------------------------------------------------------------------
# guidance
# --------------------------------------------------------------------------
def test_sphere_cells_are_equal_area_and_targets_spread():
    cov = SphereCoverage(10, 10)
    v = np.random.default_rng(1).normal(size=(200_000, 3))
    counts = np.bincount(cov.cell_of(v), minlength=100)
    assert counts.min() > 0.9 * 2000 and counts.max() < 1.1 * 2000
    d = fibonacci_sphere(80)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0)
    ang = np.degrees(np.arccos(np.clip(d @ d.T, -1, 1))) + np.eye(80) * 999
    assert ang.min(axis=1).min() > 15.0          # no two targets closer than the warning
    assert describe_up([0, 0, 1]) == "+Z face up, level"
    assert describe_up([0.5, 0, 0.866]) == "+Z face up, tilted 30 deg toward +X"
    assert describe_up([0, -1, 0.05]) == "-Y face up, tilted 3 deg toward +Z" or \
        describe_up([0, -1, 0.05]) == "-Y face up, level"
    assert describe_up([-0.7, 0, -0.7]).startswith(("-X face up, tilted 45", "-Z face up, tilted 45"))
    assert any("+Z" in line for line in sketch_up([0, 0.3, 1]))


def _feed(cap, raw, seq0=0, chunk=37):
    events = []
    for i in range(0, len(raw), chunk):
        events += cap.update(np.arange(seq0 + i, seq0 + i + len(raw[i:i + chunk])),
                             raw[i:i + chunk])
    return events


def test_static_poses_labelled_inside_true_still_stretches():
    raw, truth = pose_trajectory(n_poses=6, seed=3)
    cap = PoseCapture(1, poses=6)
    events = _feed(cap, raw, seq0=100)
    labels = [e for e in events if e.kind == "label"]
    assert [e.label for e in labels] == [1, 2, 3, 4, 5, 6] and cap.done
    for e in labels:
        assert e.seq_hi - e.seq_lo + 1 == 200
        assert set(truth[e.seq_lo - 100:e.seq_hi - 100 + 1]) == {e.label}
    assert events[-1].kind == "done"
    assert [p.index for p in cap.accepted] == [1, 2, 3, 4, 5, 6]
    # the accepted gravity directions are the true ones
    for p, d in zip(cap.accepted, fibonacci_sphere(6)):
        assert np.degrees(np.arccos(np.clip(p.direction @ d, -1, 1))) < 1.0


def test_movement_during_capture_discards_and_retries():
    raw, truth = pose_trajectory(n_poses=3, seed=4, still=400)
    raw = raw.copy()
    s1 = np.flatnonzero(truth == 1)
    bump = s1[0] + 120                          # a knock 120 rows into pose 1
    raw[bump:bump + 6, :3] += np.array([40, -30, 25], np.int16)
    cap = PoseCapture(1, poses=3)
    events = _feed(cap, raw)
    kinds = [e.kind for e in events if e.kind in ("discarded", "accepted")]
    assert kinds == ["discarded", "accepted", "accepted", "accepted"]
    first = next(e for e in events if e.kind == "label")
    assert first.seq_lo > bump + 6 and set(truth[first.seq_lo:first.seq_hi + 1]) == {1}
    assert cap.discards == 1


def test_pose_too_close_is_refused_with_a_warning():
    raw, truth = pose_trajectory(n_poses=2, seed=5)
    # the board goes back (5 deg off) to pose 1 before reaching pose 2
    r1 = raw[truth == 1]
    tilt = np.array([[1, 0, 0], [0, np.cos(0.09), -np.sin(0.09)], [0, np.sin(0.09), np.cos(0.09)]])
    near = r1.astype(float).copy()
    near[:, :3] = near[:, :3] @ tilt.T
    wobble = raw[truth == 0][:120]
    stream = np.vstack([raw[:np.flatnonzero(truth == 1)[-1] + 1], wobble, near.astype(np.int16),
                        raw[np.flatnonzero(truth == 1)[-1] + 1:]])
    cap = PoseCapture(1, poses=2)
    events = _feed(cap, stream)
    kinds = [e.kind for e in events if e.kind != "capturing"]
    assert kinds[:3] == ["label", "accepted", "too_close"]
    assert "from pose 1" in next(e.text for e in events if e.kind == "too_close")
    assert kinds[-1] == "done" and [p.index for p in cap.accepted] == [1, 2]
    assert cap.accepted[1].direction @ cap.accepted[0].direction < np.cos(np.radians(15))


def test_interactive_pose_waits_for_enter():
    raw, truth = pose_trajectory(n_poses=2, seed=6)
    cap = PoseCapture(1, poses=2, auto=False)
    half = np.flatnonzero(truth == 1)[0] + 100
    assert not [e for e in _feed(cap, raw[:half]) if e.kind == "label"]
    assert cap.phase.name == "WAIT_STILL" and not cap.armed
    half = np.flatnonzero(truth == 0)[-1] - 30        # on the way to pose 2
    cap = PoseCapture(1, poses=2, auto=False)
    _feed(cap, raw[:half])
    cap.arm()                                   # the person presses Enter
    events = _feed(cap, raw[half:], seq0=half)
    labels = [e for e in events if e.kind == "label"]
    assert [e.label for e in labels] == [1]     # the next pose needs another Enter
    assert not cap.armed and cap.next_pose == 2
    assert set(truth[labels[0].seq_lo:labels[0].seq_hi + 1]) == {2}


def test_rotation_until_coverage_or_count():
    rng = np.random.default_rng(7)
    n = 3000
    # a magnetometer turned through all directions, with a hard-iron offset
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    raw = np.zeros((n, 9), np.int16)
    raw[:, 6:] = np.rint(d * 500 + [120, -80, 40])
    cap = RotationCapture(2, samples=5000, coverage=0.9)
    events = _feed(cap, raw, seq0=1000, chunk=50)
    assert cap.done and events[-1].kind == "done"
    assert 0.9 <= cap.coverage.fraction
    assert cap.count < 1000                     # random directions cover the sphere quickly
    np.testing.assert_allclose(cap.centre, [120, -80, 40], atol=5)
    lab = [e for e in events if e.kind == "label"]
    assert all(e.label == LABEL_ROT for e in lab)
    assert lab[0].seq_lo == 1000 and lab[-1].seq_hi == 1000 + cap.count - 1
    # a turn about one axis only never covers the sphere: stops at the count
    ang = np.linspace(0, 20 * np.pi, 1200)
    ring = np.zeros((1200, 9), np.int16)
    ring[:, 6] = np.rint(500 * np.cos(ang))
    ring[:, 7] = np.rint(500 * np.sin(ang))
    cap = RotationCapture(2, samples=1000)
    events = _feed(cap, ring, chunk=64)
    assert cap.done and cap.count == 1000 and cap.coverage.fraction < 0.3
    assert "1000 samples" in events[-1].text


def test_guided_flow_follows_one_mote_or_all():
    raw, _ = pose_trajectory(n_poses=2, seed=8)
    mote = np.repeat([1, 2], len(raw))
    seq = np.tile(np.arange(len(raw)), 2)
    both = np.vstack([raw, raw])
    flow = GuidedFlow("static80", follow=2, options=dict(poses=2))
    ev = flow.update(mote, seq, both)
    assert {e.mote for e in ev} == {2} and flow.done and list(flow.captures) == [2]
    flow = GuidedFlow("static80", options=dict(poses=2))
    ev = flow.update(mote, seq, both)
    assert {e.mote for e in ev if e.kind == "label"} == {1, 2} and flow.done
    with pytest.raises(ValueError):
        GuidedFlow("dance")


# --------------------------------------------------------------------------
# whole runs, in process
# --------------------------------------------------------------------------
def test_logger_run_from_recorded_file(tmp_path):
    raws = {m: pose_trajectory(n_poses=4, seed=10 + m)[0] for m in (1, 2, 3)}
    frames, sent = sample_frames(raws, seq0={1: 65000, 2: 0, 3: 123}, status_every=50)
    rec = tmp_path / "rec.bin"
    rec.write_bytes(b"\xff\x00junk" + b"".join(frames))
    db = str(tmp_path / "run.db")
    with open_store(db, create=True) as st:
        w = st.open_session("r", kind="static80", meta={"source": str(rec)})
        lg = Logger(S.parse_port(str(rec)), w, LinkTracker(),
                    guide=GuidedFlow("static80", follow=2, options=dict(poses=4)))
        lg.run()
        assert lg.stop_reason in ("end of input", "guided flow done")
        d = st.load_session("r")
        for m in (1, 2, 3):
            dm = d.for_mote(m)
            np.testing.assert_array_equal(dm.seq, sent[m][0])
            np.testing.assert_array_equal(dm.raw, sent[m][1])
        assert d.for_mote(2).poses() == [1, 2, 3, 4] and d.for_mote(1).poses() == []
        assert np.bincount(d.for_mote(2).label)[1:].tolist() == [200] * 4
        stats = st.link_stats("r")
        assert stats["line"]["garbage_bytes"] == 6 and stats["line"]["frames"] == len(frames)
        assert stats["motes"][1]["first_seq"] == 65000 and stats["motes"][3]["lost"] == 0
        assert st.sessions()[0]["ended"] is not None
        kinds = [e["kind"] for e in st.events("r")]
        assert kinds.count("accepted") == 4 and kinds[-1] == "done"


def test_plain_status_line_never_counts_past_the_last_pose(tmp_path):
    import io
    from motecal.commands.log_screen import PlainDisplay
    raw = pose_trajectory(n_poses=3, seed=11)[0]
    frames, _ = sample_frames({1: raw}, seq0={1: 0})
    rec = tmp_path / "rec.bin"
    rec.write_bytes(b"".join(frames))
    out = io.StringIO()
    with open_store(str(tmp_path / "run.db"), create=True) as st:
        w = st.open_session("r", kind="static80", meta={"source": str(rec)})
        lg = Logger(S.parse_port(str(rec)), w, LinkTracker(), display=PlainDisplay(out, every=0),
                    guide=GuidedFlow("static80", options=dict(poses=3)))
        lg.run()
    assert lg.guide.done
    shown = [int(x) for x in __import__("re").findall(r"pose (\d+)/3", out.getvalue())]
    assert shown and max(shown) == 3 and shown[-1] == 3
    assert lg.guide.captures[1].status()["pose"] == 3


def test_a_frame_cut_short_when_the_line_ends_is_not_a_crc_error(tmp_path, capsys):
    raw = pose_trajectory(n_poses=1, seed=12)[0][:50]
    frames, _ = sample_frames({1: raw}, seq0={1: 0})
    rec = tmp_path / "rec.bin"
    rec.write_bytes(b"".join(frames) + frames[0][:20])    # the recording stops mid-frame
    with open_store(str(tmp_path / "run.db"), create=True) as st:
        w = st.open_session("r", kind="free", meta={"source": str(rec)})
        from motecal.commands.log_screen import PlainDisplay
        Logger(S.parse_port(str(rec)), w, LinkTracker(), display=PlainDisplay()).run()
        line = st.link_stats("r")["line"]
    assert (line["cut_off"], line["crc_errors"], line["frames"]) == (1, 0, len(frames))
    assert f"line: {len(frames)} frames, 0 CRC errors, 1 cut off, 0 malformed" in \
        capsys.readouterr().out


def test_a_finished_guided_log_stops_within_the_drain_not_at_the_end_of_the_line(tmp_path):
    """After the last pose the logger reads on for DRAIN_S of sample time, not
    3 s of wall time: a line read faster than real time (a simulator served
    as fast as it is read, a recording) is not swallowed to its end."""
    from motecal.capture.logger import DRAIN_S
    from motecal.commands.log_screen import PlainDisplay
    raw = pose_trajectory(n_poses=3, seed=13)[0]
    tail = np.tile(raw[-1], (30000, 1))                 # the board stays where it is
    frames, _ = sample_frames({1: np.vstack([raw, tail])}, seq0={1: 0})
    rec = tmp_path / "rec.bin"
    rec.write_bytes(b"".join(frames))
    with open_store(str(tmp_path / "run.db"), create=True) as st:
        w = st.open_session("r", kind="static80", meta={"source": str(rec)})
        lg = Logger(S.parse_port(str(rec)), w, LinkTracker(), display=PlainDisplay(),
                    guide=GuidedFlow("static80", options=dict(poses=3)))
        lg.run()
        d = st.load_session("r")
    assert lg.stop_reason == "guided flow done" and d.poses() == [1, 2, 3]
    last_pose = int(d.seq[d.label == 3].max())
    per_read = S.READ_SIZE // len(frames[0]) * 5            # records in one read
    assert last_pose + DRAIN_S * 125 <= d.seq.max() < last_pose + 2 * per_read < len(raw) + 20000


def test_push_many_decides_like_push_row_by_row():
    from motecal.sessions.still import StillDetector
    rng = np.random.default_rng(12)
    rows = rng.normal(0, 1, (2500, 9)) + [0, 0, 256, 20, -10, 5, 200, 0, -400]
    rows[400:600, :3] += rng.normal(0, 25, (200, 3))          # shaking
    rows[900:1000, 3:6] += np.linspace(0, 400, 100)[:, None]  # a turn the gyro sees
    rows[1500:1510, 6:] = np.nan                               # magnetometer gaps
    rows[2000:2300, 3:6] = np.nan
    one = StillDetector(125.0)
    ref = np.array([one.push(r) for r in rows])
    assert 0.3 < ref.mean() < 0.95
    for chunk in (1, 7, 50, 333, 2500):
        many = StillDetector(125.0)
        got = np.concatenate([many.push_many(rows[i:i + chunk])
                              for i in range(0, len(rows), chunk)])
        np.testing.assert_array_equal(got, ref)
        assert many.still == one.still


def test_argument_mistakes_are_one_line(tmp_path, capsys):
    from motecal.commands import main as cli
    rec = tmp_path / "rec.bin"
    rec.write_bytes(b"")
    base = ["log", "--db", str(tmp_path / "x.db"), "--session", "s", "--port", str(rec)]
    cases = [(["log"], "required"),
             (base + ["--duration", "-3"], "must be > 0"),
             (base + ["--duration", "soon"], "not a number"),
             (base + ["--guided", "dance"], "invalid choice"),
             (base + ["--mote", "70000"], "1..65534"),
             (base + ["--board", "7"], "MOTE=BOARD"),
             (base + ["--guided", "rotation", "--coverage", "1.5"], "fraction"),
             (base + ["--baud", "0"], "baud rate must be a whole number 300..4000000"),
             (base + ["--baud", "1"], "baud rate must be a whole number 300..4000000"),
             (base + ["--guided", "static80", "--min-angle", "500"], "--min-angle must be within 0..90"),
             (base + ["--guided", "static80", "--min-angle", "30"],
              "the sphere has room for at most 58"),
             (base[:3] + ["--session", ""] + base[5:], "not empty or blank"),
             (base[:3] + ["--session", "  "] + base[5:], "not empty or blank")]
    for argv, msg in cases:
        assert cli.main(argv) == 2, argv
        err = capsys.readouterr().err
        assert msg in err and len(err.strip().splitlines()) == 1, (argv, err)
    assert not (tmp_path / "x.db").exists()


# --------------------------------------------------------------------------
# the board temperature (ninedof_mote_temp_msg)
# --------------------------------------------------------------------------
def _temp_frame(mote, seq16, celsius, count=125):
    raw = int(round(float(P.temp_raw(celsius))))
    return P.message_frame(P.MOTE_TEMP, dest=0xFFFF, src=mote, seq=seq16 & 0xFFFF,
                           count=count, reserved=0, temp_sum=raw * count)


def _with_temps(frames, sent, motes, every=25, start=20.0, step=0.25):
    """Insert a temperature message of each of ``motes`` after every ``every``
    sample frames (the mote's newest sample so far), warming by ``step``;
    returns the new frame list and the readings sent (mote, unwrapped seq, C)."""
    out, readings, done = [], [], {m: 0 for m in motes}
    for f in frames:
        out.append(f)
        am = P.decode_stream(f)[0].am()
        m = am.src
        if m in motes and am.am_type == P.AM_NINEDOF_SAMPLES_MSG:
            done[m] += 1
            if done[m] % every == 0:
                u = int(sent[m][0][done[m] * 5 - 1])
                c = start + step * len([r for r in readings if r[0] == m])
                out.append(_temp_frame(m, u, c))
                readings.append((m, u, round(float(P.temp_c(round(float(P.temp_raw(c))))), 9)))
    return out, readings


def test_logger_stores_each_motes_temperature_and_loads_it_per_row(tmp_path, capsys):
    from motecal.commands.log_screen import PlainDisplay
    raws = {m: pose_trajectory(n_poses=2, seed=20 + m)[0] for m in (1, 2, 3)}
    frames, sent = sample_frames(raws, seq0={1: 65400, 2: 0, 3: 7})
    frames, readings = _with_temps(frames, sent, motes=(1, 2))
    early = _temp_frame(2, 3, 19.0)          # before mote 2's first samples: waits for them
    nothing = P.message_frame(P.MOTE_TEMP, dest=0xFFFF, src=1, seq=5, count=0, reserved=0,
                              temp_sum=0)    # no reading in the period: nothing stored
    again = next(f for f in frames if P.decode_stream(f)[0].am().am_type
                 == P.AM_NINEDOF_MOTE_TEMP_MSG)      # a message forwarded twice
    frames = [early, nothing] + frames + [again]
    rec = tmp_path / "rec.bin"
    rec.write_bytes(b"".join(frames))
    with open_store(str(tmp_path / "run.db"), create=True) as st:
        w = st.open_session("r", kind="free", meta={"source": str(rec)})
        lg = Logger(S.parse_port(str(rec)), w, LinkTracker(), display=PlainDisplay(every=0))
        lg.run()
        stored = st.temps("r")
        d = st.load_session("r")
    got = {(int(m), int(s)): c for m, s, _, c, n in stored}
    want = {(m, u): c for m, u, c in readings}
    want[(2, 3)] = round(float(P.temp_c(round(float(P.temp_raw(19.0))))), 9)
    assert set(got) == set(want)                     # the repeated reading kept once
    assert all(abs(got[k] - want[k]) < 1e-9 for k in want)
    assert lg.tracker.motes[1].temp_msgs == len([r for r in readings if r[0] == 1]) + 2
    assert np.isnan(d.temp[d.mote == 3]).all()       # a mote that sends none
    one = d.for_mote(1)
    centres = np.array(sorted(u for m, u, _ in readings if m == 1)) - 62
    assert np.isfinite(one.temp).all()               # rows within 2 s of a reading
    inside = (one.seq >= centres[0]) & (one.seq <= centres[-1])
    assert np.all(np.diff(one.temp[inside]) >= 0)    # warming, interpolated
    assert "mote 1 " in capsys.readouterr().out.split("line:")[0]


def test_an_old_host_ignores_temperature_messages(tmp_path, monkeypatch):
    """A host built before AM 0x69 (its FIXED_MESSAGES lack it) decodes the
    samples and status of a new image unchanged and counts the temperature
    messages as unknown."""
    raws = {m: pose_trajectory(n_poses=1, seed=30 + m)[0] for m in (1, 2)}
    frames, sent = sample_frames(raws, seq0={1: 0, 2: 9}, status_every=20)
    frames, readings = _with_temps(frames, sent, motes=(1, 2), every=10)
    assert readings
    old = {k: v for k, v in P.FIXED_MESSAGES.items() if k != P.AM_NINEDOF_MOTE_TEMP_MSG}
    monkeypatch.setattr(P, "FIXED_MESSAGES", old)
    assert P.decode_message(P.decode_stream(_temp_frame(1, 5, 25.0))[0].am()) is None
    rec = tmp_path / "rec.bin"
    rec.write_bytes(b"".join(frames))
    with open_store(str(tmp_path / "run.db"), create=True) as st:
        w = st.open_session("r", kind="free", meta={"source": str(rec)})
        Logger(S.parse_port(str(rec)), w, LinkTracker()).run()
        d = st.load_session("r")
        line = st.link_stats("r")["line"]
    for m in (1, 2):
        np.testing.assert_array_equal(d.for_mote(m).raw, sent[m][1])
    assert d.temp is None and line["unknown_msgs"] == len(readings) and line["bad_msgs"] == 0


def test_a_temperature_reading_far_from_the_motes_samples_is_rejected():
    link = MoteLink(4)
    link.temperature(dict(seq=3, count=125, reserved=0, temp_sum=-12000 * 125))
    assert link.take_temps() == []                   # waits for the mote's samples
    _accept(link, [65530, 65535, 4, 9])              # samples 65530..65543 (wrapped)
    link.temperature(dict(seq=20000, count=125, reserved=0, temp_sum=-12000 * 125))
    got = link.take_temps()
    assert [u for u, _, _ in got] == [65536 + 3] and link.temp_rejected == 1
    assert got[0][1] == pytest.approx(float(P.temp_c(-12000))) and got[0][2] == 125
    assert link.temp_c == pytest.approx(float(P.temp_c(-12000))) and link.temp_msgs == 2
