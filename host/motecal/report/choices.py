"""The report's section on what the calibration chose, per mote: the model
of each sensor and why (what the data determine), the data it came from,
its temperature term, the terms a diagnosis added, the readings set aside,
and the quality gate's verdict with each of its metrics against its limit.

Everything is read from the stored calibration (``BoardCalibration``: its
``settings``, each sensor's ``notes`` and ``quality``, ``gate``); the gate's
limits are ``calib.gate.LIMITS``.  The margins drawn are the stored metrics
over those limits; the verdict is the gate's own (``board.gate``).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from . import charts as C
from . import html as H
from .parts import Part
from .tables import Column

COLUMNS = [
    Column("mote", "mote"), Column("sensor", "sensor"), Column("model", "model"),
    Column("dataset", "data"), Column("poses", "poses"),
    Column("orientations", "distinct orientations (needed)"),
    Column("identifiable", "identifiable parameters"), Column("why", "why this model"),
    Column("temperature", "temperature term"), Column("diagnosis", "from the diagnosis"),
    Column("set_aside", "readings set aside")]
NOTES = ["why this model: the judgement of what the data determine when calibrate records "
         "it (settings.models), else the calibration's own notes on identifiability; a "
         "sensor the session could not calibrate is listed with the reason"]
DATASETS = {"O": "static poses (O)", "R": "sweep (R)", "still": "still poses"}
MARGIN_CAP = 5.0


def _why(name, sc, settings) -> str:
    chosen = (settings.get("models") or {}).get(name) or {}
    if chosen.get("why"):
        return str(chosen["why"])
    keys = ("identifiable", "moves between", "matrix", "model")
    picked = [n for n in sc.notes if any(k in n for k in keys)
              and not n.startswith("temperature")]
    if name == "gyro":             # the bias, and the matrix when the moves determine it
        return "; ".join(picked[:2]) or "bias: the mean of the still rates"
    how = f"model {settings.get('model', 'full')}" + (
        f" ({settings['params']})" if settings.get("params") else "") + " (calibrate --model)"
    return "; ".join([how] + picked[:2])


def _temperature(name, sc, settings) -> str:
    tm = sc.temperature
    if tm is not None:
        what = "sensitivity" if name == "mag" else "offset"
        return f"{what} per C, {tm.range_c[0]:.1f}-{tm.range_c[1]:.1f} C"
    nf = ((settings.get("temperature") or {}).get("not_fitted") or {}).get(name)
    if nf:
        return f"not fitted: {nf}"
    return "none (no temperature in the session)" if "temperature" not in settings else "none"


def _diagnosis(name, settings) -> str:
    dg = settings.get("diagnosis") or {}
    used = [d for d in dg.get("decisions", []) if d.get("sensor") == name and d.get("used")]
    return ", ".join(str(d.get("what")) for d in used) or ("nothing used" if dg.get("kept")
                                                            or dg.get("file") else "")


def _set_aside(sc) -> str:
    """'152 of 5000 (3.0 %)' from the robust fit's record (calib.robust), ''
    without one."""
    rec = getattr(sc, "set_aside", None) or {}
    if not isinstance(rec, dict) or rec.get("count") is None:
        return ""
    if not rec["count"]:
        return f"none of {rec.get('of', '?')}"
    return f"{rec['count']} of {rec.get('of', '?')} ({100 * rec.get('fraction', 0):.1f} %)"


def table_rows(mote: int, board) -> list:
    settings = board.settings or {}
    rows = []
    for name, sc in board.sensors():
        q = sc.quality or {}
        need = q.get("orientations_needed") or (
            max(6, int(q["identifiable_params"])) if q.get("identifiable_params") else None)
        orient = None if q.get("distinct_orientations") is None else (
            f"{q['distinct_orientations']}" + (f" ({need})" if need else ""))
        rows.append({"mote": mote, "sensor": name, "model": sc.model,
                     "dataset": DATASETS.get(sc.dataset, sc.dataset), "poses": int(sc.n_poses),
                     "orientations": orient,
                     "identifiable": f"{int(sc.rank)} of {len(sc.params)}" if sc.rank else None,
                     "why": _why(name, sc, settings),
                     "temperature": _temperature(name, sc, settings),
                     "diagnosis": _diagnosis(name, settings), "set_aside": _set_aside(sc)})
    for kind in ("skipped", "insufficient"):
        for name, why in (settings.get(kind) or {}).items():
            rows.append({"mote": mote, "sensor": name, "model": "-",
                         "why": f"{'not calibrated' if kind == 'skipped' else 'refused'}: {why}"})
    return rows


# ------------------------------------------------------------------ the gate's margins

def margins(board) -> list:
    """(label, margin, passes) per stored metric: how many times inside its
    limit (>= 1 passes)."""
    from ..calib.gate import LIMITS
    out = []
    for name, sc in board.sensors():
        q = sc.quality or {}
        need = q.get("orientations_needed") or max(LIMITS.min_orientations,
                                                   int(q.get("identifiable_params", 0)))
        if q.get("distinct_orientations") is not None:
            v = q["distinct_orientations"]
            out.append((f"{name} distinct orientations {v} (at least {need})", v / need))
        if q.get("hull_depth") is not None:
            v = q["hull_depth"]
            out.append((f"{name} hull depth {v:.2f} (at least {LIMITS.min_hull_depth:g})",
                        max(v, 0.0) / LIMITS.min_hull_depth))
        if q.get("coverage") is not None:
            v = q["coverage"]
            out.append((f"{name} sweep coverage {v:.0%} (at least "
                        f"{LIMITS.min_mag_coverage:.0%})", v / LIMITS.min_mag_coverage))
        if q.get("set_aside_frac") is not None:
            v = q["set_aside_frac"]
            out.append((f"{name} set aside {100 * v:.1f}% (at most "
                        f"{100 * LIMITS.max_set_aside:g}%)",
                        LIMITS.max_set_aside / v if v > 0 else np.inf))
        st = (getattr(sc, "set_aside", None) or {}).get("stretches_s") or []
        if st:
            v = max(b - a for a, b, *_ in st)
            out.append((f"{name} longest stretch set aside {v:.1f} s (at most "
                        f"{LIMITS.max_stretch_s:g} s)", LIMITS.max_stretch_s / v if v > 0
                        else np.inf))
        if q.get("rms_rel") is not None and name in LIMITS.max_rms_rel:
            v, lim = q["rms_rel"], LIMITS.max_rms_rel[name]
            out.append((f"{name} residual {100 * v:.2f}% (at most {100 * lim:g}%)",
                        lim / v if v > 0 else np.inf))
        if q.get("not_still") is not None:
            k = len(q["not_still"])
            out.append((f"{name} poses not still: {k}", np.inf if k == 0 else 0.0))
        worst = None
        for p in sc.params:
            if not p.identifiable or not np.isfinite(p.std) or p.std <= 0:
                continue
            if p.name.startswith(("o_", "b_")):
                lim = LIMITS.max_offset_std.get(name)
            elif p.name.startswith(("s_", "k_", "G_")):
                lim = LIMITS.max_gain_std
            else:
                continue
            if lim is not None and (worst is None or lim / p.std < worst[1]):
                worst = (f"{name} worst std {p.name} {p.std:.2g} (at most {lim:g})",
                         lim / p.std)
        if worst:
            out.append(worst)
    return [(lab, float(v), v >= 1.0) for lab, v in out]


def gate_chart(board) -> dict | None:
    ms = margins(board)
    if not ms:
        return None
    verdict = "accepted" if board.gate.get("accepted") else "refused"
    return C.chart(f"quality gate, mote {board.mote}: {verdict}", f"margin: times inside the limit (capped at "
                                               f"{MARGIN_CAP:g}; below 1 fails)", "",
                   [C.barh([lab for lab, _, _ in ms],
                           [min(v, MARGIN_CAP) for _, v, _ in ms],
                           [C.GREEN if ok else C.RED for _, _, ok in ms]),
                    C.vline(1.0, C.BLACK, "limit", dash=False)], xlim=(0, MARGIN_CAP * 1.05))


def part(mr, out: Path, set_aside_figures=()) -> Part:
    """The section of one mote; ``set_aside_figures``: the figures of the
    readings the robust fit set aside (build's, drawn from the session)."""
    from ..calib.robust import set_aside_text
    board, m = mr.board, mr.mote
    if board is None:
        return Part()
    gate = board.gate or {}
    verdict = ("accepted" if gate.get("accepted") else "refused") + (
        " (forced)" if gate.get("forced") else "")
    notes = [f"gate: {verdict}"] + [f"reason: {r}" for r in gate.get("reasons", [])] \
        + [f"warning: {w}" for w in gate.get("warnings", [])]
    for name, sc in board.sensors():
        rec = getattr(sc, "set_aside", None) or {}
        if rec:
            notes.append(f"{name}: {set_aside_text(rec, sc.unit)}")
    figs, view = [], []
    ch = gate_chart(board)
    if ch is not None:
        n = len(ch["series"][0]["labels"])
        f = C.save(out / f"mote{m}_gate.png", [ch], ncols=1, panel=(9, 0.9 + 0.28 * n))
        figs.append(H.FigureRef(f.name, "The quality gate's metrics against its limits",
                                "Each metric the gate judges (calib.gate), as stored with the "
                                "calibration, over its limit: green inside, red outside. The "
                                "verdict is the gate's own; reasons and warnings are listed "
                                "below."))
        view.append((f"quality gate: {verdict}", [ch]))
    figs += list(set_aside_figures)
    n_r, n_w = len(gate.get("reasons", [])), len(gate.get("warnings", []))
    sec = H.Section(f"choices-mote{m}", f"What the calibration chose, mote {m}",
                    f"Quality gate: {verdict} ({n_r} reason(s), {n_w} warning(s), listed "
                    f"below). The calibration: {mr.source}. Per sensor: the model and why, the "
                    f"data it came from, the temperature term, what a diagnosis added and the "
                    f"readings set aside.", figures=figs, notes=notes)
    return Part(sec, {"choices": table_rows(m, board)}, view)
