"""The simulator's mismatch blocks and the mismatch suite (issue 26, item 1):
each block planted on boards of several seeds, and a property of the
simulated data shows it at its planted size (the truth is the planted
parameter, the estimate comes from the readings).  Seeds are printed on
failure."""
from __future__ import annotations

import os

import numpy as np
import pytest

from motecal.line import protocol as P
from motecal.sim import SimModel, builtin_models, load_model, make_trajectory, simulate_session
from motecal.sim import mismatch
from motecal.sim.field import FieldDrift, _FieldDriftRun
from motecal.sim.physics import K_NOMINAL

SEED0 = int(os.environ.get("MOTECAL_TEST_SEED", "0"))
SEEDS = [SEED0 + 17 * k for k in range(3)]
SL = {"accel": slice(0, 3), "gyro": slice(3, 6), "mag": slice(6, 9)}


def _model(board_terms, **sensor_terms) -> SimModel:
    """'paper' boards (offsets, scales, white noise) with these terms added."""
    d = load_model("paper").to_json()
    d["defaults"]["terms"] = list(board_terms)
    for s, terms in sensor_terms.items():
        d["defaults"][s]["terms"] = d["defaults"][s]["terms"] + list(terms)
    return SimModel.from_json(d, "mismatch-test")


def _blocks(ses, n=125):
    k = len(ses.t) // n
    x = ses.raw[:k * n].reshape(k, n, 9).mean(axis=1)
    return x, ses.temp[:k * n].reshape(k, n).mean(axis=1), ses.t[:k * n].reshape(k, n).mean(axis=1)


def _lowpass(temp, t, lag):
    """First-order lag of a sampled temperature (exact for a piecewise-linear input)."""
    if lag <= 0:
        return temp.copy()
    y = np.empty_like(temp)
    y[0] = temp[0]
    dt = np.diff(t)
    a = np.exp(-dt / lag)
    b = 1.0 / (1.0 - a) - lag / dt               # weight of the newer sample
    for i in range(1, len(temp)):
        y[i] = a[i - 1] * y[i - 1] + (1 - a[i - 1]) * ((1 - b[i - 1]) * temp[i - 1]
                                                         + b[i - 1] * temp[i])
    return y


def _lag_estimate(y, temp, t, grid):
    """The lag whose low-passed temperature explains ``y`` best (intercept + slope)."""
    rss = []
    for lag in grid:
        X = np.column_stack([np.ones(len(y)), _lowpass(temp, t, lag)])
        r = y - X @ np.linalg.lstsq(X, y, rcond=None)[0]
        rss.append(float(r @ r))
    return float(grid[int(np.argmin(rss))])


# --------------------------------------------------------------------------
# chip_lag
# --------------------------------------------------------------------------
@pytest.mark.parametrize("seed", SEEDS)
def test_each_chip_lags_the_itg3200_by_its_planted_time_constant(seed):
    """The ADXL345's offset and the HMC5883L's gain follow the temperature
    TEMP_OUT reports (the ITG3200's die) with the planted lag; the gyro's
    offset follows it without one; the reading is the die's, not lagged."""
    rng = np.random.default_rng(seed)
    tau_a, tau_m = rng.uniform(5, 30, 2)
    m = _model([{"term": "thermal", "rise_c": 12.0, "tau_s": float(rng.uniform(60, 120))},
                {"term": "chip_lag", "accel_tau_s": float(tau_a), "mag_tau_s": float(tau_m)}],
               accel=[{"term": "temperature", "offset_per_c": [0, 0, 3.0]}],
               gyro=[{"term": "temperature", "offset_per_c": [4.0, 0, 0]}],
               mag=[{"term": "temperature", "scale_per_c": -0.01}])
    ses = simulate_session("idle", seed=seed, model=m, duration=300)[1]
    b = m.board(1, seed)
    assert np.allclose(ses.temp, P.temp_c(np.rint(P.temp_raw(b.temperature_c(ses.t)))))
    assert np.allclose(b.chip_temperature_c("gyro", ses.t), b.temperature_c(ses.t))
    x, temp, t = _blocks(ses)
    grid = np.arange(0.0, 45.0, 0.5)
    mag_axis = int(np.argmax(np.abs(x[:, 6:9]).mean(axis=0)))        # the axis the field is on
    est = {"accel": _lag_estimate(x[:, 2], temp, t, grid),
           "gyro": _lag_estimate(x[:, 3], temp, t, grid),
           "mag": _lag_estimate(x[:, 6 + mag_axis], temp, t, grid)}
    assert abs(est["accel"] - tau_a) <= max(2.0, 0.15 * tau_a), (seed, est, tau_a)
    assert abs(est["mag"] - tau_m) <= max(2.0, 0.15 * tau_m), (seed, est, tau_m)
    assert est["gyro"] <= 1.5, (seed, est)
    # the chips' temperatures: equal at power-on, apart during the warm-up, together at the end
    Ta = b.chip_temperature_c("accel", np.array([0.0, 30.0, 3000.0]))
    T = b.temperature_c(np.array([0.0, 30.0, 3000.0]))
    assert Ta[0] == T[0] and T[1] - Ta[1] > 0.2 and abs(T[2] - Ta[2]) < 0.02


