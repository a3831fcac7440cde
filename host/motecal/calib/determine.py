"""What a session's data determine, per sensor (issues 30, 31): the richest
magnitude model its static poses or its sweep can fit -- the one judgement
``calib.content`` owns and everything else asks:

* ``calibrate`` (``board.calibrate_board``) fits that model unless
  ``--model`` forces one, and does not fit a sensor the data cannot
  determine at all (a hold in one orientation: the gyroscope bias and the
  temperature terms only);
* its gate judges the chosen model with the orientations that model needs
  (``quality["orientations_needed"]``);
* the adaptive planner (``calib.design``) predicts the ``full`` model's
  error only where the poses determine it;
* the diagnosis (``diagnose.regimes``) tests magnitude terms on poses that
  determine the ``full`` model, and treats magnetometer readings as a sweep
  only by the sweep rule here.

Static poses (their mean readings in nominal units): the models, richest
first, and the distinct orientations (at least ``DISTINCT_DEG`` apart) each
needs around the centre (the origin for the accelerometer, whose offsets are
small beside 1 g; the centre of the best-fitting sphere for the
magnetometer, whose hard iron need not be), which they must surround (the
depth of the centre in their convex hull at least ``SURROUND_DEPTH``: poses
on one side leave the centre undetermined along it; whether they surround it
well enough for a calibration to be accepted -- hull depth 0.3 -- is the
gate's to judge):

* ``full`` (offsets, scales, cross-axis terms; 9 parameters): 9;
* ``offsets+scales`` (the seed paper's model without its angles; the six
  faces ArduPilot, Razor and most users record): 6;
* ``offsets`` (3, and the field for the magnetometer): 4.

and the model's Jacobian at its nominal point on those directions must have
full rank (9 orientations on one quadric do not determine 9 parameters).
A sweep (set R) determines the ``full`` model when its readings surround
the centre of their best-fitting sphere (hull depth >= 0.3), fill at least
80 % of the sphere's equal-area cells, and that sphere is a sphere: its
radius at least ``SWEEP_RADIUS_NOISE`` times the readings' noise (a still
hold's readings are a ball of noise whose fitted centre sits inside it, so
it "covers" every direction).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..maths.sphere import distinct_directions, sphere_centre, unit
from .gate import LIMITS, GateLimits, coverage_reasons, hull_depth, set_metrics
from .identify import analyse
from .models import make_model

MODELS = ("full", "offsets+scales", "offsets")            # richest first
SPEC = {"full": ("full", None), "offsets+scales": ("paper", ("offsets", "scales")),
        "offsets": ("paper", ("offsets",))}
ORIENTATIONS_NEEDED = {"full": 9, "offsets+scales": 6, "offsets": 4}
WHAT = {"full": "offsets, scales and cross-axis terms", "offsets+scales": "offsets and scales",
        "offsets": "offsets only"}
ADDS = {"full": "cross-axis terms", "offsets+scales": "scales", "offsets": "offsets"}
SPREAD = {"full": "spread over the sphere", "offsets+scales": "around the sphere (the six faces)",
          "offsets": "around the sphere"}
FACE_DEG = 20.0            # a pose within this of a +-axis is that face
SURROUND_DEPTH = 0.1       # the poses' hull holds the centre this deep (the gate asks 0.3)
SWEEP_RADIUS_NOISE = 10.0  # a sweep's sphere radius is at least this many noise sd


def model_key(family: str, groups=None) -> str:
    """The judgement's name of a fitted model: ``full``, ``offsets+scales``,
    ``offsets``, or the paper model's groups joined by '+'."""
    if family == "full":
        return "full"
    return "+".join(groups or ("offsets", "scales", "angles"))


@dataclass
class Judgement:
    """What one sensor's data set determines (see the module doc)."""
    sensor: str
    dataset: str                         # "O" static poses, "R" a sweep
    model: str | None                    # a key of MODELS; None: nothing
    orientations: int = 0                # distinct orientations (poses)
    hull_depth: float = -1.0
    coverage: float | None = None        # a sweep's share of the sphere
    faces: bool = False                  # every pose is one of the six faces
    reasons: dict = field(default_factory=dict)   # model -> why it is not determined

    @property
    def family(self) -> str | None:
        return SPEC[self.model][0] if self.model else None

    @property
    def groups(self):
        return SPEC[self.model][1] if self.model else None

    @property
    def needed(self) -> int | None:
        """Distinct orientations the chosen model needs (poses only)."""
        return ORIENTATIONS_NEEDED[self.model] if self.model and self.dataset == "O" else None

    def determines(self, model: str) -> bool:
        """The data determine ``model`` (a key of MODELS): it or a richer one
        was chosen."""
        return self.model is not None and MODELS.index(self.model) <= MODELS.index(model)

    def why_not(self) -> str:
        """Why nothing is determined (the poorest model's reasons)."""
        return "; ".join(self.reasons.get(MODELS[-1]) or self.reasons.get("full") or
                         ["no data"])

    def text(self) -> str:
        """What calibrate prints: 'offsets and scales from 6 faces; cross-axis
        terms need at least 9 orientations spread over the sphere: add poses
        to fit them'."""
        if self.dataset == "R":
            if self.model is None:
                return f"nothing determined by the sweep: {self.why_not()}"
            return (f"{WHAT['full']} from a sweep covering {100 * (self.coverage or 0):.0f}% of "
                    f"the sphere")
        what = (f"{self.orientations} face{'s' if self.orientations != 1 else ''}" if self.faces
                else f"{self.orientations} distinct orientation"
                     f"{'s' if self.orientations != 1 else ''}")
        if self.model is None:
            return f"nothing determined from {what}: {self.why_not()}"
        out = f"{WHAT[self.model]} from {what}"
        i = MODELS.index(self.model)
        if i > 0:
            richer = MODELS[i - 1]
            out += (f"; {ADDS[richer]} need at least {ORIENTATIONS_NEEDED[richer]} orientations "
                    f"{SPREAD[richer]}: add poses to fit them")
        return out


