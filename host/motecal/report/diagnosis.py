"""The report's section on the diagnosis kept with the session (``motecal
diagnose`` keeps one per mote in the database; ``motecal calibrate`` uses
it): its findings and their held-out gains, whether it was made from these
very rows, what calibrate did with each finding, and links to the figures
that show each finding -- the report's own, and the evidence pictures of
``motecal diagnose --report DIR`` when that folder is given
(``--diagnosis-report DIR``: they are copied into the report, so it stays
one folder).  Nothing is diagnosed again here: the pictures of ``diagnose``
need its fits, which are not stored.
"""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np

from ..errors import UserError
from . import charts as C
from . import html as H
from .parts import Part
from .tables import Column

COLUMNS = [
    Column("mote", "mote"), Column("finding", "finding"), Column("sensor", "sensor"),
    Column("cause", "cause"), Column("gain", "held-out gain", ".3g"),
    Column("heldout_before", "held-out rms without the term", ".3g"),
    Column("heldout_after", "held-out rms with it", ".3g"), Column("unit", "unit"),
    Column("p", "p-value", ".2g"), Column("calibrate", "what calibrate did")]
NOTES = ["gain: the held-out rms without the finding's term over the rms with it, on data not "
         "used to fit it (motecal diagnose, docs/diagnose.md)",
         "what calibrate did: from the calibration shown (settings.diagnosis): each treatment "
         "or term is kept only when it lowers the held-out error"]

# the report's figure that shows each cause best, by file name pattern
RELATED = {"temperature": ("{m}_{s}_temperature.png", "against temperature"),
           "cross_axis": ("{m}_{s}_residual_sphere.png", "residual against direction"),
           "nonlinearity": ("{m}_{s}_residual_sphere.png", "residual against direction"),
           "field_disturbance": ("{m}_{s}_magnitude.png", "magnitude per sample"),
           "unexplained": ("{m}_{s}_magnitude.png", "magnitude per sample"),
           "stale_samples": ("{m}_{s}_magnitude.png", "magnitude per sample"),
           "saturation": ("{m}_{s}_magnitude.png", "magnitude per sample"),
           "motion": ("{m}_{s}_magnitude.png", "magnitude per sample"),
           "bias_drift": ("{m}_{s}_magnitude.png", "magnitude per sample")}
GYRO_RELATED = {"bias_drift": ("{m}_gyro_temperature.png", "against temperature"),
                "temperature": ("{m}_gyro_temperature.png", "against temperature")}


def kept(store, session_name, mote) -> dict | None:
    if store is None:
        return None
    try:
        return store.load_diagnosis(session_name, mote)
    except UserError:
        return None


def folder_diagnosis(folder, mote, several: bool):
    """(diagnosis JSON, folder) of ``motecal diagnose --report DIR`` for one
    mote (DIR/mote<ID>/ when it diagnosed several), or (None, None)."""
    if folder is None:
        return None, None
    base = Path(folder)
    for d in ([base / f"mote{mote}", base] if several else [base, base / f"mote{mote}"]):
        p = d / "diagnosis.json"
        if p.is_file():
            try:
                return json.loads(p.read_text(encoding="utf-8")), d
            except (OSError, ValueError) as e:
                raise UserError(f"--diagnosis-report {p}: not readable: {e}") from None
    return None, None


def _calibrate_did(f, settings) -> str:
    dg = settings.get("diagnosis") or {}
    if not dg:
        return ""
    key = f"{f.get('sensor')} {f.get('cause')}"
    for k, word in (("used", "used"), ("not_used", "not used")):
        for line in dg.get(k) or []:
            if isinstance(line, str) and line.startswith(key):
                return f"{word}: {line[len(key):].lstrip(': ')}"
    if dg.get("not_used") and isinstance(dg["not_used"], str):
        return f"diagnosis not used: {dg['not_used']}"
    return ""


def gains_chart(findings, mote) -> dict | None:
    rows = [(i, f) for i, f in enumerate(findings, 1) if f.get("gain")]
    if not rows:
        return None
    labels, vals, cols = [], [], []
    for i, f in rows:
        ev = f.get("evidence") or {}
        b, a = ev.get("heldout_rms_before"), ev.get("heldout_rms_after")
        rms = f" ({b:.3g} -> {a:.3g} {ev.get('unit', '')})" if b and a else ""
        labels.append(f"{i}. {f['sensor']} {f['cause']}: {f['gain']:.3g}x{rms}")
        vals.append(np.log10(max(float(f["gain"]), 1e-3)))
        cols.append(C.GREEN if f["gain"] > 1 else C.GREY)
    top = max(1.0, max(vals) * 1.1)
    return C.chart(f"diagnosis, mote {mote}: held-out gain of each finding's term", "log10 of the gain "
                   "(0.3 = 2x, 1 = 10x, 2 = 100x)", "",
                   [C.barh(labels, vals, cols)], xlim=(0, top))


