"""The posture stage: every feasible IK branch's NLP solved, verified, and the best chosen.

:func:`optimise_postures` runs the whole stage for a path (warm starts, one IPOPT solve,
Gauss-Newton polish and verification per branch, the choice); :func:`optimal_pose` is the
single-pose query; :func:`analyse_freedom` says what the NLP can choose beyond the branch,
and :func:`branch_signs` gives the singularity-factor signs a branch keeps.  Never raises
for infeasible tasks: the result's status and reason say what failed.  Prints nothing.
"""

from __future__ import annotations

from typing import Any

import math
import time

import numpy as np

from models.arm import ArmModel
from models.ik import IK_REASONS, IKSolver, IKStatus, ik_solver
from models.robot import Robot
from models.symbolic import KinematicModel
from problems.path import default_branch, poses
from problems.posture.task import (
    COST_SCALE,
    DEFAULT_SCAN,
    DEGENERATE_ANGLE_TOL_RAD,
    DEGENERATE_OFFSET_TOL_M,
    GUARD_ACTIVE_TOL,
    IPOPT_OK,
    BranchResult,
    BranchStatus,
    OrientationRule,
    PostureResult,
    PostureStatus,
    PostureTask,
    SolverSettings,
)
from problems.posture import dense
from problems.posture.clearance import (
    CLEARANCE_MAX_NODES,
    CLEARANCE_TOL_M,
    NLP_MAX_PENETRATION_M,
    ClearanceSpec,
)
from problems.posture.clearance_active import (
    MAX_RESOLVES,
    clearance_margin,
    closest_pair_words,
    depth_margin,
    pair_depth_margins,
    posed_at,
    unposed_violations,
)
from problems.posture.transcription import PostureNLP, get_nlp
from problems.posture.verification import guard_bounds, verify
from problems.posture.warm_start import WarmStarts, onto_model_geometry, linear_error, warm_starts

# --------------------------------------------------------------------------------------
# What can be chosen
# --------------------------------------------------------------------------------------


def analyse_freedom(robot: Robot, rule: OrientationRule) -> tuple[str, str]:
    """What the NLP can choose beyond the branch.

    Parameters
    ----------
    robot : Robot
        Its tool (``tcp2flange``, flange frame, m) decides whether the free rotation is
        degenerate (TCP on the joint-6 axis and tool axis along it).
    rule : OrientationRule

    Returns
    -------
    kind : {"none", "degenerate", "free"}
    note : str
        One sentence for the summary.
    """
    if rule is OrientationRule.FIXED:
        return "none", (
            "fixed orientation: six equations for six joints, the posture is the IK "
            "solution of each branch; only the branch is chosen"
        )
    T = robot.tcp2flange
    off = float(np.hypot(T[0, 3], T[1, 3]))
    # Angle between the tool axis and the joint-6 axis, either sense (a tool axis
    # anti-parallel to joint 6 is just as degenerate).
    tilt = float(np.arccos(np.clip(abs(T[2, 2]), 0.0, 1.0)))
    on_axis = off <= DEGENERATE_OFFSET_TOL_M and tilt <= DEGENERATE_ANGLE_TOL_RAD
    if rule is OrientationRule.FREE_TOOL_AXIS and on_axis:
        return "degenerate", (
            "the TCP lies on the joint-6 axis and the tool axis is "
            "along it, so rotation about the tool axis only turns joint 6 and "
            "leaves C(q) unchanged (zero gradient); only the branch is chosen"
        )
    if on_axis and rule in (OrientationRule.CONE, OrientationRule.POSITION_ONLY):
        return "free", (
            f"{rule.value}: the tool axis direction is optimised; rotation about it "
            "only turns joint 6 (TCP on the joint-6 axis) and is left to the smoothness term"
        )
    return "free", f"{rule.value}: the posture is optimised along the free directions"


def branch_signs(ik: IKSolver, q: np.ndarray) -> np.ndarray:
    """Signs (G,) of the IK family's guard factors along a branch path (N, 6), rad.

    Each is the sign of the median factor over the waypoints (+1 at zero).
    """
    f = ik.guard_factors(np.atleast_2d(q))
    return np.where(np.median(f, axis=0) >= 0.0, 1.0, -1.0)


