"""bench/results.py: a figure measured on the matching model and on the
mismatch suite is one row of RESULTS.md, judged on the worse of the two; a
world-dependent figure without its mismatch twin says so."""
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "bench"))
import results as R  # noqa: E402


def _row(name, measured, met, world, note=""):
    return dict(name=name, goal="g", measured=measured, met=met, note=note,
                bench="bench/bench_x.py", world=world)


def _cells(line):
    return [c.strip() for c in line.strip("|").split("|")]


def test_pair_is_judged_on_the_worse():
    rows = R.table([_row("f", "1 mg", True, "matching", "a"), _row("other", "3", True, None),
                    _row("f", "4 mg", False, "mismatch", "b")])
    body = [_cells(x) for x in rows[2:]]
    assert [b[0] for b in body] == ["f", "other"]            # one row per figure, first place
    f = dict(zip(R.HEADER, body[0]))
    assert (f["measured"], f["on the mismatch suite"], f["met"]) == ("1 mg", "4 mg", "**not met**")
    assert f["note"] == "matching: a; mismatch suite: b"
    assert dict(zip(R.HEADER, body[1]))["on the mismatch suite"] == R.NO_WORLD


def test_matching_only_says_so():
    f = dict(zip(R.HEADER, _cells(R.table([_row("f", "1", True, "matching")])[2])))
    assert f["on the mismatch suite"] == R.MATCHING_ONLY
    assert f["met"] == "met (matching model only)"


def test_unknown_world_is_refused():
    with pytest.raises(ValueError):
        R.record("f", "g", 1, world="real")


def test_merge_keeps_older_rows_and_adds_the_column(tmp_path):
    old = tmp_path / "R.md"
    old.write_text("# Bench results\n\n- command: `make bench`\n\n"
                   "| figure | goal (issue) | measured | met | bench | note |\n"
                   "| --- | --- | --- | --- | --- | --- |\n"
                   "| kept | g | 2 x | met | `bench/bench_y.py` | n |\n"
                   "| gone | g | 9 | met | `bench/bench_x.py` |  |\n")
    R.merge([_row("f", "1", True, "matching"), _row("f", "2", True, "mismatch")], old)
    lines = [x for x in old.read_text().splitlines() if x.startswith("| ")]
    assert _cells(lines[0]) == list(R.HEADER)
    body = {c[0]: dict(zip(R.HEADER, c)) for c in map(_cells, lines[2:])}
    assert set(body) == {"kept", "f"}
    assert body["kept"]["on the mismatch suite"] == R.NO_WORLD and body["kept"]["note"] == "n"
    assert (body["f"]["on the mismatch suite"], body["f"]["met"]) == ("2", "met")
