"""Issue 9: a campaign of bad inputs, over every command.

Every case is something a new user gets wrong (a malformed or mistyped file, a wrong unit, a
wrong option value, a path that is a folder, ...).  Each must end with exit status 2 and
exactly one line on stderr, ``compplan: error: ...``, naming what is wrong (file, line/row or
key, the value and what was expected), without a traceback or a NumPy repr
(``np.float64(...)``), and with nothing written (no partial output) and nothing destroyed
(an existing file at an output path is left as it was).

The cases run in-process through :func:`planner.cli.main` (fast); argparse errors raise
``SystemExit(2)``, which the runner turns into the exit status.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

import planner.cli as cli
from planner.cli import main as cli_main

# --------------------------------------------------------------------------------------
# Templates (valid inputs that the cases break one thing at a time)
# --------------------------------------------------------------------------------------

UR5 = resources.files("models").joinpath("robots/ur5.toml").read_text(encoding="utf-8")

PROBLEM = """\
name = "bad_inputs"
[robot]
model = "ar5"
[path]
kind = "line"
start = [0.207, 0.444, 0.631]
end = [-0.137, 0.069, 0.241]
points = 5
[orientation]
rule = "fixed"
rpy_deg = [180.0, 0.0, 0.0]
[wrench]
force = [5.0, 10.0, 20.0]
moment = [0.0, 0.0, 0.0]
[limits]
max_joint_step = 1.0
[branch]
home_deg = [0.0, -90.0, 90.0, -90.0, -90.0, 0.0]
[timing]
methods = ["toppra", "ruckig"]
dt = 0.008
"""

CMD_HEADER = "q1,q2,q3,q4,q5,q6,fx,fy,fz,mx,my,mz"
CMD_ROWS = [
    "0.1,-1.2,1.4,-0.5,-1.5,0.3,0,0,-50,0,0,0",
    "0.2,-1.1,1.3,-0.6,-1.4,0.2,20,0,0,0,0,0",
    "-0.3,-1.4,1.6,-0.4,-1.6,0.1,0,30,0,0,0,0",
]
CMDS = CMD_HEADER + "\n" + "\n".join(CMD_ROWS) + "\n"

MEAS_HEADER = "q1,q2,q3,q4,q5,q6,fx,fy,fz,mx,my,mz,x,y,z"
MEAS_ROWS = [
    "0.1,-1.2,1.3,-0.5,-1.5,0.2,0,0,-50,0,0,0,0.40,0.11,0.52",
    "0.2,-1.1,1.2,-0.6,-1.4,0.3,10,0,0,0,0,0,0.41,0.12,0.51",
    "0.3,-1.0,1.1,-0.7,-1.3,0.4,0,10,0,0,0,0,0.42,0.13,0.50",
]
MEAS = MEAS_HEADER + "\n" + "\n".join(MEAS_ROWS) + "\n"

SIM = """\
seed = 3
[campaign]
poses = 20
loaded_rows = 1
[noise]
sigma_m = 2e-5
"""

#: Bytes that are not UTF-8 (Latin-1 degree sign in a comment, then binary junk).
LATIN1_COMMENT = "# Winkel in \u00b0\n".encode("latin-1")
BINARY = bytes(range(256)) * 4


def sub(text: str, *pairs: tuple[str, str], count: int = 1) -> str:
    """``text`` with each ``old`` replaced by ``new`` (``old`` must occur: the case stays honest)."""
    for old, new in pairs:
        assert old in text, f"template has no {old!r}"
        text = text.replace(old, new, count)
    return text


def drop_last_joint(robot_text: str) -> str:
    """The robot file with its last ``[[joints]]`` table removed (5 joints)."""
    k = robot_text.rfind("[[joints]]")
    return robot_text[:k]


def problem(*pairs: tuple[str, str]) -> str:
    return sub(PROBLEM, *pairs)


def robot(*pairs: tuple[str, str], count: int = 1) -> str:
    return sub(UR5, *pairs, count=count)


def meas(*pairs: tuple[str, str]) -> str:
    return sub(MEAS, *pairs)


def cmds(*pairs: tuple[str, str]) -> str:
    return sub(CMDS, *pairs)


def sim(*pairs: tuple[str, str], extra: str = "") -> str:
    return sub(SIM, *pairs) + extra


# --------------------------------------------------------------------------------------
# The cases
# --------------------------------------------------------------------------------------

Content = str | bytes | None  # None: a folder


@dataclass
class Case:
    """One bad input.

    ``argv`` may use ``{t}`` (the case's own folder, holding ``files``) and ``{fx}`` (the
    shared fixtures: ``meas.csv`` a valid measurement file, ``cmds.csv`` a valid command
    file, ``sim.toml`` a valid simulation configuration, ``robot.toml`` the UR5 file,
    ``problem.toml`` a valid problem).  ``outputs`` (relative to ``{t}``) must not exist
    afterwards, or be unchanged when the case created them; ``expect`` are fragments the
    message must contain (case-insensitive).
    """

    id: str
    argv: list[str]
    files: dict[str, Content] = field(default_factory=dict)
    outputs: list[str] = field(default_factory=list)
    expect: list[str] = field(default_factory=list)


def C(
    id: str,
    argv: str,
    files: dict[str, Content] | None = None,
    outputs: list[str] | None = None,
    expect: list[str] | None = None,
) -> Case:
    return Case(id, argv.split(), files or {}, outputs or [], expect or [])


P = "plan {t}/p.toml --out {t}/out --no-report"

PLAN = [
    C(
        "plan-no-such-file",
        "plan {t}/missing.toml --out {t}/out",
        outputs=["out"],
        expect=["missing.toml", "no such file"],
    ),
    C("plan-directory-as-problem", "plan {t}/dir --out {t}/out", {"dir": None}, ["out"], ["dir", "folder"]),
    C("plan-empty-file", P, {"p.toml": ""}, ["out"], ["p.toml", "name"]),
    C(
        "plan-malformed-toml",
        P,
        {"p.toml": problem(("points = 5", "points = = 5"))},
        ["out"],
        ["p.toml", "TOML", "line"],
    ),
    C("plan-binary-file", P, {"p.toml": BINARY}, ["out"], ["p.toml", "binary", "UTF-8"]),
    C(
        "plan-latin1-comment",
        P,
        {"p.toml": LATIN1_COMMENT + PROBLEM.encode()},
        ["out"],
        ["p.toml", "line 1, column 13", "UTF-8"],
    ),
    C("plan-unknown-top-key", P, {"p.toml": "nmae = 'x'\n" + PROBLEM}, ["out"], ["nmae"]),
    C(
        "plan-unknown-path-key",
        P,
        {"p.toml": problem(("points = 5", "points = 5\npionts = 5"))},
        ["out"],
        ["pionts", "path"],
    ),
    C("plan-name-not-string", P, {"p.toml": problem(('name = "bad_inputs"', "name = 3"))}, ["out"], ["'name'", "3"]),
    C("plan-points-1", P, {"p.toml": problem(("points = 5", "points = 1"))}, ["out"], ["path.points", "1"]),
    C("plan-points-float", P, {"p.toml": problem(("points = 5", "points = 5.5"))}, ["out"], ["path.points", "5.5"]),
    C("plan-points-string", P, {"p.toml": problem(("points = 5", 'points = "5"'))}, ["out"], ["path.points", "'5'"]),
    C("plan-start-nan", P, {"p.toml": problem(("start = [0.207", "start = [nan"))}, ["out"], ["path.start[0]", "nan"]),
    C("plan-start-inf", P, {"p.toml": problem(("start = [0.207", "start = [inf"))}, ["out"], ["path.start[0]", "inf"]),
    C(
        "plan-start-mm",
        P,
        {"p.toml": problem(("start = [0.207, 0.444, 0.631]", "start = [207.0, 444.0, 631.0]"))},
        ["out"],
        ["path.start", "millimetres"],
    ),
    C(
        "plan-start-two-numbers",
        P,
        {"p.toml": problem(("start = [0.207, 0.444, 0.631]", "start = [0.207, 0.444]"))},
        ["out"],
        ["path.start", "3 numbers"],
    ),
    C(
        "plan-start-equals-end",
        P,
        {"p.toml": problem(("end = [-0.137, 0.069, 0.241]", "end = [0.207, 0.444, 0.631]"))},
        ["out"],
        ["path.end", "distinct"],
    ),
    C(
        "plan-kind-unknown",
        P,
        {"p.toml": problem(('kind = "line"', 'kind = "spline"'))},
        ["out"],
        ["path.kind", "spline"],
    ),
    C(
        "plan-rule-unknown",
        P,
        {"p.toml": problem(('rule = "fixed"', 'rule = "free"'))},
        ["out"],
        ["orientation.rule", "free"],
    ),
    C(
        "plan-rpy-both-units",
        P,
        {"p.toml": problem(("rpy_deg = [180.0, 0.0, 0.0]", "rpy_deg = [180.0, 0.0, 0.0]\nrpy = [3.14, 0, 0]"))},
        ["out"],
        ["rpy", "not both"],
    ),
    C(
        "plan-rpy-degrees-in-radian-key",
        P,
        {"p.toml": problem(("rpy_deg = [180.0, 0.0, 0.0]", "rpy = [180.0, 0.0, 0.0]"))},
        ["out"],
        ["orientation.rpy", "180", "rpy_deg"],
    ),
    C(
        "plan-home-degrees-in-radian-key",
        P,
        {"p.toml": problem(("home_deg = [", "home = ["))},
        ["out"],
        ["branch.home", "home_deg"],
    ),
    C(
        "plan-joint-step-degrees-in-radian-key",
        P,
        {"p.toml": problem(("max_joint_step = 1.0", "max_joint_step = 30"))},
        ["out"],
        ["limits.max_joint_step", "30", "max_joint_step_deg"],
    ),
    C(
        "plan-half-angle-95",
        P,
        {"p.toml": problem(('rule = "fixed"', 'rule = "cone"\nhalf_angle_deg = 95'))},
        ["out"],
        ["half_angle", "95"],
    ),
    C(
        "plan-cone-without-half-angle",
        P,
        {"p.toml": problem(('rule = "fixed"', 'rule = "cone"'))},
        ["out"],
        ["half_angle"],
    ),
    C(
        "plan-wrench-missing-force",
        P,
        {"p.toml": problem(("force = [5.0, 10.0, 20.0]\n", ""))},
        ["out"],
        ["wrench.force"],
    ),
    C(
        "plan-wrench-force-strings",
        P,
        {"p.toml": problem(("force = [5.0, 10.0, 20.0]", 'force = ["5", "10", "20"]'))},
        ["out"],
        ["wrench.force[0]", "'5'"],
    ),
    C(
        "plan-wrench-per-waypoint-rows",
        P,
        {
            "p.toml": problem(
                ("force = [5.0, 10.0, 20.0]\nmoment = [0.0, 0.0, 0.0]", "per_waypoint = [[0, 0, 1, 0, 0, 0]]")
            )
        },
        ["out"],
        ["wrench.per_waypoint", "1 rows", "5 waypoints"],
    ),
    C(
        "plan-wrench-frame",
        P,
        {"p.toml": problem(("[wrench]", '[wrench]\nframe = "world"'))},
        ["out"],
        ["wrench.frame", "world"],
    ),
    C(
        "plan-payload-negative",
        P,
        {"p.toml": PROBLEM + "[payload]\nmass_kg = -2.0\n"},
        ["out"],
        ["payload.mass_kg", "-2"],
    ),
    C(
        "plan-payload-com-mm",
        P,
        {"p.toml": PROBLEM + "[payload]\nmass_kg = 2.0\ncom_m = [0, 0, 80]\n"},
        ["out"],
        ["payload.com_m", "millimetres"],
    ),
    C(
        "plan-velocity-negative",
        P,
        {"p.toml": problem(("max_joint_step = 1.0", "max_joint_step = 1.0\nvelocity = -1.0"))},
        ["out"],
        ["limits.velocity", "-1"],
    ),
    C(
        "plan-velocity-zero",
        P,
        {"p.toml": problem(("max_joint_step = 1.0", "max_joint_step = 1.0\nvelocity = 0"))},
        ["out"],
        ["limits.velocity", "> 0"],
    ),
    C(
        "plan-velocity-five-numbers",
        P,
        {"p.toml": problem(("max_joint_step = 1.0", "max_joint_step = 1.0\nvelocity = [1, 1, 1, 1, 1]"))},
        ["out"],
        ["limits.velocity", "6 numbers"],
    ),
    C(
        "plan-velocity-scale-zero",
        P,
        {"p.toml": problem(("max_joint_step = 1.0", "max_joint_step = 1.0\nvelocity_scale = 0.0"))},
        ["out"],
        ["limits.velocity_scale", "> 0"],
    ),
    C(
        "plan-sample-cap",
        P,
        {"p.toml": problem(("max_joint_step = 1.0", "max_joint_step = 1.0\nvelocity = 1e-9"))},
        ["out"],
        ["samples", "MAX_TRAJECTORY_SAMPLES", "dt"],
    ),
    C("plan-timing-dt-zero", P, {"p.toml": problem(("dt = 0.008", "dt = 0"))}, ["out"], ["timing.dt", "0"]),
    C("plan-timing-dt-large", P, {"p.toml": problem(("dt = 0.008", "dt = 8"))}, ["out"], ["timing.dt", "8"]),
    C(
        "plan-timing-method-unknown",
        P,
        {"p.toml": problem(('methods = ["toppra", "ruckig"]', 'methods = ["spline"]'))},
        ["out"],
        ["timing.methods", "spline"],
    ),
    C(
        "plan-timing-methods-empty",
        P,
        {"p.toml": problem(('methods = ["toppra", "ruckig"]', "methods = []"))},
        ["out"],
        ["timing.methods"],
    ),
    C("plan-solver-name", P, {"p.toml": PROBLEM + '[solver]\nname = "snopt"\n'}, ["out"], ["solver.name", "snopt"]),
    C("plan-solver-tol-negative", P, {"p.toml": PROBLEM + "[solver]\ntol = -1e-8\n"}, ["out"], ["solver.tol"]),
    C(
        "plan-solver-codegen-string",
        P,
        {"p.toml": PROBLEM + '[solver]\ncodegen = "yes"\n'},
        ["out"],
        ["solver.codegen", "yes"],
    ),
    C(
        "plan-smoothness-negative",
        P,
        {"p.toml": PROBLEM + "[cost]\nsmoothness = -1\n"},
        ["out"],
        ["cost.smoothness", "-1"],
    ),
    C(
        "plan-home-five-numbers",
        P,
        {
            "p.toml": problem(
                ("home_deg = [0.0, -90.0, 90.0, -90.0, -90.0, 0.0]", "home_deg = [0.0, -90.0, 90.0, -90.0, -90.0]")
            )
        },
        ["out"],
        ["branch.home_deg", "6 numbers"],
    ),
    C(
        "plan-robot-missing-file",
        P,
        {"p.toml": problem(('model = "ar5"', 'model = "myrobot.toml"'))},
        ["out"],
        ["robot.model", "myrobot.toml"],
    ),
    C(
        "plan-robot-5-joints",
        P,
        {"p.toml": problem(('model = "ar5"', 'model = "r.toml"')), "r.toml": drop_last_joint(UR5)},
        ["out"],
        ["r.toml", "joints", "5"],
    ),
    C(
        "plan-tool-mm",
        P,
        {"p.toml": problem(('model = "ar5"', 'model = "ar5"\ntool = { xyz = [0, 0, 150] }'))},
        ["out"],
        ["robot.tool.xyz", "millimetres"],
    ),
    C(
        "plan-outside-reach",
        P,
        {"p.toml": problem(("start = [0.207, 0.444, 0.631]", "start = [3.0, 0.0, 0.3]"))},
        ["out"],
        ["waypoint", "unreachable"],
    ),
    C("plan-dt-zero", P + " --dt 0", {"p.toml": PROBLEM}, ["out"], ["--dt", "0"]),
    C("plan-dt-negative", P + " --dt -0.01", {"p.toml": PROBLEM}, ["out"], ["--dt", "-0.01"]),
    C("plan-dt-text", P + " --dt fast", {"p.toml": PROBLEM}, ["out"], ["--dt", "fast"]),
    C("plan-dt-nan", P + " --dt nan", {"p.toml": PROBLEM}, ["out"], ["--dt", "nan"]),
    C(
        "plan-out-is-a-file",
        "plan {t}/p.toml --out {t}/out.txt",
        {"p.toml": PROBLEM, "out.txt": "keep me"},
        ["out.txt"],
        ["out.txt", "not a folder"],
    ),
    C("plan-robot-option-missing", P + " --robot nosuchrobot", {"p.toml": PROBLEM}, ["out"], ["nosuchrobot"]),
    C("plan-missing-out", "plan {t}/p.toml", {"p.toml": PROBLEM}, [], ["--out"]),
    C("plan-unknown-option", P + " --fast", {"p.toml": PROBLEM}, ["out"], ["--fast"]),
    C("plan-missing-problem", "plan --out {t}/out", {}, ["out"], ["problem"]),
    C(
        "plan-waypoints-two-numbers",
        P,
        {
            "p.toml": problem(
                ('kind = "line"', 'kind = "waypoints"\npositions = [[0.2, 0.4], [0.1, 0.3]]'),
                ("start = [0.207, 0.444, 0.631]\n", ""),
                ("end = [-0.137, 0.069, 0.241]\n", ""),
                ("points = 5\n", ""),
            )
        },
        ["out"],
        ["path.positions", "row 0", "3 numbers"],
    ),
    C(
        "plan-waypoints-empty",
        P,
        {
            "p.toml": problem(
                ('kind = "line"', 'kind = "waypoints"\npositions = []'),
                ("start = [0.207, 0.444, 0.631]\n", ""),
                ("end = [-0.137, 0.069, 0.241]\n", ""),
                ("points = 5\n", ""),
            )
        },
        ["out"],
        ["path.positions"],
    ),
    C(
        "plan-waypoints-mm",
        P,
        {
            "p.toml": problem(
                ('kind = "line"', 'kind = "waypoints"\npositions = [[207.0, 444.0, 631.0], [-137.0, 69.0, 241.0]]'),
                ("start = [0.207, 0.444, 0.631]\n", ""),
                ("end = [-0.137, 0.069, 0.241]\n", ""),
                ("points = 5\n", ""),
            )
        },
        ["out"],
        ["path.positions", "row 0", "millimetres"],
    ),
    C("plan-robot-section-missing", P, {"p.toml": problem(('[robot]\nmodel = "ar5"\n', ""))}, ["out"], ["robot.model"]),
    C("plan-robot-model-number", P, {"p.toml": problem(('model = "ar5"', "model = 5"))}, ["out"], ["robot.model", "5"]),
    C(
        "plan-force-nan",
        P,
        {"p.toml": problem(("force = [5.0, 10.0, 20.0]", "force = [5.0, nan, 20.0]"))},
        ["out"],
        ["wrench.force[1]", "nan"],
    ),
    C(
        "plan-per-waypoint-five-columns",
        P,
        {
            "p.toml": problem(
                ("force = [5.0, 10.0, 20.0]\nmoment = [0.0, 0.0, 0.0]", "per_waypoint = [[0, 0, 1, 0, 0]]")
            )
        },
        ["out"],
        ["wrench.per_waypoint", "row 0", "6 numbers"],
    ),
    C(
        "plan-gravity-strings",
        P,
        {"p.toml": PROBLEM + '[payload]\nmass_kg = 1.0\ngravity_m_s2 = ["0", "0", "-9.8"]\n'},
        ["out"],
        ["payload.gravity_m_s2[0]", "'0'"],
    ),
    C(
        "plan-gridpoints-one",
        P,
        {"p.toml": problem(("dt = 0.008", "dt = 0.008\ntoppra_gridpoints = 1"))},
        ["out"],
        ["timing.toppra_gridpoints", "1"],
    ),
    C("plan-dt-string", P, {"p.toml": problem(("dt = 0.008", 'dt = "8 ms"'))}, ["out"], ["timing.dt", "8 ms"]),
    C(
        "plan-axis-zero",
        P,
        {
            "p.toml": problem(
                ('rule = "fixed"\nrpy_deg = [180.0, 0.0, 0.0]', 'rule = "free_tool_axis"\naxis = [0, 0, 0]')
            )
        },
        ["out"],
        ["orientation.axis", "non-zero"],
    ),
    C(
        "plan-axis-with-fixed-rule",
        P,
        {"p.toml": problem(("rpy_deg = [180.0, 0.0, 0.0]", "axis = [0, 0, -1]"))},
        ["out"],
        ["orientation.axis", "fixed"],
    ),
    C(
        "plan-scan-zero",
        P,
        {"p.toml": problem(('rule = "fixed"', 'rule = "fixed"\nscan = 0'))},
        ["out"],
        ["orientation.scan", "0"],
    ),
    C("plan-csv-given", P, {"p.toml": MEAS}, ["out"], ["p.toml", "TOML"]),
    C("plan-robot-file-given", P, {"p.toml": UR5}, ["out"], ["p.toml", "robot file"]),
    C(
        "plan-force-implausible",
        P,
        {"p.toml": problem(("force = [5.0, 10.0, 20.0]", "force = [5.0, 10.0, 2e6]"))},
        ["out"],
        ["wrench.force[2]", "2e+06", "N"],
    ),
    C("plan-dt-above-max", P + " --dt 0.5", {"p.toml": PROBLEM}, ["out"], ["--dt", "0.5"]),
    C("plan-shipped-name-typo", "plan paper_44 --out {t}/out", {}, ["out"], ["paper_44", "paper_4_4"]),
]

POSE = [
    C("pose-waypoint-out-of-range", "pose {t}/p.toml --waypoint 99", {"p.toml": PROBLEM}, [], ["--waypoint", "99"]),
    C("pose-waypoint-negative", "pose {t}/p.toml --waypoint -1", {"p.toml": PROBLEM}, [], ["--waypoint", "-1"]),
    C("pose-waypoint-text", "pose {t}/p.toml --waypoint first", {"p.toml": PROBLEM}, [], ["--waypoint", "first"]),
    C("pose-no-such-problem", "pose {t}/nope.toml", {}, [], ["nope.toml"]),
    C(
        "pose-robot-5-joints",
        "pose {t}/p.toml --robot {t}/r.toml --out {t}/out",
        {"p.toml": PROBLEM, "r.toml": drop_last_joint(UR5)},
        ["out"],
        ["r.toml", "joints"],
    ),
    C(
        "pose-out-is-a-file",
        "pose {t}/p.toml --out {t}/o.txt",
        {"p.toml": PROBLEM, "o.txt": "keep"},
        ["o.txt"],
        ["o.txt"],
    ),
]

DEMO = [
    C("demo-points-zero", "demo --out {t}/out --points 0 --no-report", {}, ["out"], ["points", "0"]),
    C("demo-points-one", "demo --out {t}/out --points 1 --no-report", {}, ["out"], ["points", "1"]),
    C("demo-points-negative", "demo --out {t}/out --points -3 --no-report", {}, ["out"], ["points", "-3"]),
    C("demo-points-text", "demo --out {t}/out --points many", {}, ["out"], ["--points", "many"]),
    C("demo-robot-missing", "demo --out {t}/out --robot ur3", {}, ["out"], ["ur3"]),
    C(
        "demo-robot-inverted-limits",
        "demo --out {t}/out --robot {t}/r.toml --no-report",
        {"r.toml": robot(("q_min_deg = -360.0", "q_min_deg = 400.0"))},
        ["out"],
        ["r.toml", "joints[1]", "q_min_deg", "400", "q_max_deg", "360"],
    ),
    C("demo-missing-out", "demo", {}, [], ["--out"]),
]

MAP = [
    C("map-points-zero", "map --out {t}/out --points 0", {}, ["out"], ["points", "0"]),
    C("map-points-one", "map --out {t}/out --points 1", {}, ["out"], ["points", "1"]),
    C("map-points-huge", "map --out {t}/out --points 100000", {}, ["out"], ["points", "100000"]),
    C("map-range-inverted", "map --out {t}/out --u-range-m 1 -1", {}, ["out"], ["range", "1", "-1"]),
    C("map-offset-nan", "map --out {t}/out --offset-m nan", {}, ["out"], ["offset", "nan"]),
    C("map-offset-inf", "map --out {t}/out --offset-m inf", {}, ["out"], ["offset", "inf"]),
    C("map-offset-mm", "map --out {t}/out --offset-m 300", {}, ["out"], ["offset", "300"]),
    C("map-branch-unknown", "map --out {t}/out --branch best", {}, ["out"], ["branch", "best"]),
    C("map-plane-unknown", "map --out {t}/out --plane w", {}, ["out"], ["--plane", "w"]),
    C("map-rpy-two-values", "map --out {t}/out --rpy-deg 180 0", {}, ["out"], ["--rpy-deg"]),
    C("map-rpy-both", "map --out {t}/out --rpy-deg 180 0 0 --rpy-rad 3 0 0", {}, ["out"], ["--rpy-rad"]),
    C("map-out-is-a-file", "map --out {t}/o.txt --points 5", {"o.txt": "keep"}, ["o.txt"], ["o.txt"]),
    C("map-missing-out", "map", {}, [], ["--out"]),
    C("map-range-empty", "map --out {t}/out --u-range-m 0.2 0.2", {}, ["out"], ["range", "0.2"]),
    C("map-points-float", "map --out {t}/out --points 2.5", {}, ["out"], ["--points", "2.5"]),
    C(
        "map-robot-problem-file-given",
        "map --robot {t}/r.toml --out {t}/out",
        {"r.toml": PROBLEM},
        ["out"],
        ["r.toml", "problem file"],
    ),
]

ROBOT_FILE = [  # every robot-file mistake, through ``compplan map --robot FILE`` (loads first)
    C(
        "robot-5-joints",
        "map --robot {t}/r.toml --out {t}/out",
        {"r.toml": drop_last_joint(UR5)},
        ["out"],
        ["r.toml", "joints", "6", "5"],
    ),
    C(
        "robot-7-joints",
        "map --robot {t}/r.toml --out {t}/out",
        {"r.toml": UR5 + UR5[UR5.rfind("[[joints]]") :]},
        ["out"],
        ["r.toml", "joints", "7"],
    ),
    C(
        "robot-limits-inverted-deg",
        "map --robot {t}/r.toml --out {t}/out",
        {"r.toml": robot(("q_max_deg = 360.0", "q_max_deg = -400.0"))},
        ["out"],
        ["joints[1]", "q_min_deg", "-360", "q_max_deg", "-400"],
    ),
    C(
        "robot-limits-inverted-rad",
        "map --robot {t}/r.toml --out {t}/out",
        {"r.toml": robot(("q_min_deg = -360.0\nq_max_deg = 360.0", "q_min = 1.0\nq_max = -1.0"))},
        ["out"],
        ["joints[1]", "q_min", "q_max", "-1"],
    ),
    C(
        "robot-limits-both-units",
        "map --robot {t}/r.toml --out {t}/out",
        {"r.toml": robot(("q_min_deg = -360.0", "q_min_deg = -360.0\nq_min = -6.0"))},
        ["out"],
        ["joints[1]", "q_min", "not both"],
    ),
    C(
        "robot-stiffness-negative",
        "map --robot {t}/r.toml --out {t}/out",
        {"r.toml": robot(("stiffness = 40000.0", "stiffness = -40000.0"))},
        ["out"],
        ["stiffness", "-40000"],
    ),
    C(
        "robot-stiffness-zero",
        "map --robot {t}/r.toml --out {t}/out",
        {"r.toml": robot(("stiffness = 40000.0", "stiffness = 0.0"))},
        ["out"],
        ["stiffness", "> 0"],
    ),
    C(
        "robot-vmax-nan",
        "map --robot {t}/r.toml --out {t}/out",
        {"r.toml": robot(("v_max = 3.141592653589793", "v_max = nan"))},
        ["out"],
        ["v_max", "nan"],
    ),
    C(
        "robot-vmax-string",
        "map --robot {t}/r.toml --out {t}/out",
        {"r.toml": robot(("v_max = 3.141592653589793", 'v_max = "fast"'))},
        ["out"],
        ["v_max", "fast"],
    ),
    C(
        "robot-length-mm",
        "map --robot {t}/r.toml --out {t}/out",
        {"r.toml": robot(("a = -0.425", "a = -425.0"))},
        ["out"],
        ["joints[2]", "'a'", "-425", "millimetres"],
    ),
    C(
        "robot-unknown-joint-key",
        "map --robot {t}/r.toml --out {t}/out",
        {"r.toml": robot(("stiffness = 40000.0", "stiffnes = 40000.0"))},
        ["out"],
        ["stiffnes"],
    ),
    C(
        "robot-missing-d",
        "map --robot {t}/r.toml --out {t}/out",
        {"r.toml": robot(("d = 0.089159  # m\n", ""))},
        ["out"],
        ["joints[1]", "'d'"],
    ),
    C(
        "robot-convention",
        "map --robot {t}/r.toml --out {t}/out",
        {"r.toml": robot(('convention = "standard_dh"', 'convention = "dh"'))},
        ["out"],
        ["convention", "'dh'"],
    ),
    C(
        "robot-name-missing",
        "map --robot {t}/r.toml --out {t}/out",
        {"r.toml": robot(('name = "ur5"\n', ""))},
        ["out"],
        ["name"],
    ),
    C(
        "robot-non-utf8",
        "map --robot {t}/r.toml --out {t}/out",
        {"r.toml": LATIN1_COMMENT + UR5.encode()},
        ["out"],
        ["r.toml", "line 1", "UTF-8"],
    ),
    C("robot-binary", "map --robot {t}/r.toml --out {t}/out", {"r.toml": BINARY}, ["out"], ["r.toml", "UTF-8"]),
    C(
        "robot-malformed-toml",
        "map --robot {t}/r.toml --out {t}/out",
        {"r.toml": robot(("[tool]", "[tool"))},
        ["out"],
        ["r.toml", "TOML"],
    ),
    C("robot-empty-file", "map --robot {t}/r.toml --out {t}/out", {"r.toml": ""}, ["out"], ["r.toml", "name"]),
    C("robot-directory", "map --robot {t}/r --out {t}/out", {"r": None}, ["out"], ["folder"]),
    C(
        "robot-joints-not-tables",
        "map --robot {t}/r.toml --out {t}/out",
        {"r.toml": 'name = "x"\nconvention = "standard_dh"\njoints = 6\n'},
        ["out"],
        ["joints", "6"],
    ),
    C(
        "robot-mass-without-com",
        "map --robot {t}/r.toml --out {t}/out",
        {"r.toml": robot(("com = [0.0, -0.02561, 0.00193]  # m, in DH link frame 1\n", ""))},
        ["out"],
        ["joints[1]", "mass", "com"],
    ),
    C(
        "robot-mass-negative",
        "map --robot {t}/r.toml --out {t}/out",
        {"r.toml": robot(("mass = 3.7", "mass = -3.7"))},
        ["out"],
        ["mass", "-3.7"],
    ),
    C(
        "robot-com-two-numbers",
        "map --robot {t}/r.toml --out {t}/out",
        {"r.toml": robot(("com = [0.0, -0.02561, 0.00193]", "com = [0.0, -0.02561]"))},
        ["out"],
        ["com", "3"],
    ),
    C(
        "robot-gravity-two-numbers",
        "map --robot {t}/r.toml --out {t}/out",
        {"r.toml": robot(("gravity = [0.0, 0.0, -9.80665]", "gravity = [0.0, -9.80665]"))},
        ["out"],
        ["gravity"],
    ),
    C(
        "robot-tool-rpy-both",
        "map --robot {t}/r.toml --out {t}/out",
        {"r.toml": robot(("rpy = [0.0, 0.0, 0.0]", "rpy = [0.0, 0.0, 0.0]\nrpy_deg = [0.0, 0.0, 0.0]"))},
        ["out"],
        ["tool", "rpy", "not both"],
    ),
    C(
        "robot-tool-rpy-degrees-in-radians",
        "map --robot {t}/r.toml --out {t}/out",
        {"r.toml": robot(("rpy = [0.0, 0.0, 0.0]", "rpy = [180.0, 0.0, 0.0]"))},
        ["out"],
        ["rpy", "180", "rpy_deg"],
    ),
    C(
        "robot-alpha-degrees-in-radians",
        "map --robot {t}/r.toml --out {t}/out",
        {"r.toml": robot(("alpha_deg = 90.0", "alpha = 90.0"))},
        ["out"],
        ["joints[1]", "alpha", "90", "alpha_deg"],
    ),
    C(
        "robot-limits-degrees-in-radians",
        "map --robot {t}/r.toml --out {t}/out",
        {"r.toml": robot(("q_min_deg = -360.0\nq_max_deg = 360.0", "q_min = -360.0\nq_max = 360.0"))},
        ["out"],
        ["joints[1]", "q_min", "-360", "q_min_deg"],
    ),
]

REPORT = [
    C("report-no-such-folder", "report {t}/nope", {}, ["nope"], ["nope"]),
    C("report-no-summary", "report {t}/run", {"run": None}, ["run/report.html"], ["summary.json"]),
    C("report-file-not-folder", "report {t}/f.txt", {"f.txt": "keep"}, ["f.txt"], ["f.txt"]),
    C("report-jobs-zero", "report {t}/run --jobs 0", {"run": None}, ["run/report.html"], ["--jobs", "0"]),
    C("report-map-points-zero", "report {t}/run --map-points 0", {"run": None}, ["run/report.html"], ["points", "0"]),
    C(
        "report-summary-not-json",
        "report {t}/run --no-map",
        {"run": None, "run/summary.json": "{not json"},
        ["run/report.html"],
        ["summary.json"],
    ),
    C(
        "report-summary-binary",
        "report {t}/run --no-map",
        {"run": None, "run/summary.json": BINARY},
        ["run/report.html"],
        ["summary.json"],
    ),
    C(
        "report-summary-list",
        "report {t}/run --no-map",
        {"run": None, "run/summary.json": "[]"},
        ["run/report.html"],
        ["summary.json"],
    ),
    C(
        "report-summary-empty-object",
        "report {t}/run --no-map",
        {"run": None, "run/summary.json": "{}"},
        ["run/report.html"],
        ["summary.json", "command missing", "'plan', 'demo'"],
    ),
    C(
        "report-summary-of-identify",
        "report {t}/run --no-map",
        {"run": None, "run/summary.json": '{"command": "identify"}'},
        ["run/report.html"],
        ['command = "identify"', "'plan', 'demo'"],
    ),
]

S = "simulate --robot ur5 --config {t}/s.toml --out {t}/d.csv"

SIMULATE = [
    C(
        "simulate-negative-sigma",
        S,
        {"s.toml": sim(("sigma_m = 2e-5", "sigma_m = -2e-5"))},
        ["d.csv", "d.truth.toml"],
        ["noise", "sigma_m", "-2e-05"],
    ),
    C("simulate-unknown-top-key", S, {"s.toml": "sede = 3\n" + SIM}, ["d.csv", "d.truth.toml"], ["sede"]),
    C(
        "simulate-poses-zero",
        S,
        {"s.toml": sim(("poses = 20", "poses = 0"))},
        ["d.csv", "d.truth.toml"],
        ["poses", "0"],
    ),
    C(
        "simulate-poses-string",
        S,
        {"s.toml": sim(("poses = 20", 'poses = "many"'))},
        ["d.csv", "d.truth.toml"],
        ["poses", "many"],
    ),
    C(
        "simulate-poses-float",
        S,
        {"s.toml": sim(("poses = 20", "poses = 20.5"))},
        ["d.csv", "d.truth.toml"],
        ["poses", "20.5"],
    ),
    C(
        "simulate-loaded-rows-negative",
        S,
        {"s.toml": sim(("loaded_rows = 1", "loaded_rows = -1"))},
        ["d.csv", "d.truth.toml"],
        ["loaded_rows", "-1"],
    ),
    C(
        "simulate-force-magnitudes-text",
        S,
        {"s.toml": sim(("loaded_rows = 1", 'loaded_rows = 1\nforce_magnitudes_N = "big"'))},
        ["d.csv", "d.truth.toml"],
        ["force_magnitudes_N", "big"],
    ),
    C(
        "simulate-dt-negative",
        S,
        {"s.toml": sim(("loaded_rows = 1", "loaded_rows = 1\ndt_s = -20.0"))},
        ["d.csv", "d.truth.toml"],
        ["dt_s", "-20"],
    ),
    C(
        "simulate-no-such-config",
        "simulate --robot ur5 --config {t}/nope.toml --out {t}/d.csv",
        {},
        ["d.csv"],
        ["nope.toml"],
    ),
    C(
        "simulate-config-directory",
        "simulate --robot ur5 --config {t}/cfg --out {t}/d.csv",
        {"cfg": None},
        ["d.csv"],
        ["cfg"],
    ),
    C("simulate-malformed-toml", S, {"s.toml": sim(("[noise]", "[noise"))}, ["d.csv", "d.truth.toml"], ["TOML"]),
    C(
        "simulate-non-utf8",
        S,
        {"s.toml": LATIN1_COMMENT + SIM.encode()},
        ["d.csv", "d.truth.toml"],
        ["s.toml", "line 1", "UTF-8"],
    ),
    C("simulate-unknown-effect", S, {"s.toml": SIM + "[effects.wobble]\n"}, ["d.csv", "d.truth.toml"], ["wobble"]),
    C(
        "simulate-geometric-sigma-negative",
        S,
        {"s.toml": SIM + "[effects.geometric]\nsigma_length_m = -1e-4\n"},
        ["d.csv", "d.truth.toml"],
        ["sigma_length_m", "-0.0001"],
    ),
    C("simulate-units", S, {"s.toml": 'units = "inch"\n' + SIM}, ["d.csv", "d.truth.toml"], ["units", "inch"]),
    C(
        "simulate-registered-string",
        S,
        {"s.toml": SIM + '[registration]\nregistered = "no"\n'},
        ["d.csv", "d.truth.toml"],
        ["registered", "no"],
    ),
    C(
        "simulate-stiffness-scale-negative",
        S,
        {"s.toml": SIM + "[stiffness]\nscale = -1.0\n"},
        ["d.csv", "d.truth.toml"],
        ["scale", "-1"],
    ),
    C(
        "simulate-time-constant-zero",
        S,
        {"s.toml": SIM + "[temperature]\nend_C = 30.0\ntime_constant_s = 0.0\n"},
        ["d.csv", "d.truth.toml"],
        ["time_constant_s", "0"],
    ),
    C("simulate-seed-negative", S + " --seed -1", {"s.toml": SIM}, ["d.csv", "d.truth.toml"], ["seed", "-1"]),
    C(
        "simulate-out-is-a-folder",
        "simulate --robot ur5 --config {t}/s.toml --out {t}/d",
        {"s.toml": SIM, "d": None},
        ["d.truth.toml"],
        ["d", "folder"],
    ),
    C(
        "simulate-masses-negative",
        S,
        {"s.toml": SIM + "[effects.gravity]\nmasses_kg = -1.0\n"},
        ["d.csv", "d.truth.toml"],
        ["masses_kg", "-1"],
    ),
    C(
        "simulate-eccentricity-joint-7",
        S,
        {"s.toml": SIM + "[effects.eccentricity]\njoint = 7\n"},
        ["d.csv", "d.truth.toml"],
        ["joint", "7"],
    ),
    C(
        "simulate-directions-up",
        S,
        {"s.toml": sim(("loaded_rows = 1", 'loaded_rows = 1\ndirections = "up"'))},
        ["d.csv", "d.truth.toml"],
        ["directions", "up"],
    ),
    C(
        "simulate-sigma-column-zero-sigma",
        S,
        {"s.toml": sim(("sigma_m = 2e-5", "sigma_m = 0.0\nsigma_column = true"))},
        ["d.csv", "d.truth.toml"],
        ["sigma_m", "0"],
    ),
    C(
        "simulate-noise-not-a-table",
        S,
        {"s.toml": "noise = 5\n" + sim(("[noise]\nsigma_m = 2e-5\n", ""))},
        ["d.csv", "d.truth.toml"],
        ["noise", "table"],
    ),
    C(
        "simulate-outlier-fraction-2",
        S,
        {"s.toml": SIM + "[effects.outliers]\nfraction = 2.0\n"},
        ["d.csv", "d.truth.toml"],
        ["fraction", "2"],
    ),
    C(
        "simulate-rows-cap",
        S,
        {"s.toml": sim(("poses = 20", "poses = 10000000"))},
        ["d.csv", "d.truth.toml"],
        ["rows", "cap"],
    ),
    C(
        "simulate-seed-in-config-negative",
        S,
        {"s.toml": sim(("seed = 3", "seed = -3"))},
        ["d.csv", "d.truth.toml"],
        ["seed", "-3"],
    ),
    C(
        "simulate-robot-5-joints",
        "simulate --robot {t}/r.toml --config {t}/s.toml --out {t}/d.csv",
        {"s.toml": SIM, "r.toml": drop_last_joint(UR5)},
        ["d.csv", "d.truth.toml"],
        ["r.toml", "joints"],
    ),
]

I = "identify --robot ur5 --data {t}/d.csv --out {t}/m.toml --report {t}/rep"
IO = ["m.toml", "rep"]

IDENTIFY = [
    C(
        "identify-folds-1",
        "identify --robot ur5 --data {fx}/meas.csv --out {t}/m.toml --report {t}/rep --folds 1",
        {},
        IO,
        ["--folds", "1", "2"],
    ),
    C(
        "identify-folds-0",
        "identify --robot ur5 --data {fx}/meas.csv --out {t}/m.toml --report {t}/rep --folds 0",
        {},
        IO,
        ["--folds", "0"],
    ),
    C(
        "identify-folds-negative",
        "identify --robot ur5 --data {fx}/meas.csv --out {t}/m.toml --report {t}/rep --folds -2",
        {},
        IO,
        ["--folds", "-2"],
    ),
    C(
        "identify-folds-text",
        "identify --robot ur5 --data {fx}/meas.csv --out {t}/m.toml --report {t}/rep --folds x",
        {},
        IO,
        ["--folds", "x"],
    ),
    C("identify-no-such-data", I, {}, IO, ["d.csv"]),
    C("identify-data-directory", I, {"d.csv": None}, IO, ["d.csv", "folder"]),
    C("identify-data-empty", I, {"d.csv": ""}, IO, ["d.csv", "empty"]),
    C("identify-data-binary", I, {"d.csv": BINARY}, IO, ["d.csv", "UTF-8"]),
    C("identify-data-latin1", I, {"d.csv": LATIN1_COMMENT + MEAS.encode()}, IO, ["d.csv", "line 1", "UTF-8"]),
    # a ';' export is read by the default --csv-dialect auto; declared 'comma', it is the clear error
    C(
        "identify-data-semicolons",
        I + " --csv-dialect comma",
        {"d.csv": MEAS.replace(",", ";")},
        IO,
        ["d.csv", "';'", "','", "--csv-dialect semicolon"],
    ),
    C(
        "identify-data-semicolons-decimal-comma",
        I + " --csv-dialect comma",
        {"d.csv": MEAS.replace(",", ";").replace(".", ",")},
        IO,
        ["d.csv", "';'"],
    ),
    C("identify-data-tabs", I, {"d.csv": MEAS.replace(",", "\t")}, IO, ["d.csv", "tab"]),
    C(
        "identify-data-missing-z",
        I,
        {
            "d.csv": meas(
                (",x,y,z", ",x,y"),
                (",0.40,0.11,0.52", ",0.40,0.11"),
                (",0.41,0.12,0.51", ",0.41,0.12"),
                (",0.42,0.13,0.50", ",0.42,0.13"),
            )
        },
        IO,
        ["z"],
    ),
    C(
        "identify-data-duplicated-column",
        I,
        {
            "d.csv": meas(
                (",z\n", ",z,x_mm\n"), ("0.52\n", "0.52,400\n"), ("0.51\n", "0.51,410\n"), ("0.50\n", "0.50,420\n")
            )
        },
        IO,
        ["'x'", "twice"],
    ),
    C(
        "identify-data-same-column-twice",
        I,
        {
            "d.csv": meas(
                (",z\n", ",z,z\n"), ("0.52\n", "0.52,0.52\n"), ("0.51\n", "0.51,0.51\n"), ("0.50\n", "0.50,0.50\n")
            )
        },
        IO,
        ["'z'", "twice"],
    ),
    C("identify-data-short-row", I, {"d.csv": meas((",0.41,0.12,0.51", ",0.41,0.12"))}, IO, ["line 3", "14", "15"]),
    C("identify-data-nan", I, {"d.csv": meas(("0.40,0.11", "nan,0.11"))}, IO, ["line 2", "'x'", "nan"]),
    C("identify-data-empty-cell", I, {"d.csv": meas(("0.40,0.11", ",0.11"))}, IO, ["line 2", "'x'", "empty"]),
    C("identify-data-text-cell", I, {"d.csv": meas(("0.40,0.11", "abc,0.11"))}, IO, ["line 2", "'x'", "abc"]),
    C(
        "identify-data-mm-as-m",
        I,
        {"d.csv": meas(("0.40,0.11,0.52", "400.0,110.0,520.0"))},
        IO,
        ["line 2", "'x'", "400", "x_mm"],
    ),
    C(
        "identify-data-degrees-as-rad",
        I,
        {"d.csv": meas(("0.1,-1.2,1.3", "10,-120,130"))},
        IO,
        ["line 2", "'q2'", "-120", "q2_deg"],
    ),
    C(
        "identify-data-unknown-column",
        I,
        {
            "d.csv": meas(
                (",z\n", ",z,temprature\n"), ("0.52\n", "0.52,21\n"), ("0.51\n", "0.51,21\n"), ("0.50\n", "0.50,21\n")
            )
        },
        IO,
        ["temprature"],
    ),
    C("identify-data-header-only", I, {"d.csv": MEAS_HEADER + "\n"}, IO, ["d.csv", "no measurement rows"]),
    C("identify-data-duplicate-row", I, {"d.csv": MEAS + MEAS_ROWS[0] + "\n"}, IO, ["lines 2 and 5", "identical"]),
    C(
        "identify-data-time-backwards",
        I,
        {"d.csv": "t," + MEAS_HEADER + "\n0," + MEAS_ROWS[0] + "\n5," + MEAS_ROWS[1] + "\n3," + MEAS_ROWS[2] + "\n"},
        IO,
        ["line 4", "'t'", "3"],
    ),
    C(
        "identify-data-sigma-negative",
        I,
        {"d.csv": "sigma," + MEAS_HEADER + "\n" + "\n".join("-1e-5," + r for r in MEAS_ROWS) + "\n"},
        IO,
        ["line 2", "sigma", "-1e-05"],
    ),
    C(
        "identify-data-temperature-fahrenheit",
        I,
        {"d.csv": "temperature," + MEAS_HEADER + "\n" + "\n".join("300," + r for r in MEAS_ROWS) + "\n"},
        IO,
        ["line 2", "temperature", "300"],
    ),
    C(
        "identify-data-too-few-poses",
        I,
        {"d.csv": MEAS_HEADER + "\n" + MEAS_ROWS[0] + "\n" + sub(MEAS_ROWS[0], ("-50", "-60")) + "\n"},
        IO,
        ["pose"],
    ),
    C(
        "identify-candidates-unknown",
        "identify --robot ur5 --data {fx}/meas.csv --out {t}/m.toml --report {t}/rep --candidates wobble",
        {},
        IO,
        ["wobble"],
    ),
    C(
        "identify-include-unknown",
        "identify --robot ur5 --data {fx}/meas.csv --out {t}/m.toml --report {t}/rep --include wobble",
        {},
        IO,
        ["wobble"],
    ),
    C(
        "identify-robot-5-joints",
        "identify --robot {t}/r.toml --data {fx}/meas.csv --out {t}/m.toml --report {t}/rep",
        {"r.toml": drop_last_joint(UR5)},
        IO,
        ["r.toml", "joints"],
    ),
    C(
        "identify-validation-missing",
        "identify --robot ur5 --data {fx}/meas.csv --out {t}/m.toml --report {t}/rep --validation {t}/v.csv",
        {},
        IO,
        ["v.csv"],
    ),
    C(
        "identify-truth-missing",
        "identify --robot ur5 --data {fx}/meas.csv --out {t}/m.toml --report {t}/rep --truth {t}/tr.toml",
        {},
        IO,
        ["tr.toml"],
    ),
    C(
        "identify-truth-malformed",
        "identify --robot ur5 --data {fx}/meas.csv --out {t}/m.toml --report {t}/rep --truth {t}/tr.toml",
        {"tr.toml": "seed = = 1"},
        IO,
        ["tr.toml", "TOML"],
    ),
    C(
        "identify-truth-not-a-truth-file",
        "identify --robot ur5 --data {fx}/meas.csv --out {t}/m.toml --report {t}/rep --truth {t}/tr.toml",
        {"tr.toml": UR5},
        IO,
        ["tr.toml"],
    ),
    C(
        "identify-out-is-a-folder",
        "identify --robot ur5 --data {fx}/meas.csv --out {t}/m --report {t}/rep",
        {"m": None},
        ["rep"],
        ["--out", "folder"],
    ),
    C(
        "identify-report-is-a-file",
        "identify --robot ur5 --data {fx}/meas.csv --out {t}/m.toml --report {t}/rep.txt",
        {"rep.txt": "keep"},
        ["m.toml", "rep.txt"],
        ["--report", "rep.txt"],
    ),
    C(
        "identify-data-decimal-comma",
        I,
        {"d.csv": meas(("0.40,0.11,0.52", "0,40,0,11,0,52"))},
        IO,
        ["line 2", "18 cells", "15", "decimal"],
    ),
    C(
        "identify-data-trailing-comma-header",
        I,
        {"d.csv": MEAS.replace(",z\n", ",z,\n", 1)},
        IO,
        ["line 1", "column 16", "empty name"],
    ),
    C(
        "identify-data-rotation-incomplete",
        I,
        {
            "d.csv": meas(
                (",z\n", ",z,rx,ry\n"), ("0.52\n", "0.52,0,0\n"), ("0.51\n", "0.51,0,0\n"), ("0.50\n", "0.50,0,0\n")
            )
        },
        IO,
        ["rx, ry, rz", "together"],
    ),
    C(
        "identify-data-point-empty",
        I,
        {
            "d.csv": "point,"
            + MEAS_HEADER
            + "\n"
            + "\n".join(f"P{i}," + r for i, r in enumerate(MEAS_ROWS)).replace("P1,", ",")
            + "\n"
        },
        IO,
        ["line 3", "point", "empty"],
    ),
    C("identify-data-comments-only", I, {"d.csv": "# nothing measured yet\n# really\n"}, IO, ["d.csv", "empty"]),
    C("identify-data-unit-suffix-unknown", I, {"d.csv": MEAS.replace(",x,y,z", ",x_cm,y_cm,z_cm", 1)}, IO, ["x_cm"]),
    C("identify-data-header-repeated", I, {"d.csv": MEAS + MEAS_HEADER + "\n"}, IO, ["line 5", "'q1'"]),
    C(
        "identify-validation-without-xyz",
        "identify --robot ur5 --data {fx}/meas.csv --out {t}/m.toml --report {t}/rep --validation {fx}/cmds.csv",
        {},
        IO,
        ["cmds.csv", "x, y, z"],
    ),
    C(
        "identify-robot-is-measurement-file",
        "identify --robot {fx}/meas.csv --data {fx}/meas.csv --out {t}/m.toml --report {t}/rep",
        {},
        IO,
        ["meas.csv", "TOML"],
    ),
    C(
        "identify-folds-more-than-poses",
        "identify --robot ur5 --data {fx}/meas.csv --out {t}/m.toml --report {t}/rep --folds 500",
        {},
        IO,
        ["--folds", "500", "poses"],
    ),
    C("identify-missing-robot", "identify --data {fx}/meas.csv --out {t}/m.toml --report {t}/rep", {}, IO, ["--robot"]),
]

PR = "predict --model ur5 --input {t}/c.csv --out {t}/o.csv"
CO = "compensate --model ur5 --input {t}/c.csv --out {t}/o.csv"

PREDICT = [
    C(
        "predict-out-is-a-folder",
        "predict --model ur5 --input {fx}/cmds.csv --out {t}/o",
        {"o": None},
        [],
        ["--out", "folder"],
    ),
    C(
        "predict-no-such-model",
        "predict --model {t}/m.toml --input {fx}/cmds.csv --out {t}/o.csv",
        {},
        ["o.csv"],
        ["m.toml"],
    ),
    C(
        "predict-model-malformed",
        "predict --model {t}/m.toml --input {fx}/cmds.csv --out {t}/o.csv",
        {"m.toml": "name = \n"},
        ["o.csv"],
        ["m.toml", "TOML"],
    ),
    C(
        "predict-model-directory",
        "predict --model {t}/m --input {fx}/cmds.csv --out {t}/o.csv",
        {"m": None},
        ["o.csv"],
        ["folder"],
    ),
    C(
        "predict-missing-wrench",
        PR,
        {"c.csv": "q1,q2,q3,q4,q5,q6\n0.1,-1.2,1.4,-0.5,-1.5,0.3\n"},
        ["o.csv"],
        ["c.csv", "fx"],
    ),
    C(
        "predict-semicolons",
        PR + " --csv-dialect comma",
        {"c.csv": CMDS.replace(",", ";")},
        ["o.csv"],
        ["c.csv", "';'"],
    ),
    C("predict-non-utf8", PR, {"c.csv": LATIN1_COMMENT + CMDS.encode()}, ["o.csv"], ["c.csv", "line 1", "UTF-8"]),
    C("predict-utf16", PR, {"c.csv": CMDS.encode("utf-16")}, ["o.csv"], ["c.csv", "UTF-8"]),
    C("predict-empty", PR, {"c.csv": ""}, ["o.csv"], ["c.csv", "empty"]),
    C("predict-input-directory", PR, {"c.csv": None}, ["o.csv"], ["c.csv", "folder"]),
    C(
        "predict-existing-output-kept",
        PR,
        {"c.csv": cmds(("0.1,-1.2", "zero,-1.2")), "o.csv": "keep me"},
        ["o.csv"],
        ["line 2", "'q1'", "zero"],
    ),
    C(
        "predict-identified-table-broken",
        "predict --model {t}/m.toml --input {fx}/cmds.csv --out {t}/o.csv",
        {"m.toml": UR5 + "\n[identified]\nformat = 1\neffects = 5\n"},
        ["o.csv"],
        ["m.toml", "identified"],
    ),
    C(
        "predict-model-is-problem-file",
        "predict --model {t}/m.toml --input {fx}/cmds.csv --out {t}/o.csv",
        {"m.toml": PROBLEM},
        ["o.csv"],
        ["m.toml", "problem file"],
    ),
    C(
        "predict-robot-5-joints",
        "predict --model {t}/r.toml --input {fx}/cmds.csv --out {t}/o.csv",
        {"r.toml": drop_last_joint(UR5)},
        ["o.csv"],
        ["r.toml", "joints"],
    ),
    C(
        "predict-joint-outside-limits",
        "predict --model ur5 --input {t}/c.csv --out {t}/o.csv",
        {"c.csv": cmds(("0.1,-1.2,1.4", "7.0,-1.2,1.4"))},
        ["o.csv"],
        ["c.csv", "line 2", "q1", "7", "q_max"],
    ),
]

COMPENSATE = [
    C(
        "compensate-joint-outside-limits-rad",
        CO,
        {"c.csv": cmds(("0.1,-1.2,1.4", "7.0,-1.2,1.4"))},
        ["o.csv"],
        ["c.csv", "line 2", "q1", "7", "q_max_deg", "360"],
    ),
    C(
        "compensate-joint-outside-limits-deg",
        "compensate --model {t}/r.toml --input {t}/c.csv --out {t}/o.csv",
        {
            "r.toml": robot(("q_max_deg = 360.0", "q_max_deg = 170.0")),
            "c.csv": "q1_deg" + CMDS[2:].replace("0.1,-1.2,1.4", "175.0,-1.2,1.4", 1),
        },
        ["o.csv"],
        ["line 2", "q1_deg", "175", "q_max_deg", "170"],
    ),
    C("compensate-base-without-xyz", CO + " --targets-frame base", {"c.csv": CMDS}, ["o.csv"], ["c.csv", "x, y, z"]),
    C(
        "compensate-frame-unknown",
        CO + " --targets-frame world",
        {"c.csv": CMDS},
        ["o.csv"],
        ["--targets-frame", "world"],
    ),
    C(
        "compensate-out-is-a-folder",
        "compensate --model ur5 --input {fx}/cmds.csv --out {t}/o",
        {"o": None},
        [],
        ["--out", "folder"],
    ),
    C(
        "compensate-model-directory",
        "compensate --model {t}/m --input {fx}/cmds.csv --out {t}/o.csv",
        {"m": None},
        ["o.csv"],
        ["folder"],
    ),
    C(
        "compensate-targets-mm-as-m",
        CO + " --targets-frame base",
        {"c.csv": CMD_HEADER + ",x,y,z\n" + CMD_ROWS[0] + ",400,110,520\n"},
        ["o.csv"],
        ["line 2", "x", "400"],
    ),
    C("compensate-wrong-column-count", CO, {"c.csv": CMDS + "0.1,0.2\n"}, ["o.csv"], ["line 5", "2 cells"]),
    C("compensate-inf", CO, {"c.csv": cmds(("-50", "inf"))}, ["o.csv"], ["line 2", "fz", "inf"]),
    C(
        "compensate-measurement-without-xyz",
        CO + " --targets-frame measurement",
        {"c.csv": CMDS},
        ["o.csv"],
        ["c.csv", "x, y, z"],
    ),
    C(
        "compensate-temperature-fahrenheit",
        CO,
        {"c.csv": "temperature," + CMD_HEADER + "\n" + "\n".join("300," + r for r in CMD_ROWS) + "\n"},
        ["o.csv"],
        ["line 2", "temperature", "300"],
    ),
    C("compensate-force-kN-as-N", CO, {"c.csv": cmds(("-50", "-5e6"))}, ["o.csv"], ["line 2", "fz", "fz_kN"]),
]

ARGS = [
    C("args-no-command", "", {}, [], ["command"]),
    C("args-unknown-command", "plot --out x", {}, [], ["plot"]),
    C("args-identify-no-options", "identify", {}, [], ["--robot"]),
    C("args-predict-no-options", "predict", {}, [], ["--model"]),
    C("args-compensate-no-options", "compensate", {}, [], ["--model"]),
    C("args-simulate-no-options", "simulate", {}, [], ["--robot"]),
    C("args-report-no-folder", "report", {}, [], ["folder"]),
    C("args-pose-no-problem", "pose", {}, [], ["problem"]),
    C("args-global-unknown-option", "--quiet plan x --out y", {}, [], ["--quiet"]),
]

PLACEMENT = resources.files("problems").joinpath("files/placement_milling.toml").read_text(encoding="utf-8")


def placement(*pairs: tuple[str, str]) -> str:
    return sub(PLACEMENT, *pairs)


#: A small grid (fast cases that get past the grid checks).
PL = "place placement_milling --out {t}/out --no-report --no-optimise --grid x_m=0.8:0.9:2,y_m=0,yaw_deg=0"
PLF = "place {t}/p.toml --out {t}/out --no-report --no-optimise"

PLACE = [
    C("place-no-such-problem", "place nosuch_problem --out {t}/out", {}, ["out"], ["nosuch_problem"]),
    C("place-grid-unknown-key", PL + " --grid foo_m=1", {}, ["out"], ["foo_m", "x_m"]),
    C("place-grid-count-0", PL + " --grid x_m=0:1:0", {}, ["out"], ["x_m", "count", "0"]),
    C("place-grid-start-above-stop", PL + " --grid x_m=1:0:3", {}, ["out"], ["x_m", "start 1", "stop 0"]),
    C("place-grid-not-a-number", PL + " --grid x_m=abc", {}, ["out"], ["x_m=abc", "number"]),
    C("place-grid-no-equals", PL + " --grid x_m", {}, ["out"], ["x_m", "KEY=VALUE"]),
    C(
        "place-grid-too-many",
        PL + " --grid x_m=0:1:100000,y_m=0:1:1000",
        {},
        ["out"],
        ["100000000 placements", "10000000"],
    ),
    C("place-grid-nan", PL + " --grid y_m=nan", {}, ["out"], ["y_m", "nan", "finite"]),
    C(
        "place-grid-overflow",
        PL + " --grid x_m=0:1:65536,y_m=0:1:65536,z_m=0:1:65536,yaw_deg=0:1:65536",
        {},
        ["out"],
        ["18446744073709551616 placements", "10000000"],
    ),
    C("place-grid-top-float", PL + " --grid top=3.0", {}, ["out"], ["top", "whole number", "'3.0'"]),
    C("place-chunk-too-big", PL + " --chunk 200000", {}, ["out"], ["--chunk 200000", "100000"]),
    C("place-scheduler-superscript", PL + " --scheduler local:\u00b2", {}, ["out"], ["--scheduler", "local:"]),
    C(
        "place-scheduler-port-range",
        PL + " --scheduler tcp://127.0.0.1:99999",
        {},
        ["out"],
        ["--scheduler", "99999", "65535"],
    ),
    C("place-top-11", PL + " --top 11", {}, ["out"], ["--top 11", "[0, 10]"]),
    C("place-chunk-0", PL + " --chunk 0", {}, ["out"], ["--chunk 0", "positive"]),
    C("place-scheduler-local-0", PL + " --scheduler local:0", {}, ["out"], ["--scheduler", "local:0"]),
    C(
        "place-scheduler-nonsense",
        PL + " --scheduler somewhere",
        {},
        ["out"],
        ["--scheduler", "somewhere", "tcp://HOST:PORT"],
    ),
    C(
        "place-table-start-above-stop",
        PLF,
        {"p.toml": placement(("x_m = [-0.6, 1.0, 17]", "x_m = [1.0, -0.6, 17]"))},
        ["out"],
        ["p.toml", "placement", "x_m", "start 1", "stop -0.6"],
    ),
    C(
        "place-table-unknown-key",
        PLF,
        {"p.toml": placement(("top = 3", "top = 3\nyaw = 90"))},
        ["out"],
        ["p.toml", "placement", "yaw", "yaw_deg"],
    ),
    C(
        "place-table-not-a-table",
        PLF,
        {"p.toml": placement(("\n[placement] ", "\n[placementx] "))},
        ["out"],
        ["p.toml", "placementx"],
    ),
    C(
        "place-table-top-string",
        PLF,
        {"p.toml": placement(("top = 3", 'top = "3"'))},
        ["out"],
        ["p.toml", "top", "'3'"],
    ),
    C(
        "place-nothing-feasible",
        "place placement_milling --out {t}/out --no-report --grid x_m=3:4:2,y_m=3:4:2",
        {},
        ["out"],
        ["none of the 16 placements", "unreachable 16", "widen the grid"],
    ),
    C(
        "place-report-of-a-study",
        "report {t}/study",
        {"study/summary.json": '{"command": "place"}'},
        [],
        ["placement study", "compplan place"],
    ),
    C(
        "place-out-is-the-problem",
        "place {t}/p.toml --out {t}/p.toml --no-report",
        {"p.toml": PLACEMENT},
        ["p.toml"],
        ["p.toml"],
    ),
]

CASES = PLAN + POSE + DEMO + MAP + ROBOT_FILE + REPORT + SIMULATE + IDENTIFY + PREDICT + COMPENSATE + PLACE + ARGS


# --------------------------------------------------------------------------------------
# Runner
# --------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def fx(tmp_path_factory) -> Path:
    """Shared valid inputs: a measurement file (simulated UR5), a command file, a sim config."""
    from problems.measurements import measurements_to_csv
    from problems.virtual import simulator
    import tomllib

    d = tmp_path_factory.mktemp("fx")
    vr = simulator("ur5", tomllib.loads(SIM), where="sim.toml")
    (d / "meas.csv").write_text(measurements_to_csv(vr.campaign()))
    (d / "cmds.csv").write_text(CMDS)
    (d / "sim.toml").write_text(SIM)
    (d / "robot.toml").write_text(UR5)
    (d / "problem.toml").write_text(PROBLEM)
    return d


def _write(base: Path, files: dict[str, Content]) -> None:
    """Create the case's files (``None``: a folder)."""
    for name, content in files.items():
        p = base / name
        if content is None:
            p.mkdir(parents=True, exist_ok=True)
        else:
            p.parent.mkdir(parents=True, exist_ok=True)
            p.write_bytes(content if isinstance(content, bytes) else content.encode())


