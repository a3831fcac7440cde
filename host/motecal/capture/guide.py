"""Guided capture: what the person does next, and which samples become a pose.

The decisions live here, as explicit state machines, one per followed mote
(as ArduPilot runs one ``CompassCalibrator`` per compass):

* ``PoseCapture`` (``--guided static80``):  MOVE -> WAIT_STILL -> CAPTURE ->
  (accept) MOVE ... -> DONE.  The board must move between poses; when the
  trailing stillness window (``still.live_detector``: the offline rule,
  ``TurnStillDetector``) becomes still, the window's rows (less the first
  ``settle_s``) start a capture; ``samples`` still rows in a row, followed
  by ``confirm`` more (a move shows in the trailing window a little late),
  make the pose (labelled with its index), a moving row first discards the
  capture and the same pose is tried again.  A pose whose gravity direction lies within
  ``min_angle_deg`` of an accepted one is refused with a warning -- the one
  accept/reject point is ``PoseCapture._consider``.
* ``AdaptiveCapture`` (``--guided adaptive``): the same states and
  accept/reject point; after a few seed poses the next pose, its samples and
  the stop come from a planner's prediction of the calibration's error
  (``calib.design``, handed in by the command: this layer does not fit).
* ``RotationCapture`` (``--guided rotation``): labels rows ``rot`` from the
  start until ``samples`` rows or until the magnetometer directions (around a
  running sphere-fit centre) hit ``coverage`` of equal-area sphere cells
  (``sphere.coverage``, 10 x 10 cells: the number the quality gate checks).

In interactive use a pose is only captured after the person confirmed it
(``arm``: Enter); non-interactive flows are always armed and advance whenever
a new still pose appears.

``GuidedFlow`` holds the per-mote machines and is what the logger talks to:
``update(mote, seq, raw)`` returns ``GuideEvent``s, among them ``label``
events telling the logger which stored rows to label.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from ..maths.sphere import (COVERAGE_BANDS, COVERAGE_SECTORS, SphereCoverage, angle_deg,
                            fibonacci_sphere, sphere_centre, unit)
from ..sessions.session import HMC5883L_OVERFLOW, LABEL_ROT, NOMINAL_SCALES
from ..sessions.still import StillThresholds, live_detector

DEFAULT_POSES = 80
DEFAULT_POSE_SAMPLES = 200
DEFAULT_MIN_ANGLE = 15.0
DEFAULT_ROT_SAMPLES = 5000
DEFAULT_COVERAGE = 0.9
MAX_MIN_ANGLE = 90.0         # degrees: six poses (the +-axes) are 90 deg apart
DEFAULT_SETTLE_S = 0.3       # the first rows of a still window are left out: the slow end
#                              of a smooth move passes the integrated-rotation limit
MAG_OVERFLOW = HMC5883L_OVERFLOW


# --------------------------------------------------------------------------
# Describing a direction
# --------------------------------------------------------------------------
_AXES = (("+X", np.array([1.0, 0, 0])), ("-X", np.array([-1.0, 0, 0])),
         ("+Y", np.array([0, 1.0, 0])), ("-Y", np.array([0, -1.0, 0])),
         ("+Z", np.array([0, 0, 1.0])), ("-Z", np.array([0, 0, -1.0])))


def describe_up(d: np.ndarray) -> str:
    """Words for a gravity direction: which board face points up, and the tilt.

    ``d`` is the accelerometer's reading at rest (it points up, away from the
    Earth).  "+Z face up" is the board flat, components on top.
    """
    d = unit(d)
    dots = [float(d @ a) for _, a in _AXES]
    i = int(np.argmax(dots))
    name, axis = _AXES[i]
    tilt = float(angle_deg(d, axis))
    if tilt < 5.0:
        return f"{name} face up, level"
    horiz = d - dots[i] * axis
    j = max((k for k in range(6) if abs(float(_AXES[k][1] @ axis)) < 0.5),
            key=lambda k: float(horiz @ _AXES[k][1]))
    return f"{name} face up, tilted {tilt:.0f} deg toward {_AXES[j][0]}"


def sketch_up(d: np.ndarray) -> list[str]:
    """A three-line sketch of the board seen from the side that is up:
    the face-up axis in the middle, an arrow toward the tilt."""
    d = unit(d)
    dots = [float(d @ a) for _, a in _AXES]
    i = int(np.argmax(dots))
    name, axis = _AXES[i]
    horiz = d - dots[i] * axis
    others = [k for k in range(6) if abs(float(_AXES[k][1] @ axis)) < 0.5]
    # screen right / screen up: the first two other axes with a positive sign
    right = next(_AXES[k] for k in others if _AXES[k][0][0] == "+")
    upv = next(_AXES[k] for k in others if _AXES[k][0][0] == "+" and _AXES[k][0] != right[0])
    x, y = float(horiz @ right[1]), float(horiz @ upv[1])
    arrows = {(0, 1): "^", (1, 1): "/", (1, 0): ">", (1, -1): "\\", (0, -1): "v",
              (-1, -1): "/", (-1, 0): "<", (-1, 1): "\\"}
    if math.hypot(x, y) < math.sin(math.radians(5.0)):
        arrow = " "
    else:
        a = math.atan2(y, x)
        q = (round(math.cos(a) * 1.2), round(math.sin(a) * 1.2))
        arrow = arrows.get((max(-1, min(1, q[0])), max(-1, min(1, q[1]))), " ")
    return [f"    {upv[0]}",
            f" +-----+  tilt {arrow}",
            f" | {name:^3} | {right[0]}",
            " +-----+"]


def max_poses(min_angle_deg: float) -> int:
    """Most poses that can be pairwise ``min_angle_deg`` apart on the sphere
    (an upper bound: caps of half that radius around each cannot overlap,
    so n (1 - cos(angle / 2)) <= 2)."""
    return int(2.0 / (1.0 - math.cos(math.radians(min_angle_deg) / 2.0)))


# --------------------------------------------------------------------------
# Events
# --------------------------------------------------------------------------
@dataclass
class GuideEvent:
    kind: str            # capturing | accepted | discarded | too_close | label | estimate | done
    mote: int
    pose: int = 0
    text: str = ""
    seq_lo: int = 0
    seq_hi: int = 0
    label: int = 0


class Phase(Enum):
    MOVE = "move the board to the next pose"
    WAIT_STILL = "hold the board still"
    CAPTURE = "capturing: keep still"
    ROTATE = "turn the board through all directions"
    DONE = "done"


@dataclass
class Pose:
    index: int
    direction: np.ndarray
    seq_lo: int
    seq_hi: int
    n: int = 0                                   # samples
    mean: np.ndarray | None = None               # (9,) raw counts
    sd: np.ndarray | None = None                 # (9,) per-axis sample sd


# --------------------------------------------------------------------------
# Static poses
# --------------------------------------------------------------------------
class PoseCapture:
    """The static80 flow of one mote."""

    kind = "static80"

    def __init__(self, mote: int, *, poses: int = DEFAULT_POSES,
                 samples: int = DEFAULT_POSE_SAMPLES, min_angle_deg: float = DEFAULT_MIN_ANGLE,
                 rate_hz: float = 125.0, scales: dict | None = None, auto: bool = True,
                 settle_s: float = DEFAULT_SETTLE_S,
                 thresholds: StillThresholds = StillThresholds()):
        self.mote = mote
        self.poses = poses
        self.samples = samples
        self.min_angle = min_angle_deg
        self.auto = auto
        self.armed = auto
        self.det = live_detector(rate_hz, scales or NOMINAL_SCALES, thresholds)
        self.settle = int(round(settle_s * rate_hz))
        # a pose's last row is still by the window centred on it (as offline):
        # half a window of still rows after it confirms it
        self.confirm = self.det.w // 4
        self._confirmed = 0
        if not 0 <= self.settle < self.det.w:
            raise ValueError("settle_s must be shorter than the still window")
        if samples < self.det.w - self.settle:
            raise ValueError(f"a pose needs at least {self.det.w - self.settle} samples")
        self.targets = fibonacci_sphere(poses)   # first near +Z (flat), spiralling to -Z
        self.accepted: list[Pose] = []
        self.coverage = SphereCoverage(4, 5)
        self.phase = Phase.WAIT_STILL
        self.captured = 0
        self.discards = 0
        self.warning = ""
        self._hist_seq = np.zeros(0, np.int64)
        self._hist_raw = np.zeros((0, 9))
        self._cap_lo = 0
        self._cap_hi = 0
        self._cap_sum = np.zeros(9)
        self._cap_sq = np.zeros(9)

    @property
    def next_pose(self) -> int:
        return len(self.accepted) + 1

    @property
    def done(self) -> bool:
        return self.phase is Phase.DONE

    @property
    def target(self) -> np.ndarray | None:
        return None if self.done else self.targets[len(self.accepted)]

    def arm(self) -> None:
        """The person says the board is placed (interactive use)."""
        self.armed = True

    def _close_to(self, d: np.ndarray) -> tuple[int, float] | None:
        if not self.accepted:
            return None
        dirs = np.array([p.direction for p in self.accepted])
        ang = angle_deg(dirs, d)
        j = int(np.argmin(ang))
        return (self.accepted[j].index, float(ang[j])) if ang[j] < self.min_angle else None

    def _consider(self, d: np.ndarray, events: list) -> bool:
        """The one accept/reject decision for a still stretch with mean gravity
        direction ``d``; returns False (and warns) when it is too close."""
        close = self._close_to(d)
        if close is None:
            return True
        pose, ang = close
        self.warning = (f"mote {self.mote}: this pose is {ang:.0f} deg from pose {pose} "
                        f"(need {self.min_angle:.0f}): turn the board further")
        events.append(GuideEvent("too_close", self.mote, self.next_pose, self.warning))
        self.phase = Phase.MOVE
        return False

    def update(self, seq: np.ndarray, raw: np.ndarray) -> list[GuideEvent]:
        """Feed this mote's new rows (arrival order); returns what happened."""
        events: list[GuideEvent] = []
        n = len(seq)
        if n == 0:
            return events
        still = self.det.push_many(raw)
        raw = np.asarray(raw, float)
        h = len(self._hist_seq)
        all_seq = np.concatenate([self._hist_seq, seq])
        all_raw = np.vstack([self._hist_raw, raw])
        w = self.det.w
        i = 0
        while i < n and not self.done:
            if self.phase is Phase.MOVE:
                moving = np.flatnonzero(~still[i:])
                if not len(moving):
                    break
                i += int(moving[0])
                self.phase = Phase.WAIT_STILL
            elif self.phase is Phase.WAIT_STILL:
                if not self.armed:
                    break
                found = np.flatnonzero(still[i:])
                if not len(found):
                    break
                j = i + int(found[0])
                lo = max(h + j - w + 1 + self.settle, 0)   # window start (+ settling) in all_*
                window = all_raw[lo:h + j + 1]
                i = j + 1
                if not self._consider(unit(window[:, :3].mean(axis=0)), events):
                    continue
                self.phase = Phase.CAPTURE
                self.warning = ""
                self.captured = len(window)
                self._confirmed = 0
                self._cap_sum = window.sum(axis=0)
                self._cap_sq = (window * window).sum(axis=0)
                self._cap_lo = int(all_seq[lo])
                self._cap_hi = int(all_seq[h + j])
                events.append(GuideEvent("capturing", self.mote, self.next_pose,
                                         f"mote {self.mote}: pose {self.next_pose} still, "
                                         "capturing"))
            elif self.phase is Phase.CAPTURE:
                need = self.samples + self.confirm - self.captured - self._confirmed
                seg = still[i:i + need]
                bad = np.flatnonzero(~seg)
                take = int(bad[0]) if len(bad) else len(seg)
                into = min(take, self.samples - self.captured)    # rows of the pose
                if into:
                    self.captured += into
                    part = raw[i:i + into]
                    self._cap_sum += part.sum(axis=0)
                    self._cap_sq += (part * part).sum(axis=0)
                    self._cap_hi = int(seq[i + into - 1])
                self._confirmed += take - into                     # still rows after it
                i += take
                if len(bad):
                    self.discards += 1
                    events.append(GuideEvent(
                        "discarded", self.mote, self.next_pose,
                        f"mote {self.mote}: moved during pose {self.next_pose} "
                        f"({self.captured}/{self.samples}): hold it still again"))
                    self.phase = Phase.WAIT_STILL
                    self.captured = 0
                elif self.captured >= self.samples and self._confirmed >= self.confirm:
                    self._finish(events)
        keep = min(w, len(all_seq))
        self._hist_seq = all_seq[-keep:].copy()
        self._hist_raw = all_raw[-keep:].copy()
        return events

    def _finish(self, events: list) -> None:
        n = self.captured
        mean = self._cap_sum / n
        with np.errstate(invalid="ignore"):
            sd = np.sqrt(np.maximum(self._cap_sq - n * mean * mean, 0.0) / max(n - 1, 1))
        d = unit(mean[:3])
        self.captured = 0
        if not self._consider(d, events):
            return
        k = self.next_pose
        target = self.target
        pose = Pose(k, d, self._cap_lo, self._cap_hi, n, mean, sd)
        self.accepted.append(pose)
        self.coverage.add(d)
        off = angle_deg(target, d)
        events.append(GuideEvent("label", self.mote, k, "", pose.seq_lo, pose.seq_hi, k))
        events.append(GuideEvent(
            "accepted", self.mote, k,
            f"mote {self.mote}: pose {k}/{self.poses} recorded ({describe_up(d)}; "
            f"{off:.0f} deg from the suggested pose; coverage "
            f"{self.coverage.fraction:.0%})"))
        self.armed = self.auto
        self._next(events)

    def _next(self, events: list) -> None:
        """After an accepted pose: done, or on to the next one."""
        k = len(self.accepted)
        if len(self.accepted) >= self.poses:
            self.phase = Phase.DONE
            events.append(GuideEvent("done", self.mote, k, f"mote {self.mote}: all "
                                     f"{self.poses} poses recorded"))
        else:
            self.phase = Phase.MOVE

    def status(self) -> dict:
        phase = self.phase.value
        if self.phase is Phase.WAIT_STILL and not self.armed:
            phase = "place the board, then press Enter"
        return dict(kind=self.kind, mote=self.mote, phase=phase,
                    pose=min(self.next_pose, self.poses), poses=self.poses,
                    captured=self.captured,
                    samples=self.samples, armed=self.armed, warning=self.warning,
                    coverage=self.coverage.fraction,
                    target=None if self.done else describe_up(self.target),
                    sketch=[] if self.done else sketch_up(self.target),
                    map=self.coverage.map(self.target))

    def picture(self) -> dict:
        """The numbers a drawing of this flow needs (``motecal.view``), read
        from the state machine, never decided again: the suggested and the
        accepted gravity directions, the stillness of the trailing window, the
        capture's progress, the coverage cells.  Arrays are references to or
        copies of small state; the caller must not change them."""
        return dict(targets=self.targets, target=self.target, still=self.det.still,
                    accepted=np.array([p.direction for p in self.accepted]).reshape(-1, 3),
                    hits=self.coverage.hits.copy(), bands=self.coverage.bands,
                    sectors=self.coverage.sectors, discards=self.discards)


