"""The diagnosis of one mote's session, in stages
(docs/diagnosis-method.md, "The stages"):

    observe -> screen -> structure -> test -> name -> extend -> compare

``diagnose`` calls one function per stage; what a stage hands to the next is
the ``State`` (each field says which stage sets it).  The four questions of
``motecal diagnose`` (docs/diagnose.md) are answered along the way:

1. what the simulation gets wrong -- ``compare``: the paper's starting model
   fitted, the session simulated with it, statistics side by side;
2. the cause -- ``screen`` (raw readings: ``screens``), ``structure`` (nested
   fits per sensor: ``structure``, ``terms``, ``leftover``), ``test``
   (tilt or drift: ``tilt``; temperature or time: ``thermal``) and ``name``
   (the findings complete), named from the vocabulary (``causes``);
3. the extension -- ``extend``: the kept terms as a simulator model file;
4. the gain -- held-out rms before/after per term, measured where each term
   is decided (``gain``), and in ``compare`` how much closer the extended
   model's simulated statistics come on the held-out half.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..calib.content import describe
from ..calib.gate import field_plausibility
from ..errors import QualityError, UserError
from ..sessions.session import SessionData
from . import causes as C
from . import extend as X
from . import fitting as F
from . import gain as G
from . import leftover as LO
from . import randomwalk as RW
from . import screens as SC
from . import structure as ST
from . import terms as TM
from . import thermal as TH
from . import tilt as TL
from .prepare import all_obs, sensor_obs, session_still
from .regimes import (CANDIDATES, MIN_SWEEP_ROWS, accel_for_blocks, plan_tests, regime,
                      sweep_reasons)
from .result import Diagnosis, Finding, num as _num
from .turns import turn_corrected

TURN_SLOPE = (0.5, 2.0)  # the motion screen's slope: gyro and accelerometer agree about turns


def diagnose(data: SessionData, *, alpha: float = G.DEFAULT_ALPHA, seed: int = 0,
             simulate: bool = True, force: set | None = None) -> Diagnosis:
    """Diagnose one mote's session (see the module doc).

    ``force``: a set of (sensor, cause) to keep without testing (and nothing
    else) -- used to refit a diagnosis' terms on half of the data."""
    state = observe(data, alpha, force)
    screen(state)
    structure(state)
    test(state)
    name(state)
    d = extend(state)
    if simulate:
        compare(d, data, seed)
    return d


# ---------------------------------------------------------------------------
# the state between the stages
# ---------------------------------------------------------------------------
@dataclass
class State:
    """One diagnosis in progress.  ``observe`` sets the fields up to
    ``notes``; the others are filled by the stage their comment names.
    ``tests`` and ``notes`` grow in every stage, in the order the tests and
    remarks arise (that order is the report's)."""
    data: SessionData
    alpha: float
    force: set | None              # (sensor, cause) kept without testing, nothing else
    still: np.ndarray | None       # the session's still stretches when no row has a pose label
    obs: dict                      # sensor -> prepare.SensorObs, every reading
    plan: list                     # every (sensor, cause) tested: their count sets the level
    a_test: float                  # the per-test level (Bonferroni over the plan)
    notes: list
    tests: list = field(default_factory=list)         # every test: sensor, cause, p, level, kept
    screens: list = field(default_factory=list)       # screen: the kept screens
    stale_on: dict = field(default_factory=dict)      # screen: sensor -> its kept stale_samples
    clip_rows: dict = field(default_factory=dict)     # screen: sensor -> clipped rows (of sobs)
    motion: SC.Screen | None = None                   # screen: the kept motion screen
    sobs: dict = field(default_factory=dict)          # screen: the observations analysed
    #   (a sensor with repeats on its unique updates; structure: the gyro turn-corrected)
    structures: dict = field(default_factory=dict)    # structure: sensor -> ST.Structure
    findings: list = field(default_factory=list)      # structure, test, name
    temperature: dict = field(default_factory=dict)   # test: sensor -> thermal.TempTest

    @property
    def n_tests(self) -> int:
        return len(self.plan)

    def decide(self, sensor, cause, p, g, practical=True, fitted=True, wins=None,
               paired_p=None) -> bool:
        """The criterion (``gain.accepted``), or the forced set."""
        if self.force is not None:
            return (sensor, cause) in self.force
        return G.accepted(p, self.a_test, g if fitted else None, practical, wins, paired_p)

    def record(self, sensor, cause, p, kept, **kw) -> None:
        self.tests.append({"sensor": sensor, "cause": cause, "p": _num(p),
                           "level": _num(self.a_test), "kept": bool(kept), **kw})