def part(mr, out: Path, store, session_name, folder=None, several=False) -> Part:
    m = mr.mote
    rec = kept(store, session_name, m) if isinstance(session_name, str) else None
    full, fdir = folder_diagnosis(folder, m, several)
    if rec is None and full is None:
        return Part(meta=[("diagnosis", f"mote {m}: none kept with the session (motecal "
                                        f"diagnose keeps one)")])
    from ..sessions.fingerprint import data_key
    notes = []
    if rec is not None:
        d = rec["diagnosis"] if isinstance(rec.get("diagnosis"), dict) else {}
        same = rec.get("data_key") == data_key(mr.data)
        src = (f"the diagnosis kept with the session (database diagnosis {rec.get('id')}, "
               f"{rec.get('created')}, {rec.get('tool')}), made from "
               + ("these very rows" if same else "other rows than the session has now: run "
                  "motecal diagnose again"))
    else:
        d = full
        src = f"the diagnosis of {fdir / 'diagnosis.json'} (none kept with the session)"
    findings = [f for f in d.get("findings", []) if isinstance(f, dict)]
    settings = mr.board.settings if mr.board is not None else {}
    rows = []
    for i, f in enumerate(findings, 1):
        ev = f.get("evidence") or {}
        rows.append({"mote": m, "finding": i, "sensor": f.get("sensor"), "cause": f.get("cause"),
                     "gain": f.get("gain"), "heldout_before": ev.get("heldout_rms_before"),
                     "heldout_after": ev.get("heldout_rms_after"), "unit": ev.get("unit"),
                     "p": ev.get("p"), "calibrate": _calibrate_did(f, settings)})
        notes.append(f"{i}. {f.get('sensor')} {f.get('cause')}: {f.get('summary', '')}")
    if not findings:
        notes.append("clean: the diagnosis found nothing the paper's model gets wrong")
    dg = settings.get("diagnosis") or {}
    if dg.get("not_used") and isinstance(dg["not_used"], str):
        notes.append(f"calibrate: diagnosis not used: {dg['not_used']}")
    links = []
    # the diagnose --report pictures of the findings shown, copied into the report
    pics = {}
    if fdir is not None:
        dest = out / f"diagnosis-mote{m}"
        dest.mkdir(exist_ok=True)
        theirs = [f for f in (full or {}).get("findings", []) if isinstance(f, dict)]
        for j, f in enumerate(theirs, 1):
            name = f"finding{j}-{f.get('sensor')}-{f.get('cause')}.png"
            if (fdir / name).is_file():
                shutil.copyfile(fdir / name, dest / name)
                pics[(f.get("sensor"), f.get("cause"))] = f"{dest.name}/{name}"
        if (fdir / "statistics.png").is_file():
            shutil.copyfile(fdir / "statistics.png", dest / "statistics.png")
            links.append((f"{dest.name}/statistics.png", "the simulated statistics, paper "
                                                         "model against the extended one "
                                                         "(motecal diagnose --report)"))
        mine = {(f.get("sensor"), f.get("cause")) for f in findings}
        other = sorted(set(pics) - mine)
        if other:
            notes.append(f"the folder {fdir} holds a diagnosis with other findings ("
                         + ", ".join(f"{s} {c}" for s, c in other) + "): not the one shown")
    figs = []
    for i, f in enumerate(findings, 1):
        key = (f.get("sensor"), f.get("cause"))
        if key in pics:
            figs.append(H.FigureRef(pics[key], f"Finding {i}: {key[0]} {key[1]} "
                                               f"(motecal diagnose --report)",
                                    "The residual against what the cause depends on, "
                                    "without and with the term (docs/diagnose.md)."))
        rel = (GYRO_RELATED if key[0] == "gyro" else RELATED).get(key[1])
        if rel:
            name = rel[0].format(m=f"mote{m}", s=key[0])
            if (out / name).is_file():
                links.append((name, f"finding {i} ({key[0]} {key[1]}): the report's "
                                    f"{key[0]} {rel[1]}"))
    if fdir is None and findings:
        notes.append("the evidence pictures of motecal diagnose are not stored with the "
                     "diagnosis: run motecal diagnose --report DIR and give the report "
                     "--diagnosis-report DIR to include them")
    view = []
    ch = gains_chart(findings, m)
    if ch is not None:
        n = len(ch["series"][0]["labels"])
        fg = C.save(out / f"mote{m}_diagnosis.png", [ch], ncols=1, panel=(9, 0.9 + 0.3 * n))
        figs.insert(0, H.FigureRef(fg.name, "The findings' held-out gains",
                                   "Each finding's held-out rms without and with its term "
                                   "(motecal diagnose), on a log scale of the gain."))
        view.append(("diagnosis: held-out gains", [ch]))
    sec = H.Section(f"diagnosis-mote{m}", f"Diagnosis, mote {m}", f"From {src}.",
                    figures=figs, notes=notes, links=links)
    return Part(sec, {"diagnosis": rows}, view)