# --------------------------------------------------------------------------------------
# The whole stage
# --------------------------------------------------------------------------------------


def optimise_postures(
    robot: ArmModel | Robot,
    task: PostureTask,
    home_q: np.ndarray,
    settings: SolverSettings = SolverSettings(),
    verbose: bool = False,
    model: KinematicModel | None = None,
    ik: IKSolver | None = None,
    optimise: bool = True,
    clearance: ClearanceSpec | None = None,
) -> PostureResult:
    """Solve the posture NLP on every feasible branch and choose the best.

    Parameters
    ----------
    robot : ArmModel or Robot
        The arm model (a :class:`Robot` is wrapped in its nominal model), with its tool
        (``tcp2flange``); its IK family (:func:`models.ik.ik_solver`) gives the warm starts.  Its
        ``kinematics.fn["load_error"]`` is the objective.
    task : PostureTask
    home_q : ndarray, shape (6,)
        Home configuration (rad): the default branch is the one nearest to it.
    settings : SolverSettings
    verbose : bool
        IPOPT output on.
    model, ik : optional
        Reuse already built objects for ``robot``.
    optimise : bool
        False: analytic postures only (every branch as if it had no freedom).
    clearance : ClearanceSpec, optional
        The cell: each pair is kept at the clearance by the NLP (constraints with gradients) at
        the waypoints where it comes within
        :data:`~problems.posture.clearance_active.POSED_DISTANCE_M` at some branch's warm start;
        a solution closer than the clearance at a waypoint where its pair was not posed is solved
        again with it posed (:mod:`problems.posture.clearance_active`); the caller checks every
        pair exactly afterwards.

    Returns
    -------
    PostureResult
        Never raises for infeasible tasks: the status and reason say what failed.
    """
    arm = robot if isinstance(robot, ArmModel) else ArmModel.from_robot(robot)
    robot = arm.nominal
    model = model or arm.kinematics
    ik = ik or ik_solver(robot)
    posed = clearance is not None and bool(clearance.pairs)
    max_nodes = CLEARANCE_MAX_NODES if posed else dense.POSTURE_MAX_NODES
    if task.n > max_nodes:
        return _on_nodes(arm, task, home_q, settings, verbose, model, ik, optimise, clearance, max_nodes)
    freedom, note = analyse_freedom(robot, task.rule)
    ws = warm_starts(ik, model, task)
    if not arm.geometry_is_nominal:
        ws = onto_model_geometry(arm, ik, ws)
    default = (
        default_branch(ws.analytic, home_q)
        if ws.analytic
        else (default_branch({b: v[0] for b, v in ws.warm.items()}, home_q) if ws.warm else None)
    )
    if not ws.warm:
        return _infeasible_result(ik, task, ws, default, freedom, note)

    nlp: PostureNLP | None = None
    build = 0.0
    if optimise and freedom == "free":
        t0 = time.perf_counter()
        nlp = _build_nlp(arm, task, settings, verbose, clearance, ws)
        build = time.perf_counter() - t0

    results: dict[int, BranchResult] = {}
    for b in sorted(ws.warm):
        if nlp is None:
            results[b] = _unoptimised_branch(model, task, ws, b, freedom, note)
        else:
            results[b], nlp = _optimised_branch(nlp, model, ik, task, ws, b, robot.q_min, robot.q_max)
        results[b].label = ik.labels[b]
    res = _choose(task, ws.rejected, ws.unreachable, results, default, freedom, note, build, ik.labels)
    res.ik_family = ik.family
    return res


def _on_nodes(
    arm: ArmModel,
    task: PostureTask,
    home_q: np.ndarray,
    settings: SolverSettings,
    verbose: bool,
    model: KinematicModel,
    ik: IKSolver,
    optimise: bool,
    clearance: ClearanceSpec | None = None,
    max_nodes: int | None = None,
) -> PostureResult:
    """A long path: the NLP on nodes, densified (:mod:`problems.posture.dense`)."""
    nodes = dense.node_indices(task.n, max_nodes)
    res = optimise_postures(
        arm, dense.node_task(task, nodes), home_q, settings, verbose, model, ik, optimise, clearance
    )
    if res.ok:
        return dense.densify(arm, model, ik, task, nodes, res)
    res.reason = (
        f"on {len(nodes)} nodes spread over the {task.n} waypoints (node k is waypoint "
        f"round(k * {(task.n - 1) / (len(nodes) - 1):.6g})): {res.reason}"
    )
    res.unreachable = [int(nodes[k]) for k in res.unreachable]
    res.task = task
    return res


