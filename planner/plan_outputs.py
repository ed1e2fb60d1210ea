"""The files of a plan: ``summary.json``, ``path.csv``, ``waypoints.csv``, ``branches.csv``,
``trajectory*.csv``, ``dynamic.csv`` and the quick figures, written all or nothing
(:func:`write_outputs`) from a :class:`~planner.plan_result.PlanResult` and its
:class:`~planner.plan_result.RunView`.  The columns are :mod:`planner.record.columns`'s, those the
folder reader (:func:`planner.record.read_record`) reads back.  The module prints nothing.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from problems.timing import Trajectory

from planner.output import OutputSet
from planner.plan_record import record_from_plan
from planner.plan_result import PlanResult, RunView
from planner.record.columns import (
    CUT_COLUMNS,
    CUT_FILE,
    CUT_STOCK_FILE,
    LINK_COLUMNS,
    MM_MIN_PER_M_S,
    PATH_COLUMNS,
    PROGRAM_PATH_COLUMNS,
    PROGRAM_TRAJECTORY_COLUMNS,
    TRAJECTORY_COLUMNS,
    WAYPOINT_COLUMNS,
    trajectory_file,
)

__all__ = ["figures", "output_names", "write_outputs"]


def _trajectory_rows(tr: Trajectory) -> np.ndarray:
    """Rows of ``trajectory*.csv`` (see :data:`TRAJECTORY_COLUMNS`): t, q, qd, qdd, qddd."""
    if not len(tr.t):
        return np.empty((0, len(TRAJECTORY_COLUMNS)))
    return np.column_stack([tr.t, tr.q, tr.qd, tr.qdd, tr.qddd])


def figures(res: PlanResult, view: RunView | None = None) -> dict[str, bytes]:
    """PNG figures ``branches.png`` (error per branch) and ``trajectory.png`` (timed joints): the
    report's figures 5 and 6, drawn by the same functions
    (:func:`planner.report.figures.quick_figures`); ``view``: the plan's, when the caller has it."""
    from planner.report.figures import quick_figures

    return quick_figures(record_from_plan(res, Path("."), view))


def write_outputs(
    res: PlanResult,
    folder: str | Path,
    with_figures: bool = True,
    extra: Mapping[str, bytes] | None = None,
    view: RunView | None = None,
) -> dict[str, Any]:
    """Write the plan's files, all or nothing.

    ``summary.json``, ``path.csv`` (x, y, z, q1..q6: the exact commands),
    ``waypoints.csv``, ``branches.csv``, ``trajectory.csv`` (the controller's,
    Ruckig when available), ``trajectory_<method>.csv`` for the other methods,
    and with ``with_figures`` ``branches.png`` and ``trajectory.png`` (the report's figures 5
    and 6); ``extra`` adds files by name (the exports of ``plan --export``), in the same set.
    ``view``: the plan's :class:`RunView` when the caller has it (else it is built here).

    Raises
    ------
    CompplanError
        If the plan failed (nothing is written).
    """
    view = res.view() if view is None else view
    assert res.exact is not None and view.result is res
    summary = view.summary
    out = OutputSet(folder)
    out.add_json("summary.json", summary)
    prog = res.problem.program
    if prog is None:
        out.add_csv("path.csv", PATH_COLUMNS, np.hstack([res.positions, res.exact.q_command]))
    else:
        w = prog.waypoints
        out.add_csv(
            "path.csv",
            PATH_COLUMNS + PROGRAM_PATH_COLUMNS,
            np.column_stack([res.positions, res.exact.q_command, w.feed_m_s * MM_MIN_PER_M_S]),
            np.column_stack([w.line, w.rapid]),
        )
    out.add_csv("waypoints.csv", WAYPOINT_COLUMNS, view.waypoints)
    out.add_csv("branches.csv", view.branch_columns, view.branches)
    for m, tr in res.trajectories.items():
        name = trajectory_file(m, res.controller)
        if m == res.controller and res.dynamic is not None and res.dynamic.link is not None:
            out.add_csv(name, TRAJECTORY_COLUMNS + LINK_COLUMNS, np.hstack([_trajectory_rows(tr), res.dynamic.link.q]))
        elif m in res.feed and prog is not None:
            move = res.feed[m].sample_move
            out.add_csv(
                name,
                TRAJECTORY_COLUMNS + PROGRAM_TRAJECTORY_COLUMNS,
                _trajectory_rows(tr),
                np.column_stack([prog.waypoints.line[move], move]),
            )
        else:
            out.add_csv(name, TRAJECTORY_COLUMNS, _trajectory_rows(tr))
    if with_figures:
        for name, data in figures(res, view).items():
            out.add_bytes(name, data)
    if view.dynamic is not None:
        out.add_csv("dynamic.csv", *view.dynamic)
    if view.cut is not None:
        from planner.plan_cut import cut_stock_bytes

        out.add_csv(CUT_FILE, CUT_COLUMNS, view.cut)
        out.add_bytes(CUT_STOCK_FILE, cut_stock_bytes(res))
    for name, data in (extra or {}).items():
        out.add_bytes(name, data)
    out.publish()
    return summary


def output_names(res: PlanResult, with_figures: bool = True) -> list[str]:
    """Names of the files :func:`write_outputs` writes for ``res``."""
    names = ["summary.json", "path.csv", "waypoints.csv", "branches.csv"]
    names += [trajectory_file(m, res.controller) for m in res.trajectories]
    names += ["dynamic.csv"] if res.dynamic is not None and res.dynamic.link is not None else []
    names += [CUT_FILE, CUT_STOCK_FILE] if res.problem.cut is not None else []
    if with_figures:
        names += ["branches.png"] + (["trajectory.png"] if res.trajectories else [])
    return names
