"""Simulator sensor side: physical inputs, every error term, chip stage,
model files, truth files, simulate_session and speed."""
import json
import time

import numpy as np
import pytest

from motecal.errors import UserError
from motecal.sessions.session import HMC5883L_OVERFLOW, LABEL_ROT, SessionData
from motecal.sessions.still import segment_still
from motecal.sim import (SimModel, builtin_models, load_model, make_trajectory, simulate_session,
                         write_truth)
from motecal.sim.physics import K_NOMINAL, TERMS
from motecal.sim.trajectory import Trajectory

KA, KG, KM = K_NOMINAL["accel"], K_NOMINAL["gyro"], K_NOMINAL["mag"]
ENV = {"gravity_g": 1.0, "field_gauss": 0.48, "inclination_deg": 60.0, "declination_deg": 0.0}
B_WORLD = 0.48 * np.array([np.cos(np.radians(60)), 0.0, -np.sin(np.radians(60))])


def model_with(accel=(), gyro=(), mag=(), board_terms=(), noise=(0.0, 0.0, 0.0), clock=0.0):
    d = {"format": "motecal-sim-model", "version": 1, "name": "test", "rate_hz": 125.0,
         "environment": ENV,
         "boards": {"1": {"clock_ppm": clock, "terms": list(board_terms),
                          "accel": {"noise": noise[0], "terms": list(accel)},
                          "gyro": {"noise": noise[1], "terms": list(gyro)},
                          "mag": {"noise": noise[2], "terms": list(mag)}}}}
    return SimModel.from_json(d, "test")


def run(model, kind="idle", duration=20.0, seed=0, mote=1):
    traj = make_trajectory(kind, seed, duration=duration)
    board = model.board(mote, seed)
    t = board.sample_times(traj.duration)
    return traj, board, t, board.sampler(traj, seed).read_detail(t)


# --------------------------------------------------------------------------
# physical inputs
# --------------------------------------------------------------------------
def test_still_board_reads_gravity_field_and_gyro_bias():
    bias = [100.0, -50.0, 20.0]
    m = model_with(gyro=[{"term": "linear", "b": bias}], noise=(2.0, 5.0, 2.0))
    traj, board, t, d = run(m, "idle", 30.0)
    n = len(t)
    a, g, mg = (d.counts[:, s].astype(float) for s in (slice(0, 3), slice(3, 6), slice(6, 9)))
    assert np.abs(a.mean(0) - [0, 0, KA]).max() < 5 * 2.0 / np.sqrt(n)   # 1 g on z
    assert np.allclose(a.std(0), 2.0, rtol=0.1)
    assert np.abs(g.mean(0) - bias).max() < 5 * 5.0 / np.sqrt(n)
    assert np.allclose(g.std(0), 5.0, rtol=0.1)
    # Earth field: magnitude, dip (angle to "up" = 90 + 60 deg) and heading
    assert np.linalg.norm(mg.mean(0)) / KM == pytest.approx(0.48, abs=0.001)
    dip = np.degrees(np.arccos(mg.mean(0) @ a.mean(0) / np.linalg.norm(mg.mean(0))
                               / np.linalg.norm(a.mean(0))))
    assert dip == pytest.approx(150.0, abs=0.2)
    assert np.allclose(mg.mean(0), KM * traj.poses[0].T @ B_WORLD, atol=0.2)


def test_every_static_pose_reads_its_gravity_direction():
    m = model_with(noise=(2.0, 5.0, 2.0))
    traj, board, t, d = run(m, "static80", None)
    lab = traj.label_at(t)
    means = np.array([d.counts[lab == k, 0:3].mean(0) for k in range(1, 81)])
    expect = KA * np.array([P[2] for P in traj.poses])
    assert np.abs(means - expect).max() < 1.0


def test_gyro_reads_commanded_rate_when_turning():
    bias = [-80.0, 30.0, 150.0]
    m = model_with(gyro=[{"term": "linear", "b": bias}], noise=(0, 5.0, 0))
    traj, board, t, d = run(m, "rotation", None)
    assert np.all(traj.label_at(t) == LABEL_ROT)
    w = traj.at(t).omega
    resid = d.counts[:, 3:6] - (KG * w + bias)
    assert np.abs(w).max() > 150
    assert np.abs(resid.mean(0)).max() < 0.5 and np.allclose(resid.std(0), 5.0, rtol=0.1)


