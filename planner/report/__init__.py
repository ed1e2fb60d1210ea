"""The run report: ``report.html`` (self-contained), ``report.md`` and ``figures/*.png|pdf``.

:func:`write_report` writes, into the output folder of ``compplan demo`` or
``compplan plan``:

* ``report.html``: the headline table (status, IK branch, TCP error before and
  after, duration; :func:`~planner.report.tables.headline_table`), the run's
  tables, its provenance (version, command line, date, input files with
  SHA-256), then one section per figure; the PNGs are embedded as base64 data
  URIs so the file opens offline on its own;
* ``report.md``: the same tables, referencing ``figures/*.png``;
* ``figures/figN_*.png`` and ``.pdf``: every figure in both formats;
* ``compliance_map.csv``: the data of figure 1.

The report is drawn from the run's record (:class:`~planner.record.RunRecord`) and from
nothing else: made by the plan that just ran (``write_report(folder, record=res.record(folder))``:
``compplan plan``/``demo``) or read from the folder's files by
:func:`planner.record.read_record` (``summary.json``, ``waypoints.csv``, ``branches.csv`` and,
when a plan was timed, ``trajectory*.csv``, and with dynamic compensation ``dynamic.csv``:
``compplan report DIR``).  Both give the same record.  The report does not import the plan.

A plan with dynamic compensation (``[timing] dynamic = true``, summary.json key
``dynamic_compensation``) adds figure 8 (``figures/fig8_dynamic_compensation``:
the TCP deviation from the planned path against time without, with static and
with static + dynamic compensation, and the TCP speed) and the "Dynamic
compensation" tables; a run without it has neither.

Whatever piece of a run is absent (no trajectory, no branch table, no robot
description) is stated in the report in place of its figure; it never fails
the report.  The run's own ``summary.json`` is never rewritten.  Every number
in the HTML tables is machine-checkable (see :mod:`planner.report.tables`).

Path figures are drawn from the run's data, not recomputed; only the
compliance map and the 3-D arm need the run's arm model (the plan's; from a folder,
the identified model file its summary records, checked against its SHA-256).  The compliance map is cached
(:mod:`planner.report.maps`).  Figures are rendered in up to two forked
processes where the platform allows it.  Everything is built in memory and
published at the end (all or nothing).  The library prints nothing; progress
goes to a callback.

Modules: :mod:`~planner.report.tables` (with :mod:`~planner.report.table_base`,
:mod:`~planner.report.program_tables`, :mod:`~planner.report.dynamic_tables`),
:mod:`~planner.report.figures` (which data each figure draws),
:mod:`~planner.report.plots` (the matplotlib drawings),
:mod:`~planner.report.maps` (compliance map and its cache),
:mod:`~planner.report.rendering` (PNG/PDF, HTML, Markdown),
:mod:`~planner.report.writer` (the entry point).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from models.lazy import lazy_exports

if TYPE_CHECKING:
    from planner.report.figures import DYNAMIC_FIGURE, FIGURE_NAMES, build_figures
    from planner.report.maps import write_map
    from planner.report.rendering import (
        FigureItem,
        render_html,
        render_items,
        render_markdown,
    )
    from planner.report.table_base import Cell, Table, fmt, lookup, value_cell
    from planner.report.tables import load_words, provenance_table, summary_tables
    from planner.report.writer import report_files, write_report

#: The submodule defining each name re-exported here, imported on first use (PEP 562): a command
#: that reads only the tables (``compplan plan --no-report``) does not import matplotlib.
_LAZY = {
    name: module
    for module, names in {
        "figures": ("DYNAMIC_FIGURE", "FIGURE_NAMES", "build_figures"),
        "maps": ("write_map",),
        "rendering": ("FigureItem", "render_html", "render_items", "render_markdown"),
        "table_base": ("Cell", "Table", "fmt", "lookup", "value_cell"),
        "tables": ("load_words", "provenance_table", "summary_tables"),
        "writer": ("report_files", "write_report"),
    }.items()
    for name in names
}


__getattr__, __dir__ = lazy_exports(__name__, globals(), _LAZY)


__all__ = [
    "Cell",
    "DYNAMIC_FIGURE",
    "FIGURE_NAMES",
    "FigureItem",
    "Table",
    "build_figures",
    "fmt",
    "load_words",
    "lookup",
    "provenance_table",
    "report_files",
    "render_html",
    "render_items",
    "render_markdown",
    "summary_tables",
    "value_cell",
    "write_map",
    "write_report",
]
