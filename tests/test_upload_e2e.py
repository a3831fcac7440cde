"""End to end through one running simulated world (mote 1 on a rig that
does two static80 sessions in a row, ``session="static80,static80"``):

1. log the first session, guided, raw (``motecal.capture.logger.Logger`` in process,
   reading the world in simulated time up to the end of the first part);
2. ``motecal calibrate --db .. --session raw --out cal.json --upload --port
   socket://.. --mote 1``, a subprocess talking to the same world over TCP
   (``serve_in_thread``, paced at real time): calibrate, gate, upload,
   verify, stored; the world stopped as the command exits and booted again
   on its EEPROM file has the new set in force;
3. log again, guided, 12 poses of the second part (in process).

The second session is flagged corrected with version 1, every record is what
the firmware's C code makes of the raw sample and agrees with the float
calibration within its quantisation and output rounding; at the static poses
the corrected accelerometer reads 1 g within the noise, the magnetometer a
constant field and the gyroscope no bias.  (The logs run in process, in
simulated time: over TCP a world served as fast as it is read runs ahead of
its reader by what the socket buffers hold.)
"""
import subprocess
import sys

import numpy as np
import pytest

from motecal import upload as U
from motecal.capture.guide import DEFAULT_MIN_ANGLE, DEFAULT_POSE_SAMPLES, GuidedFlow
from motecal.capture.link import LinkTracker
from motecal.capture.logger import Logger
from motecal.firmware import fixedpoint as FP
from motecal.firmware import mote_c
from motecal.sessions.session import SENSOR_SLICES
from motecal.sessions.store import open_store
from motecal.sim.serve import serve_in_thread
from motecal.sim.world import World, WorldPort

V1 = U.flags_for(1, 0b111)            # corrected, version 1


def _motecal(*args, timeout=240):
    return subprocess.run([sys.executable, "-m", "motecal", *map(str, args)],
                          capture_output=True, text=True, timeout=timeout,
                          stdin=subprocess.DEVNULL)


def _log(world, db, name, until, poses):
    """A guided static80 log of the world, in process, until simulated ``until``."""
    port = WorldPort(world, step=0.05, until=until)
    guide = GuidedFlow("static80", auto=True, options=dict(
        poses=poses, samples=DEFAULT_POSE_SAMPLES, min_angle_deg=DEFAULT_MIN_ANGLE,
        rate_hz=125.0))
    store = open_store(str(db), create=True)
    try:
        writer = store.open_session(name, kind="static80", meta={"source": str(port.spec)})
        logger = Logger(port.spec, writer, LinkTracker(), guide=guide, source=port)
        logger.run()
    finally:
        store.close()
    return logger


def _pose_means(rec, label, sl, k):
    poses = np.unique(label[label >= 1])
    return np.array([rec[label == p, sl].mean(axis=0) / k for p in poses]), \
        np.array([np.linalg.norm(rec[label == p, sl] / k, axis=1).std() for p in poses])


