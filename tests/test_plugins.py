"""Extending by adding a file: a plug-in in a temporary folder, named by its registry's
environment variable, goes from a problem file through ``compplan plan`` to the summary, the
report and the exports with no other edit (``models/plugins.py``; effects, IK families, export
formats).  Each test runs the command line in a fresh interpreter with the variable set.
"""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
#: Agreement of joint angles written by a plug-in format with trajectory.csv (rad; both print
#: at least 12 significant digits).
CSV_ANGLE_TOL = 1e-9
#: The test effect's wrist offset, m (small: well inside what the plausibility check allows).
WRIST_OFFSET_M = 0.002
#: Agreement of the effect's geometry with the offset it was given, m.
OFFSET_TOL = 1e-9


def _run(args: list[str], env: dict[str, str], cwd: Path, module: str = "planner") -> subprocess.CompletedProcess:
    """``python -m planner ARGS`` (or ``python -c`` when ``module`` is None) with ``env`` added."""
    cmd = [sys.executable, "-m", module, *args] if module else [sys.executable, "-c", *args]
    return subprocess.run(
        cmd, cwd=cwd, env={**os.environ, **env}, capture_output=True, text=True, timeout=900, check=False
    )


def _ok(r: subprocess.CompletedProcess) -> subprocess.CompletedProcess:
    assert r.returncode == 0, f"exit {r.returncode}\n{r.stdout[-2000:]}\n{r.stderr[-3000:]}"
    return r


def _problem(tmp_path: Path, robot_file: str, name: str) -> Path:
    """paper_4_4's problem file with another robot file (relative to the problem's folder)."""
    text = (ROOT / "problems" / "files" / "paper_4_4.toml").read_text(encoding="utf-8")
    assert 'model = "ar5"' in text and 'name = "paper_4_4"' in text
    text = text.replace('model = "ar5"', f'model = "{robot_file}"').replace('name = "paper_4_4"', f'name = "{name}"')
    text = text.replace('methods = ["toppra", "jerk_optimal"]', 'methods = ["toppra"]')
    path = tmp_path / f"{name}.toml"
    path.write_text(text, encoding="utf-8")
    return path


# ------------------------------------------------------------------------------ IK family
IK_PLUGIN = '''
"""Test plug-in: the UR closed form, for robots whose name starts with "marked_" only."""
import os

from .base import IKStructureError
from .base import register_family
from .ur import BRANCH_LABELS, AnalyticIK


@register_family
class MarkedUR(AnalyticIK):
    family = "marked_ur"
    order = 5            # before the UR family it specialises
    description = "test plug-in: UR closed form for robots named marked_*"
    labels = tuple("mk" + lab for lab in BRANCH_LABELS)

    def __init__(self, robot):
        if not robot.name.startswith("marked_"):
            raise IKStructureError(f"robot '{robot.name}' is not marked")
        super().__init__(robot)
        with open(os.environ["MARKED_IK_LOG"], "a") as f:
            f.write(robot.name + "\\n")

    def branch_meaning(self):
        return {lab: "marked " + lab for lab in self.labels}
'''


def test_an_ik_family_plugin_plans_and_reports(tmp_path):
    """A family in $COMPPLAN_IK_PATH that accepts one robot is chosen for it before the built-in
    families (its ``order``), plans the problem, and its name and branch labels reach
    summary.json and the report; other robots keep their family."""
    plugins = tmp_path / "ik"
    plugins.mkdir()
    (plugins / "marked_ur.py").write_text(IK_PLUGIN, encoding="utf-8")
    log = tmp_path / "ik.log"
    env = {"COMPPLAN_IK_PATH": str(plugins), "MARKED_IK_LOG": str(log)}
    shown = _ok(_run(["robot", "show", "ar5"], env, tmp_path)).stdout
    assert 'name = "ar5"' in shown
    (tmp_path / "marked_ar5.toml").write_text(shown.replace('name = "ar5"', 'name = "marked_ar5"'), encoding="utf-8")
    problem = _problem(tmp_path, "marked_ar5.toml", "plugin_ik")
    _ok(_run(["plan", str(problem), "--out", str(tmp_path / "run")], env, tmp_path))

    s = json.loads((tmp_path / "run" / "summary.json").read_text(encoding="utf-8"))
    assert s["plan_status"] == "ok", s["reason"]
    assert s["ik_family"] == "marked_ur"
    assert s["branch_labels"] == [
        "mk" + lab for lab in ("s+w+e+", "s+w+e-", "s+w-e+", "s+w-e-", "s-w+e+", "s-w+e-", "s-w-e+", "s-w-e-")
    ]
    assert str(s["chosen_branch"]).startswith("mk")
    html = (tmp_path / "run" / "report.html").read_text(encoding="utf-8")
    assert s["chosen_branch"] in html and "mks-w-e-" in html  # the branch table names every branch
    assert "marked_ar5" in log.read_text(encoding="utf-8").split()

    check = _ok(_run(["robot", "check", "ur5"], env, tmp_path)).stdout
    assert "IK family: ur " in check  # an unmarked robot: the built-in family
    marked = _ok(_run(["robot", "check", str(tmp_path / "marked_ar5.toml")], env, tmp_path)).stdout
    assert "IK family: marked_ur " in marked


