"""Identifiability: which parameters the data and the fitness can determine.

Computed numerically from the Jacobian of the residuals at the optimum (never
assumed).  First, a column whose parameter, moved by its typical size
(``scale``: the half-width of its a-priori range), changes the residuals by
less than ``NULL_EFFECT`` of the residual's own unit (rms; ``unit``: 1 g, the
field) is no column at all: the paper's angles at an optimum of 0 have a
column of sin(angle) ~ 1e-8 that is rounding, not information, and
normalising it would turn that noise into rank.  The other columns are
normalised, the rank is the number of singular values above ``RANK_RTOL``
times the largest, and a parameter is *not identifiable* when its unit
vector has a component in the Jacobian's null space (it can be traded
against other parameters, or moved, without changing any residual).  For
the paper model with angles this finds rank 6 of 9: the angles only
multiply the scales.

Standard deviations use ``sigma^2 (J^T J)^+``; for identifiable parameters
this is the same for every generalised inverse, for the others it is
meaningless and reported as NaN.

``independent_columns`` picks, in parameter order, a largest set of columns
that are independent at the same tolerance: for a model with redundant
parameters the least-squares polish moves only those (``fit.polish``) and
sets the others to their nominal value.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

RANK_RTOL = 1e-9
NULL_TOL = 1e-6
NULL_EFFECT = 1e-6        # rms residual change (in ``unit``) of a parameter moved by ``scale``


@dataclass
class Identifiability:
    names: list
    rank: int
    singular: np.ndarray          # singular values of the column-normalised Jacobian
    identifiable: np.ndarray      # bool per parameter
    null_space: np.ndarray        # (d - rank, d) basis, in normalised-column coordinates
    cov_unit: np.ndarray          # (J^T J)^+ (multiply by sigma^2)

    @property
    def d(self) -> int:
        return len(self.names)

    @property
    def not_identifiable(self) -> list:
        return [n for n, ok in zip(self.names, self.identifiable) if not ok]

    @property
    def condition(self) -> float:
        s = self.singular[: self.rank]
        return float(s[0] / s[-1]) if len(s) else float("inf")

    def std(self, sigma2: float) -> np.ndarray:
        sd = np.sqrt(np.maximum(np.diag(self.cov_unit), 0.0) * sigma2)
        return np.where(self.identifiable, sd, np.nan)

    def note(self) -> str:
        if self.rank == self.d:
            return f"all {self.d} parameters identifiable (Jacobian rank {self.rank})"
        return (f"Jacobian rank {self.rank} of {self.d}: not identifiable: "
                f"{', '.join(self.not_identifiable)} (any value in the null space fits equally)")


def analyse(J: np.ndarray, names, scale=None, unit: float = 1.0) -> Identifiability:
    """Rank, identifiable parameters and (J^T J)^+ of the Jacobian ``J`` (n, d);
    ``scale`` (d,) is each parameter's typical size (default 1) and ``unit``
    the residual's (see the module doc)."""
    J = np.asarray(J, float)
    n, d = J.shape
    norms = np.linalg.norm(J, axis=0)
    typical = np.ones(d) if scale is None else np.broadcast_to(np.asarray(scale, float), (d,))
    effect = norms * typical / np.sqrt(max(n, 1))
    live = (norms > 0) & (effect > NULL_EFFECT * abs(unit))
    colnorm = np.where(live, norms, 1.0)
    Js = np.where(live, J, 0.0) / colnorm
    if Js.shape[0] > d:                      # same singular values, d x d work
        Js = np.linalg.qr(Js, mode="r")
    _, s, Vt = np.linalg.svd(Js, full_matrices=True)
    s_full = np.zeros(d)
    s_full[: len(s)] = s
    smax = s_full[0] if d else 0.0
    rank = int(np.sum(s_full > RANK_RTOL * smax)) if smax > 0 else 0
    null = Vt[rank:]
    ident = np.linalg.norm(null, axis=0) < NULL_TOL if len(null) else np.ones(d, bool)
    inv = np.zeros(d)
    inv[:rank] = 1.0 / s_full[:rank] ** 2
    cov_s = (Vt.T * inv) @ Vt
    cov = cov_s / np.outer(colnorm, colnorm)
    return Identifiability(list(names), rank, s_full, ident, null, cov)


def independent_columns(J: np.ndarray) -> np.ndarray:
    """Bool per column: the column adds a direction the earlier kept columns do
    not span (greedy in parameter order).  On the column-normalised Jacobian
    that is ``|R_jj| > RANK_RTOL`` of its QR factor (R_jj is the part of
    column j orthogonal to all earlier columns, and a dropped column lies in
    the span of the kept ones); an all-zero column is never kept.  For the
    paper model with angles this keeps the offsets and scales (6 of 9).  J may
    be any shape; its columns are the parameters."""
    J = np.asarray(J, float)
    norms = np.linalg.norm(J, axis=0)
    R = np.linalg.qr(J / np.where(norms > 0, norms, 1.0), mode="r")
    diag = np.zeros(J.shape[1])
    k = min(R.shape)
    diag[:k] = np.abs(np.diag(R)[:k])
    return (diag > RANK_RTOL) & (norms > 0)
