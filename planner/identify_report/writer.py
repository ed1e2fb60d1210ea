""":func:`write_report`: ``report.json``, ``report.md`` and ``report.html`` written through
:class:`planner.output.OutputSet` (all or nothing)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from planner.identify_report.data import report_dict
from planner.identify_report.figures import _figures
from planner.identify_report.html import report_html
from planner.identify_report.markdown import report_markdown
from planner.output import OutputSet
from problems.identify import IdentificationResult


def write_report(
    res: IdentificationResult, folder: str | Path, model_path: str | None = None, data_path: str | None = None
) -> dict[str, Any]:
    """Write ``report.json``, ``report.md`` and ``report.html`` to ``folder`` (all or nothing)."""
    rep = report_dict(res, model_path, data_path)
    out = OutputSet(folder)
    out.add_json("report.json", rep)
    out.add_bytes("report.md", report_markdown(rep).encode())
    out.add_bytes("report.html", report_html(rep, _figures(res, rep)).encode())
    out.publish()
    return rep
