"""``compplan plan``: problem -> branches -> posture NLP -> choice -> exact compensation -> timing.

Pipeline (every stage returns a status; the first failure stops the plan with a
:class:`PlanStatus` and a one-line reason, and :meth:`PlanResult.raise_for_status`
turns it into the matching :class:`~models.errors.CompplanError`):

1. **Posture** (:func:`problems.posture.optimise_postures`): for every IK branch
   that reaches the whole path, the stiffness-optimal posture (NLP), then the
   branch of least load-induced error.
2. **Compensation** (:func:`problems.compensation.exact`): the optimised posture
   ``q`` is the *deflected* pose that must land on the waypoints, so the command
   is ``q_c = q - K^-1 J(q)^T F``; its deflected equilibrium is solved and
   checked to put the TCP on every waypoint (residual below
   :data:`models.constants.EXACT_COMPENSATION_TOL`).  The uncompensated and
   closed-form (paper) errors of the same posture are reported alongside.
3. **Timing** (:func:`problems.timing.time_parametrize`) of the *commanded* path
   ``q_c`` at the controller period, by default with TOPP-RA (time-optimal under
   velocity and acceleration limits) and ``jerk_optimal`` (time-optimal under
   velocity, acceleration *and* jerk limits: an NLP over the path-velocity
   profile, :mod:`problems.timing.jerk_optimal`); Ruckig (jerk-limited, global
   bounds on the path parameter) on request.  All time the same geometric path
   (a cubic spline through the commanded waypoints): TOPP-RA's jerk is not
   limited, so it is reported and written to ``trajectory_toppra.csv`` as the
   time-optimal reference but is not what the controller runs; the jerk-limited
   trajectory (``jerk_optimal``, else Ruckig) is ``trajectory.csv``.  Every limit is checked
   on the sampled trajectory and a method only succeeds when all the limits it
   enforces hold (peak ratio <= 1).

The module prints nothing.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any
from collections.abc import Callable, Mapping

import numpy as np

from models.arm import ArmModel
from models.errors import InfeasibleError, UnreachableError
from models.status import Status
from models.symbolic import directional_stiffness
from problems.compensation import CompensationResult, CompensationStatus, closed_form, exact, uncompensated
from problems.identify.uncertainty import path_sigma
from problems.posture import BranchResult, BranchStatus, PostureResult, PostureStatus, optimise_postures
from problems.posture.solve import rechoose
from problems.problem import Problem

from planner.output import TRAJECTORY_COLUMNS as OUTPUT_TRAJECTORY_COLUMNS
from planner.output import OutputSet
from planner.provenance import invocation, problem_provenance
from problems.timing import (
    LIMIT_RATIO_TOL,
    JointLimits,
    Trajectory,
    TimingStatus,
    controller_methods,
    get_method,
    time_parametrize,
)
from problems.timing.trajectory import LIMIT_KEYS
from problems.toolpath.feed import FEED_FALLBACK_METHOD, FEED_SLOW_TOL, feed_time_law

#: Columns of ``waypoints.csv`` (see docs/cli.md): k, path parameter s, target position,
#: planned (deflected) joints qt, exact command qc, closed-form command qf, TCP errors
#: before / after closed form / after exact (m, base frame), directional stiffness (N/m).
WAYPOINT_COLUMNS = (
    ["k", "s", "x", "y", "z"]
    + [f"qt{i}" for i in range(1, 7)]
    + [f"qc{i}" for i in range(1, 7)]
    + [f"qf{i}" for i in range(1, 7)]
    + ["ebx", "eby", "ebz", "efx", "efy", "efz", "eex", "eey", "eez", "kx", "ky", "kz"]
)
#: Columns of ``path.csv``.
PATH_COLUMNS = ["x", "y", "z"] + [f"q{i}" for i in range(1, 7)]
#: Columns ``path.csv`` adds for a program path: the programmed feed of the move ending at the
#: waypoint (mm/min, nan for rapids and waypoint 0), its program line, 1 for a rapid.
PROGRAM_PATH_COLUMNS = ["feed_mm_min", "line", "rapid"]
#: Columns ``trajectory*.csv`` adds for a program path: the program line of the move each sample runs,
#: and the waypoint (0-based row of ``path.csv``) that move ends at.
PROGRAM_TRAJECTORY_COLUMNS = ["line", "waypoint"]
#: Columns of ``trajectory*.csv``.
TRAJECTORY_COLUMNS = OUTPUT_TRAJECTORY_COLUMNS
#: Slack on the commanded joints' position limits (rad).
COMMAND_LIMIT_TOL = 1e-9


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
        """Rows of ``waypoints.csv`` (see :data:`WAYPOINT_COLUMNS`)."""
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
        return RunView(self, self.summary(errors), self.waypoint_table(), cols, rows, dyn)

    # ------------------------------------------------------------------ summary
    def summary(self, errors: Mapping[int, tuple[np.ndarray, np.ndarray]] | None = None) -> dict[str, Any]:
        """The content of ``summary.json`` (:func:`planner.plan_summary.plan_summary`). Each call
        hashes the inputs and solves the equilibria again: build a plan's summary once
        (:meth:`view`)."""
        from planner.plan_summary import plan_summary

        return plan_summary(self, errors)

    def provenance(self) -> dict[str, Any]:
        """The ``provenance`` block: version, command line and date (when the result was made),
        and the input files (problem, arm model) with their SHA-256."""
        return problem_provenance(self.problem, self.made)


@dataclass(frozen=True)
class RunView:
    """A successful plan's outputs, computed once (:meth:`PlanResult.view`) and passed to
    everything that shows the run: ``write_outputs``, the command line's printout and the
    report (:func:`planner.report.run_from_plan`).

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

    @property
    def model(self) -> ArmModel:
        """The arm model the plan was made with (its ``kinematics`` built once)."""
        return self.result.problem.model


