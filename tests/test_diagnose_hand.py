"""Hand sessions (issue 13 part 3): poses held 1.6 s with moves longer (3-5 s)
or shorter (0.6-1 s) than the holds, with a hand's tremor during the holds
(0.07-0.21 deg rms, 1.5-5 Hz), labelled and not.  The still stretches are
judged on the board's orientation, so tremor does not lose the poses; the
tremor is named ``motion``; the gyroscope's hold means have the tremor's net
turn taken out (``diagnose.turns``).

Rates over a handful of seeds, the seeds printed on failure;
``MOTECAL_TEST_SEED`` shifts every seed.  The bench (bench/bench_diagnose.py,
kinds ``hand-*``) measures the same with hundreds of cases.  (~30-60 s)"""
import os

import numpy as np
import pytest

import hand as H
import plant as P
from motecal.calib.content import still_stretches, stretch_orientations
from motecal.diagnose.engine import diagnose
from motecal.diagnose.prepare import all_obs

SEED = 3100 + int(os.environ.get("MOTECAL_TEST_SEED", "0"))
KINDS = list(H.HAND_KINDS)          # hand-slow, hand-fast


def _tremor(seed):
    return P.make_plant("motion", "accel", np.random.default_rng([seed, 4049]))


def _session(kind, plants, seed, labelled=False):
    return H.session(kind, plants, seed, labelled=labelled)


def _angle_from_hold(traj, t, truth):
    """Per row, the rig's turn (deg) from the orientation of the hold the row
    is nearest to in time (tremor is the board's, not the rig's)."""
    R = traj.at(t).R
    out = np.zeros(len(t))
    holds = np.flatnonzero(truth >= 1)
    for i in range(len(t)):
        j = holds[np.argmin(np.abs(t[holds] - t[i]))]
        c = (np.trace(R[j].T @ R[i]) - 1) / 2
        out[i] = np.degrees(np.arccos(np.clip(c, -1, 1)))
    return out


@pytest.mark.parametrize("kind", KINDS)
def test_poses_with_tremor_are_found_and_moves_are_not(kind):
    """Unlabelled, with tremor: the still stretches find >= 90 % of the holds
    in every seed (the rate's spread, which tremor breaks, found none in most)
    and cover >= 90 % of the distinct orientations; >= 99 % of their rows
    are within 0.5 deg of a hold's orientation (the slow ends of moves that
    are kept are the last few tenths of a degree)."""
    bad = []
    for j in range(3):
        seed = SEED + j
        hold, move, n = H.HAND_KINDS[kind]
        traj = H.hand_trajectory(seed, n, hold, move)
        ses = _session(kind, [_tremor(seed)], seed)
        lab = still_stretches(ses)
        truth = traj.label_at(ses.t)
        found = {int(np.bincount(truth[lab == k]).argmax()) for k in np.unique(lab[lab > 0])}
        found.discard(0)
        kept = np.flatnonzero(lab > 0)
        near = float(np.mean(_angle_from_hold(traj, ses.t[kept], truth[kept]) <= 0.5)) \
            if len(kept) else 0.0
        ori = stretch_orientations(ses, lab)
        if len(found) < 0.9 * n or near < 0.99 or ori < 0.9 * n:
            bad.append((seed, len(found), n, round(near, 4), ori))
    assert not bad, f"{kind}: seed, holds found, holds, rows near a hold, orientations: {bad}"


@pytest.mark.parametrize("labelled", [False, True], ids=["unlabelled", "labelled"])
def test_tremor_is_named_and_nothing_else(labelled):
    """Clean boards held by a trembling hand, slow and fast moves: the tremor
    is named ``motion`` in all but at most one of 6 sessions, and at most one
    names anything else; unlabelled, the diagnosis says the data hold static
    poses."""
    missed, extra = [], []
    for j in range(6):
        seed = SEED + 20 + j
        kind = KINDS[j % 2]
        t = _tremor(seed)
        d = diagnose(_session(kind, [t], seed, labelled), simulate=False)
        if not labelled:        # what the data hold, said in a note
            assert any(n.startswith("session: ") and "static poses" in n for n in d.notes), \
                (seed, d.notes)
        if ("accel", "motion") not in d.causes():
            missed.append((seed, kind, round(t.size, 3)))
        if d.causes() - {("accel", "motion")}:
            extra.append((seed, kind, sorted(d.causes())))
    assert len(missed) <= 1, f"tremor not named: {missed}"
    assert len(extra) <= 1, f"named on clean boards with tremor: {extra}"


@pytest.mark.parametrize("key", [("cross_axis", "accel"), ("cross_axis", "mag")],
                         ids=["accel", "mag"])
