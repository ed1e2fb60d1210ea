"""Report of ``compplan identify``: ``report.json``, ``report.md``, ``report.html`` and its figures
as files, ``figures/<name>.png`` and ``.pdf``.

The JSON holds every figure of the identification (see ``docs/identification.md``,
section "Report"), opened by a ``headline`` (status, the validation file's RMS before -> after
with ``--validation``, RMS before/after in-sample and held-out, noise floor, effects added, the
structure left -- "weak structure remains" when a significant but small one does -- the joint
error maps, the held parameters in one line, and the compensation check in one sentence that
gives the measurement-frame figure first and says why the base frame's differs) and a
``provenance`` block (compplan version, command line, date, input files with SHA-256).  The
Markdown and HTML say the same for people, the HTML styled like the plan report (headline table
first, then the joint error maps when the model has any: a table of their harmonics and sizes at
the TCP and a figure of each map over its angle range with its band) with embedded figures
(matplotlib's Agg canvas, no pyplot), each also written as a PNG and a PDF and linked: the
residuals per axis before and after, the cross-validated RMS at each selection step, the
compensation re-measured on the virtual robot (measurement and base frame), and the residual
against the significant diagnostic variables (the one that shows unexplained structure first;
joint angles in degrees; the others named in one line).  Every axis names its unit.
Files are written through :class:`planner.output.OutputSet` (all or nothing).
Lengths in the report are in mm (names end in ``_mm``).  Nothing here prints.

Modules (each imports only those listed before it): :mod:`~planner.identify_report.canvas`
(the Agg canvas, PNG and PDF, figure file names), :mod:`~planner.identify_report.text` (values
and Markdown cells as text), :mod:`~planner.identify_report.diagnostics` (which diagnostics are
drawn and listed, the words of their variables), :mod:`~planner.identify_report.captions`
(figure titles, captions, order and files), :mod:`~planner.identify_report.data`
(``report.json``: report_dict, headline, sentences), :mod:`~planner.identify_report.maps` (the
joint error maps: table rows, Markdown, figure), :mod:`~planner.identify_report.figures`
(residual, history, compensation and diagnostic figures), :mod:`~planner.identify_report.markdown`,
:mod:`~planner.identify_report.html`, :mod:`~planner.identify_report.writer` (write_report).
"""

from __future__ import annotations

from planner.identify_report.data import compensation_sentence, report_dict, structure_sentence
from planner.identify_report.diagnostics import (
    REPORT_DIAGNOSTIC_PLOTS,
    REPORT_DIAGNOSTIC_ROWS,
    VARIABLE_LABELS,
    VARIABLE_UNITS,
)
from planner.identify_report.html import report_html
from planner.identify_report.maps import REPORT_MAP_PANELS
from planner.identify_report.markdown import report_markdown
from planner.identify_report.writer import write_report

__all__ = [
    "REPORT_DIAGNOSTIC_PLOTS",
    "REPORT_DIAGNOSTIC_ROWS",
    "REPORT_MAP_PANELS",
    "VARIABLE_LABELS",
    "VARIABLE_UNITS",
    "compensation_sentence",
    "report_dict",
    "report_html",
    "report_markdown",
    "structure_sentence",
    "write_report",
]
