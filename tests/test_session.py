"""SessionData.rate: the one sample-rate rule of importer, diagnosis and report."""
import numpy as np

from motecal.session import SessionData


def _data(t, raw, meta):
    n = len(t)
    return SessionData("s", raw, np.ones(n), np.arange(n), np.asarray(t, float),
                       np.zeros(n), np.zeros(n), meta=meta)


def test_rate_from_metadata_then_the_sensors_own_times():
    n = 200
    t = np.arange(n) / 100.0
    raw = np.zeros((n, 9))
    raw[1::2, 6:9] = np.nan                       # the magnetometer in every other row
    assert _data(t, raw, {"rates_hz": {"mag": 50.0}, "rate_hz": 100.0}).rate("mag") == 50.0
    assert _data(t, raw, {"rates_hz": {"mag": 50.0}, "rate_hz": 100.0}).rate("accel") == 100.0
    d = _data(t, raw, {})
    assert np.isclose(d.rate(), 100.0) and np.isclose(d.rate("accel"), 100.0)
    assert np.isclose(d.rate("mag"), 50.0)       # its own rows, not the session's
    t2 = t.copy()
    t2[::3] = np.nan                              # unknown times are left out
    assert np.isclose(_data(t2, raw, {}).rate("accel"), 100.0)
    assert _data(np.full(n, np.nan), raw, {}).rate() == 125.0
