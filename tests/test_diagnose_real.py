"""The diagnosis on the measured data sets (../shared/data/measured): the
results documented in docs/diagnose.md, kept as expectations.
(~30 s)"""
import json

import numpy as np
import pytest
from scipy.linalg import sqrtm

from motecal.diagnose.engine import diagnose
from motecal.sessions.importer import read_any
from motecal.sim import SimModel


def _load(measured, rel, **kw):
    paths = sorted(measured.glob(rel)) if "*" in rel else [measured / rel]
    return read_any([str(p) for p in paths], **kw)


EXPECTED = {
    "sensorstick-boards/razor1/razor1_acc_*.raw":
        {("accel", "motion"), ("gyro", "bias_drift")},
    "sensorstick-boards/razor2/razor2_acc_*.raw":
        {("accel", "bias_drift"), ("accel", "stale_samples"), ("gyro", "bias_drift"),
         ("mag", "bias_drift")},
    "sensorstick-boards/razor1/razor1_gyr_xyz.raw": {("gyro", "bias_drift")},
    "sensorstick-boards/razor2/razor2_gyr_xyz.raw": set(),
    "mpu6050-hmc5883l-timestamped/full-sphere":
        {("gyro", "saturation"), ("mag", "cross_axis"), ("mag", "field_disturbance"),
         ("mag", "stale_samples")},
    "mpu6050-hmc5883l-timestamped/unmoved-with-x-pointing-forward":
        {("accel", "bias_drift"), ("mag", "bias_drift"), ("mag", "stale_samples")},
    "mpu6050-hmc5883l-timestamped/unmoved-with-z-pointing-front-and-x-up":
        {("accel", "motion"), ("mag", "stale_samples")},
    "mpu6050-hmc5883l-timestamped/unmoved-with-z-pointing-front-and-y-down":
        {("accel", "motion"), ("mag", "stale_samples")},
    "mpu6050-hmc5883l-timestamped/rotate-ccw-around-z-pointing-up": {("mag", "stale_samples")},
}


@pytest.mark.parametrize("rel", list(EXPECTED), ids=[k.split("/")[-1] for k in EXPECTED])
def test_documented_findings(measured, rel):
    d = diagnose(_load(measured, rel), simulate=False)
    assert d.causes() == EXPECTED[rel], [(f.sensor, f.cause, f.gain) for f in d.findings]
    for f in d.findings:
        if f.cause in ("cross_axis", "bias_drift", "field_disturbance", "g_sensitivity",
                       "nonlinearity"):
            assert f.gain > 1.0
    SimModel.from_json(d.model, "extended")          # always a valid simulator model


def test_sensor_stick_sweep_soft_iron_and_moving_field(measured):
    """What the paper's model gets wrong on the Sensor Stick sweep: soft iron
    (cross_axis, matching the published Razor ellipsoid calibration) and a
    field magnitude that wanders by ~1 % while the board is turned by hand."""
    d = diagnose(_load(measured, "sensorstick-mag-sweep/magnetom.float"), seed=1)
    # the leftover after the kept field is still tested: single readings far
    # off (up to ~9 % of the field) are named, no term added
    assert d.causes() == {("mag", "cross_axis"), ("mag", "field_disturbance"),
                          ("mag", "unexplained")}
    un = next(f for f in d.findings if f.cause == "unexplained")
    assert un.evidence["outliers"] >= 10 and "outlier readings" in un.summary
    cross = next(f for f in d.findings if f.cause == "cross_axis")
    field = next(f for f in d.findings if f.cause == "field_disturbance")
    assert 1.05 < cross.gain < 1.2
    assert 1.3 < field.gain < 1.8
    assert 0.008 < field.evidence["relative_change"] < 0.02
    assert not field.evidence["untrustworthy"]
    # the fitted soft-iron matrix and centre against the published calibration
    pub = json.loads((measured / "sensorstick-mag-sweep/published_calibration.json")
                     .read_text())["magnetom.float"]
    A, c, H = d.structures["mag"].fit.affine()
    P = np.real(sqrtm(A.T @ A))
    P /= np.cbrt(np.linalg.det(P))
    T = np.array(pub["magn_ellipsoid_transform"])
    T /= np.cbrt(np.linalg.det(T))
    assert np.abs(P - T).max() < 0.012
    centre = -1090.0 * np.linalg.solve(A, c)
    assert np.abs(centre - pub["magn_ellipsoid_center"]).max() < 10
    # the extension brings the simulated statistics much closer on the held-out half
    ho = d.comparison["heldout"]
    assert ho["distance_extended"] < 0.5 * ho["distance_paper"]
    terms = [t["term"] for t in d.model["boards"]["1"]["mag"]["terms"]]
    assert terms[:3] == ["field_disturbance", "cross_axis", "scale_offset"]


def test_metal_hull_sweep_outliers_are_named_after_the_field(measured):
    """A kept field disturbance does not hide the rest: the metal-hull sweep's
    single readings far from the others (up to ~70 % of the field) are named."""
    d = diagnose(_load(measured, "metal-hull-sweep/magnetom.float"), simulate=False)
    assert ("mag", "field_disturbance") in d.causes()
    un = next(f for f in d.findings if (f.sensor, f.cause) == ("mag", "unexplained"))
    assert un.evidence["outliers"] >= 1 and un.evidence["largest_outlier_rel"] > 0.5


def test_disturbed_hmc5843_sweep_is_a_disturbance_not_a_calibration(measured):
    d = diagnose(_load(measured, "hmc5843-disturbed-sweep/magnetom.float", chip="mag=hmc5843"),
                 seed=1)
    assert d.causes() == {("mag", "field_disturbance")}
    f = d.findings[0]
    assert f.evidence["untrustworthy"] and f.evidence["relative_change"] > 0.15
    assert "cannot give a trustworthy" in f.summary
    assert any("not reported" in n for n in d.notes)       # calibration terms withheld
    assert f.gain > 2


def test_timestamped_numbers(measured):
    d = diagnose(_load(measured, "mpu6050-hmc5883l-timestamped/full-sphere"), simulate=False)
    by = {(f.sensor, f.cause): f for f in d.findings}
    assert by[("gyro", "saturation")].evidence["clipped_readings"] == 22
    assert abs(by[("mag", "cross_axis")].evidence["max_coupling"]) == pytest.approx(0.085, abs=0.01)
    assert by[("mag", "stale_samples")].params["update_hz"] == pytest.approx(75, abs=1.5)
