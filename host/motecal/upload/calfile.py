"""cal.json -> what upload needs of it (``CalFile``) -> the mote's
fixed-point set, checked by the mote's own C code before anything is sent."""
from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np

from ..errors import QualityError, UserError
from ..firmware import fixedpoint as FP
from ..inputs import read_input_text
from ..line import protocol as P
from ..line.protocol import MOTE_ID_MAX, MOTE_ID_MIN

# --------------------------------------------------------------------------
# cal.json -> the set
# --------------------------------------------------------------------------
def _numbers(v) -> bool:
    """Nested lists of JSON numbers only (a string "1.0" or true is not one)."""
    if isinstance(v, list):
        return all(_numbers(x) for x in v)
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _matrix(d, key, shape, where):
    if key not in d:
        raise UserError(f"{where}: no {key!r}")
    if not _numbers(d[key]):
        raise UserError(f"{where}: {key!r} is not a list of numbers")
    try:
        a = np.array(d[key], dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise UserError(f"{where}: {key!r} is not a list of numbers") from None
    if a.shape != shape:
        raise UserError(f"{where}: {key!r} must be {'x'.join(map(str, shape))}, not "
                        f"{'x'.join(map(str, a.shape)) or 'a number'}")
    if not np.all(np.isfinite(a)):
        raise UserError(f"{where}: {key!r} holds a missing or infinite value")
    return a


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
    """Read and check a cal.json (the JSON of ``calib.result.BoardCalibration``).

    Only what upload needs must be there: ``format_version``, ``mote`` and,
    per calibrated sensor, ``A`` (3x3) and ``c`` (3); the messages name the
    field that is missing or wrong."""
    from ..calib.result import FORMAT_VERSION
    text = read_input_text(path)         # a regular file of sane size: never /dev/zero
    try:
        d = json.loads(text)
    except (json.JSONDecodeError, RecursionError) as e:
        raise UserError(f"{path} is not JSON: {e}") from None
    if not isinstance(d, dict) or "format_version" not in d:
        raise UserError(f"{path} is not a motecal calibration (no format_version)")
    fv = d["format_version"]
    if isinstance(fv, bool) or not isinstance(fv, int) or not 1 <= fv <= FORMAT_VERSION:
        raise UserError(f"{path}: calibration format_version {fv!r} is not one this motecal "
                        f"reads (1..{FORMAT_VERSION})")
    mote = d.get("mote")
    if isinstance(mote, bool) or not isinstance(mote, int) or \
            not MOTE_ID_MIN <= mote <= MOTE_ID_MAX:
        raise UserError(f"{path}: no mote id (\"mote\": an integer "
                        f"{MOTE_ID_MIN}..{MOTE_ID_MAX})")
    gate = d.get("gate") or {}
    if not isinstance(gate, dict):
        raise UserError(f"{path}: \"gate\" is not an object")
    return CalFile(str(path), mote, _physical(d, str(path)), str(d.get("session") or ""), gate,
                   _temps(d, str(path)))


def cal_from_board(board, where: str = "calibration") -> CalFile:
    d = board.to_json()
    return CalFile(where, int(board.mote), _physical(d, where), board.session,
                   dict(board.gate or {}), _temps(d, where))


def _temps(d: dict, where: str) -> dict:
    """Each calibrated sensor's temperature model (cal.json format 2)."""
    from ..calib.result import TempModel
    temps = {}
    for name in P.SENSORS:
        s = d.get(name)
        t = s.get("temperature") if isinstance(s, dict) and s.get("A") is not None else None
        if not t:
            continue
        if not isinstance(t, dict):
            raise UserError(f"{where}: {name}: \"temperature\" is not an object")
        try:
            tm = TempModel.from_json(t)
        except KeyError as e:
            raise UserError(f"{where}: {name}: temperature: no {e}") from None
        except (TypeError, ValueError) as e:
            raise UserError(f"{where}: {name}: temperature: {e}") from None
        if not (np.isfinite(tm.t_ref_c) and np.all(np.isfinite(tm.range_c))):
            raise UserError(f"{where}: {name}: temperature: t_ref_c or range_c is not finite")
        temps[name] = tm
    return temps


def _physical(d: dict, where: str) -> dict:
    physical = {}
    for name in P.SENSORS:
        s = d.get(name)
        if not s:
            continue
        if not isinstance(s, dict):
            raise UserError(f"{where}: {name} is not an object")
        A = _matrix(s, "A", (3, 3), f"{where}: {name}")
        c = _matrix(s, "c", (3,), f"{where}: {name}")
        physical[name] = (A, c)
    if not physical:
        raise UserError(f"{where}: no calibrated sensor (accel, gyro or mag with A and c): "
                        "nothing to upload")
    return physical


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
