"""Problem files: the shipped problems load, round-trip, and every malformed input is named."""

from __future__ import annotations

import math
import shutil
import tomllib
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from models import load_robot
from models.constants import PLAUSIBLE_POSITION_MAX_M
from problems import paper
from problems.posture import OrientationRule
from problems.problem import ProblemFileError, load_problem, problem_from_dict, shipped_problems
from problems.timing import DT_DEFAULT_S, default_methods

SHIPPED = {
    "paper_4_4": (OrientationRule.FIXED, 40),
    "paper_5_2_points": (OrientationRule.FIXED, 11),
    "machining_offaxis": (OrientationRule.FREE_TOOL_AXIS, 40),
    "drilling_cone": (OrientationRule.CONE, 9),
    "measuring_position_only": (OrientationRule.POSITION_ONLY, 30),
    "ur10_payload_tilt": (OrientationRule.FIXED, 11),
    "ur5_tool_thrust": (OrientationRule.CONE, 20),
    "milling_pocket": (OrientationRule.FREE_TOOL_AXIS, None),  # a program: its waypoints depend on its stops
    "kr6_milling": (OrientationRule.CONE, 30),
    "ur5_fast_payload": (OrientationRule.FIXED, 24),
    "placement_milling": (OrientationRule.FREE_TOOL_AXIS, 30),
    "cell_table": (OrientationRule.CONE, 29),
    "milling_pocket_cell": (OrientationRule.FREE_TOOL_AXIS, None),  # milling_pocket in a cell
}

MINIMAL = """
name = "t"
[robot]
model = "ar5"
[path]
kind = "line"
start = [0.3, -0.1, 0.3]
end = [0.3, 0.1, 0.3]
points = 5
[orientation]
rule = "free_tool_axis"
[wrench]
force = [0.0, 0.0, -10.0]
"""