# --------------------------------------------------------------------------
# terms
# --------------------------------------------------------------------------
def test_scale_offset_is_inverted_exactly_by_the_paper_formula():
    s, o = [1.04, 0.97, 1.01], [12.0, -20.0, 7.5]
    so = {"term": "scale_offset", "s": s, "o": o}
    m = model_with(accel=[so], mag=[so])
    traj, board, t, d = run(m, "static80", 60.0)
    for sl in (slice(0, 3), slice(6, 9)):
        assert np.abs((d.pre_chip[:, sl] + o) * s - d.nominal[:, sl]).max() < 1e-9
        assert np.abs((d.counts[:, sl] + o) * s - d.nominal[:, sl]).max() <= 0.5 * 1.04 + 1e-9


def test_paper_angles_match_paper_equations_and_are_only_scale():
    s, o = [1.02, 0.98, 1.03], [5.0, -3.0, 9.0]
    aZY, aXZ, aYZ = 4.0, -3.0, 6.0
    m = model_with(accel=[{"term": "scale_offset", "s": s, "o": o},
                          {"term": "paper_angles", "aZY": aZY, "aXZ": aXZ, "aYZ": aYZ}])
    traj, board, t, d = run(m, "static80", 40.0)
    Xp, Yp, Zp = d.pre_chip[:, 0:3].T
    c = lambda a: np.cos(np.radians(a))                 # noqa: E731
    X = (Xp + o[0]) * s[0]                               # paper eqs. 1-5
    Y = (Yp * c(aZY) + o[1]) * s[1]
    Z = ((Zp * c(aXZ)) * c(aYZ) + o[2]) * s[2]
    assert np.abs(np.column_stack([X, Y, Z]) - d.nominal[:, 0:3]).max() < 1e-9
    M = np.array(board.physical_truth()["accel"]["M"])
    assert np.count_nonzero(M - np.diag(np.diag(M))) == 0      # diagonal: a scale
    assert M[1, 1] == pytest.approx(1 / (s[1] * c(aZY)))


def test_cross_axis_couples_off_diagonal_only():
    C = [[0.5, 0.0, 0.02], [0.0, 0.5, -0.01], [0.03, 0.0, 0.5]]    # diagonal ignored
    m = model_with(accel=[{"term": "cross_axis", "C": C}])
    traj, board, t, d = run(m, "idle", 5.0)
    assert np.allclose(d.pre_chip[:, 0:3], [0.02 * KA, -0.01 * KA, KA])
    assert np.diag(board.to_json()["accel"]["terms"][0]["C"]).tolist() == [0, 0, 0]
    traj, board, t, d = run(m, "static80", 30.0)
    Cz = np.array(C) - np.diag(np.diag(C))
    assert np.allclose(d.pre_chip[:, 0:3], d.nominal[:, 0:3] @ (np.eye(3) + Cz).T)


def test_linear_term():
    M = [[1.01, 0.02, 0.0], [-0.01, 0.99, 0.03], [0.0, 0.01, 1.02]]
    b = [3.0, -4.0, 5.0]
    m = model_with(mag=[{"term": "linear", "M": M, "b": b}])
    traj, board, t, d = run(m, "rotation", 10.0)
    assert np.allclose(d.pre_chip[:, 6:9], d.nominal[:, 6:9] @ np.array(M).T + b)


def test_nonlinearity_formula_and_asymmetry():
    q, c3, a = [0.01, 0.0, 0.0], [0.0, 0.02, 0.0], [0.0, 0.0, 0.03]
    m = model_with(accel=[{"term": "nonlinearity", "q": q, "c3": c3, "a": a}])
    traj, board, t, d = run(m, "static80", 60.0)
    x = d.nominal[:, 0:3]
    r = x / KA
    exp = (x + KA * (np.array(q) * r ** 2 + np.array(c3) * r ** 3))
    exp = exp * (1 + np.array(a) * np.sign(exp))
    assert np.allclose(d.pre_chip[:, 0:3], exp)
    # asymmetric: at +1 g z reads 3% more, at -1 g 3% less in magnitude
    up = TERMS["nonlinearity"]({"q": np.zeros(3), "c3": np.zeros(3), "a": np.array(a)})
    from types import SimpleNamespace
    out = up.apply(np.array([[0, 0, KA], [0, 0, -KA]]), SimpleNamespace(K=KA))
    assert out[:, 2].tolist() == [KA * 1.03, -KA * 0.97]


