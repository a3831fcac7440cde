"""The human-readable summary of a diagnosis (what ``motecal diagnose``
prints and ``--report`` writes as summary.txt)."""
from __future__ import annotations

import textwrap

from .gain import MIN_FOLD_WINS, per_test_alpha


def _fmt(v):
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def render(d) -> str:
    """The human-readable summary of one diagnosis."""
    out = [f"session {d.session}  mote {d.mote}  kind {d.kind}"]
    level = per_test_alpha(d.alpha, d.n_tests)
    comp = d.comparison or {}
    whole = comp.get("whole")
    out.append("")
    out.append("1. What the simulation gets wrong (the paper's model fitted to the session, "
               "the session simulated with it):")
    if whole:
        rows = {(r["sensor"], r["statistic"]): r for r in whole["table"]}
        worst = sorted(whole["per_stat"].items(), key=lambda kv: -kv[1])[:8]
        out.append(f"   {'statistic':<28}{'measured':>12}{'simulated':>12}  distance")
        for key, dist in worst:
            s, k = key.split(".", 1)
            r = rows.get((s, k), {})
            out.append(f"   {s + ' ' + k:<28}{_fmt(r.get('measured')):>12}"
                       f"{_fmt(r.get('simulated_paper')):>12}  {dist:.2f}")
        out.append(f"   overall distance {whole['distance_paper']:.3f} "
                   f"(rms |log measured/simulated| over {len(whole['per_stat'])} statistics)")
    else:
        out.append("   (no simulation: " + comp.get("note", "--no-sim") + ")")
    out.append("")
    out.append(f"2-4. Causes, extension and gain ({d.n_tests} tests; a finding needs "
               f"p < {d.alpha:g}/{d.n_tests} = {level:.2g}, and a fitted term a held-out "
               f"gain > 1 in >= {MIN_FOLD_WINS} of 5 folds, or under tremor by a paired "
               f"test of its held-out points):")
    if d.clean:
        out.append("   clean: nothing beyond the paper's starting model.")
    for f in d.findings:
        out.append("")
        out.append(textwrap.fill(f"[{f.sensor}] {f.cause}: {f.summary}", width=96,
                                 initial_indent="   ", subsequent_indent="   "))
    ho = comp.get("heldout")
    if ho and "distance_extended" in ho:
        out.append("")
        out.append(f"   Simulated statistics on the held-out half: distance "
                   f"{ho['distance_paper']:.3f} (paper) -> {ho['distance_extended']:.3f} "
                   f"(extended)" + (f", {ho['gain']:.3g}x closer." if ho.get("gain") else "."))
    for n in d.notes:
        out.append(textwrap.fill("note: " + n, width=96, initial_indent="   ",
                                 subsequent_indent="         "))
    return "\n".join(out)
