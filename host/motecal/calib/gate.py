"""Quality gating: one explicit accept/reject decision per board.

While calibrating, ``board.py`` records quality metrics for every sensor
(``SensorCalibration.quality``); ``decide`` compares them with ``GateLimits``
and returns a ``GateDecision`` with every reason for refusing.  The CLI then
refuses (``QualityError``, exit 3) unless ``--force``.

Reasons (and the metric behind each):

* too few distinct orientations -- static poses whose gravity (or field)
  directions are at least ``distinct_deg`` apart, fewer than the number of
  identifiable parameters (or ``min_orientations``);
* poses too clustered -- the directions must surround the origin: the depth
  of the origin inside the convex hull of the unit directions (1 for a dense
  sphere, 0.58 for the six +-axis poses, < 0 when all lie in one hemisphere)
  below ``min_hull_depth``;
* non-still "static" data -- a labelled pose whose per-axis standard deviation
  exceeds the stillness thresholds of ``motecal.sessions.still`` (accel 0.02 g, gyro
  1.5 deg/s);
* magnetometer sweep covering too little of the sphere -- the share of the
  sphere's 100 equal-area cells holding a calibrated direction
  (``sphere.coverage``: the number the logger shows while the board is
  turned) below ``min_mag_coverage``.  The logger stops a guided rotation at
  90 %; the gate asks for 80 %: its own check before the fit sees the same
  rows around the same sphere-fit centre (the logger's number, >= 90 %), and
  calibrating (soft iron, the final centre) moved the coverage of 144
  simulated guided sweeps by at most 3 points (0.87 at worst).  A sweep over
  a 60 degree cap covers ~30 %, the measured full-sphere run 86-87 %.
  Static poses are judged by their number and spread, not by coverage (80
  poses can fill at most 80 of the 100 cells);
* residual too large -- rms magnitude error after calibration, over the
  readings the robust fit kept (``calib.robust``: a trimmed rms), above
  ``max_rms_rel`` of the target (1 g or the fitted field): the data do not
  fit a fixed field / gravity (disturbed place, moving board, wrong model);
* too many readings set aside -- the robust fit set aside more than
  ``max_set_aside`` of the readings (beyond 3.5 robust sd): they disagree
  with any one calibration, so the rest is not known to be the place's
  field or gravity;
* parameter poorly determined -- an identifiable parameter whose standard
  deviation exceeds ``max_offset_std`` (offsets, in the sensor unit) or
  ``max_gain_std`` (scales, cross terms);
* a sensor with some static data but too little to fit (a single pose).

A sensor the session cannot calibrate at all (missing, or no static poses in
a rotation session) is a warning: it is simply left out of the result.  So is
a magnetometer in a session without a rotation sweep whose static poses
cannot determine it (the Razor boards' six poses, whose field directions do
not surround the centre): the session was not recorded to calibrate it
(``board.py`` records it under ``settings["skipped"]``).  Data meant for the magnetometer -- a sweep (set R) -- that
fail the limits refuse the board.

The orientation, hull and coverage limits are also checked *before* a
magnetometer data set is fitted (``set_metrics`` + ``coverage_reasons``, used
by ``board.mag_data_sets``): a set of static poses needs
``min_orientations`` distinct orientations around the centre of the
best-fitting sphere, a sweep ``min_mag_coverage`` of the sphere around it
(the centre fitted to every reading, as the logger fits it).
A set that fails is not fitted (it cannot determine the model; a single
pose used to stall the least squares for seconds).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from ..maths.sphere import DISTINCT_DEG, coverage, distinct_directions, sphere_centre, unit
from ..sessions.still import StillThresholds
from .robust import MAX_STRETCH_S, REJECT_SD


@dataclass(frozen=True)
class GateLimits:
    distinct_deg: float = DISTINCT_DEG
    min_orientations: int = 6
    min_hull_depth: float = 0.3
    min_mag_coverage: float = 0.8
    max_rms_rel: dict = field(default_factory=lambda: {"accel": 0.03, "mag": 0.05})
    max_offset_std: dict = field(default_factory=lambda: {"accel": 0.005, "mag": 0.01,
                                                         "gyro": 0.5})
    max_gain_std: float = 0.01
    max_set_aside: float = 0.2
    max_stretch_s: float = MAX_STRETCH_S
    still: StillThresholds = StillThresholds()


LIMITS = GateLimits()


# ---------------------------------------------------------------------------
# metrics (pure functions on arrays)
# ---------------------------------------------------------------------------
def hull_depth(dirs) -> float:
    """Distance from the origin to the nearest face of the convex hull of the
    unit directions (negative: the origin is outside, all in one half-space)."""
    dirs = unit(dirs)
    if len(dirs) < 4:
        return -1.0
    try:
        hull = ConvexHull(dirs)
    except QhullError:                     # coplanar or degenerate
        return -1.0
    # equations: normal . x + offset <= 0 inside; the distance of 0 is -offset
    return float(np.min(-hull.equations[:, -1]))


def set_metrics(x, label=None) -> dict:
    """The gate's metrics of a data set *before* calibration (x in nominal
    units).  The offsets are not known yet, so directions are taken from the
    centre of the best-fitting sphere: to each static pose's mean (label
    given: ``distinct_orientations``, ``hull_depth``) or to every sample of a
    sweep (``coverage``; ``hull_depth`` of at most 2000, evenly strided).
    Points that determine no sphere count as not surrounding anything (depth
    -1)."""
    x = np.asarray(x, float)
    if label is not None:
        poses, inv = np.unique(label, return_inverse=True)
        sums = np.zeros((len(poses), 3))
        np.add.at(sums, inv, x)
        pts = sums / np.bincount(inv, minlength=len(poses))[:, None]
    else:
        pts = x
    centre = sphere_centre(pts)
    dirs = pts - (centre if centre is not None else pts.mean(axis=0))
    thin = dirs if label is not None else dirs[:: max(1, len(dirs) // 2000)]
    q = {"hull_depth": hull_depth(thin) if centre is not None else -1.0}
    if label is not None:
        q["distinct_orientations"] = distinct_directions(dirs)
    else:
        q["coverage"] = coverage(dirs)
    return q


def coverage_reasons(q: dict, need: int, lim: GateLimits = LIMITS,
                     model: str | None = None) -> list:
    """Why the orientations or directions described by q (any of
    ``distinct_orientations``, ``hull_depth``, ``coverage``) cannot determine a
    model needing ``need`` distinct orientations; empty when they can.  The
    gate's reasons, word for word, without the sensor name."""
    out = []
    if "distinct_orientations" in q and q["distinct_orientations"] < need:
        out.append(f"too few distinct orientations: {q['distinct_orientations']} "
                   f"(at least {need}{' for ' + model if model else ''}; poses closer than "
                   f"{lim.distinct_deg:g} deg count once)")
    if "hull_depth" in q and q["hull_depth"] < lim.min_hull_depth:
        out.append(f"poses too clustered: the directions do not surround the "
                   f"origin (hull depth {q['hull_depth']:.2f} < {lim.min_hull_depth:g}; "
                   f"add poses on the opposite side)")
    if "coverage" in q and q["coverage"] < lim.min_mag_coverage:
        out.append(f"the readings cover too little of the sphere "
                   f"({100 * q['coverage']:.0f}% of its equal-area cells, need "
                   f"{100 * lim.min_mag_coverage:.0f}%; turn the board through the "
                   f"missing directions)")
    return out


