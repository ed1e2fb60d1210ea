"""The report's 3-D view of the cell (``planner/report/cell_view.py``, docs/cell.md "The report's
cell view"): drawn for a problem with a ``[cell]`` only, interactive in report.html with plotly.js
embedded once (no network), a static PNG/PDF beside it, the same from the run folder alone
(``compplan report RUN``, the problem file gone), the robot's capsules where forward kinematics
puts the joints of the drawn postures, and a tampered recorded cell refused naming its key.
"""

from __future__ import annotations

import base64
import contextlib
import io
import json
import re
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from planner.cli import main
from planner.report.cell_view import CELL_FIGURE, PLOTLY_DIV_ID

SHIPPED = Path(__file__).resolve().parents[1] / "problems" / "files" / "ur5_tool_thrust.toml"
#: A table under the robot (its top the mounting plane) and a fixture beside the path.
CELL = """
[cell]
clearance = 0.005
[[cell.objects]]
name = "table"
shape = "box"
size = [1.4, 1.2, 0.05]
xyz = [0.2, 0.0, -0.025]
[[cell.objects]]
name = "fixture"
shape = "cylinder"
size = [0.06, 0.3]
xyz = [0.45, -0.42, 0.15]
"""
OBJECTS = ("table", "fixture")
#: Drawn capsule ends agree with the forward kinematics to this, m (both double precision).
FK_TOL_M = 1e-9


def _cli(argv: list[str]) -> tuple[int, str]:
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        code = main(argv)
    return code, err.getvalue()


@pytest.fixture(scope="module")
def cell_run(tmp_path_factory) -> Path:
    """``compplan plan`` of the shipped UR5 drilling problem with the cell above (report from the
    plan in memory)."""
    d = tmp_path_factory.mktemp("cell_plan")
    problem = d / "cell_problem.toml"
    problem.write_text(SHIPPED.read_text(encoding="utf-8") + CELL, encoding="utf-8")
    code, err = _cli(["plan", str(problem), "--out", str(d / "run")])
    assert code == 0, err
    return d / "run"


@pytest.fixture(scope="module")
def folder_report(cell_run, tmp_path_factory) -> Path:
    """The same run re-reported from its folder alone (the problem file deleted first)."""
    d = tmp_path_factory.mktemp("cell_report") / "run"
    shutil.copytree(cell_run, d)
    (cell_run.parent / "cell_problem.toml").rename(cell_run.parent / "moved_away.toml")
    try:
        code, err = _cli(["report", str(d), "--no-map", "--jobs", "1"])
    finally:
        (cell_run.parent / "moved_away.toml").rename(cell_run.parent / "cell_problem.toml")
    assert code == 0, err
    return d


def _decode(v: Any) -> np.ndarray:
    """A plotly array: a list, or ``{"dtype", "bdata"}`` (base64 typed array)."""
    if isinstance(v, dict) and "bdata" in v:
        return np.frombuffer(base64.b64decode(v["bdata"]), dtype=np.dtype(v["dtype"])).astype(float)
    return np.array([np.nan if x is None else x for x in v], dtype=float)


def _traces(html: str) -> list[dict[str, Any]]:
    """The traces of the cell view's plotly figure in report.html."""
    m = re.search(r'Plotly\.newPlot\(\s*"' + PLOTLY_DIV_ID + r'",\s*', html)
    assert m, "no plotly figure of the cell view"
    traces, _ = json.JSONDecoder().raw_decode(html, m.end())
    return traces


@pytest.mark.parametrize("which", ["plan", "folder"])
def test_report_has_the_interactive_cell_view_self_contained(which, cell_run, folder_report):
    """One trace per object (the names of [cell]), the path coloured by the error, the robot at
    the first and last waypoint (only the last solid); plotly.js inline once, no script from the
    network; the static PNG and PDF written and referenced by report.md."""
    run = cell_run if which == "plan" else folder_report
    html = (run / "report.html").read_text(encoding="utf-8")
    traces = _traces(html)
    objects = [t for t in traces if (t.get("meta") or {}).get("kind") == "object"]
    assert sorted(t["name"] for t in objects) == sorted(OBJECTS)
    assert all(t["type"] == "mesh3d" and len(_decode(t["i"])) > 0 for t in objects)
    path = [t for t in traces if (t.get("meta") or {}).get("kind") == "path"]
    assert len(path) == 1
    n = len(np.loadtxt(run / "waypoints.csv", delimiter=",", skiprows=1, ndmin=2))
    err_mm = _decode(path[0]["marker"]["color"])
    wp = np.genfromtxt(run / "waypoints.csv", delimiter=",", names=True)
    expected = np.linalg.norm(np.column_stack([wp["ebx"], wp["eby"], wp["ebz"]]), axis=1) * 1e3
    np.testing.assert_allclose(err_mm, expected, rtol=1e-12, atol=1e-12)
    robots = [t for t in traces if (t.get("meta") or {}).get("kind") == "robot"]
    drawn = [t["meta"]["waypoint"] for t in robots]
    assert drawn[0] == 0 and drawn[-1] == n - 1 and drawn == sorted(set(drawn))
    assert [t["opacity"] == 1.0 for t in robots] == [False] * (len(robots) - 1) + [True]
    assert html.count('data-bundle="plotly.js"') == 1 and html.count(f'id="{PLOTLY_DIV_ID}"') == 1
    assert not re.search(r"<script[^>]*\bsrc=", html), "a script loaded from elsewhere"
    assert (run / "figures" / f"{CELL_FIGURE}.png").stat().st_size > 0
    assert (run / "figures" / f"{CELL_FIGURE}.pdf").stat().st_size > 0
    assert f"figures/{CELL_FIGURE}.png" in (run / "report.md").read_text(encoding="utf-8")