def _infeasible_result(
    ik: IKSolver, task: PostureTask, ws: WarmStarts, default: int | None, freedom: str, note: str
) -> PostureResult:
    """The result when no branch reaches the whole path: a waypoint unreachable on every
    branch (status UNREACHABLE, naming the first one and the IK's reasons there), or every
    branch rejected somewhere (status NO_BRANCH, with every branch's reason)."""
    if ws.unreachable:
        k = ws.unreachable[0]
        p = task.positions[k]
        sol = ik.solve(poses(task.positions[k : k + 1], task.rotations[k]))
        why = "; ".join(sorted({IK_REASONS[IKStatus.from_code(c)] for c in sol.status[0]}))
        reason = f"no IK branch reaches waypoint {k} at ({p[0]:.4g}, {p[1]:.4g}, {p[2]:.4g}) m ({why})"
        if len(ws.unreachable) > 1:
            reason += f"; {len(ws.unreachable)} unreachable waypoints in all"
        status = PostureStatus.UNREACHABLE
    else:
        reason = "no IK branch reaches the whole path: " + "; ".join(
            f"{ik.labels[b]}: {r}" for b, r in sorted(ws.rejected.items())
        )
        status = PostureStatus.NO_BRANCH
    return PostureResult(
        status,
        reason,
        task,
        {},
        ws.rejected,
        None,
        default,
        freedom,
        note,
        ws.unreachable,
        labels=ik.labels,
        ik_family=ik.family,
    )


def _analytic_of(
    model: KinematicModel, task: PostureTask, ws: WarmStarts, b: int
) -> tuple[np.ndarray | None, np.ndarray, float]:
    """Branch ``b``'s analytic posture (N, 6) rad or None, its error per waypoint (N,) m (NaN
    if None) and its cost (m^2, NaN if None)."""
    qa = ws.analytic[b].q if b in ws.analytic else None
    err_a = linear_error(model, qa, task.load) if qa is not None else np.full(task.n, np.nan)
    cost_a = float(np.sum(err_a**2)) if qa is not None else math.nan
    return qa, err_a, cost_a


def _unoptimised_branch(
    model: KinematicModel, task: PostureTask, ws: WarmStarts, b: int, freedom: str, note: str
) -> BranchResult:
    """Branch ``b`` without an NLP: its analytic posture (else its warm start), with the
    status saying why (no freedom, degenerate, or optimisation switched off)."""
    bp_warm, wname, wcost = ws.warm[b]
    qa, err_a, cost_a = _analytic_of(model, task, ws, b)
    if freedom == "none":
        st, why = BranchStatus.NO_FREEDOM, note
    elif freedom == "degenerate":
        st, why = BranchStatus.DEGENERATE, note
    else:
        st, why = BranchStatus.ANALYTIC, "optimisation switched off: analytic posture"
    q = qa if qa is not None else bp_warm.q
    err = linear_error(model, q, task.load)
    return BranchResult(
        b,
        st,
        why,
        q,
        qa,
        bp_warm.q,
        wname if qa is None else "nominal",
        float(np.sum(err**2)),
        cost_a,
        wcost,
        err,
        err_a,
    )


