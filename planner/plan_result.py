"""What a plan produced: :class:`PlanResult` (status, reason, the stages' results) and its
:class:`RunView` (the summary and tables computed once), with :class:`PlanStatus`.

The pipeline that fills a :class:`PlanResult` is :func:`planner.plan.plan`; the files written from
it, :mod:`planner.plan_outputs`; its :class:`~planner.record.RunRecord`, :mod:`planner.plan_record`.
The module prints nothing.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from models.arm import ArmModel
from models.errors import InfeasibleError, UnreachableError
from models.status import Status
from models.symbolic import directional_stiffness
from problems.compensation import CompensationResult, uncompensated
from problems.posture import BranchResult, PostureResult
from problems.problem import Problem
from problems.timing import Trajectory

from planner.provenance import invocation, problem_provenance

if TYPE_CHECKING:
    from planner.record import RunRecord

__all__ = ["PlanResult", "PlanStatus", "RunView"]


class PlanStatus(Status):
    """Outcome of :func:`plan`."""

    OK = "ok"
    UNREACHABLE = "unreachable"  # a waypoint has no IK solution
    NO_BRANCH = "no_branch"  # no branch along the whole path (flip, limits)
    SOLVER_FAILED = "solver_failed"  # the posture NLP failed on every branch
    COMPENSATION_FAILED = "compensation_failed"  # exact compensation failed or leaves the limits
    TIMING_FAILED = "timing_failed"  # a time parametrisation failed or breaks a limit
    COLLISION = "collision"  # every branch, or the controller's trajectory, closer than the cell's clearance


_ERROR_CLASS = {PlanStatus.UNREACHABLE: UnreachableError}


@dataclass
class PlanResult:
    """Everything a plan produced.

    Attributes
    ----------
    status : PlanStatus
    reason : str
        One line; names the stage, branch, waypoint or joint that failed.
    problem : Problem
    posture : PostureResult or None
    before, closed, exact : CompensationResult or None
        Of the chosen posture: uncompensated, closed-form and exact compensation.
    trajectories : dict method -> Trajectory
        Of the commanded path ``exact.q_command``.
    controller : str or None
        The method whose trajectory the controller runs (``trajectory.csv``).
    warnings : list of str
    stage_times_s : dict
    dynamic : planner.dynamic.DynamicStage or None
        The dynamic-compensation stage (``[timing] dynamic = true``): the motor-side command is
        then the controller's trajectory, its link side and predicted TCP errors are here.
        Wall time of each stage, s.
    made : dict
        When and by which command line the result was made (``command_line``, ``argv``,
        ``date_utc``; :func:`planner.provenance.invocation`): the summary's provenance.
    feed : dict method -> problems.toolpath.feed.FeedLaw
        For a program path: each method's feed law (the feed reached, the slowed moves, the
        program move of every sample); empty otherwise.
    """

    status: PlanStatus
    reason: str
    problem: Problem
    posture: PostureResult | None = None
    before: CompensationResult | None = None
    closed: CompensationResult | None = None
    exact: CompensationResult | None = None
    trajectories: dict[str, Trajectory] = field(default_factory=dict)
    controller: str | None = None
    warnings: list[str] = field(default_factory=list)
    stage_times_s: dict[str, float] = field(default_factory=dict)
    made: dict[str, Any] = field(default_factory=invocation)
    dynamic: Any = None
    feed: dict[str, Any] = field(default_factory=dict)
    #: The predicted sigma of the compensated TCP along the path and where the model extrapolates
    #: (:class:`problems.identify.uncertainty.PathSigma`), once the exact compensation succeeded.
    model_sigma: Any = None
    #: The cell check (:class:`planner.cell_check.CellCheck`) when the problem has a ``[cell]``.
    cell: Any = None
    #: A predicted cut with a ``[cut] stand_in``: the TCP errors its commands would leave under the
    #: predicted load (:class:`problems.cutting.comparison.StandInComparison`), else None.
    cut_comparison: Any = None

    @property
    def ok(self) -> bool:
        return self.status is PlanStatus.OK

    @property
    def branch(self) -> BranchResult:
        """The chosen branch (raises if the plan failed before choosing one)."""
        if self.posture is None or self.posture.chosen is None:
            raise InfeasibleError(f"plan '{self.problem.name}': no branch chosen ({self.reason})")
        return self.posture.best

    @property
    def positions(self) -> np.ndarray:
        return self.problem.positions

    @property
    def wrench(self) -> np.ndarray:
        return self.problem.wrench

    @property
    def robot(self):
        return self.problem.robot

    def raise_for_status(self) -> PlanResult:
        """Raise the matching CompplanError unless the plan succeeded; returns self."""
        if self.ok:
            return self
        cls = _ERROR_CLASS.get(self.status, InfeasibleError)
        raise cls(f"plan '{self.problem.name}' ({self.problem.source}): {self.status.value}: {self.reason}")

    # ------------------------------------------------------------------ tables
    def waypoint_table(self) -> np.ndarray:
        """Rows of ``waypoints.csv`` (see :data:`~planner.record.columns.WAYPOINT_COLUMNS`)."""
        assert self.exact is not None and self.closed is not None and self.before is not None
        P = self.positions
        n = len(P)
        seg = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))]
        s = seg / seg[-1] if seg[-1] > 0 else seg
        model = self.problem.model.kinematics
        q = self.branch.q
        Cs = model.C(q) if n > 1 else model.C(q[0])[None]
        k = np.stack([directional_stiffness(Cs, np.eye(3)[i]) for i in range(3)], axis=1)
        return np.hstack(
            [
                np.arange(n)[:, None],
                s[:, None],
                P,
                q,
                self.exact.q_command,
                self.closed.q_command,
                self.before.error_m,
                self.closed.error_m,
                self.exact.error_m,
                k,
            ]
        )

    def branch_errors(self) -> dict[int, tuple[np.ndarray, np.ndarray]]:
        """Per branch index: the load-induced TCP error norm (m, shape (N,)) at its analytic
        posture (NaN where the branch has none) and at its optimised one, from the deflected
        equilibrium of the arm model (``branches.csv``; the summary's equilibrium errors)."""
        assert self.posture is not None
        arm, n = self.problem.model, self.problem.n
        L = self.problem.load.rows(n)
        out = {}
        for b, r in self.posture.branches.items():
            ana = uncompensated(arm, r.q_analytic, L).error_norm_m if r.q_analytic is not None else np.full(n, np.nan)
            out[b] = (ana, uncompensated(arm, r.q, L).error_norm_m)
        return out

    def branch_table(
        self,
        errors: Mapping[int, tuple[np.ndarray, np.ndarray]] | None = None,
    ) -> tuple[list[str], np.ndarray]:
        """``branches.csv``: per feasible branch, the load-induced TCP error norm (m) per
        waypoint at the analytic posture (NaN where the branch has none) and at the optimised
        one, from the deflected equilibrium of the joint-compliance model (``errors``: those of
        :meth:`branch_errors`, when the caller has them)."""
        assert self.posture is not None
        errors = self.branch_errors() if errors is None else errors
        cols, data = ["k"], [np.arange(self.problem.n, dtype=float)]
        for b in sorted(self.posture.branches):
            r = self.posture.branches[b]
            cols += [f"{r.label}_analytic_m", f"{r.label}_optimised_m"]
            data += list(errors[b])
        return cols, np.stack(data, axis=1)

    def view(self) -> RunView:
        """The plan's summary and tables, computed once: what ``summary.json``, the CSV files,
        the command line's printout and the report show (:class:`RunView`).

        Raises
        ------
        CompplanError
            If the plan failed (as :meth:`raise_for_status`).
        """
        self.raise_for_status()
        errors = self.branch_errors()
        cols, rows = self.branch_table(errors)
        stage = self.dynamic
        dyn = stage.series(self.problem.model) if stage is not None and stage.link is not None else None
        cut = None
        if self.problem.cut is not None:
            from planner.plan_cut import cut_rows

            cut = cut_rows(self)
        return RunView(self, self.summary(errors), self.waypoint_table(), cols, rows, dyn, cut)

    # ------------------------------------------------------------------ summary
    def summary(self, errors: Mapping[int, tuple[np.ndarray, np.ndarray]] | None = None) -> dict[str, Any]:
        """The content of ``summary.json`` (:func:`planner.plan_summary.plan_summary`). Each call
        hashes the inputs and solves the equilibria again: build a plan's summary once
        (:meth:`view`)."""
        from planner.plan_summary import plan_summary

        return plan_summary(self, errors)

    def record(self, folder: str | Path, view: RunView | None = None) -> RunRecord:
        """The run record of this plan, its output folder ``folder``
        (:func:`planner.plan_record.record_from_plan`; ``view``: the plan's :meth:`view`, when the
        caller has it): what the report reads, the same as the folder reader gives for the files
        :func:`planner.plan_outputs.write_outputs` writes."""
        from planner.plan_record import record_from_plan

        return record_from_plan(self, folder, view)

    def provenance(self) -> dict[str, Any]:
        """The ``provenance`` block: version, command line and date (when the result was made),
        and the input files (problem, arm model) with their SHA-256."""
        return problem_provenance(self.problem, self.made)


@dataclass(frozen=True)
class RunView:
    """A successful plan's outputs, computed once (:meth:`PlanResult.view`) and passed to
    everything that shows the run: ``write_outputs``, the command line's printout and the
    report (:func:`planner.plan_record.record_from_plan`).

    Attributes
    ----------
    result : PlanResult
    summary : dict
        The content of ``summary.json`` (:meth:`PlanResult.summary`).
    waypoints : ndarray, shape (N, len(WAYPOINT_COLUMNS))
        Rows of ``waypoints.csv``.
    branch_columns : list of str
    branches : ndarray, shape (N, len(branch_columns))
        Columns and rows of ``branches.csv`` (m).
    dynamic : (list of str, ndarray) or None
        Columns and rows of ``dynamic.csv`` (a plan with dynamic compensation), else None.
    """

    result: PlanResult
    summary: dict[str, Any]
    waypoints: np.ndarray
    branch_columns: list[str]
    branches: np.ndarray
    dynamic: tuple[list[str], np.ndarray] | None = None
    #: Rows of ``cut.csv`` (a predicted cut, :func:`planner.plan_cut.cut_rows`), else None.
    cut: np.ndarray | None = None

    @property
    def model(self) -> ArmModel:
        """The arm model the plan was made with (its ``kinematics`` built once)."""
        return self.result.problem.model
