"""Razor AHRS firmware constants and the ROS razor_imu_9dof YAML.

The firmware (``Razor_AHRS.ino``, 50 Hz) corrects, per axis, in its board
frame and in float32:

* accelerometer: ``(raw - (MIN + MAX) / 2) * GRAVITY / ((MAX - MIN) / 2)``,
  ``GRAVITY`` = 256 = 1 g: an offset and a scale per axis, no cross-axis
  terms;
* gyroscope: ``(raw - GYRO_AVERAGE_OFFSET) * GYRO_GAIN`` (deg/s), one gain
  for all axes fixed in the firmware (0.06957 for the ITG-3200): an offset
  per axis only;
* magnetometer, extended calibration: ``magn_ellipsoid_transform @ (raw -
  magn_ellipsoid_center)``: a full matrix and centre (its output scale does
  not matter to the firmware, which only takes the heading from it).

The ROS node (``my_razor.yaml``) sends the same numbers, lower-case names,
to the firmware over the serial line.  motecal writes the diagonal of its
accelerometer matrix (cross-axis terms dropped), the gyroscope's bias in
counts, and its magnetometer matrix times the nominal gain (so the output is
in nominal counts) with the hard-iron centre.  Axes are the session's: a
session imported from Razor logs is in the firmware's board frame already.
"""
from __future__ import annotations

import json
import re

import numpy as np

from ..sessions.session import NOMINAL_SCALES
from .common import Export, cross_axis_lost, fmt_float, gyro_scale_lost

GRAVITY = 256.0                    # the firmware's 1 g
FIRMWARE_GYRO_GAIN = 0.06957       # deg/s per LSB, ITG-3200 / ITG-3205
AXES = "XYZ"


def constants(board) -> dict:
    """The firmware's numbers from a BoardCalibration."""
    k = {}
    if board.accel is not None:
        A, c = board.accel.A, board.accel.c
        for i, ax in enumerate(AXES):
            a = A[i, i]
            h, off = 1.0 / a, -c[i] / a                 # g = (raw - off) / h
            k[f"ACCEL_{ax}_MIN"] = off - h * 1.0
            k[f"ACCEL_{ax}_MAX"] = off + h * 1.0
    if board.gyro is not None:
        b = -np.linalg.solve(board.gyro.A, board.gyro.c)         # counts
        for i, ax in enumerate(AXES):
            k[f"GYRO_AVERAGE_OFFSET_{ax}"] = b[i]
    if board.mag is not None:
        A, c = board.mag.A, board.mag.c
        lsb = board.mag.lsb_per_unit
        centre = -np.linalg.solve(A, c)
        k["magn_ellipsoid_center"] = centre.tolist()
        k["magn_ellipsoid_transform"] = (A * lsb).tolist()
        # the standard (min/max) calibration, used only when extended is off
        field = board.mag.field_gauss or 0.5
        for i, ax in enumerate(AXES):
            half = field / A[i, i]                     # counts the field spans on this axis
            k[f"MAGN_{ax}_MIN"] = centre[i] - half
            k[f"MAGN_{ax}_MAX"] = centre[i] + half
    return k


def _lost(board) -> dict:
    lost = {}
    if board.accel is not None:
        note = cross_axis_lost(board, "min/max per axis")
        if note:
            lost["accel"] = [note]
    if board.gyro is not None:
        lost["gyro"] = [f"offsets only: the firmware's one GYRO_GAIN ({fmt_float(gyro_gain(board), 6)} "
                        f"deg/s per LSB) replaces the fitted scale and misalignment "
                        f"(largest |G - I| {gyro_scale_lost(board):.4f})"]
    return lost


def gyro_gain(board) -> float:
    """deg/s per LSB: the firmware's ITG-3200 constant for that chip's nominal
    scale (14.375 LSB per deg/s), else the session's nominal scale (set
    GYRO_GAIN to it in the firmware; the block says so)."""
    lsb = board.gyro.lsb_per_unit if board is not None and board.gyro else 14.375
    return FIRMWARE_GYRO_GAIN if abs(lsb - 14.375) < 1e-9 else 1.0 / lsb


def _apply_fns(k: dict, board) -> dict:
    """The firmware's arithmetic (float32) on parsed constants, in g, deg/s, gauss."""
    f32 = np.float32
    out = {}
    if "ACCEL_X_MIN" in k:
        mn = np.array([k[f"ACCEL_{a}_MIN"] for a in AXES], f32)
        mx = np.array([k[f"ACCEL_{a}_MAX"] for a in AXES], f32)
        off = (mn + mx) / f32(2)
        scale = f32(GRAVITY) / (mx - off)
        out["accel"] = lambda raw, off=off, scale=scale: \
            ((np.asarray(raw, f32) - off) * scale).astype(float) / GRAVITY
    if "GYRO_AVERAGE_OFFSET_X" in k:
        off = np.array([k[f"GYRO_AVERAGE_OFFSET_{a}"] for a in AXES], f32)
        gain = f32(gyro_gain(board))
        out["gyro"] = lambda raw, off=off, gain=gain: \
            ((np.asarray(raw, f32) - off) * gain).astype(float)
    if "magn_ellipsoid_center" in k:
        ctr = np.array(k["magn_ellipsoid_center"], f32)
        T = np.array(k["magn_ellipsoid_transform"], f32)
        lsb = board.mag.lsb_per_unit if board is not None and board.mag else NOMINAL_SCALES["mag"]
        out["mag"] = lambda raw, ctr=ctr, T=T, lsb=lsb: \
            ((np.asarray(raw, f32) - ctr) @ T.T).astype(float) / lsb
    return out


