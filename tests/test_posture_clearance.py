"""The posture NLP's clearance constraints (issue 25): closed-form distances in CasADi, checked
against coal, their derivatives against finite differences, and the NLP keeping the clearance.

The distances the NLP keeps are lower bounds (``problems/posture/clearance.py``): for every pair
and configuration the bound must not exceed coal's distance, and it must be close to it (a
bound that gives away centimetres would push postures needlessly far).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import trimesh

from models.collision import ClearanceStatus, capsule_distance, capsule_shape_distance
from planner.cell_check import cell_geometry, check_poses, segments
from planner.plan import plan
from problems.cell import Cell, CellObject
from problems.posture import BranchStatus
from problems.posture import optimise_postures
from problems.posture import solve as posture_solve
from problems.posture.clearance import CLEARANCE_SCALE, clearance_functions, clearance_spec, distance_function
from problems.posture.clearance_active import clearance_margin, closest_pair_words, pair_distances
from problems.posture.transcription import _SOLVERS
from problems.problem import load_problem

#: The bound may exceed coal's distance by no more than this (m): rounding only.
BOUND_ABOVE_TOL_M = 1e-9
#: Largest amount (m) the bound may give away against coal on primitives (a segment passing a
#: box's edge or corner at the coarsest sample spacing) ...
BOUND_GAP_MAX_M = 0.012
#: ... and its median over all pairs and configurations.
BOUND_GAP_MEDIAN_M = 0.002
#: Finite-difference step (rad) and tolerance relative to the largest entry.
FD_STEP_RAD = 1e-6
FD_REL_TOL = 1e-5
#: The NLP's posture keeps the clearance to this (m), measured by coal.
KEPT_TOL_M = 1e-6


def _at(p) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = p
    return T


def _cell_with_every_kind(problem) -> Cell:
    tilted = _at([-0.35, 0.45, 0.3])
    c, s = np.cos(0.6), np.sin(0.6)
    tilted[:3, :3] = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    extra = (
        CellObject("ball", "sphere", np.array([0.1]), _at([0.4, 0.3, 0.5])),
        CellObject("post", "cylinder", np.array([0.05, 0.6]), tilted),
        CellObject("bunny", "mesh", np.zeros(3), _at([0.2, -0.6, 0.4]), mesh=trimesh.creation.icosphere(2, 0.12)),
    )
    return replace(problem.cell, objects=problem.cell.objects + extra)


@pytest.fixture(scope="module")
def setting():
    problem = load_problem("cell_table")
    geom = cell_geometry(problem.robot, _cell_with_every_kind(problem))
    spec = clearance_spec(geom)
    rng = np.random.default_rng(25)
    q = rng.uniform(problem.robot.q_min, problem.robot.q_max, (150, 6))
    return problem, geom, spec, q


def _coal_distances(geom, spec, q) -> np.ndarray:
    seg = segments(geom, q)
    r = geom.model.radius
    shapes = {s.name: s for s in geom.shapes}
    out = np.empty((len(q), len(spec.pairs)))
    for n in range(len(q)):
        for i, p in enumerate(spec.pairs):
            c = p.capsule
            if p.kind == "capsule":
                j = int(p.size[0])
                out[n, i] = capsule_distance(seg[n, c], r[c], seg[n, j], r[j])
            else:
                shape = shapes[p.name.split(" – ")[1]]
                out[n, i] = capsule_shape_distance(seg[n, c, 0], seg[n, c, 1], r[c], shape).distance
    return out


def test_the_bound_never_exceeds_coal_and_gives_little_away(setting):
    problem, geom, spec, q = setting
    kinds = {p.kind for p in spec.pairs}
    assert {"box", "sphere", "cylinder", "capsule"} <= kinds  # the mesh enters as its bounding box
    bound = np.asarray(distance_function(spec).map(len(q))(q.T)).T
    exact = _coal_distances(geom, spec, q)
    apart = exact > 0.0  # in penetration both are negative (the NLP only needs the sign there)
    assert apart.sum() > 1000
    assert np.all(bound[apart] <= exact[apart] + BOUND_ABOVE_TOL_M)
    primitive = np.array(["bunny" not in p.name for p in spec.pairs])
    gap = (exact - bound)[apart & primitive[None]]
    assert gap.max() < BOUND_GAP_MAX_M
    assert np.median(gap) < BOUND_GAP_MEDIAN_M
    # the mesh's bound is below its true distance too (its bounding box holds it)
    mesh = apart & ~primitive[None]
    assert mesh.any() and np.all(bound[mesh] <= exact[mesh] + BOUND_ABOVE_TOL_M)


def test_derivatives_match_finite_differences(setting):
    _, _, spec, q = setting
    fn = clearance_functions(spec, exact_hessian=True)  # the NLP leaves it out by default; it is right
    lam = np.random.default_rng(1).uniform(0.5, 1.5, len(spec.pairs))
    for q0 in q[:5]:
        _, J = fn["jac"](q0)
        J = np.asarray(J)
        H = np.asarray(fn["hess"](q0, lam))
        E = np.eye(6) * FD_STEP_RAD
        Jfd = np.column_stack(
            [(np.asarray(fn["g"](q0 + e)) - np.asarray(fn["g"](q0 - e))).ravel() / (2 * FD_STEP_RAD) for e in E]
        )
        assert np.abs(J - Jfd).max() <= FD_REL_TOL * max(1.0, np.abs(J).max())
        Hfd = np.column_stack(
            [
                (np.asarray(fn["jac"](q0 + e)[1]).T @ lam - np.asarray(fn["jac"](q0 - e)[1]).T @ lam)
                / (2 * FD_STEP_RAD)
                for e in E
            ]
        )
        assert np.abs(H - Hfd).max() <= 1e-3 * max(1.0, np.abs(H).max())
        assert np.allclose(H, H.T)
    assert CLEARANCE_SCALE == 1e3  # the constraints are in mm (their finite differences above too)


def _ceiling(problem, q: np.ndarray, cut: float = 0.01) -> Cell:
    """The problem's cell with a ceiling cutting ``cut`` (m) into the capsules at postures ``q``."""
    geom = cell_geometry(problem.robot, problem.cell)
    seg = segments(geom, q)
    top = float((seg[..., 2].max(axis=-1) + geom.model.radius[None]).max())
    ceiling = CellObject("ceiling", "box", np.array([3.0, 3.0, 0.1]), _at([0.0, 0.0, top - cut + 0.05]))
    return replace(problem.cell, objects=problem.cell.objects + (ceiling,))


