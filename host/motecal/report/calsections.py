"""The report's sections on what the calibration did, put together: each
mote's parts (``choices``, ``temperature``, ``poses``, ``diagnosis``: one
``parts.Part`` each) give rows for one table per kind over every mote, which
goes into the first section of its kind, and lines for the page's head."""
from __future__ import annotations

from pathlib import Path

from . import choices, diagnosis, temperature
from .tables import Table, write as write_table

PART_TABLES = {"choices": ("What the calibration chose", choices.COLUMNS, choices.NOTES),
               "temperature": ("Temperature terms", temperature.COLUMNS, temperature.NOTES),
               "diagnosis": ("Findings of the diagnosis", diagnosis.COLUMNS, diagnosis.NOTES)}


def part_tables(parts: list, out: Path) -> None:
    """Write each part table (all motes' rows) and put it in the first
    section of its kind."""
    for name, (title, cols, notes) in PART_TABLES.items():
        rows = [r for p in parts for r in p.rows.get(name, [])]
        home = next((p.section for p in parts if name in p.rows and p.section is not None),
                    None)
        if not rows or home is None:
            continue
        # a column no row fills (a term no calibration of these has) is left out
        cols = [c for c in cols if any(r.get(c.key) not in (None, "") for r in rows)]
        t = Table(name, title, cols, rows, notes)
        write_table(t, out)
        home.tables.append(t)


def meta_rows(parts: list) -> list:
    """The parts' lines for the page's head, one row per key (the same text
    for every mote once)."""
    keyed: dict = {}
    for p in parts:
        for k, v in p.meta:
            keyed.setdefault(k, [])
            if v not in keyed[k]:
                keyed[k].append(v)
    return [(k, "; ".join(v)) for k, v in keyed.items()]
