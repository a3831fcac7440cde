"""Model families: analytic Jacobians, the rank of the paper's angles, the
magnetometer gauge, and expressing a known map in a model's parameters."""
import itertools

import numpy as np
import pytest

from motecal.calib.identify import analyse
from motecal.calib.models import (PARAM_GROUPS, lower_factor, make_model, parse_groups,
                                  theta_from_affine)
from motecal.errors import UserError

RNG = np.random.default_rng(7)
U = RNG.standard_normal((60, 3)) * 0.6 + 0.1

PAPER_SUBSETS = [c for k in (1, 2, 3) for c in itertools.combinations(PARAM_GROUPS, k)]
MODELS = ([("accel", "full", None, None)]
          + [("accel", "paper", g, None) for g in PAPER_SUBSETS]
          + [("mag", "full", None, None), ("mag", "full", None, 0.45)]
          + [("mag", "paper", g, None) for g in PAPER_SUBSETS
             if not ("angles" in g and "scales" not in g)]
          + [("mag", "paper", g, 0.45) for g in PAPER_SUBSETS])


def _random_theta(m, rng):
    lo, hi = m.lo, m.hi
    c, h = 0.5 * (lo + hi), 0.5 * (hi - lo)
    return c + 0.3 * h * rng.uniform(-1, 1, m.d)


@pytest.mark.parametrize("sensor,family,groups,field", MODELS)
def test_analytic_jacobian_matches_finite_differences(sensor, family, groups, field):
    m = make_model(sensor, family, groups, field=field)
    th = _random_theta(m, np.random.default_rng(1))
    J = m.jacobian(th, U)
    h = 1e-6
    Jn = np.array([(m.residuals(th + e, U) - m.residuals(th - e, U)) / (2 * h)
                   for e in np.eye(m.d) * h]).T
    assert J.shape == (len(U), m.d)
    assert np.abs(J - Jn).max() < 1e-7


@pytest.mark.parametrize("sensor,family,groups,field", MODELS)
def test_population_fitness_equals_per_individual(sensor, family, groups, field):
    m = make_model(sensor, family, groups, field=field)
    rng = np.random.default_rng(2)
    pop = np.array([_random_theta(m, rng) for _ in range(5)])
    w = rng.uniform(1, 3, len(U))
    got = m.population_mse(pop, U, w)
    want = [np.average(m.residuals(p, U) ** 2, weights=w) for p in pop]
    assert np.allclose(got, want, rtol=1e-12)


def test_paper_angles_are_a_reparametrisation_rank_6_of_9():
    m = make_model("accel", "paper", ("offsets", "scales", "angles"))
    th = _random_theta(m, np.random.default_rng(3))       # angles away from 0
    assert np.all(np.abs(th[6:]) > 1e-3)
    ident = analyse(m.jacobian(th, U), m.names)
    assert (ident.rank, ident.d) == (6, 9)
    # only o_x and s_x are untouched by the angles; everything else trades with them
    assert set(n for n, ok in zip(m.names, ident.identifiable) if ok) == {"o_x", "s_x"}
    # same map from a different parameter vector: the angles change nothing
    A, c, _ = m.affine(th)
    th2 = th.copy()
    th2[6] = 0.0                                          # a_zy -> 0, s_y absorbs cos(a_zy)
    th2[4] = th[4] * np.cos(th[6])
    th2[1] = th[1] / np.cos(th[6])
    A2, c2, _ = m.affine(th2)
    assert np.allclose(A, A2) and np.allclose(c, c2)


def test_angles_at_their_optimum_of_zero_add_no_rank():
    """At angles of 0 (where a fit that needs longer axes leaves them) their
    columns are sin(angle) ~ rounding: no rank, however the other columns
    look.  Normalising such columns used to report 2 of 3 for angles alone."""
    for groups, want in ((("angles",), 0), (("offsets", "angles"), 3)):
        m = make_model("accel", "paper", groups)
        th = m.default.copy()
        th[-3:] = [-3.1e-8, 1.7e-7, 0.0]                  # what LM leaves of 0
        ident = m.identifiability(th, U)
        assert ident.rank == want, (groups, ident.singular)
        assert not ident.identifiable[-3:].any()
        assert ident.identifiable[:want].all()
        th[-3:] = [0.2, 0.1, -0.1]                        # real angles: a_zy, and cos*cos
        assert m.identifiability(th, U).rank == want + 2
    # a column that is small only because its parameter's unit is large counts
    J = np.column_stack([U[:, 0], 1e-7 * U[:, 1]])
    assert analyse(J, ["a", "b"]).rank == 1
    assert analyse(J, ["a", "b"], scale=[1.0, 1e3]).rank == 2


def test_offsets_and_scales_and_full_are_identifiable():
    for fam, groups in (("paper", ("offsets", "scales")), ("full", None)):
        m = make_model("accel", fam, groups)
        ident = analyse(m.jacobian(_random_theta(m, np.random.default_rng(4)), U), m.names)
        assert ident.rank == m.d and ident.identifiable.all()


def test_mag_fitness_without_gauge_has_no_minimum_and_det_gauge_fixes_it():
    # all scales free and the field free: scale everything by k -> fitness by k^2
    free = make_model("mag", "paper", ("offsets", "scales"), field=0.5)   # 3 scales free
    th = _random_theta(free, np.random.default_rng(5))
    mse = np.mean(free.residuals(th, U) ** 2)
    k = 0.5
    A, c, H = free.affine(th)
    v = U @ (k * A).T + k * c
    assert np.isclose(np.mean((np.linalg.norm(v, axis=1) - k * H) ** 2), k * k * mse)
    # det gauge: s_z is derived, det(A) = 1 for every parameter vector
    for fam, groups in (("paper", ("offsets", "scales")), ("paper", ("offsets", "scales",
                                                                     "angles")), ("full", None)):
        m = make_model("mag", fam, groups)
        assert m.gauge == "det" and m.free_field and "s_z" not in m.names
        pop = np.array([_random_theta(m, np.random.default_rng(i)) for i in range(6)])
        A, _, _ = m.affine(pop)
        assert np.allclose(np.linalg.det(A), 1.0)


def test_mag_angles_without_scales_refused_under_det_gauge():
    with pytest.raises(UserError, match="angles need scales"):
        make_model("mag", "paper", ("offsets", "angles"))
    make_model("mag", "paper", ("offsets", "angles"), field=0.5)      # fine with a known field


def test_lower_factor_and_theta_from_affine_round_trip():
    rng = np.random.default_rng(6)
    A = np.eye(3) + 0.05 * rng.standard_normal((3, 3))
    L = lower_factor(A)
    assert np.allclose(np.triu(L, 1), 0) and np.all(np.diag(L) > 0)
    assert np.allclose(L.T @ L, A.T @ A)
    c = rng.uniform(-0.1, 0.1, 3)
    m = make_model("accel", "full")
    th = theta_from_affine(m, A, c)
    A2, c2, _ = m.affine(th)
    # same magnitudes for every input
    assert np.allclose(np.linalg.norm(U @ A.T + c, axis=1), np.linalg.norm(U @ A2.T + c2, axis=1))


def test_parse_groups_and_bad_models():
    assert parse_groups("offsets, scales") == ("offsets", "scales")
    assert parse_groups(None) is None
    for bad in ("", "offsets,tilt", ","):
        with pytest.raises(UserError):
            parse_groups(bad)
    with pytest.raises(UserError):
        make_model("accel", "ellipsoid")
    with pytest.raises(UserError):
        make_model("accel", "full", ("angles",))
