"""``index.html``: the report's tables and figures on one page.

Self-contained apart from the files beside it: figures are ``<img>`` with
relative links to the PNGs, tables are inlined (with relative links to their
CSV and Markdown files), the style sheet is inline; no scripts, no fonts, no
external resources, so it opens from disk in any browser.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from html import escape

from . import tables as _tables

GENERATOR = "motecal report"

CSS = """
body { font-family: sans-serif; max-width: 1200px; margin: 1em auto; padding: 0 1em;
       color: #222; line-height: 1.4; }
h1 { font-size: 1.6em; } h2 { border-bottom: 1px solid #ccc; margin-top: 2em; }
table { border-collapse: collapse; margin: 0.5em 0; font-size: 0.85em; }
th, td { border: 1px solid #bbb; padding: 2px 4px; } th { font-size: 0.92em; }
th { background: #eee; } td.num { text-align: right; font-variant-numeric: tabular-nums; }
figure { margin: 1em 0; } figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: 0.9em; color: #444; }
ul.notes { font-size: 0.85em; color: #444; }
.meta td:first-child { font-weight: bold; }
nav a { margin-right: 1em; }
"""


@dataclass
class FigureRef:
    file: str                # relative path of the PNG
    title: str
    caption: str = ""


@dataclass
class Section:
    anchor: str
    title: str
    intro: str = ""
    tables: list = field(default_factory=list)       # [Table]
    figures: list = field(default_factory=list)      # [FigureRef]
    notes: list = field(default_factory=list)        # [str]
    links: list = field(default_factory=list)        # [(relative href, text)]


def render(title: str, meta: list[tuple[str, str]], sections: list[Section],
           notes: list[str] = ()) -> str:
    out = ["<!DOCTYPE html>", '<html lang="en">', "<head>", '<meta charset="utf-8">',
           f'<meta name="generator" content="{GENERATOR}">',
           f"<title>{escape(title)}</title>", f"<style>{CSS}</style>", "</head>", "<body>",
           f"<h1>{escape(title)}</h1>"]
    if meta:
        out.append('<table class="meta">')
        out += [f"<tr><td>{escape(k)}</td><td>{escape(str(v))}</td></tr>" for k, v in meta]
        out.append("</table>")
    if notes:
        out.append('<ul class="notes">' + "".join(f"<li>{escape(n)}</li>" for n in notes)
                   + "</ul>")
    out.append("<nav>" + "".join(f'<a href="#{escape(s.anchor)}">{escape(s.title)}</a>'
                                 for s in sections) + "</nav>")
    for s in sections:
        out.append(f'<section id="{escape(s.anchor)}">')
        out.append(f'<h2>{escape(s.title)}</h2>')
        if s.intro:
            out.append(f"<p>{escape(s.intro)}</p>")
        for href, text in s.links:
            out.append(f'<p><a href="{escape(href)}">{escape(text)}</a></p>')
        for t in s.tables:
            out.append(f'<h3 id="{escape(t.name)}">{escape(t.title)}</h3>')
            out.append(f'<p>Files: <a href="{escape(t.name)}.csv">{escape(t.name)}.csv</a>, '
                       f'<a href="{escape(t.name)}.md">{escape(t.name)}.md</a></p>')
            out.append(_tables.to_html(t))
        for f in s.figures:
            out.append("<figure>")
            out.append(f'<a href="{escape(f.file)}"><img src="{escape(f.file)}" '
                       f'alt="{escape(f.title)}"></a>')
            cap = f"<b>{escape(f.title)}</b>"
            if f.caption:
                cap += " " + escape(f.caption)
            out.append(f"<figcaption>{cap}</figcaption>")
            out.append("</figure>")
        if s.notes:
            out.append('<ul class="notes">' + "".join(f"<li>{escape(n)}</li>" for n in s.notes)
                       + "</ul>")
        out.append("</section>")
    out += ["</body>", "</html>"]
    return "\n".join(out) + "\n"
