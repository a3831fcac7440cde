"""The ``motecal`` command line.

Each subcommand lives in its own module (named after what it does) that
provides ``register(subparsers)``; the parser it adds sets ``func`` to a
function taking the parsed arguments and returning an exit status.  This
module only dispatches and turns user errors into one line on stderr.
"""
from __future__ import annotations

import argparse
import importlib
import sys

from .. import __doc__ as motecal_doc, __version__
from ..errors import UserError
from .args import description

# Subcommands in the order of the data path: name -> (module in this package,
# one-line help).
# Only the module of the command being run is imported, so a command starts
# without loading every other command's dependencies (scipy, matplotlib, ...).
COMMANDS = {
    "sim": ("sim", "simulate motes, radio, BaseStation and serial line"),
    "log": ("log", "log samples from a port into a database, guiding a person"),
    "sessions": ("sessions", "list the sessions in a database"),
    "export": ("export", "write a session as the project CSV"),
    "import": ("import_", "import measured data files as a session"),
    "calibrate": ("calibrate", "calibrate accelerometer, gyroscope and magnetometer"),
    "export-cal": ("export_cal", "write a calibration in another tool's form"),
    "upload": ("upload", "send a calibration to a mote, or read/reset it"),
    "diagnose": ("diagnose", "what the simulation gets wrong, its cause and the gain"),
    "report": ("report", "the paper's tables and figures as an HTML report"),
}
COMMAND_MODULES = tuple(dict.fromkeys(m for m, _ in COMMANDS.values()))


class _Parser(argparse.ArgumentParser):
    def error(self, message):          # one line, exit 2, as for every user error
        raise UserError(f"{self.prog}: {message}")


def _command_word(argv: list[str]) -> str | None:
    for a in argv:
        if not a.startswith("-"):
            return a
    return None


def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    """The parser; with ``argv``, only the named command's module is loaded."""
    parser = _Parser(prog="motecal", description=description(motecal_doc))
    parser.add_argument("--version", action="version", version=f"motecal {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    word = _command_word(argv) if argv is not None else None
    wanted = [COMMANDS[word][0]] if word in COMMANDS else \
        (list(COMMAND_MODULES) if argv is None else [])
    for name in wanted:
        importlib.import_module(f".{name}", __package__).register(sub)
    for cmd, (_, text) in COMMANDS.items():     # the others, for --help
        if cmd not in sub.choices:
            sub.add_parser(cmd, help=text)
    return parser


def main(argv: list[str] | None = None) -> int:
    try:
        argv = sys.argv[1:] if argv is None else list(argv)
        parser = build_parser(argv)
        args = parser.parse_args(argv)
        if not getattr(args, "func", None):
            parser.print_help(sys.stderr)
            return 2
        return int(args.func(args) or 0)
    except UserError as e:
        print(f"motecal: error: {e}" if not str(e).startswith("motecal") else f"{e}",
              file=sys.stderr)
        return e.exit_code
    except KeyboardInterrupt:
        print("motecal: interrupted", file=sys.stderr)
        return 130
    except MemoryError:
        # the system failed under a correct command (exit 1); what it was writing is one
        # transaction or an atomic file, so nothing is half-written
        print("motecal: error: out of memory: the data needs more memory than the system "
              "gives this process (import a long recording in parts)", file=sys.stderr)
        return 1
    except BrokenPipeError:
        return 141


if __name__ == "__main__":
    sys.exit(main())
