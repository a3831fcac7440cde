"""Diagnosis building blocks on small arrays: models, tests, screens,
criterion, extension terms, trajectory re-simulation, JSON form.  (~10 s)"""
import json
import os

import numpy as np
import pytest

from motecal.diagnose import causes as C
from motecal.diagnose import extend as X
from motecal.diagnose import fitting as F
from motecal.diagnose import gain as G
from motecal.diagnose import screens as SC
from motecal.diagnose import structure as ST
from motecal.diagnose.compare import SampledTrajectory, distance, read_times
from motecal.diagnose.prepare import sensor_obs, unique_updates
from motecal.sessions.session import SessionData
from motecal.sim import SimModel, load_model


def _sphere(n, rng, R=256.0, noise=1.0, offset=(10.0, -5.0, 20.0)):
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    return u, R * u * np.array([1.02, 0.98, 1.0]) + np.array(offset) + rng.normal(0, noise, (n, 3))


# ---------------------------------------------------------------------------
# models
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("family", ["paper", "full"])
@pytest.mark.parametrize("sensor,K", [("accel", 256.0), ("mag", 1090.0)])
def test_jacobian_matches_finite_differences(family, sensor, K):
    rng = np.random.default_rng(1)
    u, x = _sphere(60, rng, R=K * (0.5 if sensor == "mag" else 1.0), noise=0.0)
    t = np.linspace(0, 100, 60)
    ex = [F.NonlinearityExtra(), F.DriftExtra(0, 100, 4)] + \
        ([F.FieldExtra(0, 100, 3)] if sensor == "mag" else [])
    fit = F.fit_magnitude(sensor, K, x, t, np.ones(60), family=family, extras=ex)
    th = fit.theta.copy()
    b = fit.base.d
    th[b:b + 9] = rng.normal(0, 0.01, 9)
    th[b + 9:] += rng.normal(0, 0.5, len(th) - b - 9)
    J = fit.jacobian(x, t, th)
    Jn = np.zeros_like(J)
    for i in range(len(th)):
        d = np.zeros_like(th)
        d[i] = 1e-7
        Jn[:, i] = (fit.residuals(x, t, th + d) - fit.residuals(x, t, th - d)) / 2e-7
    assert np.abs(J - Jn).max() < 1e-6 * np.abs(Jn).max()


def test_nonlinearity_inverse_is_exact():
    rng = np.random.default_rng(2)
    nl = F.NonlinearityExtra()
    p = rng.normal(0, 0.01, 9)
    y = rng.normal(0, 256, (500, 3))
    assert np.abs(nl.undo(nl.forward(y, p, 256.0), None, p, 256.0) - y).max() < 1e-8


def test_f_test_detects_a_term_and_not_noise():
    rng = np.random.default_rng(3)
    u, x = _sphere(80, rng, noise=0.05)
    t = np.zeros(80)
    w = np.ones(80) / 2e-4
    f0 = F.fit_magnitude("accel", 256.0, x, t, w)
    f1 = F.fit_magnitude("accel", 256.0, x, t, w, family="full", start=f0)
    Fv, p = F.f_test(f0.rss, f1.rss, f1.p - f0.p, 80 - f1.p)
    assert p > 1e-3                                   # axis-aligned data: no coupling
    C_ = np.array([[0, 0.01, 0], [0.01, 0, 0], [0, 0, 0]])
    xc = (x - x.mean(axis=0)) @ (np.eye(3) + C_).T + x.mean(axis=0)
    g0 = F.fit_magnitude("accel", 256.0, xc, t, w)
    g1 = F.fit_magnitude("accel", 256.0, xc, t, w, family="full", start=g0)
    Fv, p = F.f_test(g0.rss, g1.rss, g1.p - g0.p, 80 - g1.p)
    assert p < 1e-10 and Fv > 100


def test_least_squares_fit_solves_a_curve_fit():
    t = np.linspace(0, 1, 50)
    y = 2.0 * np.exp(-3.0 * t) + 0.5
    f = lambda p: p[0] * np.exp(-p[1] * t) + p[2] - y                         # noqa: E731
    j = lambda p: np.column_stack([np.exp(-p[1] * t), -p[0] * t * np.exp(-p[1] * t),  # noqa: E731
                                   np.ones_like(t)])
    p = F.least_squares_fit(f, j, np.array([1.0, 1.0, 0.0]))
    assert np.allclose(p, [2.0, 3.0, 0.5], atol=1e-6)


