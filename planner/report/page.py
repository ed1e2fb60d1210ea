"""The page base of compplan's three reports (the plan's, :mod:`planner.report`; the placement
study's, :mod:`planner.report.placement`; the identification's, :mod:`planner.identify_report`):
the HTML skeleton, its style sheet and a figure embedded with its caption and file links.

Light: no plotting imports.  A page is a list of lines joined by :func:`page_text`, opened by
:func:`page_head` and closed by :data:`PAGE_END`.
"""

from __future__ import annotations

import base64
import html

__all__ = [
    "PAGE_END",
    "embedded_figure",
    "page_head",
    "page_text",
]

#: The reports' style sheet (a page may add its own rules after it).
PAGE_CSS = """
body{font-family:system-ui,Segoe UI,Helvetica,Arial,sans-serif;max-width:1250px;margin:2em auto;
     padding:0 1em;color:#222}
h1{font-size:1.5em;margin-bottom:0.3em} h2{border-bottom:1px solid #ccc;padding-bottom:0.2em;margin-top:1.6em}
table.summary{border-collapse:collapse;margin:0.5em 0 1em}
table.summary td,table.summary th{border:1px solid #bbb;padding:3px 8px;text-align:left;vertical-align:top}
table.summary th{background:#eee} td.num{font-family:monospace;text-align:right}
table.headline{font-size:1.08em} table.headline td:first-child{font-weight:600}
table.headline td.num{font-size:1.1em} table.headline td:nth-child(2){white-space:nowrap}
td.mono{font-family:monospace;font-size:88%;text-align:left;word-break:break-all}
td.hash{font-size:80%}
img{max-width:100%;border:1px solid #ddd} .note{color:#555;font-size:90%;max-width:1100px}
.absent{background:#fff4e0;border-left:4px solid #e0a030;padding:0.5em 1em}
figure{margin:1em 0 2em} figcaption{color:#333;font-size:92%;margin-top:0.3em;max-width:1100px}
nav.toc{font-size:90%;color:#444} nav.toc a{margin-right:0.9em}
"""
#: The last line of a page.
PAGE_END = "</body></html>"


def page_head(title: str, css: str = "", head: str = "", heading: bool = True) -> list[str]:
    """The opening lines of a page: doctype, ``<head>`` with the title, :data:`PAGE_CSS` and the
    page's own ``css`` after it, ``head`` (e.g. a script), then ``<body>`` and the title as ``<h1>``
    (``heading``)."""
    t = html.escape(title)
    out = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>{t}</title><style>{PAGE_CSS}{css}</style>{head}</head><body>",
    ]
    return out + ([f"<h1>{t}</h1>"] if heading else [])


def page_text(lines: list[str]) -> str:
    """The page's text: its lines, each ended by a newline."""
    return "\n".join(lines) + "\n"


def embedded_figure(name: str, title: str, caption: str, png: bytes, png_href: str, pdf_href: str) -> str:
    """A figure embedded as a base64 PNG (the page opens offline on its own) with its caption and
    links to its PNG and PDF files."""
    b64 = base64.b64encode(png).decode("ascii")
    return (
        f'<figure><img data-figure="{html.escape(name)}" alt="{html.escape(title)}" '
        f'src="data:image/png;base64,{b64}">'
        f"<figcaption>{html.escape(caption)} Files: "
        f'<a href="{png_href}">PNG</a>, '
        f'<a href="{pdf_href}">PDF</a>.</figcaption></figure>'
    )
