"""The one place measured figures go: each bench calls ``record()`` once per
figure, and ``make bench`` then writes them all to bench/RESULTS.md (with the
machine, date and commit), from which bench/goals_table.py copies the
README's goals table.  So no figure in the docs can disagree with the last run.

    record(name, goal, measured, unit, met)     # in a bench
    python bench/results.py FILE.jsonl bench/RESULTS.md   # make bench, at the end
    python bench/results.py --merge FILE.jsonl bench/RESULTS.md   # one bench run alone

``--merge`` replaces only the rows of the benches that FILE holds, in place,
and keeps every other bench's row of the last RESULTS.md as it was; the
header then names the benches rerun and when.

``met`` is True / False, or None for a figure that is not measured here
(``measured`` None) or that has no goal of its own (context).  Outside
``make bench`` (no $MOTECAL_BENCH_RESULTS) record() only prints its line.

A figure that depends on the world the fit assumes (an accuracy, a rate of
findings, a promise) is measured twice by the same bench: on simulated boards
whose physics has exactly the form the fit assumes (``world="matching"``) and
on the mismatch suite, worlds the fit does not model (``world="mismatch"``),
under the same name.  RESULTS.md shows the two side by side in one row and
judges the goal on the worse of the two; a ``matching`` figure without its
``mismatch`` twin says that it holds on the matching model only.  Figures
the world cannot change (cycles, throughput) leave ``world`` out.
"""
from __future__ import annotations

import datetime
import json
import os
import platform
import re
import subprocess
import sys
from pathlib import Path

ENV = "MOTECAL_BENCH_RESULTS"
REPO = Path(__file__).resolve().parent.parent

# Goals no bench in this repository measures: what checks them instead.
# (The I2C time per sample is recorded by bench_cycles.py as not measured.)
NOT_BENCHED = [
    dict(name="sampling rate locked to the 32 kHz crystal", goal="exactly 125 Hz (#5)",
         where="tests/test_avr.py (test_sampling_clock_follows_the_crystal)",
         note="no bench; the test asserts a long-run rate within 1 ppm of the crystal's "
              "(2 ppm while the RC oscillator drifts 200 ppm/s), on host and simavr"),
    dict(name="C correction against a float64 reference", goal="within 1 LSB (#6)",
         where="tests/test_cal_c.py",
         note="no bench; the test asserts at most 1 LSB against the quantised set over "
              "random sets and the full int16 range"),
]


def fmt(x, digits: int = 3) -> str:
    """A figure as the docs print it: `digits` significant digits, no exponent
    for ordinary sizes, integers without a fraction."""
    if x is None:
        return "not measured here"
    if isinstance(x, str):
        return x
    x = float(x)
    if x != 0 and (abs(x) < 1e-3 or abs(x) >= 1e7):
        return f"{x:.{max(digits - 1, 0)}e}"
    if abs(x) >= 10 ** digits:
        return f"{x:.0f}"
    return f"{x:.{digits}g}"


def verdict(met) -> str:
    return {True: "met", False: "**not met**", None: "-"}.get(met, str(met))


WORLDS = (None, "matching", "mismatch")


def record(name: str, goal: str, measured, unit: str = "", met=None, note: str = "",
           digits: int = 3, bench: str | None = None, world: str | None = None) -> dict:
    """Print one figure next to its goal and, under `make bench`, keep it for
    RESULTS.md.  `measured`: a number (shown with `digits` significant
    digits), a string, or None (not measured here).  `world`: "matching" or
    "mismatch" for a figure measured on both kinds of simulated world (module
    doc), None for one the world cannot change."""
    if world not in WORLDS:
        raise ValueError(f"record: world must be one of {WORLDS}, not {world!r}")
    bench = bench or Path(sys.argv[0]).name
    shown = fmt(measured, digits) + (f" {unit}" if unit and measured is not None else "")
    met = None if measured is None or met is None else bool(met)
    row = dict(name=name, goal=goal, measured=shown, met=met,
               note=note, bench=f"bench/{bench}", world=world)
    print(f"RESULT {name}{f' [{world}]' if world else ''}: {shown}  (goal {goal or '-'}) -> "
          f"{verdict(row['met'])}" + (f"  [{note}]" if note else ""), flush=True)
    path = os.environ.get(ENV)
    if path:
        with open(path, "a") as f:
            f.write(json.dumps(row) + "\n")
    return row


