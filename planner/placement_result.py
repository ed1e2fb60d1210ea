"""What a placement study produced (:class:`PlacementStudy`: the sweep, the ranking, the full
plans, ``summary.json`` and its headline) and what it says about collisions (:func:`collision_lines`);
the pipeline that fills it is :mod:`planner.placement`."""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from models.status import Status
from planner.numbers import headline_mm, round_sig
from planner.plan_result import PlanResult
from planner.provenance import invocation, problem_provenance
from problems.placement.grid import GRID_AXES, PlacementGrid, describe_placement, placement_label
from problems.placement.scores import STATUS_REASONS, ChunkScores, PlacementStatus
from problems.placement.sweep import SweepResult
from problems.problem import Problem

__all__ = [
    "COLLISIONS_WHAT",
    "NO_CELL_NOTE",
    "PAIRS_NOTE",
    "PLAN_STAGE",
    "PlacementPlan",
    "PlacementStudy",
    "StudyStatus",
    "collision_lines",
    "plan_clearance",
    "scores_dict",
]

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
        return scores_dict(self.sweep.scores, i, self.branch_labels)

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
            "baseline": {"label": "as written", **scores_dict(self.baseline, 0, self.branch_labels)},
            "ranking": [
                {"rank": r + 1, "index": int(i), **self.scores_of(int(i))}
                for r, i in enumerate(self.ranked[: max(10, self.grid.top)])
            ],
            "improvement_rms_factor": None if self.improvement is None else round(self.improvement, 4),
            "warnings": self.warnings(),
            "collisions": self.collisions(),
            "plans": [plan_entry(p, self.problem.cell is not None) for p in self.plans],
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


def scores_dict(sc: ChunkScores, i: int, labels: tuple[str, ...]) -> dict[str, Any]:
    """The sweep's scores of placement ``i`` (``summary.json``): status and its reason, best branch
    (by label), feasible branches, RMS and max error (mm), joint margin (deg), singular margin and
    blocked waypoint; None where a value does not exist."""
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


def plan_entry(p: PlacementPlan, with_cell: bool = False) -> dict[str, Any]:
    """A full plan's entry of ``summary.json`` (``plans``), with its clearance when the problem has a cell."""
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
