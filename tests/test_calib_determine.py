"""What a session's data determine, judged once (``calib.determine``, owned by
``calib.content``) and used by calibrate (the model it fits, or none), its
gate, the adaptive planner and the diagnosis (issues 30, 31)."""
import time

import numpy as np
import pytest

from motecal.calib import design, gate
from motecal.calib.board import bounded_rows, calibrate_board, MAX_POSE_SAMPLES
from motecal.calib.content import judge_poses, judge_sweep, pose_means
from motecal.maths.sphere import fibonacci_sphere
from motecal.sessions.session import LABEL_NONE, LABEL_ROT
from synthetic import paper_sized_session

FACES = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
TETRA = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]]) / np.sqrt(3)


@pytest.fixture(scope="module")
def session():
    return paper_sized_session(1)         # 80 x 200 static + 5000 rotation, 'general'


@pytest.mark.parametrize("sensor,off,H", [("accel", [0.02, -0.03, 0.01], 1.0),
                                          ("mag", [0.1, 0.2, -0.15], 0.5)])
def test_the_ladder_of_models(sensor, off, H):
    """Full from 9+ orientations spread over the sphere, offsets + scales from
    the six faces, offsets alone from 4 around it, nothing from fewer or from
    poses on one side; the magnetometer's directions are taken from the
    centre of its best-fitting sphere (hard iron)."""
    cases = {"full": np.vstack([FACES, np.array([[1, 1, 0], [1, 0, 1], [0, 1, 1]]) / np.sqrt(2)]),
             "offsets+scales": FACES, "offsets": TETRA, None: FACES[:5]}
    for want, dirs in cases.items():
        j = judge_poses(sensor, dirs * H + off)
        assert j.model == want, (want, j)
    assert judge_poses(sensor, fibonacci_sphere(80) * H + off).model == "full"
    one = judge_poses(sensor, FACES[:1] * H + off)
    assert one.model is None and "too few distinct orientations: 1" in one.why_not()
    # 12 orientations all in one hemisphere: more than enough, but clustered
    cap = fibonacci_sphere(40)[:12]
    j = judge_poses(sensor, cap * H + off)
    assert j.model is None and j.orientations >= 9 and "too clustered" in j.why_not()
    # the six faces say what more poses would add
    assert judge_poses(sensor, FACES * H + off).text() == (
        "offsets and scales from 6 faces; cross-axis terms need at least 9 orientations spread "
        "over the sphere: add poses to fit them")


def test_nine_orientations_on_one_quadric_do_not_determine_the_full_model():
    """Nine distinct orientations around the origin that all have x*y = 0
    (on the planes x = 0 or y = 0): the full model's cross term between x
    and y has no column in its Jacobian, so offsets + scales."""
    a = np.deg2rad(30)
    ring = [[np.cos(a), 0, np.sin(a)], [0, np.cos(a), np.sin(a)], [-np.cos(a), 0, np.sin(a)]]
    dirs = np.vstack([FACES, ring])
    j = judge_poses("accel", dirs)
    assert j.orientations == 9 and j.hull_depth >= 0.3
    assert j.model == "offsets+scales" and "rank-deficient" in j.reasons["full"][0]


def test_a_hold_is_not_a_sweep():
    """A still hold's readings are a ball of noise: the sphere fitted to it
    surrounds nothing; a sweep's sphere is many times its noise."""
    rng = np.random.default_rng(3)
    hold = np.array([0.2, -0.1, 0.4]) + rng.normal(0, 0.002, (20000, 3))
    j = judge_sweep("mag", hold)
    assert j.model is None and j.reasons["full"][0].startswith("the readings do not turn")
    t = np.linspace(0, 1, 4000)                      # a spiral from pole to pole
    th, ph = np.pi * t, 40 * np.pi * t
    u = np.column_stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)])
    sweep = 0.5 * u + [0.1, 0.2, -0.15] + rng.normal(0, 0.002, (4000, 3))
    assert judge_sweep("mag", sweep).model == "full"
    assert judge_sweep("mag", sweep[::8]).model == "full"     # fast: 45 deg between readings


def test_calibrate_fits_what_the_data_determine(session):
    """No --model: the 80 poses get the full model (the benches' sessions,
    unchanged: the same fit as --model full, bit for bit), six poses near the
    faces offsets + scales (the gate accepts them), and the choice is in
    cal.json; --model still forces one, judged by the gate."""
    d = session.select(session.label >= 1)
    auto = calibrate_board(d, seed=2, kfold=0, gyro_matrix=False)
    full = calibrate_board(d, model="full", seed=2, kfold=0, gyro_matrix=False)
    assert auto.accel.model == "full" and np.array_equal(auto.accel.A, full.accel.A)
    assert auto.settings["model"] == "auto" and full.settings["model"] == "full"
    assert auto.settings["models"]["accel"]["determined"] == "full"
    assert auto.accel.notes[0].startswith("offsets, scales and cross-axis terms from 80 distinct")
    labs, means = pose_means(d, "accel")
    dirs = means / np.linalg.norm(means, axis=1, keepdims=True)
    faces = [int(labs[np.argmax(dirs @ f)]) for f in FACES]
    six = d.select(np.isin(d.label, faces))
    b = calibrate_board(six, seed=2, kfold=0, gyro_matrix=False)
    dec = gate.decide(b)
    assert b.accel.model == "paper(offsets+scales)" and dec.accepted, dec.reasons
    assert b.accel.quality["orientations_needed"] == 6
    assert b.to_json()["settings"]["models"]["accel"]["why"].startswith("offsets and scales from 6")
    forced = calibrate_board(six, model="full", seed=2, kfold=0, gyro_matrix=False)
    assert any("too few distinct orientations: 6 (at least 9 for full" in r
               for r in gate.decide(forced).reasons)


