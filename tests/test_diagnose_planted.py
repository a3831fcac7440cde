"""Hidden effects: plant each cause in a simulated board at a random size
above its documented threshold; the diagnosis, not told which, must name it
with a gain close to the truth's (computed from the planted parameters:
``tests/truth.py``).  Clean boards: no finding.  Two effects at once: both
named.

Tests hold for any seed: each asserts a *rate* over several seeds with a
stated bound, and prints the seeds that missed.  ``MOTECAL_TEST_SEED``
shifts every seed (CI uses the default; any other value must pass too).
The full sweep with hundreds of cases and Clopper-Pearson bounds is
bench/bench_diagnose.py.  (~60 s)"""
import json
import os
import re
from functools import lru_cache

import numpy as np
import pytest

import truth as TR
from motecal.diagnose.engine import diagnose
from motecal.sessions.store import open_store
from motecal.sim import load_model

P = TR.P
SEED = 20260 + int(os.environ.get("MOTECAL_TEST_SEED", "0"))
N_SEEDS = 4               # seeds per (cause, sensor)
KEYS = list(P.THRESHOLDS)


def _case(keys, seed, kind=None, labelled=True, duration=None):
    rng = np.random.default_rng([SEED, seed])
    plants = [P.make_plant(c, s, rng) for c, s in keys]
    kind = kind or plants[0].kind
    ses = P.simulate(plants, kind, SEED + seed, labelled=labelled, duration=duration)
    return plants, ses, diagnose(ses, simulate=False)


@lru_cache(maxsize=None)
def _runs(key):
    """N_SEEDS cases of one planted (cause, sensor): (seed, named, fitted/true
    gain, other causes named, limit error)."""
    i = KEYS.index(key)
    out = []
    for j in range(N_SEEDS):
        seed = 1000 * i + j
        (plant,), ses, d = _case([key], seed)
        named = (plant.sensor, plant.cause) in d.causes()
        ratio = lim = None
        if named:
            f = next(f for f in d.findings if (f.sensor, f.cause) == (plant.sensor, plant.cause))
            truth = TR.truth_gain(d, plant, [plant], plant.kind, SEED + seed)
            ratio = f.gain / truth if (truth and f.gain) else None
            lim = TR.limit_error(d, plant)
            for fd in d.findings:          # evidence, parameters and a summary with its gain
                assert fd.evidence and fd.summary
                assert fd.cause == "unexplained" or fd.params
        out.append((SEED + seed, named, ratio, sorted(d.causes() - {(plant.sensor, plant.cause)}),
                    lim))
    return out


@pytest.mark.slow
@pytest.mark.parametrize("key", KEYS, ids=[f"{c}-{s}" for c, s in KEYS])
def test_planted_cause_is_named_with_the_truths_gain(key):
    """Named in every seed but at most one (a tool that names the cause in
    >= 95 % of cases fails this with probability <= 1.4 %; the bench
    measures >= 99 %); the median fitted/true gain within 0.75-1.33 and no
    single ratio outside 0.5-2; saturation outside static poses has no
    independent gain: its fitted limit must be the planted one."""
    runs = _runs(key)
    missed = [r[0] for r in runs if not r[1]]
    assert len(missed) <= 1, f"{key} not named for seeds {missed}: {runs}"
    ratios = [r[2] for r in runs if r[2] is not None]
    if key == ("saturation", "gyro"):
        assert all(r[4] is not None and r[4] <= 1.0 for r in runs if r[1]), runs
        return
    if key == ("saturation", "mag"):
        # overflow codes (-4096) leave the pose means alone: no gain to compare
        ratios = ratios or [1.0]
        assert all(0.5 < x < 2.0 for x in ratios), runs
        return
    assert len(ratios) >= len(runs) - 1, runs
    assert 0.75 < np.median(ratios) < 1.33, (key, runs)
    assert all(0.5 < x < 2.0 for x in ratios), (key, runs)


def test_planted_causes_name_nothing_on_other_sensors():
    """Across every planted case above, a cause named on a sensor where
    nothing was planted is rare (each sensor's tests run at the 1 %
    family-wise level; at most 3 of the cases, printed)."""
    other = []
    for key in KEYS:
        sensor = key[1].split("-")[0]
        sensor = "accel" if key[0] == "motion" else sensor
        for seed, _, _, extra, _ in _runs(key):
            bad = [(s, c) for s, c in extra if s != sensor]
            if bad:
                other.append((key, seed, bad))
    assert len(other) <= 3, other


CLEAN = [(k, lab) for k in ("static80", "idle", "rotation") for lab in (True, False)]