def test_bias_drift_curve_and_random_walk():
    m = model_with(gyro=[{"term": "bias_drift", "amplitude": [50, 0, 0], "tau_s": 10,
                          "slope": [0, 1.0, 0], "sigma": [0, 0, 3.0]}])
    traj, board, t, d = run(m, "idle", 60.0)
    drift = d.pre_chip[:, 3:6] - d.nominal[:, 3:6]
    assert np.allclose(drift[:, 0], 50 * (1 - np.exp(-t / 10)))
    assert np.allclose(drift[:, 1], t)
    steps = np.diff(drift[:, 2])
    assert np.std(steps) == pytest.approx(3.0 * np.sqrt(1 / 125.0), rel=0.05)
    assert abs(drift[0, 2]) < 1e-9                    # starts at 0 at t = 0


def test_g_sensitivity_adds_rate_proportional_to_specific_force():
    G = [[0.0, 0.0, 0.5], [0.2, 0.0, 0.0], [0.0, 0.0, 0.0]]
    m = model_with(gyro=[{"term": "g_sensitivity", "G": G}])
    traj, board, t, d = run(m, "static80", 60.0)
    f = d.motion.specific_force
    assert np.allclose(d.pre_chip[:, 3:6] - d.nominal[:, 3:6], KG * f @ np.array(G).T)
    traj, board, t, d = run(m, "idle", 2.0)            # z up: 0.5 deg/s on gx
    assert np.allclose(d.pre_chip[:, 3:6], [0.5 * KG, 0, 0])
    assert board.physical_truth()["gyro"]["G"] == G


def test_saturation_clip_and_overflow_code():
    m = model_with(accel=[{"term": "saturation", "low": -100, "high": 100}],
                   gyro=[{"term": "saturation", "low": -200, "high": 200,
                          "overflow_code": -999}], noise=(3.0, 3.0, 0.0))
    traj, board, t, d = run(m, "static80", 40.0)
    nom = d.nominal
    clip_a = np.abs(nom[:, 0:3]) > 100 + 5 * 3.0
    assert clip_a.any() and (~clip_a).any()
    assert np.all(d.counts[:, 0:3][clip_a] == np.sign(nom[:, 0:3][clip_a]) * 100)
    inside = np.abs(nom[:, 0:3]) < 90
    assert (d.counts[:, 0:3][inside] - nom[:, 0:3][inside]).std() == pytest.approx(3, rel=0.1)
    assert np.abs(d.counts[:, 0:3]).max() == 100                # noise never passes a limit
    over_g = (np.abs(nom[:, 3:6]) > 215).any(axis=1)
    under_g = (np.abs(nom[:, 3:6]) < 185).all(axis=1)
    assert over_g.any() and np.all(d.counts[over_g, 3:6] == -999)
    assert under_g.any() and not np.any(d.counts[under_g, 3:6] == -999)


def test_chip_stage_ranges_and_hmc5883l_overflow():
    m = model_with(accel=[{"term": "linear", "M": [[20, 0, 0], [0, 20, 0], [0, 0, 20]]}],
                   gyro=[{"term": "linear", "b": [40000, -40000, 0]}],
                   mag=[{"term": "linear", "b": [1900, 0, 0]}])
    traj, board, t, d = run(m, "static80", 60.0)
    c = d.counts
    assert c.dtype == np.int16
    assert c[:, 0:3].max() == 4095 and c[:, 0:3].min() == -4096      # ADXL345 +-16 g
    assert np.all(c[:, 3] == 32767) and np.all(c[:, 4] == -32768)     # ITG3200 int16
    over = (np.rint(d.pre_chip[:, 6:9]) > 2047).any(axis=1)
    assert over.any() and (~over).any()
    assert np.all(c[over, 6:9] == HMC5883L_OVERFLOW)                 # all three axes
    assert np.all(np.abs(c[~over, 6:9]) <= 2048)