# --------------------------------------------------------------------------
# Adaptive poses
# --------------------------------------------------------------------------
SEED_POSES = 12              # evenly spread first poses, before any prediction
SEED_SAMPLES = 400           # samples of each seed pose (the noise is not known yet)
ADAPTIVE_MAX_POSES = 80      # the session stops here whatever the prediction says


class AdaptiveCapture(PoseCapture):
    """The adaptive flow of one mote (``--guided adaptive``): PoseCapture's
    states and its one accept/reject point (``_consider``), but the poses,
    their number and their samples are decided as it goes.

    * The first ``seed_poses`` suggestions are an even spread of gravity
      directions, held ``seed_samples`` samples each.
    * After every accepted pose from then on the ``planner`` (a callable
      ``planner(mean (K, 9), sd (K, 9), n (K,)) -> advice``, made by the
      command from ``calib.design.Planner``; this layer does not fit) says
      where the calibration stands: the promised error per sensor against
      its target (``advice.text``), whether every target is met
      (``advice.all_met``), the next pose (``advice.next_up``, a gravity
      direction in the accelerometer's frame) and its samples
      (``advice.samples``).
    * The stop rule, in one place (``_next``): DONE when every target is
      met, or at ``max_poses`` (said so: the targets were not met).
    """

    kind = "adaptive"

    def __init__(self, mote: int, *, planner, max_poses: int = ADAPTIVE_MAX_POSES,
                 seed_poses: int = SEED_POSES, seed_samples: int = SEED_SAMPLES, **kw):
        if not 1 <= seed_poses <= max_poses:
            raise ValueError("seed_poses must be 1..max_poses")
        super().__init__(mote, poses=max_poses, samples=seed_samples, **kw)
        self.planner = planner
        self.seed_poses = seed_poses
        self.targets = fibonacci_sphere(seed_poses)      # then one per suggestion
        self.advice = None
        self.met = False
        self.text = ""

    @property
    def target(self) -> np.ndarray | None:
        if self.done:
            return None
        k = len(self.accepted)
        return self.targets[min(k, len(self.targets) - 1)]

    def _next(self, events: list) -> None:
        k = len(self.accepted)
        if k >= self.seed_poses:
            mean = np.array([p.mean for p in self.accepted])
            sd = np.array([p.sd for p in self.accepted])
            n = np.array([p.n for p in self.accepted], float)
            self.advice = adv = self.planner(mean, sd, n)
            self.met = bool(adv.all_met)
            self.text = adv.text
            events.append(GuideEvent("estimate", self.mote, k,
                                     f"mote {self.mote}: after {k} poses: {adv.text}"))
            if self.met:
                self.phase = Phase.DONE
                events.append(GuideEvent("done", self.mote, k, f"mote {self.mote}: targets "
                                         f"met after {k} poses"))
                return
            if adv.next_up is not None:
                self.targets = np.vstack([self.targets[:k], unit(adv.next_up)[None]])
            self.samples = max(int(adv.samples), self.det.w - self.settle)
        if k >= self.poses:
            self.phase = Phase.DONE
            events.append(GuideEvent("done", self.mote, k, f"mote {self.mote}: {k} poses, the "
                                     "most allowed: targets not met"))
        else:
            self.phase = Phase.MOVE

    def status(self) -> dict:
        st = super().status()
        st.update(pose=self.next_pose if not self.done else len(self.accepted),
                  estimate=self.text, met=self.met, seed_poses=self.seed_poses)
        return st


