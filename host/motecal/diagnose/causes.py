"""The documented vocabulary of causes: what each id means, which sensors it
applies to, the simulator term it becomes, the evidence the diagnosis needs
for it, and the smallest size the tests and the bench require it to find
(``threshold``: planted above this, it is named in >= 95 % of cases; see the
README's section "Diagnosis" and ``bench/bench_diagnose.py``).

Detectors live in ``screens`` (raw readings) and ``structure`` (nested
fits); this module only describes and words the findings.
"""
from __future__ import annotations

from dataclasses import dataclass


# Detectability thresholds: (cause, sensor[-variant]) -> (session kind the
# effect is planted in, threshold, what the size measures).  Planted at a
# random size between the threshold and 3x it (tests/plant.py), the
# cause is named in >= 95 % of cases (tests/test_diagnose_planted.py, bench).
THRESHOLDS = {
    ("cross_axis", "accel"): ("static80", 0.002, "max |symmetric coupling|"),
    ("cross_axis", "mag"): ("static80", 0.002, "max |symmetric coupling|"),
    ("nonlinearity", "accel"): ("static80", 0.006, "max |q|, |c3|, |a|"),
    ("nonlinearity", "mag"): ("static80", 0.01, "max |q|, |c3|, |a|"),
    ("bias_drift", "accel"): ("static80", 0.015, "slope, counts/s"),
    ("bias_drift", "mag"): ("static80", 0.015, "slope, counts/s"),
    ("bias_drift", "gyro"): ("static80", 5.0, "warm-up amplitude, counts"),
    ("bias_drift", "gyro-idle"): ("idle", 0.15, "random walk sigma, counts/sqrt(s)"),
    ("g_sensitivity", "gyro"): ("static80", 0.05, "max |G|, deg/s per g"),
    ("saturation", "accel"): ("static80", 0.05, "depth of the limit below the axis' largest "
                                                "reading, g"),
    ("saturation", "gyro"): ("static80", 0.1, "depth of the limit below the axis' largest "
                                              "reading, fraction of it"),
    ("saturation", "mag"): ("static80", 0.05, "depth of the limit below the axis' largest "
                                              "reading, gauss"),
    ("stale_samples", "accel"): ("idle", 0.05, "1 - update/read rate"),
    ("stale_samples", "gyro"): ("static80", 0.05, "1 - update/read rate"),
    ("stale_samples", "mag"): ("static80", 0.05, "1 - update/read rate"),
    ("motion", "accel"): ("static80", 0.07, "rms tremor, deg"),
    ("field_disturbance", "mag"): ("static80", 0.0005, "pose_rms_gauss, gauss"),
    ("field_disturbance", "mag-rotation"): ("rotation", 0.0015, "rms_gauss (wander), gauss"),
}


# Thresholds of causes planted by their own bench (bench/bench_temperature.py,
# tests/test_diagnose_thermal.py), not by tests/plant.py: temperature needs a
# board whose temperature moves (the simulator's ``thermal`` term).
THERMAL_THRESHOLDS = {
    ("temperature", "gyro"): ("static80 warming up", 0.3, "offset per C, counts/C"),
    ("temperature", "accel"): ("5-minute hold warming up", 0.1, "offset per C, counts/C"),
    ("temperature", "accel-poses"): ("static80 warming up", 0.1, "offset per C, counts/C"),
    ("temperature", "mag"): ("5-minute hold warming up", 3e-4, "|sensitivity| per C, 1/C"),
}


def threshold_text(cause: str) -> str:
    rows = [f"{s}: {thr:g} ({what}; {kind})"
            for (c, s), (kind, thr, what) in {**THRESHOLDS, **THERMAL_THRESHOLDS}.items()
            if c == cause]
    return "; ".join(rows) or "-"


@dataclass(frozen=True)
class Cause:
    id: str
    sensors: tuple
    term: str | None            # simulator term id (None: no term)
    meaning: str
    evidence: str               # what the diagnosis needs to name it

    @property
    def threshold(self) -> str:
        """Planted sizes the tests and the bench require it to find."""
        return threshold_text(self.id)