def test_stale_samples_repeat_at_update_rate():
    m = model_with(mag=[{"term": "stale_samples", "update_hz": 75, "phase_s": 0.004}],
                   noise=(2.0, 0, 2.0))
    traj, board, t, d = run(m, "rotation", 20.0)
    changes_m = np.count_nonzero(np.any(np.diff(d.counts[:, 6:9], axis=0) != 0, axis=1))
    changes_a = np.count_nonzero(np.any(np.diff(d.counts[:, 0:3], axis=0) != 0, axis=1))
    assert changes_m / 20.0 == pytest.approx(75, abs=1)
    assert changes_a / 20.0 == pytest.approx(125, abs=2)
    # the held value is the field at the last update instant
    ts = 0.004 + np.floor((t - 0.004) * 75) / 75
    expect = KM * np.einsum("nji,j->ni", traj.at(ts).R, B_WORLD)
    assert np.abs(d.pre_chip[:, 6:9] - expect).max() < 10        # noise only (sd 2)
    assert np.abs(d.nominal[:, 6:9] - expect).max() < 1e-9


def test_motion_tremor_shakes_all_sensors_consistently():
    m = model_with(board_terms=[{"term": "motion", "rms_deg": 0.3, "bandwidth_hz": 3.0}])
    traj, board, t, d = run(m, "idle", 60.0)
    tilt = np.degrees(d.pre_chip[:, 0:2] / KA)                   # small angles, z up
    assert np.allclose(tilt.std(0), 0.3, rtol=0.3)
    assert d.pre_chip[:, 3:6].std(0).min() > 0.5 * KG           # deg/s of shaking
    assert d.pre_chip[:, 6:9].std(0).min() > 0.5                # the field moves too
    assert np.all(traj.label_at(t) == 1)                          # still labelled a pose
    # the board's rate is the derivative of its orientation
    smp = board.sampler(traj, 0)
    tt = np.linspace(5, 50, 400)
    h = 1e-5
    Rm, Rp = smp._motion(tt - h).R, smp._motion(tt + h).R
    from scipy.spatial.transform import Rotation
    num = np.degrees(Rotation.from_matrix(np.einsum("nji,njk->nik", Rm, Rp)).as_rotvec()
                     / (2 * h))
    assert np.abs(num - smp._motion(tt).omega).max() < 0.02 * np.abs(num).max()


def test_field_disturbance_per_pose_and_wander():
    m = model_with(mag=[{"term": "field_disturbance", "pose_rms_gauss": 0.01,
                         "rms_gauss": 0.0}])
    traj, board, t, d = run(m, "static80", None)
    lab = traj.label_at(t)
    world = np.einsum("nij,nj->ni", d.motion.R, d.pre_chip[:, 6:9] / KM) - B_WORLD
    per_pose = np.array([world[lab == k].mean(0) for k in range(1, 81)])
    within = max(world[lab == k].std(0).max() for k in range(1, 81))
    assert within < 1e-9 and per_pose.std() == pytest.approx(0.01, rel=0.2)
    m = model_with(mag=[{"term": "field_disturbance", "rms_gauss": 0.005, "tau_s": 2.0}])
    traj, board, t, d = run(m, "idle", 300.0)
    world = np.einsum("nij,nj->ni", d.motion.R, d.pre_chip[:, 6:9] / KM) - B_WORLD
    assert world.std(0).mean() == pytest.approx(0.005, rel=0.4)
    step = np.abs(np.diff(world, axis=0)).max()
    assert step < 0.001                                           # slow, smooth