def run_cli(argv: list[str], capsys) -> tuple[int, str, str]:
    """``compplan ARGV`` in-process: (exit status, stdout, stderr)."""
    try:
        code = cli_main(argv)
    except SystemExit as exc:  # argparse
        code = exc.code if isinstance(exc.code, int) else 2
    out, err = capsys.readouterr()
    return code, out, err


def _snapshot(p: Path) -> object:
    if not p.exists():
        return None
    if p.is_dir():
        return sorted(str(q.relative_to(p)) for q in p.rglob("*"))
    return p.read_bytes()


def check_one_line_error(code: int, err: str, expect: list[str]) -> str:
    """The shared assertions on a user error; returns the message."""
    assert "Traceback" not in err, err
    assert "np.float64(" not in err and "np.int64(" not in err, err
    assert "internal error" not in err, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, f"expected one line on stderr, got {len(lines)}:\n{err}"
    msg = lines[0]
    assert msg.startswith("compplan: error: "), msg
    assert code == 2, f"exit {code}: {msg}"
    low = msg.lower()
    for frag in expect:
        assert frag.lower() in low, f"message lacks {frag!r}: {msg}"
    return msg


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_bad_input(case: Case, fx: Path, tmp_path: Path, capsys, monkeypatch) -> None:
    monkeypatch.setenv("COMPPLAN_CACHE", str(tmp_path / ".cache"))
    # the messages themselves must be clean: switch off the CLI's last-resort NumPy-repr filter
    monkeypatch.setattr(cli, "_NUMPY_REPR", re.compile(r"((?!x)x)"))
    _write(tmp_path, case.files)
    before = {o: _snapshot(tmp_path / o) for o in case.outputs}
    argv = [a.format(t=tmp_path, fx=fx) for a in case.argv]
    code, _out, err = run_cli(argv, capsys)
    check_one_line_error(code, err, case.expect)
    for o, snap in before.items():
        assert _snapshot(tmp_path / o) == snap, f"{o} was written or changed"
    # nothing else appeared next to the inputs (temporary files included)
    made = {p.name for p in tmp_path.iterdir()} - {n.split("/")[0] for n in case.files} - {".cache"}
    assert not made, f"unexpected output {sorted(made)}"


