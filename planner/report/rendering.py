"""Rendering: figure jobs to PNG/PDF bytes (in up to two forked processes) and the
report's HTML and Markdown text.

A figure is prepared as a :class:`FigureItem` whose ``job`` holds the drawing
function of :mod:`planner.report.plots` and its arrays; :func:`render_items`
runs the jobs.  Forked workers inherit the imported matplotlib, so start-up is
cheap; without ``fork`` (Windows) the figures are rendered in this process.
"""

from __future__ import annotations

import html
import os
import re
from dataclasses import dataclass
from typing import Any
from collections.abc import Callable

from planner.compliance_map import ProgressFn
from planner.report import plots
from planner.report.figure_cache import keep_rendered, take_cached
from planner.report.page import PAGE_END, embedded_figure, page_head, page_text
from planner.record import RunRecord
from planner.report.tables import Table, report_title

#: Most processes used to render figures (see :func:`render_items`).
MAX_WORKERS = 2

#: Relative rendering cost of each figure (longest first when rendering in parallel).
_COST = {
    "fig1_compliance_map": 3.0,
    "fig3_compensation_angles": 2.8,
    "fig6_trajectory": 2.7,
    "fig4_error_before_after": 1.9,
    "fig2_stiffness_error": 1.0,
    "fig7_arm_3d": 1.0,
    "fig5_branches": 0.9,
    "fig8_dynamic_compensation": 1.2,
    "fig9_toolpath": 1.5,
    "fig10_feed": 1.2,
    "fig11_cell": 2.0,
}

#: A figure to draw: ``(drawing function, args, kwargs)``.
Job = tuple[Callable[..., Any], tuple, dict]


@dataclass
class FigureItem:
    """One figure of the report: what to draw (``job``), or the drawn bytes, or why it is absent."""

    name: str
    title: str
    caption: str
    png: bytes | None = None
    pdf: bytes | None = None
    absent: str = ""
    #: What to render; None when absent or already rendered.
    job: Job | None = None
    #: Key under which the rendered figure is cached (compliance map only).
    cache_key: str | None = None
    #: An interactive version for report.html (an HTML ``<div>`` with its script, needing plotly.js:
    #: the cell view, :mod:`planner.report.cell_view`); the PNG stays for report.md and the PDF.
    interactive: str | None = None


#: A figure file's name carries its number (``fig9_toolpath``): the report shows that number.
_NUMBERED_NAME = re.compile(r"fig(\d+)_")


def figure_number(name: str, position: int) -> int:
    """The number a figure is shown with: the one in its file name (``fig9_toolpath`` -> 9), so
    "Figure 9" is ``figures/fig9_toolpath.png`` even when figures before it are absent from the
    run; ``position`` (1-based, in the report) for a name without one."""
    m = _NUMBERED_NAME.match(name)
    return int(m.group(1)) if m else position