CAUSES = {c.id: c for c in (
    Cause("cross_axis", ("accel", "mag"), "cross_axis",
          "off-diagonal coupling between axes (non-orthogonality, magnetometer soft iron), "
          "which the paper's angle model cannot represent",
          "magnitude residual that depends on direction as u_i u_j: the full (lower-"
          "triangular) matrix lowers the weighted residual beyond chance (F-test, 3 extra "
          "parameters) and lowers the held-out residual; needs >= 12 orientations or a sweep"),
    Cause("nonlinearity", ("accel", "mag"), "nonlinearity",
          "scale that depends on the reading: quadratic/cubic terms, asymmetric +/- scale",
          "magnitude residual that is an odd/even polynomial of each axis reading: q, c3, a per "
          "axis (9 parameters) pass the F-test and lower the held-out residual"),
    Cause("bias_drift", ("accel", "gyro", "mag"), "bias_drift",
          "bias that changes over the session (warm-up, temperature, random walk)",
          "offsets that move with time: a smooth time basis per axis (4 functions, or one per "
          "~10 s for a random walk) passes the F-test on pose/block means and lowers the "
          "held-out residual of interleaved time blocks"),
    Cause("g_sensitivity", ("gyro",), "g_sensitivity",
          "gyroscope output that depends on the specific force (orientation in still data)",
          "still gyro means regressed on the calibrated accelerometer's specific force "
          "(9 parameters) beyond chance; needs still poses spanning the sphere"),
    Cause("saturation", ("accel", "gyro", "mag"), "saturation",
          "readings clipped at the range limits, or overflow codes",
          "a pile-up at an axis' extreme value: >= 4x the mean count of the 20 values inside "
          "it and beyond chance (Poisson, twice the neighbours' mean as expectation), with "
          ">= 10 readings (>= 3 at a chip's full-scale code); any HMC5883L overflow code "
          "(-4096 on all axes)"),
    Cause("stale_samples", ("accel", "gyro", "mag"), "stale_samples",
          "repeated identical readings (a sensor read faster than it updates)",
          "readings equal on all three axes to the previous one more often than to the one "
          "before it (sign test) and >= 2 % above the chance of equal fresh readings"),
    Cause("motion", ("accel", "gyro"), "motion",
          "\"static\" poses that were not still",
          "inside still segments, accelerometer changes over 64 ms follow the turn the "
          "gyroscope measured (d f = -dtheta x f): slope z-test, |slope| 0.3-3; needs both "
          "sensors on one clock.  In one orientation, an accelerometer drift that turns the reading "
          "without changing its length (length change < 0.3x the vector change) is a slow "
          "tilt, not a bias drift"),
    Cause("field_disturbance", ("mag",), "field_disturbance",
          "the magnetic field magnitude or direction changes between or within poses "
          "(iron nearby, currents)",
          "static poses: magnitude residuals scattered beyond their noise after every "
          "calibration term (chi-square), with the dip angle scattering too when the "
          "accelerometer is there; sweeps: a field magnitude that moves with time (time "
          "basis, F-test); above 5 % of the field the recording cannot give a trustworthy "
          "calibration"),
    Cause("temperature", ("accel", "gyro", "mag"), "temperature",
          "offsets (and gain) that follow the board temperature: warm-up after power-on, "
          "the room",
          "the session carries a temperature spanning >= 2 C over still blocks in few "
          "orientations (gyro: every still block; accel, mag: holds) or over the "
          "accelerometer's static poses (through the magnitude); an offset per axis "
          "times (T - t_ref) passes the F-test beyond a smooth time basis, or alone while the "
          "time basis adds nothing on top of it, and lowers the held-out residual of "
          "interleaved blocks"),
    Cause("unexplained", ("accel", "gyro", "mag"), None,
          "structured residual that no known term explains",
          "residuals scattered beyond their noise (chi-square) after every accepted term, "
          "with the structure named (direction, time, outliers)"),
)}

ORDER = tuple(CAUSES)


def applies(cause: str, sensor: str) -> bool:
    return sensor in CAUSES[cause].sensors


def _pct(x):
    return f"{100 * x:.2g} %"


def _fmt(x, unit=""):
    if x is None:
        return "-"
    a = abs(x)
    s = f"{x:.3g}" if (a >= 1e-3 or a == 0) else f"{x:.2e}"
    return s + (f" {unit}" if unit else "")


