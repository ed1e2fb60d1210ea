""":func:`write_report`: ``report.json``, ``report.md``, ``report.html`` and the figure files
``figures/<name>.png|pdf`` written through :class:`planner.output.OutputSet` (all or nothing)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from planner.identify_report.captions import figure_entries
from planner.identify_report.data import report_dict
from planner.identify_report.figures import render_figures
from planner.identify_report.html import report_html
from planner.identify_report.markdown import report_markdown
from planner.output import OutputSet
from problems.identify import IdentificationResult


def write_report(
    res: IdentificationResult, folder: str | Path, model_path: str | None = None, data_path: str | None = None
) -> dict[str, Any]:
    """Write ``report.json``, ``report.md``, ``report.html`` and every figure as
    ``figures/<name>.png`` and ``.pdf`` (listed in ``report.json`` → ``figures``, linked from the
    Markdown and the HTML) to ``folder``, all or nothing; returns the content of ``report.json``."""
    rep = report_dict(res, model_path, data_path)
    figs = render_figures(res, rep)
    rep["figures"] = figure_entries(figs)
    out = OutputSet(folder)
    out.add_json("report.json", rep)
    out.add_bytes("report.md", report_markdown(rep).encode())
    out.add_bytes("report.html", report_html(rep, figs).encode())
    for entry in rep["figures"]:
        out.add_bytes(entry["png"], figs[entry["key"]].png)
        out.add_bytes(entry["pdf"], figs[entry["key"]].pdf)
    out.publish()
    return rep