def _within(tr: Trajectory, keys: tuple[str, ...]) -> bool:
    return all(
        np.all(np.isfinite(tr.limit_ratio[k])) and float(np.max(tr.limit_ratio[k])) <= 1.0 + LIMIT_RATIO_TOL
        for k in keys
    )


# --------------------------------------------------------------------------------------
# The pipeline
# --------------------------------------------------------------------------------------

_POSTURE_TO_PLAN = {
    PostureStatus.UNREACHABLE: PlanStatus.UNREACHABLE,
    PostureStatus.NO_BRANCH: PlanStatus.NO_BRANCH,
    PostureStatus.SOLVER_FAILED: PlanStatus.SOLVER_FAILED,
    PostureStatus.COLLISION: PlanStatus.COLLISION,
}


def plan(
    problem: Problem,
    verbose: bool = False,
    optimise: bool = True,
    progress: Callable[[str, int, int], None] | None = None,
) -> PlanResult:
    """Plan a problem: posture, exact compensation, time parametrisation.

    Parameters
    ----------
    problem : Problem
        With its arm model (``problem.model``) and load (``problem.load``).
    verbose : bool
        IPOPT output on.
    optimise : bool
        False: analytic postures only (branch choice without the NLP).
    progress : callable, optional
        ``progress(stage, done, total)`` at each stage (``"posture"``, ``"compensation"``) and, for a
        program path, after each stretch timed (``"timing <method>"``); the CLI draws bars from it.

    Returns
    -------
    PlanResult
        Its status says whether (and where) the plan failed; it never raises for an
        infeasible problem (see :meth:`PlanResult.raise_for_status`).
    """
    times: dict[str, float] = {}
    t0 = time.perf_counter()
    arm = problem.model
    if problem.arm is None:  # one model object for the whole run (its kinematics built once)
        problem = replace(problem, arm=arm)
    ik = arm.ik
    times["model_s"] = time.perf_counter() - t0

    tick = progress or (lambda stage, done, total: None)
    tick("posture", 0, 1)
    t0 = time.perf_counter()
    geom = spec = None
    if problem.cell is not None:
        from planner.cell_check import cell_geometry
        from problems.posture.clearance import clearance_spec

        geom = cell_geometry(problem.robot, problem.cell)
        spec = clearance_spec(geom)
    ps = optimise_postures(
        arm,
        problem.task(),
        problem.home_q,
        problem.solver,
        verbose,
        model=arm.kinematics,
        ik=ik,
        optimise=optimise,
        clearance=spec,
    )
    times["posture_s"] = time.perf_counter() - t0
    tick("posture", 1, 1)
    res = PlanResult(PlanStatus.OK, "", problem, ps, stage_times_s=times)
    if geom is not None and ps.status in (PostureStatus.OK, PostureStatus.SOLVER_FAILED) and ps.branches:
        _cell_branches(res, geom, optimise)  # failed branches too: the NLP may have failed on the cell
        ps = res.posture
    if not ps.ok:
        res.status, res.reason = _POSTURE_TO_PLAN[ps.status], ps.reason
        return res
    res.warnings += _posture_warnings(ps)
    _after_posture(res, tick, progress)
    set_aside: list[str] = []
    while _trajectory_collides(res):  # the next collision-free branch, if there is one
        assert res.posture is not None and res.cell is not None and res.cell.trajectory is not None
        ps, b = res.posture, res.posture.chosen
        assert b is not None
        why = f"its controller's trajectory ({res.controller}): {res.cell.trajectory.reason}"
        branches = dict(ps.branches)
        branches[b] = replace(branches[b], status=BranchStatus.COLLISION, reason=why)
        res.cell.branches[b] = res.cell.trajectory
        nxt = rechoose(replace(ps, branches=branches))
        if not nxt.ok:
            res.reason += (
                f"; every other branch was set aside too ({len(set_aside)} for their trajectories, the rest at "
                "their waypoints: see the branch table)"
            )
            break
        set_aside.append(f"branch {ps.labels[b]} set aside: {why}")
        check = replace(res.cell, waypoints=res.cell.branches[nxt.chosen], trajectory=None, trajectory_method=None)
        res = PlanResult(PlanStatus.OK, "", problem, nxt, stage_times_s=times)
        res.cell = check
        res.warnings += _posture_warnings(nxt) + set_aside
        _after_posture(res, tick, progress)
    return res


