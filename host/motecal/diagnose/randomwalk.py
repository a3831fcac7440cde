"""A bias that wanders as a random walk (docs/diagnosis-method.md, "A
gyroscope random walk").

* ``krige_drift_gain``: on top of a kept smooth drift, a walk finer than its
  basis is predicted on held-out blocks from the other blocks (kriging with
  the restricted-likelihood intensity); the drift's held-out gain is the
  better of the basis alone and basis + walk.
* ``random_walk_finding``: block means that scatter beyond their noise with
  no smooth drift kept: a walk that passes the restricted likelihood-ratio
  test and predicts held-out blocks better is named ``bias_drift``.
"""
from __future__ import annotations

import numpy as np

from . import causes as C
from . import extend as X
from . import gain as G
from . import structure as ST
from .prepare import SensorObs
from .result import Finding

def krige_drift_gain(st: ST.Structure, o: SensorObs):
    """A random walk finer than the drift's basis is predicted on held-out
    blocks by its conditional mean given the other blocks (kriging with the
    restricted-likelihood intensity): the drift's held-out "after" is the
    better of the smooth basis alone and the basis + walk."""
    rw = getattr(st, "random_walk", None)
    if rw is None or not np.any(np.asarray(rw["sigma_counts_per_sqrt_s"]) > 0):
        return
    kr = ST.heldout_random_walk(st, o, rw["sigma_counts_per_sqrt_s"])
    before, after = st.heldout["bias_drift"]
    if kr is None or not kr[0] < after:
        return
    item = next(c for c in st.accepted if ST.cause_of(c) == "bias_drift")
    without = getattr(st, "fold_ms", {}).get(frozenset(st.accepted) - {item})
    st.heldout["bias_drift"] = (before, kr[0])
    if without is not None:
        st.fold_wins["bias_drift"] = int(np.sum(kr[1] < without))
    st.heldout_total = (st.heldout_total[0], kr[0])
    st.kriged = True


def random_walk_finding(s, st: ST.Structure, o: SensorObs, a_test) -> Finding | None:
    """Block means that scatter beyond their noise with no smooth drift: a
    bias random walk (restricted likelihood ratio against no walk) that
    predicts held-out blocks from their neighbours (kriging) better than the
    model without it, overall and in MIN_FOLD_WINS folds, is a bias_drift."""
    rw = ST.random_walk(st, o)
    if rw is None or not rw["lr_p"] < a_test:
        return None
    sig = np.asarray(rw["sigma_counts_per_sqrt_s"], float)
    kr = ST.heldout_random_walk(st, o, sig)
    base = getattr(st, "fold_ms", {}).get(frozenset(st.accepted))
    if kr is None or base is None or st.heldout_total is None:
        return None
    before, after = st.heldout_total[1], kr[0]
    g = before / after if after > 0 else None
    wins = int(np.sum(kr[1] < base))
    if not G.accepted(rw["lr_p"], a_test, g, True, wins):
        return None
    span = float(np.ptp(st.points["T"]))
    ev = {"p": rw["lr_p"], "level": a_test, "likelihood_ratio": rw["lr"], "regime": st.regime,
          "heldout_rms_before": before, "heldout_rms_after": after, "unit": st.unit,
          "noise_floor": st.noise_floor, "points": int(len(st.points["Y"])),
          "random_walk_sigma_counts_per_sqrt_s": sig,
          "drift_range": float(sig.max() * np.sqrt(span) / o.K),
          "basis": "a random walk (restricted likelihood)",
          "gain_basis": "held-out rms of block means (interleaved time blocks), the walk "
                        "predicted from the neighbouring blocks (kriging)"}
    params = {"amplitude": [0.0, 0.0, 0.0], "tau_s": 300.0, "slope": [0.0, 0.0, 0.0],
              "sigma": X._r(sig * X.sim_scale(s, o.K))}
    summ = (f"The {s} bias wanders as a random walk: {X._r(sig)} counts/sqrt(s) per axis "
            f"(restricted likelihood ratio {rw['lr']:.1f}, p = {rw['lr_p']:.2g}), about "
            f"{C._fmt(ev['drift_range'], st.unit)} over the session. Gain on held-out data: "
            f"{g:.3g}x (rms {C._fmt(before, st.unit)} -> {C._fmt(after, st.unit)}).")
    return Finding(s, "bias_drift", summ, ev, params, g)