def _header(board, what: str) -> list[str]:
    return [f"motecal {what} for mote {board.mote}, session '{board.session}' "
            f"(calibration {board.created})",
            "axes: the session's (Razor logs imported by motecal are in the firmware's board "
            "frame)"]


def write_c(board) -> Export:
    k = constants(board)
    lines = ["// " + s for s in _header(board, "Razor AHRS constants")]
    if board.accel is not None:
        lines.append("// Accelerometer: offset and scale per axis (cross-axis terms dropped)")
        for a in AXES:
            for m in ("MIN", "MAX"):
                lines.append(f"#define ACCEL_{a}_{m} ((float) {fmt_float(k[f'ACCEL_{a}_{m}'])})")
    if board.mag is not None:
        lines.append("// Magnetometer, standard calibration (unused with the extended one)")
        for a in AXES:
            for m in ("MIN", "MAX"):
                lines.append(f"#define MAGN_{a}_{m} ((float) {fmt_float(k[f'MAGN_{a}_{m}'])})")
        lines.append("// Magnetometer, extended calibration (hard and soft iron)")
        lines.append("#define CALIBRATION__MAGN_USE_EXTENDED true")
        ctr = ", ".join(fmt_float(v) for v in k["magn_ellipsoid_center"])
        lines.append(f"const float magn_ellipsoid_center[3] = {{{ctr}}};")
        rows = ", ".join("{" + ", ".join(fmt_float(v) for v in r) + "}"
                         for r in k["magn_ellipsoid_transform"])
        lines.append(f"const float magn_ellipsoid_transform[3][3] = {{{rows}}};")
    if board.gyro is not None:
        gain = gyro_gain(board)
        if gain == FIRMWARE_GYRO_GAIN:
            lines.append(f"// Gyroscope: average offsets in counts (the firmware's GYRO_GAIN "
                         f"{FIRMWARE_GYRO_GAIN} deg/s per LSB stays)")
        else:
            lines.append(f"// Gyroscope: average offsets in counts; this chip's nominal gain: "
                         f"set GYRO_GAIN to {fmt_float(gain)} deg/s per LSB")
        for a in AXES:
            lines.append(f"#define GYRO_AVERAGE_OFFSET_{a} ((float) "
                         f"{fmt_float(k[f'GYRO_AVERAGE_OFFSET_{a}'])})")
    text = "\n".join(lines) + "\n"
    return Export("razor-c", text, _apply_fns(parse_c(text), board), _lost(board),
                  {s: "numbers written with 9 significant digits, applied in float32"
                   for s, _ in board.sensors()})


def write_yaml(board) -> Export:
    k = constants(board)
    lines = ["# " + s for s in _header(board, "razor_imu_9dof calibration")]
    lines.append("##### Calibration ####")
    if board.accel is not None:
        lines.append("### accelerometer (offset and scale per axis; cross-axis terms dropped)")
        for a in AXES:
            for m in ("min", "max"):
                lines.append(f"accel_{a.lower()}_{m}: {fmt_float(k[f'ACCEL_{a}_{m.upper()}'])}")
    if board.mag is not None:
        lines.append("### magnetometer")
        lines.append("# standard calibration")
        for a in AXES:
            for m in ("min", "max"):
                lines.append(f"magn_{a.lower()}_{m}: {fmt_float(k[f'MAGN_{a}_{m.upper()}'])}")
        lines.append("# extended calibration")
        lines.append("calibration_magn_use_extended: true")
        lines.append("magn_ellipsoid_center: ["
                     + ", ".join(fmt_float(v) for v in k["magn_ellipsoid_center"]) + "]")
        lines.append("magn_ellipsoid_transform: ["
                     + ", ".join("[" + ", ".join(fmt_float(v) for v in r) + "]"
                                 for r in k["magn_ellipsoid_transform"]) + "]")
    if board.gyro is not None:
        lines.append("### gyroscope (average offsets, counts; the firmware's GYRO_GAIN: "
                     f"{fmt_float(gyro_gain(board))} deg/s per LSB)")
        for a in AXES:
            lines.append(f"gyro_average_offset_{a.lower()}: "
                         f"{fmt_float(k[f'GYRO_AVERAGE_OFFSET_{a}'])}")
    text = "\n".join(lines) + "\n"
    return Export("razor-yaml", text, _apply_fns(parse_yaml(text), board), _lost(board),
                  {s: "numbers written with 9 significant digits, applied in float32"
                   for s, _ in board.sensors()})


# ------------------------------------------------------------------ reading back

_DEFINE = re.compile(r"^#define\s+(\w+)\s+\(\(float\)\s*([-+0-9.eE]+)\)\s*$")
_ARRAY = re.compile(r"^const float (\w+)\[3\](?:\[3\])?\s*=\s*(\{.*\});\s*$")


def parse_c(text: str) -> dict:
    """The constants of a Razor C block (the subset motecal writes)."""
    k = {}
    for line in text.splitlines():
        line = line.strip()
        m = _DEFINE.match(line)
        if m:
            k[m.group(1)] = float(m.group(2))
            continue
        m = _ARRAY.match(line)
        if m:
            k[m.group(1)] = json.loads(m.group(2).replace("{", "[").replace("}", "]"))
    return k


def parse_yaml(text: str) -> dict:
    """``key: value`` lines of my_razor.yaml (flow lists are JSON), names as in C."""
    k = {}
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if not line or ":" not in line:
            continue
        key, _, val = line.partition(":")
        val = json.loads(val.strip())
        key = key.strip()
        if key.startswith(("accel_", "magn_x", "magn_y", "magn_z", "gyro_")):
            key = key.upper()
        k[key] = val
    return k
