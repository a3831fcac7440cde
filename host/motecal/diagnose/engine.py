"""The diagnosis: the four questions, in order, for one mote's session.

1. what the simulation gets wrong -- the paper's starting model fitted, the
   session simulated with it, statistics side by side (``compare``);
2. the cause -- screens on the raw readings and nested fits (``screens``,
   ``structure``), named from the vocabulary (``causes``) with evidence;
3. the extension -- the kept terms as a simulator model file (``extend``);
4. the gain -- held-out rms before/after per term, and how much closer the
   simulated statistics come (``gain``, ``compare``).
"""
from __future__ import annotations

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


# ---------------------------------------------------------------------------
# the diagnosis
# ---------------------------------------------------------------------------
def diagnose(data: SessionData, *, alpha: float = G.DEFAULT_ALPHA, seed: int = 0,
             simulate: bool = True, force: set | None = None) -> Diagnosis:
    """Diagnose one mote's session (see the module doc).

    ``force``: a set of (sensor, cause) to keep without testing (and nothing
    else) -- used to refit a diagnosis' terms on half of the data."""
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
    n_tests = len(plan)
    notes: list[str] = []
    if still is not None:
        notes.append("session: " + describe(data, still))
    a_test = G.per_test_alpha(alpha, n_tests)
    tests: list[dict] = []
    findings: list[Finding] = []
    screens: list[SC.Screen] = []

    def decide(sensor, cause, p, g, practical=True, fitted=True, wins=None, paired_p=None):
        if force is not None:
            return (sensor, cause) in force
        return G.accepted(p, a_test, g if fitted else None, practical, wins, paired_p)

    def record(sensor, cause, p, kept, **kw):
        tests.append({"sensor": sensor, "cause": cause, "p": _num(p), "level": _num(a_test),
                      "kept": bool(kept), **kw})

    # -- screens on raw readings ----------------------------------------------------
    stale_on, clip_rows = {}, {}
    for s, o in obs.items():
        sc = SC.stale_samples(o, o.rate)
        if sc is not None:
            g = sc.gain()
            kept = decide(s, "stale_samples", sc.p, g, sc.practical, fitted=False)
            record(s, "stale_samples", sc.p, kept, effect=sc.effect)
            if kept:
                stale_on[s] = sc
                screens.append(sc)
        sat = SC.saturation(o, X.SIM_LIMITS[s])
        if sat is not None:
            g = sat.gain()
            kept = decide(s, "saturation", sat.p, g, sat.practical, fitted=False)
            record(s, "saturation", sat.p, kept, effect=sat.effect)
            if kept:
                screens.append(sat)
                rows = o.overflow.copy()
                for h in sat.evidence.get("limits", []):
                    rows |= o.x[:, "xyz".index(h["axis"])] == h["limit_counts"]
                clip_rows[s] = rows
    mot = None
    if ("accel", "motion") in plan:
        mot = SC.motion(obs["accel"], obs["gyro"], True)
        if mot is not None:
            kept = decide("accel", "motion", mot.p, mot.gain(), mot.practical, fitted=False)
            record("accel", "motion", mot.p, kept, effect=mot.effect)
            if not kept:
                mot = None
            else:
                screens.append(mot)

    # sensors with repeats are analysed on their unique updates
    sobs = dict(obs)
    for s in stale_on:
        o2 = sensor_obs(data, s, dedup=True, still=still)
        if o2 is not None:
            sobs[s] = o2
            if s in clip_rows:
                keep_rows = np.isin(obs[s].rows, o2.rows)
                clip_rows[s] = clip_rows[s][keep_rows]

    # -- structure: nested fits ----------------------------------------------------------
    structures = {}
    for s in ("accel", "mag", "gyro"):
        if s == "gyro" and mot is not None:
            _turn_correct(sobs, structures, mot, notes)
        o = sobs.get(s)
        if o is None:
            continue
        r = regime(o)
        if r is None:
            why = ("a sweep that cannot determine a calibration ("
                   + "; ".join(sweep_reasons(o)) + ")"
                   if s == "mag" and o.moving is not None and o.moving.sum() >= MIN_SWEEP_ROWS
                   else "no still segments and no sweep")
            notes.append(f"{s}: {why}: only the raw-reading screens ran")
            continue
        cands = [c for (ss, c) in plan if ss == s and c in CANDIDATES[r]]
        level = a_test
        if force is not None:
            cands = [c for c in cands if (s, c) in force]
            level = 1.01
        st = None
        if r in ("poses", "sweep"):
            st = ST.analyse_magnitude(o, r, cands, level, drop_rows=clip_rows.get(s))
        elif r == "single":
            st = ST.analyse_linear(o, cands, level, per_orientation=True)
        else:
            acc_g = accel_for_blocks(o, structures.get("accel"), sobs.get("accel"))
            drop = None
            if s in clip_rows:
                drop = np.array([clip_rows[s][g].any() for g in o.blocks.rows])
            if o.blocks is not None and o.blocks.var is not None:
                # blocks whose turn could not be measured (turns): left out
                bad = ~np.all(np.isfinite(o.blocks.var), axis=1)
                drop = bad if drop is None else drop | bad
            st = ST.analyse_linear(o, [c for c in cands if acc_g is not None
                                       or c != "g_sensitivity"], level, accel_g=acc_g,
                                   drop_blocks=drop)
        if st is None:
            notes.append(f"{s}: too few points for the {r} analysis")
            continue
        structures[s] = st
        if "bias_drift" in st.causes and not isinstance(st.fit, F.MagnitudeFit):
            st.random_walk = ST.random_walk(st, o)
            RW.krige_drift_gain(st, o)
        for t in st.tests:
            record(s, t.cause, t.p, False, F=t.F, q=t.q, dof=t.dof, dbic=t.dbic, round=t.round)
        for c in st.causes:
            before, after = st.heldout.get(c, (None, None))
            g = before / after if before and after else None
            ok = decide(s, c, min(t.p for t in st.tests if t.cause == c), g,
                        wins=st.fold_wins.get(c), paired_p=st.heldout_p.get(c))
            for t in tests:
                if t["sensor"] == s and t["cause"] == c:
                    t["kept"] = ok
            if ok:
                findings.append(TM.term_finding(s, c, st, o, g, before, after))
            else:
                notes.append(f"{s}: {c} passed the F-test but not the held-out check "
                             f"(gain {g if g is None else round(g, 3)}, better in "
                             f"{st.fold_wins.get(c)} of {ST.KFOLD} folds"
                             + (f", held-out points' paired test p {st.heldout_p[c]:.2g}"
                                if st.heldout_p.get(c) is not None else "") + "); not kept")
        fd = LO.excess_finding(s, st, o, sobs, structures, a_test, record, mot, force)
        if fd is not None:
            findings.append(fd)

    # one orientation: an accelerometer "drift" that turns the reading without
    # changing its length is the board tilting (motion), not a bias
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
                    findings = [g for g in findings if (g.sensor, g.cause) != ("mag", "bias_drift")]
                    notes.append("mag: its drift in one orientation is the same slow tilt "
                                 "(it turns with the accelerometer): not a bias drift")
                break

    # temperature (issue 16): a drift that follows the board temperature
    temp_tests = {}
    for s in ("accel", "gyro", "mag"):
        if (s, "temperature") not in plan or s not in sobs:
            continue
        tt = (TH.make_pose_test(data, sobs[s], structures.get(s))
              if regime(sobs[s]) == "poses" else TH.make_test(data, sobs[s], regime(sobs[s])))
        if tt is None:
            continue
        TH.run_test(tt, a_test)
        if force is not None:
            tt.named = (s, "temperature") in force
            tt.keep_drift = (s, "bias_drift") in force
        temp_tests[s] = tt
        record(s, "temperature", min(tt.p_T, tt.p_T_D), tt.named, p_temperature=tt.p_T,
               p_temperature_beyond_time=tt.p_T_D, p_time_beyond_temperature=tt.p_D_T)
        if not tt.named:
            continue
        ev, params, g = TH.finding_parts(tt)
        findings.append(Finding(s, "temperature", C.summary(
            s, "temperature", ev, params, g, ev["heldout_rms_before"], ev["heldout_rms_after"],
            TH.UNITS[s]), ev, params, g))
        if not tt.keep_drift and (s, "bias_drift") in {(f.sensor, f.cause) for f in findings}:
            findings = [f for f in findings if (f.sensor, f.cause) != (s, "bias_drift")]
            notes.append(f"{s}: its drift follows the board temperature (the time basis adds "
                         f"nothing on top of it, p = {tt.p_D_T:.2g}): named temperature, not "
                         f"bias_drift")

    # saturation in static poses: the gain on the pose means (censored)
    for sc in screens:
        if sc.cause == "saturation" and sc.sensor in structures and sc.sensor in clip_rows:
            sg = ST.saturation_gain(structures[sc.sensor], sobs[sc.sensor],
                                    clip_rows[sc.sensor], sc.evidence.get("limits", []))
            if sg is not None:
                sc.fixed_gain = sg
                sc.gain_unit = "held-out rms of the pose-mean magnitude residual, clipped " \
                               "poses censored"

    # screens become findings (after the structure, so that mag disturbance can veto)
    for sc in screens:
        sensor = "accel" if sc.cause == "motion" else sc.sensor
        b, a = sc.rms()
        ev = dict(sc.evidence)
        ev.update({"p": _num(sc.p), "level": _num(a_test), "gain_basis": sc.gain_unit,
                   "heldout_rms_before": b, "heldout_rms_after": a})
        if sc.cause == "motion":
            ev["sensors"] = ["accel", "gyro"]
            tilt = next((f for f in findings if f.cause == "motion"), None)
            if tilt is not None:               # a slow tilt already named: add the tremor
                tilt.evidence["tremor"] = ev
                continue
        findings.append(Finding(sensor, sc.cause, C.summary(sensor, sc.cause, ev, sc.params,
                                                            sc.gain(), b, a), ev, sc.params,
                                sc.gain()))

    # the magnetometer: a strongly disturbed field voids its calibration terms
    fdist = [f for f in findings if f.sensor == "mag" and f.cause == "field_disturbance"]
    if fdist and fdist[0].evidence.get("untrustworthy"):
        dropped = [f.cause for f in findings if f.sensor == "mag"
                   and f.cause in ("cross_axis", "nonlinearity", "bias_drift", "unexplained")]
        findings = [f for f in findings if not (f.sensor == "mag" and f.cause in dropped)]
        if dropped:
            notes.append("mag: the field changes too much for a calibration: "
                         + ", ".join(dropped) + " not reported")

    # a field the Earth cannot give: the scale (gain setting, chip) or the place
    mst = structures.get("mag")
    if mst is not None and isinstance(mst.fit, F.MagnitudeFit):
        why = field_plausibility(mst.fit.field_magnitude(), sobs["mag"].chip)
        if why:
            notes.append(f"mag: {why}")

    order = {c: i for i, c in enumerate(C.ORDER)}
    findings.sort(key=lambda f: ({"accel": 0, "gyro": 1, "mag": 2}[f.sensor], order[f.cause]))
    start_model, model = X.models(data, obs, sobs, structures, findings, screens, mot)
    d = Diagnosis(data.name, motes[0], data.kind, findings, tests, alpha, n_tests, model,
                  start_model, structures, screens, sobs, notes=notes, temperature=temp_tests)
    if simulate:
        from .compare import comparison
        d.comparison = comparison(data, d, seed=seed, rediagnose=diagnose)
    return d


