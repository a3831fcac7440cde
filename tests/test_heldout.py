"""maths.heldout: the one k-fold held-out loop (calib.loop, calib.thermal,
calib.extra_terms and diagnose.thermal use it)."""
import numpy as np

from motecal.maths.heldout import fold_sums, interleaved, kfold_heldout


def _fit(X, y):
    return lambda tr: np.linalg.lstsq(X[tr], y[tr], rcond=None)[0]


def test_held_out_residuals_of_a_linear_fit_match_a_loop_by_hand():
    rng = np.random.default_rng(4)
    X = np.column_stack([np.ones(40), rng.normal(size=40)])
    y = X @ [1.0, 2.0] + rng.normal(0, 0.1, 40)
    fold = interleaved(40, 5)
    r = kfold_heldout(fold, _fit(X, y), lambda b, te: y[te] - X[te] @ b)
    for f in range(5):
        te = fold == f
        b = np.linalg.lstsq(X[~te], y[~te], rcond=None)[0]
        np.testing.assert_array_equal(r[te], y[te] - X[te] @ b)
    # a held-out residual is larger than the in-sample one on average
    b_all = np.linalg.lstsq(X, y, rcond=None)[0]
    assert np.mean(r ** 2) > np.mean((y - X @ b_all) ** 2)
    sums = fold_sums(r ** 2, fold)
    assert [f for f, _, _ in sums] == [0, 1, 2, 3, 4] and sum(n for _, _, n in sums) == 40
    assert np.isclose(sum(s for _, s, _ in sums), np.sum(r ** 2))


def test_units_in_no_fold_and_skipped_folds_stay_nan():
    y = np.arange(10.0)
    fold = np.array([0, 1, 2, 0, 1, 2, -1, 0, 1, 2])
    seen = []

    def fit(tr):
        seen.append(np.flatnonzero(tr).tolist())
        return None if not tr[0] else float(y[tr].mean())      # fold 0 has nothing to fit
    r = kfold_heldout(fold, fit, lambda m, te: np.full(te.sum(), m))
    assert 6 not in sum(seen, [])                                # never trained on
    assert np.isnan(r[[0, 3, 6, 7]]).all() and np.isfinite(r[[1, 2, 4, 5, 8, 9]]).all()
    assert r[1] == y[[0, 2, 3, 5, 7, 9]].mean()
    assert fold_sums(r, fold) == [(1, float(np.sum(r[fold == 1])), 3),
                                  (2, float(np.sum(r[fold == 2])), 3)]
    assert np.isnan(kfold_heldout(np.array([-1, -1]), fit, None)).all()


def test_one_row_of_scores_per_unit():
    fold = interleaved(6, 3)
    r = kfold_heldout(fold, lambda tr: tr.sum(), lambda m, te: np.tile([m, -m], (te.sum(), 1)))
    assert r.shape == (6, 2) and (r[:, 0] == 4).all() and (r[:, 1] == -4).all()
