"""The truth a planted case is judged against, from the planted parameters only
(issue 13 part 1).  A test and bench helper (``import truth``), beside
``plant``.

The diagnosis' gain of a term is held-out rms before / after: "before" the
model without the term, "after" with the fitted term.  The truth's gain is
the same "before" over what a *perfect* treatment of the planted effect
leaves, measured, not assumed:

* terms that change the mean (cross_axis, nonlinearity, bias_drift,
  g_sensitivity, the field's wander in a sweep) and saturation in static
  poses: the session is simulated again with the same seed *without* the
  planted term (the simulator's noise streams do not depend on the other
  terms, so the twin holds the same noise), and the same held-out rms of the
  same model (every other kept term, forced) is measured on the twin.  The
  ratio fitted gain / truth's gain is then (rms the true model leaves) /
  (rms the fitted term leaves), both on held-out data;
* spread terms predict the same held-out statistic from the planted effect in
  place of the fitted one: repeats from the planted update rate, tremor from
  the planted rms and bandwidth, field scatter between poses from the
  scatter that was really planted (each pose's residual minus its twin's);
* a random walk (the gyroscope's idle drift) is a stochastic term: the
  true model's best held-out prediction is the walk's conditional mean given
  the other blocks with the *planted* intensity (kriging,
  ``structure.heldout_random_walk``), so that is its "after";
* clipping outside static poses (the gyroscope in moves) has no held-out
  prediction that is not the reading itself: its truth is the planted limit,
  reported as the limit error, not as a gain (``limit_error``).

Nothing here reads a finding's fitted parameters or its gain.
"""
from __future__ import annotations

import numpy as np

import plant as P

from motecal.diagnose.engine import diagnose

MEAN_TERMS = ("cross_axis", "nonlinearity", "bias_drift", "g_sensitivity")


def twin(plants: list, drop, kind: str, seed: int, labelled: bool = True, sim=None):
    """The same session (same seed, trajectory and noise) without ``drop``;
    ``sim(plants)`` simulates sessions that ``plant.simulate`` does not (hand
    sessions, long holds)."""
    keep = [P.Plant(q.cause, q.sensor, q.kind, q.size, dict(q.term), q.level, dict(q.truth))
            for q in plants if q is not drop]
    if sim is not None:
        return sim(keep)
    return P.simulate(keep, kind, seed, labelled=labelled)


def _twin_rms(diag, plant, plants, kind, seed, labelled, sim=None):
    """Held-out rms that the diagnosis' model without the planted term leaves
    on the twin session (every other kept term forced)."""
    force = diag.causes() - {(plant.sensor, plant.cause)}
    d0 = diagnose(twin(plants, plant, kind, seed, labelled, sim), simulate=False, force=force)
    st = d0.structures.get(plant.sensor)
    if st is None or st.heldout_total is None:
        return None
    return st.heldout_total[1]


def truth_gain(diag, plant, plants: list, kind: str, seed: int,
               labelled: bool = True, sim=None) -> float | None:
    """The truth's held-out gain of ``plant`` (see the module doc), or None
    when the diagnosis did not name it or no independent truth exists."""
    f = next((f for f in diag.findings if f.cause == plant.cause and f.sensor == plant.sensor),
             None)
    if f is None:
        return None
    st = diag.structures.get(plant.sensor)
    if plant.cause in MEAN_TERMS or (plant.cause == "field_disturbance"
                                     and "rms_gauss" in plant.term):
        if st is None:
            return None
        if plant.cause in st.heldout:
            before = st.heldout[plant.cause][0]
        elif plant.cause == "bias_drift" and st.heldout_total is not None:
            before = st.heldout_total[1]          # a walk named from the excess
        else:
            return None
        if plant.cause == "bias_drift" and "sigma" in plant.term:
            after = _random_walk_truth(diag, plant)
        else:
            after = _twin_rms(diag, plant, plants, kind, seed, labelled, sim)
        return before / after if after else None
    if plant.cause == "saturation":
        sc = next((s for s in diag.screens if s.cause == "saturation"
                   and s.sensor == plant.sensor), None)
        if sc is None or sc.fixed_gain is None:
            return None                       # no gain basis independent of the reading
        after = _twin_rms(diag, plant, plants, kind, seed, labelled, sim)
        return sc.fixed_gain[1] / after if after else None
    if plant.cause == "stale_samples":
        sc = next(s for s in diag.screens if s.cause == "stale_samples"
                  and s.sensor == plant.sensor)
        rho = plant.term["update_hz"] / f.evidence["read_rate_hz"]
        after = (1 - rho) + rho * f.evidence["chance_fraction"]
        b = np.sqrt(np.mean((sc.block_stat - sc.pred_before) ** 2))
        a = np.sqrt(np.mean((sc.block_stat - after) ** 2))
        return float(b / a) if a > 0 else None
    if plant.cause == "field_disturbance":
        # the pose-to-pose field scatter that was really planted: each pose's
        # residual minus the same pose's residual in the twin without it;
        # its variance on the training poses is the true term's prediction
        from motecal.diagnose import gain as G
        from motecal.diagnose.prepare import sensor_obs
        X, T = st.points["X"], st.points["T"]
        r = st.fit.residuals(X, T)
        o0 = sensor_obs(twin(plants, plant, kind, seed, labelled, sim), plant.sensor)
        if o0 is None or o0.segs is None or len(o0.segs) <= st.points["group"].max():
            return None
        r0 = st.fit.residuals(o0.segs.mean[st.points["group"]], T)
        dist = r - r0
        g, _, _ = G.variance_gain(r, st.points["V"], st.points["fold"],
                                  lambda m: float(np.mean(dist[m] ** 2)))
        return g
    if plant.cause == "motion":
        from motecal.sim.physics import K_NOMINAL
        sc = next((s for s in diag.screens if s.cause == "motion"), None)
        if sc is None:
            return None
        B = plant.term["bandwidth_hz"]
        lo = min(0.1, B / 2)
        ef2 = (B ** 3 - lo ** 3) / (3 * (B - lo))
        rate_var = (plant.term["rms_deg"] * 2 * np.pi) ** 2 * ef2 * K_NOMINAL["gyro"] ** 2
        b = np.sqrt(np.mean((sc.block_stat - sc.pred_before) ** 2))
        a = np.sqrt(np.mean((sc.block_stat - rate_var) ** 2))
        return float(b / a) if a > 0 else None
    return None


def limit_error(diag, plant) -> float | None:
    """Saturation: |fitted limit - planted limit| in counts on the planted axis."""
    if plant.cause != "saturation":
        return None
    f = next((f for f in diag.findings if f.cause == "saturation"
              and f.sensor == plant.sensor), None)
    if f is None or "limit" not in plant.truth:
        return None
    a = plant.truth["axis"]
    key = "high" if plant.truth["side"] > 0 else "low"
    return abs(float(f.params[key][a]) - float(plant.truth["limit"]))


def _random_walk_truth(diag, plant):
    """gyro random walk: the true model (a constant bias + a walk of the
    planted intensity, in counts/sqrt(s)) predicting each held-out block
    from the others, kriging with the planted sigma."""
    import dataclasses

    from motecal.diagnose import structure as ST
    st = diag.structures.get(plant.sensor)
    o = diag.obs.get(plant.sensor)
    if st is None or o is None:
        return None
    true = dataclasses.replace(st, accepted=[])
    kr = ST.heldout_random_walk(true, o, np.asarray(plant.term["sigma"], float))
    return None if kr is None else kr[0]
