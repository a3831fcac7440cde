"""Simulator trajectories: poses, coverage, kinematic consistency, JSON."""
import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from motecal.errors import UserError
from motecal.sessions.session import LABEL_NONE, LABEL_ROT
from motecal.sim.trajectory import (STANDARD_G, Trajectory, make_trajectory)

RATE = 125.0
FIELD = np.array([np.cos(np.radians(60)), 0.0, -np.sin(np.radians(60))])


def sphere_cells(v):
    """Index of 100 equal-area cells (10 bands equal in z x 10 sectors)."""
    v = v / np.linalg.norm(v, axis=1, keepdims=True)
    zb = np.clip(((v[:, 2] + 1) / 2 * 10).astype(int), 0, 9)
    lb = np.clip(((np.arctan2(v[:, 1], v[:, 0]) + np.pi) / (2 * np.pi) * 10).astype(int), 0, 9)
    return set(zip(zb.tolist(), lb.tolist()))


def omega_from_R(traj, t, h=1e-5):
    """Body rate (deg/s) from a central difference of R: R^T dR/dt = [w]x."""
    Rm, R0, Rp = traj.at(t - h).R, traj.at(t).R, traj.at(t + h).R
    dRel = np.einsum("nji,njk->nik", Rm, Rp)              # R(t-h)^T R(t+h)
    return np.degrees(Rotation.from_matrix(dRel).as_rotvec() / (2 * h)), R0


@pytest.mark.parametrize("seed", [0, 7])
def test_static80_poses_spread_and_still(seed):
    tr = make_trajectory("static80", seed)
    assert len(tr.poses) == 80
    t = np.arange(int(tr.duration * RATE)) / RATE
    m = tr.at(t)
    counts = np.bincount(m.label, minlength=81)
    assert counts[1:].min() >= 200 + int(0.5 * RATE) + 25     # 0.5 s settle + 200 + margin
    assert set(np.unique(m.label)) == set(range(0, 81))
    # labelled samples are truly still, at the listed pose
    for k in (1, 40, 80):
        sel = m.label == k
        assert np.abs(m.omega[sel]).max() == 0.0
        assert np.allclose(m.R[sel], tr.poses[k - 1])
        assert np.allclose(m.specific_force[sel], tr.poses[k - 1][2])   # R^T e_z
    # gravity directions pairwise >= 15 deg apart
    ups = np.array([P[2] for P in tr.poses])
    cosang = ups @ ups.T - 2 * np.eye(80)
    assert np.degrees(np.arccos(cosang.max())) > 15.0
    # and they cover the sphere: every octant holds about 10 of them
    octant = (ups > 0) @ np.array([1, 2, 4])
    assert np.bincount(octant, minlength=8).min() >= 5
    # moves of 1-1.5 s at realistic rates; total length ~ 5 minutes
    moving = np.diff(np.flatnonzero(np.diff(np.r_[0, m.label == 0, 0])))[::2] / RATE
    assert moving.min() >= 0.99 and moving.max() <= 1.51
    rate = np.linalg.norm(m.omega, axis=1)
    assert 100 < rate.max() < 300
    assert 250 < tr.duration < 350


def test_rotation_covers_sphere_and_is_labelled():
    for seed in (0, 1, 2, 3):
        tr = make_trajectory("rotation", seed)
        assert tr.duration == pytest.approx(5000 / RATE)
        t = np.arange(5000) / RATE
        m = tr.at(t)
        assert np.all(m.label == LABEL_ROT)
        up = m.specific_force                         # gravity (and a little lever arm)
        field = np.einsum("nji,j->ni", m.R, FIELD)
        assert len(sphere_cells(up)) >= 90, seed
        assert len(sphere_cells(field)) >= 90, seed
        rate = np.linalg.norm(m.omega, axis=1)
        assert rate.min() > 20 and rate.max() < 350       # continuous, hand-made turning
    assert tr.at([tr.duration + 1.0]).label[0] == LABEL_NONE


@pytest.mark.parametrize("kind", ["static80", "rotation", "free"])
def test_omega_agrees_with_numeric_derivative_of_R(kind):
    tr = make_trajectory(kind, 3)
    rng = np.random.default_rng(1)
    t = np.sort(rng.uniform(0.01, tr.duration - 0.01, 3000))
    if kind == "static80":
        t = t[tr.label_at(t) == 0]                     # during moves
        assert len(t) > 500
    num, _ = omega_from_R(tr, t)
    w = tr.at(t).omega
    assert np.abs(w).max() > 50
    assert np.abs(num - w).max() < 1e-3 * np.abs(w).max() + 1e-3


def test_specific_force_is_gravity_plus_lever_arm_acceleration():
    tr = make_trajectory("rotation", 5)
    t = np.linspace(1, 30, 400)
    h = 1e-4
    r = tr.lever_m
    pos = [np.einsum("nij,j->ni", tr.at(t + d).R, r) for d in (-h, 0, h)]
    acc_world = (pos[0] - 2 * pos[1] + pos[2]) / h ** 2 / STANDARD_G
    m = tr.at(t)
    expect = np.einsum("nji,nj->ni", m.R, acc_world + [0, 0, 1])
    assert np.abs(m.specific_force - expect).max() < 1e-4
    lin = np.linalg.norm(m.specific_force, axis=1) - 1.0
    assert 0.005 < np.abs(lin).max() < 0.15           # noticeable but small