def test_campaign_size() -> None:
    """The campaign covers every command with at least 80 cases."""
    assert len(CASES) >= 80
    assert len({c.id for c in CASES}) == len(CASES)
    for cmd in ("plan", "pose", "demo", "map", "report", "simulate", "identify", "predict", "compensate", "place"):
        assert any(c.argv and c.argv[0] == cmd for c in CASES), cmd


# --------------------------------------------------------------------------------------
# The items of the issue, one by one
# --------------------------------------------------------------------------------------


def test_cli_formats_numpy_scalars_and_newlines() -> None:
    """The CLI's last resort: a message never shows ``np.float64(...)`` and stays on one line."""
    assert cli.one_line(f"got {np.float64(0.5)!r} and {np.int64(3)!r}\nsecond line") == "got 0.5 and 3 second line"


def test_sample_cap_refuses_before_sampling() -> None:
    """A velocity limit of 1e-9 rad/s asks for ~1e11 samples: refused at once, naming the number of
    samples, the duration, dt and the cap (MAX_TRAJECTORY_SAMPLES)."""
    from models.errors import InputError
    from problems.timing import JointLimits, time_parametrize
    from problems.timing.registry import MAX_TRAJECTORY_SAMPLES, check_sample_count

    q = np.array([[0.0] * 6, [0.5, -0.3, 0.2, 0.1, 0.0, 0.4]])
    lim = JointLimits(velocity=np.full(6, 1e-9), acceleration=np.full(6, 5.0), jerk=np.full(6, 50.0))
    for method in ("toppra", "ruckig"):
        with pytest.raises(InputError) as exc:
            time_parametrize(q, lim, method, 0.008)
        msg = str(exc.value)
        assert "samples" in msg and "dt = 0.008 s" in msg and str(MAX_TRAJECTORY_SAMPLES) in msg
        assert "MAX_TRAJECTORY_SAMPLES" in msg and method in msg
    assert check_sample_count(1.0, 0.01) == 101
    with pytest.raises(InputError, match=r"1e\+06 s at dt = 0.001 s"):
        check_sample_count(1e6, 1e-3)
    # an ordinary motion is not affected
    ok = time_parametrize(
        q, JointLimits(velocity=np.full(6, 1.0), acceleration=np.full(6, 5.0), jerk=np.full(6, 50.0)), "toppra", 0.008
    )
    assert ok.ok and len(ok.t) < MAX_TRAJECTORY_SAMPLES