# ---------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------
TURN_SLOPE = (0.5, 2.0)  # the motion screen's slope: gyro and accelerometer agree about turns


def _turn_correct(sobs: dict, structures: dict, mot, notes: list) -> None:
    """The board turned inside its still segments (tremor: the motion screen
    kept, its gyro and accelerometer agreeing about turns): each gyro block's
    mean carries the net turn.  The accelerometer and magnetometer, through
    their fitted calibrations, measure it, and the gyro's analysis works on
    the bias with that turn taken out (``turns``).  A sensor without a fitted
    calibration (one orientation) is used as read only if it is the
    accelerometer (its offsets are small next to gravity; a magnetometer's
    hard iron is not)."""
    g = sobs.get("gyro")
    if g is None or not TURN_SLOPE[0] < mot.evidence.get("slope_accel_on_gyro", 0) < TURN_SLOPE[1]:
        return
    refs = []
    for s in ("accel", "mag"):
        o, st = sobs.get(s), structures.get(s)
        if o is None:
            continue
        if st is not None and isinstance(st.fit, F.MagnitudeFit):
            refs.append((o, lambda x, t, fit=st.fit: fit.calibrate(x, np.broadcast_to(t, len(x)))))
        elif s == "accel":
            refs.append((o, lambda x, t, K=o.K: x / K))
    g2 = turn_corrected(g, refs)
    if g2 is not None:
        sobs["gyro"] = g2
        notes.append(f"gyro: the board turned inside its still segments (motion): the bias of "
                     f"{g2.turn_corrected} blocks is the rate less the turn that "
                     f"{' and '.join(s for s in ('accel', 'mag') if any(r[0] is sobs.get(s) for r in refs))}"
                     f" measured over each (their whole paths against the gyro's)"
                     + (f"; {g2.turn_left_out} blocks too short to measure left out"
                        if g2.turn_left_out else ""))
