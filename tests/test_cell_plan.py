"""The cell in the plan (issue 25, first slice): branch choice and timed trajectory against the cell.

The scenario is the issue's: a UR10 with a 0.18 m tool, a tool-down cone along a 0.7 m line at
x = 0.75 m, z = 0.12 m, standing on a table; without the cell the stiffness-best branch puts the
elbow through the table. Every claim is checked *independently* of ``planner/cell_check.py``:
thin capsules (thinner than any real link) along the chain of frame origins (base, joints 1..6,
flange, TCP) from the arm model's own forward kinematics, against the objects directly with coal.
"""

from __future__ import annotations

from dataclasses import replace

import coal
import numpy as np
import pytest

from pathlib import Path

from models.collision import ClearanceStatus
from planner.cell_check import cell_geometry, segments
from planner.plan import PlanStatus, plan
from problems.cell import Cell, CellObject
from problems.posture import BranchStatus
from problems.problem import load_problem

#: Radius of the independent check's capsules (m): thinner than any link of the built-in arms.
THIN_RADIUS_M = 0.01
#: The table's top (m): the robot stands on a 20 mm mounting plate on it.
TABLE_TOP_M = -0.02

PROBLEM = """
name = "ur10_cone_table"
description = "UR10, 0.18 m tool, tool-down cone along a line over a table"
source = "tests/test_cell_plan.py"

[robot]
model = "ur10"
tool = {{ xyz = [0.0, 0.0, 0.18], rpy_deg = [0.0, 0.0, 0.0] }}

[path]
kind = "line"
start = [0.75, -0.35, 0.12]
end = [0.75, 0.35, 0.12]
points = 8

[orientation]
rule = "cone"
rpy_deg = [180.0, 0.0, 0.0]
half_angle_deg = 20.0

[wrench]
force = [0.0, 0.0, 40.0]

[limits]
max_joint_step = 0.3

[timing]
dt = 0.008
{cell}
"""

TABLE = f"""
[cell]
clearance = 0.005
[[cell.objects]]
name = "table"
shape = "box"
size = [2.0, 2.0, 0.1]
xyz = [0.5, 0.0, {TABLE_TOP_M - 0.05}]
rpy_deg = [0.0, 0.0, 0.0]
role = "obstacle"
"""


def _problem(tmp_path, cell: str = ""):
    f = tmp_path / "p.toml"
    f.write_text(PROBLEM.format(cell=cell))
    return load_problem(str(f))


def _chain_points(problem, q: np.ndarray) -> np.ndarray:
    """Frame origins base, 1..6, flange, TCP at configurations q (N, 6): shape (N, 9, 3), m."""
    km = problem.model.kinematics
    robot = problem.robot
    F = km.batch(km.fk_frames, np.atleast_2d(q))  # frames 1..6, (N, 4, 4) each
    flange = F[-1] @ robot.flange2frame6
    tcp = flange @ robot.tcp2flange
    n = len(np.atleast_2d(q))
    base = np.broadcast_to(robot.frame02base[:3, 3], (n, 3))
    return np.stack([base] + [f[:, :3, 3] for f in F] + [flange[:, :3, 3], tcp[:, :3, 3]], axis=1)


def _coal_tf(T: np.ndarray):
    tf = coal.Transform3s()
    tf.setRotation(np.ascontiguousarray(T[:3, :3]))
    tf.setTranslation(np.ascontiguousarray(T[:3, 3]))
    return tf


def _thin_distance(problem, q: np.ndarray, obj: CellObject, skip_tool: bool = False) -> np.ndarray:
    """Smallest signed distance (m) per configuration between thin capsules along the chain and an
    object, directly with coal (independent of planner/cell_check.py)."""
    P = _chain_points(problem, q)
    req = coal.DistanceRequest()
    req.enable_signed_distance = True
    out = np.full(len(P), np.inf)
    last = P.shape[1] - (2 if skip_tool else 1)
    for i in range(len(P)):
        for a, b in zip(P[i, :last], P[i, 1 : last + 1]):
            length = float(np.linalg.norm(b - a))
            if length < 1e-9:
                continue
            z = (b - a) / length
            x = np.cross([1.0, 0.0, 0.0] if abs(z[0]) < 0.9 else [0.0, 1.0, 0.0], z)
            x /= np.linalg.norm(x)
            T = np.eye(4)
            T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
            T[:3, 3] = 0.5 * (a + b)
            res = coal.DistanceResult()
            d = coal.distance(
                coal.Capsule(THIN_RADIUS_M, length), _coal_tf(T), obj.geometry, _coal_tf(obj.object2base), req, res
            )
            out[i] = min(out[i], d)
    return out