# ---------------------------------------------------------------------------
# 1. observe: what the session allows
# ---------------------------------------------------------------------------
def observe(data: SessionData, alpha: float, force: set | None) -> State:
    """Each sensor's observations (still segments or poses, time blocks,
    noise: ``prepare``) and the plan of tests they allow (``regimes``, with
    ``temperature`` where the session's temperature span allows it); their
    count sets the per-test level."""
    motes = data.motes
    if len(motes) != 1:
        raise UserError(f"session {data.name} holds motes {motes}: diagnose one mote at a "
                        f"time (--mote)")
    if not 0 < alpha < 1:
        raise UserError(f"--alpha must be within 0..1, not {alpha}")
    still = session_still(data)
    obs = all_obs(data, still=still)
    if not obs:
        raise QualityError(f"session {data.name}: no sensor readings to diagnose")
    plan = plan_tests(obs)
    plan += [(s, "temperature") for s, o in obs.items()           # issue 16
             if TH.testable(data, o, regime(o))]
    notes: list[str] = []
    if still is not None:
        notes.append("session: " + describe(data, still))
    return State(data, alpha, force, still, obs, plan, G.per_test_alpha(alpha, len(plan)),
                 notes)


# ---------------------------------------------------------------------------
# 2. screen: the raw readings
# ---------------------------------------------------------------------------
def screen(state: State) -> None:
    """Repeated readings and clipping on every sensor, the accelerometer
    following the gyroscope's turns (``motion``) inside the still segments
    (``screens``), each kept by the criterion; then a sensor with repeats is
    observed again on its unique updates (``state.sobs``)."""
    obs = state.obs
    for s, o in obs.items():
        sc = SC.stale_samples(o, o.rate)
        if sc is not None:
            g = sc.gain()
            kept = state.decide(s, "stale_samples", sc.p, g, sc.practical, fitted=False)
            state.record(s, "stale_samples", sc.p, kept, effect=sc.effect)
            if kept:
                state.stale_on[s] = sc
                state.screens.append(sc)
        sat = SC.saturation(o, X.SIM_LIMITS[s])
        if sat is not None:
            g = sat.gain()
            kept = state.decide(s, "saturation", sat.p, g, sat.practical, fitted=False)
            state.record(s, "saturation", sat.p, kept, effect=sat.effect)
            if kept:
                state.screens.append(sat)
                rows = o.overflow.copy()
                for h in sat.evidence.get("limits", []):
                    rows |= o.x[:, "xyz".index(h["axis"])] == h["limit_counts"]
                state.clip_rows[s] = rows
    if ("accel", "motion") in state.plan:
        mot = SC.motion(obs["accel"], obs["gyro"], True)
        if mot is not None:
            kept = state.decide("accel", "motion", mot.p, mot.gain(), mot.practical,
                                fitted=False)
            state.record("accel", "motion", mot.p, kept, effect=mot.effect)
            if kept:
                state.motion = mot
                state.screens.append(mot)

    # sensors with repeats are analysed on their unique updates
    state.sobs = dict(obs)
    for s in state.stale_on:
        o2 = sensor_obs(state.data, s, dedup=True, still=state.still)
        if o2 is not None:
            state.sobs[s] = o2
            if s in state.clip_rows:
                keep_rows = np.isin(obs[s].rows, o2.rows)
                state.clip_rows[s] = state.clip_rows[s][keep_rows]


# ---------------------------------------------------------------------------
# 3. structure: nested fits per sensor
# ---------------------------------------------------------------------------
def structure(state: State) -> None:
    """Per sensor (accelerometer, magnetometer, then the gyroscope, whose
    specific force and turns come from the other two): the nested fits of
    its regime's candidates (``structure``), each fitted term kept by its
    test and the held-out check (``terms``), then the scatter left
    (``leftover``)."""
    for s in ("accel", "mag", "gyro"):
        if s == "gyro" and state.motion is not None:
            _turn_correct(state)
        o = state.sobs.get(s)
        if o is None:
            continue
        r = regime(o)
        if r is None:
            why = ("a sweep that cannot determine a calibration ("
                   + "; ".join(sweep_reasons(o)) + ")"
                   if s == "mag" and o.moving is not None and o.moving.sum() >= MIN_SWEEP_ROWS
                   else "no still segments and no sweep")
            state.notes.append(f"{s}: {why}: only the raw-reading screens ran")
            continue
        st = _fit(state, s, o, r)
        if st is None:
            state.notes.append(f"{s}: too few points for the {r} analysis")
            continue
        state.structures[s] = st
        if "bias_drift" in st.causes and not isinstance(st.fit, F.MagnitudeFit):
            st.random_walk = ST.random_walk(st, o)
            RW.krige_drift_gain(st, o)
        _keep_terms(state, s, st, o)
        fd = LO.excess_finding(s, st, o, state.sobs, state.structures, state.a_test,
                               state.record, state.motion, state.force)
        if fd is not None:
            state.findings.append(fd)