def test_drift_sizes_and_time_basis():
    B = F.time_basis(np.linspace(0, 10, 11), 0, 10, 4)
    assert B.shape == (11, 4) and abs(B[:, 0].mean()) < 1e-12
    assert ST.drift_sizes(300, 200) == [4, 10, 30]
    assert ST.drift_sizes(300, 37) == [4, 10, 12]
    assert ST.drift_sizes(60, 30, per_axis=1) == [4, 6, 8]


def test_lag1_whiteness():
    rng = np.random.default_rng(4)
    r = rng.normal(size=2000)
    rho, z = ST.lag1(r, np.arange(2000))
    assert abs(z) < 4
    walk = np.cumsum(rng.normal(size=2000))
    assert ST.lag1(walk, np.arange(2000))[1] > 20


# ---------------------------------------------------------------------------
# screens on arrays
# ---------------------------------------------------------------------------
def _obs(x, rate=125.0, label=None, sensor="gyro"):
    n = len(x)
    raw = np.full((n, 9), np.nan)
    sl = {"accel": slice(0, 3), "gyro": slice(3, 6), "mag": slice(6, 9)}[sensor]
    raw[:, sl] = x
    lab = np.ones(n, np.int32) if label is None else label
    d = SessionData("t", raw, np.ones(n, np.int32), np.arange(n), np.arange(n) / rate, lab,
                    np.zeros(n, np.uint8), meta={"rate_hz": rate})
    return sensor_obs(d, sensor)


def test_stale_samples_found_with_update_rate_and_not_on_white_noise():
    rng = np.random.default_rng(5)
    x = np.round(rng.normal(0, 3, (6000, 3)))
    clean = SC.stale_samples(_obs(x), 125.0)
    assert clean.p > 0.01 and not clean.practical
    # sample-and-hold at 80 Hz read at 125 Hz
    t = np.arange(6000) / 125.0
    k = np.floor(t * 80.0).astype(int)
    held = x[k]
    sc = SC.stale_samples(_obs(held), 125.0)
    assert sc.p < 1e-20 and sc.practical
    assert sc.params["update_hz"] == pytest.approx(80.0, rel=0.03)
    assert sc.gain() > 5
    assert unique_updates(held).mean() == pytest.approx(80 / 125, rel=0.02)


def test_saturation_pileup_and_overflow():
    rng = np.random.default_rng(6)
    x = rng.normal(0, 200, (5000, 3))
    assert not SC.saturation(_obs(np.round(x)), (-32768, 32767)).practical
    xc = np.round(x)
    xc[:, 1] = np.minimum(xc[:, 1], 250)
    sc = SC.saturation(_obs(xc), (-32768, 32767))
    assert sc.practical and sc.p < 1e-10
    assert sc.params["high"][1] == 250 and sc.params["high"][0] == 32767
    xo = np.round(x)
    xo[:7] = -4096
    so = SC.saturation(_obs(xo, sensor="mag"), (-2048, 2047))
    assert so.evidence["overflow_rows"] == 7 and so.params["overflow_code"] == -4096


