"""An ArduPilot parameter file (``NAME,VALUE`` lines, as Mission Planner
saves and loads them; ``#`` comments).

ArduPilot's order of operations, from its source:

* accelerometer (libraries/AP_InertialSensor/AP_InertialSensor_Backend.cpp,
  ``_rotate_and_correct_accel``): the driver's chip rotation, then ``a =
  INS_ACCSCAL * (a_in - INS_ACCOFFS)`` per axis (m/s^2: the offset is
  *subtracted*, then scaled; no cross-axis terms), then the board rotation
  ``AHRS_ORIENTATION``;
* gyroscope (``_rotate_and_correct_gyro``): the chip rotation, ``w = w_in -
  INS_GYROFFS`` (rad/s, an offset only, re-learnt at every boot), then
  ``AHRS_ORIENTATION``;
* compass (libraries/AP_Compass/AP_Compass_Backend.cpp,
  ``accumulate_sample``): ``rotate_field`` first (the chip rotation, then
  ``AHRS_ORIENTATION`` for an internal compass), then ``correct_field``: ``m
  += COMPASS_OFS`` (milligauss, *added*: minus the hard-iron centre), ``m
  *= COMPASS_SCALE`` (when it lies in ArduPilot's accepted range; 0: none),
  ``m = M m`` with ``M`` symmetric, ``COMPASS_DIA_X/Y/Z`` on its diagonal
  and ``COMPASS_ODI_X`` = M_xy, ``COMPASS_ODI_Y`` = M_xz, ``COMPASS_ODI_Z``
  = M_yz.

So the INS parameters are in the sensor frame, and the compass parameters
in the frame *after* the board rotation.  The session's axes are taken as
ArduPilot's sensor frame (its driver's chip rotation: none), and the board
rotation is ``--orientation`` (ArduPilot's ``Rotation`` number or name,
default none), which the file writes as ``AHRS_ORIENTATION``: with ``R``
its matrix, the compass is written as ``M_b = R M R^T`` and ``ofs_b = R
ofs``, so ArduPilot's output is ``R`` times the calibrated field.  An
external compass (rotated by ``COMPASS_ORIENT`` instead) is not handled.
``COMPASS_SCALE`` is written as 1, so that no learnt scale stays in force.
The offsets' vector length is checked against ``COMPASS_OFFS_MAX`` (1800
mGauss by default) as the pre-arm check does (libraries/AP_Arming/
AP_Arming.cpp, ``compass_checks``: ``offsets.length() >
get_offsets_max()``).

``a_in``, ``w_in`` and ``m_in`` are the driver's readings, the raw counts at
the chip's nominal scale (9.80665 m/s^2 per g; deg -> rad; 1000 mG per
gauss), which is what motecal's nominal scales assume.  motecal's
accelerometer matrix keeps its diagonal; its magnetometer matrix ``A = U P``
(polar) keeps the symmetric ``P``: the magnitudes are the same and the frame
turns by U's angle (a magnitude-only fit does not fix that rotation anyway).
"""
from __future__ import annotations

import numpy as np

from ..errors import UserError
from .common import (Export, ExportOptions, Target, float32_value, fmt_float, header_words,
                     per_axis_lost, polar, rotation_deg)

G0 = 9.80665
OFS_MAX_MG = 1800.0           # COMPASS_OFFS_MAX default (AP_COMPASS_OFFSETS_MAX_DEFAULT)

