"""``motecal report``: the seed paper's tables and figures for one session
(``motecal.report``)."""
from __future__ import annotations

from pathlib import Path

from ..errors import UserError
from ..outputs import check_output_dir
from ..report import write_report
from ..sessions.store import open_store
from ..upload.calfile import load_cal
from .args import mote_id, seed


def run(args) -> int:
    check_output_dir(args.out, inputs=[args.db, args.cal], what="--out")
    if args.cal is not None:
        load_cal(args.cal)       # a regular file, a calibration, finite numbers: one line if not
    if args.diagnosis_report is not None and not Path(args.diagnosis_report).is_dir():
        raise UserError(f"--diagnosis-report {args.diagnosis_report}: not a folder (a motecal "
                        f"diagnose --report DIR)")
    store = open_store(args.db, readonly=True)
    try:
        def log(msg):
            if not args.quiet:
                print(msg, flush=True)
        index = write_report(store, args.session, args.out, mote=args.mote, cal=args.cal,
                             seed=args.seed, log=log, diagnosis_report=args.diagnosis_report)
    finally:
        store.close()
    print(f"report written: {index}")
    return 0


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "report", help="the paper's tables and figures for a session (HTML, PNG, CSV, Markdown)",
        description="Write the seed paper's Tables I-III (Markdown and CSV), figures (PNG) "
                    "and an index.html for one session of the database.")
    p.add_argument("--db", required=True, metavar="FILE", help="session database")
    p.add_argument("--session", required=True, metavar="NAME", help="session to report on")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="output directory (new, empty, or an earlier report to replace)")
    p.add_argument("--mote", type=mote_id, default=None, metavar="ID",
                   help="only this mote (default: every mote of the session)")
    p.add_argument("--cal", default=None, metavar="cal.json",
                   help="calibration to show (default: the latest stored for the session, "
                        "else calibrate now with the full model)")
    p.add_argument("--seed", type=seed, default=0,
                   help="seed of the GA runs made for the tables (default 0)")
    p.add_argument("--diagnosis-report", default=None, metavar="DIR",
                   help="a motecal diagnose --report DIR folder: its evidence pictures go into "
                        "the report's diagnosis section")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
    p.set_defaults(func=run)
