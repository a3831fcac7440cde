"""Charts as data: one description of a plot, drawn twice -- by matplotlib
into the report's PNG figures (``draw``, ``save``) and by view.html's script
into a canvas (``to_view``: the same description as JSON, thinned).

A chart is a dict::

    {"title", "xlabel", "ylabel", "ylog": bool, "xlim": [lo, hi] | None,
     "xint": bool (whole-number ticks), "series": [...]}

and each series one of (colours are "#rrggbb", so both renderers agree):

* ``points``  x, y, colour, label, size
* ``line``    x, y, colour, label, dash, width
* ``band``    x, lo, hi, colour, label          (a filled area between lo and hi)
* ``hline``   y, colour, label, dash             (``vline``: x)
* ``vspan``   x0, x1, colour, label              (``hspan``: y0, y1)
* ``barh``    labels, values, colours            (horizontal bars from 0)

NaN in x or y is a gap; ``to_view`` writes it as null.  Nothing here
computes a result: the report's section modules build the charts from the
stored calibration and the session, these functions only draw them.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .figures import DPI

BLUE, ORANGE, GREEN, RED, GREY, BLACK = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728",
                                         "#7f7f7f", "#222222")
PURPLE, BROWN, PALE = "#9467bd", "#8c564b", "#cccccc"
AXIS_COLOURS = (RED, GREEN, BLUE)           # x, y, z
VIEW_POINTS = 600                           # points per series sent to view.html


def chart(title: str, xlabel: str, ylabel: str, series: list, *, ylog: bool = False,
          xlim=None, xint: bool = False) -> dict:
    return {"title": title, "xlabel": xlabel, "ylabel": ylabel, "ylog": bool(ylog),
            "xint": bool(xint),
            "xlim": None if xlim is None else [float(xlim[0]), float(xlim[1])],
            "series": [s for s in series if s is not None]}


def _arr(v):
    return np.asarray(v, float).reshape(-1)


def points(x, y, colour: str, label: str = "", size: float = 3.0) -> dict:
    return {"kind": "points", "x": _arr(x), "y": _arr(y), "colour": colour, "label": label,
            "size": float(size)}


def line(x, y, colour: str, label: str = "", dash: bool = False, width: float = 1.5) -> dict:
    return {"kind": "line", "x": _arr(x), "y": _arr(y), "colour": colour, "label": label,
            "dash": bool(dash), "width": float(width)}


def band(x, lo, hi, colour: str, label: str = "") -> dict:
    return {"kind": "band", "x": _arr(x), "lo": _arr(lo), "hi": _arr(hi), "colour": colour,
            "label": label}


def hline(y: float, colour: str, label: str = "", dash: bool = True) -> dict:
    return {"kind": "hline", "y": float(y), "colour": colour, "label": label, "dash": bool(dash)}


def vline(x: float, colour: str, label: str = "", dash: bool = True) -> dict:
    return {"kind": "vline", "x": float(x), "colour": colour, "label": label, "dash": bool(dash)}


def vspan(x0: float, x1: float, colour: str, label: str = "") -> dict:
    return {"kind": "vspan", "x0": float(x0), "x1": float(x1), "colour": colour, "label": label}


def hspan(y0: float, y1: float, colour: str, label: str = "") -> dict:
    return {"kind": "hspan", "y0": float(y0), "y1": float(y1), "colour": colour, "label": label}


def barh(labels: list, values, colours: list) -> dict:
    return {"kind": "barh", "labels": [str(x) for x in labels], "values": _arr(values),
            "colours": list(colours)}


# ------------------------------------------------------------------ matplotlib

def draw(ax, ch: dict, shown: set | None = None) -> None:
    """Draw one chart on a matplotlib Axes; its legend leaves out the labels
    in ``shown`` (drawn by an earlier panel of the same figure) and adds its
    own to it."""
    shown = set() if shown is None else shown
    for s in ch["series"]:
        k, lab = s["kind"], s.get("label") or None
        if k == "points":
            ax.scatter(s["x"], s["y"], s=s["size"] ** 2 / 2, c=s["colour"], linewidths=0,
                       label=lab, zorder=3)
        elif k == "line":
            ax.plot(s["x"], s["y"], color=s["colour"], lw=s["width"],
                    ls="--" if s["dash"] else "-", label=lab, zorder=4)
        elif k == "band":
            ax.fill_between(s["x"], s["lo"], s["hi"], color=s["colour"], alpha=0.25, lw=0,
                            label=lab, zorder=2)
        elif k == "hline":
            ax.axhline(s["y"], color=s["colour"], lw=1, ls="--" if s["dash"] else "-",
                       label=lab, zorder=2)
        elif k == "vline":
            ax.axvline(s["x"], color=s["colour"], lw=1, ls="--" if s["dash"] else "-",
                       label=lab, zorder=2)
        elif k == "vspan":
            ax.axvspan(s["x0"], s["x1"], color=s["colour"], alpha=0.18, lw=0, label=lab,
                       zorder=1)
        elif k == "hspan":
            ax.axhspan(s["y0"], s["y1"], color=s["colour"], alpha=0.18, lw=0, label=lab,
                       zorder=1)
        elif k == "barh":
            y = np.arange(len(s["labels"]))[::-1]
            ax.barh(y, s["values"], color=s["colours"], zorder=3)
            ax.set_yticks(y)
            ax.set_yticklabels(s["labels"], fontsize=7)
    if ch["ylog"]:
        ax.set_yscale("log")
    if ch["xlim"]:
        ax.set_xlim(*ch["xlim"])
    if ch.get("xint"):
        from matplotlib.ticker import MaxNLocator
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel(ch["xlabel"], fontsize=8)
    ax.set_ylabel(ch["ylabel"], fontsize=8)
    ax.set_title(ch["title"], fontsize=9)
    ax.tick_params(labelsize=7)
    ax.grid(alpha=0.3, which="both")
    handles, labels = ax.get_legend_handles_labels()
    new = [(h, lab) for h, lab in zip(handles, labels) if lab not in shown]
    if new:
        ax.legend(*zip(*new), fontsize=6.5, loc="best", markerscale=2)
        shown.update(lab for _, lab in new)


def save(path, charts: list, title: str | None = None, ncols: int = 3,
         panel=(4.2, 3.2)) -> Path:
    """One PNG of ``charts`` on a grid of ``ncols`` columns, under ``title``
    (none for a single chart: its own title says it)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    n = max(1, len(charts))
    ncols = min(ncols, n)
    nrows = -(-n // ncols)
    wide = any(s["kind"] == "barh" for ch in charts for s in ch["series"])
    H = panel[1] * nrows + (0.4 if title else 0.0)
    W = panel[0] * ncols
    fig = Figure(figsize=(W, H), dpi=DPI)
    FigureCanvasAgg(fig)
    # fixed margins in inches (a layout engine costs seconds per report)
    fig.subplots_adjust(left=(3.3 if wide else 0.75) / W, right=1 - 0.2 / W,
                        bottom=0.55 / H, top=1 - (0.75 if title else 0.35) / H,
                        wspace=0.8 / (panel[0] - 0.8), hspace=0.9 / (panel[1] - 0.9))
    axes = np.atleast_1d(fig.subplots(nrows, ncols, squeeze=False)).reshape(-1)
    shown: set = set()
    for ax, ch in zip(axes, charts):
        draw(ax, ch, shown)
    for ax in axes[n:]:
        ax.set_visible(False)
    if title:
        fig.suptitle(title, fontsize=10)
    path = Path(path)
    fig.savefig(path, format="png", dpi=DPI)
    return path


# ------------------------------------------------------------------ view.html

def _list(a) -> list:
    return [None if not np.isfinite(v) else float(f"{v:.6g}") for v in a]


def to_view(ch: dict, max_points: int = VIEW_POINTS) -> dict:
    """The chart as JSON for view.html: arrays as lists (NaN -> null), each
    point series thinned evenly to ``max_points`` (a line or band to twice
    that)."""
    out = {k: v for k, v in ch.items() if k != "series"}
    ser = []
    for s in ch["series"]:
        d = dict(s)
        keys = [k for k in ("x", "y", "lo", "hi") if k in d and np.ndim(d[k]) == 1]
        if keys:
            n = len(d[keys[0]])
            idx = np.arange(n)
            most = max_points if s["kind"] == "points" else 2 * max_points
            if n > most:
                idx = np.unique(np.linspace(0, n - 1, most).astype(int))
            for k in keys:
                d[k] = _list(np.asarray(d[k])[idx])
        if "values" in d:
            d["values"] = _list(d["values"])
        ser.append(d)
    out["series"] = ser
    return out
