"""What the subcommands' parsers share: argument types and help text.

The types raise ``argparse.ArgumentTypeError``, which the parser turns into
one line on stderr (exit 2), as for every user error.

* ``positive(kind, most=None)``: a number > 0 (finite for floats), at most ``most``;
* ``int_range(what, lo, hi)``: a whole number in lo..hi (hi None: no bound);
* ``mote_id``: a sensing mote's id, 1..65534 (0 is the BaseStation, 65535 the
  broadcast address);
* ``seed``: a random seed, a whole number >= 0;
* ``between(lo, hi)``: a number strictly between lo and hi;
* ``session_name``: a session name the store accepts (not empty or blank);
* ``baud_rate``: a serial baud rate, 300..4000000 (``baud_problem``);
* ``description(doc)``: a module docstring's first paragraph as plain text
  for ``--help`` (reStructuredText markup removed).
"""
from __future__ import annotations

import argparse
import math
import re

from ..line.protocol import MOTE_ID_MAX, MOTE_ID_MIN
from ..line.sources import baud_problem


def positive(kind=float, most=None):
    """Argument type: a number of ``kind`` (int or float) > 0, finite, and at
    most ``most`` when given (checked before anything uses the value)."""
    def parse(text):
        try:
            v = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a number: {text[:40]!r}") from None
        if not v > 0 or (isinstance(v, float) and not math.isfinite(v)):
            raise argparse.ArgumentTypeError(f"must be > 0: {text[:40]!r}")
        if most is not None and v > most:
            raise argparse.ArgumentTypeError(f"must be at most {most:g}: {text[:40]!r}")
        return v
    return parse


def int_range(what: str, lo: int, hi: int | None = None, note: str = ""):
    """Argument type: a whole number (a ``what``) in ``lo..hi``; ``note`` is
    added to the complaint about the range."""
    def parse(text):
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a {what}: {text!r}") from None
        if v < lo or (hi is not None and v > hi):
            limits = f"{lo}..{hi}" if hi is not None else f">= {lo}"
            raise argparse.ArgumentTypeError(f"{what} must be {limits}{note}: {text!r}")
        return v
    return parse


mote_id = int_range("mote id", MOTE_ID_MIN, MOTE_ID_MAX,
                    " (0 is the BaseStation, 65535 broadcast)")

# a random seed: numpy's SeedSequence takes whole numbers >= 0
seed = int_range("seed", 0)


def between(lo: float, hi: float):
    """Argument type: a number strictly between ``lo`` and ``hi``."""
    def parse(text):
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
        if not lo < v < hi:
            raise argparse.ArgumentTypeError(f"must be between {lo:g} and {hi:g}: {text!r}")
        return v
    return parse


def baud_rate(text):
    """Argument type: a baud rate (``baud_problem``)."""
    try:
        value = int(text)
    except ValueError:
        value = text
    problem = baud_problem(value)
    if problem:
        raise argparse.ArgumentTypeError(problem)
    return value


def session_name(text):
    """Argument type: a session name as the store accepts it
    (``store.check_session_name``), checked before anything is opened."""
    from ..errors import UserError
    from ..sessions.store import check_session_name
    try:
        return check_session_name(text)
    except UserError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


_ROLES = re.compile(r":[a-z]+:`([^`]*)`")          # :func:`x` -> x
_LITERAL = re.compile(r"``([^`]*)``|`([^`]*)`")       # ``x`` / `x` -> x
_EMPHASIS = re.compile(r"\*\*([^*]+)\*\*|\*([^*\s][^*]*)\*")


def plain(text: str) -> str:
    """reStructuredText inline markup removed (roles, literals, emphasis)."""
    text = _ROLES.sub(r"\1", text)
    text = _LITERAL.sub(lambda m: m.group(1) if m.group(1) is not None else m.group(2), text)
    return _EMPHASIS.sub(lambda m: m.group(1) or m.group(2), text)


def description(doc: str | None) -> str:
    """A module docstring's first paragraph as one plain-text line for
    ``--help`` (argparse wraps it)."""
    first = (doc or "").strip().split("\n\n")[0]
    return plain(" ".join(first.split()))