def test_read_does_not_depend_on_block_split():
    model = load_model("full")
    d = model.to_json()
    d["boards"] = {"2": dict(d["defaults"])}
    d["boards"]["2"]["mag"] = dict(d["boards"]["2"]["mag"])
    d["boards"]["2"]["mag"]["terms"] = d["boards"]["2"]["mag"]["terms"] + [
        {"term": "saturation", "low": -400, "high": 400, "overflow_code": -4096}]
    model = SimModel.from_json(d)
    traj = make_trajectory("static80", 4, duration=40.0)
    board = model.board(2, 4)
    t = board.sample_times(traj.duration)
    whole = board.sampler(traj, 4).read(t)
    smp = board.sampler(traj, 4)
    rng = np.random.default_rng(0)
    cuts = np.sort(rng.choice(len(t), 60, replace=False))
    parts = [smp.read(b) for b in np.split(t, cuts)] + [smp.read(np.array([]))]
    assert np.array_equal(np.concatenate(parts), whole)
    assert (whole[:, 6] == -4096).any()
    with pytest.raises(ValueError):
        smp.read(t[:5])                                     # time went back
    other = model.board(2, 4).sampler(traj, 5).read(t)        # another seed: other noise
    assert not np.array_equal(other, whole)


def test_clock_ppm_sets_sample_times():
    m = model_with(clock=50.0)
    b = m.board(1, 0)
    t = b.sample_times(100.0)
    assert b.clock_ppm == 50.0
    assert np.diff(t).mean() == pytest.approx(1 / (125 * (1 + 50e-6)), rel=1e-12)
    assert len(t) == int(np.ceil(100 * 125 * (1 + 50e-6)))


# --------------------------------------------------------------------------
# model files
# --------------------------------------------------------------------------
BAD_MODELS = [
    ("{not json", "invalid JSON"),
    ('{"format": "x", "version": 1}', "format"),
    ('{"format": "motecal-sim-model", "version": 2, "defaults": {}}', "version"),
    ('{"format": "motecal-sim-model", "version": 1}', "defaults"),
    ('{"format": "motecal-sim-model", "version": 1, "defaults": {"accel": {"terms": '
     '[{"term": "scale"}]}}}', "unknown term"),
    ('{"format": "motecal-sim-model", "version": 1, "defaults": {"accel": {"terms": '
     '[{"term": "scale_offset", "k": 1}]}}}', "unknown parameter 'k'"),
    ('{"format": "motecal-sim-model", "version": 1, "defaults": {"accel": {"terms": '
     '[{"term": "scale_offset", "s": [1, 2]}]}}}', "3 elements"),
    ('{"format": "motecal-sim-model", "version": 1, "defaults": {"accel": {"terms": '
     '[{"term": "scale_offset", "s": 0}]}}}', "must be > 0"),
    ('{"format": "motecal-sim-model", "version": 1, "defaults": {"accel": {"noise": '
     '{"uniform": [3, 1]}}}}', "lo <= hi"),
    ('{"format": "motecal-sim-model", "version": 1, "defaults": {"accel": {"terms": '
     '[{"term": "g_sensitivity"}]}}}', "gyro only"),
    ('{"format": "motecal-sim-model", "version": 1, "defaults": {"mag": {"terms": '
     '[{"term": "motion"}]}}}', "board-level"),
    ('{"format": "motecal-sim-model", "version": 1, "defaults": {"mag": {"terms": '
     '[{"term": "stale_samples"}]}}}', "missing parameter 'update_hz'"),
    ('{"format": "motecal-sim-model", "version": 1, "boards": {"x": {}}}', "not a mote id"),
    ('{"format": "motecal-sim-model", "version": 1, "defaults": {"acel": {}}}',
     "unknown key 'acel'"),
    ('{"format": "motecal-sim-model", "version": 1, "environment": {"field_gauss": "a"}, '
     '"defaults": {}}', "environment.field_gauss"),
    ('[1, 2]', "JSON object"),
    ('{"format": "motecal-sim-model", "version": 1, "defaults": {"clock_ppm": 1e9}}',
     "defaults.clock_ppm: must be within +-1000 ppm"),
    ('{"format": "motecal-sim-model", "version": 1, "boards": {"2": {"clock_ppm": '
     '{"uniform": [0, 5000]}}}}', "boards.2.clock_ppm: must be within +-1000 ppm"),
]


@pytest.mark.parametrize("text,needle", BAD_MODELS)
def test_bad_model_file_gives_one_line_user_error(tmp_path, text, needle):
    p = tmp_path / "m.json"
    p.write_text(text)
    with pytest.raises(UserError) as e:
        load_model(str(p))
    msg = str(e.value)
    assert needle in msg and "\n" not in msg and str(p) in msg


