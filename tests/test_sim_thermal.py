"""The simulator's board temperature (``thermal``) and the sensors'
temperature coefficients (``temperature``): issue 16, item 2."""
from __future__ import annotations

import os

import numpy as np
import pytest

from motecal.line import protocol as P
from motecal.sim import SimModel, load_model, simulate_session

SEED0 = int(os.environ.get("MOTECAL_TEST_SEED", "0"))


def _model(thermal: dict, **coef) -> SimModel:
    d = load_model("paper").to_json()
    d["defaults"]["terms"] = [dict({"term": "thermal"}, **thermal)]
    for sensor, term in coef.items():
        d["defaults"][sensor]["terms"].append(dict({"term": "temperature"}, **term))
    return SimModel.from_json(d, "thermal-test")


def test_warm_up_and_room_change_follow_the_parameters():
    m = _model({"ambient_c": 21.0, "rise_c": 8.0, "tau_s": 200.0, "room_slope_c_per_h": 1.8,
                "room_amp_c": 0.5, "room_period_s": 1000.0})
    b = m.board(1, 0)
    t = np.array([0.0, 200.0, 1000.0, 5000.0])
    want = (21.0 + 8.0 * (1 - np.exp(-t / 200.0)) + 1.8 * t / 3600
            + 0.5 * np.sin(2 * np.pi * t / 1000.0))
    assert np.allclose(b.temperature_c(t), want)
    # the sensor's reading: rounded to raw TEMP_OUT counts (280 per degree)
    r = b.temperature_reading_c(t)
    assert np.all(np.abs(r - want) <= 0.5 / 280 + 1e-12)
    assert np.allclose(P.temp_raw(r), np.rint(P.temp_raw(r)))


def test_existing_models_have_no_temperature_and_a_constant_25c():
    for name in ("paper", "general", "full"):
        ses = simulate_session("idle", seed=SEED0, model=name, duration=5)[1]
        assert ses.temp is None, name
        b = load_model(name).board(1, SEED0)
        assert b.thermal is None and np.all(b.temperature_c([0.0, 100.0]) == 25.0)


@pytest.mark.parametrize("k", range(3))
def test_planted_coefficients_move_the_readings_by_coefficient_times_dt(k):
    """Gyro offset and accel offset per degree, mag gain per degree: the
    still readings' change between the first and the last minute of a
    warm-up hold is the planted coefficient times the temperature change
    (within 5 standard errors of the block means), for 3 seeds."""
    seed = SEED0 + 31 * k
    rng = np.random.default_rng(seed)
    og = rng.uniform(-3, 3, 3)
    oa = rng.uniform(-1, 1, 3)
    sm = float(rng.uniform(-0.0035, -0.0025))
    m = _model({"rise_c": 10.0, "tau_s": 120.0},
               gyro={"offset_per_c": og.tolist()}, accel={"offset_per_c": oa.tolist()},
               mag={"scale_per_c": [sm] * 3})
    ses = simulate_session("idle", seed=seed, model=m, duration=900)[1]
    t = ses.t
    a, z = t < 30, t > 870
    dT = ses.temp[z].mean() - ses.temp[a].mean()
    assert 8.5 < dT < 10.0, f"seed {seed}: dT {dT}"
    for sl, want, sd in ((slice(3, 6), og * dT, 5.0), (slice(0, 3), oa * dT, 2.0)):
        d = ses.raw[z, sl].mean(0) - ses.raw[a, sl].mean(0)
        se = sd * np.sqrt(1 / a.sum() + 1 / z.sum())
        assert np.all(np.abs(d - want) < 5 * se + 0.05), f"seed {seed}: {d} vs {want}"
    # the gain scales the whole reading, hard iron included (a field the chip measures)
    mag0 = ses.raw[a, 6:9].mean(0)
    truth = ses.meta["physical_truth"]["mag"]
    ratio = ses.raw[z, 6:9].mean(0) / mag0
    big = np.abs(mag0) > 200
    assert np.allclose(ratio[big], 1 + sm * dT, atol=0.004), f"seed {seed}: {ratio} vs {1 + sm * dT}"
    assert "temperature" in truth["nonaffine"]


def test_thermal_model_round_trips_through_its_truth_json():
    m = load_model("thermal")
    b = m.board(3, SEED0)
    assert b.thermal is not None
    again = SimModel.from_json(m.with_boards({3: b}).to_json(), "again").board(3, 0)
    assert again.to_json() == b.to_json()
    t = np.linspace(0, 3000, 7)
    assert np.array_equal(again.temperature_c(t), b.temperature_c(t))
    ses = simulate_session("idle", seed=SEED0, model="thermal", duration=10)[1]
    assert ses.has_temp


def test_unknown_parameter_and_wrong_level_are_one_line_errors():
    from motecal.errors import UserError
    d = load_model("paper").to_json()
    d["defaults"]["gyro"]["terms"].append({"term": "thermal", "rise_c": 3})
    with pytest.raises(UserError, match="board-level term"):
        SimModel.from_json(d, "x")
    d = load_model("paper").to_json()
    d["defaults"]["gyro"]["terms"].append({"term": "temperature", "offset": [1, 2, 3]})
    with pytest.raises(UserError, match="unknown parameter 'offset'"):
        SimModel.from_json(d, "x")
