"""The criterion that turns tests into findings, and held-out gains of terms
that change the spread rather than the mean.

Criterion (pure noise never produces a finding)
-----------------------------------------------
Every test the diagnosis runs is counted (``n_tests``: per sensor, each
candidate cause its data allow, plus the screens).  A cause becomes a finding
only when

1. its p-value under the current model is below ``alpha / n_tests``
   (Bonferroni: the chance that pure noise produces *any* finding is at most
   ``alpha``, default 1 %).  For a term with q parameters the F-test is a
   likelihood-ratio test: each extra parameter has to lower the weighted
   residual by a fixed multiple of its noise, a penalty that grows with the
   number of parameters (the BIC difference is reported next to it);
2. it is above the cause's practical floor (``screens``), and
3. for a fitted term (one that changes the mean reading), its held-out gain
   is above 1 and consistent: on poses, time blocks or readings not used for
   fitting (5 interleaved folds) the model with the term predicts better
   (rms) than without it overall and in at least ``MIN_FOLD_WINS`` of the 5
   folds (a term that only fits noise wins each fold with probability ~1/2,
   all but one of five with ~0.19 -- on top of the p-value gate).  Where the
   points carry their own variances (the gyroscope's turn-corrected holds
   under tremor), a paired test of the held-out points (one-sided,
   p < ``PAIRED_P``) may stand in for the folds won: 24-33 hand-held poses
   make folds of 5-7 points, where a real term loses two by chance.
   (The screens' terms --
   repeats, clipping, shaking -- are measured, not fitted through the
   residual; their gain is reported, not used as a veto.)

The bench measures the resulting false-alarm rate on clean simulated boards.
"""
from __future__ import annotations

import numpy as np

DEFAULT_ALPHA = 0.01
MIN_FOLD_WINS = 4        # of the 5 held-out folds, a fitted term must improve at least 4
PAIRED_P = 0.05          # or: the held-out points' paired test (blocks known to their own variance)


def per_test_alpha(alpha: float, n_tests: int) -> float:
    return alpha / max(1, n_tests)


def accepted(p: float, alpha_test: float, gain: float | None, practical: bool = True,
             fold_wins: int | None = None, paired_p: float | None = None) -> bool:
    if not (p < alpha_test) or not practical:
        return False
    if gain is None:
        return True
    return gain > 1.0 and (fold_wins is None or fold_wins >= MIN_FOLD_WINS
                           or (paired_p is not None and paired_p < PAIRED_P))


def variance_gain(r: np.ndarray, V: np.ndarray, fold: np.ndarray, tau2_fn) -> tuple:
    """Held-out gain of a variance term (extra scatter tau^2 per point):
    per fold, the measured rms of the held-out residuals against the rms the
    model predicts -- sqrt(mean V) without the term, sqrt(mean V + tau^2) with
    tau^2 estimated on the other folds (``tau2_fn(train_mask)``).
    Returns (gain, rms discrepancy before, after)."""
    meas, b, a = [], [], []
    for f in np.unique(fold):
        te = fold == f
        if te.sum() < 2:
            continue
        m = float(np.sqrt(np.mean(r[te] ** 2)))
        meas.append(m)
        b.append(float(np.sqrt(np.mean(V[te]))))
        a.append(float(np.sqrt(np.mean(V[te]) + tau2_fn(~te))))
    meas, b, a = map(np.asarray, (meas, b, a))
    if not len(meas):
        return None, None, None
    before = float(np.sqrt(np.mean((meas - b) ** 2)))
    after = float(np.sqrt(np.mean((meas - a) ** 2)))
    return (before / after if after > 0 else float("inf")), before, after
