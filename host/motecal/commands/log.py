"""``motecal log``: record what the BaseStation forwards into the database,
optionally guiding a person through 80 static poses or a rotation sweep.

The loop is ``capture.logger.Logger`` (data path, reconnects, clean stop:
see there); this module parses the options, opens the port and the store,
installs the signal handlers and picks the screen (``log_screen``).
"""
from __future__ import annotations

import argparse
import contextlib
import signal
import sys

from ..calib import design
from ..capture.guide import (ADAPTIVE_MAX_POSES, DEFAULT_COVERAGE, DEFAULT_MIN_ANGLE,
                             DEFAULT_POSE_SAMPLES, DEFAULT_POSES, DEFAULT_ROT_SAMPLES,
                             MAX_MIN_ANGLE, SEED_POSES, GuidedFlow, max_poses)
from ..capture.link import LinkTracker
from ..capture.logger import Logger, TeeDisplay
from ..errors import UserError
from ..line import protocol as P
from ..line import sources as S
from ..sessions.session import NOMINAL_SCALES
from ..sessions.store import LOCK_TIMEOUT_S, open_store
from ..view.server import open_server, parse_address
from ..view.state import LiveView
from .args import baud_rate, mote_id, positive, session_name
from .log_screen import KeyReader, PlainDisplay, RichDisplay, no_echo


def _board(text):
    mote, sep, board = text.partition("=")
    if not sep or not board:
        raise argparse.ArgumentTypeError(f"want MOTE=BOARD, not {text!r}")
    return mote_id(mote), board


def register(sub) -> None:
    p = sub.add_parser(
        "log", help="record a session from the BaseStation into the database",
        description="Record what the BaseStation forwards (serial port, pyserial URL, "
                    "serial@DEV:BAUD, sf@HOST:PORT, or a recorded file) into a database "
                    "session, optionally guiding through 80 static poses or a rotation.")
    p.add_argument("--port", help="device, pyserial URL (socket://, rfc2217://, loop://), "
                                  "serial@DEV:BAUD, sf@HOST:PORT or a recorded file; "
                                  "default: $MOTECOM")
    p.add_argument("--baud", type=baud_rate, help="baud rate (default 250000)")
    p.add_argument("--db", required=True,
                   help="database: sqlite file, postgresql:// or mysql:// URL")
    p.add_argument("--session", required=True, type=session_name, help="session name")
    p.add_argument("--append", action="store_true", help="add to an existing session")
    p.add_argument("--guided", choices=("static80", "adaptive", "rotation"),
                   help="guide a person (adaptive: the poses that most reduce the predicted "
                        "error, until it meets the targets)")
    p.add_argument("--kind", choices=("free", "idle", "static80", "rotation"),
                   help="session kind when not guided (default free)")
    p.add_argument("--mote", type=mote_id, help="mote the guided flow follows (default all)")
    p.add_argument("--duration", type=positive(float, 1e8), help="stop after SECONDS")
    p.add_argument("--yes", action="store_true",
                   help="non-interactive: advance whenever a new still pose appears")
    p.add_argument("--notes", help="free text stored with the session")
    p.add_argument("--view", type=parse_address, metavar="[HOST:]PORT",
                   help="serve a live view of the session in the browser at http://HOST:PORT/ "
                        "(HOST default 127.0.0.1; port 0 = any free port)")
    p.add_argument("--board", type=_board, action="append", default=[], metavar="MOTE=BOARD",
                   help="which sensor board sits on which mote (repeatable)")
    g = p.add_argument_group("guided flow")
    g.add_argument("--poses", type=positive(int, 10_000), default=DEFAULT_POSES)
    g.add_argument("--pose-samples", type=positive(int, 1_000_000),
                   default=DEFAULT_POSE_SAMPLES)
    g.add_argument("--min-angle", type=positive(float), default=DEFAULT_MIN_ANGLE,
                   help="degrees a new pose must be from every earlier one")
    a = p.add_argument_group("adaptive flow")
    a.add_argument("--target-mg", type=positive(float, 1000), default=design.TARGET_ACCEL_G * 1e3,
                   help="accelerometer: promised rms error on fresh directions, mg (0.5)")
    a.add_argument("--target-mag-pct", type=positive(float, 100),
                   default=design.TARGET_MAG_REL * 100,
                   help="magnetometer: promised rms shape error, %% of the field (0.3)")
    a.add_argument("--target-gyro-dps", type=positive(float, 100),
                   default=design.TARGET_GYRO_DPS,
                   help="gyroscope: promised bias error, deg/s (0.05)")
    a.add_argument("--max-poses", type=positive(int, 10_000), default=ADAPTIVE_MAX_POSES,
                   help=f"stop here even if the targets are not met ({ADAPTIVE_MAX_POSES})")
    g.add_argument("--rot-samples", type=positive(int, 100_000_000),
                   default=DEFAULT_ROT_SAMPLES)
    g.add_argument("--coverage", type=positive(float), default=DEFAULT_COVERAGE,
                   help="rotation stops at this fraction of sphere cells hit")
    p.add_argument("--lock-timeout", type=positive(float, 86400), default=LOCK_TIMEOUT_S,
                   metavar="S", help="while another process holds the database's write lock, "
                   f"buffer samples and retry for up to S seconds ({LOCK_TIMEOUT_S:g})")
    p.add_argument("--commit-every", type=positive(float, 60), default=0.25,
                   help=argparse.SUPPRESS)
    p.set_defaults(func=run)