def _fit(state: State, s: str, o, r: str) -> ST.Structure | None:
    """The nested fits of one sensor's candidates in its regime (all of them
    at level 1.01 when forced)."""
    cands = [c for (ss, c) in state.plan if ss == s and c in CANDIDATES[r]]
    level = state.a_test
    if state.force is not None:
        cands = [c for c in cands if (s, c) in state.force]
        level = 1.01
    clip_rows = state.clip_rows
    if r in ("poses", "sweep"):
        return ST.analyse_magnitude(o, r, cands, level, drop_rows=clip_rows.get(s))
    if r == "single":
        return ST.analyse_linear(o, cands, level, per_orientation=True)
    acc_g = accel_for_blocks(o, state.structures.get("accel"), state.sobs.get("accel"))
    drop = None
    if s in clip_rows:
        drop = np.array([clip_rows[s][g].any() for g in o.blocks.rows])
    if o.blocks is not None and o.blocks.var is not None:
        # blocks whose turn could not be measured (turns): left out
        bad = ~np.all(np.isfinite(o.blocks.var), axis=1)
        drop = bad if drop is None else drop | bad
    return ST.analyse_linear(o, [c for c in cands if acc_g is not None
                                 or c != "g_sensitivity"], level, accel_g=acc_g,
                             drop_blocks=drop)


def _keep_terms(state: State, s: str, st: ST.Structure, o) -> None:
    """Every nested test recorded; each cause the fits selected is kept when
    it also passes the held-out check (a finding), else a note says why not."""
    for t in st.tests:
        state.record(s, t.cause, t.p, False, F=t.F, q=t.q, dof=t.dof, dbic=t.dbic,
                     round=t.round)
    for c in st.causes:
        before, after = st.heldout.get(c, (None, None))
        g = before / after if before and after else None
        ok = state.decide(s, c, min(t.p for t in st.tests if t.cause == c), g,
                          wins=st.fold_wins.get(c), paired_p=st.heldout_p.get(c))
        for t in state.tests:
            if t["sensor"] == s and t["cause"] == c:
                t["kept"] = ok
        if ok:
            state.findings.append(TM.term_finding(s, c, st, o, g, before, after))
        else:
            state.notes.append(
                f"{s}: {c} passed the F-test but not the held-out check "
                f"(gain {g if g is None else round(g, 3)}, better in "
                f"{st.fold_wins.get(c)} of {ST.KFOLD} folds"
                + (f", held-out points' paired test p {st.heldout_p[c]:.2g}"
                   if st.heldout_p.get(c) is not None else "") + "); not kept")


def _turn_correct(state: State) -> None:
    """The board turned inside its still segments (tremor: the motion screen
    kept, its gyro and accelerometer agreeing about turns): each gyro block's
    mean carries the net turn.  The accelerometer and magnetometer, through
    their fitted calibrations, measure it, and the gyro's analysis works on
    the bias with that turn taken out (``turns``).  A sensor without a fitted
    calibration (one orientation) is used as read only if it is the
    accelerometer (its offsets are small next to gravity; a magnetometer's
    hard iron is not)."""
    sobs, mot = state.sobs, state.motion
    g = sobs.get("gyro")
    if g is None or not TURN_SLOPE[0] < mot.evidence.get("slope_accel_on_gyro", 0) < TURN_SLOPE[1]:
        return
    refs = []
    for s in ("accel", "mag"):
        o, st = sobs.get(s), state.structures.get(s)
        if o is None:
            continue
        if st is not None and isinstance(st.fit, F.MagnitudeFit):
            refs.append((o, lambda x, t, fit=st.fit: fit.calibrate(x, np.broadcast_to(t, len(x)))))
        elif s == "accel":
            refs.append((o, lambda x, t, K=o.K: x / K))
    g2 = turn_corrected(g, refs)
    if g2 is not None:
        sobs["gyro"] = g2
        state.notes.append(
            f"gyro: the board turned inside its still segments (motion): the bias of "
            f"{g2.turn_corrected} blocks is the rate less the turn that "
            f"{' and '.join(s for s in ('accel', 'mag') if any(r[0] is sobs.get(s) for r in refs))}"
            f" measured over each (their whole paths against the gyro's)"
            + (f"; {g2.turn_left_out} blocks too short to measure left out"
               if g2.turn_left_out else ""))


