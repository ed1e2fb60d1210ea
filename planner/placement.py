"""The placement study pipeline (``compplan place``): sweep the grid, rank, plan the best in full.

1. :func:`~problems.placement.sweep.run_sweep` scores every placement of the grid (serial or on
   Dask) with the per-pose kernel; the problem as written (the robot at the cell origin, the
   *baseline*) is scored by the same kernel.
2. The feasible placements are ranked (:func:`~problems.placement.scores.ranking`: smallest RMS
   load-induced error of the best branch first).
3. The best ``top`` placements and the baseline are planned in full (posture NLP, exact
   compensation, timing: :func:`planner.plan.plan` on :func:`~problems.placement.placed.problem_at`).

The report and the files (:func:`write_study`) are built from the :class:`PlacementStudy` in
memory.
"""

from __future__ import annotations

import time
from typing import Any
from collections.abc import Callable

import numpy as np

from planner.plan import plan
from planner.placement_outputs import SCORE_COLUMNS, scores_csv, write_study
from planner.placement_result import (
    COLLISIONS_WHAT,
    NO_CELL_NOTE,
    PAIRS_NOTE,
    PLAN_STAGE,
    PlacementPlan,
    PlacementStudy,
    StudyStatus,
    collision_lines,
    plan_clearance,
    scores_dict,
)
from problems.placement.grid import PlacementGrid
from problems.placement.kernel import PlacementKernel
from problems.placement.placed import problem_at
from problems.placement.scores import ChunkScores, PlacementStatus, ranking
from problems.placement.sweep import run_sweep
from problems.problem import Problem


def study(
    problem: Problem,
    grid: PlacementGrid,
    scheduler: str | None = None,
    chunk_placements: int | None = None,
    progress: Callable[[str, int, int], None] | None = None,
    optimise: bool = True,
) -> PlacementStudy:
    """Run a placement study (see the module docstring).

    Parameters
    ----------
    problem : Problem
        The task, in the cell frame.
    grid : PlacementGrid
    scheduler : str, optional
        ``serial`` (default), ``local:N`` or ``tcp://HOST:PORT``.
    chunk_placements : int, optional
        Placements per chunk (default: :func:`~problems.placement.sweep.chunk_placements_for`).
    progress : callable, optional
        ``progress(stage, done, total)``.
    optimise : bool
        False: the full plans use analytic postures (no NLP).

    Returns
    -------
    PlacementStudy
        Status ``SWEEP_FAILED`` (no baseline, ranking or plans) when the sweep's cluster failed.
    """
    kernel = PlacementKernel(problem)
    sw = run_sweep(kernel, grid.placements(), scheduler, chunk_placements, progress)
    labels = tuple(kernel.ik.labels)
    if not sw.scored:  # the cluster failed: nothing to rank
        none, unranked = ChunkScores.empty(0, kernel.n_branches), np.zeros(0, dtype=int)
        failed = StudyStatus.SWEEP_FAILED
        return PlacementStudy(failed, sw.reason, problem, grid, sw, none, unranked, branch_labels=labels)
    base = kernel.evaluate(np.zeros((1, 5)))
    ranked = ranking(sw.scores)
    status, reason = (StudyStatus.OK, "") if sw.ok else (StudyStatus.NO_FEASIBLE, sw.reason)
    st = PlacementStudy(status, reason, problem, grid, sw, base, ranked, branch_labels=labels)
    if kernel.cell is not None:  # which collisions are the base's: the kernel's footprint test, asked again
        coll = np.flatnonzero(sw.scores.status == PlacementStatus.COLLISION.code)
        st.footprint_collisions = coll[kernel.cell.footprint_blocked(sw.placements[coll])]
        st.baseline_on_object = bool(kernel.cell.footprint_blocked(np.zeros((1, 5)))[0])
    if not st.ok:
        return st  # nothing to compare the problem as written with
    rank_of = {int(i): r + 1 for r, i in enumerate(ranked)}
    todo: list[tuple[str, int | None, int | None, np.ndarray, dict[str, Any]]] = [
        (f"best {n + 1}", rank_of[i], i, sw.placements[i], st.scores_of(i))
        for n, i in enumerate(distinct_positions(ranked, sw.placements, grid.top))
    ]
    todo.append(("as written", None, None, np.zeros(5), scores_dict(base, 0, labels)))
    for n, (label, rank, idx, pl, sc) in enumerate(todo):
        t0 = time.perf_counter()
        res = plan(problem_at(problem, pl), optimise=optimise)
        st.plans.append(PlacementPlan(label, rank, idx, np.asarray(pl, dtype=float), sc, res, time.perf_counter() - t0))
        if progress is not None:
            progress(PLAN_STAGE, n + 1, len(todo))
    return st


def distinct_positions(ranked: np.ndarray, placements: np.ndarray, n: int) -> list[int]:
    """The first ``n`` ranked placements at distinct base positions (x, y, z, tilt): the full plans
    compare different places to put the robot, not yaws of one place (on an arm whose first
    joint has room, a yaw changes only joint 1's angle, not the error)."""
    out: list[int] = []
    seen: set[tuple[float, ...]] = set()
    if n <= 0:
        return out
    for i in ranked:
        key = tuple(np.round(placements[i, [0, 1, 2, 4]], 12))
        if key in seen:
            continue
        seen.add(key)
        out.append(int(i))
        if len(out) >= n:
            break
    return out


__all__ = [
    "COLLISIONS_WHAT",
    "NO_CELL_NOTE",
    "PAIRS_NOTE",
    "PLAN_STAGE",
    "PlacementPlan",
    "PlacementStudy",
    "SCORE_COLUMNS",
    "StudyStatus",
    "collision_lines",
    "distinct_positions",
    "plan_clearance",
    "scores_csv",
    "study",
    "write_study",
]
