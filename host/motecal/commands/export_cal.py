"""``motecal export-cal``: a calibration (``cal.json``) in another tool's form
(docs/interop.md; the targets: ``motecal.targets.TARGETS``).  Prints the axes
written and what the target cannot hold and what that costs: on the
session's own rows with ``--db`` (the session named in cal.json, or
``--session``), else over evenly spread directions.  The output file is
written whole or not at all (a temporary file renamed into place)."""
from __future__ import annotations

import sys
from pathlib import Path

from ..errors import UserError
from ..inputs import MAX_JSON_BYTES, read_input_text
from ..outputs import check_output, is_stdout, write_text

OPTION_FLAGS = {"axes": "--axes", "orientation": "--orientation"}


def write_atomic(path: Path, text: str, inputs=()) -> None:
    """The output file, whole or not at all, never over an input
    (``outputs.write_text``)."""
    write_text(path, text, inputs=inputs, what="--out")


def options(args, board, data):
    """The writer's options from the command line; an option the target does
    not take is refused (one line)."""
    from ..targets import TARGETS, ardupilot
    from ..targets.common import ExportOptions
    takes = TARGETS[args.to].options
    for name, flag in OPTION_FLAGS.items():
        if getattr(args, name) is not None and name not in takes:
            raise UserError(f"{flag} goes with --to {takers(name).replace(', ', ' or ')}, "
                            f"not {args.to}")
    # the session's own record first (targets.export falls back on cal.json's)
    frame = data.meta.get("axis_frame") if data is not None and data.meta else None
    orientation = 0 if args.orientation is None else ardupilot.parse_rotation(args.orientation)
    return ExportOptions(axes=args.axes, axis_frame=frame, orientation=orientation)


def run(args) -> int:
    from ..calib.result import BoardCalibration
    from ..targets import export
    from ..targets.common import cost_lines, costs
    inputs = [args.cal, args.db]
    if args.out:
        check_output(args.out, inputs=inputs, what="--out")
    # a regular UTF-8 file of sane size, checked as upload checks it
    # (calib.result.check_document): types, shapes, finite numbers, an
    # invertible A, the mote id, the scales
    board = BoardCalibration.loads(read_input_text(args.cal, max_bytes=MAX_JSON_BYTES),
                                   str(args.cal))
    data = None
    if args.db:
        from ..sessions.store import open_store
        name = args.session or board.session
        with open_store(args.db, readonly=True) as store:
            data = store.load_session(name, mote=board.mote)
    exp = export(board, args.to, options(args, board, data))
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


def takers(option: str) -> str:
    """The targets that take an option (the registry's ``Target.options``)."""
    from ..targets import TARGETS
    return ", ".join(t.name for t in TARGETS.values() if option in t.options)


def register(subparsers) -> None:
    from ..targets import FORMATS, described
    p = subparsers.add_parser(
        "export-cal", help="write a calibration in another tool's form",
        description=f"Write cal.json in another tool's form ({described()}); say which axes "
                    "were written, what the target cannot hold and what it costs.")
    p.add_argument("cal", metavar="CAL_JSON", help="a calibration written by motecal calibrate")
    p.add_argument("--to", required=True, choices=FORMATS, help="target format")
    p.add_argument("--out", metavar="FILE",
                   help="output file ('-' or none: standard output)")
    p.add_argument("--db", metavar="FILE",
                   help="session database: measure the cost on the session's own rows")
    p.add_argument("--session", metavar="NAME",
                   help="session to measure on (default: the one named in the calibration)")
    p.add_argument("--axes", choices=("chip", "razor"),
                   help=f"{takers('axes')}: the calibration's axes, the chips' (remapped "
                        "into the Razor firmware's board frame) or the firmware's (default: "
                        "the session's, as recorded)")
    p.add_argument("--orientation", metavar="ROTATION",
                   help=f"{takers('orientation')}: AHRS_ORIENTATION, ArduPilot's Rotation "
                        "number or name (e.g. 2 or YAW_90; default 0, none); the compass is "
                        "written in the frame after it")
    p.set_defaults(func=run)
