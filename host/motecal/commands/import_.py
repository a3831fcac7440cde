"""``motecal import``: measured data files read (``sessions.importer``) and
saved as one session; nothing is written when a file is bad."""
from __future__ import annotations

from ..sessions.importer import FORMATS, KINDS, read_any, summary
from ..sessions.store import open_store


def run(args) -> int:
    data = read_any(args.files, fmt=args.format, chip=args.chip or None, kind=args.kind)
    data.name = args.session
    with open_store(args.db, create=True) as store:
        store.save_session(data, replace=args.replace)
    print(summary(data))
    print(f"Saved to {args.db} as session '{args.session}'.")
    return 0


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "import", help="import measured data files into a session",
        description="Read measured data (the motecal CSV, Razor AHRS text or float logs, "
                    "timestamped CSV pairs) and save it as one session; nothing is written "
                    "when a file is bad.")
    p.add_argument("files", nargs="+", metavar="FILE",
                   help="data files (or one timestamped run directory)")
    p.add_argument("--db", required=True, metavar="FILE", help="session database (created if missing)")
    p.add_argument("--session", required=True, metavar="NAME", help="session name to write")
    p.add_argument("--format", default="auto", choices=("auto",) + FORMATS,
                   help="input format (default: detected from the content)")
    p.add_argument("--chip", action="append", default=[], metavar="SENSOR=CHIP",
                   help="override a chip and its scale, e.g. mag=hmc5843, gyro=itg3205, "
                        "accel=mpu6050 or mag=name:LSB_PER_UNIT (repeatable)")
    p.add_argument("--kind", default="auto", choices=KINDS,
                   help="static (still segments are poses), rotation (all rows 'rot'), "
                        "idle, or auto (decided from stillness; default)")
    p.add_argument("--replace", action="store_true", help="replace an existing session")
    p.set_defaults(func=run)
