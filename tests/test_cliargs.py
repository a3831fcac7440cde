"""The subcommands' shared argument types and plain-text help (motecal.commands.args)."""
import argparse
import re

import pytest

from motecal.commands import main as cli
from motecal.commands.args import between, description, int_range, mote_id, plain, positive, seed


def test_positive_numbers():
    assert positive(float)("2.5") == 2.5 and positive(int)("7") == 7
    for kind, text, msg in [(float, "-3", "must be > 0"), (float, "0", "must be > 0"),
                            (float, "inf", "must be > 0"), (float, "nan", "must be > 0"),
                            (float, "soon", "not a number"), (int, "2.5", "not a number"),
                            (int, "0", "must be > 0")]:
        with pytest.raises(argparse.ArgumentTypeError, match=msg):
            positive(kind)(text)


def test_mote_ids_and_ranges():
    assert mote_id("1") == 1 and mote_id("65534") == 65534
    for text, msg in [("0", "mote id must be 1..65534 \\(0 is the BaseStation"),
                      ("65535", "1..65534"), ("x", "not a mote id")]:
        with pytest.raises(argparse.ArgumentTypeError, match=msg):
            mote_id(text)
    count = int_range("whole number", 0)
    assert count("0") == 0 and count("12") == 12
    with pytest.raises(argparse.ArgumentTypeError, match="must be >= 0"):
        count("-1")
    with pytest.raises(argparse.ArgumentTypeError, match="version must be 1..9: '10'"):
        int_range("version", 1, 9)("10")


def test_seeds_and_open_intervals():
    assert seed("0") == 0 and seed(str(2 ** 70)) == 2 ** 70
    for text, msg in [("-3", "seed must be >= 0"), ("1.5", "not a seed")]:
        with pytest.raises(argparse.ArgumentTypeError, match=msg):
            seed(text)
    assert between(0, 1)("0.05") == 0.05
    for text in ("0", "1", "nan", "inf", "-0.1", "x"):
        with pytest.raises(argparse.ArgumentTypeError):
            between(0, 1)(text)


def test_rst_markup_becomes_plain_text():
    assert plain("``motecal calibrate``: see :func:`gate.decide` and `x`, *not* **this**") \
        == "motecal calibrate: see gate.decide and x, not this"
    assert description('"""``a``: one\n    two.\n\nmore"""'.strip('"')) == "a: one two."
    assert plain("5 * 3 * 2") == "5 * 3 * 2"


def test_every_subcommand_help_is_plain_text(capsys):
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    assert set(sub.choices) == set(cli.COMMANDS)
    for name, p in [("motecal", parser)] + sorted(sub.choices.items()):
        text = p.format_help()
        assert not re.search(r"``|`[^`]+`|:[a-z]+:`|\*\*", text), (name, text)