def _optimised_branch(
    nlp: PostureNLP,
    model: KinematicModel,
    ik: IKSolver,
    task: PostureTask,
    ws: WarmStarts,
    b: int,
    q_min: np.ndarray,
    q_max: np.ndarray,
) -> tuple[BranchResult, PostureNLP]:
    """Branch ``b`` through the NLP: IPOPT from its warm start, Gauss-Newton polish, verification.

    The optimised posture is kept only if IPOPT converged and every constraint verifies;
    otherwise the analytic posture (else the warm start) is kept and the status says why.
    ``q_min``, ``q_max`` (6,) are the joint limits, rad.  With a cell, a solution closer than the
    clearance where its pair was not posed is solved again with it posed (at most
    :data:`~problems.posture.clearance_active.MAX_RESOLVES` times); the NLP used last is
    returned with the result (the next branch starts from it).
    """
    bp_warm, wname, wcost = ws.warm[b]
    qa, err_a, cost_a = _analytic_of(model, task, ws, b)
    base = qa if qa is not None else bp_warm.q
    sign = branch_signs(ik, bp_warm.q)
    kept = "analytic posture" if qa is not None else "warm start"
    deep = pair_depth_margins(nlp.clearance, bp_warm.q)
    if deep.min() < -NLP_MAX_PENETRATION_M:  # a posture change does not pull a link out of an object
        k, i = np.unravel_index(int(np.argmin(deep)), deep.shape)
        err = linear_error(model, base, task.load)
        why = (
            f"not optimised: at waypoint {k} of its warm start {nlp.clearance.pairs[i].name} is "
            f"{-deep[k, i] * 1e3:.0f} mm inside the cell's clearance (more than {NLP_MAX_PENETRATION_M * 1e3:.0f} "
            f"mm); the {kept} is kept"
        )
        return BranchResult(
            b, BranchStatus.SOLVER_FAILED, why, base, qa, bp_warm.q, wname, float(np.sum(err**2)), cost_a, wcost,
            err, err_a,
        ), nlp  # fmt: skip
    nlp, q_pol, ip_status, iters, dt = _solve_posing_clearances(nlp, task, bp_warm.q, sign, q_min, q_max)
    problems, res_m, res_rad = verify(model, task, q_pol, q_min, q_max, ik, sign)
    clear = _clearance_problems(nlp, task, q_pol)
    st, why = _branch_verdict(ip_status, iters, [*problems, *clear], kept, clear)
    q = q_pol if st is BranchStatus.OPTIMISED else base
    if st is BranchStatus.OPTIMISED and _start_is_better(nlp, model, ik, task, bp_warm.q, q, sign, q_min, q_max):
        # a local optimum worse than the (feasible) point it started from: keep the start
        q, why = (
            bp_warm.q,
            (
                f"IPOPT: {ip_status} in {iters} iterations at a local optimum worse than its warm "
                "start; the warm start is kept"
            ),
        )
    err = linear_error(model, q, task.load)
    return BranchResult(
        b,
        st,
        why,
        q,
        qa,
        bp_warm.q,
        wname,
        float(np.sum(err**2)),
        cost_a,
        wcost,
        err,
        err_a,
        iters,
        dt,
        ip_status,
        res_m,
        res_rad,
        _active_guards(ik, q, sign),
    ), nlp


def _solve_posing_clearances(
    nlp: PostureNLP, task: PostureTask, q0: np.ndarray, sign: np.ndarray, q_min: np.ndarray, q_max: np.ndarray
) -> tuple[PostureNLP, np.ndarray, str, int, float]:
    """IPOPT from ``q0`` and the Gauss-Newton polish; with a cell, solved again with the clearance
    pairs the solution violates posed (at most :data:`MAX_RESOLVES` times).  Returns the NLP used
    last, the polished posture (N, 6) rad, IPOPT's status, its iterations and its wall time, s."""
    q_opt, ip_status, iters, dt = nlp.solve(task, q0, sign, q_min, q_max)
    q_pol = nlp.polish(task, q_opt, sign) if np.all(np.isfinite(q_opt)) else q_opt
    for _ in range(MAX_RESOLVES if nlp.clearance is not None else 0):
        more = unposed_violations(nlp.clearance, nlp.posed, q_pol)
        if more is None:
            break
        nlp = nlp.with_posed(more)
        q_opt, ip_status, it2, dt2 = nlp.solve(task, q0, sign, q_min, q_max)
        iters, dt = iters + it2, dt + dt2
        q_pol = nlp.polish(task, q_opt, sign) if np.all(np.isfinite(q_opt)) else q_opt
    return nlp, q_pol, ip_status, iters, dt