def test_motion_coherence_needs_both_sensors_turning():
    rng = np.random.default_rng(7)
    n, rate = 4000, 125.0
    t = np.arange(n) / rate
    lab = (np.arange(n) // 400 + 1).astype(np.int32)
    f = np.array([0.0, 0.0, 256.0])
    for tremor in (0.0, 0.3):
        th = np.radians(tremor) * np.column_stack([np.sin(2 * np.pi * 1.3 * t),
                                                   np.sin(2 * np.pi * 0.7 * t + 1), 0 * t])
        acc = -np.cross(th, f) + f + rng.normal(0, 2, (n, 3))
        w = np.degrees(np.gradient(th, axis=0) * rate) * 14.375 + rng.normal(0, 5, (n, 3))
        raw = np.hstack([acc, w, np.full((n, 3), np.nan)])
        d = SessionData("m", raw, np.ones(n, np.int32), np.arange(n), t, lab,
                        np.zeros(n, np.uint8), meta={"rate_hz": rate})
        m = SC.motion(sensor_obs(d, "accel"), sensor_obs(d, "gyro"), True)
        if tremor == 0:
            assert m.p > 1e-3
        else:
            assert m.p < 1e-4 and abs(m.evidence["slope_accel_on_gyro"]) > 0.5


# ---------------------------------------------------------------------------
# criterion, vocabulary, extension terms
# ---------------------------------------------------------------------------
def test_criterion_bonferroni_and_held_out():
    assert G.per_test_alpha(0.01, 20) == pytest.approx(5e-4)
    assert G.accepted(1e-5, 5e-4, 1.5, True, 5)
    assert not G.accepted(1e-3, 5e-4, 1.5, True, 5)        # not significant enough
    assert not G.accepted(1e-9, 5e-4, 0.98, True, 5)        # worse on held-out data
    assert not G.accepted(1e-9, 5e-4, 1.2, True, 3)         # inconsistent across folds
    assert not G.accepted(1e-9, 5e-4, None, False)          # below the practical floor
    assert G.accepted(1e-9, 5e-4, None, True)               # screen: no fitted gain


def test_vocabulary_covers_the_issue_ids_and_simulator_terms():
    ids = {"cross_axis", "nonlinearity", "bias_drift", "g_sensitivity", "saturation",
           "stale_samples", "motion", "field_disturbance", "temperature", "unexplained"}
    assert set(C.CAUSES) == ids
    from motecal.sim.physics import TERMS
    for c in C.CAUSES.values():
        assert c.term is None or c.term in TERMS
        assert c.evidence and c.threshold and c.meaning


def test_affine_terms_reproduce_the_map_in_the_simulator():
    A = np.array([[1.01, 0, 0], [0.02, 0.97, 0], [-0.01, 0.005, 1.03]])
    c = np.array([0.05, -0.02, 0.1])
    terms, M, b = X.affine_terms(A, c, 256.0, cross=True)
    d = load_model("paper").to_json()
    d["defaults"]["accel"] = {"noise": 0, "terms": terms}
    board = SimModel.from_json(d, "t").board(1, 0)
    truth = board.physical_truth()["accel"]
    assert np.allclose(np.array(truth["M"]), np.linalg.inv(A), atol=1e-5)
    assert np.allclose(np.array(truth["b"]), b, atol=1e-3)


def test_drift_params_recover_a_warm_up():
    t = np.linspace(0, 300, 200)
    curve = np.column_stack([8 * (1 - np.exp(-t / 50)), 0.02 * t, 0 * t])
    p, d0 = X.drift_params(t, curve, False, 4)
    assert p["tau_s"] == 50.0
    assert p["amplitude"][0] == pytest.approx(8, rel=1e-3)
    assert p["slope"][1] == pytest.approx(0.02, rel=1e-3)


# ---------------------------------------------------------------------------
# re-simulation and statistics
# ---------------------------------------------------------------------------
def test_sampled_trajectory_holds_are_still_and_turns_have_the_rate():
    from scipy.spatial.transform import Rotation
    R0 = np.eye(3)
    R1 = Rotation.from_rotvec([0, 0, np.radians(10)]).as_matrix()
    tk = np.array([0.0, 1.0, 2.0, 3.0])
    traj = SampledTrajectory("static80", tk, [R0, R0, R1, R1], [1, 1, 2, 2], [1, 1, 2, 2], 125)
    m = traj.at(np.array([0.5, 1.0, 1.5, 2.5, 3.0]))
    assert np.allclose(m.omega[[0, 1, 3, 4]], 0)           # holds, ends of holds included
    assert m.omega[2, 2] == pytest.approx(10.0)            # 10 deg in 1 s
    assert list(traj.label_at(np.array([0.5, 2.5]))) == [1, 2]


def test_jittered_arrival_times_are_read_evenly():
    rng = np.random.default_rng(8)
    n = 200
    t = np.sort(rng.uniform(0, 2, n))
    raw = np.full((n, 9), np.nan)
    raw[:, 6:] = 1
    d = SessionData("j", raw, np.ones(n, np.int32), np.arange(n), t, np.zeros(n, np.int32),
                    np.zeros(n, np.uint8))
    tr = read_times(d, t - t[0])
    assert np.allclose(np.diff(tr), np.diff(tr).mean())


def test_distance_is_zero_for_equal_statistics_and_grows_with_difference():
    a = {"accel": {"noise": (0.004, "unit"), "repeat_fraction": (0.01, "fraction")}}
    b = {"accel": {"noise": (0.004, "unit"), "repeat_fraction": (0.40, "fraction")}}
    assert distance(a, a)[0] == 0
    d, per = distance(a, b)
    assert per["accel.repeat_fraction"] > 3 and per["accel.noise"] == 0


def test_json_has_exactly_the_issue_keys():
    import plant as P
    from motecal.diagnose.engine import diagnose
    ses = P.simulate([], "idle", 3, duration=20.0)
    d = diagnose(ses, simulate=False)
    j = d.to_json()
    assert set(j) == {"clean", "findings", "model"}
    assert j["clean"] is True and j["findings"] == []
    json.dumps(j)
    SimModel.from_json(j["model"], "extended")            # a valid simulator model


def test_sample_times_from_seq_when_t_is_batch_receive_time():
    from motecal.diagnose.prepare import sample_times
    n = 600
    raw = np.zeros((n, 9))
    seq = np.arange(n) + 100
    t_recv = np.repeat(np.arange(n // 6) * 0.01, 6)          # 6 samples per frame, fast host
    d = SessionData("b", raw, np.ones(n, np.int32), seq, t_recv, np.zeros(n, np.int32),
                    np.zeros(n, np.uint8), meta={"rate_hz": 125.0})
    assert np.allclose(sample_times(d), np.arange(n) / 125.0)
    d.t = np.arange(n) / 100.0                                # a real clock is kept
    assert np.allclose(sample_times(d), d.t)


def test_question_one_statistics_see_reading_size_direction_and_the_other_sensor():
    """Question 1's side-by-side statistics: the residual against direction,
    the reading's size per axis and the other sensor (issue 7), each responding
    to its own effect and not to the others; the gyro's Allan deviation at 1 s
    pooled over the 2.5 s poses."""
    import plant as P
    from motecal.diagnose.compare import session_stats

    def stats(keys):
        rng = np.random.default_rng(5)
        return session_stats(P.simulate([P.make_plant(c, s, rng) for c, s in keys],
                                        "static80", 77))

    clean = stats([])
    for s, other in (("accel", "r2_mag"), ("mag", "r2_accel")):
        for k in ("r2_direction", "r2_reading", "r2_time", other):
            assert 0 <= clean[s][k][0] < 0.3, (s, k, clean[s][k])
    a = clean["gyro"]["allan_1s"][0]
    assert np.isfinite(a) and 0 < a < clean["gyro"]["noise"][0]   # white noise averages down
    nl = stats([("nonlinearity", "accel")])
    assert nl["accel"]["r2_reading"][0] > 0.4
    assert all(nl["mag"][k] == clean["mag"][k] for k in ("r2_direction", "r2_reading", "r2_time"))
    ca = stats([("cross_axis", "mag")])
    assert ca["mag"]["r2_direction"][0] > 0.8 and ca["mag"]["r2_reading"][0] < 0.3


def test_paired_heldout_p():
    """The held-out points' paired test (structure.paired_heldout_p): a term
    that predicts no better than without it passes (p < 0.05) on about 5 %
    of noise draws (here at most 4 of 40, binomial tail ~0.14); a real
    improvement of half the points' spread on 30 points passes; too few
    points give None."""
    from motecal.diagnose.structure import paired_heldout_p
    seed = 17 + int(os.environ.get("MOTECAL_TEST_SEED", "0"))
    rng = np.random.default_rng(seed)
    hits = 0
    for _ in range(40):
        base = rng.chisquare(3, 30)
        hits += (paired_heldout_p(base + rng.normal(0, 1, 30), base) or 1.0) < 0.05
    assert hits <= 6, (seed, hits)
    base = rng.chisquare(3, 30)
    assert paired_heldout_p(base + 1.5 + rng.normal(0, 1, 30), base) < 0.05
    assert paired_heldout_p(np.ones(5), np.zeros(5)) is None