def _timed_samples(res) -> list[np.ndarray]:
    return [tr.q for tr in res.trajectories.values()]


@pytest.fixture(scope="module")
def plans(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("cell")
    bare = plan(_problem(tmp))
    with_cell = plan(_problem(tmp, TABLE))
    return bare, with_cell


def test_stiffness_best_branch_goes_through_the_table_without_the_cell(plans):
    bare, with_cell = plans
    assert bare.ok and bare.problem.cell is None
    table = with_cell.problem.cell.object("table")
    d = _thin_distance(bare.problem, bare.exact.q_command, table)
    assert d.min() < 0.0  # the independent check can fail: it does on the plan made in empty space


def test_cell_plan_picks_a_collision_free_branch_and_reports_it(plans):
    bare, res = plans
    assert res.ok, res.reason
    ps = res.posture
    assert ps.chosen != bare.posture.chosen
    assert ps.branches[bare.posture.chosen].status is BranchStatus.COLLISION
    # the stiffness-best branch is the one the plan without the cell chose, and the choice says its price
    assert res.cell.stiffness_best == bare.posture.chosen
    assert "pays" in ps.reason and bare.posture.best.label in ps.reason
    assert ps.best.cost >= bare.posture.best.cost
    # every colliding branch's reason names a waypoint, a pair and millimetres
    for r in ps.branches.values():
        if r.status is BranchStatus.COLLISION:
            assert "table" in r.reason and "waypoint" in r.reason and "mm" in r.reason
    s = res.view().summary["cell"]
    assert s["clearance_mm"] == pytest.approx(5.0)
    assert s["waypoints"]["status"] == "ok" and s["trajectory"]["status"] == "ok"
    assert s["waypoints"]["min_clearance_mm"] >= 5.0 and s["trajectory"]["min_clearance_mm"] >= 5.0
    assert s["trajectory"]["method"] == res.controller and s["trajectory"]["time_s"] is not None
    assert s["deflection_margin_mm"] > 0.0


def test_every_waypoint_and_timed_sample_keeps_the_clearance_by_an_independent_check(plans):
    _, res = plans
    cell = res.problem.cell
    for obj in cell.objects:
        for q in [res.exact.q_command, res.posture.best.q, *_timed_samples(res)]:
            assert _thin_distance(res.problem, q, obj).min() >= cell.clearance


def test_a_cell_no_branch_can_avoid_fails_with_the_pair_named(tmp_path):
    base = _problem(tmp_path)
    T = np.eye(4)
    T[:3, 3] = [0.75, 0.0, 0.225]  # a plate the tool must pass through, 0.08-0.13 m above the path
    plate = CellObject("plate", "box", np.array([0.1, 1.2, 0.05]), T)
    problem = replace(base, cell=Cell((plate,), 0.005))
    res = plan(problem, optimise=False)
    assert res.status is PlanStatus.COLLISION
    assert "tool – plate" in res.reason and "waypoint" in res.reason
    assert all(r.status is BranchStatus.COLLISION for r in res.posture.branches.values())
    # independently: every branch's tool really passes through the plate
    for r in res.posture.branches.values():
        assert _thin_distance(problem, r.q, plate).min() < 0.0


SWEEP = PROBLEM.replace(
    """kind = "line"
start = [0.75, -0.35, 0.12]
end = [0.75, 0.35, 0.12]
points = 8""",
    """kind = "waypoints"
positions = [[0.75, -0.35, 0.12], [0.0, 0.75, 0.12]]""",
).replace("max_joint_step = 0.3", "max_joint_step = 3.0")


def test_a_trajectory_closer_than_the_clearance_between_waypoints_fails_with_time_and_pair(tmp_path):
    """An obstacle the waypoints clear but the timed motion between them meets."""
    f = tmp_path / "sweep.toml"
    f.write_text(SWEEP.format(cell=""))
    bare = plan(load_problem(str(f)))
    assert bare.ok, bare.reason
    tr = bare.trajectories[bare.controller]
    elbow = _chain_points(bare.problem, tr.q)[:, 3]  # frame 3's origin at every sample
    point = [CellObject("p", "sphere", np.array([1e-3]), _at(e)) for e in elbow]
    gap = np.array([_thin_distance(bare.problem, bare.exact.q_command, o).min() for o in point])
    i = int(np.argmax(gap))  # the sample whose elbow is farthest from every waypoint's chain
    radius = gap[i] - 0.11  # every real capsule (radius <= 0.095 m) keeps > 5 mm at the waypoints
    assert radius > 0.01
    ball = CellObject("ball", "sphere", np.array([radius]), _at(elbow[i]))
    problem = replace(bare.problem, cell=Cell((ball,), 0.005))
    res = plan(problem)
    # the waypoints clear the ball (the NLP, now with the ball's clearance constraint, may settle in
    # another local optimum and choose another branch: what matters is that its waypoints are clear)
    assert res.cell.waypoints.status is ClearanceStatus.OK
    assert res.status is PlanStatus.COLLISION
    assert "t = " in res.reason and "ball" in res.reason
    assert _thin_distance(problem, tr.q, ball).min() < 0.0  # independently


def _at(p: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = p
    return T


def test_the_shipped_cell_problem_shows_the_choice():
    """problems/files/cell_table.toml: the stiffness-best branch goes through the table; the plan
    takes the best collision-free one, says what it pays, and every waypoint and timed sample keeps
    the clearance by the independent check."""
    res = plan(load_problem("cell_table"))
    assert res.ok, res.reason
    best = res.cell.stiffness_best
    assert best is not None and best != res.posture.chosen
    assert res.posture.branches[best].status is BranchStatus.COLLISION
    assert "pays" in res.posture.reason
    cell = res.problem.cell
    for obj in cell.objects:
        for q in [res.exact.q_command, *_timed_samples(res)]:
            d = _thin_distance(res.problem, q, obj, skip_tool=obj.role == "workpiece")
            assert d.min() >= cell.clearance, obj.name


def test_a_branch_whose_trajectory_alone_meets_the_cell_is_set_aside_and_the_next_planned(tmp_path):
    """Three waypoints 0.35 m apart: a small ball on the path link 5 sweeps between two waypoints
    (the waypoints clear it); the plan sets that branch aside with the time and the pair and plans
    the next branch, whose trajectory keeps the clearance by the independent check."""
    f = tmp_path / "three.toml"
    f.write_text(
        (Path(__file__).parents[1] / "problems/files/cell_table.toml").read_text().replace("points = 29", "points = 3")
    )
    problem = load_problem(str(f))
    base = plan(problem)
    assert base.ok, base.reason
    tr = base.trajectories[base.controller]
    geom = cell_geometry(problem.robot, problem.cell)
    c = geom.names.index("link 5")
    ball = CellObject(
        "ball", "sphere", np.array([0.005]), _at(segments(geom, tr.q)[int(0.3 * len(tr.t)), c].mean(axis=0))
    )
    res = plan(replace(problem, cell=Cell(problem.cell.objects + (ball,), 0.005)))
    assert res.ok, res.reason
    aside = [r for r in res.posture.branches.values() if "controller's trajectory" in r.reason]
    assert aside and all(r.status is BranchStatus.COLLISION for r in aside)
    assert any("set aside" in w and "ball" in w and "t = " in w for w in res.warnings)
    assert res.posture.chosen != base.posture.chosen
    final = res.trajectories[res.controller]
    assert res.cell.trajectory.status is ClearanceStatus.OK
    assert _thin_distance(res.problem, final.q, ball).min() > 0.0  # independently
