"""Text for the upload command: a set in force decoded in physical units, and
what a dry run would send."""
from __future__ import annotations

import numpy as np

from ..firmware import fixedpoint as FP
from ..line import protocol as P
from ..sessions.session import NOMINAL_SCALES, UNITS
from .calfile import CalFile, build_set, mote_check
from .uploader import InForce, fragments, sensor_names

# --------------------------------------------------------------------------
# Showing a set
# --------------------------------------------------------------------------
def _fmt_row(v, spec):
    return "[" + ", ".join(format(float(x), spec) for x in v) + "]"


def show_lines(inf: InForce, cal: CalFile | None = None) -> list[str]:
    """The set in force, decoded, in physical units."""
    cs = inf.calset
    lines = [f"mote {inf.mote}: calibration version {inf.version} in force "
             f"(CRC 0x{inf.crc:04x}), corrected: {sensor_names(cs.mask)}"]
    lines += stored_lines(inf)
    if cs.mote != inf.mote:
        lines.append(f"  (the set names mote {cs.mote})")
    for name in P.SENSORS:
        fs = cs.sensors.get(name)
        if fs is None:
            lines.append(f"  {name}: raw")
            continue
        k, unit = NOMINAL_SCALES[name], UNITS[name]
        A, c = fs.matrix / k, fs.offset / k
        lines.append(f"  {name} (Q{fs.shift}): calibrated [{unit}] = A @ raw [counts] + c")
        for i in range(3):
            lines.append(f"    A[{i}] = {_fmt_row(A[i], '+.6e')}")
        lines.append(f"    c    = {_fmt_row(c, '+.6f')} {unit}"
                     f"  (= {_fmt_row(fs.offset, '+.2f')} counts)")
        per = f"({unit})" if "/" in unit else unit
        lines.append(f"    scale {_fmt_row(np.diag(fs.matrix), '.5f')} x nominal "
                     f"{k:g} LSB/{per}")
        if name in cs.temps:
            lines += ["  " + ln for ln in FP.temp_lines(name, cs.temps[name])]
    if cal is not None:
        mine, _ = build_set(cal, inf.mote, inf.version if inf.version else 1,
                            temperature=cs.format == P.CALSET_TEMP)
        same = inf.version and mine == inf.data
        lines.append(f"  {'equals' if same else 'differs from'} {cal.path} "
                     f"(quantised for mote {inf.mote}, version {inf.version})")
    return lines


def stored_lines(inf: InForce) -> list[str]:
    """What the mote's EEPROM holds, when it is not the set in force (or
    when the image does not say)."""
    if not inf.reports_stored:
        return ["  stored in its EEPROM: not reported (firmware built before the stored-set "
                "report)"]
    if inf.stored:
        return []
    held = (f"version {inf.stored_version} (CRC 0x{inf.stored_crc:04x})"
            if inf.stored_version else "no set")
    after = (f"version {inf.stored_version}" if inf.stored_version
             else "raw output, version 0")
    why = {P.STORE_WRITING: f"version {inf.version} is being written",
           P.STORE_FAILED: f"writing version {inf.version} failed: the EEPROM did not read "
                           "back what was written"}.get(inf.store, "")
    return [f"  stored in its EEPROM: {held}, not the set in force"
            + (f" ({why})" if why else "") + f": after a reset the mote has {after}"]


def dry_run_lines(cal: CalFile, mote: int, version: int | None,
                  temperature: bool = True) -> list[str]:
    v = version or 1
    calset, report = build_set(cal, mote, v, temperature)
    lines = [f"{cal.path}: mote {cal.mote}" + (f", session {cal.session}" if cal.session else "")
             + (", refused by the quality gate" if cal.refused else "")]
    lines.append(f"set for mote {mote}, version {v}"
                 + ("" if version else " (at upload: the version in force + 1)")
                 + f": {len(calset)} bytes in {len(fragments(calset))} fragments, "
                   f"CRC 0x{P.crc16(calset):04x}"
                 + (" (with temperature terms: needs firmware with on-mote temperature "
                    "correction)" if len(calset) > P.CALSET_SIZE else
                    (" (temperature models left out: --no-temp)"
                     if cal.temps and not temperature else "")))
    lines += FP.format_report(report)
    code = mote_check(calset, mote)
    if code is None:
        lines.append("the mote's checks: not run (no C compiler for tinyos/ninedof_calset.c)")
    elif code == P.CAL_OK:
        lines.append("the mote's checks (tinyos/ninedof_calset.c): accepted")
    else:
        lines.append(f"the mote's checks (tinyos/ninedof_calset.c): would reject: "
                     f"{P.cal_reason(code)}")
    return lines
