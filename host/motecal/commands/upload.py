"""``motecal upload``: a calibration (cal.json) to a mote, through the
BaseStation and the radio, then verified (the protocol: ``upload.uploader``).

    motecal upload cal.json --port URL [--mote ID] [--version N] [--timeout S] [--retries N]
                            [--store-timeout S]
    motecal upload cal.json --dry-run [--mote ID] [--version N]
    motecal upload --show [cal.json] --port URL --mote ID
    motecal upload --reset --port URL --mote ID [--version N]

Errors are one line on stderr: bad input exits 2, a set that cannot be
represented or that the mote's own checks would refuse exits 3, and an
upload that fails (no answer, rejected, verification failed, not stored in
the mote's EEPROM within --store-timeout) exits 1.  A failure after the mote
acknowledged the commit says that the set was acknowledged in force and is
neither verified nor known to be stored (``CommittedNotFinished``).
"""
from __future__ import annotations

import sys

from ..errors import UserError
from ..line import sources as S
from ..upload.calfile import build_set, cal_from_board, check_set, load_cal
from ..upload.describe import dry_run_lines, show_lines
from ..upload.link import DEFAULT_RETRIES, DEFAULT_TIMEOUT, Link
from ..upload.uploader import (MAX_VERSION, STORE_WAIT, CommittedNotFinished, InForceChanged,
                               NotStored, Options, Result, Uploader, check_cal, choose_version,
                               summary, upload_cal)
from .args import baud_rate, int_range, mote_id, positive
from .upload_screen import PlainProgress, make_progress

def _open(spec: S.PortSpec) -> S.Source:
    if spec.kind == "file":
        raise UserError(f"{spec} is a recorded file: upload needs a live port (device, "
                        "pyserial URL, serial@DEV:BAUD or sf@HOST:PORT)")
    return S.open_source(spec)


# --------------------------------------------------------------------------
# Command line
# --------------------------------------------------------------------------
def register(sub) -> None:
    p = sub.add_parser(
        "upload", help="send a calibration to a mote (fixed point, verified)",
        description="Send a calibration (cal.json from motecal calibrate) through the "
                    "BaseStation to a mote, which then corrects its samples itself; "
                    "verified by reading the set back and by the flags of the next samples.")
    p.add_argument("cal", nargs="?", metavar="cal.json", help="calibration file")
    p.add_argument("--port", help="the BaseStation: device, pyserial URL, serial@DEV:BAUD "
                                  "or sf@HOST:PORT; default $MOTECOM")
    p.add_argument("--baud", type=baud_rate, help="baud rate (default 250000)")
    p.add_argument("--mote", type=mote_id, help="target mote (default: the mote of cal.json)")
    p.add_argument("--version", type=int_range("version", 1, MAX_VERSION),
                   help="version of the new set, 1..65535, above the one in force "
                        "(default: the one in force + 1)")
    mode = p.add_mutually_exclusive_group()
    mode.add_argument("--dry-run", action="store_true",
                      help="print the fixed-point values and their rounding error; no port")
    mode.add_argument("--reset", action="store_true", help="put the mote back to raw output")
    mode.add_argument("--show", action="store_true",
                      help="read back and print the set in force (with cal.json: compare)")
    p.add_argument("--timeout", type=positive(float, 3600), default=DEFAULT_TIMEOUT,
                   help=f"seconds to wait for each reply of the mote ({DEFAULT_TIMEOUT:g})")
    p.add_argument("--retries", type=int_range("whole number", 0, 10_000), default=DEFAULT_RETRIES,
                   help=f"repeats of a message that gets no reply ({DEFAULT_RETRIES})")
    p.add_argument("--store-timeout", dest="store_timeout", type=positive(float, 3600),
                   default=STORE_WAIT,
                   help="seconds to wait until the mote reports the set stored in its "
                        f"EEPROM, so that it survives a reset ({STORE_WAIT:g})")
    p.add_argument("--force", action="store_true",
                   help="upload a calibration the quality gate refused, or under a "
                        "--version not above the one in force")
    p.add_argument("--no-temp", dest="no_temp", action="store_true",
                   help="leave out cal.json's temperature models: the plain 102-byte set, "
                        "for a mote whose firmware has no on-mote temperature correction")
    p.set_defaults(func=run)


