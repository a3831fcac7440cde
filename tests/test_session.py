"""SessionData.rate: the one sample-rate rule of importer, diagnosis and report."""
import numpy as np

from motecal.sessions.session import SessionData


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


def test_sample_times_from_seq_when_t_is_batch_receive_time():
    """A logged session's t is when the host got each batch (5 rows share it,
    compressed when the simulator runs fast): times come from seq per mote."""
    n = 100
    seq = np.r_[np.arange(1000, 1000 + n), np.arange(7, 7 + n)]
    mote = np.r_[np.ones(n), np.full(n, 2)]
    t_rx = np.repeat(np.arange(2 * n // 5) * 0.001, 5)       # batches of 5, 25x fast
    d = SessionData("s", np.zeros((2 * n, 9)), mote, seq, t_rx, np.zeros(2 * n),
                    np.zeros(2 * n), meta={"rate_hz": 125.0})
    st = d.sample_times()
    assert np.allclose(st[:n], np.arange(n) / 125.0) and np.allclose(st[n:], np.arange(n) / 125.0)
    # real sample times are kept
    t = np.arange(n) / 100.0 + 3.0
    assert np.array_equal(_data(t, np.zeros((n, 9)), {}).sample_times(), t)
    # unknown times: seq
    assert np.allclose(_data(np.full(n, np.nan), np.zeros((n, 9)), {"rate_hz": 50.0})
                       .sample_times(), np.arange(n) / 50.0)


def test_pose_means_in_pose_order_at_the_session_scales():
    """Each static pose's mean (missing values left out); free rows (label 0) ignored."""
    label = np.array([0, 2, 2, 1, 1, 1, 0])
    raw = np.zeros((7, 9))
    raw[:, 0:3] = np.arange(21).reshape(7, 3)
    raw[4, 1] = np.nan
    d = SessionData("s", raw, np.ones(7), np.arange(7), np.arange(7) / 100.0, label,
                    np.zeros(7), meta={})
    k = d.physical("accel")[3] / raw[3, 0:3]                        # the session's scale
    assert d.poses() == [1, 2]
    assert np.allclose(d.pose_means("accel"),
                       k * np.array([[12, (10 + 16) / 2, 14], [4.5, 5.5, 6.5]]))
    empty = SessionData("s", raw, np.ones(7), np.arange(7), np.arange(7) / 100.0,
                        np.zeros(7), np.zeros(7), meta={})
    assert empty.pose_means("mag").shape == (0, 3)


def test_pose_magnitudes_per_mote():
    """|accel| and |mag| of each pose's mean per mote, and its samples' flags."""
    raw = np.zeros((6, 9))
    raw[:, 0:3] = [3.0, 4.0, 0.0]                 # |a| = 5 counts
    raw[:, 6:9] = [0.0, 6.0, 8.0]                 # |m| = 10 counts
    raw[3:, 0:3] *= 2
    d = SessionData("s", raw, np.array([1, 1, 1, 2, 2, 2]), np.arange(6), np.arange(6) / 100.0,
                    np.array([1, 1, 2, 1, 1, 0]), np.array([1, 1, 1, 0, 0, 0]), meta={})
    ka = d.physical("accel")[0, 0] / 3.0
    km = d.physical("mag")[0, 1] / 6.0
    got = d.pose_magnitudes()
    assert sorted(got) == [1, 2]
    assert got[1]["poses"] == 2 and got[2]["poses"] == 1
    assert np.allclose(got[1]["acc"], [5 * ka, 5 * ka]) and np.allclose(got[2]["acc"], [10 * ka])
    assert np.allclose(got[2]["mag"], [10 * km])
    assert got[1]["flags"].tolist() == [1, 1, 1] and got[2]["flags"].tolist() == [0, 0, 0]
