"""``motecal export-cal``: a calibration (``cal.json``) in another tool's form
(docs/interop.md).  Prints what the target cannot hold and what that costs:
on the session's own rows with ``--db`` (the session named in cal.json, or
``--session``), else over evenly spread directions.  The output file is
written whole or not at all (a temporary file renamed into place)."""
from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

from ..errors import UserError


def _formats():
    from ..targets import FORMATS
    return FORMATS


def write_atomic(path: Path, text: str) -> None:
    path = Path(path)
    d = path.parent if str(path.parent) else Path(".")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=d)
    except OSError as e:
        raise UserError(f"cannot write {path}: {e.strerror or e}") from None
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        os.replace(tmp, path)
    except OSError as e:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise UserError(f"cannot write {path}: {e.strerror or e}") from None


def run(args) -> int:
    from ..calib.result import BoardCalibration
    from ..targets import export
    from ..targets.common import cost_lines, costs
    board = BoardCalibration.load(args.cal)
    if not board.sensors():
        raise UserError(f"{args.cal}: no calibrated sensor in it")
    data = None
    if args.db:
        from ..sessions.store import open_store
        name = args.session or board.session
        with open_store(args.db) as store:
            data = store.load_session(name, mote=board.mote)
    exp = export(board, args.to)
    held = [s for s, _ in board.sensors() if s in exp.apply]
    if not held:
        raise UserError(f"{args.to} holds none of the sensors of {args.cal} "
                        f"({', '.join(s for s, _ in board.sensors())})")
    cost = costs(board, exp, data)
    if args.out:
        write_atomic(Path(args.out), exp.text)
        info = sys.stdout
        print(f"wrote {args.out} ({args.to})", file=info)
    else:
        sys.stdout.write(exp.text)
        info = sys.stderr
    for line in cost_lines(exp, cost):
        print(line, file=info)
    return 0


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "export-cal", help="write a calibration in another tool's form",
        description="Write cal.json as Razor AHRS constants (razor-c), razor_imu_9dof YAML "
                    "(razor-yaml), an ArduPilot parameter file (ardupilot), imucal's JSON "
                    "(imucal) or the IRIS fixed-point set as a C header (c-header); say what "
                    "the target cannot hold and what it costs.")
    p.add_argument("cal", metavar="CAL_JSON", help="a calibration written by motecal calibrate")
    p.add_argument("--to", required=True, choices=_formats(), help="target format")
    p.add_argument("--out", metavar="FILE", help="output file (default: standard output)")
    p.add_argument("--db", metavar="FILE",
                   help="session database: measure the cost on the session's own rows")
    p.add_argument("--session", metavar="NAME",
                   help="session to measure on (default: the one named in the calibration)")
    p.set_defaults(func=run)