def test_calibration_terms_are_named_under_tremor(key):
    """A cross-axis coupling at its threshold .. 3x, unlabelled hand sessions
    with tremor: named in at least 3 of 4."""
    missed = []
    for j in range(4):
        seed = SEED + 40 + j
        plant = P.make_plant(*key, np.random.default_rng([seed, 7]))
        d = diagnose(_session(KINDS[j % 2], [plant, _tremor(seed)], seed), simulate=False)
        if (plant.sensor, plant.cause) not in d.causes():
            missed.append((seed, round(plant.size, 4), sorted(d.causes())))
    assert len(missed) <= 1, missed


def test_gyro_hold_means_without_the_tremors_turn():
    """With tremor, each hold's plain gyro mean carries the tremor's net turn
    (its scatter is >= 2x what the white noise allows); with the turn taken
    out (the accelerometer's and magnetometer's whole paths against the
    gyroscope's), the scatter matches the stated variance (chi-square per
    degree of freedom 0.5-2) and >= 80 % of the blocks are measured, in all
    but at most one of 6 sessions (labelled and not, slow and fast moves;
    a block too short to measure is left out, never kept with the tremor
    inside and the plain mean's variance)."""
    bad = []
    for j in range(6):
        seed = SEED + 60 + j
        labelled = j < 3
        ses = _session(KINDS[j % 2], [_tremor(seed)], seed, labelled=labelled)
        d = diagnose(ses, simulate=False)
        g = d.obs["gyro"]
        plain = all_obs(ses)["gyro"]
        if g.blocks.var is None:
            bad.append((seed, "not corrected", d.notes))
            continue
        ok = np.all(np.isfinite(g.blocks.var), axis=1)

        def chi2(mean, var):
            r = mean - np.average(mean, axis=0, weights=1 / var)
            return float(np.sum(r ** 2 / var) / (r.size - 3)), float(np.sqrt(np.mean(r ** 2)))

        c_plain, _ = chi2(plain.blocks.mean, plain.sigma ** 2 / plain.blocks.n[:, None])
        c_corr, _ = chi2(g.blocks.mean[ok], g.blocks.var[ok])
        if not (c_plain >= 2.0 and 0.5 <= c_corr <= 2.0 and ok.mean() >= 0.8):
            bad.append((seed, labelled, round(c_plain, 2), round(c_corr, 2),
                        round(float(ok.mean()), 2)))
    assert len(bad) <= 1, f"seed, labelled, chi2 plain, chi2 corrected, blocks measured: {bad}"


def test_clean_hand_sessions_without_tremor():
    """No tremor, slow and fast moves, labelled and not: at most one of 8
    clean boards with any finding."""
    alarms = []
    for j in range(8):
        seed = SEED + 80 + j
        d = diagnose(_session(KINDS[j % 2], [], seed, labelled=j % 4 >= 2), simulate=False)
        if not d.clean:
            alarms.append((seed, sorted(d.causes())))
    assert len(alarms) <= 1, alarms


def test_gyro_hold_bias_unlabelled_fast_against_the_truth():
    """Unlabelled fast hand sessions with tremor: the still stretches are cut
    well inside the 1.6 s holds (about 1.1 s), so the accelerometer's span
    is widened over the rest of each hold while the board stays within the
    tremor's reach, and the magnetometer's into the moves' first degrees.
    Against the planted bias (a clean board: constant), the measured holds'
    biases scatter as their stated variances say (chi-square per degree of
    freedom 0.5-2), and the median stated sd is <= 0.105 deg/s (0.12-0.14
    with the still stretches' spans alone), in at least 3 of 4 sessions."""
    bad = []
    for j in range(4):
        seed = SEED + 90 + j
        plants = [_tremor(seed)]
        ses = _session("hand-fast", plants, seed, labelled=False)
        d = diagnose(ses, simulate=False)
        g = d.obs["gyro"]
        if g.blocks.var is None:
            bad.append((seed, "not corrected"))
            continue
        ok = np.all(np.isfinite(g.blocks.var), axis=1)
        truth = np.asarray(P.planted_model(plants).board(1, seed).physical_truth()["gyro"]["b"])
        r = (g.blocks.mean[ok] - truth) / g.K
        sd = np.sqrt(g.blocks.var[ok]) / g.K
        chi2 = float(np.mean((r / sd) ** 2))
        if not (float(np.median(sd)) <= 0.105 and 0.5 <= chi2 <= 2.0):
            bad.append((seed, round(float(np.median(sd)), 3), round(chi2, 2)))
    assert len(bad) <= 1, f"seed, median sd deg/s, chi2 per dof: {bad}"
