"""k-fold held-out evaluation, the one loop calibrate, its temperature term
and the diagnosis judge a model term by (pure: arrays and callables in,
arrays out).

``kfold_heldout(fold, fit, score)``: the units (rows, blocks, poses or
groups) carry a fold number each (negative: in no fold); for every fold
``f`` (each distinct value >= 0, ascending) the model is fitted on the units
of the other folds, ``fit(train)`` with ``train`` a bool mask over the units
(None: nothing to fit, the fold is skipped), and scored on the fold's own,
``score(model, test)`` -> one value (or row of values) per test unit, in
unit order.  The result holds every unit's held-out score (NaN for units of
skipped folds and of no fold): the callers sum it per fold, per group or in
all, as their statistic needs.

``interleaved(n, k)``: the usual assignment, unit i in fold i mod k.
"""
from __future__ import annotations

import numpy as np


def interleaved(n: int, k: int) -> np.ndarray:
    """Fold per unit: 0, 1, ..., k-1, 0, 1, ... (n units)."""
    return np.arange(int(n)) % max(1, int(k))


def kfold_heldout(fold, fit, score) -> np.ndarray:
    """Held-out score per unit (the module doc).  The score array has shape
    (units,) + the shape of one unit's score."""
    fold = np.asarray(fold)
    out = None
    for f in np.unique(fold[fold >= 0]):
        test = fold == f
        model = fit((fold >= 0) & ~test)
        if model is None:
            continue
        s = np.asarray(score(model, test), float)
        if out is None:
            out = np.full((len(fold),) + s.shape[1:], np.nan)
        out[test] = s
    return np.full(len(fold), np.nan) if out is None else out


def fold_sums(values: np.ndarray, fold: np.ndarray) -> list[tuple[int, float, int]]:
    """(fold, sum of its units' values, number of values summed) per fold that
    has a finite value, ascending -- each fold summed on its own, in unit
    order, as a loop over folds would."""
    values = np.asarray(values, float)
    fold = np.asarray(fold)
    out = []
    for f in np.unique(fold[fold >= 0]):
        v = values[fold == f]
        if not np.isfinite(v).all():
            continue
        out.append((int(f), float(np.sum(v)), int(v.size)))
    return out
