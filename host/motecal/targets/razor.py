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

**Frames.**  The firmware reads the chips' registers into its board frame
(``Sensors.ino``: ``Read_Accel`` accel = (chip y, chip x, chip z);
``Read_Gyro`` gyro = (-chip y, -chip x, -chip z); ``Read_Magn`` for the
SEN-10736 and SEN-10125 boards magnetom = (-chip y, -chip x, -chip z)).  A
calibration in the chips' axes (a session logged by motecal, its CSV,
timestamped chip logs) is written in that frame: ``A' = M A M^T``, ``c' = M
c`` with ``M`` the firmware's map.  One in the firmware's frame already
(Razor logs imported by motecal) is written as it is.  Which one a session
is comes from its ``axis_frame`` (recorded by import; calibrate copies it
into cal.json), or ``--axes``; a frame motecal cannot tell (other tools'
logs) is written as it is, and the output says so.

The ROS node (``my_razor.yaml``) sends the same numbers, lower-case names,
to the firmware over the serial line as ``str(value)``, which the firmware
reads with Arduino's ``Stream::parseFloat``: digits into a 32-bit ``long``,
one '.', no exponent.  So the YAML never holds an exponent, at most 9
significant digits, nothing of 1e9 or more, and a value under 1e-4 (which
Python's ``str`` writes in exponent form) is written to 4 decimals.

The C block and the YAML are one list of entries (``_entries``) in two
renderings (``_RENDER``).
"""
from __future__ import annotations

import json
import re

import numpy as np

from ..sessions.session import NOMINAL_SCALES
from .common import (Export, ExportOptions, Target, TargetCannotHold, float32_value, fmt_float,
                     header_words, per_axis_lost)

GRAVITY = 256.0                    # the firmware's 1 g
FIRMWARE_GYRO_GAIN = 0.06957       # deg/s per LSB, ITG-3200 / ITG-3205
AXES = "XYZ"
_SWAP = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
# the firmware's board frame from the chips' axes (Sensors.ino, above)
CHIP_TO_BOARD = {"accel": _SWAP, "gyro": -_SWAP, "mag": -_SWAP}
ARDUINO_FLOAT_MAX = 1e9            # parseFloat's long holds 9 digits
PYTHON_STR_MIN = 1e-4              # str() writes smaller floats as 1e-05


# ------------------------------------------------------------------ frames

def axes_kind(axis_frame: str | None) -> str | None:
    """"razor", "chip" or None (not known) from a session's ``axis_frame``."""
    from ..sessions.importer import CSV_FRAME, RAZOR_FLOAT_FRAME, RAZOR_FRAME, TIMESTAMPED_FRAME
    if axis_frame in (RAZOR_FRAME, RAZOR_FLOAT_FRAME):
        return "razor"
    if axis_frame in (CSV_FRAME, TIMESTAMPED_FRAME):
        return "chip"
    return None


def frame(opts: ExportOptions) -> tuple[bool, str]:
    """(remap the chips' axes into the board frame?, the frame written in words)."""
    kind, why = opts.axes, "--axes"
    if kind is None:
        kind, why = axes_kind(opts.axis_frame), f"the session's axes: {opts.axis_frame}"
    if kind == "chip":
        return True, (f"the Razor firmware's board frame, remapped from the chips' axes ({why}): "
                      "accel (y, x, z), gyro (-y, -x, -z), mag (-y, -x, -z) of the chips")
    if kind == "razor":
        return False, f"the Razor firmware's board frame, as the calibration's ({why})"
    said = opts.axis_frame or "not recorded in the calibration (give --db)"
    return False, (f"as the calibration's, not remapped: its axes are {said}; if those are "
                   "the chips' axes, give --axes chip")


def in_board_frame(sensor: str, A, c, remap: bool):
    """(A, c) of a calibration in the firmware's board frame."""
    if not remap:
        return np.asarray(A, float), np.asarray(c, float)
    M = CHIP_TO_BOARD[sensor]
    return M @ A @ M.T, M @ c


# ------------------------------------------------------------------ numbers

def constants(board, opts: ExportOptions = ExportOptions()) -> dict:
    """The firmware's numbers from a BoardCalibration (float64, unformatted)."""
    remap, _ = frame(opts)
    k = {}
    if board.accel is not None:
        A, c = in_board_frame("accel", board.accel.A, board.accel.c, remap)
        for i, ax in enumerate(AXES):
            a = A[i, i]
            h, off = 1.0 / a, -c[i] / a                 # g = (raw - off) / h
            k[f"ACCEL_{ax}_MIN"] = off - h * 1.0
            k[f"ACCEL_{ax}_MAX"] = off + h * 1.0
    if board.gyro is not None:
        A, c = in_board_frame("gyro", board.gyro.A, board.gyro.c, remap)
        b = -np.linalg.solve(A, c)                      # counts
        for i, ax in enumerate(AXES):
            k[f"GYRO_AVERAGE_OFFSET_{ax}"] = b[i]
    if board.mag is not None:
        A, c = in_board_frame("mag", board.mag.A, board.mag.c, remap)
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


def arduino_float(v: float, name: str = "value") -> str:
    """``v`` as the ROS node sends it and Arduino's parseFloat reads it back:
    positional (never an exponent), at most 9 significant digits; a value
    under 1e-4 to 4 decimals; TargetCannotHold from 1e9 on."""
    v = float32_value(name, v, "razor-yaml")
    if abs(v) >= ARDUINO_FLOAT_MAX:
        raise TargetCannotHold(f"razor-yaml: {name} = {v:g} is beyond what the firmware's "
                               f"parseFloat reads (|value| < {ARDUINO_FLOAT_MAX:g})")
    if abs(v) < PYTHON_STR_MIN:
        v = round(v, 4) + 0.0                    # + 0.0: never "-0"
    return np.format_float_positional(v, precision=9, unique=False, fractional=False,
                                      trim="-")


def gyro_gain(board) -> float:
    """deg/s per LSB: the firmware's ITG-3200 constant for that chip's nominal
    scale (14.375 LSB per deg/s), else the session's nominal scale (set
    GYRO_GAIN to it in the firmware; the block says so)."""
    lsb = board.gyro.lsb_per_unit if board is not None and board.gyro else 14.375
    return FIRMWARE_GYRO_GAIN if abs(lsb - 14.375) < 1e-9 else 1.0 / lsb


def _lost(board) -> dict:
    return per_axis_lost(board, "min/max per axis",
                         f"the firmware's one GYRO_GAIN ({fmt_float(gyro_gain(board), 6)} deg/s "
                         "per LSB) replaces the fitted scale and misalignment")


def _apply_fns(k: dict, board, opts: ExportOptions = ExportOptions()) -> dict:
    """The firmware's arithmetic (float32) on parsed constants, in g, deg/s,
    gauss: raw counts in the session's axes are read into the board frame as
    the firmware reads them, and the output is turned back into the
    session's axes to compare with the calibration."""
    remap, _ = frame(opts)
    f32 = np.float32
    out = {}

    def framed(sensor, fn):
        if not remap:
            return fn
        M = CHIP_TO_BOARD[sensor]
        return lambda raw: fn(np.asarray(raw, float) @ M.T) @ M

    if "ACCEL_X_MIN" in k:
        mn = np.array([k[f"ACCEL_{a}_MIN"] for a in AXES], f32)
        mx = np.array([k[f"ACCEL_{a}_MAX"] for a in AXES], f32)
        off = (mn + mx) / f32(2)
        scale = f32(GRAVITY) / (mx - off)
        out["accel"] = framed("accel", lambda raw, off=off, scale=scale:
                              ((np.asarray(raw, f32) - off) * scale).astype(float) / GRAVITY)
    if "GYRO_AVERAGE_OFFSET_X" in k:
        off = np.array([k[f"GYRO_AVERAGE_OFFSET_{a}"] for a in AXES], f32)
        gain = f32(gyro_gain(board))
        out["gyro"] = framed("gyro", lambda raw, off=off, gain=gain:
                             ((np.asarray(raw, f32) - off) * gain).astype(float))
    if "magn_ellipsoid_center" in k:
        ctr = np.array(k["magn_ellipsoid_center"], f32)
        T = np.array(k["magn_ellipsoid_transform"], f32)
        lsb = board.mag.lsb_per_unit if board is not None and board.mag else NOMINAL_SCALES["mag"]
        out["mag"] = framed("mag", lambda raw, ctr=ctr, T=T, lsb=lsb:
                            ((np.asarray(raw, f32) - ctr) @ T.T).astype(float) / lsb)
    return out


# ------------------------------------------------------------------ the text

def _entries(board, k: dict, remap_words: str, title: str) -> list[tuple]:
    """What both renderings hold, in order: ("comment", text), ("scalar",
    NAME, value), ("vector", name, [3]), ("matrix", name, [[3] x 3]),
    ("flag", C name, YAML name)."""
    e = [("comment", f"motecal {title} for {header_words(board)}"),
         ("comment", f"axes: {remap_words}")]
    if board.accel is not None:
        e.append(("comment", "Accelerometer: offset and scale per axis (cross-axis terms "
                             "dropped)"))
        e += [("scalar", f"ACCEL_{a}_{m}", k[f"ACCEL_{a}_{m}"]) for a in AXES
              for m in ("MIN", "MAX")]
    if board.mag is not None:
        e.append(("comment", "Magnetometer, standard calibration (unused with the extended "
                             "one)"))
        e += [("scalar", f"MAGN_{a}_{m}", k[f"MAGN_{a}_{m}"]) for a in AXES
              for m in ("MIN", "MAX")]
        e += [("comment", "Magnetometer, extended calibration (hard and soft iron)"),
              ("flag", "CALIBRATION__MAGN_USE_EXTENDED", "calibration_magn_use_extended"),
              ("vector", "magn_ellipsoid_center", k["magn_ellipsoid_center"]),
              ("matrix", "magn_ellipsoid_transform", k["magn_ellipsoid_transform"])]
    if board.gyro is not None:
        gain = gyro_gain(board)
        if gain == FIRMWARE_GYRO_GAIN:
            e.append(("comment", f"Gyroscope: average offsets in counts (the firmware's "
                                 f"GYRO_GAIN {FIRMWARE_GYRO_GAIN} deg/s per LSB stays)"))
        else:
            e.append(("comment", f"Gyroscope: average offsets in counts; this chip's nominal "
                                 f"gain: set GYRO_GAIN to {fmt_float(gain)} deg/s per LSB"))
        e += [("scalar", f"GYRO_AVERAGE_OFFSET_{a}", k[f"GYRO_AVERAGE_OFFSET_{a}"])
              for a in AXES]
    return e


def _c_number(v, name):
    return fmt_float(float32_value(name, v, "razor-c"))


def _render(entries, style: str) -> str:
    """The entries as the Razor C block (``style`` "c") or my_razor.yaml ("yaml")."""
    c = style == "c"
    num = _c_number if c else arduino_float
    lines = [] if c else ["##### Calibration ####"]
    for kind, name, *rest in entries:
        if kind == "comment":
            lines.append(("// " if c else "# ") + name)
        elif kind == "scalar":
            v = num(rest[0], name)
            lines.append(f"#define {name} ((float) {v})" if c else f"{name.lower()}: {v}")
        elif kind == "flag":
            lines.append(f"#define {name} true" if c else f"{rest[0]}: true")
        else:
            rows = [rest[0]] if kind == "vector" else rest[0]
            vals = [", ".join(num(v, f"{name}[{i}]") for v in row) for i, row in enumerate(rows)]
            if kind == "vector":
                body = vals[0]
                lines.append(f"const float {name}[3] = {{{body}}};" if c else f"{name}: [{body}]")
            else:
                body = (", ".join("{" + v + "}" for v in vals) if c
                        else ", ".join("[" + v + "]" for v in vals))
                lines.append(f"const float {name}[3][3] = {{{body}}};" if c
                             else f"{name}: [{body}]")
    return "\n".join(lines) + "\n"


_ROUNDING = {"razor-c": "numbers written with 9 significant digits, applied in float32",
             "razor-yaml": "numbers written with 9 significant digits and no exponent "
                           "(under 1e-4: to 4 decimals), applied in float32"}
_TITLE = {"razor-c": "Razor AHRS constants", "razor-yaml": "razor_imu_9dof calibration"}


def _write(board, opts: ExportOptions, fmt: str) -> Export:
    remap, words = frame(opts)
    k = constants(board, opts)
    text = _render(_entries(board, k, words, _TITLE[fmt]), "c" if fmt == "razor-c" else "yaml")
    parse = parse_c if fmt == "razor-c" else parse_yaml
    return Export(fmt, text, _apply_fns(parse(text), board, opts), _lost(board),
                  {s: _ROUNDING[fmt] for s, _ in board.sensors()}, frame=words)


def write_c(board, opts: ExportOptions = ExportOptions()) -> Export:
    return _write(board, opts, "razor-c")


def write_yaml(board, opts: ExportOptions = ExportOptions()) -> Export:
    return _write(board, opts, "razor-yaml")


TARGETS = (
    Target("razor-c", "Razor AHRS firmware constants (a block for Razor_AHRS.ino)", write_c,
           ("axes",)),
    Target("razor-yaml", "the ROS razor_imu_9dof node's my_razor.yaml (same numbers, sent to "
                         "the firmware)", write_yaml, ("axes",)),
)


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
