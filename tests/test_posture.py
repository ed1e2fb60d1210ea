"""The posture NLP: derivatives, optimality against the analytic posture, constraints at the
optimum, branch labels, the degenerate case, the single-pose query, and each failure status."""

from __future__ import annotations

import functools
import math

import casadi as ca
import numpy as np
import pytest

from models import AnalyticIK, KinematicModel, load_robot
from models.ik import BRANCH_LABELS, IKStatus
from models.transforms import tool_down_rotation, transform
from problems import paper
from problems.path import line_positions
from problems.posture import (
    BranchStatus,
    N_THETA,
    OrientationRule,
    PostureError,
    PostureNLP,
    PostureStatus,
    PostureTask,
    SolverSettings,
    analyse_freedom,
    branch_signs,
    guard_bounds,
    optimal_pose,
    optimise_postures,
    singular_factors,
    warm_starts,
)
from problems.posture.transcription import _stage_sx
from problems.problem import load_problem

#: Tolerances of the assertions.
POSITION_TOL_M = 1e-9
ANGLE_TOL_RAD = 1e-9
COST_SLACK = 1e-12  # m^2: optimised may equal the analytic cost
STEP_SLACK_RAD = 1e-6

OFF_AXIS_TOOL = transform(np.eye(3), [0.1, 0.0, 0.05])
FORCE = np.array([15.0, -25.0, 30.0, 0.0, 0.0, 0.0])


@functools.cache
def _tooled(xyz: tuple[float, ...]):
    robot = load_robot("ar5").with_tool(transform(np.eye(3), list(xyz)))
    return robot, KinematicModel(robot), AnalyticIK(robot)


def _task(rule: OrientationRule, n: int = 12, **kw) -> PostureTask:
    P = line_positions([0.20, 0.40, 0.30], [0.45, -0.10, 0.30], n)
    kw.setdefault("cone_half_angle", math.radians(20.0))
    kw.setdefault("max_joint_step", 0.6)
    return PostureTask(P, tool_down_rotation(), rule, FORCE, **kw)


@functools.cache
def _solved(rule_value: str):
    robot, model, ik = _tooled((0.1, 0.0, 0.05))
    task = _task(OrientationRule(rule_value))
    return robot, model, ik, task, optimise_postures(robot, task, paper.HOME_Q, model=model, ik=ik)


# ------------------------------------------------------------------------------ model pieces
@pytest.mark.parametrize("name", ["ar5", "ur5", "ur10"])
def test_singular_factors_multiply_to_det_J(name, rng):
    robot = load_robot(name)
    model, ik = KinematicModel(robot), AnalyticIK(robot)
    a = ik.a
    for q in rng.uniform(-math.pi, math.pi, (6, 6)):
        f = singular_factors(ik, q)
        assert math.isclose(np.linalg.det(model.J(q)), a[1] * a[2] * f[0] * f[1] * f[2], rel_tol=1e-9, abs_tol=1e-15)


def test_branch_signs_are_the_branch_label():
    robot, model, ik = _tooled((0.0, 0.0, 0.0))
    sol = ik.solve(transform(tool_down_rotation(), [0.35, 0.1, 0.3]))
    for b in np.where(sol.status[0] == IKStatus.OK.code)[0]:
        s = branch_signs(ik, sol.q[0, b][None])
        label = BRANCH_LABELS[b]
        # shoulder sign flips between s+ and s-; wrist and elbow signs are those of the label
        assert s[1] == (1.0 if label[3] == "+" else -1.0) and s[2] == (1.0 if label[5] == "+" else -1.0)
    shoulders = {
        BRANCH_LABELS[b][1]: branch_signs(ik, sol.q[0, b][None])[0]
        for b in np.where(sol.status[0] == IKStatus.OK.code)[0]
    }
    assert shoulders["+"] == -shoulders["-"]


