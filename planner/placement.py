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

import functools
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from collections.abc import Callable, Iterator

import numpy as np

from models.status import Status
from planner.plan import PlanResult, plan
from planner.numbers import headline_mm, round_sig
from planner.provenance import invocation, problem_provenance
from problems.placement.grid import GRID_AXES, PlacementGrid, describe_placement, placement_label
from problems.placement.kernel import PlacementKernel
from problems.placement.placed import problem_at
from problems.placement.scores import STATUS_REASONS, ChunkScores, PlacementStatus, ranking
from problems.placement.sweep import SweepResult, run_sweep
from problems.problem import Problem

#: Columns of ``scores.csv`` (one row per placement, grid order; edge units in the names; ``status``
#: a :class:`PlacementStatus` value, ``best_branch`` an IK branch label; empty cells where a value
#: does not exist).
SCORE_COLUMNS = (
    "index",
    "x_m",
    "y_m",
    "z_m",
    "yaw_deg",
    "tilt_deg",
    "status",
    "best_branch",
    "feasible_branches",
    "rms_error_mm",
    "max_error_mm",
    "joint_margin_deg",
    "singular_margin",
    "blocked_waypoint",
)
#: Decimals of the grid coordinates in the CSV files (m, deg): the grid's own values, without the
#: round-off of ``linspace`` (-0.19999999999999996 -> -0.2).
GRID_DIGITS = 12
#: Progress stage of the full plans.
PLAN_STAGE = "full plans"
#: The collision line of a study without a ``[cell]`` (summary ``collisions.note``, terminal, report).
NO_CELL_NOTE = "not checked (the problem has no [cell]: docs/cell.md)"
#: What the sweep checks against the cell (summary ``collisions.what``).
COLLISIONS_WHAT = (
    "every placement's base footprint against every object (before the IK); where the base is free, the "
    "arm's capsules and the tool at the scanned orientations of every branch that reaches the whole path "
    "without a flip, against the objects and themselves: a placement is set aside (status collision) when "
    "its base overlaps an object or when every such branch comes closer than the clearance on every "
    "sequence of orientations (problems/placement/collide.py)"
)
#: Why the summary names no colliding pair (summary ``collisions.colliding_pairs_note``).
PAIRS_NOTE = (
    "the sweep records one status per placement, not the colliding pair: the placements set aside are "
    "counted by reason (base_on_object, every_branch_colliding); the full plans name their nearest pair"
)


class StudyStatus(Status):
    """Outcome of a placement study."""

    OK = "ok"
    #: no placement of the grid is feasible
    NO_FEASIBLE = "no feasible placement"
    #: the sweep did not complete on its cluster (the sweep's status and reason:
    #: ``SweepStatus.NO_WORKERS`` or ``CLUSTER_FAILED``)
    SWEEP_FAILED = "sweep failed"


@dataclass
class PlacementPlan:
    """A full plan of one placement.

    Attributes
    ----------
    label : str
        ``best 1`` .. ``best N`` or ``as written``.
    rank : int or None
        1-based rank in the sweep (None for the baseline).
    index : int or None
        Grid index (None for the baseline, which is not necessarily on the grid).
    placement : ndarray, shape (5,)
        ``[x, y, z, yaw, tilt]`` (m, rad).
    sweep : dict
        The sweep's scores of this placement (edge units).
    result : PlanResult
    elapsed_s : float
    """

    label: str
    rank: int | None
    index: int | None
    placement: np.ndarray
    sweep: dict[str, Any]
    result: PlanResult
    elapsed_s: float

    def headline(self) -> dict[str, Any]:
        """The plan's headline (branch, errors before and after compensation in mm, duration).

        Built once from the plan's summary: the study's summary, figures and page all read it."""
        return self._headline

    @functools.cached_property
    def _headline(self) -> dict[str, Any]:
        if not self.result.ok:
            return {"status": self.result.status.value, "reason": self.result.reason}
        return self.result.summary()["headline"]

    def cell(self) -> dict[str, Any] | None:
        """The plan's cell check as its ``summary.json`` holds it (``cell``,
        :func:`planner.cell_check.cell_summary`), read from the result (nothing is checked again);
        None without a cell or when the plan stopped before the check."""
        return self._cell

    @functools.cached_property
    def _cell(self) -> dict[str, Any] | None:
        r = self.result
        if r.cell is None or r.posture is None:
            return None
        from planner.cell_check import cell_summary

        return cell_summary(r.cell, r.posture.labels)

    def clearance(self) -> dict[str, Any] | None:
        """The plan's smallest clearance to the cell (:func:`plan_clearance`), None without a cell check."""
        c = self.cell()
        return None if c is None else plan_clearance(c)


