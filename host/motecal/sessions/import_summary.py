"""The one paragraph ``motecal import`` prints about the session it read.
"""
from __future__ import annotations

from pathlib import Path

from .imported import _sensor_counts
from .session import LABEL_ROT, SENSOR_SLICES, UNITS, SessionData

def _fmt_scale(sensor, scale) -> str:
    return f"{scale:g} LSB/{UNITS[sensor] if sensor != 'gyro' else '(deg/s)'}"


def summary(data: SessionData) -> str:
    """One paragraph: samples per sensor, rates, kind and poses, chips/scales."""
    m = data.meta
    src = [f["file"] for f in m.get("files", [])] or ([m["source"]] if m.get("source") else [])
    counts = m.get("samples") or _sensor_counts(data.raw)
    rates = m.get("rates_hz", {})
    parts = []
    for s in SENSOR_SLICES:
        if counts.get(s):
            r = rates.get(s)
            parts.append(f"{s} {counts[s]}" + (f" at {r:.1f} Hz" if r else ""))
    poses = data.poses()
    if data.kind == "rotation":
        lab = f"{int((data.label == LABEL_ROT).sum())} rows labelled rot"
    elif poses:
        still = int((data.label >= 1).sum())
        lab = (f"{len(poses)} pose{'s' if len(poses) != 1 else ''} found "
               f"({', '.join(map(str, poses[:12]))}{', ...' if len(poses) > 12 else ''}; "
               f"{still} still rows)")
    else:
        lab = "no still pose found"
    chips = "; ".join(f"{s} {data.chips.get(s)} {_fmt_scale(s, data.scales[s])}"
                      for s in SENSOR_SLICES if counts.get(s))
    text = (f"Session '{data.name}': {len(data)} rows from {len(src)} "
            f"{m.get('format', '?')} file{'s' if len(src) != 1 else ''} "
            f"({', '.join(Path(s).name for s in src[:4])}{', ...' if len(src) > 4 else ''}); "
            f"samples {', '.join(parts)}; kind {data.kind} [{m.get('kind_decision', '')}]; "
            f"{lab}; chips {chips}; axes {m.get('axis_frame', 'as recorded')}.")
    clipped = m.get("clipped") or {}
    if clipped:
        text += " Clipped at full scale: " + ", ".join(
            f"{s} {k} samples" for s, k in clipped.items()) + "."
    if m.get("notes"):
        text += f" Notes: {m['notes']}."
    return text