# ---------------------------------------------------------------------------
# 4. test: between two explanations
# ---------------------------------------------------------------------------
def test(state: State) -> None:
    """The questions that need every sensor's structure first: is an
    accelerometer drift in one orientation the board tilting (``tilt``), and
    does a drift follow the board's temperature rather than time
    (``thermal``)?"""
    _tilt_or_drift(state)
    _temperature_or_time(state)


def _tilt_or_drift(state: State) -> None:
    """One orientation: an accelerometer "drift" that turns the reading
    without changing its length, with the magnetometer turning too, is the
    board tilting (motion), not a bias; the magnetometer's own "drift" is
    then the same tilt."""
    findings, structures, sobs = state.findings, state.structures, state.sobs
    for i, f in enumerate(findings):
        if f.sensor == "accel" and f.cause == "bias_drift" and \
                structures["accel"].regime == "single":
            tilt = TL.tilt_of_blocks(sobs["accel"])
            tilt.update(TL.tilt_in_mag(sobs["accel"], sobs.get("mag")))
            f.evidence.update(tilt)
            if TL.is_tilt(tilt):
                params = {"rms_deg": round(tilt["angle_rms_deg"], 5),
                          "bandwidth_hz": round(max(0.02, 2.0 / max(tilt["segment_s"], 1.0)), 4)}
                ev = dict(f.evidence, slow_tilt=True)
                summ = C.summary("accel", "motion", {**ev, "what": "slow"}, params, f.gain,
                                 ev.get("heldout_rms_before"), ev.get("heldout_rms_after"), "g")
                findings[i] = Finding("accel", "motion", summ, ev, params, f.gain)
                if ("mag", "bias_drift") in {(g.sensor, g.cause) for g in findings} and \
                        structures.get("mag") is not None and \
                        structures["mag"].regime == "single":
                    state.findings = [g for g in findings
                                      if (g.sensor, g.cause) != ("mag", "bias_drift")]
                    state.notes.append("mag: its drift in one orientation is the same slow "
                                       "tilt (it turns with the accelerometer): not a bias "
                                       "drift")
                break


def _temperature_or_time(state: State) -> None:
    """(issue 16) Per sensor the plan tests for it: a drift that follows the
    board temperature is named ``temperature``, and replaces the sensor's
    ``bias_drift`` when the time basis adds nothing on top of it."""
    data, sobs, structures = state.data, state.sobs, state.structures
    for s in ("accel", "gyro", "mag"):
        if (s, "temperature") not in state.plan or s not in sobs:
            continue
        tt = (TH.make_pose_test(data, sobs[s], structures.get(s))
              if regime(sobs[s]) == "poses" else TH.make_test(data, sobs[s], regime(sobs[s])))
        if tt is None:
            continue
        TH.run_test(tt, state.a_test)
        if state.force is not None:
            tt.named = (s, "temperature") in state.force
            tt.keep_drift = (s, "bias_drift") in state.force
        state.temperature[s] = tt
        state.record(s, "temperature", min(tt.p_T, tt.p_T_D), tt.named, p_temperature=tt.p_T,
                     p_temperature_beyond_time=tt.p_T_D, p_time_beyond_temperature=tt.p_D_T)
        if not tt.named:
            continue
        ev, params, g = TH.finding_parts(tt)
        state.findings.append(Finding(s, "temperature", C.summary(
            s, "temperature", ev, params, g, ev["heldout_rms_before"], ev["heldout_rms_after"],
            TH.UNITS[s]), ev, params, g))
        if not tt.keep_drift and \
                (s, "bias_drift") in {(f.sensor, f.cause) for f in state.findings}:
            state.findings = [f for f in state.findings if (f.sensor, f.cause) != (s, "bias_drift")]
            state.notes.append(f"{s}: its drift follows the board temperature (the time basis "
                               f"adds nothing on top of it, p = {tt.p_D_T:.2g}): named "
                               f"temperature, not bias_drift")


