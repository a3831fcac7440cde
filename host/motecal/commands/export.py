"""``motecal export``: a stored session to the project CSV."""
from __future__ import annotations

import errno
import os
import secrets

from ..errors import UserError
from ..sessions import importer
from ..sessions.store import open_store
from .args import mote_id

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


def register(sub) -> None:
    p = sub.add_parser("export", help="write a session as the project CSV",
                       description="Write a stored session as CSV: mote,seq,t,label,ax,ay,az,"
                                   "gx,gy,gz,mx,my,mz (empty cells where a sensor is missing).")
    p.add_argument("--db", required=True,
                   help="database: sqlite file, postgresql:// or mysql:// URL")
    p.add_argument("--session", required=True)
    p.add_argument("--csv", required=True, metavar="OUT", help="CSV file to write")
    p.add_argument("--mote", type=mote_id, help="only this mote")
    p.set_defaults(func=export)
