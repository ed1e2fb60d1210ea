"""``report.html``: :func:`report_html`, self-contained and styled like the plan report (the
Markdown's sections converted by a tiny Markdown subset, figures embedded as base64 PNGs and linked
to their files ``figures/<name>.png|pdf``)."""

from __future__ import annotations

import html
import re
from collections.abc import Mapping
from typing import Any

from planner.identify_report.canvas import RenderedFigure
from planner.identify_report.captions import figure_entries, figure_text
from planner.identify_report.diagnostics import not_significant_line
from planner.identify_report.markdown import headline_rows, provenance_rows, campaigns_text, report_markdown


def _html_table(
    header: list[str], rows: list[tuple[str, ...]], css: str = "summary", mono_cols: tuple[int, ...] = ()
) -> str:
    out = [f'<table class="{css}"><tr>' + "".join(f"<th>{html.escape(h)}</th>" for h in header) + "</tr>"]
    mono = ' class="mono"'
    for r in rows:
        out.append(
            "<tr>"
            + "".join(f"<td{mono if i in mono_cols else ''}>{html.escape(c)}</td>" for i, c in enumerate(r))
            + "</tr>"
        )
    out.append("</table>")
    return "\n".join(out)


def report_html(rep: dict[str, Any], figs: Mapping[str, RenderedFigure]) -> str:
    """Self-contained HTML, styled like the plan report: headline table, figures with captions
    (each linked to its PNG and PDF files), then the tables of the selection, parameters and
    diagnostics, and the provenance."""
    from planner.report.page import PAGE_END, embedded_figure, page_head, page_text

    md = report_markdown(rep)
    sections = md.split("\n## ")
    parts = page_head("compplan identification report") + [
        '<h3 id="headline">Headline</h3>',
        _html_table(["quantity", "value", "note"], headline_rows(rep), "summary headline"),
        f'<p class="note">Data: {html.escape(str(rep["data"]["file"]))}. {html.escape(rep["rms_definition"])}. '
        "Lengths in mm.</p>",
    ]
    if rep.get("campaigns"):
        text = html.escape(campaigns_text(rep))
        parts.append(f'<p class="note">Campaigns (the last is the model&#39;s registration): {text}.</p>')
    entries = {e["key"]: e for e in rep.get("figures") or figure_entries(figs)}

    def figure(k: str) -> None:
        e = entries[k]
        title, caption = figure_text(k)
        parts.append(
            f'<h3 id="{html.escape(k)}">Figure {e["number"]}. {html.escape(title)}</h3>'
            + embedded_figure(k, title, caption, figs[k].png, e["png"], e["pdf"])
        )

    maps_sec = next((sec for sec in sections[1:] if sec.startswith("Joint error maps")), None)
    if maps_sec is not None:  # what an engineer looks for when a map was added: near the top
        parts.append('<h2 id="error_maps">Joint error maps</h2>')
        parts.append(md_block(maps_sec.split("\n", 1)[1]))
        if "error_maps" in figs:
            figure("error_maps")
    parts.append("<h2>Figures</h2>")
    for k in entries:
        if k in figs and k != "error_maps":
            figure(k)
    line = not_significant_line(rep["diagnostics"])
    if line:
        parts.append(f'<p class="note">Residual against the diagnostic variables: {html.escape(line)}.</p>')
    for sec in sections[1:]:
        if sec.startswith(("Provenance", "Figures")) or sec is maps_sec:
            continue
        parts.append(md_block("## " + sec))
    parts.append('<h2 id="provenance">Provenance</h2>')
    parts.append(_html_table(["item", "value", "SHA-256"], provenance_rows(rep), mono_cols=(1, 2)))
    parts.append(PAGE_END)
    return page_text(parts)


def _md_cells(line: str) -> list[str]:
    """The cells of a Markdown table row (escaped pipes ``\\|`` are text)."""
    return [c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", line.strip().strip("|"))]


def md_block(text: str) -> str:
    """Tiny Markdown subset -> HTML (headings, bullet lists, pipe tables, paragraphs)."""
    out: list[str] = []
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        ln = lines[i]
        if ln.startswith("#"):
            lvl = len(ln) - len(ln.lstrip("#"))
            out.append(f"<h{lvl}>{html.escape(ln[lvl:].strip())}</h{lvl}>")
        elif ln.startswith("|"):
            rows = []
            while i < len(lines) and lines[i].startswith("|"):
                if not set(lines[i].replace("|", "").strip()) <= set("-"):
                    rows.append([html.escape(c) for c in _md_cells(lines[i])])
                i += 1
            if rows:
                out.append(
                    '<table class="summary"><tr>'
                    + "".join(f"<th>{c}</th>" for c in rows[0])
                    + "</tr>"
                    + "".join("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>" for r in rows[1:])
                    + "</table>"
                )
            continue
        elif ln.startswith("- "):
            items = []
            while i < len(lines) and lines[i].startswith("- "):
                items.append(f"<li>{html.escape(lines[i][2:]).replace('**', '')}</li>")
                i += 1
            out.append("<ul>" + "".join(items) + "</ul>")
            continue
        elif ln.strip():
            out.append(f"<p>{html.escape(ln).replace('**', '')}</p>")
        i += 1
    return "\n".join(out)
