"""Gyroscope: the paper's eq. 6 evaluated and minimised exactly, the mean as a
check, and scale/misalignment from the moves between poses (simulated)."""
import numpy as np
import pytest

from motecal.calib import eq6, gyro
from motecal.calib.board import calibrate_board
from motecal.calib.models import lower_factor
from synthetic import paper_sized_session, true_affine


def integer_rates(seed, n=16000, sd=(6, 7, 5)):
    rng = np.random.default_rng(seed)
    bias = rng.uniform(-200, 200, 3)
    return np.round(bias + rng.standard_normal((n, 3)) * sd) / 14.375, bias / 14.375


def direct(g, b):
    return np.mean(np.abs(g - b).sum(axis=1) ** 2)


def test_table_evaluates_eq6_exactly_for_a_population():
    g, _ = integer_rates(0)
    T = eq6.Eq6Table(g)
    rng = np.random.default_rng(1)
    B = g.mean(axis=0) + rng.standard_normal((50, 3)) * [0.5, 1.0, 2.0]
    B[:5] = g[:5]                                  # exactly on kinks
    got = T(B)
    want = np.array([direct(g, b) for b in B])
    assert np.allclose(got, want, rtol=1e-11)


@pytest.mark.parametrize("seed", range(4))
def test_exact_minimum_beats_every_probe_and_lm(seed):
    g, _ = integer_rates(seed)
    T = eq6.Eq6Table(g)
    b, e = T.exact_minimum(np.zeros(3))
    rng = np.random.default_rng(seed)
    for scale in (1e-1, 1e-3, 1e-6):
        probes = b + rng.standard_normal((4000, 3)) * scale
        assert T(probes).min() >= e * (1 - 1e-12)
    b_lm, e_lm = gyro.lm_bias(g)
    assert e <= e_lm * (1 + 1e-12)                 # LM stalls at kinks, never below


def test_ga_bias_is_the_paper_method_within_half_a_count_of_the_mean():
    g, bias = integer_rates(7)
    bf = gyro.ga_bias(g, seed=3)
    bm = gyro.mean_bias(g)
    assert np.allclose(bm.b, g.mean(axis=0))
    assert np.allclose(bm.std, g.std(axis=0, ddof=1) / np.sqrt(len(g)))
    # the eq. 6 minimiser sits on a kink: on whole counts, not on the mean
    # (half a count, 0.035 deg/s, is ~10 standard errors of the mean here)
    assert np.all(np.abs(bf.b - bm.b) < 4 * bm.std + 0.5 / 14.375)
    assert np.all(np.abs(bm.b - bias) < 4 * bm.std)
    assert bf.e6 < bf.e6_before
    assert len(bf.trace) == bf.ga_generations + 1
    again = gyro.ga_bias(g, seed=3)
    assert np.array_equal(again.b, bf.b)


def test_mean_bias_std_counts_the_scatter_of_the_poses():
    rng = np.random.default_rng(4)
    label = np.repeat(np.arange(1, 21), 200)
    g = rng.standard_normal((len(label), 3)) * 0.3 + [1.0, -2.0, 0.5]
    white = gyro.mean_bias(g, label)
    assert np.all(white.std == np.fmax(white.std_white, white.std_poses))
    assert np.all(np.abs(white.std_poses / white.std_white - 1) < 0.5)   # white noise: alike
    drift = g + rng.standard_normal((20, 3))[label - 1] * 0.05     # the bias moves between poses
    bm = gyro.mean_bias(drift, label)
    assert np.all(bm.std == bm.std_poses)
    assert np.all(bm.std > 2 * bm.std_white)
    assert np.allclose(bm.std, np.sqrt(20 / 19) * np.std(
        [drift[label == p].mean(axis=0) for p in range(1, 21)], axis=0) / np.sqrt(20))


def test_non_integer_data_use_the_direct_path():
    rng = np.random.default_rng(2)
    g = rng.standard_normal((3000, 3)) + [1, 2, 3]
    old = eq6.MAX_TABLE_CELLS
    eq6.MAX_TABLE_CELLS = 100
    try:
        T = eq6.Eq6Table(g)
        assert T.direct
        assert np.isclose(T(np.array([1.0, 2.0, 3.0])), direct(g, [1.0, 2.0, 3.0]))
    finally:
        eq6.MAX_TABLE_CELLS = old