def _full_rank(sensor: str, key: str, dirs: np.ndarray) -> bool:
    """The model's Jacobian at its nominal point on unit directions ``dirs``
    has full rank (``identify.analyse``)."""
    family, groups = SPEC[key]
    mdl = make_model(sensor, family, groups)
    theta = mdl.default
    _, _, H = mdl.affine(theta)
    J = mdl.jacobian(theta, unit(dirs) * float(H))
    return analyse(J, mdl.names, scale=0.5 * (mdl.hi - mdl.lo), unit=float(H)).rank == mdl.d


def on_faces(dirs) -> bool:
    """Every direction within ``FACE_DEG`` of a +-axis (the six faces)."""
    d = unit(dirs)
    return bool(len(d)) and bool((np.abs(d).max(axis=1) >= np.cos(np.deg2rad(FACE_DEG))).all())


def judge_poses(sensor: str, means, lim: GateLimits = LIMITS,
                surround: float = SURROUND_DEPTH) -> Judgement:
    """What static poses determine: ``means`` (K, 3) are the poses' mean
    readings in nominal units (g, gauss); see the module doc.  ``surround``:
    the hull depth asked (the magnetometer's pose sets ask the gate's own
    before they are fitted, ``content.magnetometer_sets``)."""
    lim = replace(lim, min_hull_depth=surround)
    x = np.asarray(means, float).reshape(-1, 3)
    x = x[np.isfinite(x).all(axis=1)]
    if sensor == "mag":
        q = set_metrics(x, np.arange(len(x)))
        c = sphere_centre(x)
        dirs = x - (c if c is not None else x.mean(axis=0))
    else:
        dirs = x
        q = {"distinct_orientations": distinct_directions(dirs, lim.distinct_deg),
             "hull_depth": hull_depth(dirs)}
    j = Judgement(sensor, "O", None, int(q.get("distinct_orientations", 0)),
                  float(q.get("hull_depth", -1.0)))
    j.faces = on_faces(dirs) and j.orientations <= 6
    for key in MODELS:
        why = coverage_reasons(q, ORIENTATIONS_NEEDED[key], lim, model=key)
        if not why and not _full_rank(sensor, key, dirs):
            why = [f"the poses' directions do not determine {WHAT[key]} (the model's Jacobian "
                   f"is rank-deficient on them: add poses in other directions)"]
        if not why:
            j.model = key
            break
        j.reasons[key] = why
    return j


def reading_noise(x) -> float:
    """Robust noise sd of consecutive readings (n, 3): the largest over the
    axes of median |second difference| / 0.6745 / sqrt(6) (a second
    difference takes out a steady turn, so a sweep's motion does not pass for
    noise)."""
    x = np.asarray(x, float)
    if len(x) < 4:
        return 0.0
    return float(np.median(np.abs(np.diff(x, 2, axis=0)), axis=0).max() / 0.6745 / np.sqrt(6))


def judge_sweep(sensor: str, x, lim: GateLimits = LIMITS) -> Judgement:
    """What a sweep determines: readings ``x`` (n, 3) in nominal units, in
    time order; see the module doc."""
    x = np.asarray(x, float)
    x = x[np.isfinite(x).all(axis=1)]
    j = Judgement(sensor, "R", None)
    if len(x) < 10:
        j.reasons["full"] = ["fewer than 10 readings"]
        return j
    q = set_metrics(x, None)
    j.hull_depth, j.coverage = float(q.get("hull_depth", -1.0)), q.get("coverage")
    why = coverage_reasons(q, 0, lim)
    c = sphere_centre(x)
    if c is not None:
        r = float(np.median(np.linalg.norm(x - c, axis=1)))
        noise = reading_noise(x)
        if r < SWEEP_RADIUS_NOISE * noise:
            why.insert(0, f"the readings do not turn: the sphere they fit (radius {r:.3g}) is "
                          f"within {SWEEP_RADIUS_NOISE:g}x their noise ({noise:.2g}): a hold, not "
                          f"a sweep")
    if why:
        j.reasons["full"] = why
    else:
        j.model = "full"
    return j
