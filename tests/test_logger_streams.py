"""Synthetic serial streams for the logger tests (built with protocol.encode_am /
pack_samples), and checks that the streams themselves are what they claim."""
from __future__ import annotations

import numpy as np

from motecal.line import protocol as P
from motecal.maths.sphere import fibonacci_sphere

G = 256.0            # ADXL345 counts per g
GYRO = 14.375        # ITG3200 counts per deg/s


def pose_trajectory(n_poses=6, still=250, move=120, seed=0, lead=60):
    """Rows (n, 9) int16 of a board put into ``n_poses`` static poses (evenly
    spread directions) with smooth turns in between; ``truth`` is the pose index
    of rows well inside a still stretch, 0 while moving."""
    rng = np.random.default_rng(seed)
    dirs = fibonacci_sphere(n_poses)
    earth = np.array([0.2, 0.0, -0.43]) * 1090.0
    rows, truth = [], []

    def still_block(d, k, n):
        acc = G * d + rng.normal(0, 1.2, (n, 3))
        gyr = np.array([12.0, -7.0, 3.0]) + rng.normal(0, 4.0, (n, 3))
        mag = _mag_for(d, earth) + rng.normal(0, 1.5, (n, 3))
        rows.append(np.hstack([acc, gyr, mag]))
        truth.extend([k] * n)

    prev = np.array([0.0, 0.0, 1.0])
    # start moving so the first pose is a new still stretch
    for k, d in enumerate(dirs, start=1):
        m = move if k > 1 else lead
        a = prev if k > 1 else np.array([0.3, 0.2, 0.93]) / np.linalg.norm([0.3, 0.2, 0.93])
        ang = np.arccos(np.clip(a @ d, -1, 1))
        s = (1 - np.cos(np.linspace(0, np.pi, m))) / 2          # smooth start and stop
        path = _slerp(a, d, s)
        rate = np.gradient(s) * ang * 125.0 * 180 / np.pi           # deg/s along the path
        axis = np.cross(a, d)
        axis = axis / np.linalg.norm(axis) if np.linalg.norm(axis) > 1e-9 else np.array([1.0, 0, 0])
        # a hand never turns perfectly smoothly: add a wobble while moving
        wob = np.sin(np.linspace(0, 6 * np.pi, m))[:, None] * 25.0
        acc = G * path + rng.normal(0, 1.2, (m, 3)) + wob * np.array([1, -1, 0.5])
        gyr = np.array([12.0, -7.0, 3.0]) + GYRO * rate[:, None] * axis + rng.normal(0, 4, (m, 3))
        mag = np.array([_mag_for(p, earth) for p in path]) + rng.normal(0, 1.5, (m, 3))
        rows.append(np.hstack([acc, gyr, mag]))
        truth.extend([0] * m)
        still_block(d, k, still)
        prev = d
    raw = np.clip(np.rint(np.vstack(rows)), -32768, 32767).astype(np.int16)
    return raw, np.array(truth)


def _slerp(a, b, s):
    om = np.arccos(np.clip(a @ b, -1, 1))
    if om < 1e-9:
        return np.tile(a, (len(s), 1))
    return (np.sin((1 - s) * om)[:, None] * a + np.sin(s * om)[:, None] * b) / np.sin(om)


def _mag_for(d, earth):
    """Earth field seen by a board whose 'up' is d (rotation taking +Z to d)."""
    z = np.array([0.0, 0.0, 1.0])
    v = np.cross(z, d)
    c = float(z @ d)
    if np.linalg.norm(v) < 1e-9:
        r = np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    else:
        vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
        r = np.eye(3) + vx + vx @ vx / (1 + c)
    return r.T @ earth + np.array([40.0, -25.0, 10.0])       # plus a hard-iron offset


def sample_frames(raw_by_mote: dict, *, batch=5, seq0=None, status_every=0, group=0x22):
    """Frames of every mote's rows, interleaved in time; returns (frames, sent)
    where sent[mote] = (unwrapped seqs, rows) in the order sent."""
    seq0 = seq0 or {}
    per_mote = {}
    for m, raw in raw_by_mote.items():
        s0 = seq0.get(m, 0)
        msgs = []
        for i in range(0, len(raw), batch):
            rec = raw[i:i + batch]
            payload = P.pack_samples(s0 + i, 0x10, rec)
            msgs.append(P.encode_am(P.AMPacket(0xFFFF, m, group, P.AM_NINEDOF_SAMPLES_MSG,
                                               payload)))
        per_mote[m] = msgs
    frames = []
    longest = max(len(v) for v in per_mote.values())
    for i in range(longest):
        for m in sorted(per_mote):
            if i < len(per_mote[m]):
                frames.append(per_mote[m][i])
        if status_every and i % status_every == status_every - 1:
            for m in sorted(per_mote):
                frames.append(P.message_frame(P.MOTE_STATUS, dest=0xFFFF, src=m, seq=i,
                                              version=3, sensors=0, dropped=i // 50,
                                              send_fail=1, i2c_errors=0, late=2))
            frames.append(P.message_frame(P.BS_STATUS, dest=0xFFFF, src=0, radio_rx=i,
                                          radio_drops=0, serial_rx=0, serial_drops=0,
                                          radio_fail=0, serial_fail=0))
    sent = {m: (seq0.get(m, 0) + np.arange(len(r)), r) for m, r in raw_by_mote.items()}
    return frames, sent


def test_trajectory_poses_are_still_and_distinct():
    from motecal.sessions.still import segment_still
    raw, truth = pose_trajectory(n_poses=5, seed=2)
    lab = segment_still(raw.astype(float), 125.0)
    assert lab.max() == 5
    # every still segment found lies inside one true pose
    for k in range(1, 6):
        assert set(np.unique(truth[lab == k])) <= {0, k}


def test_frames_decode_back_to_rows():
    raw, _ = pose_trajectory(n_poses=2, seed=1)
    frames, sent = sample_frames({1: raw, 7: raw[:100]}, seq0={1: 65530})
    got = [P.decode_message(f.am()) for f in P.decode_stream(b"".join(frames))]
    assert sum(len(g.records) for g in got) == len(raw) + 100
    assert got[0].seq == 65530 and got[2].seq == (65530 + 5) % 65536
