"""``compplan demo``: the plan of the paper's section-4.4 problem (``problems/files/paper_4_4.toml``).

Kept for the API the report and its benchmark use: :func:`run_demo` returns the
:class:`~planner.plan.PlanResult` of the shipped problem ``paper_4_4`` (robot and
number of points may be overridden) and :func:`write_outputs` writes its files and,
on request, its report (built from the result in memory, as ``compplan demo`` does).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from models import Robot
from problems import paper
from problems.problem import Problem, load_problem

from planner.plan import WAYPOINT_COLUMNS, PlanResult, plan
from planner.plan import write_outputs as _write_plan_outputs

#: The shipped problem the demo plans.
DEMO_PROBLEM = "paper_4_4"

#: Alias kept for existing callers: the demo result *is* a plan result.
DemoResult = PlanResult

__all__ = [
    "WAYPOINT_COLUMNS",
    "demo_problem",
    "run_demo",
    "write_outputs",
]


def error_stats(res: Any) -> dict[str, float]:
    """Max and RMS of the Euclidean TCP position error of a CompensationResult, mm."""
    return res.stats_mm()


def demo_problem(robot: Robot | str | None = None, n_points: int | None = None) -> Problem:
    """The paper's section-4.4 problem, optionally on another robot or with another point count.

    ``robot`` may be a built-in name, a robot file path or a :class:`Robot` (its own tool is
    replaced by the problem's: the TCP at the flange).
    """
    pr = load_problem(DEMO_PROBLEM)
    if isinstance(robot, Robot):  # its arm model too (not the problem's robot's)
        from models.arm import load_arm

        pr = pr.with_robot(load_arm(robot))
    elif robot is not None:
        pr = pr.with_robot(str(robot))
    if n_points is not None and n_points != pr.n:
        pr = pr.with_points(n_points)
    return pr


def run_demo(
    robot: Robot | str | None = None,
    n_points: int = paper.SECTION_4_4_POINTS,
    wrench: np.ndarray | None = None,
    verbose: bool = False,
) -> PlanResult:
    """Plan the paper's section-4.4 problem (raises CompplanError if it is infeasible)."""
    pr = demo_problem(robot, n_points)
    if wrench is not None:
        from dataclasses import replace

        pr = replace(pr, wrench=np.broadcast_to(np.asarray(wrench, float), (pr.n, 6)).copy())
    return plan(pr, verbose=verbose).raise_for_status()


def write_outputs(
    res: PlanResult, folder: str | Path, with_figures: bool = False, report: bool = False, **report_options: Any
) -> dict[str, Any]:
    """Write the demo's files (see :func:`planner.plan.write_outputs`); figures off by default.

    With ``report`` the report is written too, from ``res`` (keyword arguments of
    :func:`planner.report.write_report` in ``report_options``).  Returns the summary.
    """
    view = res.view()
    extra: dict[str, bytes] = {}
    if report:  # the plan's files and its report are written as one set
        from planner.report.writer import report_files

        extra = report_files(res.record(folder, view), **report_options)
    _write_plan_outputs(res, folder, with_figures=with_figures, view=view, extra=extra)
    return view.summary