def test_a_long_hold_is_judged_before_any_fit():
    """An unlabelled still hold (a logged idle session): its still stretch
    gives the gyroscope bias; the accelerometer and the magnetometer are not
    fitted at all -- the magnetometer's readings used to be taken for a
    sweep around the centre of their own noise and fitted for minutes."""
    from motecal.sim import simulate_session
    d = simulate_session("idle", seed=1, duration=120)[1]
    d.label[:] = LABEL_NONE                       # as logged: no labels
    t0 = time.process_time()
    b = calibrate_board(d, seed=1)
    took = time.process_time() - t0
    dec = gate.decide(b)
    assert dec.accepted and b.gyro is not None and b.accel is None and b.mag is None, dec
    assert b.settings["poses_found"].startswith("a hold found in the data: 1 still stretch")
    assert b.settings["skipped"]["accel"].startswith("a still hold in one orientation")
    assert "the readings do not turn" not in b.settings["skipped"]["mag"]     # no R set
    assert took < 20, took          # generous: minutes before (not a timing test)


def test_a_hold_in_a_few_orientations_is_skipped_not_refused(session):
    """An unlabelled recording whose still stretches cover three orientations
    is a hold (for the gyroscope), not poses meant for the accelerometer:
    skipped with what they determine, not refused; labelled, the same three
    poses refuse it."""
    rows = np.flatnonzero(np.isin(session.label, [1, 2, 3]))
    part = session.select(np.arange(rows[0], rows[-1] + 1))
    b = calibrate_board(part, seed=1, kfold=0, gyro_matrix=False)
    assert b.accel is None and "accel" in b.settings["insufficient"]
    part.label[:] = LABEL_NONE
    b = calibrate_board(part, seed=1, kfold=0, gyro_matrix=False)
    dec = gate.decide(b)
    assert b.settings["poses_found"].startswith("a hold found in the data")
    assert b.settings["skipped"]["accel"].startswith("a hold in the data: nothing determined "
                                                     "from 3 distinct orientations")
    assert dec.accepted and b.gyro is not None and b.accel is None, dec


def test_bounded_sample_per_pose():
    """At most MAX_POSE_SAMPLES of a pose, evenly spaced, whatever the hold;
    nothing left out below it."""
    lab = np.repeat([1, 2, 3], [50, 5000, 999])
    keep = bounded_rows(lab, len(lab))
    n = np.bincount(lab[keep])
    assert n[1] == 50 and n[2] == MAX_POSE_SAMPLES and n[3] == 999
    gaps = np.diff(keep[lab[keep] == 2])
    assert gaps.max() - gaps.min() <= 1
    assert bounded_rows(np.repeat([1, 2], 200), 400) is None
    assert bounded_rows(None, 5000) is None and len(bounded_rows(None, 10 ** 6)) == 20000


def test_planner_and_diagnosis_ask_the_same_judgement(session):
    """The adaptive planner predicts the full model's error only where the
    poses determine it; the diagnosis tests magnitude terms (``poses``) only
    there, and takes magnetometer readings for a sweep by the same rule."""
    from motecal.diagnose.prepare import all_obs as observe
    from motecal.diagnose.regimes import regime
    d = session.select(session.label >= 1)
    st = design.pose_stats(d.raw, d.label)
    assert design.design_sensor("accel", st, d.scales["accel"]) is not None
    up = [i for i in range(len(st)) if st.mean[i, 2] > 0.3 * 256]     # one hemisphere
    assert len(up) >= design.MIN_POSES
    assert not judge_poses("accel", st.mean[up, :3] / 256).determines("full")
    dsg = design.design_sensor("accel", st.take(up), d.scales["accel"])
    assert dsg is not None and not dsg.determined            # fitted, for the next pose ...
    a = design.assess(st.take(up), d.scales)
    assert a.bounds["accel"] is None and not a.met["accel"]  # ... but no promise
    assert a.next_up is not None
    obs = observe(session.select(np.isin(session.label, [st.labels[i] for i in up] + [LABEL_ROT])))
    assert regime(obs["accel"]) == "single"
    obs = observe(session)
    assert regime(obs["accel"]) == "poses" and regime(obs["mag"]) in ("poses", "sweep")