@pytest.mark.slow
def test_clean_boards_give_no_finding():
    """Clean boards of every session kind, labelled and not: at most one
    board of the 18 with any finding (the criterion's family-wise level is
    1 % per board: two or more false alarms has probability 1.4 %)."""
    alarms = []
    for i, (kind, labelled) in enumerate(CLEAN):
        for seed in range(3):
            ses = P.simulate([], kind, SEED + 100 + 10 * i + seed, labelled=labelled)
            d = diagnose(ses, simulate=False)
            assert d.n_tests >= 5
            if not d.clean:
                alarms.append((kind, labelled, SEED + 100 + 10 * i + seed, sorted(d.causes())))
            if not labelled and kind != "rotation":
                assert not d.obs["accel"].labelled_poses and len(d.obs["accel"].segs) >= 1
    assert len(alarms) <= 1, alarms


def test_drift_in_a_long_hold_is_bias_drift_not_motion():
    """A pure accelerometer (or magnetometer) bias drift in a session held in
    one orientation for five minutes, on any axis: named bias_drift, never
    motion (a drift across gravity turns the reading without changing its
    length, exactly like a tilt; the magnetometer, which does not turn,
    tells them apart).  At most one miss in 8; no motion at all."""
    res = []
    for j in range(8):
        sensor = ("accel", "mag")[j % 2]
        rng = np.random.default_rng([SEED, 500 + j])
        plant = P.make_plant("bias_drift", sensor, rng)
        ses = P.simulate([plant], "idle", SEED + 500 + j, duration=300.0)
        d = diagnose(ses, simulate=False)
        res.append((SEED + 500 + j, plant.term, sorted(d.causes())))
    assert not any(("accel", "motion") in r[2] for r in res), res
    assert sum((r[1].get("slope") is not None) and
               any(c == "bias_drift" for _, c in r[2]) for r in res) >= 7, res


def test_slow_tilt_in_a_hold_is_motion():
    """The converse: the board itself tilting slowly (0.1 deg rms, 0.02 Hz) in
    a five-minute hold turns accelerometer and magnetometer together: motion
    (at least 3 of 4 seeds), and the magnetometer's share of it is not called a
    drift of its own."""
    res = []
    for j in range(4):
        p = P.Plant("motion", "accel", "idle", 0.1,
                    {"term": "motion", "rms_deg": 0.1, "bandwidth_hz": 0.02}, "board")
        d = diagnose(P.simulate([p], "idle", SEED + 600 + j, duration=300.0), simulate=False)
        res.append((SEED + 600 + j, sorted(d.causes())))
    assert sum(("accel", "motion") in r[1] for r in res) >= 3, res
    assert not any(("mag", "bias_drift") in r[1] for r in res), res


def test_gyro_random_walk_nearby_seeds():
    """The case the review found seed-bound (8 of 20 nearby seeds failed):
    a gyroscope bias random walk in an idle session, 20 consecutive seeds:
    named bias_drift in at least 19, with fitted/true gain (the truth: the
    walk of the planted intensity predicted from the neighbouring blocks)
    within 0.8-1.25 in at least 18."""
    key = ("bias_drift", "gyro-idle")
    i = KEYS.index(key)
    res = []
    for s in range(SEED, SEED + 20):
        rng = np.random.default_rng([s, i])
        plant = P.make_plant(*key, rng)
        ses = P.simulate([plant], "idle", s + i)
        d = diagnose(ses, simulate=False)
        named = (plant.sensor, plant.cause) in d.causes()
        ratio = None
        if named:
            f = next(f for f in d.findings if f.cause == "bias_drift")
            t = TR.truth_gain(d, plant, [plant], "idle", s + i)
            ratio = f.gain / t if t else None
        res.append((s, named, ratio))
    assert sum(r[1] for r in res) >= 19, res
    assert sum(r[2] is not None and 0.8 < r[2] < 1.25 for r in res) >= 18, res


def test_clean_unguided_log_gives_no_finding(tmp_path):
    """The same through the real path: sim -> log (unguided, batch receive
    times) -> diagnose."""
    from motecal.commands.main import main
    bin_, db = tmp_path / "q.bin", tmp_path / "d.db"
    assert main(["sim", "--model", "paper", "--session", "static80", "--seed", "1",
                 "--motes", "1", "--out", str(bin_), "--quiet"]) == 0
    assert main(["log", "--port", str(bin_), "--db", str(db), "--session", "s"]) == 0
    with open_store(str(db)) as st:
        data = st.load_session("s", 1)
    assert not (data.label != 0).any()
    d = diagnose(data, simulate=False)
    assert d.clean, [(f.sensor, f.cause, f.evidence.get("p")) for f in d.findings]
    assert len(d.obs["accel"].segs) == 80


PAIRS = [(("cross_axis", "accel"), ("stale_samples", "mag")),
         (("g_sensitivity", "gyro"), ("nonlinearity", "accel")),
         (("field_disturbance", "mag"), ("motion", "accel"))]


