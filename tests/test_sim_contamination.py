"""The simulator's contamination terms (sim/contamination.py): glitches and
disturbed stretches, planted where the bench and the robust-fit tests need
them; the truth of what was planted comes from the term, never from a fit."""
import copy

import numpy as np
import pytest

from motecal.sim import SimModel, load_model, make_trajectory
from motecal.sim.physics import K_NOMINAL, TERMS


def _board(mag_terms_first=(), mag_terms_last=(), seed=3):
    d = copy.deepcopy(load_model("paper").to_json())
    d["defaults"]["mag"]["noise"] = 0.0
    terms = d["defaults"]["mag"]["terms"]
    d["defaults"]["mag"]["terms"] = list(mag_terms_first) + terms + list(mag_terms_last)
    return SimModel.from_json(d, "t").board(1, seed)


def _read(board, kind="rotation", seed=3, n=5000, blocks=1):
    traj = make_trajectory(kind, seed)
    t = board.sample_times(traj.duration)[:n]
    s = board.sampler(traj, seed)
    parts = np.array_split(np.arange(len(t)), blocks)
    return np.vstack([s.read_detail(t[p]).pre_chip for p in parts]), t, traj


def test_terms_registered():
    assert {"glitch", "disturbed_stretch"} <= set(TERMS)


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_glitch_rate_size_and_blocks(seed):
    B = 0.48
    g = {"term": "glitch", "rate": 0.05, "size_min": 0.1 * B, "size_max": 0.5 * B, "radial": 1}
    clean, _, _ = _read(_board(seed=seed), seed=seed)
    dirty, _, _ = _read(_board([g], seed=seed), seed=seed)
    split, _, _ = _read(_board([g], seed=seed), seed=seed, blocks=7)
    assert np.array_equal(dirty, split)                      # the same however it is read
    d = dirty[:, 6:9] - clean[:, 6:9]
    hit = np.linalg.norm(d, axis=1) > 1e-6
    n = len(hit)
    # binomial: 5 % of 5000, within 4.5 sd
    assert abs(hit.sum() - 0.05 * n) < 4.5 * np.sqrt(n * 0.05 * 0.95), hit.sum()
    # radial, listed first: the true field's magnitude is off by the drawn size
    # (the paper model's scales, 0.95-1.05, act after it)
    size = np.linalg.norm(d[hit], axis=1) / (B * K_NOMINAL["mag"])
    assert size.min() > 0.1 * 0.94 and size.max() < 0.5 * 1.06
    assert np.ptp(size) > 0.3                             # drawn over the range, not one size


def test_glitch_in_a_random_direction():
    """radial 0 (listed last, on the output): offsets of the given length in
    directions spread over the sphere, not along the reading."""
    B = 0.48
    g = {"term": "glitch", "rate": 0.2, "size_min": 0.3 * B, "size_max": 0.3 * B}
    clean, _, _ = _read(_board(seed=5), seed=5, n=3000)
    dirty, _, _ = _read(_board(mag_terms_last=[g], seed=5), seed=5, n=3000)
    d = dirty[:, 6:9] - clean[:, 6:9]
    hit = np.linalg.norm(d, axis=1) > 1e-6
    assert abs(hit.mean() - 0.2) < 0.04
    assert np.allclose(np.linalg.norm(d[hit], axis=1), 0.3 * B * K_NOMINAL["mag"], rtol=1e-9)
    cos = np.sum(d[hit] * clean[hit, 6:9], axis=1) / (
        np.linalg.norm(d[hit], axis=1) * np.linalg.norm(clean[hit, 6:9], axis=1))
    assert abs(np.mean(cos)) < 0.15 and np.mean(np.abs(cos)) < 0.7   # uniform: E|cos| = 0.5


def test_disturbed_stretch_window_and_size():
    B = 0.48
    st = {"term": "disturbed_stretch", "size": 0.12 * B, "duration_s": 1.0, "start_s": 10.0}
    clean, t, _ = _read(_board())
    dirty, _, _ = _read(_board([st]))
    d = np.linalg.norm(dirty[:, 6:9] - clean[:, 6:9], axis=1)
    inside = (t >= 10.0) & (t < 11.0)
    assert np.all(d[~inside] < 1e-9)
    assert np.allclose(d[inside], 0.12 * B * K_NOMINAL["mag"], rtol=0.05)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_disturbed_stretch_drawn_start_is_inside(seed):
    st = {"term": "disturbed_stretch", "size": 0.05, "duration_s": 2.0}
    clean, t, traj = _read(_board(seed=seed), seed=seed)
    dirty, _, _ = _read(_board([st], seed=seed), seed=seed)
    d = np.linalg.norm(dirty[:, 6:9] - clean[:, 6:9], axis=1) > 1e-9
    assert d.any()
    span = t[d].max() - t[d].min()
    assert 1.9 < span <= 2.0 and t[d].min() >= 0 and t[d].max() <= traj.duration


def test_model_file_checks_parameters():
    from motecal.errors import UserError
    d = copy.deepcopy(load_model("paper").to_json())
    d["defaults"]["mag"]["terms"].append({"term": "glitch", "rate": 1.5})
    with pytest.raises(UserError):
        SimModel.from_json(d, "bad").board(1, 0)