# --------------------------------------------------------------------------
# Rotation sweep
# --------------------------------------------------------------------------
MIN_FIT_POINTS = 20          # fewer readings: the sweep's centre is the mid-range


def sweep_centre(m: np.ndarray) -> np.ndarray:
    """Centre of a magnetometer sweep m (n, 3): the best-fitting sphere's
    (``sphere.sphere_centre``), the mid-range while too few readings or too
    flat a set determine none."""
    m = np.asarray(m, float)
    c = sphere_centre(m) if len(m) >= MIN_FIT_POINTS else None
    return (m.max(axis=0) + m.min(axis=0)) / 2.0 if c is None else c


class RotationCapture:
    """The rotation flow of one mote: label rows ``rot`` while the board is turned."""

    kind = "rotation"

    def __init__(self, mote: int, *, samples: int = DEFAULT_ROT_SAMPLES,
                 coverage: float = DEFAULT_COVERAGE, auto: bool = True,
                 bands: int = COVERAGE_BANDS, sectors: int = COVERAGE_SECTORS,
                 refit_every: int = 250):
        self.mote = mote
        self.samples = samples
        self.target_coverage = coverage
        self.auto = auto
        self.armed = auto
        self.coverage = SphereCoverage(bands, sectors)
        self.refit_every = refit_every
        self.phase = Phase.ROTATE
        self.count = 0
        self._mag = np.zeros((0, 3))
        self._fitted_at = 0
        self.centre = np.zeros(3)

    @property
    def done(self) -> bool:
        return self.phase is Phase.DONE

    def arm(self) -> None:
        self.armed = True

    def update(self, seq: np.ndarray, raw: np.ndarray) -> list[GuideEvent]:
        events: list[GuideEvent] = []
        if self.done or not self.armed or not len(seq):
            return events
        take = min(len(seq), self.samples - self.count)
        s = np.asarray(seq[:take])
        self.count += take
        events.append(GuideEvent("label", self.mote, 0, "", int(s.min()), int(s.max()),
                                 LABEL_ROT))
        mag = np.asarray(raw, float)[:take, 6:9]
        good = np.isfinite(mag).all(axis=1) & (mag != MAG_OVERFLOW).all(axis=1)
        self._mag = np.vstack([self._mag, mag[good]])
        if len(self._mag) - self._fitted_at >= self.refit_every or self.count >= self.samples:
            self._fitted_at = len(self._mag)
            self.centre = sweep_centre(self._mag)
            self.coverage.reset()
            self.coverage.add(self._mag - self.centre)
        frac = self.coverage.fraction
        if self.count >= self.samples or frac >= self.target_coverage:
            self.phase = Phase.DONE
            why = (f"coverage {frac:.0%}" if frac >= self.target_coverage
                   else f"{self.samples} samples")
            events.append(GuideEvent("done", self.mote, 0,
                                     f"mote {self.mote}: rotation recorded ({self.count} "
                                     f"samples, {why})"))
        return events

    def status(self) -> dict:
        return dict(kind=self.kind, mote=self.mote, phase=self.phase.value, count=self.count,
                    samples=self.samples, armed=self.armed, coverage=self.coverage.fraction,
                    target_coverage=self.target_coverage, map=self.coverage.map())

    def picture(self) -> dict:
        """The numbers a drawing of the sweep needs (``motecal.view``): every
        usable magnetometer reading so far (raw counts; the array is replaced,
        never changed, so the reference stays valid), the centre of the last
        fit and the coverage cells it counted."""
        return dict(points=self._mag, centre=self.centre.copy(), hits=self.coverage.hits.copy(),
                    bands=self.coverage.bands, sectors=self.coverage.sectors)