# ------------------------------------------------------------------------------ export format
EXPORT_PLUGIN = '''
"""Test plug-in: the joint positions (model convention, rad) at the trajectory's samples."""
from . import ExportFormat, register_format


def write(data, stem, options):
    rows = ["t," + ",".join(f"q{i}" for i in range(1, 7))]
    rows += [f"{t:.17g}," + ",".join(f"{v:.17g}" for v in q) for t, q in zip(data.t, data.q)]
    return {f"{stem}.csv": "\\n".join(rows) + "\\n"}


register_format(ExportFormat("tq_csv", (".csv",), write, {}, "test plug-in: t, q1..q6 as CSV"))
'''


def _columns(path: Path, names: list[str]) -> np.ndarray:
    with path.open(newline="", encoding="utf-8") as f:
        rows = [r for r in csv.reader(f) if r and not r[0].startswith("#")]
    head = [h.strip() for h in rows[0]]
    return np.array([[float(r[head.index(n)]) for n in names] for r in rows[1:]])


def test_an_export_format_plugin_is_offered_and_written(tmp_path):
    """A format in $COMPPLAN_EXPORT_PATH is offered by ``--export`` and ``--format`` and listed by
    ``export --list``; ``plan --export`` and ``compplan export`` write it, with the samples of the
    run's trajectory.csv."""
    plugins = tmp_path / "export"
    plugins.mkdir()
    (plugins / "tq_csv.py").write_text(EXPORT_PLUGIN, encoding="utf-8")
    env = {"COMPPLAN_EXPORT_PATH": str(plugins)}
    listed = _ok(_run(["export", "--list"], env, tmp_path)).stdout
    assert "tq_csv (.csv): test plug-in" in listed
    run = tmp_path / "run"
    _ok(
        _run(
            ["plan", "paper_4_4", "--out", str(run), "--no-report", "--no-figures", "--export", "tq_csv"], env, tmp_path
        )
    )
    _ok(_run(["export", str(run), "--format", "tq_csv", "--out", str(tmp_path / "again")], env, tmp_path))

    names = ["t"] + [f"q{i}" for i in range(1, 7)]
    reference = _columns(run / "trajectory.csv", names)
    planned = sorted(run.glob("*tq_csv*.csv"))
    assert len(planned) == 1, sorted(p.name for p in run.iterdir())
    for path in (planned[0], tmp_path / "again.csv"):
        got = _columns(path, names)
        assert got.shape == reference.shape and got.shape[0] > 2
        assert np.max(np.abs(got - reference)) < CSV_ANGLE_TOL, path

    unknown = _run(["export", str(run), "--format", "no_such", "--out", str(tmp_path / "x")], env, tmp_path)
    assert unknown.returncode == 2 and "tq_csv" in unknown.stderr  # the choices name the plug-in


# ------------------------------------------------------------------------------ effect
EFFECT_PLUGIN = '''
"""Test plug-in: an offset of the wrist along the joint-4 axis (a geometry hook)."""
import casadi as ca

from .base import Effect, ParamGroup, register


@register
class WristOffset(Effect):
    name = "wrist_offset"
    order = 50
    groups = (ParamGroup("wrist_offset.d", ("wrist_offset.d",), "m", scale=1e-3),)
    formula = "d_4 += d (test plug-in)"

    def geometry(self, ctx, dh):
        return {**dh, "d": dh["d"] + ca.vertcat(0, 0, 0, ctx.p("wrist_offset.d"), 0, 0)}
'''

WRITE_MODEL = """
import sys
import numpy as np
import models.effects as fx
from models import load_robot
from models.arm import ArmModel
from models.arm_file import model_from_robot, model_toml

base = model_from_robot(load_robot("ar5"))
theta = base.theta.copy()
theta[fx.GROUP_SLICES["wrist_offset.d"]] = float(sys.argv[2])
model = ArmModel(nominal=base.nominal, theta=theta, beams=base.beams, effects=["wrist_offset"])
q = np.array([0.1, -1.0, 1.2, -1.5, -1.4, 0.3])
moved = np.linalg.norm(model.kinematics.tcp(q)[:3, 3] - base.kinematics.tcp(q)[:3, 3])
open(sys.argv[1], "w", encoding="utf-8").write(model_toml(model))
print(moved)
"""


