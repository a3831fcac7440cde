"""The diagnosis' cause ``temperature`` (issue 16, item 6) on planted boards
that warm up: named with its coefficient per axis, separate from a time-only
``bias_drift``, no false alarm on clean warming boards.  Rates over several
seeds (MOTECAL_TEST_SEED shifts them); truths from what was planted."""
from __future__ import annotations

import os

import numpy as np
import pytest

from motecal.diagnose.engine import diagnose
from warmup import plant_clean, plant_temperature, plant_time_drift, simulate_plant, true_coef

SEED0 = int(os.environ.get("MOTECAL_TEST_SEED", "0"))


def _run(p, seed):
    ses = simulate_plant(p, seed)
    return ses, diagnose(ses, simulate=False, seed=seed)


@pytest.mark.parametrize("key", ["gyro", "accel", "mag", "accel-poses"])
def test_planted_temperature_is_named_with_its_coefficient(key):
    """4 seeds: named in all but at most one; its coefficient within 5 std
    of the planted slope; fitted / true held-out gain (true: the planted
    coefficient predicting the same held-out blocks) median within 0.75-1.33."""
    miss, ratios, off = [], [], []
    for k in range(4):
        seed = SEED0 + 1000 + 17 * k
        rng = np.random.default_rng(seed)
        p = plant_temperature(key, rng)
        sensor = p["sensor"]
        ses, d = _run(p, seed)
        f = next((f for f in d.findings if (f.sensor, f.cause) == (sensor, "temperature")), None)
        if f is None:
            miss.append((seed, sorted(d.causes())))
            continue
        tt = d.temperature[sensor]
        want = true_coef(ses, sensor)
        if np.any(np.abs(tt.coef - want) > 5 * tt.coef_std + 0.02 * np.abs(want).max()):
            off.append((seed, tt.coef, want, tt.coef_std))
        before, after = tt.heldout
        ratios.append(tt.truth_heldout_rms(want) / after)
    assert len(miss) <= 1, f"missed: {miss}"
    assert not off, off
    assert 0.75 <= float(np.median(ratios)) <= 1.33, ratios


@pytest.mark.parametrize("key", ["gyro", "accel", "mag", "accel-poses"])
def test_drift_that_does_not_follow_temperature_stays_bias_drift(key):
    """3 seeds: a drift whose course differs from the warm-up's is named
    bias_drift and not temperature, in all but at most one."""
    bad = []
    for k in range(3):
        seed = SEED0 + 2000 + 13 * k
        sensor = key.split("-")[0]
        p = plant_time_drift(sensor, np.random.default_rng(seed), poses=key.endswith("poses"))
        ses, d = _run(p, seed)
        c = d.causes()
        if (sensor, "bias_drift") not in c or (sensor, "temperature") in c:
            bad.append((seed, sorted(c)))
    assert len(bad) <= 1, bad


def test_clean_warming_boards_no_false_alarm():
    """6 clean boards warming up (3 static80, 3 holds): at most one finding
    of any kind, none of them temperature."""
    alarms = []
    for k in range(6):
        seed = SEED0 + 3000 + 11 * k
        p = plant_clean("static80" if k % 2 == 0 else "idle", np.random.default_rng(seed))
        ses, d = _run(p, seed)
        if d.findings:
            alarms.append((seed, p["kind"], sorted(d.causes())))
    assert len(alarms) <= 1, alarms
    assert not any(("gyro", "temperature") in a[2] or ("accel", "temperature") in a[2]
                   or ("mag", "temperature") in a[2] for a in alarms), alarms


def test_without_temperature_nothing_is_tested_and_the_model_gets_the_term():
    from motecal.sim import simulate_session
    ses = simulate_session("idle", seed=SEED0, model="paper", duration=60)[1]
    d = diagnose(ses, simulate=False)
    assert not any(t["cause"] == "temperature" for t in d.tests)
    p = plant_temperature("gyro", np.random.default_rng(SEED0 + 5))
    p["term"]["offset_per_c"] = [1.5, 0.0, 0.0]
    ses, d = _run(p, SEED0 + 5)
    assert ("gyro", "temperature") in d.causes()
    d2 = d.model["defaults"] if "defaults" in d.model else next(iter(d.model["boards"].values()))
    assert any(t["term"] == "temperature" for t in d2["gyro"]["terms"])
    assert any(t["term"] == "thermal" for t in d2["terms"])
    f = next(f for f in d.findings if f.cause == "temperature")
    assert "follows the board temperature" in f.summary and "deg/s/C" in f.summary


def test_report_draws_the_temperature_finding(tmp_path):
    from motecal.diagnose.plots import write_report
    p = plant_temperature("accel", np.random.default_rng(SEED0 + 9))
    p["term"]["offset_per_c"] = [0.0, 0.5, 0.0]
    ses, d = _run(p, SEED0 + 9)
    files = write_report(d, ses, tmp_path)
    name = next(f for f in files if f.endswith("accel-temperature.png"))
    assert (tmp_path / name).stat().st_size > 5000
    assert "temperature" in (tmp_path / "summary.txt").read_text()
