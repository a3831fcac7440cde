"""The report's tables: a column layout, rows of plain values, and two
renderings of the same rows -- CSV (every number at full precision, so it can
be compared with the calibration results) and Markdown (rounded for reading).

A cell is a number (float or int), a string, or None (empty: not applicable).
"""
from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass, field
from pathlib import Path


@dataclass(frozen=True)
class Column:
    key: str                  # CSV header and row key
    header: str               # Markdown header
    fmt: str = ""             # format spec for numbers in Markdown ("" = str())


@dataclass
class Table:
    name: str                 # file stem: <name>.csv, <name>.md
    title: str
    columns: list[Column]
    rows: list[dict] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)     # shown under the Markdown table

    def column(self, key: str) -> list:
        return [r.get(key) for r in self.rows]


def _csv_cell(v) -> str:
    if v is None:
        return ""
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return "nan" if math.isnan(v) else repr(v)
    return str(v)


def _md_cell(v, fmt: str) -> str:
    if v is None:
        return ""
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        if math.isnan(v):
            return "n/a"
        return format(v, fmt) if fmt else repr(v)
    if isinstance(v, int):
        return format(v, "d")
    return str(v).replace("|", "\\|")


def to_csv(table: Table) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow([c.key for c in table.columns])
    for r in table.rows:
        w.writerow([_csv_cell(r.get(c.key)) for c in table.columns])
    return buf.getvalue()


def to_markdown(table: Table, heading_level: int = 3) -> str:
    out = [f"{'#' * heading_level} {table.title}", ""]
    out.append("| " + " | ".join(c.header.replace("|", "\\|") for c in table.columns) + " |")
    out.append("| " + " | ".join("---" if not c.fmt else "---:" for c in table.columns) + " |")
    for r in table.rows:
        out.append("| " + " | ".join(_md_cell(r.get(c.key), c.fmt) for c in table.columns)
                   + " |")
    if table.notes:
        out.append("")
        out += [f"* {n}" for n in table.notes]
    return "\n".join(out) + "\n"


def to_html(table: Table) -> str:
    """The Markdown rendering's cells as an HTML table (no markup of our own
    inside cells besides escaping)."""
    from html import escape
    h = ['<table>', '<thead><tr>'
         + "".join(f'<th>{escape(c.header)}</th>' for c in table.columns) + '</tr></thead>',
         '<tbody>']
    for r in table.rows:
        cells = []
        for c in table.columns:
            v = r.get(c.key)
            cls = ' class="num"' if isinstance(v, (int, float)) and not isinstance(v, bool) else ""
            cells.append(f"<td{cls}>{escape(_md_cell(v, c.fmt).replace(chr(92) + '|', '|'))}</td>")
        h.append("<tr>" + "".join(cells) + "</tr>")
    h.append("</tbody></table>")
    if table.notes:
        h.append("<ul class=\"notes\">" + "".join(f"<li>{escape(n)}</li>" for n in table.notes)
                 + "</ul>")
    return "\n".join(h)


def write(table: Table, out_dir) -> tuple[Path, Path]:
    """Write <name>.csv and <name>.md into out_dir; returns both paths."""
    out_dir = Path(out_dir)
    p_csv = out_dir / f"{table.name}.csv"
    p_md = out_dir / f"{table.name}.md"
    p_csv.write_text(to_csv(table))
    p_md.write_text(to_markdown(table))
    return p_csv, p_md


def read_csv(path) -> list[dict]:
    """Rows of a table CSV as dicts of strings (for checks and tests)."""
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def read_markdown(path) -> list[dict]:
    """Rows of the first pipe table of a Markdown file, keyed by header."""
    lines = [ln for ln in Path(path).read_text().splitlines() if ln.startswith("|")]
    if len(lines) < 2:
        return []

    def cells(ln):
        parts, cur, esc = [], "", False
        for ch in ln.strip()[1:-1]:
            if esc:
                cur += ch
                esc = False
            elif ch == "\\":
                esc = True
            elif ch == "|":
                parts.append(cur.strip())
                cur = ""
            else:
                cur += ch
        parts.append(cur.strip())
        return parts
    head = cells(lines[0])
    return [dict(zip(head, cells(ln))) for ln in lines[2:]]
