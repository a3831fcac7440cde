"""``motecal export``: a stored session to the project CSV."""
from __future__ import annotations

import sys

from ..outputs import check_output, is_stdout, open_output
from ..sessions import importer
from ..sessions.store import open_store
from .args import mote_id

CSV_HEADER = importer.CSV_HEADER


def export_csv(data, path: str, *, inputs=()) -> int:
    """Write a SessionData as the project CSV (``importer.write_csv``, the one
    writer of that format) through ``outputs.open_output``: ``-`` is stdout; a
    file is written under a temporary name and renamed over ``path`` only when
    complete; an input (``inputs``: the database), a device, FIFO or folder is
    refused.  Returns the rows written."""
    with open_output(path, inputs=inputs, newline="", what="--csv") as f:
        importer.write_csv(data, f)
    return len(data)


def export(args) -> int:
    check_output(args.csv, inputs=[args.db], what="--csv")     # before reading anything
    with open_store(args.db, readonly=True) as store:
        data = store.load_session(args.session, args.mote)
    n = export_csv(data, args.csv, inputs=[args.db])
    print(f"wrote {n} samples of session {args.session} "
          f"(motes {', '.join(map(str, data.motes)) or 'none'}) to "
          f"{'standard output' if is_stdout(args.csv) else args.csv}",
          file=sys.stderr if is_stdout(args.csv) else sys.stdout)
    return 0


def register(sub) -> None:
    p = sub.add_parser("export", help="write a session as the project CSV",
                       description="Write a stored session as CSV: mote,seq,t,label,ax,ay,az,"
                                   "gx,gy,gz,mx,my,mz (empty cells where a sensor is missing).")
    p.add_argument("--db", required=True,
                   help="database: sqlite file, postgresql:// or mysql:// URL")
    p.add_argument("--session", required=True)
    p.add_argument("--csv", required=True, metavar="OUT",
                   help="CSV file to write ('-' = standard output)")
    p.add_argument("--mote", type=mote_id, help="only this mote")
    p.set_defaults(func=export)