def job(fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Job:
    """A figure job: ``fn(*args, **kwargs)`` builds the figure."""
    return fn, args, kwargs


def render_job(jb: Job) -> tuple[bytes, bytes]:
    """Build one figure from its arrays and render it to PNG and PDF bytes."""
    fn, args, kwargs = jb
    return plots.render(fn(*args, **kwargs))


def render_png(jb: Job) -> tuple[bytes, None]:
    """Build one figure from its arrays and render it to PNG bytes only (no PDF)."""
    fn, args, kwargs = jb
    return plots.render_png(fn(*args, **kwargs)), None


def _fork_available() -> bool:
    import multiprocessing

    return "fork" in multiprocessing.get_all_start_methods()


def default_workers() -> int:
    """Processes used to render figures: 2 where ``fork`` exists and 2+ CPUs, else 1."""
    cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return min(MAX_WORKERS, cpus) if _fork_available() else 1


def render_items(
    items: list[FigureItem],
    progress: ProgressFn | None = None,
    workers: int | None = None,
    pdf: bool = True,
    cache: bool = True,
) -> None:
    """Render every item that has a job, as :func:`render_fresh`; with ``cache``, a figure drawn
    before from the same data by the same code is read from the figure cache instead
    (:mod:`planner.report.figure_cache`), and the others are kept there."""
    todo = [it for it in items if it.job is not None]
    unrendered = take_cached(todo, pdf) if cache else {}
    cached = sum(it.job is None for it in todo)
    for i in range(1, cached + 1):
        if progress is not None:
            progress("figures", i, len(todo))

    def shifted(stage: str, done: int, total: int) -> None:
        progress(stage, cached + done, cached + total)  # type: ignore[misc]

    render_fresh(todo, shifted if progress is not None else None, workers, pdf)
    if cache:
        keep_rendered(todo, unrendered)


def render_fresh(
    items: list[FigureItem], progress: ProgressFn | None = None, workers: int | None = None, pdf: bool = True
) -> None:
    """Render every item that has a job, filling ``png`` and ``pdf`` (``pdf`` False: PNG only,
    ``pdf`` stays None).

    With ``workers > 1`` the figures are rendered in forked processes (they
    inherit the imported matplotlib, so start-up is cheap); the jobs hold only
    arrays and strings.  Without ``fork`` (Windows) or with ``workers=1`` they
    are rendered here, one after the other.
    """
    render = render_job if pdf else render_png
    todo = [it for it in items if it.job is not None]
    total = len(todo)
    n = default_workers() if workers is None else max(1, int(workers))
    n = min(n, total)

    def tick(i: int) -> None:
        if progress is not None:
            progress("figures", i, total)

    if n <= 1 or not _fork_available():
        for i, it in enumerate(todo, start=1):
            it.png, it.pdf = render(it.job)  # type: ignore[arg-type]
            tick(i)
        return
    import multiprocessing

    # Most expensive first, so the two processes finish together.
    order = sorted(todo, key=lambda it: -_COST.get(it.name, 1.0))
    ctx = multiprocessing.get_context("fork")
    from models.interrupts import forked_worker_signals

    with ctx.Pool(processes=n, initializer=forked_worker_signals) as pool:
        results = pool.imap(render, [it.job for it in order], chunksize=1)
        for i, (it, (png, pdf_bytes)) in enumerate(zip(order, results), start=1):
            it.png, it.pdf = png, pdf_bytes
            tick(i)


# ------------------------------------------------------------------------------ HTML and MD
def _html_lists(run: RunRecord) -> list[str]:
    """Rejected branches, warnings and absent pieces, as HTML lists (when there are any)."""
    s, out = run.summary, []
    rej = s.get("rejected_branches") or {}
    if rej:
        out.append(
            "<h3>IK branches not feasible along the path</h3><ul>"
            + "".join(f"<li>{html.escape(str(b))}: {html.escape(str(r))}</li>" for b, r in rej.items())
            + "</ul>"
        )
    warn = s.get("warnings") or []
    if warn:
        out.append("<h3>Warnings</h3><ul>" + "".join(f"<li>{html.escape(str(w))}</li>" for w in warn) + "</ul>")
    if run.absent:
        out.append(
            "<h3>Absent in this run</h3><ul>"
            + "".join(f"<li>{html.escape(v)}</li>" for v in run.absent.values())
            + "</ul>"
        )
    return out


def _html_figure(i: int, it: FigureItem) -> list[str]:
    i = figure_number(it.name, i)
    out = [f'<h3 id="{it.name}">Figure {i}. {html.escape(it.title)}</h3>']
    if it.png is None:
        out.append(f'<p class="absent" data-absent="{it.name}">{html.escape(it.absent)}</p>')
        return out
    if it.interactive is not None:  # shown instead of the PNG; the PNG and PDF are linked
        out.append(
            f'<figure data-figure="{it.name}" data-interactive="plotly">{it.interactive}'
            f"<figcaption>{html.escape(it.caption)} Static files: "
            f'<a href="figures/{it.name}.png">PNG</a>, '
            f'<a href="figures/{it.name}.pdf">PDF</a>.</figcaption></figure>'
        )
        return out
    out.append(
        embedded_figure(it.name, it.title, it.caption, it.png, f"figures/{it.name}.png", f"figures/{it.name}.pdf")
    )
    return out


def _split_tables(tables: list[Table]) -> tuple[list[Table], list[Table], list[Table]]:
    """(headline, body, provenance) tables, by their anchors."""
    head = [t for t in tables if t.anchor == "headline"]
    prov = [t for t in tables if t.anchor == "provenance"]
    body = [t for t in tables if t.anchor not in ("headline", "provenance")]
    return head, body, prov


def _plotly_script(items: list[FigureItem]) -> str:
    """The plotly.js bundle, inline and once, when a figure is interactive (no network needed to
    view the report; about 4.9 MB); else nothing."""
    if not any(it.interactive is not None and it.png is not None for it in items):
        return ""
    from plotly.offline import get_plotlyjs

    return f'<script type="text/javascript" data-bundle="plotly.js">{get_plotlyjs()}</script>'


def render_html(run: RunRecord, tables: list[Table], items: list[FigureItem]) -> str:
    """``report.html``: self-contained (the PNGs embedded as data URIs), the headline first."""
    title = report_title(run.summary)
    head, body, prov = _split_tables(tables)
    toc = " ".join(f'<a href="#{it.name}">Fig. {figure_number(it.name, i)}</a>' for i, it in enumerate(items, start=1))
    out = page_head(title, head=_plotly_script(items))
    out += [t.html() for t in head]
    out += [
        f'<nav class="toc"><a href="#details">Run details</a> <a href="#provenance">Provenance</a> {toc}</nav>',
        '<h2 id="details">Run details</h2>',
        f'<p class="note">Output folder: {html.escape(str(run.folder))}. All values from '
        "summary.json and the CSV files of this folder; SI inside, mm and deg in the "
        "displays.</p>",
    ]
    out += [t.html() for t in body]
    out += _html_lists(run)
    out += [t.html() for t in prov]
    out.append("<h2>Figures</h2>")
    for i, it in enumerate(items, start=1):
        out += _html_figure(i, it)
    out.append(PAGE_END)
    return page_text(out)


def render_markdown(run: RunRecord, tables: list[Table], items: list[FigureItem]) -> str:
    """``report.md``: the same tables, referencing ``figures/*.png``."""
    s = run.summary
    head, body, prov = _split_tables(tables)
    out = [f"# {report_title(s)}", ""]
    for t in head:
        out += [t.markdown(), ""]
    out += [
        "## Run details",
        "",
        "All values from summary.json and the CSV files of this folder; SI inside, mm and deg in the displays.",
        "",
    ]
    for t in body:
        out += [t.markdown(), ""]
    rej = s.get("rejected_branches") or {}
    if rej:
        out += ["### IK branches not feasible along the path", ""] + [f"- {b}: {r}" for b, r in rej.items()] + [""]
    warn = s.get("warnings") or []
    if warn:
        out += ["### Warnings", ""] + [f"- {w}" for w in warn] + [""]
    if run.absent:
        out += ["### Absent in this run", ""] + [f"- {v}" for v in run.absent.values()] + [""]
    for t in prov:
        out += [t.markdown(), ""]
    out += ["## Figures", ""]
    for i, it in enumerate(items, start=1):
        i = figure_number(it.name, i)
        out += [f"### Figure {i}. {it.title}", ""]
        if it.png is None:
            out += [f"*{it.absent}*", ""]
            continue
        out += [
            f"![Figure {i}. {it.title}](figures/{it.name}.png)",
            "",
            f"{it.caption} ([PDF](figures/{it.name}.pdf))",
            "",
        ]
    return "\n".join(out)