def _trajectory_collides(res: PlanResult) -> bool:
    """Whether the plan failed only because the controller's trajectory meets the cell."""
    from models.collision import ClearanceStatus

    return (
        res.status is PlanStatus.COLLISION
        and res.cell is not None
        and res.cell.trajectory is not None
        and res.cell.trajectory.status is not ClearanceStatus.OK
    )


def _after_posture(
    res: PlanResult, tick: Callable[[str, int, int], None], progress: Callable[[str, int, int], None] | None
) -> None:
    """Compensation, timing, dynamic compensation and the trajectory's cell check of the chosen
    branch (each stage only if the ones before succeeded)."""
    problem, times = res.problem, res.stage_times_s
    tick("compensation", 0, 1)
    t0 = time.perf_counter()
    _compensate(res)
    times["compensation_s"] = time.perf_counter() - t0
    tick("compensation", 1, 1)
    if not res.ok:
        return
    if problem.n < 2:
        res.warnings.append("single waypoint: nothing to time-parametrise")
        if res.cell is not None:
            _cell_trajectory(res)
        return
    t0 = time.perf_counter()
    _time(res, progress)
    times["timing_s"] = time.perf_counter() - t0
    if res.ok and problem.timing.dynamic:
        t0 = time.perf_counter()
        _dynamic(res)
        times["dynamic_compensation_s"] = time.perf_counter() - t0
    if res.ok and res.cell is not None:
        _cell_trajectory(res)


def _cell_branches(res: PlanResult, geom: Any, optimise: bool) -> None:
    """Every usable branch checked against the cell at every waypoint, the choice made again
    among the collision-free ones (:func:`planner.cell_check.choose_collision_free`); the
    posture stage is solved once more in empty space to say what the cell costs."""
    from planner.cell_check import choose_collision_free

    t0 = time.perf_counter()
    assert res.posture is not None
    p = res.problem
    free = optimise_postures(
        p.model, p.task(), p.home_q, p.solver, False, model=p.model.kinematics, ik=p.model.ik, optimise=optimise
    )
    res.stage_times_s["posture_empty_space_s"] = time.perf_counter() - t0
    res.posture, res.cell = choose_collision_free(p, res.posture, geom, free)
    res.stage_times_s["cell_branches_s"] = time.perf_counter() - t0


