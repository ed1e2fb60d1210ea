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

:class:`~planner.plan_result.PlanResult` (what a plan produced) lives in :mod:`planner.plan_result`,
the files written from it in :mod:`planner.plan_outputs`, its run record in
:mod:`planner.plan_record`; this module re-exports their public names.  The module prints nothing.
"""

from __future__ import annotations

import time
from dataclasses import replace
from typing import Any
from collections.abc import Callable

import numpy as np

from models.arm import ArmModel
from problems.compensation import CompensationStatus, closed_form, exact, uncompensated
from problems.identify.uncertainty import path_sigma
from problems.posture import BranchStatus, PostureResult, PostureStatus, optimise_postures
from problems.posture.solve import rechoose
from problems.problem import Problem
from problems.timing import (
    JointLimits,
    Trajectory,
    TimingStatus,
    controller_methods,
    get_method,
    time_parametrize,
)
from problems.timing.trajectory import LIMIT_KEYS
from problems.toolpath.feed import FEED_SLOW_TOL, feed_time_law
from problems.toolpath.feed_stretch import FEED_FALLBACK_METHOD
from problems.toolpath.waypoints import ARC_SAGITTA_SHARE

from planner.plan_outputs import figures, output_names, write_outputs
from planner.plan_result import PlanResult, PlanStatus, RunView
from planner.plan_summary import within_limits
from planner.record.columns import WAYPOINT_COLUMNS

#: Slack on the commanded joints' position limits (rad).
COMMAND_LIMIT_TOL = 1e-9


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
    if problem.cut is not None:  # what the predicted cut could not model (plunges, ...)
        res.warnings += list(problem.cut.warnings)
    res.warnings += _posture_warnings(ps)
    _after_posture(res, tick, progress)
    return _set_aside_colliding(res, problem, times, tick, progress)


def _set_aside_colliding(
    res: PlanResult,
    problem: Problem,
    times: dict[str, float],
    tick: Callable[[str, int, int], None],
    progress: Callable[[str, int, int], None] | None,
) -> PlanResult:
    """While the controller's trajectory collides with the cell, re-plan on the next collision-free branch."""
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
    if res.status is not PlanStatus.COLLISION or res.cell is None or res.cell.trajectory is None:
        return False  # a plan without a cell does not import the collision package
    from models.collision import ClearanceStatus

    return res.cell.trajectory.status is not ClearanceStatus.OK


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
    check_command(res.cell, res.exact.q_command, res.posture.best.q, res.posture.chosen)
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
    _compare_cut(res, q, L)
    qc = res.exact.q_command
    res.model_sigma = path_sigma(arm, qc, arm.tcp_wrench(res.exact.q_deflected, L))
    for caveat in (res.model_sigma.warning(), res.model_sigma.load_warning()):
        if caveat:
            res.warnings.append(caveat)
    lo, hi = qc < robot.q_min - COMMAND_LIMIT_TOL, qc > robot.q_max + COMMAND_LIMIT_TOL
    if lo.any() or hi.any():
        k, j = (int(v) for v in np.argwhere(lo | hi)[0])
        res.status = PlanStatus.COMPENSATION_FAILED
        res.reason = (
            f"the compensated command of joint {j + 1} at waypoint {k} is {qc[k, j]:.6g} rad, "
            f"outside its limits [{robot.q_min[j]:.6g}, {robot.q_max[j]:.6g}] rad"
        )


def _compare_cut(res: PlanResult, q: np.ndarray, L: np.ndarray) -> None:
    """With a predicted cut and a ``[cut] stand_in``: the errors the stand-in's commands would leave."""
    cut = res.problem.cut
    if cut is None or cut.stand_in is None:
        return
    from problems.cutting.comparison import compare_stand_in, stand_in_load

    load = res.problem.load
    res.cut_comparison = compare_stand_in(
        res.problem.model, q, load, stand_in_load(load, cut.wrench_base, cut.stand_in, cut.stand_in_frame)
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
                tcp_frame=problem.model.kinematics.tcp,
                tolerance_m=w.tolerance_m,
                path_slack_m=None if w.arc_chord is None else w.arc_chord * (ARC_SAGITTA_SHARE * w.tolerance_m),
                **problem.timing.options(m),
            )
            res.feed[m] = fl
            res.trajectories[m] = fl.trajectory
        else:
            if progress is not None:
                progress(f"timing {m}", 0, 1)
            res.trajectories[m] = time_parametrize(qc, lim, m, problem.timing.dt, **problem.timing.options(m))
            if progress is not None:
                progress(f"timing {m}", 1, 1)
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
        for k in (k for k in LIMIT_KEYS if not within_limits(tr, (k,))):  # limits the method does not enforce
            r = float(np.max(tr.limit_ratio[k]))
            hint = (
                f"; add '{_jerk_limited()}' to timing.methods for a jerk-limited controller trajectory"
                if k == "jerk"
                else ""
            )
            res.warnings.append(
                f"{m}, the controller's trajectory, does not limit {k}: peak {k} ratio {r:.3g} > 1{hint}"
            )


