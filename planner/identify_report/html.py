"""``report.html``: :func:`report_html`, self-contained and styled like the plan report (the
Markdown's sections converted by a tiny Markdown subset, figures embedded as base64 PNGs)."""

from __future__ import annotations

import html
import re
from typing import Any

from planner.identify_report.diagnostics import _is_angle, _var_name
from planner.identify_report.markdown import _headline_rows, _provenance_rows, report_markdown
from problems.identify.map_summary import MAP_BAND_SIGMAS

#: Figures of the HTML report, in order: key -> (title, caption).
FIGURE_TEXT = {
    "residuals": (
        "Residual per axis, before and after",
        "Histograms of predicted − measured per axis of the measurement frame (mm; µm where every residual is "
        "below 0.1 mm), inlier rows: top, "
        "the nominal model (registration and measured point fitted); bottom, the identified model.",
    ),
    "history": (
        "Selection history",
        "Per-axis RMS (mm) at each step of the selection: held-out (cross-validated over poses) and "
        "in-sample; the label names the effect added at that step.",
    ),
    "error_maps": (
        "Joint error maps over the angle range of the data",
        "Each panel: the identified error of one joint (one component of its motion) against its "
        "commanded angle (deg), µrad for angles, µm for lengths; shaded, the uncertainty band of "
        f"±{MAP_BAND_SIGMAS:g} standard deviations from the fit's covariance; ticks at the bottom, the "
        "commanded angles of the measured rows; grey, beyond the range: there the map is held at its "
        "end value (dashed), not extrapolated.",
    ),
    "compensation": (
        "Compensation re-measured on the virtual robot",
        "RMS TCP error (mm) of new poses and loads before and after compensation with the identified "
        "model: in the virtual robot's base frame (the TCP) and in the measurement frame (the "
        "measured point against its target mapped by the identified registration). With "
        "unregistered data the base frame is not checkable through the parameters that alias with "
        "the registration: judge the measurement frame.",
    ),
}


def _diag_figure_text(key: str) -> tuple[str, str]:
    """(title, caption) of a diagnostic figure ``diag_<variable>``."""
    v = key[5:]
    if v.endswith(".xyz"):
        j = v[1]
        return (
            f"Residual per axis against joint {j} angle",
            f"The residual after identification (predicted − measured, one panel per axis of the measurement "
            f"frame) against the commanded angle of joint {j} in degrees (dots: rows; line: binned mean); "
            "each panel names the cross-validated share of that axis a smooth function of the angle explains.",
        )
    if _is_angle(v):
        return (
            f"Equivalent error of joint {v[1]} against its angle",
            f"The residual after identification projected on joint {v[1]}'s column of the positional "
            f"Jacobian (the joint-{v[1]} error that would explain it) against the commanded angle in degrees "
            "(dots: rows; line: binned mean).",
        )
    return (
        f"Residual against {_var_name(v)}",
        "The residual after identification against a diagnostic variable (dots: rows; line: binned mean); "
        "one panel per axis of the measurement frame, or the residual projected on the joint.",
    )


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


def report_html(rep: dict[str, Any], figs: dict[str, str]) -> str:
    """Self-contained HTML, styled like the plan report: headline table, figures with captions,
    then the tables of the selection, parameters and diagnostics, and the provenance."""
    from planner.report.rendering import _CSS

    md = report_markdown(rep)
    sections = md.split("\n## ")
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>compplan identification report</title><style>{_CSS}</style></head><body>",
        "<h1>compplan identification report</h1>",
        '<h3 id="headline">Headline</h3>',
        _html_table(["quantity", "value", "note"], _headline_rows(rep), "summary headline"),
        f'<p class="note">Data: {html.escape(str(rep["data"]["file"]))}. {html.escape(rep["rms_definition"])}. '
        "Lengths in mm.</p>",
    ]
    n = 0

    def figure(k: str) -> None:
        nonlocal n
        n += 1
        title, caption = FIGURE_TEXT.get(k) or _diag_figure_text(k)
        parts.append(
            f'<h3 id="{html.escape(k)}">Figure {n}. {html.escape(title)}</h3>'
            f'<figure><img data-figure="{html.escape(k)}" alt="{html.escape(title)}" '
            f'src="data:image/png;base64,{figs[k]}"><figcaption>{html.escape(caption)}</figcaption>'
            "</figure>"
        )

    maps_sec = next((sec for sec in sections[1:] if sec.startswith("Joint error maps")), None)
    if maps_sec is not None:  # what an engineer looks for when a map was added: near the top
        parts.append('<h2 id="error_maps">Joint error maps</h2>')
        parts.append(_md_block(maps_sec.split("\n", 1)[1]))
        if "error_maps" in figs:
            figure("error_maps")
    parts.append("<h2>Figures</h2>")
    for k in ["residuals", "history", "compensation"] + [k for k in figs if k.startswith("diag_")]:
        if k in figs:
            figure(k)
    for sec in sections[1:]:
        if sec.startswith("Provenance") or sec is maps_sec:
            continue
        parts.append(_md_block("## " + sec))
    parts.append('<h2 id="provenance">Provenance</h2>')
    parts.append(_html_table(["item", "value", "SHA-256"], _provenance_rows(rep), mono_cols=(1, 2)))
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"


def _md_cells(line: str) -> list[str]:
    """The cells of a Markdown table row (escaped pipes ``\\|`` are text)."""
    return [c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", line.strip().strip("|"))]


def _md_block(text: str) -> str:
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