def test_an_effect_plugin_reaches_the_plan_and_report(tmp_path):
    """An effect in $COMPPLAN_EFFECT_PATH, in a model file's ``[identified]`` table, is the model
    a problem is planned with: summary.json lists it among the model's effects and names its
    parameter; the report is written."""
    plugins = tmp_path / "effects"
    plugins.mkdir()
    (plugins / "wrist_offset.py").write_text(EFFECT_PLUGIN, encoding="utf-8")
    env = {"COMPPLAN_EFFECT_PATH": str(plugins)}
    model = tmp_path / "ar5_offset.toml"
    moved = float(
        _ok(
            _run([textwrap.dedent(WRITE_MODEL), str(model), str(WRIST_OFFSET_M)], env, tmp_path, module=None)
        ).stdout.split()[-1]
    )
    assert abs(moved - WRIST_OFFSET_M) < OFFSET_TOL
    assert "wrist_offset" in model.read_text(encoding="utf-8")
    problem = _problem(tmp_path, model.name, "plugin_effect")
    _ok(_run(["plan", str(problem), "--out", str(tmp_path / "run")], env, tmp_path))

    s = json.loads((tmp_path / "run" / "summary.json").read_text(encoding="utf-8"))
    assert s["plan_status"] == "ok", s["reason"]
    assert "wrist_offset" in s["model"]["effects"]
    assert s["model"]["identified"] is True
    assert "wrist_offset" in (tmp_path / "run" / "report.html").read_text(encoding="utf-8")

    without = _run(["plan", str(problem), "--out", str(tmp_path / "run2"), "--no-report"], {}, tmp_path)
    assert without.returncode == 2 and "wrist_offset" in without.stderr  # not found: a clear error


# ------------------------------------------------------------------------------ errors
def _one_line_error(r: subprocess.CompletedProcess, *needles: str) -> None:
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2, (r.returncode, r.stderr[-3000:])
    assert len(lines) == 1 and lines[0].startswith("compplan: error: "), r.stderr[-3000:]
    assert "Traceback" not in r.stderr
    for n in needles:
        assert n in lines[0], (n, lines[0])


@pytest.mark.parametrize(
    "variable", ["COMPPLAN_EFFECT_PATH", "COMPPLAN_IK_PATH", "COMPPLAN_TIMING_PATH", "COMPPLAN_EXPORT_PATH"]
)
def test_a_missing_plugin_folder_is_one_line(tmp_path, variable):
    missing = tmp_path / "no_such_folder"
    r = _run(["plan", "paper_4_4", "--out", str(tmp_path / "run")], {variable: str(missing)}, tmp_path)
    _one_line_error(r, f"${variable}", str(missing))
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize(
    "variable, text, error",
    [
        ("COMPPLAN_IK_PATH", "def broken(:\n", "SyntaxError"),
        ("COMPPLAN_EXPORT_PATH", "from . import no_such_name\n", "ImportError"),
        ("COMPPLAN_EFFECT_PATH", "raise RuntimeError('plug-in refuses')\n", "plug-in refuses"),
        (
            "COMPPLAN_IK_PATH",
            (
                "from .base import register_family\nfrom .ur import AnalyticIK\n"
                "register_family(type('Twice', (AnalyticIK,), {}))\n"
            ),
            "registered twice",
        ),
        (
            "COMPPLAN_TIMING_PATH",
            (
                "from .registry import TimingMethod, register_method\n"
                "register_method(TimingMethod('nothing_checked', lambda *a: None, (), lambda o: o, ()))\n"
            ),
            "checked_limits is empty",
        ),
    ],
)
def test_a_failing_plugin_module_is_one_line(tmp_path, variable, text, error):
    folder = tmp_path / "plugins"
    folder.mkdir()
    (folder / "bad_plugin.py").write_text(text, encoding="utf-8")
    r = _run(["plan", "paper_4_4", "--out", str(tmp_path / "run")], {variable: str(folder)}, tmp_path)
    _one_line_error(r, f"${variable}", str(folder / "bad_plugin.py"), error)


def test_a_plugin_named_like_a_builtin_module_is_refused(tmp_path):
    """A plug-in module that a built-in module of the same name would hide is an error, not ignored."""
    folder = tmp_path / "plugins"
    folder.mkdir()
    (folder / "urscript.py").write_text("", encoding="utf-8")
    r = _run(["export", "--list"], {"COMPPLAN_EXPORT_PATH": str(folder)}, tmp_path)
    _one_line_error(r, "$COMPPLAN_EXPORT_PATH", str(folder / "urscript.py"), "rename it")