@pytest.mark.parametrize("rule", list(OrientationRule))
def test_hand_assembled_derivatives_equal_automatic_differentiation(rule, rng):
    """grad_f, jac_g and the Lagrangian Hessian given to IPOPT are the exact derivatives."""
    robot = _tooled((0.1, 0.0, 0.05))[0]
    n = 3
    nlp = PostureNLP(robot, rule, n, SolverSettings(codegen=False))
    task = _task(rule, n)
    th = nlp.theta(task, np.array([1.0, -1.0, 1.0]))
    lam_s, w_obj = 0.7, 2.5
    p = np.r_[th.reshape(-1, order="F"), lam_s, w_obj]
    X = ca.SX.sym("X", 6, n)
    sx = _stage_sx(robot, rule)
    c, g = sx["f"].map(n)(X, ca.DM(th))
    dX = X[:, 1:] - X[:, :-1]
    f = w_obj * (ca.sum2(c) + lam_s * ca.sumsqr(dX))
    G = ca.vertcat(ca.vec(g), ca.vec(dX))
    x = ca.vec(X)
    xv = rng.uniform(-2.0, 2.0, 6 * n)
    lam = rng.normal(size=G.shape[0])
    sigma = 0.37
    ref_grad = np.asarray(ca.Function("g", [x], [ca.gradient(f, x)])(xv)).ravel()
    ref_jac = np.asarray(ca.densify(ca.Function("j", [x], [ca.jacobian(G, x)])(xv)))
    ref_hess = np.asarray(
        ca.densify(ca.Function("h", [x], [ca.triu(ca.hessian(sigma * f + ca.dot(ca.DM(lam), G), x)[0])])(xv))
    )
    S = nlp.solver
    got_grad = np.asarray(S.get_function("nlp_grad_f")(xv, p)[1]).ravel()
    got_jac = np.asarray(ca.densify(S.get_function("nlp_jac_g")(xv, p)[1]))
    got_hess = np.asarray(ca.densify(S.get_function("nlp_hess_l")(xv, p, sigma, lam)))
    assert np.allclose(got_grad, ref_grad, rtol=1e-10, atol=1e-9)
    assert np.allclose(got_jac, ref_jac, rtol=1e-10, atol=1e-9)
    assert np.allclose(got_hess, ref_hess, rtol=1e-10, atol=1e-8)
    assert N_THETA == th.shape[0]


# ------------------------------------------------------------------------------ the degenerate case
def test_degenerate_case_is_detected_and_really_degenerate():
    robot, model, ik = _tooled((0.0, 0.0, 0.0))
    kind, note = analyse_freedom(robot, OrientationRule.FREE_TOOL_AXIS)
    assert kind == "degenerate" and "joint-6 axis" in note
    # ... and the claim holds: turning joint 6 leaves C(q) unchanged (zero gradient) ...
    q = np.array([0.3, -1.2, 1.4, -1.7, -1.5, 0.2])
    C0 = model.C(q)
    for d6 in (0.5, 2.0, -1.0):
        assert np.allclose(model.C(q + [0, 0, 0, 0, 0, d6]), C0, rtol=0, atol=1e-15 * np.abs(C0).max())
    # ... while it does change C with the TCP 0.1 m off the axis.
    off, model_off, _ = _tooled((0.1, 0.0, 0.05))
    assert analyse_freedom(off, OrientationRule.FREE_TOOL_AXIS)[0] == "free"
    assert np.abs(model_off.C(q + [0, 0, 0, 0, 0, 1.0]) - model_off.C(q)).max() > 1e-3 * np.abs(model_off.C(q)).max()

    res = optimise_postures(robot, _task(OrientationRule.FREE_TOOL_AXIS, 6), paper.HOME_Q, model=model, ik=ik)
    assert res.ok and res.freedom == "degenerate"
    for r in res.branches.values():
        assert r.status is BranchStatus.DEGENERATE and r.iterations == 0
        assert np.array_equal(r.q, r.q_analytic)


def test_fixed_orientation_has_no_freedom():
    robot, model, ik = _tooled((0.0, 0.0, 0.0))
    P = line_positions(paper.SECTION_4_4_START_M, paper.SECTION_4_4_END_M, 8)
    res = optimise_postures(
        robot,
        PostureTask(P, tool_down_rotation(), OrientationRule.FIXED, paper.SECTION_4_4_WRENCH, max_joint_step=2.0),
        paper.HOME_Q,
        model=model,
        ik=ik,
    )
    assert res.ok and res.freedom == "none"
    assert {BRANCH_LABELS[b] for b in res.branches} == {"s+w+e+", "s+w+e-", "s-w-e+", "s-w-e-"}
    for r in res.branches.values():
        assert r.status is BranchStatus.NO_FREEDOM and np.array_equal(r.q, r.q_analytic)
    assert res.best.label == "s-w-e-" and BRANCH_LABELS[res.default] == "s-w-e+"
    assert res.gains()["vs_default"] > 2.5 and math.isclose(res.gains()["vs_best_analytic"], 1.0)


