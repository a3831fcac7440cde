"""The browser view of a session (``motecal log --view``, ``motecal report``).

* ``state``: the one JSON document the page draws -- live from a running
  logger (``LiveView``, a logger display that snapshots the guide's numbers)
  or from a stored session (``session_state``);
* ``server``: the small HTTP server (page, script, ``/state.json``,
  ``/events`` as Server-Sent Events; 404 for anything else);
* ``assets/``: the page, its script (plain canvas 2D, no library, no build
  step), the charts of the report's calibration part (``charts.js``) and
  style, served by motecal itself;
* ``static_page(doc)``: the same page as one self-contained HTML file with
  the data embedded (the report's ``view.html``).
"""
from __future__ import annotations

from .server import asset
from .state import dumps


def static_page(doc: dict) -> str:
    """One HTML file: the page with its style, script and ``doc`` inlined."""
    page = asset("index.html").decode()
    data = dumps(doc).decode().replace("</", "<\\/")
    css = asset("view.css").decode()
    js = asset("view.js").decode().replace("</script", "<\\/script")
    charts = asset("charts.js").decode().replace("</script", "<\\/script")
    page = page.replace('<link rel="stylesheet" href="view.css">', f"<style>\n{css}</style>")
    page = page.replace("<!--STATE-->", f"<script>window.MOTECAL_STATE = {data};</script>")
    page = page.replace('<script src="view.js"></script>', f"<script>\n{js}</script>")
    page = page.replace('<script src="charts.js"></script>', f"<script>\n{charts}</script>")
    return page