def _cell_trajectory(res: PlanResult) -> None:
    """The chosen command at the waypoints and the controller's trajectory at every sample
    against the cell; closer than the clearance: status COLLISION with the time and the pair."""
    from planner.cell_check import check_command, check_trajectory
    from models.collision import ClearanceStatus

    assert res.exact is not None and res.posture is not None
    t0 = time.perf_counter()
    check_command(res.cell, res.exact.q_command, res.posture.best.q)
    clearance = res.cell.geometry.clearance
    if res.cell.deflection_m > clearance:
        res.warnings.append(
            f"cell: the load-induced deflection moves the arm by up to {res.cell.deflection_m * 1e3:.3g} mm "
            f"({res.cell.deflection_where}), more than the clearance {clearance * 1e3:.3g} mm: the waypoints are "
            "checked at both poses, the trajectory at the commanded one only"
        )
    if res.controller is not None and res.controller in res.trajectories:
        tr = res.trajectories[res.controller]
        c = check_trajectory(res.cell, res.controller, tr.t, tr.q)
        if c.status is not ClearanceStatus.OK:
            res.status = PlanStatus.COLLISION
            res.reason = f"the controller's trajectory ({res.controller}) comes closer than the clearance: {c.reason}"
    res.stage_times_s["cell_trajectory_s"] = time.perf_counter() - t0


def _dynamic(res: PlanResult) -> None:
    """Motor-side commands for the inertial torques (``[timing] dynamic = true``): the controller's
    trajectory becomes the command of :func:`planner.dynamic.dynamic_stage`; the link side is kept."""
    from planner.dynamic import DynamicStageStatus, dynamic_stage

    problem = res.problem
    assert res.exact is not None and res.controller is not None
    m = res.controller
    if not get_method(m).enforces_jerk:
        res.status, res.reason = (
            PlanStatus.TIMING_FAILED,
            (
                f"timing.dynamic needs a jerk-limited controller trajectory (the motor-side command follows "
                f"the accelerations), but the controller's method is {m}; add '{_jerk_limited()}' to timing.methods"
            ),
        )
        return
    if not problem.robot.has_masses:
        res.status, res.reason = (
            PlanStatus.TIMING_FAILED,
            (f"timing.dynamic: robot {problem.robot.name} has no link masses (robot file keys mass, com, inertia)"),
        )
        return
    lim = JointLimits(problem.limits.velocity, problem.limits.acceleration, problem.limits.jerk)
    stage = dynamic_stage(
        problem.model, res.exact.q_deflected, lim, problem.timing.dt, m, problem.timing.options(m), problem.load
    )
    res.dynamic = stage
    if stage.status is not DynamicStageStatus.OK or stage.command is None:
        res.status, res.reason = PlanStatus.TIMING_FAILED, f"dynamic compensation: {stage.reason}"
        return
    res.trajectories[m] = stage.command


def _posture_warnings(ps: PostureResult) -> list[str]:
    """Failed branches, and a chosen optimum that rests on a singularity guard."""
    out = [f"branch {r.label}: {r.status.value}: {r.reason}" for r in ps.branches.values() if not r.status.usable]
    if ps.best.active_guards:
        out.append(
            f"chosen branch {ps.best.label}: the optimum rests on its singularity guard ("
            + ", ".join(f"{k} at {v} waypoint(s)" for k, v in ps.best.active_guards.items())
            + "): the model's load error keeps falling towards the singularity, where it is not credible"
        )
    return out


def _compensate(res: PlanResult) -> None:
    """Uncompensated, closed-form and exact compensation of the chosen posture (sets the status
    when the exact one fails or leaves the joint limits)."""
    problem, arm, robot = res.problem, res.problem.model, res.problem.robot
    assert res.posture is not None
    q = res.posture.best.q
    L = problem.load.rows(problem.n)
    res.before = uncompensated(arm, q, L)
    res.closed = closed_form(arm, q, L)
    res.exact = exact(arm, q, L)
    res.warnings += arm.caveats(res.exact.q_deflected, L)
    res.warnings += _base_frame_caveat(arm, q, L)
    if res.exact.status is not CompensationStatus.OK:
        res.status = PlanStatus.COMPENSATION_FAILED
        res.reason = f"exact compensation of branch {res.posture.best.label}: {res.exact.reason}"
        return
    qc = res.exact.q_command
    res.model_sigma = path_sigma(arm, qc, arm.tcp_wrench(res.exact.q_deflected, L))
    extrapolates = res.model_sigma.warning()
    if extrapolates:
        res.warnings.append(extrapolates)
    lo, hi = qc < robot.q_min - COMMAND_LIMIT_TOL, qc > robot.q_max + COMMAND_LIMIT_TOL
    if lo.any() or hi.any():
        k, j = (int(v) for v in np.argwhere(lo | hi)[0])
        res.status = PlanStatus.COMPENSATION_FAILED
        res.reason = (
            f"the compensated command of joint {j + 1} at waypoint {k} is {qc[k, j]:.6g} rad, "
            f"outside its limits [{robot.q_min[j]:.6g}, {robot.q_max[j]:.6g}] rad"
        )