# ArduPilot's Rotation (libraries/AP_Math/rotations.h): number -> (name, roll,
# pitch, yaw) in degrees; the vector is rotated by Rz(yaw) Ry(pitch) Rx(roll).
# 38 (Yaw293Pitch68Roll180, a measured matrix) and the custom ones (100..102)
# are not offered.
ROTATIONS = {
    0: ("NONE", 0, 0, 0), 1: ("YAW_45", 0, 0, 45), 2: ("YAW_90", 0, 0, 90),
    3: ("YAW_135", 0, 0, 135), 4: ("YAW_180", 0, 0, 180), 5: ("YAW_225", 0, 0, 225),
    6: ("YAW_270", 0, 0, 270), 7: ("YAW_315", 0, 0, 315), 8: ("ROLL_180", 180, 0, 0),
    9: ("ROLL_180_YAW_45", 180, 0, 45), 10: ("ROLL_180_YAW_90", 180, 0, 90),
    11: ("ROLL_180_YAW_135", 180, 0, 135), 12: ("PITCH_180", 0, 180, 0),
    13: ("ROLL_180_YAW_225", 180, 0, 225), 14: ("ROLL_180_YAW_270", 180, 0, 270),
    15: ("ROLL_180_YAW_315", 180, 0, 315), 16: ("ROLL_90", 90, 0, 0),
    17: ("ROLL_90_YAW_45", 90, 0, 45), 18: ("ROLL_90_YAW_90", 90, 0, 90),
    19: ("ROLL_90_YAW_135", 90, 0, 135), 20: ("ROLL_270", 270, 0, 0),
    21: ("ROLL_270_YAW_45", 270, 0, 45), 22: ("ROLL_270_YAW_90", 270, 0, 90),
    23: ("ROLL_270_YAW_135", 270, 0, 135), 24: ("PITCH_90", 0, 90, 0),
    25: ("PITCH_270", 0, 270, 0), 26: ("PITCH_180_YAW_90", 0, 180, 90),
    27: ("PITCH_180_YAW_270", 0, 180, 270), 28: ("ROLL_90_PITCH_90", 90, 90, 0),
    29: ("ROLL_180_PITCH_90", 180, 90, 0), 30: ("ROLL_270_PITCH_90", 270, 90, 0),
    31: ("ROLL_90_PITCH_180", 90, 180, 0), 32: ("ROLL_270_PITCH_180", 270, 180, 0),
    33: ("ROLL_90_PITCH_270", 90, 270, 0), 34: ("ROLL_180_PITCH_270", 180, 270, 0),
    35: ("ROLL_270_PITCH_270", 270, 270, 0), 36: ("ROLL_90_PITCH_180_YAW_90", 90, 180, 90),
    37: ("ROLL_90_YAW_270", 90, 0, 270), 39: ("PITCH_315", 0, 315, 0),
    40: ("ROLL_90_PITCH_315", 90, 315, 0), 41: ("PITCH_7", 0, 7, 0),
    42: ("ROLL_45", 45, 0, 0), 43: ("ROLL_315", 315, 0, 0),
}


def parse_rotation(text) -> int:
    """ArduPilot's Rotation number, from a number or a name (``YAW_90``,
    ``ROTATION_YAW_90``, ``Yaw90``); UserError for anything else."""
    t = str(text).strip()
    if t.isdigit() and int(t) in ROTATIONS:
        return int(t)
    key = t.upper().removeprefix("ROTATION_").replace("_", "")
    for n, (name, *_) in ROTATIONS.items():
        if key == name.replace("_", ""):
            return n
    raise UserError(f"--orientation {t!r:.40}: not an ArduPilot rotation this writer takes "
                    "(0..43 but 38, or a name such as YAW_90; AHRS_ORIENTATION's values)")


def rotation_matrix(n: int) -> np.ndarray:
    """The matrix ArduPilot's ``Vector3f::rotate(Rotation n)`` applies."""
    _, r, p, y = ROTATIONS[n]
    r, p, y = np.radians([r, p, y])
    Rx = np.array([[1, 0, 0], [0, np.cos(r), -np.sin(r)], [0, np.sin(r), np.cos(r)]])
    Ry = np.array([[np.cos(p), 0, np.sin(p)], [0, 1, 0], [-np.sin(p), 0, np.cos(p)]])
    Rz = np.array([[np.cos(y), -np.sin(y), 0], [np.sin(y), np.cos(y), 0], [0, 0, 1]])
    R = Rz @ Ry @ Rx
    return np.where(np.abs(R) < 1e-15, 0.0, R)


def params(board, opts: ExportOptions = ExportOptions()) -> dict:
    """The parameters, float64 and unformatted."""
    p = {}
    if board.accel is not None:
        A, c = board.accel.A, board.accel.c
        lsb = board.accel.lsb_per_unit
        for i, ax in enumerate("XYZ"):
            s = A[i, i] * lsb                         # a_in = raw * G0 / lsb
            p[f"INS_ACCSCAL_{ax}"] = s
            p[f"INS_ACCOFFS_{ax}"] = -G0 * c[i] / s
    if board.gyro is not None:
        G = board.gyro.A * board.gyro.lsb_per_unit
        b = -np.linalg.solve(G, board.gyro.c)        # nominal deg/s
        for i, ax in enumerate("XYZ"):
            p[f"INS_GYROFFS_{ax}"] = float(np.radians(b[i]))
    if board.mag is not None:
        A, c = board.mag.A, board.mag.c
        lsb = board.mag.lsb_per_unit
        U, P = polar(A)
        M = P * lsb                                   # m_in = raw * 1000 / lsb (mG)
        ofs = np.linalg.solve(M, 1000.0 * U.T @ c)
        R = rotation_matrix(opts.orientation)         # applied before correct_field
        M, ofs = R @ M @ R.T, R @ ofs
        for i, ax in enumerate("XYZ"):
            p[f"COMPASS_OFS_{ax}"] = ofs[i]
            p[f"COMPASS_DIA_{ax}"] = M[i, i]
        p["COMPASS_ODI_X"], p["COMPASS_ODI_Y"], p["COMPASS_ODI_Z"] = M[0, 1], M[0, 2], M[1, 2]
        p["COMPASS_SCALE"] = 1.0
    p["AHRS_ORIENTATION"] = opts.orientation
    return p