#: A trajectory's distance from the programmed path may exceed the tolerance by this share before
#: the plan warns (the samples' rounding).
PATH_TOL_SLACK = 1e-6
#: Slowed program lines named in a warning (the summary lists them all).
FEED_WARN_LINES = 5


def _feed_warnings(res: PlanResult) -> list[str]:
    """The program lines whose feed the joint limits force down (the controller's law), apart from
    those the stops around them slow; and a trajectory that leaves the path tolerance."""
    fl = res.feed[res.controller]
    if res.problem.program is None:
        return []
    out = []
    w = res.problem.program.waypoints
    if np.isfinite(fl.path_deviation_m) and fl.path_deviation_m > fl.tolerance_m * (1.0 + PATH_TOL_SLACK):
        out.append(
            f"the controller's trajectory ({res.controller}) leaves the path tolerance: a sample's TCP is "
            f"{fl.path_deviation_m * 1e3:.4g} mm from the programmed path, tolerance {fl.tolerance_m * 1e3:.4g} mm "
            "(summary.json program.feed.<method>.path_deviation_mm)"
        )
    if not fl.slowed:
        return out
    worst = fl.slowed_lines(w.line)
    by_limit = fl.slowed_by_limit(w.line)
    n_stops = len(worst) - len(by_limit)
    if by_limit:
        out.append(_held_feed_warning(by_limit, n_stops))
    elif n_stops:
        out.append(
            f"{n_stops} program line(s) stay below {100 * (1 - FEED_SLOW_TOL):.0f} % of F only because of the stops "
            "around them (accelerating out of and into a stop); the joints could cruise at F there "
            "(summary.json program.slowed_lines)"
        )
    return out


#: Per bound kind (``problems.timing.lookahead.BOUND_KINDS``): the robot-file key and the problem
#: file's ``[limits]`` key of that limit (the advice of :func:`_held_feed_warning`).
_LIMIT_KEYS = {"velocity": ("v_max", "velocity"), "acceleration": ("a_max", "acceleration"), "jerk": ("j_max", "jerk")}


def _held_feed_warning(by_limit: dict[int, tuple[float, int, str]], n_stops: int) -> str:
    """The warning of program lines a joint limit holds below F (``FeedLaw.slowed_by_limit``):
    which limit of which joint binds, on how many lines, the slowest lines, and what would let
    the feed reach F (that limit raised, F lowered, and for acceleration or jerk a larger path
    tolerance: the corners rounded wider)."""
    order = sorted(by_limit, key=lambda L: by_limit[L][0])
    binding: dict[tuple[int, str], int] = {}
    for L in order:
        key = (by_limit[L][1], by_limit[L][2])
        binding[key] = binding.get(key, 0) + 1
    which = ", ".join(f"joint {j}'s {kind} limit on {n}" for (j, kind), n in binding.items())
    shown = ", ".join(
        f"line {L}: {100 * by_limit[L][0]:.0f} % (joint {by_limit[L][1]} {by_limit[L][2]})"
        for L in order[:FEED_WARN_LINES]
    )
    more = (
        f" and {len(order) - FEED_WARN_LINES} more (summary.json program.feed.<method>.slowed_by_limit)"
        if len(order) > FEED_WARN_LINES
        else ""
    )
    kinds = [k for k in dict.fromkeys(kind for _, kind in binding) if k in _LIMIT_KEYS]
    advice = (
        f"to reach F raise {'that limit' if len(binding) == 1 else 'those limits'} ("
        + ", ".join(f"{_LIMIT_KEYS[k][0]} in the robot file or [limits] {_LIMIT_KEYS[k][1]}" for k in kinds)
        + "), lower F there"
    )
    if any(k != "velocity" for k in kinds):
        advice += " or allow a larger path tolerance (G64 P) for wider corners"
    text = (
        f"a joint limit holds the feed below {100 * (1 - FEED_SLOW_TOL):.0f} % of F on {len(order)} program "
        f"line(s): {which}; {advice}; slowest (peak TCP speed / F): {shown}{more}"
    )
    if n_stops:
        text += f"; {n_stops} more line(s) are slowed only by what surrounds them (a stop, or a line held down)"
    return text


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
    bad = [k for k in get_method(m).checked_limits if not within_limits(tr, (k,))]
    if bad:
        return (
            f"{m}: {TimingStatus.LIMIT_EXCEEDED.value}: {' and '.join(bad)} ratio above 1 although the "
            f"method reported {tr.status.value} ({tr.reason})"
        )
    return ""


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