def _tight_limits_robot(q: np.ndarray, half_width: float):
    """UR5 whose joint limits are q +- half_width (rad)."""
    from models.robot import robot_from_dict, load_robot

    d = load_robot("ur5").to_dict()
    for j, row in enumerate(d["joints"]):
        row["q_min"], row["q_max"] = float(q[j] - half_width), float(q[j] + half_width)
    return robot_from_dict(d, "tight.toml")


def test_compensate_reports_commands_outside_the_limits(tmp_path: Path, capsys) -> None:
    """A compensated command beyond q_min/q_max is a FAILED row naming row, joint, value and the limit;
    ``--strict`` refuses it (exit 2, nothing written)."""
    import tomli_w

    from models.arm_file import model_from_robot
    from problems.compensation import CompensationStatus
    from problems.identify import compensate

    q = np.array([[0.1, -1.2, 1.4, -0.5, -1.5, 0.3]])
    robot = _tight_limits_robot(q[0], 1e-7)
    out = compensate(model_from_robot(robot), q, np.array([0.0, 0.0, -80.0, 0.0, 0.0, 0.0]))
    assert out.status is CompensationStatus.FAILED
    assert "outside the joint limits" in out.reason and "row 0: joint" in out.reason
    assert re.search(r"beyond q_m(in|ax) = -?\d", out.reason), out.reason
    assert list(out.failed_rows) == [0]

    rfile = tmp_path / "tight.toml"
    rfile.write_text(tomli_w.dumps(robot.to_dict()))
    inp = tmp_path / "c.csv"
    inp.write_text(CMD_HEADER + "\n" + CMD_ROWS[0] + "\n")
    res = tmp_path / "o.csv"
    code, _out, err = run_cli(
        ["compensate", "--model", str(rfile), "--input", str(inp), "--out", str(res), "--strict"], capsys
    )
    check_one_line_error(code, err, ["c.csv", "outside the joint limits", "joint"])
    assert not res.exists()
    code, _out, err = run_cli(["compensate", "--model", str(rfile), "--input", str(inp), "--out", str(res)], capsys)
    assert code == 0 and "compplan: warning:" in err and "outside the joint limits" in err and "input lines 2" in err