def summary(sensor: str, cause: str, ev: dict, params: dict, gain, before=None, after=None,
            unit: str = "") -> str:
    """One paragraph per finding, ending with the gain."""
    s = {
        "cross_axis": lambda: (
            f"The {sensor} axes are coupled: the magnitude residual depends on direction "
            f"as products of two axes, which per-axis offsets and scales cannot absorb "
            f"(F = {ev.get('F', 0):.1f}, p = {ev.get('p', 1):.2g}). Largest coupling "
            f"{_fmt(ev.get('max_coupling'))} ({ev.get('max_coupling_at', '')})"
            + (" -- soft iron." if sensor == "mag" else " -- non-orthogonal axes.")),
        "nonlinearity": lambda: (
            f"The {sensor} scale depends on the reading: a quadratic/cubic/asymmetric term "
            f"per axis explains the residual (F = {ev.get('F', 0):.1f}, p = "
            f"{ev.get('p', 1):.2g}); largest coefficient {_fmt(ev.get('max_coef'))} "
            f"({ev.get('max_coef_at', '')})."),
        "bias_drift": lambda: (
            f"The {sensor} bias moves during the session by {_fmt(ev.get('drift_range'), unit)} "
            f"peak to peak ({ev.get('basis', '')}; F = {ev.get('F', 0):.1f}, p = "
            f"{ev.get('p', 1):.2g})."),
        "g_sensitivity": lambda: (
            f"The gyroscope output follows the specific force: largest coefficient "
            f"{_fmt(ev.get('max_G'), 'deg/s per g')} ({ev.get('max_G_at', '')}; F = "
            f"{ev.get('F', 0):.1f}, p = {ev.get('p', 1):.2g})."),
        "saturation": lambda: (
            f"{ev.get('clipped_readings', 0)} {sensor} readings "
            f"({_pct(ev.get('clipped_fraction', 0))}) sit at a range limit"
            + (f", {ev.get('overflow_rows')} of them overflow codes" if ev.get('overflow_rows')
               else "")
            + ": " + ", ".join(f"{h['axis']} {h['side']} {h['limit_counts']:g} counts "
                               f"({h['count']}x vs {h['neighbour_mean']:.2g} just inside)"
                               for h in ev.get("limits", [])[:4]) + "."),
        "stale_samples": lambda: (
            f"{_pct(ev.get('repeat_fraction', 0))} of the {sensor} readings repeat the "
            f"previous one on all axes (chance {_pct(ev.get('chance_fraction', 0))}, two "
            f"steps apart {_pct(ev.get('repeat_fraction_lag2', 0))}): the sensor updates at "
            f"about {ev.get('update_rate_hz', 0):.3g} Hz but is read at "
            f"{ev.get('read_rate_hz', 0):.3g} Hz."),
        "motion": lambda: (
            f"The board tilted slowly while \"still\": the accelerometer reading turned by "
            f"{_fmt(ev.get('angle_rms_deg'), 'deg')} rms while its length changed "
            f"{ev.get('length_to_vector_change', 0):.2g}x as much as the vector (a bias drift "
            f"would change the length as much; F = {ev.get('F', 0):.1f}, p = "
            f"{ev.get('p', 1):.2g})." if ev.get("slow_tilt") else
            f"The \"still\" poses were not still: inside them the accelerometer turns the way "
            f"the gyroscope says (slope {ev.get('slope_accel_on_gyro', 0):.2f}, z = "
            f"{ev.get('z', 0):.1f}); tremor about {_fmt(ev.get('tremor_angle_rms_deg'), 'deg')} "
            f"rms, {_fmt(ev.get('tremor_rate_rms_dps'), 'deg/s')} rms rate."),
        "field_disturbance": lambda: (
            f"The magnetic field is not constant: {ev.get('what', '')} "
            + (f"The field changes by {_pct(ev.get('relative_change', 0))} rms: "
               + ("the recording cannot give a trustworthy magnetometer calibration."
                  if ev.get("untrustworthy") else "small enough to calibrate through.")
               if ev.get("relative_change") is not None else "")),
        "temperature": lambda: (
            f"The {sensor} offset follows the board temperature: ("
            + ", ".join(_fmt(v) for v in ev.get("coef_per_c", []))
            + f") {ev.get('unit', '')} per axis over {ev.get('span_c', 0):.2g} C "
            f"(p = {ev.get('p', 1):.2g}"
            + ("; a time drift on top of it is named bias_drift" if ev.get("time_drift_too")
               else "; the time basis adds nothing on top of it") + ")."),
        "unexplained": lambda: (
            f"The {sensor} residual is {ev.get('excess_ratio', 0):.2g}x its noise after every "
            f"known term (chi-square p = {ev.get('p', 1):.2g}); structure: "
            f"{ev.get('structure', 'none identified')}."),
    }[cause]()
    if gain is not None and cause != "unexplained":
        tail = f" Gain on held-out data: {gain:.3g}x"
        if before is not None and after is not None:
            tail += f" (rms {_fmt(before, unit)} -> {_fmt(after, unit)})"
        s += tail + "."
    elif cause == "unexplained":
        s += " No term added (gain 1)."
    return s