def test_scale_and_misalignment_from_moves_between_poses():
    d = paper_sized_session(2, rotation=False)
    b = calibrate_board(d, seed=2, kfold=0)
    sc = b.gyro
    assert sc.model == "bias+matrix"
    assert sc.extra["matrix_fit"]["moves"] >= 70
    assert sc.extra["matrix_fit"]["rms_deg_after"] < 0.2 < sc.extra["matrix_fit"]["rms_deg_before"]
    pt = d.meta["physical_truth"]
    # truth, expressed in the calibrated accelerometer frame (A_acc = Q L)
    Aa, _ = true_affine(pt, "accel")
    Q = Aa @ np.linalg.inv(lower_factor(Aa))
    Ag, cg = true_affine(pt, "gyro")
    want_A = Q.T @ Ag
    K = sc.lsb_per_unit
    assert np.abs(sc.A * K - want_A * K).max() < 0.004          # scales and cross terms
    bias_true = -np.linalg.solve(Ag, cg) / K                     # deg/s at the input
    bfit = np.array([sc.param(f"b_{a}").value for a in "xyz"])
    assert np.all(np.abs(bfit - bias_true) < 0.03)
    # stated standard deviations of G consistent with the error
    G = np.array([[sc.param(f"G_{i}{j}").value for j in "xyz"] for i in "xyz"])
    Gs = np.array([[sc.param(f"G_{i}{j}").std for j in "xyz"] for i in "xyz"])
    assert np.abs((G - want_A * K) / Gs).max() < 4
    assert set(sc.extra["matrix_fit"]["std_from"]) == {"moves", "accel", "bias"}


# ---------------------------------------------------------------------------
# the calibration's stated standard deviations against the truth, over
# repeated simulated boards (each a fresh board and fresh noise)
# ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def repeated_boards():
    out = []
    for seed in range(12):
        d = paper_sized_session(100 + seed, rotation=False)
        out.append((d, calibrate_board(d, seed=seed, kfold=0)))
    return out


@pytest.mark.slow
def test_gyro_bias_std_is_the_error_of_the_reported_bias(repeated_boards):
    z = []
    for d, b in repeated_boards:
        sc = b.gyro
        Ag, cg = true_affine(d.meta["physical_truth"], "gyro")
        bias_true = -np.linalg.solve(Ag, cg) / sc.lsb_per_unit
        bfit = np.array([sc.param(f"b_{a}").value for a in "xyz"])
        std = np.array([sc.param(f"b_{a}").std for a in "xyz"])
        z.append((bfit - bias_true) / std)
    z = np.array(z)
    assert np.abs(z).max() < 4, z
    assert 0.6 < np.sqrt(np.mean(z ** 2)) < 1.4, z
    for d, b in repeated_boards:       # the paper's eq. 6 minimiser is kept next to it
        sc = b.gyro
        bfit = np.array([sc.param(f"b_{a}").value for a in "xyz"])
        std = np.array([sc.param(f"b_{a}").std for a in "xyz"])
        assert np.allclose(np.array(sc.extra["bias_eq6"]) - bfit, sc.extra["bias_eq6_minus_mean"])
        assert np.all(np.abs(sc.extra["bias_eq6_minus_mean"]) <= 0.5 / 14.375 + 4 * std)


def test_gyro_matrix_std_is_the_error_of_the_reported_matrix(repeated_boards):
    """G maps into the calibrated accelerometer frame, whose own errors (and
    the gravity directions of the poses shared by consecutive moves) are part
    of G's error against the truth."""
    z = []
    for d, b in repeated_boards:
        sc = b.gyro
        assert sc.model == "bias+matrix"
        pt = d.meta["physical_truth"]
        Aa, _ = true_affine(pt, "accel")
        Q = Aa @ np.linalg.inv(lower_factor(Aa))
        Ag, _ = true_affine(pt, "gyro")
        want = Q.T @ Ag * sc.lsb_per_unit
        G = np.array([[sc.param(f"G_{i}{j}").value for j in "xyz"] for i in "xyz"])
        Gs = np.array([[sc.param(f"G_{i}{j}").std for j in "xyz"] for i in "xyz"])
        z.append((G - want) / Gs)
    z = np.array(z)                                   # (boards, 3, 3)
    assert np.abs(z).max() < 4.5, z
    assert np.sqrt(np.mean(z ** 2, axis=0)).max() < 1.8, np.sqrt(np.mean(z ** 2, axis=0))
    assert 0.7 < np.sqrt(np.mean(z ** 2)) < 1.3
