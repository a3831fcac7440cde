"""The plain algebraic ellipsoid fit the Razor AHRS tools use (Yury Petrov's
``ellipsoid_fit``, ported to Processing and Python in their repositories):
the baseline ``bench_robust.py`` compares the robust fit with.

Every reading ``x`` (n, 3) is put in the quadric ``a x^2 + b y^2 + c z^2 +
2 d xy + 2 e xz + 2 f yz + 2 g x + 2 h y + 2 i z = 1``, solved by linear
least squares (each reading counts with the square of its algebraic error,
so a reading far off pulls it hard, and the error is not the distance to the
surface).  Centre ``-Q^-1 (g, h, i)``; the ellipsoid's axes and radii from
the eigen-decomposition of ``Q / (1 + centre^T Q centre)``; the Razor
transform ``T = V diag(min(r) / r) V^T`` makes it a sphere of the smallest
radius, so ``calibrated = T (x - centre)``.
"""
from __future__ import annotations

import numpy as np


def algebraic_fit(x) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(T, centre, radii) of the Razor tools' ellipsoid fit to readings x
    (n, 3): calibrated = T (x - centre), a sphere of radius min(radii)."""
    x = np.asarray(x, float)
    X, Y, Z = x.T
    D = np.column_stack([X * X, Y * Y, Z * Z, 2 * X * Y, 2 * X * Z, 2 * Y * Z,
                         2 * X, 2 * Y, 2 * Z])
    p, *_ = np.linalg.lstsq(D, np.ones(len(x)), rcond=None)
    Q = np.array([[p[0], p[3], p[4]], [p[3], p[1], p[5]], [p[4], p[5], p[2]]])
    centre = -np.linalg.solve(Q, p[6:9])
    M = Q / (1.0 + centre @ Q @ centre)
    w, V = np.linalg.eigh(M)
    radii = 1.0 / np.sqrt(np.abs(w))
    T = V @ np.diag(radii.min() / radii) @ V.T
    return T, centre, radii


def as_affine(T, centre) -> tuple[np.ndarray, np.ndarray]:
    """(A, c) with calibrated = A x + c."""
    T = np.asarray(T, float)
    return T, -T @ np.asarray(centre, float)