def test_lag_is_exact_against_an_integrated_ode():
    m = _model([{"term": "thermal", "ambient_c": 21, "rise_c": 9, "tau_s": 200,
                 "room_slope_c_per_h": 2, "room_amp_c": 0.7, "room_period_s": 900},
                {"term": "chip_lag", "accel_tau_s": 15, "mag_tau_s": 200}])   # tau = lag too
    b = m.board(1, 0)
    t = np.arange(0.0, 1500.0, 0.05)
    T = b.temperature_c(t)
    for s, lag in (("accel", 15.0), ("mag", 200.0)):
        y = _lowpass(T, t, lag)
        assert np.abs(b.chip_temperature_c(s, t) - y).max() < 1e-4, s


def test_chip_lag_rejects_a_negative_time_constant():
    from motecal.errors import UserError
    with pytest.raises(UserError) as e:
        _model([{"term": "chip_lag", "accel_tau_s": -1}])
    assert "accel_tau_s" in str(e.value) and "\n" not in str(e.value)


# --------------------------------------------------------------------------
# temperature_curve
# --------------------------------------------------------------------------
@pytest.mark.parametrize("seed", SEEDS)
def test_quadratic_term_bends_the_offset_by_its_planted_curvature(seed):
    """Over a 12 C warm-up the gyro's still output is a parabola in the
    temperature: the fitted curvature is the planted one (within 4 standard
    errors) and many standard errors from none (a straight line)."""
    rng = np.random.default_rng(seed)
    c2 = float(rng.choice([-1, 1]) * rng.uniform(0.05, 0.15))
    m = _model([{"term": "thermal", "ambient_c": 22.0, "rise_c": 12.0, "tau_s": 150.0}],
               gyro=[{"term": "temperature", "offset_per_c": [2.0, 0, 0]},
                     {"term": "temperature_curve", "offset_per_c2": [c2, 0, 0], "t_ref_c": 28.0}])
    ses = simulate_session("idle", seed=seed, model=m, duration=600)[1]
    x, temp, _ = _blocks(ses)
    X = np.column_stack([np.ones(len(temp)), temp - 28.0, (temp - 28.0) ** 2])
    beta, *_ = np.linalg.lstsq(X, x[:, 3], rcond=None)
    r = x[:, 3] - X @ beta
    cov = np.linalg.inv(X.T @ X) * float(r @ r) / (len(r) - 3)
    assert abs(beta[2] - c2) < 4 * np.sqrt(cov[2, 2]), (seed, beta[2], c2)
    assert abs(beta[2]) > 8 * np.sqrt(cov[2, 2]), seed          # far from a straight line


# --------------------------------------------------------------------------
# temperature_hysteresis
# --------------------------------------------------------------------------
@pytest.mark.parametrize("seed", SEEDS)
def test_hysteresis_offsets_differ_between_warming_and_cooling(seed):
    """A room cycle of +-3 C: at the same temperature the accelerometer's z
    reads 2 offset_c more while warming than while cooling (band 1 C, long
    crossed); at power-on the board is on its cooling branch (-offset_c)."""
    rng = np.random.default_rng(seed)
    h = float(rng.choice([-1, 1]) * rng.uniform(1.0, 3.0))
    m = _model([{"term": "thermal", "room_amp_c": 3.0, "room_period_s": 400.0}],
               accel=[{"term": "temperature_hysteresis", "offset_c": [0, 0, h], "band_c": 1.0}])
    ses = simulate_session("idle", seed=seed, model=m, duration=1200)[1]
    b = m.board(1, seed)
    x, _, t = _blocks(ses)
    T = b.temperature_c(t)
    dTdt = np.gradient(T, t)
    mid = np.abs(T - 25.0) < 0.5
    up, down = mid & (dTdt > 0) & (t > 50), mid & (dTdt < 0)
    diff = x[up, 2].mean() - x[down, 2].mean()
    se = np.sqrt(x[up, 2].var() / up.sum() + x[down, 2].var() / down.sum())
    assert abs(diff - 2 * h) < max(5 * se, 0.05), (seed, diff, h)
    # at power-on: the cooling branch
    traj = make_trajectory("idle", seed, duration=1.0)
    smp = b.sampler(traj, seed)
    run = next(r for r in smp.chain["accel"][0] if hasattr(r, "state"))
    temp_of = smp.chip_temperature("accel")
    assert run.state(np.array([0.0]), temp_of)[0] == -1.0
    assert abs(run.state(np.array([50.0]))[0] - 1.0) < 1e-12     # warmed by > 1 C