def test_compensate_input_limits_quote_the_robot_file_unit(tmp_path: Path, capsys) -> None:
    """An input command outside the limits is named by line and column in the column's unit; the limit
    in the robot file's key and unit (q_max_deg for a file in degrees, q_max in rad otherwise)."""
    import tomli_w

    q = np.array([0.1, -1.2, 1.4, -0.5, -1.5, 0.3])
    rfile = tmp_path / "tight.toml"
    rfile.write_text(tomli_w.dumps(_tight_limits_robot(q, 0.05).to_dict()))
    inp = tmp_path / "c.csv"
    inp.write_text(CMD_HEADER + "\n" + CMD_ROWS[0] + "\n" + CMD_ROWS[1] + "\n")
    code, _out, err = run_cli(
        ["compensate", "--model", str(rfile), "--input", str(inp), "--out", str(tmp_path / "o.csv")], capsys
    )
    msg = check_one_line_error(code, err, ["line 3", "column 'q1'", "0.2 rad", "q_max = 0.15 rad"])
    assert "_deg" not in msg


IMPLAUSIBLE_SIM = """\
seed = 7
[campaign]
poses = 150
loaded_rows = 1
[noise]
sigma_m = 2e-5
[effects.geometric]
sigma_length_m = 5e-4
sigma_angle_rad = 1e-3
"""