def _build_nlp(
    arm: ArmModel,
    task: PostureTask,
    settings: SolverSettings,
    verbose: bool,
    clearance: ClearanceSpec | None,
    ws: Any,
) -> PostureNLP:
    """The posture NLP of ``task``, with the cell's pairs posed where the branches it will solve
    come near at their warm starts (:mod:`problems.posture.clearance_active`)."""
    spec = clearance if clearance is not None and clearance.pairs else None
    posed = None
    if spec is not None:
        starts = [v[0].q for v in ws.warm.values()]
        posed = posed_at(spec, [q for q in starts if depth_margin(spec, q).min() >= -NLP_MAX_PENETRATION_M])
    return get_nlp(arm, task.rule, task.n, settings, verbose, spec, posed)


def _clearance_problems(nlp: PostureNLP, task: PostureTask, q: np.ndarray) -> list[str]:
    """The deepest waypoint of ``q`` (N, 6) inside the cell's clearance, as a verification problem
    (none when every waypoint keeps :data:`CLEARANCE_TOL_M`; a non-finite ``q`` is inside)."""
    margin_c = clearance_margin(nlp.clearance, q)
    if np.any(margin_c < -CLEARANCE_TOL_M):
        k = int(np.argmin(margin_c))
        pair = closest_pair_words(nlp.clearance, q[k])
        return [
            f"waypoint {k}: {-margin_c[k] * 1e3:.3g} mm inside the cell's clearance" + (f" ({pair})" if pair else "")
        ]
    return []


def _branch_verdict(
    ip_status: str, iters: int, problems: list[str], kept: str, clear: list[str] | None = None
) -> tuple[BranchStatus, str]:
    """A branch's status and reason from IPOPT's status and the verification ``problems``; ``kept``
    names the posture kept when it is not optimised; ``clear``: the clearance problem of IPOPT's
    last iterate (the pair named), said when IPOPT failed."""
    if ip_status not in IPOPT_OK:
        at = f"; its last iterate: {clear[0]}" if clear else ""
        return BranchStatus.SOLVER_FAILED, f"IPOPT: {ip_status} after {iters} iterations{at}; the {kept} is kept"
    if problems:
        return BranchStatus.CONSTRAINT_VIOLATED, f"{problems[0]}; the {kept} is kept"
    return BranchStatus.OPTIMISED, f"IPOPT: {ip_status} in {iters} iterations"


def _start_is_better(
    nlp: PostureNLP,
    model: KinematicModel,
    ik: IKSolver,
    task: PostureTask,
    q_start: np.ndarray,
    q: np.ndarray,
    sign: np.ndarray,
    q_min: np.ndarray,
    q_max: np.ndarray,
) -> bool:
    """Whether the warm start ``q_start`` (N, 6) has a lower objective than the optimum ``q`` and
    verifies (constraints and clearance): IPOPT then stopped at a worse local optimum."""
    return bool(
        _objective(model, task, q_start) < _objective(model, task, q)
        and not verify(model, task, q_start, q_min, q_max, ik, sign)[0]
        and np.all(clearance_margin(nlp.clearance, q_start) >= -CLEARANCE_TOL_M)
    )


def _active_guards(ik: IKSolver, q: np.ndarray, sign: np.ndarray) -> dict[str, int]:
    """Guard name -> the number of waypoints of ``q`` (N, 6) where it is active (within
    :data:`GUARD_ACTIVE_TOL` of its bound); guards never active are left out."""
    margin = ik.guard_factors(q) * sign - guard_bounds(ik)
    active = {name: int(np.sum(margin[:, i] <= GUARD_ACTIVE_TOL)) for i, name in enumerate(ik.guard_names)}
    return {k: v for k, v in active.items() if v}


def _objective(model: KinematicModel, task: PostureTask, q: np.ndarray) -> float:
    """The NLP's objective at ``q`` (N, 6): ``COST_SCALE sum ||S C F||^2 + smoothness sum ||dq||^2`` (mm^2)."""
    err = linear_error(model, q, task.load)
    return float(COST_SCALE * np.sum(err**2) + task.smoothness * np.sum(np.diff(q, axis=0) ** 2))


