"""diagnose.compare's twin (the session simulated again with a model) on a
session with temperature: the twin's board has the session's measured
temperature and carries it, so a drift that follows the temperature is in
the twin too (with the model's temperature term) instead of showing up as a
simulator miss.  Truth: the planted board (the 'thermal' model, a warm-up
with a room cycle the model's own temperature curve does not have)."""
import dataclasses

import numpy as np

from motecal.diagnose.compare import session_stats, simulate_like
from motecal.sessions.session import SessionData
from motecal.sim.model import SimModel
from motecal.sim.trajectory import SequenceTrajectory, make_trajectory
from warmup import thermal_board

SEEDS = (3, 4, 5)


def _session(seed):
    m, b = thermal_board(seed, room_amp_c=1.5, room_period_s=400.0)
    traj = SequenceTrajectory("idle,static80", seed, None, b.rate_hz,
                              parts=[make_trajectory("idle", seed, duration=300.0),
                                     make_trajectory("static80", seed + 1, n_poses=20)])
    t = b.sample_times(traj.duration)
    raw = b.sampler(traj, seed).read(t).astype(float)
    n = len(t)
    ses = SessionData(name=f"warm{seed}", raw=raw, mote=np.full(n, 1, np.int32),
                      seq=np.arange(n, dtype=np.int64), t=t, label=traj.label_at(t),
                      flags=np.zeros(n, np.uint8), kind="static80",
                      meta={"source": "sim", "rate_hz": b.rate_hz},
                      temp=b.temperature_reading_c(t))
    # the model: the planted board with its temperature terms, but without its
    # own temperature curve (it would sit at 25 C)
    bj = b.to_json()
    bj["terms"] = [x for x in bj["terms"] if x["term"] != "thermal"]
    return ses, traj, m.with_boards({1: bj}).to_json()


def _drift(ses):
    """Gyro 5 s block means over the first hold (deg/s), less their mean."""
    g = ses.sensor("gyro")[ses.label == 1] / ses.scales["gyro"]
    n = int(5 * 125)
    k = len(g) // n
    d = g[:k * n].reshape(k, n, 3).mean(axis=1)
    return d - d.mean(axis=0)


def test_the_twin_follows_the_measured_temperature():
    bad, rows = [], []
    for seed in SEEDS:
        ses, traj, model = _session(seed)
        twin = simulate_like(ses, model, traj, ses.t, seed=seed + 100)
        assert twin.temp is not None and np.array_equal(twin.temp, ses.temp, equal_nan=True)
        d_meas, d_twin = _drift(ses), _drift(twin)
        miss = np.sqrt(np.mean((d_twin - d_meas) ** 2))
        size = np.sqrt(np.mean(d_meas ** 2))
        # without the session's temperature the twin's board stays at 25 C: no drift
        cold = simulate_like(dataclasses.replace(ses, temp=None), model, traj, ses.t,
                             seed=seed + 100)
        assert cold.temp is None
        miss_cold = np.sqrt(np.mean((_drift(cold) - d_meas) ** 2))
        if not (size > 0.05 and miss < 0.2 * size and miss_cold > 0.7 * size):
            bad.append((seed, size, miss, miss_cold))
        # and the statistics the comparison uses see the same between-block scatter
        sm, st = session_stats(ses)["gyro"], session_stats(twin)["gyro"]
        rows.append(f"seed {seed}: drift rms {size:.3f} deg/s, twin misses {miss:.3f} "
                    f"(without the temperature {miss_cold:.3f}); between_sd measured "
                    f"{sm['between_sd'][0]:.4f}, twin {st['between_sd'][0]:.4f}")
        if not abs(np.log(st["between_sd"][0] / sm["between_sd"][0])) < np.log(1.3):
            bad.append((seed, "between_sd", sm["between_sd"][0], st["between_sd"][0]))
    print("\n".join(rows))
    assert not bad, f"seeds failing: {bad}"


def test_a_session_without_temperature_is_simulated_as_before():
    ses, traj, model = _session(SEEDS[0])
    plain = dataclasses.replace(ses, temp=None)
    twin = simulate_like(plain, model, traj, ses.t, seed=7)
    board = SimModel.from_json(model, "m").board(1, 7)
    np.testing.assert_array_equal(twin.raw, board.sampler(traj, 7).read(ses.t).astype(float))
    assert twin.temp is None
