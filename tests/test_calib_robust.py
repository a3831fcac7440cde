"""The robust fit (issue 25): glitches and disturbed stretches planted
through the simulator (tests/contaminated.py) are set aside, the
calibration stays near the clean board's, the gate says what it set aside
and refuses what is beyond it; the held-out check is robust.  Rates over
several seeds; every truth from what was planted."""
import copy

import numpy as np
import pytest

import contaminated as CT
from motecal.calib import fit as F, robust as R
from motecal.calib.board import calibrate_board
from motecal.calib.ellipsoid import algebraic_fit, as_affine
from motecal.calib.gate import decide
from motecal.calib.loop import magnitude_heldout
from motecal.calib.models import make_model
from motecal.calib.result import BoardCalibration
from synthetic import shape_error, vector_error

MDL = make_model("mag", "full")
SEEDS = (11, 12, 13, 14)


def _shape(p, sc):
    return shape_error(sc.A, sc.c, p.truth, "mag", p.field)


def _ls_shape(p):
    A, c, _ = MDL.affine(F.lm_optimize(MDL, p.data.sensor("mag") / 1090.0)[0])
    return shape_error(A / 1090.0, c, p.truth, "mag", p.field)


@pytest.fixture(scope="module")
def glitchy():
    """Four sweeps with 5 % glitches (10-50 % of the field) and a 1-s
    stretch 12 % off, calibrated as calibrate does."""
    out = []
    for s in SEEDS:
        p = CT.sweep(s, rate=0.05, size=(0.1, 0.5), stretch_s=1.0)
        b = calibrate_board(p.data, seed=s, kfold=0)
        out.append((s, p, b, decide(b)))
    return out


def test_glitchy_sweeps_accepted_and_near_the_clean_error(glitchy):
    ok = 0
    for s, p, b, d in glitchy:
        e = _shape(p, b.mag)
        e_clean = _ls_shape(CT.sweep(s, clean=True))
        T, ctr, _ = algebraic_fit(p.data.sensor("mag"))
        e_alg = shape_error(*as_affine(T, ctr), p.truth, "mag", p.field)
        good = d.accepted and e <= e_alg / 3 and e <= 1.5 * e_clean
        ok += good
        print(f"seed {s}: accepted {d.accepted}, shape {100 * e:.4f} % (clean {100 * e_clean:.4f}"
              f" %, algebraic {100 * e_alg:.3f} %)")
    assert ok >= 3, "fewer than 3 of 4 glitchy sweeps accepted near the clean error"


def test_planted_readings_are_set_aside(glitchy):
    """What was planted (the terms' own draws) against what was set aside:
    every glitch of 10 % of the field or more and every reading of the
    stretch, and few clean readings besides."""
    for s, p, b, _ in glitchy:
        aside = np.zeros(len(p.data), bool)
        for a, k in b.mag.set_aside["rows"]:
            aside[a:a + k] = True
        planted = p.glitched | p.stretched
        found = (aside & planted).sum() / planted.sum()
        false = (aside & ~planted).sum() / (~planted).sum()
        assert found > 0.97 and false < 0.01, (s, found, false)
        st = b.mag.set_aside["stretches_s"]
        t = p.data.sample_times()
        assert any(abs(a - t[p.stretched].min()) < 0.05 and abs(e - t[p.stretched].max()) < 0.05
                   for a, e, *_ in st), (s, st)        # the stretch, with its times


def test_clean_sweeps_unchanged():
    """On clean sweeps the robust fit is least squares on (nearly) every
    reading: the same error within a few per cent."""
    r = []
    for s in SEEDS:
        p = CT.sweep(s, clean=True)
        rf = R.ga_fit(MDL, p.data.sensor("mag") / 1090.0, seed=s)
        A, c, _ = MDL.affine(rf.theta)
        r.append((shape_error(A / 1090.0, c, p.truth, "mag", p.field), _ls_shape(p)))
        assert rf.keep.mean() > 0.998
    r = np.array(r)
    ratio = np.sqrt(np.mean(r[:, 0] ** 2) / np.mean(r[:, 1] ** 2))
    assert abs(ratio - 1) < 0.05, ratio


@pytest.mark.parametrize("seed", [21, 22])
def test_twenty_percent_refused_with_the_reason_or_accurate(seed):
    p = CT.sweep(seed, rate=0.2, size=(0.05, 0.6), stretch_s=3.0)
    b = calibrate_board(p.data, seed=seed, kfold=0)
    d = decide(b)
    if d.accepted:
        assert _shape(p, b.mag) <= 2 * _ls_shape(CT.sweep(seed, clean=True))
    else:
        assert any(r.startswith("mag: too many readings set aside") for r in d.reasons), d.reasons


@pytest.mark.parametrize("seed", [31, 32])
def test_a_long_stretch_is_refused_and_said_so(seed):
    """6 s in a field 12 % off: set aside, and refused for it, with its times."""
    p = CT.sweep(seed, rate=0.0, stretch_s=6.0, stretch=0.12)
    b = calibrate_board(p.data, seed=1, kfold=0)
    d = decide(b)
    assert not d.accepted
    why = [r for r in d.reasons if r.startswith("mag: disturbed for too long")]
    assert why and "limit 5 s" in why[0], d.reasons
    t = p.data.sample_times()[p.stretched]
    assert f"({t.min():.1f}-{t.max():.1f} s" in why[0], (why, t.min(), t.max())


