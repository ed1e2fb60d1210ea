"""Writing a report: view -> tables and figures -> ``report.html``, ``report.md``, ``figures/``."""

from __future__ import annotations

from pathlib import Path
from typing import Any
from collections.abc import Mapping

from planner.compliance_map import ProgressFn
from planner.output import OutputSet
from planner.report.figures import build_figures
from planner.report.maps import cache_rendered_maps
from planner.report.rendering import render_html, render_items, render_markdown
from planner.record import RunRecord, read_record
from planner.report.tables import summary_tables

#: The entries of a run folder that its report owns (replaced together by each report).
REPORT_OUTPUTS = ("report.html", "report.md", "figures", "compliance_map.csv")


def write_report(
    folder: str | Path,
    progress: ProgressFn | None = None,
    *,
    record: RunRecord | None = None,
    map_options: Mapping[str, Any] | None | bool = None,
    workers: int | None = None,
    map_cache: bool = True,
) -> Path:
    """Write ``report.html``, ``report.md`` and ``figures/*.png|pdf`` into a run folder.

    Parameters
    ----------
    folder : str or Path
        Output folder of ``compplan demo`` or ``compplan plan``.
    progress : callable, optional
        ``progress(stage, done, total)`` with stage ``"compliance map"`` (per
        chunk of grid points) and ``"figures"`` (per figure).
    record : RunRecord, optional
        The record of the run the folder holds, made by the plan still in memory
        (:meth:`~planner.plan_result.PlanResult.record`); without it the record is read from the
        folder's files (:func:`~planner.record.read_record`).  Its arm model is the one the
        report draws (compliance map, arm).
    map_options : mapping, None or False
        Options of :func:`planner.compliance_map.compliance_map` for figure 1
        (default: the paper's section-4.3 plane with the run's robot);
        ``False`` leaves the map out.
    workers : int, optional
        Processes that render the figures (default
        :func:`~planner.report.rendering.default_workers`; 1 renders in this process).
    map_cache : bool
        Reuse the compliance map drawn earlier for the same robot and options
        (kept under ``$COMPPLAN_CACHE/maps``, default ``~/.cache/compplan``), and every figure
        drawn earlier from the same data (``$COMPPLAN_CACHE/figures``).

    Returns
    -------
    Path
        The path of ``report.html``.

    Raises
    ------
    InputError
        The folder is not a run folder or one of its files is malformed, or the identified
        model file its summary records is missing or changed (SHA-256).
    """
    run = record if record is not None else read_record(folder)
    return publish_report(run, progress, map_options=map_options, workers=workers, map_cache=map_cache)


def publish_report(
    run: RunRecord,
    progress: ProgressFn | None = None,
    *,
    map_options: Mapping[str, Any] | None | bool = None,
    workers: int | None = None,
    map_cache: bool = True,
) -> Path:
    """Write the report of a :class:`~planner.record.RunRecord` into ``run.folder``, all or
    nothing (options as for :func:`write_report`); returns the path of ``report.html``.

    The folder's :data:`REPORT_OUTPUTS` are replaced together, in one step (the folder is
    rebuilt beside itself with the run's other files hard-linked, then swapped in; see
    :class:`planner.output.OutputSet`): an earlier report's figure or map is never left
    beside the new report, and a failure leaves the earlier report as it was.
    """
    out = OutputSet(run.folder, owns=REPORT_OUTPUTS)
    for name, data in report_files(
        run, progress, map_options=map_options, workers=workers, map_cache=map_cache
    ).items():
        out.add_bytes(name, data)
    out.publish()  # every entry of REPORT_OUTPUTS replaced at once: no earlier figure is left
    return run.folder / "report.html"


def report_files(
    run: RunRecord,
    progress: ProgressFn | None = None,
    *,
    map_options: Mapping[str, Any] | None | bool = None,
    workers: int | None = None,
    map_cache: bool = True,
) -> dict[str, bytes]:
    """The files of a run's report (names relative to the run folder: ``report.html``, ``report.md``,
    ``figures/*.png|pdf``, ``compliance_map.csv``), built in memory and written nowhere: the caller
    puts them in an output set (:func:`publish_report`, or ``compplan plan``'s own set, so that the
    plan and its report are swapped in together). Options as for :func:`write_report`."""
    files: dict[str, bytes] = {}
    items = build_figures(run, progress, map_options, files, map_cache)
    render_items(items, progress, workers, cache=map_cache)
    cache_rendered_maps(items, files)
    tables = summary_tables(run.summary, run.absent)
    out: dict[str, bytes] = {}
    for it in items:
        if it.png is not None:
            out[f"figures/{it.name}.png"] = it.png
            out[f"figures/{it.name}.pdf"] = it.pdf  # type: ignore[assignment]
    out.update(files)
    out["report.md"] = render_markdown(run, tables, items).encode()
    out["report.html"] = render_html(run, tables, items).encode()
    return out