def parse(text: str) -> dict:
    """``NAME,VALUE`` (or ``NAME VALUE``) lines; ``#`` comments."""
    out = {}
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        name, val = line.replace(",", " ").split()
        out[name] = float(val)
    return out


def apply_fns(p: dict, board) -> dict:
    """ArduPilot's arithmetic (float32) on parsed parameters, in its order of
    operations with the board rotation ``AHRS_ORIENTATION``, in g, deg/s,
    gauss; its body-frame output turned back into the session's axes
    (``R^T``) to compare with the calibration."""
    f32 = np.float32
    out = {}
    R = rotation_matrix(int(p.get("AHRS_ORIENTATION", 0)))
    Rf = R.astype(f32)

    def back(body):                                  # body frame -> the session's axes
        return np.asarray(body, float) @ R
    if "INS_ACCSCAL_X" in p:
        s = np.array([p[f"INS_ACCSCAL_{a}"] for a in "XYZ"], f32)
        o = np.array([p[f"INS_ACCOFFS_{a}"] for a in "XYZ"], f32)
        lsb = board.accel.lsb_per_unit
        out["accel"] = lambda raw, s=s, o=o, lsb=lsb: back(
            (s * (np.asarray(raw, f32) * f32(G0 / lsb) - o)) @ Rf.T) / G0
    if "INS_GYROFFS_X" in p:
        o = np.array([p[f"INS_GYROFFS_{a}"] for a in "XYZ"], f32)
        lsb = board.gyro.lsb_per_unit
        out["gyro"] = lambda raw, o=o, lsb=lsb: np.degrees(back(
            (np.asarray(raw, f32) * f32(np.pi / 180 / lsb) - o) @ Rf.T))
    if "COMPASS_DIA_X" in p:
        d = [p[f"COMPASS_DIA_{a}"] for a in "XYZ"]
        x, y, z = p["COMPASS_ODI_X"], p["COMPASS_ODI_Y"], p["COMPASS_ODI_Z"]
        M = np.array([[d[0], x, y], [x, d[1], z], [y, z, d[2]]], f32)
        o = np.array([p[f"COMPASS_OFS_{a}"] for a in "XYZ"], f32)
        k = f32(p.get("COMPASS_SCALE", 0.0) or 1.0)
        lsb = board.mag.lsb_per_unit
        out["mag"] = lambda raw, o=o, M=M, k=k, lsb=lsb: back(
            ((np.asarray(raw, f32) * f32(1000.0 / lsb)) @ Rf.T + o) * k @ M.T) / 1000.0
    return out


def write(board, opts: ExportOptions = ExportOptions()) -> Export:
    p = params(board, opts)
    rot = ROTATIONS[opts.orientation][0]
    frame = (f"ArduPilot's sensor frame = the session's axes (the driver's chip rotation: "
             f"none); AHRS_ORIENTATION {opts.orientation} ({rot}): the INS offsets and scales "
             "apply before it, the compass after it (written in that frame)")
    lines = [f"# motecal calibration for {header_words(board)}",
             f"# axes: {frame}",
             "# INS_ACCOFFS m/s^2 (subtracted), INS_ACCSCAL (multiplies), INS_GYROFFS rad/s "
             "(subtracted), COMPASS_OFS mGauss (added), COMPASS_SCALE, COMPASS_DIA/ODI "
             "(symmetric matrix); internal compass"]
    lines += [f"{k},{int(v)}" if k == "AHRS_ORIENTATION"
              else f"{k},{fmt_float(float32_value(k, v, 'ardupilot'))}" for k, v in p.items()]
    text = "\n".join(lines) + "\n"
    notes = []
    lost = per_axis_lost(board, "offset and scale per axis", "no gyroscope scale parameter, "
                         "and ArduPilot re-learns the offsets at boot")
    if board.mag is not None:
        U, _ = polar(board.mag.A)
        lost["mag"] = [f"a symmetric matrix: the calibration's frame turns by "
                       f"{rotation_deg(U):.2f} deg (magnitudes unchanged)"]
        length = float(np.linalg.norm([p[f"COMPASS_OFS_{a}"] for a in "XYZ"]))
        if length > OFS_MAX_MG:
            notes.append(f"COMPASS_OFS is {length:.0f} mGauss long, beyond COMPASS_OFFS_MAX "
                         f"({OFS_MAX_MG:g} by default): ArduPilot's pre-arm check fails "
                         "('Compass offsets too high') unless COMPASS_OFFS_MAX is raised")
    return Export("ardupilot", text, apply_fns(parse(text), board), lost,
                  {s: "9 significant digits, applied in float32" for s, _ in board.sensors()},
                  notes, frame=frame)


TARGETS = (Target("ardupilot", "an ArduPilot parameter file (INS_ACC*, INS_GYROFFS, "
                               "COMPASS_*; Mission Planner loads it)", write, ("orientation",)),)