@dataclass
class PlacementStudy:
    """Everything a placement study produced (see the module docstring).

    Attributes
    ----------
    status : StudyStatus
    reason : str
    problem : Problem
        As written (cell frame).
    grid : PlacementGrid
    sweep : SweepResult
    baseline : ChunkScores
        The kernel's scores of the problem as written (one row).
    ranked : ndarray of int
        Grid indices of the feasible placements, best first.
    plans : list of PlacementPlan
        The best ``grid.top`` placements at distinct base positions (:func:`distinct_positions`),
        then the baseline; none when no placement is feasible.
    branch_labels : tuple of str
    footprint_collisions : ndarray of int or None
        With a ``[cell]``: grid indices of the placements set aside for collision whose base
        footprint overlaps an object (the kernel's own footprint test,
        :meth:`problems.placement.collide.KernelCell.footprint_blocked`, asked again for the
        ``collision`` placements only); the other ``collision`` placements have every flip-free
        branch colliding.  None without a cell or when it was not asked.
    baseline_on_object : bool or None
        The same for the problem as written.
    """

    status: StudyStatus
    reason: str
    problem: Problem
    grid: PlacementGrid
    sweep: SweepResult
    baseline: ChunkScores
    ranked: np.ndarray
    plans: list[PlacementPlan] = field(default_factory=list)
    branch_labels: tuple[str, ...] = ()
    made: dict[str, Any] = field(default_factory=invocation)
    footprint_collisions: np.ndarray | None = None
    baseline_on_object: bool | None = None

    @property
    def ok(self) -> bool:
        return self.status is StudyStatus.OK

    def scores_of(self, i: int) -> dict[str, Any]:
        """The sweep's scores of grid placement ``i`` (edge units: mm, deg)."""
        return _scores_dict(self.sweep.scores, i, self.branch_labels)

    @property
    def improvement(self) -> float | None:
        """Baseline RMS error / best placement's RMS error (sweep), or None when either is infeasible
        or the best placement's error is 0 (no load)."""
        if not len(self.ranked) or not self.baseline.status_of(0).ok:
            return None
        best = float(self.sweep.scores.rms_error_m[self.ranked[0]])
        return float(self.baseline.rms_error_m[0]) / best if best > 0.0 else None  # no load: no factor

    def warnings(self) -> list[str]:
        """What the engineer should know before trusting the ranking: the best placement on the
        edge of the grid (the optimum may lie outside it), failed full plans."""
        out: list[str] = []
        if len(self.ranked):
            best = self.sweep.placements[self.ranked[0]]
            edge = [
                k
                for i, k in enumerate(GRID_AXES)
                if len(self.grid.axes[k]) > 1
                and k not in ("yaw_deg",)
                and (np.isclose(best[i], self.grid.axes[k][0]) or np.isclose(best[i], self.grid.axes[k][-1]))
            ]
            if edge:
                out.append(
                    f"the best placement lies on the edge of the grid in {', '.join(edge)}: a better one may "
                    "lie outside it (widen the grid)"
                )
        out += [f"full plan '{p.label}' failed: {p.result.reason}" for p in self.plans if not p.result.ok]
        return out

    def summary(self) -> dict[str, Any]:
        """``summary.json``: the grid, the sweep's figures, the ranking, the baseline and the plans."""
        sc = self.sweep.scores
        counts = {s.value: int((sc.status == s.code).sum()) for s in PlacementStatus}
        out: dict[str, Any] = {
            "command": "place",
            "headline": self.headline(),
            "status": self.status.value,
            "reason": self.reason or None,
            "problem": self.problem.name,
            "robot": self.problem.robot.name,
            "frames": "placement = base origin (m) and yaw, tilt (deg) in the cell frame (the problem's own frame); "
            "base2cell = Trans(x, y, z) Rot_z(yaw) Rot_x(tilt)",
            "grid": self.grid.describe(),
            "sweep": {
                "placements": int(len(self.sweep.placements)),
                "poses": int(self.sweep.poses),
                "poses_per_placement": int(self.sweep.poses // max(1, len(self.sweep.placements))),
                "chunk_placements": self.sweep.chunk_placements,
                "chunks": self.sweep.n_chunks,
                "scheduler": self.sweep.scheduler,
                "workers": self.sweep.workers,
                "elapsed_s": round(self.sweep.elapsed_s, 3),
                "poses_per_second": round(self.sweep.poses_per_second, 1),
                "compiled": self.sweep.compiled,
                "status_counts": counts,
            },
            "baseline": {"label": "as written", **_scores_dict(self.baseline, 0, self.branch_labels)},
            "ranking": [
                {"rank": r + 1, "index": int(i), **self.scores_of(int(i))}
                for r, i in enumerate(self.ranked[: max(10, self.grid.top)])
            ],
            "improvement_rms_factor": None if self.improvement is None else round(self.improvement, 4),
            "warnings": self.warnings(),
            "collisions": self.collisions(),
            "plans": [_plan_entry(p, self.problem.cell is not None) for p in self.plans],
            "definitions": {
                "rms_error_mm": "RMS over the waypoints of the load-induced TCP position error of the best branch "
                "(arm model load_error, analytic posture at the cheapest scanned orientations)",
                "joint_margin_deg": "smallest distance of a joint to its limit along the path",
                "singular_margin": "smallest ratio of a singularity guard factor to its guard bound along the path "
                "(1 = at the posture NLP's guard)",
            },
            "provenance": problem_provenance(self.problem, self.made),
        }
        return out

    def collisions(self) -> dict[str, Any]:
        """``summary.json`` ``collisions``: whether the placements were checked against the cell,
        how many were set aside for collision and why, and the best placement's smallest clearance
        in its full plan (counts over the whole grid; lengths in mm)."""
        cell = self.problem.cell
        if cell is None:
            return {"checked": False, "note": NO_CELL_NOTE}
        sc = self.sweep.scores
        coll = sc.status == PlacementStatus.COLLISION.code
        n_coll = int(coll.sum())
        if self.footprint_collisions is None:
            on_object = branches = None
        else:
            foot = np.zeros(len(coll), dtype=bool)
            foot[np.asarray(self.footprint_collisions, dtype=int)] = True
            on_object = int((foot & coll).sum())
            branches = n_coll - on_object
        b0 = self.baseline.status_of(0) if len(self.baseline) else None
        why0 = None
        if b0 is PlacementStatus.COLLISION and self.baseline_on_object is not None:
            why0 = "base_on_object" if self.baseline_on_object else "every_branch_colliding"
        best = next((p for p in self.plans if p.rank == 1), None)
        return {
            "checked": True,
            "objects": [{"name": o.name, "shape": o.shape, "role": o.role} for o in cell.objects],
            "clearance_mm": float(cell.clearance * 1e3),
            "placements_checked": int(len(sc)),
            "set_aside": n_coll,
            "base_on_object": on_object,
            "every_branch_colliding": branches,
            "feasible": int(sc.feasible.sum()),
            "as_written": {"status": None if b0 is None else b0.value, "collision": why0},
            "colliding_pairs": None,
            "colliding_pairs_note": PAIRS_NOTE,
            "best_plan": None
            if best is None
            else {
                "label": best.label,
                "placement_text": placement_label(best.placement),
                "plan_status": best.result.status.value,
                "clearance": best.clearance(),
            },
            "what": COLLISIONS_WHAT,
        }

    def headline(self) -> dict[str, Any]:
        """What the engineer reads first (``summary.json`` ``headline``): the best placement (edge
        units), its branch and sweep errors against the problem as written, the improvement factor,
        and the full plans of both (errors before and after compensation, cycle time); lengths in mm
        to 4 significant digits."""
        h: dict[str, Any] = {"status": self.status.value, "reason": self.reason or None}
        best = int(self.ranked[0]) if len(self.ranked) else None
        sc = self.sweep.scores
        h["best_placement"] = None if best is None else describe_placement(self.sweep.placements[best])
        h["best_placement_text"] = None if best is None else placement_label(self.sweep.placements[best])
        h["best_branch"] = None if best is None else self.branch_labels[int(sc.best_branch[best])]
        h["best_rms_error_mm"] = None if best is None else headline_mm(float(sc.rms_error_m[best] * 1e3))
        h["best_max_error_mm"] = None if best is None else headline_mm(float(sc.max_error_m[best] * 1e3))
        ok0 = self.baseline.status_of(0).ok
        h["as_written_status"] = self.baseline.status_of(0).value
        h["as_written_rms_error_mm"] = headline_mm(float(self.baseline.rms_error_m[0] * 1e3)) if ok0 else None
        h["improvement_rms_factor"] = None if self.improvement is None else round_sig(self.improvement)
        for key, p in (
            ("best_plan", next((p for p in self.plans if p.rank == 1), None)),
            ("as_written_plan", next((p for p in self.plans if p.rank is None), None)),
        ):
            if p is None:
                h[key] = None
                continue
            ph = p.headline()
            h[key] = {
                k: ph.get(k)
                for k in (
                    "status",
                    "reason",
                    "branch",
                    "error_before_rms_mm",
                    "error_before_max_mm",
                    "error_after_max_mm",
                    "duration_s",
                )
                if k in ph
            }
            h[key]["status"] = p.result.status.value
            if self.problem.cell is not None:
                c = p.clearance()
                h[key]["min_clearance_mm"] = None if c is None else c["min_clearance_mm"]
        col = self.collisions()
        h["collisions_checked"] = col["checked"]
        h["collision_set_aside"] = col.get("set_aside")
        h["definition"] = (
            "errors: load-induced TCP position error of the best IK branch; best_* and "
            "as_written_rms_error_mm from the sweep (first order, analytic postures), *_plan from "
            "the full plans (posture optimisation, exact equilibrium, before and after exact "
            "compensation); improvement_rms_factor = as written / best (sweep)"
        )
        return h


def _scores_dict(sc: ChunkScores, i: int, labels: tuple[str, ...]) -> dict[str, Any]:
    st = sc.status_of(i)
    b = int(sc.best_branch[i])
    d: dict[str, Any] = {
        "status": st.value,
        "status_reason": STATUS_REASONS[st],
        "best_branch": labels[b] if 0 <= b < len(labels) else None,
        "feasible_branches": int(sc.feasible_branches[i]),
    }
    for k, v, s in (
        ("rms_error_mm", sc.rms_error_m, 1e3),
        ("max_error_mm", sc.max_error_m, 1e3),
        ("joint_margin_deg", sc.joint_margin_rad, 180.0 / np.pi),
        ("singular_margin", sc.singular_margin, 1.0),
    ):
        d[k] = None if not np.isfinite(v[i]) else float(v[i] * s)
    d["blocked_waypoint"] = int(sc.blocked_waypoint[i]) if sc.blocked_waypoint[i] >= 0 else None
    return d


def _plan_entry(p: PlacementPlan, with_cell: bool = False) -> dict[str, Any]:
    out = {
        "label": p.label,
        "rank": p.rank,
        "index": p.index,
        "placement": describe_placement(p.placement),
        "placement_text": placement_label(p.placement),
        "sweep": p.sweep,
        "plan": p.headline(),
        "plan_status": p.result.status.value,
        "elapsed_s": round(p.elapsed_s, 3),
    }
    if with_cell:
        out["clearance"] = p.clearance()
    return out


def plan_clearance(cell: dict[str, Any]) -> dict[str, Any]:
    """A full plan's smallest clearance to the cell, from its ``cell`` block
    (:func:`planner.cell_check.cell_summary`): the smaller of the chosen branch's at the waypoints
    and the controller's trajectory's, with its pair and where; a plan that chose no branch (all
    collide) gives its branches' smallest at the waypoints.

    Returns
    -------
    dict
        ``min_clearance_mm`` (None when nothing was checked), ``pair``, ``where`` (text),
        ``status`` (ok / too_close / collision), ``waypoints_min_clearance_mm``,
        ``trajectory_min_clearance_mm`` and the required ``clearance_mm``.
    """
    found: list[tuple[float, str | None, str, str]] = []
    w, tr = cell.get("waypoints"), cell.get("trajectory")
    if w and w.get("min_clearance_mm") is not None:
        found.append((w["min_clearance_mm"], w["pair"], f"waypoint {w['index']}", w["status"]))
    if tr and tr.get("min_clearance_mm") is not None:
        t = tr.get("time_s")
        where = f"{tr.get('method')} trajectory" + ("" if t is None else f", t = {t:.3f} s")
        found.append((tr["min_clearance_mm"], tr["pair"], where, tr["status"]))
    if not found:
        for label, b in (cell.get("branches") or {}).items():
            if b and b.get("min_clearance_mm") is not None:
                found.append((b["min_clearance_mm"], b["pair"], f"branch {label}, waypoint {b['index']}", b["status"]))
    d, pair, where, status = min(found, key=lambda f: f[0]) if found else (None, None, None, None)
    return {
        "min_clearance_mm": d,
        "pair": pair,
        "where": where,
        "status": status,
        "waypoints_min_clearance_mm": w.get("min_clearance_mm") if w else None,
        "trajectory_min_clearance_mm": tr.get("min_clearance_mm") if tr else None,
        "clearance_mm": cell["clearance_mm"],
    }


def _objects_text(objects: list[dict[str, Any]]) -> str:
    return ", ".join(o["name"] + (" (workpiece)" if o["role"] == "workpiece" else "") for o in objects)


def collision_lines(s: dict[str, Any]) -> list[str]:
    """What a study says about collisions, one line each (the terminal prints them, the report
    shows them): from ``summary.json`` (``s``: :meth:`PlacementStudy.summary`) ``collisions``."""
    c = s["collisions"]
    if not c["checked"]:
        return [f"collisions: {c['note']}"]
    n, k = c["placements_checked"], c["set_aside"]
    out = [
        f"collisions: checked against the cell ({_objects_text(c['objects'])}; clearance {c['clearance_mm']:g} mm): "
        f"{n:,} placement{'s' if n != 1 else ''} checked"
    ]
    if not k:
        out.append("collisions: none set aside for collision")
    elif c["base_on_object"] is None:
        out.append(f"collisions: {k:,} set aside for collision (base on an object or every branch colliding)")
    else:
        out.append(
            f"collisions: {k:,} set aside for collision: {c['base_on_object']:,} with the base overlapping an "
            f"object, {c['every_branch_colliding']:,} with every flip-free branch colliding along the path"
        )
        out.append(
            "collisions: the sweep records a status per placement, not the colliding pair; "
            "the full plans name their nearest pair"
        )
    why0 = c["as_written"]["collision"]
    if why0 is not None:
        out.append(
            "collisions: the problem as written is set aside: "
            + ("its base overlaps an object" if why0 == "base_on_object" else "every flip-free branch collides")
        )
    b = c["best_plan"]
    if b is None:
        out.append("collisions: no placement planned in full, so no clearance along a path")
        return out
    cl = b["clearance"]
    if cl is None or cl["min_clearance_mm"] is None:
        out.append(
            f"collisions: {b['label']} ({b['placement_text']}): no clearance recorded (full plan {b['plan_status']})"
        )
    else:
        out.append(
            f"collisions: {b['label']} ({b['placement_text']}): smallest clearance {cl['min_clearance_mm']:.1f} mm "
            f"in its full plan ({cl['pair']}, {cl['where']}; required {cl['clearance_mm']:g} mm)"
        )
    return out


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
    todo.append(("as written", None, None, np.zeros(5), _scores_dict(base, 0, labels)))
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


def _text(values: np.ndarray, finite: np.ndarray | None = None) -> np.ndarray:
    """Numbers as CSV text (shortest round-trip form), an object array; empty where ``finite`` is
    False."""
    out = np.asarray(values).astype(str).astype(object)
    if finite is not None:
        out[~finite] = ""
    return out


#: Rows of the CSV files formatted at a time (about 40 MB of text objects in memory).
CSV_BLOCK_ROWS = 50_000


def scores_csv(st: PlacementStudy, rows: np.ndarray | None = None, rank: bool = False) -> Iterator[bytes]:
    """``scores.csv`` (every placement, grid order) or, with ``rows`` and ``rank``, ``ranking.csv``
    (the feasible placements best first, with a ``rank`` column), in parts of
    :data:`CSV_BLOCK_ROWS` rows: the columns of :data:`SCORE_COLUMNS`, edge units in the names (m,
    deg, mm), ``status`` and ``best_branch`` by name, empty cells where a value does not exist (an
    infeasible placement's errors and margins, no blocked waypoint).  A sweep may hold millions of
    placements: only one block is formatted at a time."""
    sc, pl = st.sweep.scores, st.sweep.placements
    idx_all = np.arange(len(pl)) if rows is None else np.asarray(rows, dtype=int)
    scale = np.array([GRID_AXES[k][0] for k in GRID_AXES])
    labels = np.array(list(st.branch_labels) + [""], dtype=object)
    names = np.array([PlacementStatus.from_code(c).value for c in range(len(PlacementStatus))], dtype=object)
    yield (",".join((["rank"] if rank else []) + list(SCORE_COLUMNS)) + "\n").encode()
    for a in range(0, len(idx_all), CSV_BLOCK_ROWS):
        idx = idx_all[a : a + CSV_BLOCK_ROWS]
        grid = np.round(pl[idx] / scale, GRID_DIGITS) + 0.0  # -0.0 -> 0.0
        cols = [_text(idx)] + [_text(grid[:, j]) for j in range(grid.shape[1])]
        cols += [
            names[sc.status[idx].astype(int)],
            labels[sc.best_branch[idx].astype(int)],
            _text(sc.feasible_branches[idx]),
        ]
        for v, f in (
            (sc.rms_error_m, 1e3),
            (sc.max_error_m, 1e3),
            (sc.joint_margin_rad, 180.0 / np.pi),
            (sc.singular_margin, 1.0),
        ):
            x = v[idx] * f
            cols.append(_text(x, np.isfinite(x)))
        bw = sc.blocked_waypoint[idx]
        cols.append(_text(bw, bw >= 0))
        if rank:
            cols.insert(0, _text(np.arange(a + 1, a + len(idx) + 1)))
        lines = map(",".join, zip(*(c.tolist() for c in cols)))
        yield ("\n".join(lines) + "\n").encode()


def write_study(st: PlacementStudy, folder: str | Path, with_report: bool = True) -> list[Path]:
    """Write ``summary.json``, ``scores.csv``, ``ranking.csv`` and, with ``with_report``, the report
    (``report.html`` and ``figures/``), whole or not at all."""
    from planner.output import OutputSet

    out = OutputSet(folder)
    summary = st.summary()
    out.add_json("summary.json", summary)
    out.add_bytes("scores.csv", lambda: scores_csv(st))
    out.add_bytes("ranking.csv", lambda: scores_csv(st, st.ranked, rank=True))
    if with_report:
        from planner.report.placement import figures, html

        figs = figures(st)
        for name, data in figs.items():
            out.add_bytes(f"figures/{name}", data)
        out.add_bytes("report.html", html(st, sorted(figs), summary).encode("utf-8"))
    return out.publish()


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