def _base_frame_caveat(arm: ArmModel, q: np.ndarray, L: np.ndarray) -> list[str]:
    """A model identified from unregistered data leaves the parameters that alias with the
    registration and the measured point at zero: the plan is not exact in the base frame there."""
    if arm.registered:  # nothing aliases (and problems.identify, with scipy.stats, is not imported)
        return []
    from problems.identify import alias_effect_m, unobservable_in_base

    names = unobservable_in_base(arm)
    if not names:
        return []
    size = alias_effect_m(arm, names, q, arm.tcp_wrench(q, L))
    worst = max(names, key=lambda n: size[n])
    return [
        f"the arm model was identified from unregistered data: {', '.join(names)} cannot be told apart from "
        "the registration or the measured point and are held at their nominal values (zero for DH errors), "
        "so the commands are exact in the "
        f"measurement frame, not in the base frame (the largest, {worst}, moves the TCP by up to "
        f"{size[worst] * 1e3:.3g} mm per typical magnitude on this path); identify from registered data "
        "(--registered) to plan exactly in the base frame"
    ]


def _time(res: PlanResult, progress: Callable[[str, int, int], None] | None = None) -> None:
    """Time the commanded path with every requested method and check each trajectory."""
    problem = res.problem
    assert res.exact is not None
    qc = res.exact.q_command
    lim = JointLimits(problem.limits.velocity, problem.limits.acceleration, problem.limits.jerk)
    for m in problem.timing.methods:
        t1 = time.perf_counter()
        if problem.program is not None:  # at the programmed feed, stretch by stretch between stops
            w = problem.program.waypoints
            fl = feed_time_law(
                qc,
                problem.positions,
                w.feed_m_s,
                lim,
                problem.timing.dt,
                m,
                w.stop,
                w.dwell_s,
                progress,
                **problem.timing.options(m),
            )
            res.feed[m] = fl
            res.trajectories[m] = fl.trajectory
        else:
            res.trajectories[m] = time_parametrize(qc, lim, m, problem.timing.dt, **problem.timing.options(m))
        res.stage_times_s[f"timing_{m}_s"] = time.perf_counter() - t1
    for m, fl in res.feed.items():
        if fl.n_substituted:
            res.warnings.append(
                f"{m} failed on {fl.n_substituted} stretch(es) between stops; {FEED_FALLBACK_METHOD} timed them "
                f"(summary.json timing.{m}.reason names the first and why)"
            )
    ranked = controller_methods(res.trajectories)
    if not ranked:  # a problem file names one (check_timing); a Problem built in code may not
        res.status = PlanStatus.TIMING_FAILED
        res.reason = f"none of the timing methods {list(res.trajectories)} can be the controller's trajectory"
        return
    res.controller = ranked[0]
    if res.controller in res.feed:
        res.warnings += _feed_warnings(res)
    for m, tr in res.trajectories.items():
        failure = _trajectory_failure(res, m, tr)
        if failure:
            res.status, res.reason = PlanStatus.TIMING_FAILED, failure
            return
        if m != res.controller:  # a reference beside the controller's: its unenforced limits are in the summary
            continue
        for k in (k for k in LIMIT_KEYS if not _within(tr, (k,))):  # limits the method does not enforce
            r = float(np.max(tr.limit_ratio[k]))
            hint = (
                f"; add '{_jerk_limited()}' to timing.methods for a jerk-limited controller trajectory"
                if k == "jerk"
                else ""
            )
            res.warnings.append(
                f"{m}, the controller's trajectory, does not limit {k}: peak {k} ratio {r:.3g} > 1{hint}"
            )


