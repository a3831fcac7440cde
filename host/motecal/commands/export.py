"""``motecal export`` (a session to the project CSV) and ``motecal sessions``
(what a database holds)."""
from __future__ import annotations

import errno
import json
import os
import secrets
import sys

from . import importer
from .cliargs import mote_id
from .errors import UserError
from .store import open_store

CSV_HEADER = importer.CSV_HEADER


def _new_file(folder: str) -> str:
    """Create an empty temporary file in ``folder`` with the mode a plain
    ``open`` would give it (0666 less the umask; ``mkstemp`` makes 0600, and
    the exported CSV kept it)."""
    for _ in range(100):
        tmp = os.path.join(folder, f".export-{secrets.token_hex(6)}.csv")
        try:
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
            return tmp
        except FileExistsError:
            continue
    raise FileExistsError(errno.EEXIST, "no free temporary name", folder)


def export_csv(data, path: str) -> int:
    """Write a SessionData as the project CSV (``importer.write_csv``, the one
    writer of that format) atomically: into a temporary file in the same
    folder, renamed over ``path`` only when complete.  Returns the rows written.
    """
    path = os.path.abspath(path)
    folder = os.path.dirname(path)
    if not os.path.isdir(folder):
        raise UserError(f"cannot write {path}: folder {folder} does not exist")
    if os.path.isdir(path):
        raise UserError(f"cannot write {path}: it is a directory")
    try:
        tmp = _new_file(folder)
    except OSError as e:
        raise UserError(f"cannot write {path}: {e.strerror}") from None
    try:
        importer.write_csv(data, tmp)
        os.replace(tmp, path)
    except BaseException as e:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if isinstance(e, OSError):
            raise UserError(f"cannot write {path}: {e.strerror or e}") from None
        raise
    return len(data)


def export(args) -> int:
    with open_store(args.db) as store:
        data = store.load_session(args.session, args.mote)
    n = export_csv(data, args.csv)
    print(f"wrote {n} samples of session {args.session} "
          f"(motes {', '.join(map(str, data.motes)) or 'none'}) to {args.csv}")
    return 0


def list_sessions(args) -> int:
    with open_store(args.db) as store:
        rows = store.sessions()
        if args.json:
            for r in rows:
                r["link"] = store.link_stats(r["name"])
            json.dump(rows, sys.stdout, indent=1)
            print()
            return 0
    if not rows:
        print(f"{args.db}: no sessions")
        return 0
    head = ("name", "kind", "motes", "samples", "poses", "started", "ended", "source")
    table = [head] + [(r["name"], r["kind"], ",".join(map(str, r["motes"])), str(r["samples"]),
                       str(r["poses"]), r["started"] or "", r["ended"] or "(open)",
                       r["source"] or "") for r in rows]
    widths = [max(len(row[i]) for row in table) for i in range(len(head))]
    for row in table:
        print("  ".join(c.ljust(w) for c, w in zip(row, widths)).rstrip())
    return 0


def register(sub) -> None:
    p = sub.add_parser("export", help="write a session as the project CSV",
                       description="Write a stored session as CSV: mote,seq,t,label,ax,ay,az,"
                                   "gx,gy,gz,mx,my,mz (empty cells where a sensor is missing).")
    p.add_argument("--db", required=True, help="database: sqlite file or postgresql:// URL")
    p.add_argument("--session", required=True)
    p.add_argument("--csv", required=True, metavar="OUT", help="CSV file to write")
    p.add_argument("--mote", type=mote_id, help="only this mote")
    p.set_defaults(func=export)

    p = sub.add_parser("sessions", help="list the sessions in a database")
    p.add_argument("--db", required=True, help="database: sqlite file or postgresql:// URL")
    p.add_argument("--json", action="store_true", help="JSON with link statistics")
    p.set_defaults(func=list_sessions)