def test_the_nlp_moves_a_branch_off_a_ceiling_and_pays_for_it():
    """A low ceiling cuts into the shipped plan's posture: the NLP keeps the clearance (by coal)
    on an optimised branch instead of setting branches aside, and the load-induced error grows."""
    problem = load_problem("cell_table")
    base = plan(problem)
    assert base.ok, base.reason
    cell = _ceiling(problem, base.posture.best.q)
    before = check_poses(cell_geometry(problem.robot, cell), base.posture.best.q)
    assert before.status is not ClearanceStatus.OK and "ceiling" in before.pair
    res = plan(replace(problem, cell=cell))
    assert res.ok, res.reason
    assert res.posture.best.status is BranchStatus.OPTIMISED
    kept = check_poses(cell_geometry(problem.robot, cell), res.posture.best.q)
    assert kept.distance >= cell.clearance - KEPT_TOL_M
    assert res.cell.waypoints.status is ClearanceStatus.OK
    assert res.posture.best.rms_error_m >= base.posture.best.rms_error_m
    # the constraint is active: the posture keeps the clearance to within the bound's gap
    assert kept.distance < cell.clearance + BOUND_GAP_MAX_M


def test_branches_that_cannot_clear_the_table_are_named(setting):
    res = plan(load_problem("cell_table"))
    colliding = [r for r in res.posture.branches.values() if r.status is BranchStatus.COLLISION]
    assert colliding
    for r in colliding:
        assert "table" in r.reason and "waypoint" in r.reason and "mm" in r.reason
        # the posture NLP's own part names the pair too (it was "its warm start is 105 mm inside")
        assert " – table is " in r.reason.split("posture NLP:", 1)[-1], r.reason


def test_the_closest_pair_is_named_with_its_distance(setting):
    problem, geom, spec, q = setting
    d = pair_distances(spec, q[:1])[0]
    i = int(np.argmin(d))
    words = closest_pair_words(spec, q[0])
    assert words.startswith(spec.pairs[i].name + " ")
    assert f"{abs(d[i]) * 1e3:.3g} mm {'apart' if d[i] >= 0 else 'deep'}" in words
    assert closest_pair_words(None, q[0]) == "" and closest_pair_words(spec, np.full(6, np.nan)) == ""


def test_the_broad_phase_measures_what_coal_measures(setting):
    """The NumPy distances that decide where a pair is posed: exact against coal for boxes,
    spheres and capsule pairs, never above it for cylinders (a bound)."""
    _, geom, spec, q = setting
    got = pair_distances(spec, q)
    exact = _coal_distances(geom, spec, q)
    kind = np.array([p.kind for p in spec.pairs])
    mesh = np.array(["bunny" in p.name for p in spec.pairs])  # measured as the NLP does: its bounding box
    closed = np.isin(kind, ["box", "sphere", "capsule"]) & ~mesh
    np.testing.assert_allclose(got[:, closed], exact[:, closed], atol=KEPT_TOL_M)
    bound = (kind == "cylinder") | mesh
    apart = exact > 0.0  # in penetration coal's depth on a cylinder is unreliable: the sign only
    assert (bound[None] & apart).sum() > 100
    assert np.all(got[apart & bound[None]] <= exact[apart & bound[None]] + BOUND_ABOVE_TOL_M)
    assert np.all(got[~apart & bound[None]] <= BOUND_ABOVE_TOL_M)


def test_a_pair_not_posed_where_the_solution_comes_too_close_is_posed_and_solved_again(monkeypatch):
    """With no pair posed from the warm starts, the first solve goes into the ceiling; the branch is
    solved again with the entries it violated posed, and keeps the clearance."""
    problem = load_problem("cell_table")
    arm, task = problem.model, problem.task()
    table = clearance_spec(cell_geometry(problem.robot, problem.cell))
    base = optimise_postures(arm, task, problem.home_q, problem.solver, clearance=table)
    cell = _ceiling(problem, base.best.q)
    spec = clearance_spec(cell_geometry(problem.robot, cell))
    monkeypatch.setattr(posture_solve, "posed_at", lambda spec, q_sets: np.zeros((len(spec.pairs), task.n), dtype=bool))
    _SOLVERS.clear()
    res = optimise_postures(arm, task, problem.home_q, problem.solver, clearance=spec)
    best = res.branches[base.chosen]
    assert best.status is BranchStatus.OPTIMISED, best.reason
    assert clearance_margin(spec, best.q).min() >= -KEPT_TOL_M
    posed = [nlp for nlp in _SOLVERS.values() if nlp.clear is not None]
    assert posed and any("ceiling" in spec.pairs[i].name for nlp in posed for i in nlp.clear.pairs)
