"""``motecal sessions``: what a database holds."""
from __future__ import annotations

import json
import sys

from ..sessions.store import open_store


def list_sessions(args) -> int:
    with open_store(args.db, readonly=True) as store:
        rows = store.sessions()
        if args.json:
            for r in rows:
                r["link"] = store.link_stats(r["name"])
                r["writers"] = store.writers(r["name"])
            json.dump(rows, sys.stdout, indent=1)
            print()
            return 0
    if not rows:
        print(f"{store.target}: no sessions")
        return 0
    head = ("name", "kind", "motes", "samples", "poses", "started", "ended", "source")
    table = [head] + [(r["name"], r["kind"], ",".join(map(str, r["motes"])), str(r["samples"]),
                       str(r["poses"]), r["started"] or "", r["ended"] or "(open)",
                       r["source"] or "") for r in rows]
    widths = [max(len(row[i]) for row in table) for i in range(len(head))]
    for row in table:
        print("  ".join(c.ljust(w) for c, w in zip(row, widths)).rstrip())
    return 0


def register(sub) -> None:
    p = sub.add_parser("sessions", help="list the sessions in a database")
    p.add_argument("--db", required=True,
                   help="database: sqlite file, postgresql:// or mysql:// URL")
    p.add_argument("--json", action="store_true", help="JSON with link statistics")
    p.set_defaults(func=list_sessions)