def test_a_drawn_clock_error_beyond_the_range_is_refused():
    with pytest.raises(UserError, match=r"clock_ppm: must be within \+-1000 ppm"):
        load_model("general").with_boards({4: {"clock_ppm": {"normal": [0, 1e6]}}}).board(4, 0)


def test_missing_and_unreadable_model(tmp_path):
    for arg in (str(tmp_path / "nope.json"), "no_such_model"):
        with pytest.raises(UserError) as e:
            load_model(arg)
        assert "no such file" in str(e.value) and "general" in str(e.value)
    bad = tmp_path / "bin.json"
    bad.write_bytes(b"\xff\xfe\x00")
    with pytest.raises(UserError) as e:
        load_model(str(bad))
    assert "\n" not in str(e.value)


def test_builtin_models_and_drawn_boards():
    assert {"paper", "general", "full"} <= set(builtin_models())
    assert load_model(None).name == "general"
    g = load_model("general")
    a, b, c = g.board(3, 9), g.board(3, 9), g.board(4, 9)
    assert a.to_json() == b.to_json() and a.to_json() != c.to_json()
    assert g.board(3, 10).to_json() != a.to_json()
    boards = [g.board(m, 1) for m in range(1, 31)]
    def term(bd, s, tid):
        return next(t for t in bd.sensors[s].terms if t.id == tid).p
    o_a = np.array([term(bd, "accel", "scale_offset")["o"] for bd in boards])
    s_a = np.array([term(bd, "accel", "scale_offset")["s"] for bd in boards])
    o_g = np.array([term(bd, "gyro", "scale_offset")["o"] for bd in boards]) / KG
    o_m = np.array([term(bd, "mag", "scale_offset")["o"] for bd in boards])
    C_m = np.array([term(bd, "mag", "cross_axis")["C"] for bd in boards])
    C_a = np.array([term(bd, "accel", "cross_axis")["C"] for bd in boards])
    assert 0.05 < np.abs(o_a).max() / KA <= 0.1 and np.abs(s_a - 1).max() <= 0.05
    assert 10 < np.abs(o_g).max() <= 15 and 60 < np.abs(o_m).max() <= 100
    off = ~np.eye(3, dtype=bool)
    assert C_a[:, off].std() == pytest.approx(0.01, rel=0.3)
    assert C_m[:, off].std() == pytest.approx(0.025, rel=0.3)
    noise = np.array([bd.sensors["gyro"].noise for bd in boards])
    assert noise.min() >= 4.5 and noise.max() <= 5.5
    paper = load_model("paper").board(1, 0)
    assert [t.id for s in ("accel", "gyro", "mag") for t in paper.sensors[s].terms] == \
        ["scale_offset", "linear", "scale_offset"]
    # an explicit board overrides the defaults for that mote only
    m = g.with_boards({7: {"clock_ppm": 1.5, "accel": {"noise": 1.0}}})
    assert m.board(7, 0).clock_ppm == 1.5 and m.board(7, 0).sensors["gyro"].terms == []
    assert m.board(8, 0).to_json() == g.board(8, 0).to_json()


@pytest.mark.parametrize("name", ["general", "full"])
def test_physical_truth_is_the_affine_map(name):
    board = load_model(name).board(2, 5)
    for s in board.sensors.values():
        s.noise[:] = 0.0
    traj = make_trajectory("static80", 5, duration=30.0)
    d = board.sampler(traj, 5).read_detail(board.sample_times(traj.duration))
    truth = board.physical_truth()
    for s, sl in (("accel", slice(0, 3)), ("gyro", slice(3, 6)), ("mag", slice(6, 9))):
        M, b = np.array(truth[s]["M"]), np.array(truth[s]["b"])
        pred = d.nominal[:, sl] @ M.T + b
        if s == "gyro":
            pred += KG * d.motion.specific_force @ np.array(truth[s]["G"]).T
        err = np.abs(pred - d.pre_chip[:, sl]).max()
        if truth[s]["exact"]:
            assert err < 1e-8, s
        else:
            assert name == "full" and truth[s]["nonaffine"] and err > 1e-3


