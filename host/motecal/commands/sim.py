"""``motecal sim``: the simulated motes + BaseStation on a serial line."""
from __future__ import annotations

import argparse
import json
import sys
import time

from ..errors import UserError
from ..line import protocol as P
from ..outputs import check_output, open_output, write_text
from ..sim.world import MAX_DURATION_S
from .args import baud_rate, positive


def _host_port(text: str):
    host, sep, port = text.rpartition(":")
    if not sep:
        host, port = "127.0.0.1", text
    host = host.strip("[]") or "127.0.0.1"
    try:
        p = int(port)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected HOST:PORT, not {text!r}") from None
    if not 0 <= p <= 65535:
        raise argparse.ArgumentTypeError(f"port {p} outside 0..65535")
    return host, p


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "sim", help="simulate motes, radio, BaseStation and the serial line",
        description="Simulate N IRIS motes with 9DOF boards on one rig, their radio "
                    "(802.15.4, CSMA, collisions, loss), the BaseStation and its serial "
                    "line, and put the exact serial byte stream in a file, on a TCP port "
                    "(pyserial socket://HOST:PORT) or on a pseudo-terminal.")
    out = p.add_argument_group("output (one of)")
    out.add_argument("--out", metavar="FILE",
                     help="write the serial byte stream to FILE ('-' = stdout)")
    out.add_argument("--serve", metavar="HOST:PORT", type=_host_port,
                     help="serve the line over TCP; prints the pyserial URL on stdout")
    out.add_argument("--pty", action="store_true",
                     help="create a pseudo-terminal; prints its path on stdout")
    p.add_argument("--motes", type=int, default=3, help="number of motes, ids 1..N (3)")
    p.add_argument("--session", default="static80", metavar="KIND",
                   help="static80 | rotation | idle | free, or several in a row separated "
                        "by commas, e.g. static80,static80 (static80)")
    p.add_argument("--seed", type=int, default=1, help="random seed (1)")
    p.add_argument("--duration", type=positive(float, MAX_DURATION_S), default=None, metavar="S",
                   help="simulated seconds (default: the session's natural length)")
    p.add_argument("--baud", type=baud_rate, default=250000,
                   help="serial baud rate, 10 bits per byte (250000; iris stock 57600)")
    p.add_argument("--loss", type=float, default=0.0, metavar="P",
                   help="independent loss probability per radio frame, 0..1 (0)")
    p.add_argument("--batch", type=int, default=P.NINEDOF_BATCH,
                   help=f"records per sample message, 1..6 ({P.NINEDOF_BATCH}, "
                        "NINEDOF_BATCH)")
    p.add_argument("--model", metavar="FILE|NAME", default=None,
                   help="error model JSON file or built-in name (general)")
    p.add_argument("--truth", metavar="FILE", help="write the model's truth as JSON")
    p.add_argument("--eeprom", metavar="FILE",
                   help="keep the motes' EEPROM (uploaded calibrations) in FILE: restored "
                        "at boot, written when a mote stores a set")
    p.add_argument("--realtime", action="store_true",
                   help="pace the bytes at the line rate in wall time")
    p.add_argument("--speed", type=positive(float, 1e6), default=None, metavar="X",
                   help="pace at X times real time (implies pacing)")
    p.add_argument("--no-temp", dest="temperature", action="store_false",
                   help="motes running an image built before the temperature message "
                        "(they send none)")
    p.add_argument("--quiet", action="store_true", help="no summary on stderr")
    p.set_defaults(func=run)


def _summary(world, wall: float) -> str:
    st = world.stats
    lines = [f"motecal sim: {st['now']:.1f} s simulated in {wall:.2f} s wall, "
             f"{st['line']['bytes_out']} serial bytes at {world.baud} baud"]
    for m, d in st["motes"].items():
        lost = d["generated"] - d["delivered"]
        lines.append(f"  mote {m}: {d['generated']} samples, {d['delivered']} delivered, "
                     f"{lost} lost (queue {d['dropped']}, radio {d['radio_lost']}, "
                     f"BaseStation {d['bs_dropped']}); {d['frames']} frames, "
                     f"{d['retries']} retries, {d['collided']} collided"
                     + (f"; {d['temp_sent']} temperature messages" if d["temp_sent"] else ""))
    bs = st["basestation"]
    lines.append(f"  BaseStation: {bs['radio_rx']} packets forwarded, {bs['radio_drops']} "
                 f"dropped (queue full), {bs['serial_rx']} from the PC, "
                 f"{bs['serial_acks']} serial acks")
    if st["line"]["unread_bytes"]:
        lines.append(f"  line: {st['line']['unread_bytes']} bytes produced while nobody read")
    return "\n".join(lines)


def run(args) -> int:
    from ..sim.serve import PtyLine, TcpLine, write_file
    from ..sim.world import World

    n_out = sum(x is not None and x is not False for x in (args.out, args.serve, args.pty or None))
    if n_out != 1:
        raise UserError("choose one output: --out FILE, --serve HOST:PORT or --pty")
    inputs = [args.model, args.eeprom]
    if args.out is not None:
        check_output(args.out, inputs=inputs, what="--out")
    if args.truth:
        check_output(args.truth, inputs=inputs + [args.out], what="--truth")
    speed = args.speed if args.speed is not None else (1.0 if args.realtime else None)
    world = World(motes=args.motes, session=args.session, seed=args.seed, baud=args.baud,
                  loss=args.loss, model=args.model, batch=args.batch,
                  duration=args.duration, eeprom=args.eeprom, temperature=args.temperature)
    if args.truth:
        write_text(args.truth, json.dumps(world.truth(), indent=1) + "\n",
                   inputs=inputs + [args.out], what="--truth")
    t0 = time.monotonic()
    if args.out is not None:
        # '-' is stdout; a file is complete or not there (outputs.open_output)
        with open_output(args.out, inputs=inputs + [args.truth], binary=True,
                         what="--out") as fh:
            write_file(world, fh, speed)
        if not args.quiet:
            print(_summary(world, time.monotonic() - t0), file=sys.stderr)
        return 0

    if args.serve is not None:
        line = TcpLine(world, args.serve[0], args.serve[1], speed)
        print(line.url, flush=True)
        what = f"serving {line.url}"
    else:
        line = PtyLine(world, speed)
        print(line.path, flush=True)
        what = f"pseudo-terminal {line.path}"
    if not args.quiet:
        print(f"motecal sim: {what}; {args.motes} motes, {args.session}, "
              f"{world.duration:.1f} s, {'as fast as read' if speed is None else f'{speed:g}x real time'}"
              "; Ctrl-C to stop", file=sys.stderr, flush=True)
    announced = False
    try:
        while True:
            line.step()
            if world.done and not announced and not args.quiet:
                announced = True
                print(_summary(world, time.monotonic() - t0), file=sys.stderr, flush=True)
    except KeyboardInterrupt:
        pass
    finally:
        line.close()
    if not announced and not args.quiet:
        print(_summary(world, time.monotonic() - t0), file=sys.stderr)
    return 0
