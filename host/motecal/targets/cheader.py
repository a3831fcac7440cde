"""A plain C header with the fixed-point set the IRIS firmware applies: per
sensor ``a`` (int16, 3x3), ``c`` (int32) and ``shift``, and the whole
``ninedof_calset`` (tinyos/NineDofMsg.h) as bytes, as EEPROM and upload hold
it.  Built by ``motecal.firmware.fixedpoint`` (the one definition the uploader and the
simulator use); the mote computes ``sat((a raw + c + 2^(shift-1)) >> shift)``
in the nominal counts (256 LSB/g, 14.375 LSB/(deg/s), 1090 LSB/gauss).
"""
from __future__ import annotations

import re

import numpy as np

from ..firmware import fixedpoint as FP
from ..sessions.session import NOMINAL_SCALES, SENSOR_SLICES
from .common import Export, ExportOptions, Target, header_words

VERSION = 1


def build(board):
    """The set and fixedpoint's report, with each sensor's temperature model
    (the 164-byte set the IRIS firmware applies on the mote)."""
    physical = {s: (cal.A, cal.c) for s, cal in board.sensors()}
    temps = {s: cal.temperature for s, cal in board.sensors() if cal.temperature is not None}
    return FP.build_calset(board.mote, VERSION, physical, temps or None)


def write(board, opts: ExportOptions = ExportOptions()) -> Export:
    calset, report = build(board)
    mote = int(board.mote)
    g = f"MOTECAL_CAL_MOTE{mote}_H"
    lines = [f"/* motecal calibration for {header_words(board)}.",
             " * Fixed point as the IRIS firmware applies it (tinyos/ninedof_correct.c):",
             " *   out = sat((a * raw + c + 2^(shift-1)) >> shift), in nominal counts",
             " *   (256 LSB/g, 14.375 LSB/(deg/s), 1090 LSB/gauss). */",
             f"#ifndef {g}", f"#define {g}", "#include <stdint.h>", "",
             f"#define MOTECAL_CAL_MOTE {mote}", f"#define MOTECAL_CAL_VERSION {VERSION}"]
    rounding = {}
    for s in FP.P.SENSORS:
        r = report.get(s)
        if r is None:
            lines.append(f"/* {s}: not corrected (raw) */")
            continue
        fs = r.fixed
        up = s.upper()
        lines += [f"/* {s}: worst case over +-{r.input_range} counts incl. output rounding: "
                  + ", ".join(f"{v:.2f}" for v in r.worst_lsb) + " LSB */",
                  f"#define MOTECAL_{up}_SHIFT {fs.shift}",
                  f"static const int16_t motecal_{s}_a[9] = {{"
                  + ", ".join(str(int(v)) for v in np.asarray(fs.a).reshape(9)) + "};",
                  f"static const int32_t motecal_{s}_c[3] = {{"
                  + ", ".join(str(int(v)) for v in fs.c) + "};"]
        if r.temp is not None:
            lines.append(f"/* {s}: temperature terms in the set below (t_ref, range, offset "
                         f"and gain per TEMP_OUT count: tinyos/ninedof_correct.c) */")
        rounding[s] = (f"fixed point Q{fs.shift}, worst "
                       + ", ".join(f"{v:.2f}" for v in r.worst_lsb)
                       + f" LSB ({np.max(r.worst_units):.3g} {FP.UNITS[s]})"
                       + ("" if r.temp is None else
                          f"; its temperature terms held (rounding over the range: offset <= "
                          f"{r.temp_offset_error:.2g} counts, gain <= {r.temp_gain_error:.2g})"))
    body = ", ".join(f"0x{b:02x}" for b in calset)
    lines += ["/* the ninedof_calset (tinyos/NineDofMsg.h) as stored and uploaded */",
              f"static const uint8_t motecal_calset[{len(calset)}] = {{{body}}};", "",
              f"#endif /* {g} */"]
    text = "\n".join(lines) + "\n"
    return Export("c-header", text, apply_fns(parse(text)), {}, rounding,
                  frame="as the calibration's (the mote's sample frame)",
                  holds_temperature=tuple(s for s, r in report.items() if r.temp is not None))


TARGETS = (Target("c-header", "the IRIS fixed-point set as a C header (the bytes upload "
                              "sends)", write),)


_BYTES = re.compile(r"motecal_calset\[(\d+)\]\s*=\s*\{([^}]*)\}")


def parse(text: str) -> bytes:
    m = _BYTES.search(text)
    if not m:
        raise ValueError("no motecal_calset in the header")
    data = bytes(int(t, 16) for t in m.group(2).split(","))
    if len(data) != int(m.group(1)):
        raise ValueError("motecal_calset length differs from its declaration")
    return data


def apply_fns(calset: bytes) -> dict:
    """What the mote outputs for a stream of samples of a freshly applied
    set (in order: its rounding carries a residual from sample to sample,
    fixedpoint.feedback_correct), in g, deg/s, gauss."""
    cs = FP.unpack_calset(calset)
    out = {}
    for s in cs.sensors:
        def f(raw, s=s):
            raw = np.asarray(raw, float)
            full = np.zeros((len(raw), 9))
            full[:, SENSOR_SLICES[s]] = raw
            # (a set with temperature terms: at each sensor's t_ref, as
            # the mote before it has a temperature)
            y = FP.feedback_correct(cs, full)[:, SENSOR_SLICES[s]]
            return y / NOMINAL_SCALES[s]
        out[s] = f
    return out