def _write(tmp_path: Path, text: str, name: str = "p.toml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def test_shipped_problems_load_with_their_rule_and_size():
    assert set(shipped_problems()) == set(SHIPPED)
    for name, (rule, n) in SHIPPED.items():
        pr = load_problem(name)
        assert pr.rule is rule and (pr.n == n if n is not None else pr.n > 10_000)
        n = pr.n
        assert pr.positions.shape == (n, 3) and pr.rotations.shape == (n, 3, 3) and pr.wrench.shape == (n, 6)
        assert np.allclose(np.einsum("nji,njk->nik", pr.rotations, pr.rotations), np.eye(3))


def test_paper_problem_is_the_papers_scenario():
    pr = load_problem("paper_4_4")
    assert np.allclose(pr.positions[0], paper.SECTION_4_4_START_M)
    assert np.allclose(pr.positions[-1], paper.SECTION_4_4_END_M)
    assert np.allclose(pr.wrench, paper.SECTION_4_4_WRENCH)
    assert np.allclose(pr.home_q, paper.HOME_Q)
    assert np.allclose(pr.robot.tcp2flange, np.eye(4))
    assert np.allclose(pr.rotations[0][:, 2], [0.0, 0.0, -1.0])  # tool down


def test_off_axis_problems_have_their_tool():
    assert np.allclose(load_problem("machining_offaxis").robot.tcp2flange[:3, 3], [0.1, 0.0, 0.05])
    dr = load_problem("drilling_cone")
    assert math.isclose(dr.cone_half_angle, math.radians(20.0))
    assert dr.wrench_per_waypoint and np.ptp(dr.wrench[:, 2]) > 0


@pytest.mark.parametrize("name", sorted(SHIPPED))
def test_to_dict_round_trips(name):
    pr = load_problem(name)
    again = problem_from_dict(pr.to_dict(), "round-trip")
    for key in ("positions", "rotations", "wrench", "home_q"):
        assert np.allclose(getattr(again, key), getattr(pr, key), atol=1e-12), key
    assert again.rule is pr.rule and again.n == pr.n and again.scan == pr.scan
    assert math.isclose(again.cone_half_angle, pr.cone_half_angle)
    for key in ("velocity", "acceleration", "jerk"):
        assert np.allclose(getattr(again.limits, key), getattr(pr.limits, key))
    assert np.allclose(again.robot.tcp2flange, pr.robot.tcp2flange)
    assert again.timing == pr.timing and again.solver == pr.solver


def test_defaults_come_from_the_robot_and_the_paper(tmp_path):
    pr = load_problem(_write(tmp_path, MINIMAL))
    robot = load_robot("ar5")
    assert np.allclose(pr.limits.velocity, robot.v_max) and np.allclose(pr.limits.jerk, robot.j_max)
    assert pr.timing.dt == DT_DEFAULT_S and pr.timing.methods == default_methods()
    assert np.allclose(pr.home_q, paper.HOME_Q)
    assert np.allclose(pr.rotations[:, :, 2], [0.0, 0.0, -1.0])  # default: tool down
    assert np.allclose(pr.wrench[:, 2], -10.0) and np.allclose(pr.wrench[:, 3:], 0.0)


def test_units_scales_axis_and_relative_robot_path(tmp_path):
    robot_file = tmp_path / "arm.toml"
    shutil.copyfile(resources.files("models").joinpath("robots/ur5.toml"), robot_file)
    text = MINIMAL.replace(
        'model = "ar5"', 'model = "arm.toml"\ntool = { xyz = [0.0, 0.0, 0.1], rpy_deg = [0, 0, 90] }'
    )
    text = text.replace('rule = "free_tool_axis"', 'rule = "cone"\naxis = [1.0, 0.0, 0.0]\nhalf_angle_deg = 10')
    text += "[limits]\nvelocity_scale = 0.5\njerk = 20.0\nmax_joint_step_deg = 10\n[timing]\ndt = 0.002\n"
    pr = load_problem(_write(tmp_path / "", text))
    assert pr.robot.name == "ur5"
    assert np.allclose(pr.robot.tcp2flange[:3, 3], [0.0, 0.0, 0.1])
    assert np.allclose(pr.rotations[0][:, 2], [1.0, 0.0, 0.0])
    assert math.isclose(pr.cone_half_angle, math.radians(10))
    assert np.allclose(pr.limits.velocity, 0.5 * load_robot("ur5").v_max)
    assert np.allclose(pr.limits.jerk, 20.0)
    assert math.isclose(pr.limits.max_joint_step, math.radians(10))
    assert pr.timing.dt == 0.002


def test_with_points_resamples_a_line_and_refuses_waypoints():
    pr = load_problem("paper_4_4").with_points(7)
    assert pr.n == 7 and np.allclose(pr.positions[-1], paper.SECTION_4_4_END_M)
    with pytest.raises(ProblemFileError, match="line path"):
        load_problem("paper_5_2_points").with_points(5)
    with pytest.raises(ProblemFileError, match="path.points"):
        load_problem("paper_4_4").with_points(1)
    with pytest.raises(ProblemFileError, match="timing.dt"):
        load_problem("paper_4_4").with_timing(dt=0.5)


BAD = [
    # (replace this, by this, expected words in the message)
    ('name = "t"', 'name = "t"\ncolour = "red"', ["unknown top-level key", "colour"]),
    ("points = 5", "points = 1", ["path.points", "integer >= 2", "got 1"]),
    ("points = 5", "points = 5.5", ["path.points", "5.5"]),
    ('kind = "line"', 'kind = "spline"', ["path.kind", "['line', 'waypoints', 'gcode', 'toolpath_csv']", "spline"]),
    ('rule = "free_tool_axis"', 'rule = "free"', ["orientation.rule", "position_only", "'free'"]),
    ('rule = "free_tool_axis"', 'rule = "cone"', ["orientation.half_angle_deg", "required"]),
    ('rule = "free_tool_axis"', 'rule = "cone"\nhalf_angle_deg = 95', ["half_angle_deg", "(0, 90)"]),
    ('rule = "free_tool_axis"', 'rule = "fixed"\naxis = [0, 0, 1]', ["orientation.axis", "fixed"]),
    ('rule = "free_tool_axis"', 'rule = "free_tool_axis"\naxis = [0, 0, 0]', ["orientation.axis", "non-zero"]),
    ('rule = "free_tool_axis"', 'rule = "free_tool_axis"\nrpy = [0,0,0]\nrpy_deg = [0,0,0]', ["either", "rpy"]),
    ("start = [0.3, -0.1, 0.3]", "start = [300.0, -100.0, 300.0]", ["path.start/end", "metres", "millimetres"]),
    ("start = [0.3, -0.1, 0.3]", "start = [0.3, -0.1]", ["path.start", "list of 3 numbers"]),
    ("end = [0.3, 0.1, 0.3]", "end = [0.3, -0.1, 0.3]", ["path.end", "distinct"]),
    ("force = [0.0, 0.0, -10.0]", 'force = [0.0, 0.0, "x"]', ["wrench.force[2]", "number"]),
    (
        "force = [0.0, 0.0, -10.0]",
        "per_waypoint = [[0, 0, 1, 0, 0, 0]]",
        ["wrench.per_waypoint", "1 rows", "5 waypoints"],
    ),
    ("force = [0.0, 0.0, -10.0]", 'force = [0,0,1]\nframe = "world"', ["wrench.frame", "'tool'"]),
    ("force = [0.0, 0.0, -10.0]", "force = [0,0,1]\n[payload]\ncom_m = [0,0,0.1]", ["payload.mass_kg"]),
    ("force = [0.0, 0.0, -10.0]", "force = [0,0,1]\n[payload]\nmass_kg = -2.0", ["payload.mass_kg", ">= 0"]),
    (
        "force = [0.0, 0.0, -10.0]",
        "force = [0,0,1]\n[payload]\nmass_kg = 2.0\ncom_m = [0, 0, 120]",
        ["payload.com_m", "millimetres"],
    ),
    ('model = "ar5"', 'model = "nosuch.toml"', ["robot.model", "no such file"]),
    ('model = "ar5"', "model = 5", ["robot.model", "built-in robot name"]),
    (
        "force = [0.0, 0.0, -10.0]",
        "force = [0.0, 0.0, -10.0]\n[limits]\nvelocity = [1, 1, 1, 1, 0, 1]",
        ["limits.velocity", "joint 5", "> 0"],
    ),
    (
        "force = [0.0, 0.0, -10.0]",
        'force = [0.0, 0.0, -10.0]\n[timing]\nmethods = ["toppra", "bang"]',
        ["timing.methods", "bang"],
    ),
    ("force = [0.0, 0.0, -10.0]", "force = [0.0, 0.0, -10.0]\n[timing]\ndt = 0.5", ["timing.dt", "(0, 0.1]"]),
    ("force = [0.0, 0.0, -10.0]", 'force = [0.0, 0.0, -10.0]\n[solver]\nname = "snopt"', ["solver.name", "ipopt"]),
    ("force = [0.0, 0.0, -10.0]", "force = [0.0, 0.0, -10.0]\n[cost]\nsmoothness = -1", ["cost.smoothness", ">= 0"]),
    (
        "force = [0.0, 0.0, -10.0]",
        "force = [0.0, 0.0, -10.0]\n[branch]\nhome_deg = [0, 1]",
        ["branch.home_deg", "6 numbers"],
    ),
    # gravity checked like positions (issue 24): 10 g, and cm/s^2
    (
        "force = [0.0, 0.0, -10.0]",
        "force = [0.0, 0.0, -10.0]\n[payload]\nmass_kg = 1.0\ngravity_m_s2 = [0.0, 0.0, -98.0665]",
        ["payload.gravity_m_s2", "98.0665", "implausible", "multiple of g"],
    ),
    (
        "force = [0.0, 0.0, -10.0]",
        "force = [0.0, 0.0, -10.0]\n[payload]\nmass_kg = 1.0\ngravity_m_s2 = [0.0, 0.0, -980.665]",
        ["payload.gravity_m_s2", "cm/s^2 given?"],
    ),
]


@pytest.mark.parametrize("old,new,words", BAD, ids=[b[1].split("\n")[-1][:30] for b in BAD])
def test_malformed_files_are_named(tmp_path, old, new, words):
    assert old in MINIMAL
    p = _write(tmp_path, MINIMAL.replace(old, new))
    with pytest.raises(ProblemFileError) as exc:
        load_problem(p)
    msg = str(exc.value)
    assert "\n" not in msg and str(p) in msg
    for w in words:
        assert w in msg, (w, msg)


def test_waypoints_kind_rows_are_named(tmp_path):
    text = MINIMAL.replace(
        'kind = "line"\nstart = [0.3, -0.1, 0.3]\nend = [0.3, 0.1, 0.3]\npoints = 5',
        'kind = "waypoints"\npositions = [[0.3, 0.0, 0.3], [0.3, 0.1]]',
    )
    with pytest.raises(ProblemFileError, match=r"path.positions' row 1"):
        load_problem(_write(tmp_path, text))
    text = text.replace("[0.3, 0.1]]", "[0.3, 0.1, 0.3]]\nrpy_deg = [[180, 0, 0]]")
    with pytest.raises(ProblemFileError, match=r"path.rpy_deg.*1 rows.*has 2"):
        load_problem(_write(tmp_path, text))


def test_not_toml_and_unknown_names(tmp_path):
    with pytest.raises(ProblemFileError, match="not valid TOML"):
        load_problem(_write(tmp_path, "name = [unclosed"))
    with pytest.raises(ProblemFileError, match="not a shipped problem.*paper_4_4"):
        load_problem("no_such_problem")


def test_shipped_files_parse_as_plain_toml():
    for name in shipped_problems():
        data = tomllib.loads(resources.files("problems").joinpath(f"files/{name}.toml").read_text())
        assert data["name"] == name
        assert np.all(np.abs(np.asarray(load_problem(name).positions)) < PLAUSIBLE_POSITION_MAX_M)


def test_the_starter_file_shows_the_posture_optimisation_working():
    """docs/examples/my_task.toml is what users copy (issue 24): its tool is off the flange axis, so the
    free rotation about the tool axis moves the arm (on the axis it would be 'degenerate')."""
    from problems.posture import analyse_freedom

    pr = load_problem(Path(__file__).resolve().parents[1] / "docs/examples/my_task.toml")
    freedom, note = analyse_freedom(pr.robot, pr.rule)
    assert freedom == "free", note
