"""Stillness detection: live and offline agree, motion and turns about the vertical are caught."""
import numpy as np
import pytest

from motecal.sessions.still import StillDetector, segment_still, still_mask, StillThresholds


def _synthetic(rate=125.0, seed=0):
    rng = np.random.default_rng(seed)
    rows, truth = [], []
    # still 2 s, yaw turn 1 s (accel constant, gyro z ramps, mag rotates), still 2 s, shake 1 s, still 2 s
    def block(n, acc, gyr, mag):
        return np.hstack([acc + rng.normal(0, 1.0, (n, 3)), gyr + rng.normal(0, 5, (n, 3)),
                          mag + rng.normal(0, 2, (n, 3))])
    n2, n1 = int(2 * rate), int(rate)
    acc = np.array([0, 0, 256.0]); gyr = np.array([100, -50, 20.0]); mag = np.array([200, 0, -400.0])
    rows.append(block(n2, acc, gyr, mag)); truth += [1] * n2
    ang = np.linspace(0, np.pi / 2, n1)[:, None]
    yaw_mag = np.hstack([200 * np.cos(ang), 200 * np.sin(ang), np.full((n1, 1), -400.0)])
    yaw_gyr = np.tile(gyr, (n1, 1)); yaw_gyr[:, 2] += 14.375 * 90 * np.sin(np.linspace(0, np.pi, n1))
    rows.append(np.hstack([acc + rng.normal(0, 1.0, (n1, 3)), yaw_gyr, yaw_mag])); truth += [0] * n1
    rows.append(block(n2, acc, gyr, yaw_mag[-1])); truth += [2] * n2
    shake = block(n1, acc, gyr, yaw_mag[-1]); shake[:, :3] += rng.normal(0, 40, (n1, 3))
    rows.append(shake); truth += [0] * n1
    rows.append(block(n2, acc, gyr, yaw_mag[-1])); truth += [3] * n2
    return np.vstack(rows), np.array(truth)


def test_segments_found_in_order():
    raw, truth = _synthetic()
    lab = segment_still(raw, 125.0)
    assert set(np.unique(lab)) == {0, 1, 2, 3}
    # every labelled row is truly still, and most still rows are found
    assert np.all(truth[lab > 0] == lab[lab > 0])
    for k in (1, 2, 3):
        assert (lab == k).sum() > 0.7 * (truth == k).sum()


def test_yaw_turn_is_not_still_without_accel_change():
    raw, truth = _synthetic()
    m = still_mask(raw, 125.0)
    assert not m[(truth == 0)].all()
    # without the magnetometer the gyro still sees the turn
    raw_nomag = raw.copy(); raw_nomag[:, 6:] = np.nan
    m2 = still_mask(raw_nomag, 125.0)
    assert m2[truth == 0].mean() < 0.5


def test_streaming_detector_matches_offline():
    raw, truth = _synthetic(seed=3)
    det = StillDetector(125.0)
    live = np.array([det.push(raw[i:i + 5]) for i in range(0, len(raw), 5)])
    # live decision at the end of each chunk vs offline trailing window there
    w = det.w
    idx = np.arange(4, len(raw), 5)
    off = np.zeros(len(idx), bool)
    for j, i in enumerate(idx):
        if i + 1 >= w:
            seg = raw[i + 1 - w:i + 1]
            off[j] = all((seg[:, sl] / s).std(axis=0).max() < lim for sl, s, lim in
                         ((slice(0, 3), 256.0, 0.02), (slice(3, 6), 14.375, 1.5), (slice(6, 9), 1090.0, 0.012)))
    assert np.array_equal(live, off)


def test_min_length_drops_short_segments():
    raw, _ = _synthetic()
    th = StillThresholds(min_still_s=2.5)
    assert segment_still(raw, 125.0, th=th).max() == 0


@pytest.mark.parametrize("n", [0, 1, 5, 10, 19, 20, 21, 68, 69])
def test_recordings_shorter_than_the_window(n):
    """Fewer rows than one window (0.4 s = 20 rows at 50 Hz): nothing can be
    still, and nothing breaks.  A row is judged by the window centred on it,
    so rows 9 .. n - 11 have one."""
    raw = np.tile([0.0, 0, 256, 0, 0, 0, 100, 0, 400], (n, 1))
    m = still_mask(raw, 50.0)
    assert m.shape == (n,) and m.dtype == bool
    assert np.array_equal(np.flatnonzero(m), np.arange(9, n - 10))
    lab = segment_still(raw, 50.0)
    assert lab.shape == (n,)
    assert (lab.max() if n else 0) == (1 if n >= 69 else 0)   # a segment needs 1 s = 50 rows