# ------------------------------------------------------------------------------ optimality and constraints
@pytest.mark.parametrize("rule", ["free_tool_axis", "cone", "position_only"])
def test_optimum_beats_the_analytic_posture_and_meets_every_constraint(rule):
    robot, model, ik, task, res = _solved(rule)
    assert res.ok and res.freedom == "free"
    assert len(res.branches) == 8
    for b, r in res.branches.items():
        assert r.status is BranchStatus.OPTIMISED, (r.label, r.reason)
        # optimality: never worse than where it started or than the analytic posture
        assert r.cost <= r.cost_warm + COST_SLACK, r.label
        if np.isfinite(r.cost_analytic):
            assert r.cost <= r.cost_analytic + COST_SLACK, r.label
        # constraints, checked with the model's own forward kinematics
        T = model.tcp(r.q)
        assert np.abs(T[:, :3, 3] - task.positions).max() <= POSITION_TOL_M
        z = T[:, :3, 2]
        ang = np.arctan2(np.linalg.norm(np.cross(z, task.axes), axis=1), np.einsum("ij,ij->i", z, task.axes))
        if rule == "free_tool_axis":
            assert ang.max() <= ANGLE_TOL_RAD
        elif rule == "cone":
            assert ang.max() <= task.cone_half_angle + ANGLE_TOL_RAD
        assert np.all(r.q >= robot.q_min) and np.all(r.q <= robot.q_max)
        assert np.abs(np.diff(r.q, axis=0)).max() <= task.max_joint_step + STEP_SLACK_RAD
        # the branch label is right: the analytic IK of the reached pose on that branch is q
        sol = ik.solve(T)
        assert np.all(sol.status[:, b] == IKStatus.OK.code), r.label
        d = (sol.q[:, b] - r.q + np.pi) % (2 * np.pi) - np.pi
        assert np.abs(d).max() < 1e-7, r.label
        f = singular_factors(ik, r.q) * branch_signs(ik, r.q)
        assert np.all(f >= guard_bounds(ik) - 1e-7)
    # the continuous freedom buys something beyond the branch choice
    assert res.gains()["vs_best_analytic"] > 1.0
    assert res.best.cost == min(r.cost for r in res.branches.values())


def test_cone_solution_uses_the_tilt():
    _, model, _, task, res = _solved("cone")
    T = model.tcp(res.best.q)
    ang = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", T[:, :3, 2], task.axes), -1, 1)))
    assert ang.max() > 1.0  # it does tilt (the free directions are used)


def test_warm_start_dynamic_programme_beats_every_constant_rotation():
    """The warm start minimises the NLP objective over per-waypoint scanned rotations."""
    robot, model, ik = _tooled((0.1, 0.0, 0.05))
    task = _task(OrientationRule.FREE_TOOL_AXIS, 10, smoothness=1.0)
    ws = warm_starts(ik, model, task)
    from problems.path import branch_paths, poses
    from problems.posture import candidates, linear_error

    lam = task.smoothness

    def objective(q):
        return 1e6 * np.sum(linear_error(model, q, task.wrench) ** 2) + lam * np.sum(np.diff(q, axis=0) ** 2)

    for name, R in candidates(task):
        feas, _ = branch_paths(ik, poses(task.positions, R), task.max_joint_step)
        for b, bp in feas.items():
            assert b in ws.warm
            assert objective(ws.warm[b][0].q) <= objective(bp.q) + 1e-9, (name, BRANCH_LABELS[b])


def test_compiled_and_virtual_machine_solvers_agree():
    robot, model, ik = _tooled((0.1, 0.0, 0.05))
    task = _task(OrientationRule.FREE_TOOL_AXIS, 6)
    a = optimise_postures(robot, task, paper.HOME_Q, SolverSettings(codegen=True), model=model, ik=ik)
    b = optimise_postures(robot, task, paper.HOME_Q, SolverSettings(codegen=False), model=model, ik=ik)
    assert a.chosen == b.chosen
    for k in a.branches:
        assert np.allclose(a.branches[k].q, b.branches[k].q, atol=1e-6)


