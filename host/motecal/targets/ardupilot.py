"""An ArduPilot parameter file (``NAME,VALUE`` lines, as Mission Planner
saves and loads them; ``#`` comments).

ArduPilot's conventions (libraries/AP_InertialSensor/AP_InertialSensor_Backend.cpp,
``_rotate_and_correct_accel`` / ``_rotate_and_correct_gyro``, and
libraries/AP_Compass/AP_Compass_Backend.cpp, ``correct_field``), in the
sensor frame, before the board rotation:

* accelerometer, m/s^2: ``a = INS_ACCSCAL * (a_in - INS_ACCOFFS)`` per axis:
  the offset is *subtracted*, then scaled; no cross-axis terms;
* gyroscope, rad/s: ``w = w_in - INS_GYROFFS``: an offset only (ArduPilot
  learns it at every boot, so the file's value is a starting point);
* compass, milligauss: ``m = M (m_in + COMPASS_OFS)`` with ``M`` symmetric,
  ``COMPASS_DIA_X/Y/Z`` on its diagonal and ``COMPASS_ODI_X`` = M_xy,
  ``COMPASS_ODI_Y`` = M_xz, ``COMPASS_ODI_Z`` = M_yz: the offset is *added*
  (it is minus the hard-iron centre).

``a_in``, ``w_in`` and ``m_in`` are the driver's readings, the raw counts at
the chip's nominal scale (9.80665 m/s^2 per g; deg -> rad; 1000 mG per
gauss), which is what motecal's nominal scales assume.  motecal's
accelerometer matrix keeps its diagonal; its magnetometer matrix ``A = U P``
(polar) keeps the symmetric ``P``: the magnitudes are the same and the frame
turns by U's angle (a magnitude-only fit does not fix that rotation anyway).
"""
from __future__ import annotations

import numpy as np

from .common import Export, cross_axis_lost, fmt_float, gyro_scale_lost, polar, rotation_deg

G0 = 9.80665
OFS_MAX_MG = 1800.0           # COMPASS_OFFS_MAX default in recent ArduPilot


def params(board) -> dict:
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
        for i, ax in enumerate("XYZ"):
            p[f"COMPASS_OFS_{ax}"] = ofs[i]
            p[f"COMPASS_DIA_{ax}"] = M[i, i]
        p["COMPASS_ODI_X"], p["COMPASS_ODI_Y"], p["COMPASS_ODI_Z"] = M[0, 1], M[0, 2], M[1, 2]
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
    """ArduPilot's arithmetic (float32) on parsed parameters, in g, deg/s, gauss."""
    f32 = np.float32
    out = {}
    if "INS_ACCSCAL_X" in p:
        s = np.array([p[f"INS_ACCSCAL_{a}"] for a in "XYZ"], f32)
        o = np.array([p[f"INS_ACCOFFS_{a}"] for a in "XYZ"], f32)
        lsb = board.accel.lsb_per_unit
        out["accel"] = lambda raw, s=s, o=o, lsb=lsb: \
            (s * (np.asarray(raw, f32) * f32(G0 / lsb) - o)).astype(float) / G0
    if "INS_GYROFFS_X" in p:
        o = np.array([p[f"INS_GYROFFS_{a}"] for a in "XYZ"], f32)
        lsb = board.gyro.lsb_per_unit
        out["gyro"] = lambda raw, o=o, lsb=lsb: np.degrees(
            (np.asarray(raw, f32) * f32(np.pi / 180 / lsb) - o).astype(float))
    if "COMPASS_DIA_X" in p:
        d = [p[f"COMPASS_DIA_{a}"] for a in "XYZ"]
        x, y, z = p["COMPASS_ODI_X"], p["COMPASS_ODI_Y"], p["COMPASS_ODI_Z"]
        M = np.array([[d[0], x, y], [x, d[1], z], [y, z, d[2]]], f32)
        o = np.array([p[f"COMPASS_OFS_{a}"] for a in "XYZ"], f32)
        lsb = board.mag.lsb_per_unit
        out["mag"] = lambda raw, o=o, M=M, lsb=lsb: ((np.asarray(raw, f32) * f32(1000.0 / lsb) + o) @ M.T
                                  ).astype(float) / 1000.0
    return out


def write(board) -> Export:
    p = params(board)
    lines = [f"# motecal calibration for mote {board.mote}, session '{board.session}' "
             f"({board.created}); ArduPilot sensor frame = the session's axes",
             "# INS_ACCOFFS m/s^2 (subtracted), INS_ACCSCAL (multiplies), INS_GYROFFS rad/s "
             "(subtracted), COMPASS_OFS mGauss (added), COMPASS_DIA/ODI (symmetric matrix)"]
    lines += [f"{k},{fmt_float(v)}" for k, v in p.items()]
    text = "\n".join(lines) + "\n"
    lost, notes = {}, []
    if board.accel is not None:
        note = cross_axis_lost(board, "offset and scale per axis")
        if note:
            lost["accel"] = [note]
    if board.gyro is not None:
        lost["gyro"] = [f"offsets only: no gyroscope scale parameter (largest |G - I| "
                        f"{gyro_scale_lost(board):.4f} is lost); ArduPilot re-learns the "
                        f"offsets at boot"]
    if board.mag is not None:
        U, _ = polar(board.mag.A)
        lost["mag"] = [f"a symmetric matrix: the calibration's frame turns by "
                       f"{rotation_deg(U):.2f} deg (magnitudes unchanged)"]
        big = [k for k in ("COMPASS_OFS_X", "COMPASS_OFS_Y", "COMPASS_OFS_Z")
               if abs(p[k]) > OFS_MAX_MG]
        if big:
            notes.append(f"{', '.join(big)} beyond COMPASS_OFFS_MAX ({OFS_MAX_MG:g} mGauss): "
                         f"ArduPilot's pre-arm check will complain")
    return Export("ardupilot", text, apply_fns(parse(text), board), lost,
                  {s: "9 significant digits, applied in float32" for s, _ in board.sensors()},
                  notes)