def test_hysteresis_state0_and_check():
    from motecal.errors import UserError
    m = _model([], gyro=[{"term": "temperature_hysteresis", "offset_c": [3, 0, 0],
                          "state0": 0.5}])
    ses = simulate_session("idle", seed=1, model=m, duration=2)[1]
    nominal = simulate_session("idle", seed=1, model=_model([]), duration=2)[1]
    assert np.mean(ses.raw[:, 3] - nominal.raw[:, 3]) == pytest.approx(1.5, abs=0.05)
    with pytest.raises(UserError):
        _model([], gyro=[{"term": "temperature_hysteresis", "state0": 2}])


# --------------------------------------------------------------------------
# field_drift
# --------------------------------------------------------------------------
def test_field_drift_rate_turns_with_the_board():
    rate = [0.004, -0.002, 0.003]
    m = _model([], mag=[{"term": "field_drift", "rate_gauss_per_h": rate}])
    d = m.to_json()
    d["defaults"]["mag"]["noise"] = 0.0
    m0 = SimModel.from_json(d, "x")
    traj = make_trajectory("static80", 3, duration=120.0)
    b = m0.board(1, 3)
    t = b.sample_times(traj.duration)
    det = b.sampler(traj, 3).read_detail(t)
    d["defaults"]["mag"]["terms"] = d["defaults"]["mag"]["terms"][:-1]
    plain = SimModel.from_json(d, "y").board(1, 3).sampler(traj, 3).read_detail(t)
    world = np.einsum("nij,nj->ni", det.motion.R, (det.pre_chip - plain.pre_chip)[:, 6:9])
    want = np.outer(t / 3600.0, rate) * K_NOMINAL["mag"]
    assert np.abs(world - want).max() < 1e-6


def test_field_drift_random_walk_grows_as_sigma_sqrt_t():
    """Over 200 keys and the three world axes, the walk's variance after 30
    minutes is sigma^2 t (within 20 %, 3.5 standard errors), and it is continuous (no step above 5 sd of one
    second's)."""
    sigma, T = 0.004, 1800.0
    term = FieldDrift({"rate_gauss_per_h": np.zeros(3), "sigma_gauss_per_sqrt_h": np.float64(sigma)})
    ends, steps = [], []
    for k in range(200):
        run = _FieldDriftRun(term, [7, SEED0, k])
        w = run.drift(np.arange(0.0, T + 0.01, 0.25))
        ends.append(w[-1])
        steps.append(np.abs(np.diff(w, axis=0)).max())
    var = np.mean(np.array(ends) ** 2)                    # the three axes pooled
    assert abs(var / (sigma ** 2 * T / 3600) - 1) < 0.2, var
    assert max(steps) < 5 * sigma * np.sqrt(1 / 3600)


# --------------------------------------------------------------------------
# the suite
# --------------------------------------------------------------------------
def test_suite_models_hold_their_blocks():
    assert set(mismatch.NAMES) <= set(builtin_models())
    want = {"lag": ("board", "chip_lag"), "quadratic": ("gyro", "temperature_curve"),
            "hysteresis": ("accel", "temperature_hysteresis"),
            "nonlinearity": ("accel", "nonlinearity"), "gsens": ("gyro", "g_sensitivity"),
            "field": ("mag", "field_drift"), "warmup": ("board", "thermal")}
    assert set(want) == set(mismatch.BLOCKS)

    def ids(b, where):
        return [t.id for t in (b.board_terms if where == "board" else b.sensors[where].terms)]
    full = load_model("mismatch").board(1, SEED0)
    for block, (where, tid) in want.items():
        assert tid in ids(full, where), block
        single = load_model(f"mismatch-{block}").board(1, SEED0)
        assert tid in ids(single, where) and "thermal" in ids(single, "board"), block
        others = [t for b2, (w2, t2) in want.items() if b2 not in (block, "warmup")
                  for t in [t2] if t2 in ids(single, w2)]
        assert not others, (block, others)
    # the linear temperature coefficients are the thermal model's, the suite's own
    # terms inside their documented ranges
    th = load_model("mismatch-warmup").board(1, SEED0)
    assert th.to_json() == load_model("thermal").board(1, SEED0).to_json()
    lag = full.chip_lag
    assert 5 <= lag.tau("accel") <= 30 and 5 <= lag.tau("mag") <= 30 and lag.tau("gyro") == 0