def test_two_effects_at_once_are_both_named():
    """Three pairs, two seeds each: both causes named in at least 5 of the 6
    (the bench measures 97 % over 30 random pairs)."""
    res = []
    for k, pair in enumerate(PAIRS):
        for j in range(2):
            plants, ses, d = _case(list(pair), 50 + 10 * k + j, kind="static80")
            res.append((SEED + 50 + 10 * k + j, pair,
                        all((p.sensor, p.cause) in d.causes() for p in plants),
                        sorted(d.causes())))
    assert sum(r[2] for r in res) >= 5, [r for r in res if not r[2]]


def test_general_model_cross_axis_in_the_simulators_own_order():
    """The simulator's built-in 'general' board (cross-axis before
    scale_offset, paper angles after) is named as cross-axis coupling on
    accelerometer and magnetometer, and nothing else."""
    from motecal.sim import simulate_session
    ses = simulate_session("static80", seed=11, model="general")[1]
    d = diagnose(ses, simulate=False)
    assert d.causes() == {("accel", "cross_axis"), ("mag", "cross_axis")}


def test_extended_model_reproduces_the_measured_statistics(tmp_path):
    """motecal sim --model extended.json: a new session simulated from the
    written model shows the planted behaviour again (the same causes are
    named, relative to the paper model) with statistics close to the
    original's."""
    from motecal.diagnose.compare import distance, session_stats
    keys = [("cross_axis", "accel"), ("stale_samples", "mag")]
    plants, ses, d = _case(keys, 77, kind="static80")
    path = tmp_path / "extended.json"
    path.write_text(json.dumps(d.model))
    model = load_model(str(path))
    again = P.simulate([], "static80", 4242, base=str(path))
    assert model.name.endswith("extended")
    d2 = diagnose(again, simulate=False)
    assert {("accel", "cross_axis"), ("mag", "stale_samples")} <= d2.causes()
    paper = P.simulate([], "static80", 4242)
    s0 = session_stats(ses)
    assert distance(s0, session_stats(again))[0] < 0.5 * distance(s0, session_stats(paper))[0]


@pytest.mark.parametrize("seed", [1, 2])
def test_structure_outside_the_vocabulary_is_unexplained_and_says_where(seed):
    """An effect no term models: the accelerometer's offset hops by 30 mg in
    6 random poses (a knock, a loose screw) and back.  Nothing in the
    vocabulary explains it, so the diagnosis says 'unexplained', adds no term,
    and names the poses it saw as outliers: only planted ones."""
    import dataclasses
    rng = np.random.default_rng([SEED, 300 + seed])
    ses = P.simulate([], "static80", SEED + 300 + seed)
    raw, lab = ses.raw.copy(), ses.label
    bad = rng.choice(np.unique(lab[lab > 0]), 6, replace=False)
    for p in bad:
        v = rng.normal(size=3)
        raw[lab == p, 0:3] += v * (0.030 * 256 / np.linalg.norm(v))
    d = diagnose(dataclasses.replace(ses, raw=raw), simulate=False)
    assert d.causes() == {("accel", "unexplained")}, [(f.sensor, f.cause) for f in d.findings]
    f = d.findings[0]
    assert f.gain == 1.0 and not f.params and "No term added" in f.summary
    assert f.evidence["excess_ratio"] > 10 and f.evidence["p"] < f.evidence["level"]
    text = f.evidence["structure"]
    assert "outlier poses" in text
    named = {int(x) for x in re.findall(r"pose (\d+) at", text)}
    assert len(named) >= 2 and named <= set(bad.tolist()), (named, bad)


def test_what_the_data_cannot_determine_is_not_claimed():
    """A sweep over a cap of the sphere (a third of it) or the field
    directions of six +-axis poses cannot determine a magnetometer model by
    calibrate's own rule: no coupling is claimed, and the note gives the
    gate's reason (the diagnosis used to report couplings of -3.2 and +3.6
    from six poses and 0.09 on a 26 % cap).  A board with real soft iron
    ('general'), two seeds each."""
    from motecal.sessions.session import LABEL_ROT
    for seed in (1, 2):
        rot = P.simulate([], "rotation", SEED + 700 + seed, base="general")
        z = rot.sensor("mag")[:, 2]
        c, r = 0.5 * (z.max() + z.min()), 0.5 * (z.max() - z.min())
        cap = rot.select(z > c + 0.3 * r)
        d = diagnose(cap, simulate=False)
        assert ("mag", "cross_axis") not in d.causes(), d.causes()
        assert any("cover too little of the sphere" in n for n in d.notes), d.notes
        # six +-axis holds, rows between them dropped: poses, not a sweep
        ses = P.simulate([], "static80", SEED + 710 + seed, base="general", n_poses=6)
        d = diagnose(ses.select(ses.label >= 1), simulate=False)
        assert ("mag", "cross_axis") not in d.causes() and \
            ("accel", "cross_axis") not in d.causes(), d.causes()
        assert (cap.label == LABEL_ROT).all()
