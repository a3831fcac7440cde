"""cal.json -> what upload needs of it (``CalFile``) -> the mote's
fixed-point set, checked by the mote's own C code before anything is sent."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import QualityError, UserError
from ..firmware import fixedpoint as FP
from ..inputs import read_input_text
from ..line import protocol as P
from ..line.protocol import MOTE_ID_MAX, MOTE_ID_MIN

# --------------------------------------------------------------------------
# cal.json -> the set (checked by calib.result.check_document, the one
# validation of cal.json that export-cal and report share)
# --------------------------------------------------------------------------
@dataclass
class CalFile:
    """What upload needs of a cal.json: per sensor (A, c), the mote, the gate."""
    path: str
    mote: int
    physical: dict                     # sensor -> (A (3, 3), c (3,)) in its unit
    session: str = ""
    gate: dict = field(default_factory=dict)
    temps: dict = field(default_factory=dict)   # sensor -> calib.result.TempModel

    @property
    def refused(self) -> bool:
        return bool(self.gate) and not self.gate.get("accepted", True)


def load_cal(path) -> CalFile:
    """Read and check a cal.json (the JSON of ``calib.result.BoardCalibration``,
    checked by ``calib.result.read_document``): only what upload needs must be
    there: ``format_version``, ``mote`` and, per calibrated sensor, ``A``
    (3x3) and ``c`` (3); the messages name the field that is missing or
    wrong.  The mote must be one the upload can address (1..65534)."""
    from ..calib.result import read_document
    text = read_input_text(path)         # a regular file of sane size: never /dev/zero
    d = read_document(text, str(path))
    return _calfile(d, str(path))


def cal_from_board(board, where: str = "calibration") -> CalFile:
    from ..calib.result import check_document
    d = board.to_json()
    check_document(d, where)
    return _calfile(d, where)


def _calfile(d: dict, where: str) -> CalFile:
    """A checked document (``check_document``) as what upload needs of it."""
    from ..calib.result import TempModel
    mote = d["mote"]
    if not MOTE_ID_MIN <= mote <= MOTE_ID_MAX:
        raise UserError(f"{where}: no mote id an upload can address (\"mote\": an integer "
                        f"{MOTE_ID_MIN}..{MOTE_ID_MAX}, not {mote})")
    physical, temps = {}, {}
    for name in P.SENSORS:
        s = d.get(name)
        if s is None:
            continue
        physical[name] = (np.array(s["A"], dtype=np.float64), np.array(s["c"], dtype=np.float64))
        if s.get("temperature") is not None:
            temps[name] = TempModel.from_json(s["temperature"])
    return CalFile(where, mote, physical, str(d.get("session") or ""), dict(d.get("gate") or {}),
                   temps)


def build_set(cal: CalFile, mote: int, version: int,
              temperature: bool = True) -> tuple[bytes, dict]:
    """The set's bytes and fixedpoint's rounding report per sensor; with
    the temperature terms of cal.json's temperature models unless
    ``temperature`` is False (then the plain set, which every image takes)."""
    for name, (A, c) in cal.physical.items():
        try:
            FP.fixed_from_physical(name, A, c)
            if temperature and name in cal.temps:
                FP.fixed_temp(name, cal.temps[name])
        except FP.NotRepresentable as e:
            raise FP.NotRepresentable(f"{cal.path}: {name}: {e}") from None
    try:
        return FP.build_calset(mote, version, cal.physical,
                               cal.temps if temperature else None)
    except FP.NotRepresentable as e:
        raise FP.NotRepresentable(f"{cal.path}: {e}") from None
    except ValueError as e:
        raise UserError(f"{cal.path}: {e}") from None


def mote_check(calset: bytes, mote: int) -> int | None:
    """The reason code the mote's own validation gives (tinyos/ninedof_calset.c
    through ctypes), None when the C code cannot be built here."""
    try:
        from ..firmware import mote_c
        return mote_c.validate(calset, mote)
    except (UserError, OSError, ImportError):
        return None


def check_set(calset: bytes, mote: int, where: str) -> None:
    code = mote_check(calset, mote)
    if code not in (None, P.CAL_OK):
        raise QualityError(f"{where}: the mote would reject this calibration: "
                           f"{P.cal_reason(code)}")