# ---------------------------------------------------------------------------
# 5. name: the findings complete
# ---------------------------------------------------------------------------
def name(state: State) -> None:
    """The kept screens become findings (after the structure: clipping in
    poses gets its gain on the pose means, and a tremor joins a slow tilt
    already named); a strongly disturbed field voids the magnetometer's
    calibration terms; a field the Earth cannot give is noted; the findings
    in the vocabulary's chain order."""
    _saturation_gain_in_poses(state)
    _screen_findings(state)
    _disturbed_field_veto(state)
    # a field the Earth cannot give: the scale (gain setting, chip) or the place
    mst = state.structures.get("mag")
    if mst is not None and isinstance(mst.fit, F.MagnitudeFit):
        why = field_plausibility(mst.fit.field_magnitude(), state.sobs["mag"].chip)
        if why:
            state.notes.append(f"mag: {why}")
    order = {c: i for i, c in enumerate(C.ORDER)}
    state.findings.sort(key=lambda f: ({"accel": 0, "gyro": 1, "mag": 2}[f.sensor],
                                       order[f.cause]))


def _saturation_gain_in_poses(state: State) -> None:
    """Saturation in static poses: the gain on the pose means (censored)."""
    for sc in state.screens:
        if sc.cause == "saturation" and sc.sensor in state.structures and \
                sc.sensor in state.clip_rows:
            sg = ST.saturation_gain(state.structures[sc.sensor], state.sobs[sc.sensor],
                                    state.clip_rows[sc.sensor], sc.evidence.get("limits", []))
            if sg is not None:
                sc.fixed_gain = sg
                sc.gain_unit = "held-out rms of the pose-mean magnitude residual, clipped " \
                               "poses censored"


def _screen_findings(state: State) -> None:
    """Each kept screen as a finding; the tremor of a board already named as
    slowly tilting goes into that finding's evidence."""
    for sc in state.screens:
        sensor = "accel" if sc.cause == "motion" else sc.sensor
        b, a = sc.rms()
        ev = dict(sc.evidence)
        ev.update({"p": _num(sc.p), "level": _num(state.a_test), "gain_basis": sc.gain_unit,
                   "heldout_rms_before": b, "heldout_rms_after": a})
        if sc.cause == "motion":
            ev["sensors"] = ["accel", "gyro"]
            tilt = next((f for f in state.findings if f.cause == "motion"), None)
            if tilt is not None:               # a slow tilt already named: add the tremor
                tilt.evidence["tremor"] = ev
                continue
        state.findings.append(Finding(sensor, sc.cause, C.summary(sensor, sc.cause, ev,
                                                                  sc.params, sc.gain(), b, a),
                                      ev, sc.params, sc.gain()))


def _disturbed_field_veto(state: State) -> None:
    """The magnetometer: a strongly disturbed field (the gate's 5 % rule)
    voids its calibration terms and leftover."""
    findings = state.findings
    fdist = [f for f in findings if f.sensor == "mag" and f.cause == "field_disturbance"]
    if fdist and fdist[0].evidence.get("untrustworthy"):
        dropped = [f.cause for f in findings if f.sensor == "mag"
                   and f.cause in ("cross_axis", "nonlinearity", "bias_drift", "unexplained")]
        state.findings = [f for f in findings if not (f.sensor == "mag" and f.cause in dropped)]
        if dropped:
            state.notes.append("mag: the field changes too much for a calibration: "
                               + ", ".join(dropped) + " not reported")


# ---------------------------------------------------------------------------
# 6. extend: the model files
# ---------------------------------------------------------------------------
def extend(state: State) -> Diagnosis:
    """The paper's starting model fitted to the session and the model the
    findings extend it to (``extend.models``), in the diagnosis."""
    data = state.data
    start_model, model = X.models(data, state.obs, state.sobs, state.structures,
                                  state.findings, state.screens, state.motion)
    return Diagnosis(data.name, data.motes[0], data.kind, state.findings, state.tests,
                     state.alpha, state.n_tests, model, start_model, state.structures,
                     state.screens, state.sobs, notes=state.notes,
                     temperature=state.temperature)


# ---------------------------------------------------------------------------
# 7. compare: the simulated statistics
# ---------------------------------------------------------------------------
def compare(d: Diagnosis, data: SessionData, seed: int) -> None:
    """The session simulated again with the starting model, its statistics
    beside the measured ones (question 1); both models fitted on one half
    and compared on the other (the whole model's gain): ``compare``."""
    from .compare import comparison
    d.comparison = comparison(data, d, seed=seed, rediagnose=diagnose)
