"""What one of the report's calibration sections gives for a mote
(``temperature``, ``choices``, ``poses``, ``diagnosis``): its section of
index.html, its tables' rows, the charts view.html draws, and lines for the
page's head."""
from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class Part:
    section: object = None                          # html.Section, or None: nothing to show
    rows: dict = field(default_factory=dict)        # table name -> [row]
    view: list = field(default_factory=list)        # [(heading, [chart])] for view.html
    meta: list = field(default_factory=list)        # [(key, value)] for the page's head
