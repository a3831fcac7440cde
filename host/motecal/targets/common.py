"""What every writer shares: the exported text, what the target computes,
and what its restricted model costs."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..sessions.session import LABEL_ROT, UNITS

SPHERE_N = 2000            # directions for the data-free worst case


@dataclass
class Export:
    fmt: str
    text: str
    # sensor -> function(raw counts (n, 3)) -> what the target outputs, in
    # motecal's unit (g, deg/s, gauss) so it compares with the calibration
    apply: dict = field(default_factory=dict)
    lost: dict = field(default_factory=dict)       # sensor -> [what the target cannot hold]
    rounding: dict = field(default_factory=dict)   # sensor -> text (number formatting)
    notes: list = field(default_factory=list)


def fmt_float(v: float, digits: int = 9) -> str:
    """A float written with ``digits`` significant digits (what targets read back)."""
    return f"{float(v):.{digits}g}"


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
    session's rows (``data``) or, without data, over the unit sphere."""
    out = {}
    for s, cal in board.sensors():
        f = exp.apply.get(s)
        if f is None:
            continue
        if data is not None:
            raw = data.sensor(s)[cal_rows(data, s)]
            on = f"session '{data.name}', {len(raw)} rows"
        else:
            raw = sphere_counts(cal)
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
    return out


def cost_lines(exp: Export, cost: dict) -> list[str]:
    lines = []
    for s in ("accel", "gyro", "mag"):
        lost = exp.lost.get(s)
        if s not in cost and not lost:
            continue
        head = f"{s}: " + ("; ".join(lost) if lost else "held whole")
        if s in cost:
            c = cost[s]
            head += (f". Cost on {c['on']}: vector rms {c['rms']:.3g} (max {c['max']:.3g}) "
                     f"{c['unit']}, magnitude rms {c['magnitude_rms']:.3g} "
                     f"(max {c['magnitude_max']:.3g}) {c['unit']}")
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