@pytest.mark.parametrize("kind", ["static80", "rotation", "idle"])
def test_every_protocol_warms_up_on_the_suite(kind):
    """A suite board warms up in every session kind: its sessions carry the
    ITG3200's reading, rising from power-on."""
    ses = simulate_session(kind, seed=SEED0, model="mismatch", duration=40.0)[1]
    assert ses.temp is not None and ses.temp[-1] > ses.temp[0] + 0.3


def test_the_adaptive_flow_on_a_warming_board_carries_the_temperature():
    from motecal.calib.design import Planner
    from motecal.capture.guide import AdaptiveCapture
    from motecal.sessions.session import NOMINAL_SCALES
    from motecal.sim.person import run_guided
    cap = AdaptiveCapture(1, planner=Planner(NOMINAL_SCALES), rate_hz=125.0, max_poses=14)
    data, _ = run_guided(cap, load_model("mismatch"), SEED0, step_s=0.2, max_s=20.0)
    assert data.temp is not None and len(data.temp) == len(data)
    assert data.temp[-1] > data.temp[0]
    b = load_model("mismatch").board(1, SEED0)
    assert np.allclose(data.temp, b.temperature_reading_c(data.t))


def test_suite_reads_do_not_depend_on_block_split():
    model = load_model("mismatch")
    traj = make_trajectory("static80", 4, duration=40.0)
    board = model.board(2, 4)
    t = board.sample_times(traj.duration)
    whole = board.sampler(traj, 4).read(t)
    smp = board.sampler(traj, 4)
    cuts = np.sort(np.random.default_rng(1).choice(len(t), 40, replace=False))
    parts = [smp.read(b) for b in np.split(t, cuts)]
    assert np.array_equal(np.concatenate(parts), whole)


def test_a_measured_temperature_given_to_the_sampler_is_followed_through_the_lags():
    """diagnose.compare gives a twin's sampler the session's measured
    temperature (``sampler.temperature_c``): the gyro reads it as it is, the
    lagging chips through their lags, the hysteresis through its history."""
    m = _model([{"term": "thermal"}, {"term": "chip_lag", "accel_tau_s": 20.0}],
               accel=[{"term": "temperature", "offset_per_c": [0, 0, 2.0]},
                      {"term": "temperature_hysteresis", "offset_c": [1.0, 0, 0]}],
               gyro=[{"term": "temperature", "offset_per_c": [3.0, 0, 0]}])
    b = m.board(1, 0)
    traj = make_trajectory("idle", 0, duration=200.0)
    t = b.sample_times(200.0)
    smp = b.sampler(traj, 0)
    smp.temperature_c = lambda tt: 25.0 + 8.0 * np.minimum(np.asarray(tt, float) / 100.0, 1.0)
    det = smp.read_detail(t)
    ref = m.board(1, 0).sampler(traj, 0).read_detail(t)          # 25 C throughout
    d = det.pre_chip - ref.pre_chip
    T = smp.temperature_c(t)
    assert np.allclose(d[:, 3], 3.0 * (T - 25.0))
    Ta = _lowpass(T, t, 20.0)
    assert np.abs(d[:, 2] - 2.0 * (Ta - 25.0)).max() < 1e-3
    assert d[-1, 0] == pytest.approx(2.0)            # warmed: from -1 to +1 times offset_c


def test_vector_error_at_follows_the_boards_whole_model():
    """The benches' truth on the suite (tests/synthetic.py): through a board
    with affine terms only it is vector_error; a planted nonlinearity and a
    temperature term at the evaluation time show in it, not in the affine
    truth."""
    from synthetic import true_affine, vector_error, vector_error_at

    from motecal.calib.models import lower_factor

    class Perfect:                      # the affine truth inverted, in its gauge frame
        sensor = "accel"

        def __init__(self, pt):
            A, c = true_affine(pt, "accel")
            Q = A @ np.linalg.inv(lower_factor(A))
            self.A, self.c = Q.T @ A, Q.T @ c

        def apply(self, raw, temp_c=None):
            return np.asarray(raw) @ self.A.T + self.c
    g = load_model("general").board(1, SEED0)
    sc = Perfect(g.physical_truth())
    assert vector_error(sc, g.physical_truth()) < 1e-9
    assert vector_error_at(sc, g, 100.0) < 1e-9
    m = _model([{"term": "thermal", "rise_c": 10.0, "tau_s": 100.0}],
               accel=[{"term": "nonlinearity", "q": [0, 0, 0.01]},
                      {"term": "temperature", "offset_per_c": [0, 0, 1.0]}])
    b = m.board(1, SEED0)
    sc = Perfect(b.physical_truth())
    assert vector_error(sc, b.physical_truth()) < 1e-9
    cold, warm = vector_error_at(sc, b, 0.0), vector_error_at(sc, b, 600.0)
    assert 3e-3 < cold < 1.2e-2                           # the nonlinearity: up to 10 mg
    assert warm > cold                                    # + 10 C x 1 count/C on z
