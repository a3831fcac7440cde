"""Directions on the sphere (motecal.maths.sphere): the one definition the logger,
the quality gate, the simulator, the diagnosis and the report share."""
import numpy as np
import pytest

from motecal.maths import sphere as S


def test_unit_and_angles():
    v = np.array([[3.0, 0, 4], [0, 0, 0], [0, -2, 0]])
    u = S.unit(v)
    np.testing.assert_allclose(u, [[0.6, 0, 0.8], [0, 0, 0], [0, -1, 0]])
    assert S.angle_deg([1, 0, 0], [0, 5, 0]) == pytest.approx(90.0)
    assert S.angle_deg([1, 1, 0], [2, 2, 0]) == pytest.approx(0.0, abs=1e-6)
    assert S.angle_deg([0, 0, 1], [0, 0, -3]) == pytest.approx(180.0)
    a = S.angle_deg(np.eye(3), [1, 1, 1])                   # broadcasts over rows
    np.testing.assert_allclose(a, np.degrees(np.arccos(1 / np.sqrt(3))))


def test_distinct_directions_count_close_ones_once():
    d = np.array([[0, 0, 1], [0, np.sin(0.1), np.cos(0.1)],   # 5.7 deg apart: one
                  [1, 0, 0], [-1, 0, 0]])
    assert S.distinct_directions(d) == 3
    assert S.distinct_directions(d, min_deg=5.0) == 4
    assert S.distinct_directions(np.eye(3) * 7) == 3


def test_fibonacci_points_are_unit_spread_and_start_near_plus_z():
    d = S.fibonacci_sphere(80)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0)
    assert d[0, 2] > 0.98 and d[-1, 2] < -0.98
    ang = S.angle_deg(d[:, None], d[None]) + np.eye(80) * 999
    assert 15.0 < ang.min() and ang.min(axis=1).max() < 25.0
    np.testing.assert_allclose(d.mean(axis=0), 0.0, atol=0.02)


def test_sphere_centre_of_an_offset_sphere_and_of_a_flat_ring():
    rng = np.random.default_rng(3)
    x = 500 * S.unit(rng.normal(size=(300, 3))) + [120, -80, 40] + rng.normal(0, 2, (300, 3))
    np.testing.assert_allclose(S.sphere_centre(x), [120, -80, 40], atol=1.0)
    ang = np.linspace(0, 2 * np.pi, 100)
    ring = np.c_[500 * np.cos(ang), 500 * np.sin(ang), np.zeros(100)]
    assert S.sphere_centre(ring) is None                        # a plane: no centre
    assert S.sphere_centre(x[:3]) is None


def test_coverage_cells_are_equal_area_and_the_running_count_agrees():
    v = np.random.default_rng(1).normal(size=(200_000, 3))
    counts = S.coverage_counts(v)
    assert counts.shape == (S.COVERAGE_BANDS, S.COVERAGE_SECTORS)
    assert counts.min() > 0.9 * 2000 and counts.max() < 1.1 * 2000
    assert S.coverage(v) == 1.0
    assert S.coverage(np.eye(3)) == pytest.approx(3 / (S.COVERAGE_BANDS * S.COVERAGE_SECTORS))
    assert S.coverage(np.zeros((0, 3))) == 0.0
    # a cap within 60 deg of +z: a quarter of the area, a few more cells at its rim
    cap = v[S.unit(v)[:, 2] > 0.5]
    assert 0.25 <= S.coverage(cap) <= 0.35
    assert S.coverage_counts(cap)[0].all() and not S.coverage_counts(cap)[-1].any()
    run = S.SphereCoverage()
    for part in np.array_split(cap[:500], 7):
        run.add(part)
    assert run.fraction == S.coverage(cap[:500])
    lon, z = S.cell_edges()
    assert len(lon) == S.COVERAGE_SECTORS + 1 and z[0] == 1.0 and z[-1] == -1.0