# --------------------------------------------------------------------------
# Several motes
# --------------------------------------------------------------------------
@dataclass
class GuidedFlow:
    """One capture per followed mote (``follow`` = a mote id, or None = all)."""

    kind: str                              # static80 | adaptive | rotation
    follow: int | None = None
    auto: bool = True
    options: dict = field(default_factory=dict)
    captures: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.kind not in FLOWS:
            raise ValueError(f"unknown guided flow {self.kind!r}")

    def _capture(self, mote: int):
        cap = self.captures.get(mote)
        if cap is None:
            cls = FLOWS[self.kind]
            cap = self.captures[mote] = cls(mote, auto=self.auto, **self.options)
        return cap

    def update(self, mote: np.ndarray, seq: np.ndarray, raw: np.ndarray) -> list[GuideEvent]:
        """Rows of any motes (arrival order); unfollowed motes are ignored."""
        events: list[GuideEvent] = []
        if not len(mote):
            return events
        for m in np.unique(mote):
            m = int(m)
            if self.follow is not None and m != self.follow:
                continue
            sel = mote == m
            events += self._capture(m).update(seq[sel], raw[sel])
        return events

    def arm(self) -> None:
        for cap in self.captures.values():
            cap.arm()

    @property
    def done(self) -> bool:
        return bool(self.captures) and all(c.done for c in self.captures.values())

    def status(self) -> list[dict]:
        return [self.captures[m].status() for m in sorted(self.captures)]


FLOWS = {"static80": PoseCapture, "adaptive": AdaptiveCapture, "rotation": RotationCapture}