#: Slowed program lines named in a warning (the summary lists them all).
FEED_WARN_LINES = 5


def _feed_warnings(res: PlanResult) -> list[str]:
    """The program lines whose feed the joint limits force down (the controller's law)."""
    fl = res.feed[res.controller]
    if not fl.slowed or res.problem.program is None:
        return []
    worst = fl.slowed_lines(res.problem.program.waypoints.line)
    order = sorted(worst, key=lambda L: worst[L])
    shown = ", ".join(f"line {L}: {100 * worst[L]:.0f} %" for L in order[:FEED_WARN_LINES])
    more = (
        f" and {len(order) - FEED_WARN_LINES} more (summary.json program.slowed_lines)"
        if len(order) > FEED_WARN_LINES
        else ""
    )
    return [
        f"the joint limits (or the stops around them) keep the feed below {100 * (1 - FEED_SLOW_TOL):.0f} % of F on "
        f"{len(order)} program line(s), peak TCP speed as a fraction of F: {shown}{more}"
    ]


def _jerk_limited() -> str:
    """The registered jerk-limited method the controller prefers (for advice in messages)."""
    return next((m for m in controller_methods() if get_method(m).enforces_jerk), "a jerk-limited method")


def _trajectory_failure(res: PlanResult, m: str, tr: Trajectory) -> str:
    """Why trajectory ``tr`` of method ``m`` fails (empty if it does not): its own status, a limit
    it enforces, or a joint position limit between waypoints (the spline may overshoot)."""
    robot = res.problem.robot
    if tr.status is TimingStatus.OK and tr.q.size:
        out = (tr.q < robot.q_min - COMMAND_LIMIT_TOL) | (tr.q > robot.q_max + COMMAND_LIMIT_TOL)
        if out.any():
            i, j = (int(v) for v in np.argwhere(out)[0])
            return (
                f"{m}: joint {j + 1} reaches {tr.q[i, j]:.6g} rad at t = {tr.t[i]:.4g} s, "
                f"outside its position limits [{robot.q_min[j]:.6g}, {robot.q_max[j]:.6g}] rad "
                "(the interpolating spline overshoots between waypoints)"
            )
    if tr.status is not TimingStatus.OK:
        return f"{m}: {tr.status.value}: {tr.reason}"
    bad = [k for k in get_method(m).checked_limits if not _within(tr, (k,))]
    if bad:
        return (
            f"{m}: {TimingStatus.LIMIT_EXCEEDED.value}: {' and '.join(bad)} ratio above 1 although the "
            f"method reported {tr.status.value} ({tr.reason})"
        )
    return ""


# --------------------------------------------------------------------------------------
# Outputs
# --------------------------------------------------------------------------------------


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
    from planner.report.run import run_from_plan

    return quick_figures(run_from_plan(res, Path("."), view))


#: Extra columns of ``trajectory.csv`` with dynamic compensation: the planned link side, rad.
LINK_COLUMNS = [f"ql{i}" for i in range(1, 7)]


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
            np.column_stack([res.positions, res.exact.q_command, w.feed_m_s * 6e4]),
            np.column_stack([w.line, w.rapid]),
        )
    out.add_csv("waypoints.csv", WAYPOINT_COLUMNS, view.waypoints)
    out.add_csv("branches.csv", view.branch_columns, view.branches)
    for m, tr in res.trajectories.items():
        name = "trajectory.csv" if m == res.controller else f"trajectory_{m}.csv"
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
    for name, data in (extra or {}).items():
        out.add_bytes(name, data)
    out.publish()
    return summary


def output_names(res: PlanResult, with_figures: bool = True) -> list[str]:
    """Names of the files :func:`write_outputs` writes for ``res``."""
    names = ["summary.json", "path.csv", "waypoints.csv", "branches.csv"]
    names += ["trajectory.csv" if m == res.controller else f"trajectory_{m}.csv" for m in res.trajectories]
    names += ["dynamic.csv"] if res.dynamic is not None and res.dynamic.link is not None else []
    if with_figures:
        names += ["branches.png"] + (["trajectory.png"] if res.trajectories else [])
    return names


__all__ = [
    "PlanResult",
    "PlanStatus",
    "RunView",
    "WAYPOINT_COLUMNS",
    "figures",
    "output_names",
    "plan",
    "write_outputs",
]