def test_a_run_without_a_cell_has_no_cell_view(paper_report):
    """No figure, no absent note, no plotly bundle."""
    html = (paper_report / "report.html").read_text(encoding="utf-8")
    assert CELL_FIGURE not in html and "plotly" not in html.lower()
    assert not (paper_report / "figures" / f"{CELL_FIGURE}.png").exists()
    assert CELL_FIGURE not in (paper_report / "report.md").read_text(encoding="utf-8")


def _expected_points(robot: Any, q: np.ndarray) -> np.ndarray:
    """The capsule ends the chain defines at ``q`` (6,), from the arm model's compiled forward
    kinematics: base origin, DH frame origins, the points the d offsets reach along the joint axes
    (and a modified-DH row's a offset), the flange, and the ends of the robot's own segments."""
    from models.arm import ArmModel

    km = ArmModel.from_robot(robot).kinematics
    F = [np.asarray(robot.frame02base, float)] + [f[0] for f in km.batch(km.fk_frames, q[None])]
    pts = [np.zeros(3)] + [T[:3, 3] for T in F]
    for i in range(1, 7):
        if robot.convention == "standard_dh":
            pts.append(F[i - 1][:3, 3] + robot.d[i - 1] * F[i - 1][:3, 2])
        else:
            pts.append(F[i][:3, 3] - robot.d[i - 1] * F[i][:3, 2])
            if i < 6:
                pts.append(F[i][:3, 3] + robot.a[i] * F[i][:3, 0])
    if robot.convention != "standard_dh":
        pts.append(F[0][:3, 3] + robot.a[0] * F[0][:3, 0])
    pts.append((F[6] @ np.asarray(robot.flange2frame6, float))[:3, 3])
    # the robot's own segments (its [collision] table: UR link offsets, lines), each end fixed in a
    # DH frame (-1 base), placed by the same forward kinematics
    from models.collision import capsule_model

    m = capsule_model(robot)
    ext = [np.eye(4)] + F
    for fr, loc in zip(np.r_[m.frame_a, m.frame_b], np.vstack([m.local_a, m.local_b])):
        pts.append(ext[fr + 1][:3, :3] @ loc + ext[fr + 1][:3, 3])
    return np.array(pts)


def test_capsule_ends_are_the_forward_kinematics_of_the_drawn_postures(folder_report):
    """Every drawn capsule end is a joint point of the commanded posture (``qc`` of waypoints.csv)
    by the arm model's forward kinematics, and every joint point is drawn; the tool runs from the
    flange to the TCP."""
    from models.robot import robot_from_dict

    summary = json.loads((folder_report / "summary.json").read_text(encoding="utf-8"))
    robot = robot_from_dict(summary["robot_file"])
    wp = np.genfromtxt(folder_report / "waypoints.csv", delimiter=",", names=True)
    qc = np.column_stack([wp[f"qc{i}"] for i in range(1, 7)])
    traces = _traces((folder_report / "report.html").read_text(encoding="utf-8"))
    axes = [t for t in traces if (t.get("meta") or {}).get("kind") == "capsule_axes"]
    tools = {t["meta"]["waypoint"]: t for t in traces if (t.get("meta") or {}).get("kind") == "tool"}
    assert len(axes) >= 2
    from models.arm import ArmModel

    km = ArmModel.from_robot(robot).kinematics
    for t in axes:
        k = t["meta"]["waypoint"]
        drawn = np.column_stack([_decode(t[a]) for a in "xyz"])
        drawn = drawn[np.all(np.isfinite(drawn), axis=1)]
        exp = _expected_points(robot, qc[k])
        d = np.linalg.norm(drawn[:, None] - exp[None], axis=2)
        assert d.min(axis=1).max() < FK_TOL_M, f"waypoint {k}: a drawn end is no joint point"
        assert d.min(axis=0).max() < FK_TOL_M, f"waypoint {k}: a joint point is not drawn"
        tool = np.column_stack([_decode(tools[k][a]) for a in "xyz"])
        np.testing.assert_allclose(tool[1], km.tcp(qc[k][None])[0, :3, 3], atol=FK_TOL_M)


@pytest.mark.parametrize(
    "edit,key",
    [
        (lambda c: c["objects"][1].__setitem__("size", [0.06]), "problem.cell.objects[1].size"),
        (lambda c: c["objects"][0].__setitem__("shape", "cone"), "problem.cell.objects[0].shape"),
        (lambda c: c["objects"][0].__setitem__("xyz", [0.0, "x", 0.0]), "problem.cell.objects[0].xyz"),
        (lambda c: c.__setitem__("clearance", -0.001), "problem.cell.clearance"),
        (lambda c: c.pop("objects"), "problem.cell.objects"),
    ],
)
def test_a_tampered_recorded_cell_is_refused_naming_the_key(edit, key, cell_run, tmp_path):
    """``compplan report`` refuses with one line naming the key; nothing is written."""
    d = tmp_path / "run"
    shutil.copytree(cell_run, d, ignore=shutil.ignore_patterns("report.*", "figures", "compliance_map.csv"))
    doc = json.loads((d / "summary.json").read_text(encoding="utf-8"))
    edit(doc["problem"]["cell"])
    (d / "summary.json").write_text(json.dumps(doc), encoding="utf-8")
    code, err = _cli(["report", str(d), "--no-map", "--jobs", "1"])
    assert code == 2 and err.startswith("compplan: error:") and err.count("\n") == 1, err
    assert key in err and "Traceback" not in err, err
    assert not (d / "report.html").exists()
