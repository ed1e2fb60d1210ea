"""A plan's :class:`~planner.record.RunRecord`, from its :class:`~planner.plan_result.PlanResult`
in memory: what ``compplan plan`` and ``demo`` hand the report right after planning.

:func:`record_from_plan` gives the same record as :func:`planner.record.read_record` on the folder
that :func:`planner.plan_outputs.write_outputs` writes from the plan, without reading it, with the
plan's own arm model.  The module prints nothing.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from planner.output import jsonable
from planner.record.columns import CUT_COLUMNS, DYNAMIC_KEY, MM_MIN_PER_M_S, PROGRAM_KEY, WAYPOINT_COLUMNS
from planner.record.record import (
    NO_TRAJECTORY,
    ProgramRecord,
    RunRecord,
    add_trajectory,
    no_dynamic,
    program_record,
    trajectory_files,
)

if TYPE_CHECKING:
    from planner.plan_result import PlanResult, RunView
    from problems.timing import Trajectory

__all__ = [
    "record_from_plan",
]


def record_from_plan(res: PlanResult, folder: str | Path, view: RunView | None = None) -> RunRecord:
    """The record of a successful plan, from its in-memory result.

    Parameters
    ----------
    res : PlanResult
    folder : str or Path
        The run's output folder (where the report goes).
    view : RunView, optional
        The plan's summary and tables (:meth:`~planner.plan_result.PlanResult.view`) when the caller
        has them; else they are computed here.

    Raises
    ------
    CompplanError
        If the plan failed (:meth:`~planner.plan_result.PlanResult.raise_for_status`).
    """
    view = res.view() if view is None else view
    assert view.result is res, "the view of another plan"
    summary = jsonable(view.summary)
    run = RunRecord(Path(folder), summary, robot=res.problem.robot, model=view.model)
    run.waypoints = dict(zip(WAYPOINT_COLUMNS, view.waypoints.T))
    run.branches = dict(zip(view.branch_columns, view.branches.T))
    for name, method in trajectory_files(summary):
        tr = res.trajectories.get(method)
        if tr is not None:
            add_trajectory(run, method, name, _trajectory_arrays(tr))
    if not run.trajectories:
        run.absent.setdefault("trajectory", NO_TRAJECTORY)
    run.program = program_from_plan(res, summary)
    if view.dynamic is not None:
        cols, rows = view.dynamic
        run.dynamic = {c: np.asarray(rows[:, j], float) for j, c in enumerate(cols)}
    elif isinstance(summary.get(DYNAMIC_KEY), Mapping):
        run.absent["dynamic"] = no_dynamic(summary)
    if view.cut is not None:
        c = res.problem.cut
        run.cut = {col: np.asarray(view.cut[:, j], float) for j, col in enumerate(CUT_COLUMNS)}
        run.cut_stock = {
            "before": np.asarray(c.heights_before, dtype=float),
            "after": np.asarray(c.heights_after, dtype=float),
            "extent": np.asarray(c.grid_extent_m, dtype=float),
        }
    return run


def _trajectory_arrays(tr: Trajectory) -> dict[str, np.ndarray | None]:
    return {"t": tr.t, "q": tr.q, "qd": tr.qd, "qdd": tr.qdd, "qddd": tr.qddd}


def program_from_plan(res: PlanResult, summary: Mapping[str, Any]) -> ProgramRecord | None:
    """The program record of a plan in memory (None for a path that is not a program).

    ``summary``: the plan's ``summary.json`` content.  Gives the arrays that
    :func:`planner.plan_outputs.write_outputs` writes into ``path.csv`` and the ``line`` column of
    ``trajectory*.csv``, so the record equals :func:`planner.record.read.program_from_folder`'s of
    the written folder.
    """
    prog = getattr(res.problem, "program", None)
    if prog is None or not isinstance(summary.get(PROGRAM_KEY), Mapping):
        return None
    w = prog.waypoints
    view = program_record(summary, res.positions, w.feed_m_s * MM_MIN_PER_M_S, w.line, w.rapid)
    link = res.dynamic is not None and getattr(res.dynamic, "link", None) is not None
    for m, fl in res.feed.items():
        tr = res.trajectories.get(m)
        if tr is None or (m == res.controller and link):  # a motor-side command: no line column
            continue
        if len(fl.sample_move) == len(tr.t):
            view.sample_line[m] = np.asarray(w.line)[fl.sample_move].astype(int)
            view.sample_waypoint[m] = np.asarray(fl.sample_move).astype(int)
    return view