def _guide(args, interactive: bool) -> GuidedFlow | None:
    if not args.guided:
        return None
    if args.guided == "adaptive":
        if not args.min_angle <= MAX_MIN_ANGLE:
            raise UserError(f"--min-angle must be within 0..{MAX_MIN_ANGLE:g} degrees, "
                            f"not {args.min_angle:g}")
        if args.max_poses < SEED_POSES:
            raise UserError(f"--max-poses must be at least {SEED_POSES} (the seed poses)")
        if args.max_poses > max_poses(args.min_angle):
            raise UserError(f"--max-poses {args.max_poses} cannot be {args.min_angle:g} degrees "
                            f"apart from each other: the sphere has room for at most "
                            f"{max_poses(args.min_angle)} (lower --min-angle or --max-poses)")
        targets = design.Targets(args.target_mg / 1e3, args.target_mag_pct / 100,
                                 args.target_gyro_dps)
        planner = design.Planner(NOMINAL_SCALES, targets, min_angle_deg=args.min_angle)
        opts = dict(planner=planner, max_poses=args.max_poses, min_angle_deg=args.min_angle,
                    rate_hz=P.NINEDOF_RATE_HZ)
    elif args.guided == "static80":
        if args.pose_samples < 50:
            raise UserError("--pose-samples must be at least 50 (the stillness window)")
        if not args.min_angle <= MAX_MIN_ANGLE:
            raise UserError(f"--min-angle must be within 0..{MAX_MIN_ANGLE:g} degrees, "
                            f"not {args.min_angle:g}")
        if args.poses > max_poses(args.min_angle):
            raise UserError(f"--poses {args.poses} cannot be {args.min_angle:g} degrees apart "
                            f"from each other: the sphere has room for at most "
                            f"{max_poses(args.min_angle)} (lower --min-angle or --poses)")
        opts = dict(poses=args.poses, samples=args.pose_samples, min_angle_deg=args.min_angle,
                    rate_hz=P.NINEDOF_RATE_HZ)
    else:
        if args.coverage > 1:
            raise UserError("--coverage is a fraction, 0 < c <= 1")
        opts = dict(samples=args.rot_samples, coverage=args.coverage)
    return GuidedFlow(args.guided, follow=args.mote, auto=not interactive, options=opts)


def run(args) -> int:
    spec = S.parse_port(args.port, args.baud)
    interactive = bool(args.guided) and not args.yes and sys.stdin.isatty()
    guide = _guide(args, interactive)
    with contextlib.ExitStack() as stack:
        view = None
        if args.view is not None:
            # the view's address first: taken, nothing is started (exit 2)
            view = LiveView()
            server = open_server(args.view, view)
            stack.callback(server.close)
            print(f"view: {server.url}", flush=True)
        # the port first: if it cannot be opened, no database file is made
        source = S.open_source(spec)
        stack.callback(source.close)
        # --append continues a session: the database must be there already
        store = stack.enter_context(open_store(args.db, create=not args.append))
        meta = {"source": str(spec), "rate_hz": P.NINEDOF_RATE_HZ, "notes": args.notes,
                "baud": spec.baud}
        if args.board:
            meta["boards"] = {str(m): b for m, b in args.board}
        link = line = last = None
        if args.append and store.session_exists(args.session):
            stats = store.link_stats(args.session)
            link, line = stats["motes"], stats["line"]
            last = store.last_seqs(args.session)
        writer = store.open_session(args.session, kind=args.guided or args.kind or "free",
                                    meta=meta, append=args.append,
                                    commit_every=args.commit_every,
                                    lock_timeout=args.lock_timeout)
        # a commit attempt waits briefly for a held lock, then the loop reads
        # on with the samples queued (SessionWriter.commit) and tries again
        store.set_busy_timeout(0.05)
        tracker = LinkTracker(link, line, last)
        display = RichDisplay() if sys.stdout.isatty() else PlainDisplay()
        if view is not None:
            display = TeeDisplay(display, view)
        logger = Logger(spec, writer, tracker, guide=guide, display=display,
                        duration=args.duration, source=source)
        old = {}

        def on_signal(signum, frame):
            logger.request_stop("interrupted" if signum == signal.SIGINT else "terminated")

        for sig in (signal.SIGINT, signal.SIGTERM):
            old[sig] = signal.signal(sig, on_signal)
        try:
            with no_echo(interactive):
                if interactive:
                    KeyReader(logger).start()
                logger.run()
        finally:
            for sig, h in old.items():
                signal.signal(sig, h)
    return 0