def pose_spread(x, label) -> dict:
    """Largest per-axis standard deviation of each pose: {label: sd}."""
    out = {}
    for p in np.unique(label):
        xs = x[label == p]
        if len(xs) > 1:
            out[int(p)] = float(xs.std(axis=0, ddof=1).max())
    return out


# ---------------------------------------------------------------------------
# the decision
# ---------------------------------------------------------------------------
@dataclass
class GateDecision:
    accepted: bool
    reasons: list                   # why refused (empty when accepted)
    warnings: list
    forced: bool = False

    def to_json(self) -> dict:
        return {"accepted": self.accepted, "forced": self.forced,
                "reasons": list(self.reasons), "warnings": list(self.warnings)}

    def summary(self) -> str:
        if self.accepted:
            return "accepted" + (f" ({len(self.warnings)} warning(s))" if self.warnings else "")
        return "refused: " + "; ".join(self.reasons)


def residual_reason(sensor: str, rms_rel, lim: GateLimits = LIMITS,
                    set_aside=None) -> str | None:
    """The one decision whether what is left after a calibration is small
    enough to calibrate through: rms magnitude error relative to the target
    (1 g, or the field) above ``max_rms_rel`` -- of the readings a robust
    fit kept when ``set_aside`` (their fraction set aside) is given.  Used by
    the gate and by ``diagnose`` (a field disturbance that leaves more is
    "not calibratable" in both)."""
    if rms_rel is None or sensor not in lim.max_rms_rel or not rms_rel > lim.max_rms_rel[sensor]:
        return None
    what = "the field is not constant (disturbed place or moving magnets?)" \
        if sensor == "mag" else "the board was not still or the model does not fit"
    over = (f" over the {100 * (1 - set_aside):.0f}% of readings kept" if set_aside else "")
    return (f"residual too large: rms magnitude error {100 * rms_rel:.1f}% of the target "
            f"after calibration{over} (limit {100 * lim.max_rms_rel[sensor]:.0f}%): {what}")


def set_aside_reason(sensor: str, frac, lim: GateLimits = LIMITS) -> str | None:
    """Too many readings set aside by the robust fit (``max_set_aside``)."""
    if frac is None or not frac > lim.max_set_aside:
        return None
    what = ("the field changed while the board was turned (a disturbed place, a magnet or "
            "steel moving nearby)" if sensor == "mag" else
            "the board moved or was knocked while it should have been still")
    return (f"too many readings set aside: {100 * frac:.0f}% disagree with the calibration "
            f"by more than {REJECT_SD:g} robust standard deviations (limit "
            f"{100 * lim.max_set_aside:.0f}%): {what}")


