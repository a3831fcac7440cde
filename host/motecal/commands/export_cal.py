"""``motecal export-cal``: a calibration (``cal.json``) in another tool's form
(docs/interop.md).  Prints what the target cannot hold and what that costs:
on the session's own rows with ``--db`` (the session named in cal.json, or
``--session``), else over evenly spread directions.  The output file is
written whole or not at all (a temporary file renamed into place)."""
from __future__ import annotations

import sys
from pathlib import Path

from ..errors import UserError
from ..inputs import MAX_JSON_BYTES, read_input_text
from ..outputs import check_output, is_stdout, write_text


def _formats():
    from ..targets import FORMATS
    return FORMATS


def write_atomic(path: Path, text: str, inputs=()) -> None:
    """The output file, whole or not at all, never over an input
    (``outputs.write_text``)."""
    write_text(path, text, inputs=inputs, what="--out")


def run(args) -> int:
    from ..calib.result import BoardCalibration
    from ..targets import export
    from ..targets.common import cost_lines, costs
    inputs = [args.cal, args.db]
    if args.out:
        check_output(args.out, inputs=inputs, what="--out")
    # a regular UTF-8 file of sane size: never /dev/zero, a FIFO or a database
    try:
        board = BoardCalibration.loads(read_input_text(args.cal, max_bytes=MAX_JSON_BYTES))
    except UserError as e:
        raise UserError(f"{args.cal}: {e}") from None
    if not board.sensors():
        raise UserError(f"{args.cal}: no calibrated sensor in it")
    data = None
    if args.db:
        from ..sessions.store import open_store
        name = args.session or board.session
        with open_store(args.db, readonly=True) as store:
            data = store.load_session(name, mote=board.mote)
    exp = export(board, args.to)
    held = [s for s, _ in board.sensors() if s in exp.apply]
    if not held:
        raise UserError(f"{args.to} holds none of the sensors of {args.cal} "
                        f"({', '.join(s for s, _ in board.sensors())})")
    cost = costs(board, exp, data)
    if args.out and not is_stdout(args.out):
        write_atomic(Path(args.out), exp.text, inputs)
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
    p.add_argument("--out", metavar="FILE",
                   help="output file ('-' or none: standard output)")
    p.add_argument("--db", metavar="FILE",
                   help="session database: measure the cost on the session's own rows")
    p.add_argument("--session", metavar="NAME",
                   help="session to measure on (default: the one named in the calibration)")
    p.set_defaults(func=run)