@pytest.fixture(scope="module")
def ur10_data(tmp_path_factory) -> Path:
    """A UR10 campaign (150 poses, small geometric errors)."""
    import tomllib

    from problems.measurements import measurements_to_csv
    from problems.virtual import simulator

    d = tmp_path_factory.mktemp("ur10")
    (d / "ur10.csv").write_text(measurements_to_csv(simulator("ur10", tomllib.loads(IMPLAUSIBLE_SIM)).campaign()))
    return d / "ur10.csv"


@pytest.mark.slow
def test_identify_with_the_wrong_robot_file_is_not_ok(ur10_data: Path, tmp_path: Path, capsys) -> None:
    """UR10 data identified with the UR5 robot file: ~187 mm DH "corrections" fit the data, but the
    status is implausible_geometry and a warning names the parameters and the robot file."""
    import json

    from models.plausibility import IMPLAUSIBLE_LENGTH_ERROR_M

    out, rep = tmp_path / "m.toml", tmp_path / "rep"
    code, stdout, err = run_cli(
        [
            "identify",
            "--robot",
            "ur5",
            "--data",
            str(ur10_data),
            "--out",
            str(out),
            "--report",
            str(rep),
            "--candidates",
            "geometric",
            "--no-progress",
        ],
        capsys,
    )
    assert code == 0, err
    assert "status implausible_geometry" in stdout
    warn = [ln for ln in err.splitlines() if ln.startswith("compplan: warning:")]
    assert len(warn) == 1, err
    assert "da[2] = -18" in warn[0] and "mm" in warn[0] and "robot 'ur5'" in warn[0] and "--robot" in warn[0]
    assert f"{IMPLAUSIBLE_LENGTH_ERROR_M * 1e3:g} mm" in warn[0]
    assert json.loads((rep / "report.json").read_text())["status"] == "implausible_geometry"


@pytest.mark.slow
def test_identify_with_the_right_robot_file_is_plausible(ur10_data: Path) -> None:
    """The same data with the UR10 file: sub-millimetre corrections, no implausibility."""
    from models import load_robot
    from problems.identify import IdentifyStatus, identify
    from models.plausibility import implausible_geometry
    from problems.measurements import read_measurements

    res = identify(load_robot("ur10"), read_measurements(ur10_data), candidates=["geometric"])
    assert res.status is IdentifyStatus.OK, res.reason
    assert implausible_geometry(res.model.nominal, res.model.theta) is None