def test_single_pose_query():
    robot = _tooled((0.1, 0.0, 0.05))[0]
    p = np.array([0.35, 0.1, 0.3])
    res = optimal_pose(robot, p, tool_down_rotation(), OrientationRule.FREE_TOOL_AXIS, FORCE, home_q=paper.HOME_Q)
    assert res.ok and res.task.n == 1 and len(res.branches) == 8
    model = KinematicModel(robot)
    for r in res.branches.values():
        assert r.q.shape == (1, 6) and r.status is BranchStatus.OPTIMISED
        assert r.cost <= r.cost_analytic + COST_SLACK
        T = model.tcp(r.q[0])
        assert np.linalg.norm(T[:3, 3] - p) <= POSITION_TOL_M
        assert abs(T[2, 2] + 1.0) <= 1e-12
    assert res.best.cost < min(r.cost_analytic for r in res.branches.values())


# ------------------------------------------------------------------------------ failures
def test_unreachable_waypoint_is_named():
    robot, model, ik = _tooled((0.1, 0.0, 0.05))
    P = np.array([[0.35, 0.0, 0.3], [1.6, 0.0, 0.3], [0.35, 0.1, 0.3]])
    res = optimise_postures(
        robot,
        PostureTask(P, tool_down_rotation(), OrientationRule.FREE_TOOL_AXIS, FORCE),
        paper.HOME_Q,
        model=model,
        ik=ik,
    )
    assert res.status is PostureStatus.UNREACHABLE and res.unreachable == [1]
    assert "waypoint 1" in res.reason and "1.6" in res.reason
    with pytest.raises(Exception, match="no branch chosen"):
        _ = res.best


def test_unavoidable_flip_is_reported():
    robot, model, ik = _tooled((0.1, 0.0, 0.05))
    task = _task(OrientationRule.FREE_TOOL_AXIS, 12, max_joint_step=0.01)
    res = optimise_postures(robot, task, paper.HOME_Q, model=model, ik=ik)
    assert res.status is PostureStatus.NO_BRANCH and not res.unreachable
    assert "flip between waypoints" in res.reason and len(res.rejected) == 8


def test_solver_failure_is_reported_per_branch():
    robot, model, ik = _tooled((0.1, 0.0, 0.05))
    res = optimise_postures(
        robot, _task(OrientationRule.POSITION_ONLY, 8), paper.HOME_Q, SolverSettings(max_iter=1), model=model, ik=ik
    )
    assert res.status is PostureStatus.SOLVER_FAILED and res.chosen is None
    for r in res.branches.values():
        assert r.status is BranchStatus.SOLVER_FAILED and "Maximum_Iterations_Exceeded" in r.reason


@pytest.mark.parametrize(
    "kw,words",
    [
        ({"positions": np.zeros((3, 2))}, "positions"),
        ({"rotations": np.eye(3) * 2}, "proper rotation"),
        ({"wrench": np.zeros(5)}, "wrench"),
        ({"cone_half_angle": 0.0, "rule": OrientationRule.CONE}, "half-angle"),
        ({"max_joint_step": -1.0}, "max_joint_step"),
        ({"positions": np.array([[0.3, 0.0, np.nan]])}, "not finite"),
    ],
)
def test_task_validation(kw, words):
    args = dict(
        positions=np.array([[0.3, 0.0, 0.3]]),
        rotations=np.eye(3),
        rule=OrientationRule.POSITION_ONLY,
        wrench=np.zeros(6),
    )
    args.update(kw)
    with pytest.raises(PostureError, match=words):
        PostureTask(**args)


def test_shipped_paper_end_point_branches_differ_by_about_four():
    pr = load_problem("paper_4_4")
    res = optimal_pose(pr.robot, pr.positions[-1], pr.rotations[-1], pr.rule, pr.wrench[-1], home_q=pr.home_q)
    e = np.array([r.error_m[0] for r in res.branches.values()])
    assert len(e) == 8 and 3.5 < e.max() / e.min() < 5.0


# ------------------------------------------------------------------------------ the package
def test_package_reexports_its_modules_names():
    """``problems.posture`` re-exports what other code imports, the same objects as its modules."""
    import problems.posture as pkg
    from problems.posture import solve, task, transcription, verification, warm_start

    for name in pkg.__all__:
        assert hasattr(pkg, name), name
    assert pkg.PostureTask is task.PostureTask and pkg.N_THETA == task.N_THETA
    assert pkg.get_nlp is transcription.get_nlp
    assert pkg.warm_starts is warm_start.warm_starts and pkg.candidates is warm_start.candidates
    assert pkg.verify is verification.verify and pkg.singular_factors is verification.singular_factors
    assert pkg.optimise_postures is solve.optimise_postures and pkg.optimal_pose is solve.optimal_pose
