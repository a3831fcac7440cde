"""The report's section on the poses a session needed (``calib.design``,
the criterion of the adaptive session): per sensor the promised error (a
90 % upper bound of the rms error on fresh directions) against the number
of poses, in the order taken and in the best order the greedy selection
finds, with the targets and the two answers ``motecal calibrate`` prints
(``accel.quality.poses_needed`` in cal.json).

A calibration stored before the curve was kept (or calibrated by the report
itself) has none: the report then computes it from the session's pose means
(``design.session_poses_needed``, about a second for 80 poses) and says so.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from . import charts as C
from . import html as H
from .parts import Part

SCALE = {"accel": (1e3, "mg", "accel_g"), "mag": (1e2, "%", "mag_rel"),
         "gyro": (1.0, "deg/s", "gyro_dps")}
WHAT = {"accel": "accelerometer", "mag": "magnetometer", "gyro": "gyroscope bias"}
ERROR = {"accel": "vector error at 1 g", "mag": "vector error / field",
         "gyro": "bias error"}


def stored_or_computed(board, data) -> tuple[dict | None, str]:
    """(poses_needed with its curve, where it came from)."""
    from ..calib.design import session_poses_needed
    pn = (board.accel.quality or {}).get("poses_needed") if board.accel is not None else None
    if pn and pn.get("curve"):
        return pn, "as motecal calibrate computed it (cal.json accel.quality.poses_needed)"
    if board.accel is None or not (data.label >= 1).any():
        return None, ""
    again = session_poses_needed(board, data, keep=False)
    why = ("the calibration shown keeps no curve" if pn else
           "the calibration shown has no poses-needed figures")
    return again, (f"computed by the report from this session's pose means ({why}; "
                   f"calib.design.session_poses_needed, the same criterion)")


def charts(pn: dict) -> list:
    cur = pn.get("curve") or {}
    ks = np.asarray(cur.get("k", []), float)
    out = []
    for s in pn["sensors"]:
        if s not in cur.get("in_order", {}):
            continue
        k, unit, key = SCALE[s]
        target = pn["targets"][key] * k

        def arr(v):
            return np.array([np.nan if x is None else x * k for x in v], float)
        ser = [C.hline(target, C.RED, f"target {target:g} {unit}")]
        io = arr(cur["in_order"][s])
        ser.append(C.line(ks, io, C.BLUE, "in the order taken"))
        ser.append(C.points(ks, io, C.BLUE, "", size=3))
        bs = arr(cur.get("best_subset", {}).get(s, []))
        if len(bs) == len(ks):
            ser.append(C.line(ks, bs, C.ORANGE, "best subset (greedy)"))
            ser.append(C.points(ks, bs, C.ORANGE, "", size=3))
        if pn.get("in_order"):
            ser.append(C.vline(pn["in_order"], C.BLUE, f"first {pn['in_order']} keep the "
                                                       f"promise"))
        if pn.get("best_subset"):
            ser.append(C.vline(pn["best_subset"], C.ORANGE,
                               f"best {pn['best_subset']} keep it"))
        b = pn["bounds_all"].get(s)
        title = WHAT[s] + (f": all {pn['poses']} promise {b * k:.3g} {unit}" if b else "")
        vals = np.r_[io[np.isfinite(io)], bs[np.isfinite(bs)] if len(bs) else [], target]
        out.append(C.chart(title, "number of poses", f"promised {ERROR[s]} ({unit})", ser,
                           ylog=bool(len(vals) and np.nanmax(vals) / max(np.nanmin(vals), 1e-12)
                                     > 20), xint=True))
    return out


def part(mr, out: Path) -> Part:
    from ..calib.design import describe_poses_needed
    board, m = mr.board, mr.mote
    if board is None:
        return Part()
    pn, source = stored_or_computed(board, mr.data)
    if pn is None:
        return Part()
    lines = [ln.strip() for ln in describe_poses_needed(pn)]
    figs, view = [], []
    chs = charts(pn)
    if chs:
        f = C.save(out / f"mote{m}_poses_needed.png", chs,
                   f"Poses needed, mote {m} (promised error at {pn['confidence']:.0%} on fresh "
                   f"directions)", ncols=3)
        figs.append(H.FigureRef(
            f.name, "Promised error against the number of poses",
            "The promised error (an upper bound, at the confidence shown, of the rms error "
            "on fresh directions: calib.design, the adaptive session's criterion) of the "
            "first k poses in the order they were taken (blue) and of the first k the "
            "greedy selection picks (orange), against the target (red). The vertical lines "
            "are calibrate's answers: the fewest poses in the order taken from which the "
            "promise holds for good, and the fewest of the best subset. The promise is the "
            "full model's whatever model was fitted; the magnetometer is judged only when "
            "its calibration came from the poses."))
        view.append(("poses needed", chs))
    elif pn["poses"] < 12:
        lines.append(f"no curve: {pn['poses']} poses (the promise needs at least 12)")
    sec = H.Section(f"poses-mote{m}", f"Poses needed, mote {m}",
                    f"How many of the session's poses the result needed: {source}.",
                    figures=figs, notes=lines)
    return Part(sec, {}, view)
