"""What every writer shares: the registry entry (``Target``), the options,
the exported text, what the target computes, what its restricted model
costs (a dropped temperature model too), and the text rules of generated
source (names escaped, numbers a target can read)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..errors import QualityError
from ..sessions.session import LABEL_ROT, UNITS

SPHERE_N = 2000            # directions for the data-free worst case
FLOAT32_MAX = 3.4028234e38


class TargetCannotHold(QualityError):
    """A value the target's number format cannot carry (exit 3, as a set the
    mote's fixed point cannot hold)."""


@dataclass(frozen=True)
class ExportOptions:
    """What a writer may be told besides the calibration (``motecal export-cal``)."""
    axes: str | None = None          # razor: "chip" or "razor" (None: from axis_frame)
    axis_frame: str | None = None    # the session's axes as recorded (session meta, cal.json)
    orientation: int = 0             # ardupilot: AHRS_ORIENTATION (ArduPilot's Rotation)


@dataclass(frozen=True)
class Target:
    """One export target, as the registry (``motecal.targets.TARGETS``) lists it."""
    name: str                        # the --to value
    what: str                        # one line: the file and who reads it (help, docs)
    write: Callable                  # (board, ExportOptions) -> Export
    options: tuple = ()              # ExportOptions fields it reads besides axis_frame


@dataclass
class Export:
    fmt: str
    text: str
    # sensor -> function(raw counts (n, 3), in the session's axes) -> what the
    # target outputs, in motecal's unit (g, deg/s, gauss) and in the session's
    # axes, so that it compares with the calibration
    apply: dict = field(default_factory=dict)
    lost: dict = field(default_factory=dict)       # sensor -> [what the target cannot hold]
    rounding: dict = field(default_factory=dict)   # sensor -> text (number formatting)
    notes: list = field(default_factory=list)
    frame: str = ""                                # the axes written, in words
    holds_temperature: tuple = ()                  # sensors whose temperature model it keeps


def fmt_float(v: float, digits: int = 9) -> str:
    """A float written with ``digits`` significant digits (what targets read back)."""
    return f"{float(v):.{digits}g}"


def float32_value(name: str, v: float, fmt: str) -> float:
    """``v`` if a float32 target holds it (finite, within float32's range), else
    TargetCannotHold naming the value."""
    v = float(v)
    if not math.isfinite(v) or abs(v) > FLOAT32_MAX:
        raise TargetCannotHold(f"{fmt}: {name} = {v:g} does not fit the target's float32")
    return v


# Generated source (C, YAML, parameter files) gets names and dates only in
# comments, and only these characters as they are; every other byte
# (newlines, '*' and '/' that could end a C comment, '\\' that splices a
# line, '?' of trigraphs, '%', quotes, control and non-ASCII bytes) is
# written %XX (percent-encoded UTF-8), so no text from a cal.json can become
# a live line of source.
_SAFE = frozenset("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789"
                  " -_.,:;+=@()[]{}<>!$&~^|")


def safe_text(text) -> str:
    """``text`` for a comment of generated source: safe characters kept,
    every other byte percent-encoded."""
    return "".join(ch if ch in _SAFE else "".join(f"%{b:02X}" for b in ch.encode("utf-8"))
                   for ch in str(text))


def header_words(board) -> str:
    """'mote M, session 'S' (calibration C)' with the names made safe."""
    return (f"mote {int(board.mote)}, session '{safe_text(board.session)}' "
            f"(calibration {safe_text(board.created)})")


def cal_rows(data, sensor: str) -> np.ndarray:
    """The session rows a cost is judged on: accelerometer and gyroscope over
    every row that holds them (static poses and the moves between them),
    magnetometer over the rotation rows (set R) when there are any."""
    has = data.has(sensor)
    if sensor == "mag" and (data.label[has] == LABEL_ROT).any():
        has = has & (data.label == LABEL_ROT)
    return np.flatnonzero(has)


def sphere_counts(cal, n=SPHERE_N, seed=0) -> np.ndarray:
    """Raw counts that the calibration maps onto the unit's typical size in
    every direction (1 g; 0.5 gauss; 100 deg/s): the data-free comparison."""
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    size = {"accel": 1.0, "mag": 0.5, "gyro": 100.0}[cal.sensor]
    return np.linalg.solve(cal.A, (size * u - cal.c).T).T