def test_set_aside_kept_in_cal_json(glitchy, tmp_path):
    s, p, b, _ = glitchy[0]
    path = b.save(tmp_path / "cal.json")
    back = BoardCalibration.load(path)
    assert back.mag.set_aside == b.mag.set_aside and back.mag.set_aside["count"] > 0
    # a file written before issue 25 (no set_aside) still reads
    d = b.to_json()
    d["mag"].pop("set_aside")
    old = BoardCalibration.from_json(copy.deepcopy(d))
    assert old.mag.set_aside == {} and np.allclose(old.mag.A, b.mag.A)


def test_summary_says_what_was_set_aside_and_what_it_is_worth(glitchy):
    from motecal.commands.calibrate import summary
    s, p, b, _ = glitchy[0]
    text = summary(b)
    assert "mag: set aside" in text and "stretch" in text and "single readings" in text
    assert "worth: a heading from one reading is off by about" in text


# ---------------------------------------------------------------------------
# the held-out check: robust, or it cannot see what leaving readings out gains
# ---------------------------------------------------------------------------
def _ls_copy(sc, u):
    """The calibration least squares gives (pulled by the glitches), in the
    form calibrate's loop compares."""
    out = copy.deepcopy(sc)
    th, _ = F.lm_optimize(MDL, u)
    for prm, v in zip(out.params, th):
        prm.value = float(v)
    out.set_aside = {}
    return out


def test_heldout_check_is_robust(glitchy):
    """Least squares pulled by the glitches against the robust fit, judged on
    held-out 1-s chunks of the same readings: the robust fit must win the
    check.  Judged by a plain rms the held-out chunks are made of the
    glitches, the same for both, and the check cannot tell (this test fails
    when ``magnitude_heldout`` scores with a plain mean square)."""
    wins = 0
    for s, p, b, _ in glitchy:
        data = p.data
        u = data.sensor("mag") / 1090.0
        base = _ls_copy(b.mag, u)
        rows = np.ones(len(data), bool)
        group = (data.sample_times() // 1.0).astype(int)
        dec = magnitude_heldout("mag", data, base, b.mag, rows, rows, group, rows,
                                b.settings, 5, False)
        print(s, dec)
        wins += dec.accepted
    assert wins >= 3


# ---------------------------------------------------------------------------
# poses with knocks, gyroscope glitches
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("seed", [41, 42])
def test_knocked_poses_and_gyro_glitches(seed):
    p = CT.poses(seed, bumps=3, gyro_rate=0.01, n_poses=30)
    pc = CT.poses(seed, n_poses=30, clean=True)
    b = calibrate_board(p.data, seed=1, kfold=0, gyro_matrix=False)
    bc = calibrate_board(pc.data, seed=1, kfold=0, gyro_matrix=False)
    d = decide(b)
    assert d.accepted, d.reasons                    # the knocks are not "non-still" poses
    # the knocks set aside (the planted stretches' rows), little else
    aside = np.zeros(len(p.data), bool)
    for a, k in b.accel.set_aside["rows"]:
        aside[a:a + k] = True
    knocked = p.stretched & (p.data.label >= 1)
    assert (aside & knocked).sum() >= 0.9 * knocked.sum()
    assert b.accel.set_aside["count"] < knocked.sum() + 0.005 * len(p.data)
    assert vector_error(b.accel, p.truth) <= 1.5 * vector_error(bc.accel, pc.truth)
    # gyroscope: the glitches set aside, the bias as the clean twin's within its noise
    bias = np.array([q.value for q in b.gyro.params[:3]])
    bias0 = np.array([q.value for q in bc.gyro.params[:3]])
    std0 = np.array([q.std for q in bc.gyro.params[:3]])
    assert np.all(np.abs(bias - bias0) < 4 * std0 + 0.01), (bias - bias0, std0)
    assert b.gyro.set_aside["count"] >= 0.8 * (p.glitched & (p.data.label >= 1)).sum()


def test_a_knocked_move_is_left_out_of_the_gyro_matrix():
    """A knock while turning (the gyroscope 40 deg/s off for 0.05 s: 2 deg of
    rotation that did not happen) in one move of 29: that move is set aside
    from the scale and misalignment fit, which stays the clean twin's; a
    move with a lost sample is not used at all (``gyro.find_moves``)."""
    p = CT.poses(51, bumps=0, n_poses=30, move_knock=(40.0, 0.05))
    pc = CT.poses(51, bumps=0, n_poses=30, clean=True)
    b = calibrate_board(p.data, seed=1, kfold=0)
    bc = calibrate_board(pc.data, seed=1, kfold=0)
    assert b.gyro.model == "bias+matrix" and bc.gyro.model == "bias+matrix"
    assert b.gyro.extra["matrix_fit"]["moves_set_aside"] >= 1
    assert any(n.startswith("moves set aside") and "15->16" in n for n in b.gyro.notes)
    G = np.array([q.value for q in b.gyro.params[3:]])
    G0 = np.array([q.value for q in bc.gyro.params[3:]])
    sd = np.array([q.std for q in bc.gyro.params[3:]])
    assert np.all(np.abs(G - G0) < 3 * sd), (G - G0) / sd
    # a lost sample in that move: the move is not integrated at all
    d = pc.data
    mid = np.flatnonzero((d.label == 0) & (d.sample_times() > 0))
    cut = mid[len(mid) // 2]
    lost = d.select(np.arange(len(d)) != cut)
    bl = calibrate_board(lost, seed=1, kfold=0)
    assert bl.gyro.extra["matrix_fit"]["moves"] == bc.gyro.extra["matrix_fit"]["moves"] - 1