def run(args) -> int:
    cal = load_cal(args.cal) if args.cal else None
    if cal is None and not (args.reset or args.show):
        raise UserError("give a calibration file (cal.json), or --reset / --show")
    if cal is not None and args.reset:
        raise UserError("--reset takes no calibration file")
    mote = args.mote if args.mote is not None else (cal.mote if cal else None)
    if mote is None:
        raise UserError("--mote is needed with --reset and --show")
    if cal is not None and cal.mote != mote and not args.show:
        raise UserError(f"{cal.path} calibrates the board of mote {cal.mote}, not mote {mote} "
                        f"(use that mote's cal.json, or --mote {cal.mote})")
    if args.no_temp and cal is None:
        raise UserError("--no-temp goes with a calibration file")
    if args.dry_run:
        for line in dry_run_lines(cal, mote, args.version, not args.no_temp):
            print(line)
        sys.stdout.flush()
        check_set(build_set(cal, mote, args.version or 1, not args.no_temp)[0], mote, cal.path)
        return 0
    opts = Options(timeout=args.timeout, retries=args.retries, version=args.version,
                   force=args.force, temperature=not args.no_temp,
                   store_wait=args.store_timeout)
    if not (args.show or args.reset):
        check_cal(cal, mote, opts)
    spec = S.parse_port(args.port, args.baud)
    with _open(spec) as source:
        if args.show:
            return _show(source, mote, cal, opts)
        if args.reset:
            return _reset(source, mote, opts)
        res = upload_cal(source, cal, mote, opts, progress=make_progress())
    print(summary(res))
    return 0


def _show(source, mote, cal, opts) -> int:
    link = Link(source, timeout=opts.timeout, retries=opts.retries,
                progress=PlainProgress(steps=False))     # only the repeats, then the set
    up = Uploader(link, mote)
    inf = up.read_set()
    for line in show_lines(inf, cal):
        print(line)
    return 0


def _reset(source, mote, opts) -> int:
    progress = make_progress()
    link = Link(source, timeout=opts.timeout, retries=opts.retries, progress=progress)
    up = Uploader(link, mote, progress)
    try:
        t0 = link.clock()
        old = up.in_force()
        version = choose_version(mote, old.version, opts)
        progress.note(f"mote {mote}: version {old.version} in force; reset to raw output, "
                      f"version {version}")
        res = up.reset(version, old.version, opts.verify_wait, opts.store_wait)
        res.seconds = link.clock() - t0
    finally:
        progress.close()
    print(summary(res, "raw output"))
    return 0


# --------------------------------------------------------------------------
# The one-step form: motecal calibrate ... --upload --port URL --mote ID
# --------------------------------------------------------------------------
def add_calibrate_options(parser) -> None:
    """``--upload``, ``--port``, ``--baud`` for ``motecal calibrate``."""
    g = parser.add_argument_group("upload (one step: calibrate, gate, upload, verify)")
    g.add_argument("--upload", action="store_true",
                   help="send each accepted calibration to its mote and verify it")
    g.add_argument("--port", help="with --upload: the BaseStation (device, pyserial URL, "
                                  "serial@DEV:BAUD, sf@HOST:PORT); default $MOTECOM")
    g.add_argument("--baud", type=baud_rate, help="with --upload: baud rate (250000)")


def calibrate_step(args):
    """For ``motecal calibrate``: None without ``--upload``, else a function
    ``step(board, path)`` that uploads a delivered calibration to its mote and
    verifies it.  The port is checked here, before calibrating."""
    if not getattr(args, "upload", False):
        if getattr(args, "port", None) or getattr(args, "baud", None):
            raise UserError("--port and --baud go with --upload")
        return None
    spec = S.parse_port(args.port, args.baud)
    if spec.kind == "file":
        _open(spec)
    opts = Options(force=bool(getattr(args, "force", False)))

    def step(board, path=None) -> Result:
        where = str(path) if path else f"mote {board.mote}"
        try:
            cal = cal_from_board(board, where)
            check_cal(cal, cal.mote, opts)
            print(f"  uploading to mote {board.mote} through {spec}", flush=True)
            with _open(spec) as source:
                res = upload_cal(source, cal, cal.mote, opts, progress=make_progress())
        except NotStored as e:              # in force on the mote, not in its EEPROM
            raise UserError(f"calibration saved ({where}) and in force on mote {board.mote}, "
                            f"but not stored there: {e}", exit_code=e.exit_code) from None
        except (CommittedNotFinished, InForceChanged) as e:   # committed: not "not uploaded"
            raise UserError(f"calibration saved ({where}) and committed to mote {board.mote}, "
                            f"but the upload did not finish: {e}", exit_code=e.exit_code) from None
        except UserError as e:              # same exit status, saying what was done
            raise UserError(f"calibration saved ({where}), not uploaded: {e}",
                            exit_code=e.exit_code) from None
        print("  " + summary(res), flush=True)
        return res

    return step
