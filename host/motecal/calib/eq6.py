"""The seed paper's gyroscope fitness (eq. 6), evaluated and minimised exactly.

    E(b) = mean_k ( |X'_k - b_1| + |Y'_k - b_2| + |Z'_k - b_3| )^2

``E`` is convex and piecewise quadratic in ``b`` with kinks where ``b_i``
equals a data value; gyroscope counts are integers, so the optimum often sits
on a kink where gradient methods (Levenberg-Marquardt included) stall short
of it.  ``Eq6Table`` evaluates ``E`` for a whole population at once from
2-D prefix sums over the distinct values of each pair of axes (exact, O(1)
per point after O(n) set-up); ``exact_minimum`` finds the minimiser by
minimising the quadratic piece of every cell around a start point over its
closed cell (all 27 active sets of the box constraint) and moving the block of
cells until the best point is inside it.
"""
from __future__ import annotations

import itertools

import numpy as np

MAX_TABLE_CELLS = 4_000_000      # above this, evaluate sample by sample

_PAIRS = ((0, 1), (0, 2), (1, 2))
_PATTERNS = np.array(list(itertools.product((0, 1, 2), repeat=3)))   # 0 free, 1 lower, 2 upper


class Eq6Table:
    """Exact eq. 6 for many bias vectors; ``g`` is (n, 3) in deg/s."""

    def __init__(self, g: np.ndarray):
        g = np.asarray(g, float)
        self.n = len(g)
        self.shift = np.median(g, axis=0)
        x = g - self.shift                      # exact when data and medians are on a grid
        self.g = x
        self.U = []
        inv = []
        for i in range(3):
            u, iv = np.unique(x[:, i], return_inverse=True)
            self.U.append(u)
            inv.append(iv)
        self.S1 = x.sum(axis=0)
        self.Q = (x * x).sum(axis=0)
        self.tables = {}
        self.direct = any(len(self.U[i]) * len(self.U[j]) > MAX_TABLE_CELLS for i, j in _PAIRS)
        if self.direct:
            return
        for i, j in _PAIRS:
            ni, nj = len(self.U[i]), len(self.U[j])
            idx = inv[i] * nj + inv[j]
            C = np.zeros((4, ni + 1, nj + 1))
            for m, w in enumerate((None, x[:, i], x[:, j], x[:, i] * x[:, j])):
                h = np.bincount(idx, weights=w, minlength=ni * nj).reshape(ni, nj)
                C[m, 1:, 1:] = h.cumsum(0).cumsum(1)
            self.tables[(i, j)] = C

    # -- signed quadrant sums ----------------------------------------------------
    def _signed(self, a):
        """For count indices a (..., 3) (# values below b_i on each axis):
        per pair, the sums of s_i s_j * (1, x_i, x_j, x_i x_j) with
        s = sign(x - b): shape (3 pairs, 4, ...)."""
        out = []
        for i, j in _PAIRS:
            C = self.tables[(i, j)]
            ai, aj = a[..., i], a[..., j]
            ll = C[:, ai, aj]
            la = C[:, ai, -1]
            al = C[:, -1, aj]
            tot = C[:, -1, -1].reshape((4,) + (1,) * ai.ndim)
            out.append(tot - 2 * la - 2 * al + 4 * ll)
        return out

    def counts_below(self, b):
        b = np.asarray(b, float)
        return np.stack([np.searchsorted(self.U[i], b[..., i], side="left")
                         for i in range(3)], axis=-1)

    def _quadratic(self, a):
        """Hessian (..., 3, 3), linear term (..., 3), constant (...) of n*E in the
        cell with count indices a, in shifted coordinates."""
        sg = self._signed(a)
        shp = a.shape[:-1]
        Hm = np.zeros(shp + (3, 3))
        lin = np.zeros(shp + (3,))
        const = np.full(shp, self.Q.sum())
        for i in range(3):
            Hm[..., i, i] = 2.0 * self.n
            lin[..., i] = -2.0 * self.S1[i]
        for (i, j), s in zip(_PAIRS, sg):
            s0, si, sj, sij = s
            # 2 * (sij - b_j si - b_i sj + b_i b_j s0)
            const = const + 2.0 * sij
            lin[..., i] += -2.0 * sj
            lin[..., j] += -2.0 * si
            Hm[..., i, j] += 2.0 * s0
            Hm[..., j, i] += 2.0 * s0
        return Hm, lin, const

    # -- evaluation ----------------------------------------------------------------
    def __call__(self, b):
        """E(b) for b of shape (..., 3) (deg/s)."""
        b = np.asarray(b, float) - self.shift
        if self.direct:
            flat = b.reshape(-1, 3)
            out = np.array([np.mean(np.abs(self.g - bb).sum(axis=1) ** 2) for bb in flat])
            return out.reshape(b.shape[:-1])
        a = self.counts_below(b)
        Hm, lin, const = self._quadratic(a)
        val = const + np.einsum("...i,...i->...", lin, b) \
            + 0.5 * np.einsum("...i,...ij,...j->...", b, Hm, b)
        return val / self.n

    # -- exact minimiser -----------------------------------------------------------
    def exact_minimum(self, b0, max_moves: int = 50):
        """Minimiser of E near b0 (deg/s); exact to rounding.  Returns (b, E)."""
        if self.direct:
            return np.asarray(b0, float), float(self(b0))
        b = np.asarray(b0, float) - self.shift
        val = float(self(b + self.shift))
        offs = np.array(list(itertools.product((-1, 0, 1), repeat=3)))
        nU = np.array([len(u) for u in self.U])
        ext_lo = [np.concatenate([[-np.inf], u]) for u in self.U]
        ext_hi = [np.concatenate([u, [np.inf]]) for u in self.U]
        for _ in range(max_moves):
            # the 3x3x3 block of cells around b covers a neighbourhood of b: if
            # nothing in it is lower, b is a local, hence (convexity) global minimum
            cells = self.counts_below(b) + offs
            cells = cells[((cells >= 0) & (cells <= nU)).all(axis=1)]
            lo = np.stack([ext_lo[i][cells[:, i]] for i in range(3)], 1)
            hi = np.stack([ext_hi[i][cells[:, i]] for i in range(3)], 1)
            Hm, lin, _ = self._quadratic(cells)
            cand = _box_qp_candidates(Hm, lin, lo, hi)
            if not len(cand):
                break
            vals = self(cand + self.shift)
            k = int(np.argmin(vals))
            if vals[k] >= val * (1 - 1e-13):
                break
            b, val = cand[k], float(vals[k])
        return b + self.shift, float(self(b + self.shift))


