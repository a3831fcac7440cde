"""Directions on the unit sphere: the one definition of each piece of math
the logger's guidance, the calibration's quality gate, the simulator, the
diagnosis and the report share.

* ``unit``, ``angle_deg``, ``distinct_directions``: directions, the angle
  between two, and how many of a set are at least some angle apart (greedy);
* ``fibonacci_sphere``: n directions evenly spread (Fibonacci lattice), the
  first near +Z spiralling to -Z;
* ``sphere_centre``: the centre of the sphere best fitting some points (a
  magnetometer sweep's hard-iron offset), None when they cannot determine one;
* coverage: the sphere cut into equal-area cells, ``bands`` equal-height z
  bands (equal area, Archimedes) times ``sectors`` equal azimuth sectors, as
  MotionCal counts the gaps in a magnetometer sweep.  The coverage of a set of
  directions is the share of cells holding at least one of them; with the
  default 10 x 10 cells it is the number the logger shows while a board is
  turned (and stops at), the quality gate checks and the report prints.
  Band 0 is the top one (around +Z), sector 0 starts at azimuth -180 deg.

Pure numpy; vectors are (..., 3) arrays of any length (zero stays zero).
"""
from __future__ import annotations

import numpy as np

COVERAGE_BANDS = 10
COVERAGE_SECTORS = 10
DISTINCT_DEG = 10.0         # directions closer than this count once (distinct_directions)


def unit(v) -> np.ndarray:
    """v (..., 3) scaled to length 1 (a zero vector stays zero)."""
    v = np.asarray(v, float)
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0, n, 1.0)


def angle_deg(a, b) -> np.ndarray:
    """Angles (degrees) between the directions of a (..., 3) and b (..., 3):
    atan2(|a x b|, a . b), accurate for nearly parallel directions too (where
    acos of the dot product loses half the digits)."""
    a, b = np.broadcast_arrays(unit(a), unit(b))
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1),
                                 np.sum(a * b, axis=-1)))


def distinct_directions(dirs, min_deg: float = DISTINCT_DEG) -> int:
    """Greedy count of directions at least ``min_deg`` from all counted ones."""
    dirs = unit(dirs)
    cos_lim = np.cos(np.deg2rad(min_deg))
    kept = []
    for d in dirs:
        if not kept or np.max(np.array(kept) @ d) < cos_lim:
            kept.append(d)
    return len(kept)


def fibonacci_sphere(n: int) -> np.ndarray:
    """n unit vectors evenly spread over the sphere (Fibonacci lattice)."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    phi = i * np.pi * (3.0 - np.sqrt(5.0))
    r = np.sqrt(1.0 - z * z)
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


def sphere_centre(x, rcond: float = 1e-6) -> np.ndarray | None:
    """Centre of the sphere best fitting the points x (n, 3): linear least
    squares on |x|^2 = 2 c.x + k.  None when the points cannot determine one:
    fewer than four, or (nearly) all in one plane -- the smallest singular
    value of the system under ``rcond`` times the largest."""
    x = np.asarray(x, float)
    if len(x) < 4:
        return None
    M = np.c_[2.0 * x, np.ones(len(x))]
    sol, _, rank, sv = np.linalg.lstsq(M, np.einsum("ij,ij->i", x, x), rcond=None)
    if rank < 4 or sv[-1] < rcond * sv[0]:
        return None
    return sol[:3]


# --------------------------------------------------------------------------
# coverage: equal-area cells
# --------------------------------------------------------------------------
def coverage_cell(v, bands: int = COVERAGE_BANDS, sectors: int = COVERAGE_SECTORS) -> np.ndarray:
    """Cell index (band * sectors + sector) of each direction v (n, 3)."""
    v = unit(np.atleast_2d(v))
    band = np.clip(((1.0 - v[:, 2]) / 2.0 * bands).astype(int), 0, bands - 1)
    az = (np.arctan2(v[:, 1], v[:, 0]) + np.pi) / (2 * np.pi)
    sector = np.clip((az * sectors).astype(int), 0, sectors - 1)
    return band * sectors + sector


def coverage_counts(v, bands: int = COVERAGE_BANDS,
                    sectors: int = COVERAGE_SECTORS) -> np.ndarray:
    """Directions per cell, (bands, sectors); row 0 is the band around +Z."""
    v = np.asarray(v, float).reshape(-1, 3)
    counts = np.bincount(coverage_cell(v, bands, sectors), minlength=bands * sectors) \
        if len(v) else np.zeros(bands * sectors, np.int64)
    return counts.reshape(bands, sectors)


def coverage(v, bands: int = COVERAGE_BANDS, sectors: int = COVERAGE_SECTORS) -> float:
    """Share of the equal-area cells holding at least one direction of v (n, 3)."""
    return float((coverage_counts(v, bands, sectors) > 0).mean())


def cell_edges(bands: int = COVERAGE_BANDS,
               sectors: int = COVERAGE_SECTORS) -> tuple[np.ndarray, np.ndarray]:
    """The cells' borders: azimuths (sectors + 1, radians, -pi..pi) and z
    (bands + 1, from +1 down to -1: band b lies between z[b] and z[b + 1])."""
    return np.linspace(-np.pi, np.pi, sectors + 1), np.linspace(1.0, -1.0, bands + 1)


class SphereCoverage:
    """The coverage of a growing set of directions (the logger's running count)."""

    def __init__(self, bands: int = COVERAGE_BANDS, sectors: int = COVERAGE_SECTORS):
        self.bands, self.sectors = bands, sectors
        self.hits = np.zeros(bands * sectors, np.int64)

    @property
    def cells(self) -> int:
        return self.bands * self.sectors

    def cell_of(self, v) -> np.ndarray:
        return coverage_cell(v, self.bands, self.sectors)

    def reset(self) -> None:
        self.hits[:] = 0

    def add(self, v) -> None:
        v = np.asarray(v, float).reshape(-1, 3)
        if len(v):
            self.hits += np.bincount(self.cell_of(v), minlength=self.cells)

    @property
    def fraction(self) -> float:
        """The same number as ``coverage`` of every direction added."""
        return float((self.hits > 0).mean())

    def map(self, mark=None) -> list[str]:
        """Text map, top row = +Z band: '#' hit, '.' empty, 'o' the cell of ``mark``."""
        grid = (self.hits > 0).reshape(self.bands, self.sectors)
        m = int(self.cell_of(mark)[0]) if mark is not None else -1
        return ["".join("o" if b * self.sectors + s == m else ("#" if grid[b, s] else ".")
                        for s in range(self.sectors)) for b in range(self.bands)]