def _choose(
    task: PostureTask,
    rejected: dict[int, str],
    unreachable: list[int],
    results: dict[int, BranchResult],
    default: int | None,
    freedom: str,
    note: str,
    build: float,
    labels: tuple[str, ...],
) -> PostureResult:
    """The usable branch of least cost (status OK); if none is usable, COLLISION when a branch
    was set aside for colliding with the cell (:func:`rechoose`), else SOLVER_FAILED.

    ``rejected``, ``unreachable``: the warm starts' (:class:`PostureResult`); ``build`` is the
    solver's build time, s; ``labels`` the IK family's branch labels.
    """
    usable = {b: r for b, r in results.items() if r.status.usable}
    if not usable:
        colliding = [r for r in results.values() if r.status is BranchStatus.COLLISION]
        if colliding:
            status = PostureStatus.COLLISION
            reason = (
                f"every branch the posture stage gave ({len(colliding)}) collides with the cell; first "
                f"{colliding[0].label}: {colliding[0].reason}"
            )
        else:
            status = PostureStatus.SOLVER_FAILED
            reason = "the NLP failed on every feasible branch: " + "; ".join(
                f"{r.label}: {r.reason}" for r in results.values()
            )
        return PostureResult(
            status, reason, task, results, rejected, None, default, freedom, note, unreachable, build, labels
        )
    chosen = min(usable, key=lambda b: usable[b].cost)
    n_coll = sum(r.status is BranchStatus.COLLISION for r in results.values())
    n_fail = len(results) - len(usable) - n_coll
    reason = (
        f"branch {labels[chosen]} chosen among {len(usable)} usable branch(es)"
        + (f"; {n_fail} failed" if n_fail else "")
        + (f"; {n_coll} set aside for colliding with the cell" if n_coll else "")
    )
    return PostureResult(
        PostureStatus.OK, reason, task, results, rejected, chosen, default, freedom, note, unreachable, build, labels
    )


def rechoose(ps: PostureResult) -> PostureResult:
    """The choice made again after branches' statuses changed (e.g. set to ``collision`` by the
    plan's cell check): the usable branch of least cost, or the status saying why none is.

    Returns a new :class:`PostureResult` with the same branches (``ik_family`` and the rest kept).
    """
    out = _choose(
        ps.task,
        ps.rejected,
        ps.unreachable,
        ps.branches,
        ps.default,
        ps.freedom,
        ps.freedom_note,
        ps.build_time_s,
        ps.labels,
    )
    out.ik_family = ps.ik_family
    return out


def optimal_pose(
    robot: ArmModel | Robot,
    position: np.ndarray,
    rotation: np.ndarray,
    rule: OrientationRule,
    wrench: np.ndarray,
    cone_half_angle: float = 0.0,
    home_q: np.ndarray | None = None,
    settings: SolverSettings = SolverSettings(),
    scan: int = DEFAULT_SCAN,
    verbose: bool = False,
) -> PostureResult:
    """Single-pose query: the stiffness-optimal posture for one target and wrench.

    Parameters
    ----------
    robot : ArmModel or Robot
        As for :func:`optimise_postures`.
    position : ndarray, shape (3,)
        TCP target, m, base frame.
    rotation : ndarray, shape (3, 3)
        Nominal base->TCP rotation (the tool axis is its z column).
    rule : OrientationRule
    wrench : ndarray, shape (6,) or (LOAD_SIZE,)
        [N, N*m] on the TCP, base frame (or a load row, :mod:`models.load`).
    cone_half_angle : float
        Rule ``cone`` only, rad.
    home_q : ndarray, shape (6,), optional
        For the default branch, rad (zeros if not given).
    settings : SolverSettings
    scan : int
        Scanned rotations about the tool axis for the warm starts.
    verbose : bool
        IPOPT output on.

    Returns
    -------
    PostureResult
        With N = 1 (no joint-step constraint).
    """
    task = PostureTask(
        np.asarray(position, float).reshape(1, 3),
        np.asarray(rotation, float),
        rule,
        np.asarray(wrench, float),
        cone_half_angle=cone_half_angle,
        scan=scan,
    )
    return optimise_postures(
        robot, task, np.zeros(6) if home_q is None else np.asarray(home_q, float), settings, verbose
    )