def _git(*args) -> str:
    try:
        return subprocess.run(["git", *args], cwd=REPO, capture_output=True, text=True,
                              check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return ""


def machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    osname = platform.system()
    try:
        for line in Path("/etc/os-release").read_text().splitlines():
            if line.startswith("PRETTY_NAME="):
                osname = line.split("=", 1)[1].strip('"')
    except OSError:
        pass
    return (f"{cpu}, {os.cpu_count()} cores, {osname}, Python {platform.python_version()}")


def cell(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


HEADER = ("figure", "goal (issue)", "measured", "on the mismatch suite", "met", "bench",
          "note")
NO_WORLD = "-"                    # the world cannot change this figure
MATCHING_ONLY = "not measured (matching model only)"


def paired(rows: list[dict]) -> list[dict]:
    """One row per figure: a "matching" row and the "mismatch" row of the
    same name (and bench) become one, judged on the worse of the two; rows
    keep their first place."""
    out, at = [], {}
    for r in rows:
        world = r.get("world")
        key = (r["name"], r["bench"])
        if world in ("matching", "mismatch") and key in at:
            other = out[at[key]]
            m, x = (other, r) if world == "mismatch" else (r, other)
            out[at[key]] = _pair(m, x)
            continue
        if world in ("matching", "mismatch"):
            at[key] = len(out)
            r = _pair(r, None) if world == "matching" else _pair(None, r)
        else:
            r = dict(r, mismatch=r.get("mismatch", NO_WORLD))
        out.append(r)
    return out


def _pair(m: dict | None, x: dict | None) -> dict:
    base = dict(m or x)
    base.pop("met_note", None)
    base["world"] = "paired"
    base["measured"] = m["measured"] if m else "not measured"
    base["mismatch"] = x["measured"] if x else MATCHING_ONLY
    mets = [r["met"] for r in (m, x) if r is not None]
    base["met"] = (None if any(v is None for v in mets) else all(mets))
    if m is None or x is None:
        base["met_note"] = "matching model only" if x is None else "mismatch suite only"
    notes = [r["note"] for r in (m, x) if r is not None and r["note"]]
    if m is not None and x is not None and len(notes) == 2:
        notes = [f"matching: {notes[0]}", f"mismatch suite: {notes[1]}"]
    base["note"] = "; ".join(notes)
    return base


def table(rows: list[dict]) -> list[str]:
    out = ["| " + " | ".join(HEADER) + " |", "|" + " --- |" * len(HEADER)]
    for r in paired(rows):
        met = ("not measured" if r["measured"].startswith("not measured")
               else verdict(r["met"]))
        if r.get("met_note") and r["met"] is not None:
            met += f" ({r['met_note']})"
        out.append("| " + " | ".join(cell(x) for x in (
            r["name"], r["goal"] or "-", r["measured"], r.get("mismatch", NO_WORLD), met,
            f"`{r['bench']}`", r["note"])) + " |")
    return out


def write(rows: list[dict], out: Path) -> None:
    commit = _git("rev-parse", "--short", "HEAD") or "unknown"
    if _git("status", "--porcelain", "--untracked-files=no", "--", "host", "tinyos", "bench",
            "basestation", "tests"):
        commit += " (with uncommitted changes to the code)"
    now = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    rows = rows + [dict(name=n["name"], goal=n["goal"], measured="not measured by a bench",
                        met=None, note=n["note"], bench=n["where"])
                   for n in NOT_BENCHED]
    lines = ["# Bench results", "",
             "<!-- Written by `make bench` (bench/results.py); do not edit by hand. -->", "",
             f"- date: {now}",
             f"- commit: {commit}",
             f"- machine: {machine()}",
             "- command: `make bench` (each bench prints its full tables too; "
             "timings depend on machine load and are never pass/fail)", "",
             *table(rows), ""]
    tmp = out.with_suffix(".tmp")
    tmp.write_text("\n".join(lines))
    tmp.replace(out)


def _cells(line: str) -> list[str]:
    return [c.strip() for c in re.split(r"(?<!\\)\|", line)[1:-1]]


def merge(rows: list[dict], out: Path) -> None:
    """RESULTS.md with the rows of the benches in ``rows`` replaced (at the
    place of their first old row, or at the end) and every other line kept
    (rows written before the mismatch column get "-" there)."""
    if not out.is_file():
        return write(rows, out)
    benches = {r["bench"] for r in rows}
    new = table(rows)[2:]
    lines, placed, head = [], False, None
    for line in out.read_text().splitlines():
        if not line.startswith("| "):
            lines.append(line)
            continue
        cells = _cells(line)
        if head is None:                                 # the header, then the separator
            head = cells
            lines += table([])[:2]
            continue
        if set("".join(cells)) <= set("- "):
            continue
        row = dict(zip(head, cells))
        if row.get("bench", "").strip("`") in benches:
            if not placed:
                lines += new
                placed = True
            continue
        row.setdefault("on the mismatch suite", NO_WORLD)
        lines.append("| " + " | ".join(row.get(h, "") for h in HEADER) + " |")
    if not placed:
        end = max(i for i, x in enumerate(lines) if x.startswith("| ")) + 1
        lines[end:end] = new
    now = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    commit = _git("rev-parse", "--short", "HEAD") or "unknown"
    note = (f"- rerun alone: {', '.join(sorted(benches))} at {now}, commit {commit} "
            f"(its rows only; `bench/results.py --merge`)")
    lines = [x for x in lines if not x.startswith("- rerun alone: ")]
    at = max(i for i, x in enumerate(lines) if x.startswith("- command:")) + 1
    lines.insert(at, note)
    tmp = out.with_suffix(".tmp")
    tmp.write_text("\n".join(lines) + "\n")
    tmp.replace(out)


def read_results(path: Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    merging = argv[:1] == ["--merge"]
    argv = argv[1:] if merging else argv
    if len(argv) != 2:
        print("usage: results.py [--merge] RESULTS.jsonl RESULTS.md", file=sys.stderr)
        return 2
    src, out = Path(argv[0]), Path(argv[1])
    if not src.is_file():
        print(f"results.py: {src}: no results recorded (run make bench)", file=sys.stderr)
        return 2
    rows = read_results(src)
    (merge if merging else write)(rows, out)
    print(f"{'merged into' if merging else 'wrote'} {out} ({len(rows)} figures)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