def test_nonuniform_unsorted_times_and_clamping():
    tr = make_trajectory("static80", 2)
    rng = np.random.default_rng(0)
    t = rng.uniform(-1, tr.duration + 1, 500)
    m = tr.at(t)
    for i in (0, 17, 499):
        one = tr.at(t[i])
        assert np.allclose(one.R[0], m.R[i]) and np.allclose(one.omega[0], m.omega[i])
        assert one.label[0] == m.label[i]
    out = (t < 0) | (t > tr.duration)
    assert np.all(m.omega[out] == 0)
    assert np.allclose(tr.at([-5.0]).R[0], tr.poses[0])


def test_idle_free_and_duration():
    idle = make_trajectory("idle", 4)
    assert idle.duration == 60.0 and len(idle.poses) == 1
    m = idle.at(np.arange(0, 60, 0.5))
    assert np.all(m.label == 1) and np.all(m.omega == 0)
    assert np.allclose(m.specific_force, [0, 0, 1])          # flat, z up
    assert make_trajectory("idle", 4, duration=10).duration == 10
    free = make_trajectory("free", 4, duration=20)
    mf = free.at(np.arange(0, 20, 0.01))
    assert free.duration == 20 and np.all(mf.label == 0)
    assert np.linalg.norm(mf.omega, axis=1).mean() > 10
    short = make_trajectory("static80", 4, duration=50)
    lab = short.label_at(np.arange(0, 60, 1 / RATE))
    assert short.duration == 50 and 10 < lab.max() < 20          # truncated after ~14 poses
    assert np.all(short.at([50.5, 55.0]).omega == 0)
    assert make_trajectory("static80", 4, n_poses=10, still_s=3.0).n_poses == 10
    with pytest.raises(UserError):
        make_trajectory("spin", 0)


@pytest.mark.parametrize("kind", ["static80", "rotation"])
def test_json_round_trip_is_exact(kind):
    tr = make_trajectory(kind, 11)
    d = json.loads(json.dumps(tr.to_json()))
    tr2 = Trajectory.from_json(d)
    t = np.linspace(0, tr.duration, 2000)
    a, b = tr.at(t), tr2.at(t)
    assert np.array_equal(a.R, b.R) and np.array_equal(a.omega, b.omega)
    assert np.array_equal(a.label, b.label)
    assert [p.tolist() for p in tr.poses] == [p.tolist() for p in tr2.poses]
    with pytest.raises(UserError):
        Trajectory.from_json({"format": "nope"})


def test_deterministic_in_seed():
    a, b, c = (make_trajectory("static80", s) for s in (5, 5, 6))
    assert np.array_equal(a.poses, b.poses)
    assert not np.allclose(a.poses[1], c.poses[1])


def test_sequence_runs_its_parts_one_after_the_other():
    first, second = make_trajectory("static80", 3), make_trajectory("static80", 4)
    seq = make_trajectory("static80,static80", 3)
    assert seq.n_poses == 160 and seq.start[0] == 0.0
    assert seq.start[1] - first.duration == pytest.approx(seq.moves[0][1])      # one move
    assert seq.duration == pytest.approx(seq.start[1] + second.duration)
    t1 = np.arange(0, first.duration, 1 / RATE)
    a, s = first.at(t1), seq.at(t1)
    assert np.array_equal(a.R, s.R) and np.array_equal(a.label, s.label)        # part 1 as is
    t2 = np.arange(0, second.duration, 1 / RATE)
    b, s = second.at(t2), seq.at(seq.start[1] + t2)
    assert np.allclose(b.R, s.R) and np.allclose(b.omega, s.omega)
    assert np.array_equal(s.label, np.where(b.label > 0, b.label + 80, 0))      # 81..160
    # the move between them is smooth: omega from R, no jumps, label 0
    tm = np.linspace(first.duration, seq.start[1], 200)[1:-1]
    w, _ = omega_from_R(seq, tm)
    assert np.abs(w - seq.at(tm).omega).max() < 0.05
    assert np.all(seq.label_at(tm) == 0)
    m = seq.at([seq.duration + 1.0])
    assert np.all(m.omega == 0) and m.label[0] == 160
    back = Trajectory.from_json(json.loads(json.dumps(seq.to_json())))
    t = np.linspace(0, seq.duration, 3000)
    assert np.array_equal(back.at(t).R, seq.at(t).R)
    assert np.array_equal(back.label_at(t), seq.label_at(t))
    rot = make_trajectory("idle,rotation", 2, duration=200)
    assert rot.duration == 200 and rot.at([rot.start[1] + 5]).label[0] == LABEL_ROT
    assert rot.at([150.0]).label[0] == LABEL_NONE                   # the rotation is over
    with pytest.raises(UserError):
        make_trajectory("static80,spin", 0)
