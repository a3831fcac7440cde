"""The project's GA: reproducible, bounded by the priors, a stop rule that
does not depend on the size of the fitness, and a real search."""
import numpy as np

from motecal.calib.ga import GAOptions, minimize

LO = np.full(4, -5.0)
HI = np.full(4, 5.0)
XSTAR = np.array([1.0, -2.0, 0.5, 3.0])


def sphere(P):
    return np.sum((P - XSTAR) ** 2, axis=1)


def double_well(P):
    """Global minimum 0 at XSTAR; a local minimum 0.5 at the box centre, where a
    local method started at the prior's centre stays."""
    return np.minimum(0.2 * np.sum((P - XSTAR) ** 2, axis=1),
                      0.5 + np.sum(P ** 2, axis=1))


def test_same_seed_same_run_different_seed_different_run():
    a = minimize(sphere, LO, HI, seed=11)
    b = minimize(sphere, LO, HI, seed=11)
    c = minimize(sphere, LO, HI, seed=12)
    assert a.trace == b.trace and np.array_equal(a.x, b.x)
    assert a.trace != c.trace


def test_trace_is_best_per_generation_and_never_worsens():
    r = minimize(sphere, LO, HI, seed=1)
    assert len(r.trace) == r.generations + 1
    assert np.all(np.diff(r.trace) <= 0)              # elitism
    assert r.f == r.trace[-1] == sphere(r.x[None])[0]
    assert r.evaluations > r.generations


def test_priors_bound_the_search():
    # optimum outside the box: the GA ends on the boundary, never beyond it
    far = np.array([9.0, -9.0, 0.0, 0.0])
    r = minimize(lambda P: np.sum((P - far) ** 2, axis=1), LO, HI, seed=3)
    assert np.all(r.x >= LO) and np.all(r.x <= HI)
    assert np.allclose(r.x[:2], [5.0, -5.0], atol=0.05)


def test_stop_rule_independent_of_the_size_of_the_fitness():
    """An absolute tolerance would stop at once on a fitness scaled by 1e-12;
    the relative stagnation rule runs exactly the same generations."""
    opts = GAOptions(rtol=1e-6, max_gen=400)
    big = minimize(sphere, LO, HI, seed=5, options=opts)
    tiny = minimize(lambda P: 1e-12 * sphere(P), LO, HI, seed=5, options=opts)
    assert big.generations == tiny.generations > 30
    assert np.allclose(big.x, tiny.x)
    assert np.allclose(np.array(tiny.trace) * 1e12, big.trace)
    assert big.stop.startswith("stagnation")
    assert np.linalg.norm(big.x - XSTAR) < 1e-2


def test_global_search_finds_the_deeper_well():
    from scipy.optimize import minimize as local_min
    start = 0.5 * (LO + HI)
    loc = local_min(lambda x: double_well(x[None])[0], start, method="BFGS")
    assert np.linalg.norm(loc.x) < 1e-3                 # a local method stays at the centre
    for seed in range(10):
        r = minimize(double_well, LO, HI, seed=seed)
        assert np.linalg.norm(r.x - XSTAR) < 0.1, seed


def test_max_gen_stops():
    r = minimize(sphere, LO, HI, seed=0, options=GAOptions(max_gen=5, rtol=0.0))
    assert r.generations == 5 and r.stop == "max_gen"