def stretch_reason(sensor: str, aside: dict, lim: GateLimits = LIMITS) -> str | None:
    """One stretch set aside longer than ``max_stretch_s``: the field (or
    gravity) was something else for that long -- the board lay in a
    disturbed place, not a glitch or a passer-by; the bench shows stretches
    up to 3 s calibrated through, nothing longer."""
    st = [s for s in aside.get("stretches_s") or [] if s[1] - s[0] > lim.max_stretch_s]
    if not st:
        return None
    a, b, k, *rel = max(st, key=lambda s: s[1] - s[0])
    off = f", {100 * rel[0]:+.0f} % off" if rel else ""
    what = "the board lay in a disturbed place (a magnet or iron next to it)" \
        if sensor == "mag" else "the board was moved or knocked for that long"
    return (f"disturbed for too long: {k} readings over {b - a:.1f} s ({a:.1f}-{b:.1f} s{off}) "
            f"set aside in one stretch (limit {lim.max_stretch_s:g} s): {what}; record again "
            "away from it")


EARTH_FIELD_GAUSS = (0.25, 0.65)   # the total field anywhere on the Earth's surface


def field_plausibility(field_gauss, chip: str | None = None) -> str | None:
    """Why a fitted field magnitude (gauss) is not one the Earth gives, with
    the likely causes, or None when it is.  Shared by calibrate's gate and
    diagnose."""
    lo, hi = EARTH_FIELD_GAUSS
    if field_gauss is None or not np.isfinite(field_gauss) or lo <= field_gauss <= hi:
        return None
    side = "below" if field_gauss < lo else "above"
    return (f"field {field_gauss:.3g} gauss is {side} what the Earth gives ({lo:g}-{hi:g} "
            f"gauss): a wrong gain setting or chip (counts per gauss{' of ' + chip if chip else ''}"
            f" not what the import assumed; see --chip), or a disturbed place (iron, magnets, "
            f"currents nearby)")


def _check_sensor(name, sc, lim: GateLimits, reasons, warnings):
    q = sc.quality or {}
    if name == "mag" and sc.gauge != "field":
        why = field_plausibility(sc.field_gauss, getattr(sc, "chip", None))
        if why:
            warnings.append(f"mag: {why}")
    unit_ = sc.unit
    # the orientations the chosen model needs (calib.determine, recorded by
    # calibrate_board); else at least the identifiable parameters
    need = q.get("orientations_needed") or max(lim.min_orientations,
                                              int(q.get("identifiable_params", 0)))
    reasons += [f"{name}: {r}" for r in coverage_reasons(q, need, lim, model=sc.model)]
    if q.get("not_still"):
        bad = q["not_still"]
        lab = ", ".join(str(p) for p in list(bad)[:8]) + (" ..." if len(bad) > 8 else "")
        reasons.append(f"{name}: non-still data in static poses {lab} (per-axis sd above "
                       f"{q.get('still_limit')} {unit_}; re-log those poses)")
    why = residual_reason(name, q.get("rms_rel"), lim, q.get("set_aside_frac"))
    if why:
        reasons.append(f"{name}: {why}")
    why = set_aside_reason(name, q.get("set_aside_frac"), lim)
    if why:
        reasons.append(f"{name}: {why}")
    why = stretch_reason(name, getattr(sc, "set_aside", None) or {}, lim)
    if why:
        reasons.append(f"{name}: {why}")
    for p in sc.params:
        if not p.identifiable or not np.isfinite(p.std):
            continue
        if p.name.startswith(("o_", "b_")):
            limit = lim.max_offset_std.get(name, np.inf)
        elif p.name.startswith(("s_", "k_", "G_")):
            limit = lim.max_gain_std
        else:
            continue
        if p.std > limit:
            reasons.append(f"{name}: parameter {p.name} poorly determined "
                           f"(std {p.std:.3g} > {limit:g}): poses too few or too clustered")
    if sc.not_identifiable:
        warnings.append(f"{name}: not identifiable with this model: "
                        f"{', '.join(sc.not_identifiable)}")
    for w in q.get("warnings", []):
        warnings.append(f"{name}: {w}")


def decide(board, limits: GateLimits = LIMITS, force: bool = False) -> GateDecision:
    """Accept or refuse a BoardCalibration; records the decision in board.gate."""
    reasons, warnings = [], []
    if not board.sensors():
        reasons.append("no sensor could be calibrated from this session")
    for name, sc in board.sensors():
        _check_sensor(name, sc, limits, reasons, warnings)
    for name in ("accel", "gyro", "mag"):
        why = board.settings.get("skipped", {}).get(name)
        if why:
            warnings.append(f"{name}: not calibrated: {why}")
        why = board.settings.get("insufficient", {}).get(name)
        if why:
            reasons.append(f"{name}: {why}")
    d = GateDecision(not reasons, reasons, warnings, forced=bool(force and reasons))
    board.gate = d.to_json()
    return d