def _box_qp_candidates(Hm, lin, lo, hi):
    """All KKT candidates of min 0.5 x'Hx + lin'x over boxes [lo, hi]:
    every pattern of free / at-lower / at-upper coordinates; infeasible and
    infinite ones dropped.  Hm (m,3,3), lin (m,3), lo/hi (m,3)."""
    m = len(lin)
    P = _PATTERNS                                  # (27, 3)
    Hb = np.repeat(Hm, len(P), axis=0)             # (m*27, 3, 3)
    lb = np.repeat(lin, len(P), axis=0)
    lob = np.repeat(lo, len(P), axis=0)
    hib = np.repeat(hi, len(P), axis=0)
    pat = np.tile(P, (m, 1))
    fixed_val = np.where(pat == 1, lob, np.where(pat == 2, hib, 0.0))
    free = pat == 0
    ok = np.isfinite(fixed_val).all(axis=1)
    # solve H_ff x_f = -(lin_f + H_fx x_x): build a full system with identity rows for fixed
    rhs = -(lb + np.einsum("kij,kj->ki", Hb, np.where(free, 0.0, fixed_val)))
    Ms = np.where(free[:, :, None] & free[:, None, :], Hb, 0.0)
    eye = np.eye(3)[None]
    Ms = Ms + np.where(~free[:, :, None], eye, 0.0) * np.where(~free[:, None, :], eye, 0.0)
    rhs = np.where(free, rhs, fixed_val)
    det = np.linalg.det(Ms)
    ok &= np.abs(det) > 1e-12 * np.abs(np.einsum("kii->k", Ms)) ** 3
    x = np.full((len(pat), 3), np.nan)
    if ok.any():
        x[ok] = np.linalg.solve(Ms[ok], rhs[ok][..., None])[..., 0]
    tol = 1e-12 * (1 + np.abs(x))
    ok &= np.all((x >= lob - tol) & (x <= hib + tol), axis=1)
    x = np.clip(x[ok], lob[ok], hib[ok])
    return x


def residuals(b, g):
    """Per-sample sqrt of eq. 6: |X'-b1| + |Y'-b2| + |Z'-b3| (for least squares)."""
    return np.abs(g - b).sum(axis=1)


def jacobian(b, g):
    return -np.sign(g - b)