def test_truth_file_is_a_model_that_reproduces_the_boards(tmp_path):
    model = load_model("general")
    traj = make_trajectory("static80", 12, duration=30.0)
    boards = {m: model.board(m, 12) for m in (1, 2, 5)}
    path = tmp_path / "truth.json"
    written = write_truth(path, model, boards, traj, 12)
    assert json.loads(path.read_text()) == written
    again = load_model(str(path))
    for m, b in boards.items():
        b2 = again.board(m, 999)                      # explicit now: seed does not matter
        assert b2.to_json() == b.to_json()
        t = b.sample_times(traj.duration)
        assert np.array_equal(b.sampler(traj, 12).read(t), b2.sampler(traj, 12).read(t))
    traj2 = Trajectory.from_json(written["truth"]["trajectory"])
    assert np.array_equal(traj2.at([3.0, 17.2]).R, traj.at([3.0, 17.2]).R)
    assert written["truth"]["physical_truth"]["5"] == boards[5].physical_truth()
    assert again.board(9, 12).to_json() == model.board(9, 12).to_json()   # defaults kept


# --------------------------------------------------------------------------
# simulate_session and speed
# --------------------------------------------------------------------------
def test_simulate_session_and_speed():
    t0 = time.perf_counter()
    ses = simulate_session("static80", motes=(1, 2, 3), seed=21)
    wall = time.perf_counter() - t0
    sim_minutes = sum(s.t[-1] for s in ses.values()) / 60.0
    print(f"\nstatic80 3 motes x {ses[1].t[-1]:.0f} s: {wall:.2f} s wall, "
          f"{wall / sim_minutes:.3f} s per simulated mote-minute, "
          f"{sim_minutes * 60 / wall:.0f}x real time")
    assert wall / (sim_minutes / 3) < 1.0           # < 1 s per simulated (session) minute
    s1 = ses[1]
    assert isinstance(s1, SessionData) and s1.kind == "static80" and s1.motes == [1]
    assert s1.poses() == list(range(1, 81))
    assert np.array_equal(s1.seq, np.arange(len(s1)))
    assert np.all(s1.flags == 0) and np.all(s1.raw == np.rint(s1.raw))
    ppm = s1.meta["truth"]["clock_ppm"]
    assert np.diff(s1.t).mean() == pytest.approx(1 / (125 * (1 + ppm * 1e-6)), rel=1e-9)
    assert s1.meta["truth"] == load_model("general").board(1, 21).to_json()
    assert not np.array_equal(ses[1].raw[:1000], ses[2].raw[:1000])
    json.dumps(s1.meta)
    # a logger's stillness detection finds the 80 poses, each long enough for 200 samples
    seg = segment_still(s1.raw, 125.0)
    lens = np.bincount(seg)[1:]
    assert len(lens) == 80 and lens.min() >= 200 + 62
    # the poses' raw accelerometer magnitudes spread like the paper's "before"
    a = np.array([s1.physical("accel")[s1.label == k].mean(0) for k in s1.poses()])
    mag = np.linalg.norm(a, axis=1)
    assert 0.8 < mag.min() < 0.97 and 1.03 < mag.max() < 1.2


@pytest.mark.parametrize("kind", ["rotation", "idle", "free"])
def test_simulate_other_kinds(kind):
    ses = simulate_session(kind, motes=(4,), seed=2, model="paper", duration=12.0)
    s = ses[4]
    assert s.kind == kind and abs(s.t[-1] - 12.0) < 0.02
    assert s.meta["model"] == "paper"
    if kind == "rotation":
        assert np.all(s.label == LABEL_ROT)


def test_model_doc_documents_every_term_and_parameter():
    from pathlib import Path
    doc = (Path(__file__).resolve().parent.parent / "docs" / "simulator-model.md").read_text()
    for tid, cls in TERMS.items():
        assert f"`{tid}`" in doc, tid
        for prm in cls.params:
            assert f"`{prm.name}`" in doc, (tid, prm.name)
    for name in builtin_models():
        assert f"`{name}`" in doc, name