@pytest.mark.slow
def test_log_calibrate_upload_log_again(tmp_path):
    ee = tmp_path / "eeprom.json"
    world = World(motes=1, session="static80,static80", seed=1, eeprom=ee)
    db, cal_path = tmp_path / "e2e.db", tmp_path / "cal.json"
    part2 = world.trajectory.start[1]
    first = _log(world, db, "raw", until=part2, poses=80)
    # done with pose 80 and 0.5 s of samples after it: before the end of the first part
    assert first.guide.done and first.stop_reason == "guided flow done"
    logged_to = world.now
    assert logged_to < part2
    # the same world over TCP, in real time (while calibrate computes, the motes sample
    # on and nobody reads, as on a real line)
    server, port = serve_in_thread(world, speed=1.0)
    try:
        r = _motecal("calibrate", "--db", db, "--session", "raw", "--out", cal_path, "--seed", 1,
                     "--upload", "--port", f"socket://127.0.0.1:{port}", "--mote", 1)
    finally:
        server.stop()
        server.close()
    assert r.returncode == 0, r.stdout + r.stderr
    up_out = r.stdout
    uploaded_at = world.now
    # the simulator stopped the moment calibrate --upload exited: started again
    # on the same EEPROM file, the mote boots with the new set (issue 29)
    rebooted = World(motes=1, session="idle", seed=1, duration=1.0, eeprom=ee).motes[1].cal
    assert rebooted.version == 1 and rebooted.active_calset() == world.motes[1].cal.active_calset()
    assert logged_to < uploaded_at < part2 + 60
    second = _log(world, db, "after", until=world.duration, poses=12)
    assert second.guide.done

    # the one-step form: calibrated, gated, uploaded, verified
    assert "gate: accepted" in up_out and f"wrote {cal_path}" in up_out
    assert "mote 1: version 0 in force" in up_out
    assert "commit: accepted" in up_out and "read-back: 102 bytes identical" in up_out
    assert "samples: 3 messages in a row flagged corrected, version low bits 1" in up_out
    assert "mote 1: calibration version 1 (was 0) in force and verified, and stored (survives " \
           "a reboot)" in up_out
    assert "  stored: version 1 written to the EEPROM and read back" in up_out
    cal = U.load_cal(cal_path)
    calset, report = U.build_set(cal, 1, 1)
    assert world.motes[1].cal.active_calset() == calset

    with open_store(str(db)) as st:
        raw_s = st.load_session("raw")
        after = st.load_session("after")
    assert set(raw_s.flags.tolist()) == {0} and raw_s.poses() == list(range(1, 81))
    assert len(after.poses()) == 12 and len(after) > 12 * 200
    assert set(after.flags.tolist()) == {V1}                 # every record: corrected, v1

    # every stored record is what the mote sent: the C code's correction of its raw sample
    sent = world.sent[1]
    i = np.searchsorted(sent.seq, after.seq)
    assert np.array_equal(sent.seq[i], after.seq)
    rec, raw = after.raw, sent.raw[i]
    assert np.array_equal(rec, sent.records[i])
    # (its rounding carries a residual from sample to sample since the set was
    # applied: replay every sample the mote corrected with it, in order)
    v1 = np.flatnonzero(sent.flags == V1)
    j = np.searchsorted(v1, i)
    assert np.array_equal(v1[j], i)
    assert np.array_equal(rec, mote_c.correct(calset, sent.raw[v1])[j])
    # ... and agrees with the host's float calibration within quantisation + rounding
    for name, (A, c) in cal.physical.items():
        sl = SENSOR_SLICES[name]
        exact = FP.physical_correct(name, A, c, raw[:, sl])
        M, off = FP.counts_domain(name, A, c)
        fs = report[name].fixed
        bound = np.abs(raw[:, sl]) @ np.abs(fs.matrix - M).T + np.abs(fs.offset - off) \
            + FP.OUTPUT_ROUNDING_LSB       # error feedback: within 1 LSB
        err = np.abs(rec[:, sl] - exact)
        assert np.all(err < bound), name

    # static poses: 1 g within the noise, a constant field, no gyro bias
    lab = after.label
    acc, acc_sd = _pose_means(rec, lab, SENSOR_SLICES["accel"], 256.0)
    g = np.linalg.norm(acc, axis=1)
    assert np.all(np.abs(g - 1.0) < acc_sd) and np.abs(g - 1.0).max() < 0.005, g
    raw_g = np.linalg.norm(_pose_means(raw, lab, SENSOR_SLICES["accel"], 256.0)[0], axis=1)
    assert np.abs(raw_g - 1.0).max() > 5 * np.abs(g - 1.0).max()      # it did need it
    mag, mag_sd = _pose_means(rec, lab, SENSOR_SLICES["mag"], 1090.0)
    b = np.linalg.norm(mag, axis=1)
    assert b.std() < np.median(mag_sd) and (b.max() - b.min()) / b.mean() < 0.01, b
    host = np.linalg.norm(FP.physical_correct("mag", *cal.physical["mag"],
                                              raw[lab >= 1, 6:9]) / 1090.0, axis=1)
    assert abs(b.mean() - host.mean()) < 0.001                        # the host's field
    raw_b = np.linalg.norm(_pose_means(raw, lab, SENSOR_SLICES["mag"], 1090.0)[0], axis=1)
    assert raw_b.std() > 5 * b.std()
    gyro, _ = _pose_means(rec, lab, SENSOR_SLICES["gyro"], 14.375)
    raw_gyro, _ = _pose_means(raw, lab, SENSOR_SLICES["gyro"], 14.375)
    assert np.abs(gyro).max() < 0.3 < np.abs(raw_gyro).max()
    print(f"upload at {uploaded_at - part2:+.1f} s from part 2; |a| per pose {g.min():.4f}.."
          f"{g.max():.4f} g (raw {raw_g.min():.3f}..{raw_g.max():.3f}, noise "
          f"{np.median(acc_sd):.4f}); |B| {b.min():.4f}..{b.max():.4f} gauss (raw "
          f"{raw_b.min():.3f}..{raw_b.max():.3f}); gyro bias <= {np.abs(gyro).max():.3f} deg/s "
          f"(raw {np.abs(raw_gyro).max():.1f})")
