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

from . import __version__
from .errors import UserError

# subcommand modules, in the order of the data path
COMMAND_MODULES = (
    "motecal.sim.cli",
    "motecal.logger",
    "motecal.store_cli",
    "motecal.importer",
    "motecal.calib.cli",
    "motecal.upload",
    "motecal.diagnose.cli",
    "motecal.report",
)


class _Parser(argparse.ArgumentParser):
    def error(self, message):          # one line, exit 2, as for every user error
        raise UserError(f"{self.prog}: {message}")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="motecal", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=f"motecal {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name in COMMAND_MODULES:
        try:
            mod = importlib.import_module(name)
        except ModuleNotFoundError as e:
            if e.name and name.startswith(e.name):   # subcommand not built yet
                continue
            raise
        mod.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    try:
        parser = build_parser()
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
    except BrokenPipeError:
        return 141


if __name__ == "__main__":
    sys.exit(main())
