"""``motecal import``: measured data files read (``sessions.importer``, and
other tools' formats by ``sessions.foreign``, docs/interop.md) and saved as
one session; nothing is written when a file is bad.  Files of different
formats go into one session, each read by its own reader; ``--append`` adds
files to a stored session (``sessions.combine``)."""
from __future__ import annotations

import argparse

import numpy as np

from ..errors import UserError
from ..sessions import ranges
from ..sessions.combine import append
from ..sessions.foreign import FORMATS as FOREIGN, read_session
from ..sessions.importer import FORMATS, KINDS, summary
from ..sessions.store import open_store


def run(args) -> int:
    if args.append and args.replace:
        raise UserError("--append adds to a session, --replace replaces it: give one")
    data = read_session(args.files, fmt=args.format, chip=args.chip or None, kind=args.kind,
                        units=args.units or None, scale=args.scale or None,
                        gravity=args.gravity, rate_hz=args.rate_hz,
                        rate_dps=args.rate_dps or None, rpm=args.rpm or None,
                        columns=args.columns, angle_deg=args.angle_deg)
    data.name = args.session
    # --append continues a session: the database and the session must be there already
    with open_store(args.db, create=not args.append) as store:
        if args.append:
            if not store.session_exists(args.session):
                raise UserError(f"session {args.session!r} does not exist in {args.db}: "
                                "--append continues a session (see motecal sessions; leave "
                                "--append out to start one)")
            old = store.load_session(args.session)
            added = len(data)
            data = append(old, data)
            store.append_session(data, data.select(np.arange(len(old), len(data))))
            print(f"Appended {added} rows to session '{args.session}' ({len(old)} before).")
        else:
            store.save_session(data, replace=args.replace)
        where = store.target                 # as shown: never a password
    print(summary(data))
    for line in (data.meta.get("rounding") or {}).values():
        print(f"  {line}")
    print(f"Saved to {where} as session '{args.session}'.")
    return 0


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "import", help="import measured data files into a session",
        description="Read measured data (the motecal CSV, Razor AHRS text or float logs, "
                    "timestamped CSV pairs; imucal's Ferraris sessions, FreeIMU-cal float "
                    "logs and turntable runs, MotionCal Raw: logs) and save it as one "
                    "session; nothing is written when a file is bad.",
        epilog=ranges.help_text(), formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("files", nargs="+", metavar="FILE",
                   help="data files (or one timestamped run directory)")
    p.add_argument("--db", required=True, metavar="FILE", help="session database (created if missing)")
    p.add_argument("--session", required=True, metavar="NAME", help="session name to write")
    p.add_argument("--format", default="auto", choices=("auto",) + FORMATS + FOREIGN,
                   help="input format (default: detected from the content)")
    p.add_argument("--chip", action="append", default=[], metavar="SENSOR=CHIP",
                   help="override a chip and its scale, e.g. mag=hmc5843, gyro=itg3205, "
                        "accel=mpu6050 or mag=name:LSB_PER_UNIT (repeatable)")
    p.add_argument("--kind", default="auto", choices=KINDS,
                   help="static (still segments are poses), rotation (all rows 'rot'), "
                        "idle, or auto (decided from stillness; default)")
    p.add_argument("--replace", action="store_true", help="replace an existing session")
    p.add_argument("--append", action="store_true",
                   help="add the files to an existing session (same board: its motes, chips "
                        "and scales; no rows twice)")
    g = p.add_argument_group("float inputs and other tools' formats (docs/interop.md)")
    g.add_argument("--units", action="append", default=[], metavar="si|counts|SENSOR=UNIT",
                   help="units of float values: si (m/s^2, rad/s, uT), counts, or per sensor, "
                        "e.g. gyro=deg/s (repeatable)")
    g.add_argument("--scale", action="append", default=[], metavar="SENSOR=LSB",
                   help="LSB per g, deg/s or gauss to turn floats into counts (default: the "
                        "chip's, else the file's own step); repeatable. Range: "
                        + "; ".join(f"{s} {r.text()}" for s, r in ranges.SCALE.items()))
    g.add_argument("--gravity", type=float, metavar="M/S2",
                   help="m/s^2 per g for m/s^2 inputs (default 9.80665; imucal's example: 9.81). "
                        f"Range: {ranges.GRAVITY.text()}")
    g.add_argument("--rate-hz", type=float, metavar="HZ",
                   help="sample rate of files without times (imucal formats need it). "
                        f"Range: {ranges.RATE_HZ.text()}")
    g.add_argument("--rate-dps", action="append", default=[], metavar="DPS",
                   help="turntable speed(s), deg/s: steady turns at it become rotations. "
                        f"Range: {ranges.TURN_DPS.text()}")
    g.add_argument("--rpm", action="append", default=[], metavar="RPM",
                   help="turntable speed(s) in rpm, e.g. 33.333,45. Range: "
                        f"{ranges.TURN_DPS.lo / 6:.3g}..{ranges.TURN_DPS.hi / 6:.4g} rpm")
    g.add_argument("--columns", metavar="SENSORS",
                   help="sensors of a float log's columns, e.g. gyro or accel,gyro "
                        "(default: from the file name)")
    g.add_argument("--angle-deg", type=float, metavar="DEG",
                   help="size of the imucal session's turns (default 360). "
                        f"Range: +-{ranges.ANGLE_DEG.text()}")
    p.set_defaults(func=run)
