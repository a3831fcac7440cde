"""Overlapping Allan deviation (motecal.maths.stats), the one the report draws and
the diagnosis compares: white rate noise falls as tau^-1/2, a rate random walk
rises as tau^+1/2."""
import numpy as np

from motecal.maths.stats import allan_deviation


def _slope(tau, adev, lo, hi):
    sel = (tau >= lo) & (tau <= hi)
    return np.polyfit(np.log(tau[sel]), np.log(adev[sel]), 1)[0]


def test_allan_deviation_of_white_noise():
    rng = np.random.default_rng(0)
    sigma, rate = 0.5, 100.0
    runs = [rng.normal(0.0, sigma, (4000, 3)) for _ in range(3)]
    tau, adev, terms = allan_deviation(runs, rate)
    # white rate noise: sigma(tau) = sigma / sqrt(tau * rate)
    expect = sigma / np.sqrt(tau * rate)
    sel = tau < 2.0
    assert np.allclose(adev[sel], expect[sel, None], rtol=0.1)
    assert terms[0] == 3 * (4000 - 1)
    for j in range(3):
        assert abs(_slope(tau, adev[:, j], 0.01, 2.0) + 0.5) < 0.05


def test_allan_deviation_of_a_rate_random_walk():
    rng = np.random.default_rng(1)
    q, rate, n = 0.01, 100.0, 40000
    x = np.cumsum(rng.normal(0.0, q, (n, 2)), axis=0)          # K = q * sqrt(rate)
    tau, adev, _ = allan_deviation([x], rate)
    for j in range(2):
        assert abs(_slope(tau, adev[:, j], 1.0, 50.0) - 0.5) < 0.1
    # sigma(tau) = K sqrt(tau / 3) for a rate random walk of strength K
    K = q * np.sqrt(rate)
    sel = (tau > 1.0) & (tau < 20.0)
    assert np.allclose(adev[sel], (K * np.sqrt(tau[sel] / 3))[:, None], rtol=0.35)


def test_given_cluster_sizes_and_too_short_runs():
    x = np.random.default_rng(2).normal(0.0, 1.0, 1000)         # one axis, 1-D
    tau, adev, terms = allan_deviation([x, x[:2]], 10.0, m=[10, 400, 600])
    np.testing.assert_allclose(tau, [1.0, 40.0])                # 600: needs 1201 samples
    assert adev.shape == (2, 1) and terms.tolist() == [1000 + 1 - 20, 1000 + 1 - 800]
    tau, adev, terms = allan_deviation([np.zeros((2, 3))], 10.0)
    assert len(tau) == 0 and adev.shape == (0, 3)