def costs(board, exp: Export, data=None) -> dict:
    """Per sensor the target holds: rms and max of |target - calibration|
    (vector) and of the magnitude difference, in the sensor's unit, over the
    session's rows (``data``) or, without data, over the unit sphere; and,
    where the calibration has a temperature model the target drops, what
    dropping it costs (``"temperature"``: ``temperature_cost``)."""
    out = {}
    for s, cal in board.sensors():
        f = exp.apply.get(s)
        if f is None:
            continue
        if data is not None:
            rows = cal_rows(data, s)
            raw = data.sensor(s)[rows]
            on = f"session '{data.name}', {len(raw)} rows"
        else:
            rows, raw = None, sphere_counts(cal)
            on = f"{SPHERE_N} directions at " + {"accel": "1 g", "mag": "0.5 gauss",
                                                 "gyro": "100 deg/s"}[s]
        if not len(raw):
            continue
        want = cal.apply(raw)
        got = f(raw)
        d = np.linalg.norm(got - want, axis=1)
        dm = np.abs(np.linalg.norm(got, axis=1) - np.linalg.norm(want, axis=1))
        out[s] = {"unit": UNITS[s], "on": on, "rms": float(np.sqrt(np.mean(d ** 2))),
                  "max": float(d.max()), "magnitude_rms": float(np.sqrt(np.mean(dm ** 2))),
                  "magnitude_max": float(dm.max())}
        if cal.temperature is not None and s not in exp.holds_temperature:
            temp = None if data is None or data.temp is None else data.temp[rows]
            out[s]["temperature"] = temperature_cost(cal, raw, temp, on)
    return out


def temperature_cost(cal, raw, temp=None, on: str = "") -> dict:
    """What a target that applies the calibration at its reference
    temperature (``t_ref_c``) loses against the temperature model: |cal at T
    - cal at t_ref|, rms and max, over the rows at their own temperatures
    (``temp``, where known), else over ``raw`` at both ends of the model's
    range (where the loss is largest: it grows with |T - t_ref|)."""
    tm = cal.temperature
    base = cal.apply(raw)
    known = None if temp is None else np.isfinite(temp)
    if known is not None and known.any():
        d = np.linalg.norm(cal.apply(raw[known], temp[known]) - base[known], axis=1)
        where = f"{on}, {int(known.sum())} at their temperatures"
    else:
        d = np.concatenate([np.linalg.norm(cal.apply(raw, t) - base, axis=1)
                            for t in tm.range_c])
        where = f"{on}, at {tm.range_c[0]:g} and {tm.range_c[1]:g} C"
    return {"t_ref_c": tm.t_ref_c, "range_c": tm.range_c, "on": where,
            "rms": float(np.sqrt(np.mean(d ** 2))), "max": float(d.max())}


def cost_lines(exp: Export, cost: dict) -> list[str]:
    lines = [f"axes: {exp.frame}"] if exp.frame else []
    for s in ("accel", "gyro", "mag"):
        lost = exp.lost.get(s)
        if s not in cost and not lost:
            continue
        c = cost.get(s, {})
        t = c.get("temperature")
        parts = list(lost or [])
        if t:
            parts.append(f"temperature model dropped (applied at its reference "
                         f"{t['t_ref_c']:g} C; fitted over {t['range_c'][0]:g}.."
                         f"{t['range_c'][1]:g} C)")
        head = f"{s}: " + ("; ".join(parts) if parts else "held whole")
        if c:
            head += (f". Cost on {c['on']}: vector rms {c['rms']:.3g} (max {c['max']:.3g}) "
                     f"{c['unit']}, magnitude rms {c['magnitude_rms']:.3g} "
                     f"(max {c['magnitude_max']:.3g}) {c['unit']}")
        if t:
            head += (f"; dropping the temperature model costs vector rms {t['rms']:.3g} "
                     f"(max {t['max']:.3g}) {c['unit']} on {t['on']}")
        if exp.rounding.get(s):
            head += f"; {exp.rounding[s]}"
        lines.append(head)
    return lines + list(exp.notes)


def cross_axis_lost(board, what: str) -> str | None:
    """The note for a format that keeps ``what`` per accelerometer axis and so
    drops the fitted cross-axis terms; None when there are none."""
    off = board.accel.A - np.diag(np.diag(board.accel.A))
    if np.abs(off).max() == 0:
        return None
    return (f"{what}: cross-axis terms dropped (largest "
            f"{np.abs(off).max() * board.accel.lsb_per_unit:.4f} of the nominal scale)")


def per_axis_lost(board, accel_what: str, gyro_words: str) -> dict:
    """The notes of a target that keeps ``accel_what`` per accelerometer axis
    (so drops its cross-axis terms) and the gyroscope's offsets only."""
    lost = {}
    if board.accel is not None:
        note = cross_axis_lost(board, accel_what)
        if note:
            lost["accel"] = [note]
    if board.gyro is not None:
        lost["gyro"] = [f"offsets only: {gyro_words} (largest |G - I| "
                        f"{gyro_scale_lost(board):.4f} is lost)"]
    return lost


def gyro_scale_lost(board) -> float:
    """Largest |G - I| of the gyroscope's fitted matrix in nominal units: what a
    format that keeps only the gyro offsets loses."""
    G = board.gyro.A * board.gyro.lsb_per_unit
    return float(np.abs(G - np.eye(3)).max())


def polar(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A = U P: U orthogonal, P symmetric positive definite."""
    W, s, Vt = np.linalg.svd(A)
    return W @ Vt, Vt.T @ np.diag(s) @ Vt


def rotation_deg(U: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(U) - 1) / 2, -1, 1))))


ApplyFn = Callable[[np.ndarray], np.ndarray]
