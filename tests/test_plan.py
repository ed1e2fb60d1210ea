"""``compplan plan`` / ``demo`` end to end: output files, an independent physics check of
``path.csv``, finite-difference limit checks of the trajectories, and every infeasible input
giving its status, one line on stderr and a non-zero exit."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from planner.cli import EXIT_USER_ERROR, main
from planner.plan import PlanStatus, WAYPOINT_COLUMNS, plan
from problems.problem import load_problem

#: The independent check's contract: TCP on the straight line / waypoint to this (m).
LINE_TOL_M = 1e-6
#: Finite-difference limit checks: a ratio may exceed 1 by this much (rounding of the CSV).
FD_RATIO_TOL = 1e-6
#: Fixed-point iteration of the independent physics.
FIXED_POINT_TOL = 1e-15


# ------------------------------------------------------------------------------ helpers
def _read(path: Path) -> dict[str, np.ndarray]:
    rows = list(csv.reader(path.open()))
    data = np.array(rows[1:], dtype=float).reshape(len(rows) - 1, len(rows[0]))
    return {h: data[:, j] for j, h in enumerate(rows[0])}


def _cols(d: dict[str, np.ndarray], prefix: str) -> np.ndarray:
    return np.column_stack([d[f"{prefix}{i}"] for i in range(1, 7)])


def _rpy(r: list[float]) -> np.ndarray:
    cr, sr, cp, sp, cy, sy = np.cos(r[0]), np.sin(r[0]), np.cos(r[1]), np.sin(r[1]), np.cos(r[2]), np.sin(r[2])
    return (
        np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
        @ np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
        @ np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    )


def _tcp_and_jacobian(q: np.ndarray, robot: dict) -> tuple[np.ndarray, np.ndarray]:
    """Independent standard-DH forward kinematics and geometric Jacobian (NumPy, from the
    robot dictionary written to summary.json)."""
    assert robot["convention"] == "standard_dh"
    T = np.eye(4)
    origins = [np.eye(4)]
    for j, qi in zip(robot["joints"], q):
        th = qi + j["theta_offset"]
        ct, st, ca, sa = np.cos(th), np.sin(th), np.cos(j["alpha"]), np.sin(j["alpha"])
        T = T @ np.array(
            [
                [ct, -st * ca, st * sa, j["a"] * ct],
                [st, ct * ca, -ct * sa, j["a"] * st],
                [0.0, sa, ca, j["d"]],
                [0.0, 0.0, 0.0, 1.0],
            ]
        )
        origins.append(T)
    tool = np.eye(4)
    tool[:3, :3] = _rpy(robot["tool"]["rpy"])
    tool[:3, 3] = robot["tool"]["xyz"]
    tcp = T @ tool
    J = np.zeros((6, 6))
    for i, O in enumerate(origins[:6]):
        z = O[:3, 2]
        J[:3, i] = np.cross(z, tcp[:3, 3] - O[:3, 3])
        J[3:, i] = z
    return tcp, J


def _settle(q_command: np.ndarray, wrench: np.ndarray, robot: dict) -> np.ndarray:
    """Deflected equilibrium q = q_c + K^-1 J(q)^T F by fixed-point iteration; returns the TCP pose."""
    K = np.array([j["stiffness"] for j in robot["joints"]])
    q = q_command.copy()
    for _ in range(200):
        _, J = _tcp_and_jacobian(q, robot)
        q_new = q_command + (J.T @ wrench) / K
        done = np.max(np.abs(q_new - q)) < FIXED_POINT_TOL
        q = q_new
        if done:
            break
    return _tcp_and_jacobian(q, robot)[0]


def _run(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    # without a C compiler the CLI adds one "compplan: note: ..." line (tests/test_no_compiler.py)
    err = "".join(line for line in err.splitlines(keepends=True) if not line.startswith("compplan: note:"))
    return code, out, err


# paper_run (compplan plan paper_4_4 --out DIR --no-figures --no-report): once per session, conftest.py


@pytest.fixture(scope="module")
def machining_run(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("machining")
    assert main(["plan", "machining_offaxis", "--out", str(out), "--dt", "0.004", "--no-report"]) == 0
    return out


# ------------------------------------------------------------------------------ outputs
def test_paper_plan_summary(paper_run):
    s = json.loads((paper_run / "summary.json").read_text())
    assert s["plan_status"] == "ok" and s["chosen_branch"] == "s-w-e-" and s["default_branch"] == "s-w-e+"
    assert set(s["branches"]) == {"s+w+e+", "s+w+e-", "s-w-e+", "s-w-e-"}
    for info in s["branches"].values():
        assert info["status"] == "no_freedom" and info["cost"] > 0
    costs = {k: v["cost"] for k, v in s["branches"].items()}
    assert min(costs, key=costs.get) == "s-w-e-"
    # the gain of the chosen branch over the default, in RMS load-induced TCP error
    assert s["gain"]["vs_default"] == pytest.approx(np.sqrt(costs["s-w-e+"] / costs["s-w-e-"]))
    assert s["gain"]["vs_default"] > 3.0
    assert set(s["duration_s"]) == {"toppra", "jerk_optimal"} and s["controller_trajectory"] == "jerk_optimal"
    for m in ("toppra", "jerk_optimal"):
        for k in ("velocity", "acceleration"):
            assert len(s["limit_ratio"][m][k]) == 6 and max(s["limit_ratio"][m][k]) <= 1.0 + 1e-9
    assert max(s["limit_ratio"]["jerk_optimal"]["jerk"]) <= 1.0 + 1e-9
    for k in ("velocity", "acceleration", "jerk"):
        assert len(s["limits"][k]) == 6
    assert s["robot_file"]["name"] == "ar5" and s["problem"]["name"] == "paper_4_4"
    assert s["wrench"]["F_N"] == [5.0, 10.0, 20.0] and s["status"]["exact"] == "ok"
    assert s["error_after"]["exact"]["max_mm"] < 1e-6 < s["error_before"]["max_mm"]
    # the headline first (units in the keys, rounded), then where the run came from
    assert list(s)[:2] == ["headline", "provenance"]
    h = s["headline"]
    assert (h["status"], h["branch"], h["default_branch"]) == ("ok", "s-w-e-", "s-w-e+")
    assert h["error_after_max_mm"] == 0.0 and h["error_before_max_mm"] == pytest.approx(
        s["error_before"]["max_mm"], rel=5e-4
    )
    assert h["duration_s"] == pytest.approx(s["duration_s"]["jerk_optimal"], rel=5e-4)
    p = s["provenance"]
    assert p["argv"] == ["compplan", "plan", "paper_4_4", "--out", str(paper_run), "--no-figures", "--no-report"]
    assert p["command_line"].startswith("compplan plan paper_4_4 --out ") and p["date_utc"].endswith("Z")
    assert [e["role"] for e in p["inputs"]] == ["problem", "robot model"] and all(e["sha256"] for e in p["inputs"])
    for info in s["branches"].values():  # the exact-equilibrium error beside the NLP's first-order one
        assert info["rms_error_equilibrium_mm"] == pytest.approx(info["rms_error_mm"], rel=0.02)


def test_output_files_and_columns(paper_run):
    names = {p.name for p in paper_run.iterdir()}
    assert {
        "summary.json",
        "path.csv",
        "waypoints.csv",
        "branches.csv",
        "trajectory.csv",
        "trajectory_toppra.csv",
    } <= names
    wp = list(csv.reader((paper_run / "waypoints.csv").open()))[0]
    assert wp == list(WAYPOINT_COLUMNS)
    br = list(csv.reader((paper_run / "branches.csv").open()))[0]
    assert br[0] == "k" and set(br[1:]) == {
        f"{b}_{k}_m" for b in ("s+w+e+", "s+w+e-", "s-w-e+", "s-w-e-") for k in ("analytic", "optimised")
    }
    assert list(csv.reader((paper_run / "path.csv").open()))[0] == ["x", "y", "z"] + [f"q{i}" for i in range(1, 7)]
    tr = list(csv.reader((paper_run / "trajectory.csv").open()))[0]
    assert tr == ["t"] + [f"{p}{i}" for p in ("q", "qd", "qdd", "qddd") for i in range(1, 7)]


@pytest.mark.parametrize("run", ["paper_run", "machining_run"])
def test_path_csv_lands_on_the_line_under_independent_physics(run, request):
    folder = request.getfixturevalue(run)
    s = json.loads((folder / "summary.json").read_text())
    path = _read(folder / "path.csv")
    P = np.column_stack([path["x"], path["y"], path["z"]])
    Q = _cols(path, "q")
    W = np.r_[s["wrench"]["F_N"], s["wrench"]["M_Nm"]]
    a, b = np.array(s["problem"]["path"]["start"]), np.array(s["problem"]["path"]["end"])
    u = (b - a) / np.linalg.norm(b - a)
    for k in range(len(P)):
        T = _settle(Q[k], W, s["robot_file"])
        d = T[:3, 3] - a
        assert np.linalg.norm(d - u * (d @ u)) < LINE_TOL_M, k  # on the straight line
        assert np.linalg.norm(T[:3, 3] - P[k]) < LINE_TOL_M, k  # at its waypoint
        if s["problem"]["orientation"]["rule"] in ("fixed", "free_tool_axis"):
            assert abs(T[2, 2] + 1.0) < 1e-9  # tool axis still down


@pytest.mark.parametrize("run", ["paper_run", "machining_run"])
def test_trajectories_respect_the_limits_by_finite_differences(run, request):
    folder = request.getfixturevalue(run)
    s = json.loads((folder / "summary.json").read_text())
    lim = {k: np.array(s["limits"][k]) for k in ("velocity", "acceleration", "jerk")}
    path = _cols(_read(folder / "path.csv"), "q")
    for name, checked in (
        ("trajectory.csv", ("velocity", "acceleration", "jerk")),
        ("trajectory_toppra.csv", ("velocity", "acceleration")),
    ):
        tr = _read(folder / name)
        t, q = tr["t"], _cols(tr, "q")
        dt = s["dt"]
        assert np.allclose(np.diff(t), dt, atol=1e-12)
        d = {
            "velocity": np.diff(q, axis=0) / dt,
            "acceleration": np.diff(q, 2, axis=0) / dt**2,
            "jerk": np.diff(q, 3, axis=0) / dt**3,
        }
        for k in checked:
            ratio = np.abs(d[k]).max(axis=0) / lim[k]
            assert ratio.max() <= 1.0 + FD_RATIO_TOL, (name, k, ratio)
        assert np.allclose(q[0], path[0], atol=1e-12) and np.allclose(q[-1], path[-1], atol=1e-12)
        assert np.allclose(_cols(tr, "qd")[[0, -1]], 0.0, atol=1e-12)  # rest to rest
        assert s["duration_s"][name == "trajectory.csv" and "jerk_optimal" or "toppra"] == pytest.approx(t[-1])


def test_machining_gain_and_figures(machining_run):
    s = json.loads((machining_run / "summary.json").read_text())
    assert s["posture"]["freedom"] == "free"
    assert all(v["status"] == "optimised" for v in s["branches"].values())
    for v in s["branches"].values():
        assert v["cost"] <= v["cost_analytic"] + 1e-12
    assert s["gain"]["vs_best_analytic"] > 1.05 and s["gain"]["vs_default"] > s["gain"]["vs_best_analytic"]
    for name in ("branches.png", "trajectory.png"):
        assert (machining_run / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_demo_is_plan_on_the_paper_problem(tmp_path, capsys, paper_run):
    code, out, err = _run(capsys, "demo", "--out", str(tmp_path), "--no-figures", "--no-report")
    assert code == 0 and err == ""
    assert "before compensation" in out and "after exact" in out and "chosen branch s-w-e-" in out
    s = json.loads((tmp_path / "summary.json").read_text())
    ref = json.loads((paper_run / "summary.json").read_text())
    assert {k: v["cost"] for k, v in s["branches"].items()} == {k: v["cost"] for k, v in ref["branches"].items()}
    assert s["error_before"] == ref["error_before"]


def test_demo_api_used_by_the_report(tmp_path):
    from planner.demo import run_demo, write_outputs

    res = run_demo(n_points=12)
    assert res.ok and res.branch.label == "s-w-e-" and res.positions.shape == (12, 3)
    summary = write_outputs(res, tmp_path)
    assert summary["n_waypoints"] == 12 and (tmp_path / "branches.csv").is_file()


# ------------------------------------------------------------------------------ failures
def _problem_file(tmp_path: Path, **sections: str) -> Path:
    base = {
        "head": 'name = "bad"\n[robot]\nmodel = "ar5"\ntool = { xyz = [0.1, 0.0, 0.05] }\n',
        "path": '[path]\nkind = "line"\nstart = [0.20, 0.40, 0.30]\nend = [0.45, -0.10, 0.30]\npoints = 10\n',
        "orientation": '[orientation]\nrule = "free_tool_axis"\n',
        "wrench": "[wrench]\nforce = [15.0, -25.0, 30.0]\n",
        "rest": "",
    }
    base.update(sections)
    p = tmp_path / "bad.toml"
    p.write_text("".join(base.values()))
    return p


FAILURES = [
    (
        "unreachable",
        {"path": '[path]\nkind = "waypoints"\npositions = [[0.3, 0.0, 0.3], [1.5, 0.0, 0.3], [0.3, 0.1, 0.3]]\n'},
        ["unreachable", "waypoint 1"],
    ),
    ("flip", {"rest": "[limits]\nmax_joint_step = 0.01\n"}, ["no_branch", "flip between waypoints"]),
    ("toppra", {"rest": "[timing]\ntoppra_max_iterations = 1\n"}, ["timing_failed", "toppra", "acceleration"]),
    ("ipopt", {"rest": "[solver]\nmax_iter = 1\n"}, ["solver_failed", "IPOPT", "Maximum_Iterations_Exceeded"]),
    ("bad file", {"rest": "[limits]\nspeed = 1\n"}, ["[limits]", "unknown key", "speed"]),
]


@pytest.mark.parametrize("case,sections,words", FAILURES, ids=[f[0] for f in FAILURES])
def test_infeasible_input_gives_status_one_line_and_nonzero_exit(tmp_path, capsys, case, sections, words):
    out_dir = tmp_path / "out"
    code, out, err = _run(capsys, "plan", str(_problem_file(tmp_path, **sections)), "--out", str(out_dir))
    assert code == EXIT_USER_ERROR
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("compplan: error: "), err
    for w in words:
        assert w in lines[0], (w, lines[0])
    assert "Traceback" not in err and not out_dir.exists()  # nothing written


def test_missing_problem_and_bad_dt(tmp_path, capsys):
    code, _, err = _run(capsys, "plan", "no_such_problem", "--out", str(tmp_path))
    assert code == EXIT_USER_ERROR and "not a shipped problem" in err and len(err.strip().splitlines()) == 1
    with pytest.raises(SystemExit):
        main(["plan", "paper_4_4", "--out", str(tmp_path), "--dt", "0.5"])


def test_plan_result_statuses_without_the_cli():
    pr = load_problem("paper_4_4").with_timing(toppra_max_iterations=1)
    res = plan(pr)
    assert res.status is PlanStatus.TIMING_FAILED and "toppra" in res.reason
    assert res.posture is not None and res.exact is not None  # what ran is kept
    with pytest.raises(Exception, match="timing_failed"):
        res.raise_for_status()


def test_single_pose_command(tmp_path, capsys):
    code, out, err = _run(capsys, "pose", "paper_4_4", "--waypoint", "39", "--out", str(tmp_path))
    assert code == 0 and err == ""
    d = json.loads((tmp_path / "pose.json").read_text())
    assert d["provenance"]["argv"][:2] == ["compplan", "pose"] and d["provenance"]["inputs"][0]["name"] == "paper_4_4"
    e = [b["error_m"] for b in d["branches"].values()]
    assert len(e) == 8 and d["chosen_branch"] == min(d["branches"], key=lambda k: d["branches"][k]["error_m"])
    code, _, err = _run(capsys, "pose", "paper_4_4", "--waypoint", "40")
    assert code == EXIT_USER_ERROR and "--waypoint 40" in err


# ------------------------------------------------------------------------------ a run is computed once
def test_a_plan_is_computed_once(tmp_path, monkeypatch, capsys):
    """One ``compplan plan`` with its report (here ``demo``, the same pipeline, on fewer waypoints):
    the summary (input hashes, every branch's equilibrium), the tables and the arm model's
    kinematics are built once and shared by summary.json, the CSV files, the printout and the
    report, whose compliance map (drawn here, not cached) uses them."""
    import collections

    from models.symbolic import KinematicModel
    from planner.plan import PlanResult
    from planner.report import maps

    calls: collections.Counter = collections.Counter()

    def count(owner: type, name: str, key: str) -> None:
        f = getattr(owner, name)

        def counted(*args, **kwargs):
            calls[key] += 1
            return f(*args, **kwargs)

        monkeypatch.setattr(owner, name, counted)

    for name in ("summary", "waypoint_table", "branch_table", "branch_errors"):
        count(PlanResult, name, name)
    count(KinematicModel, "__init__", "KinematicModel")
    monkeypatch.setattr(maps, "_map_cache_dir", lambda key: tmp_path / "cache" / key)
    code, _, err = _run(capsys, "demo", "--points", "12", "--out", str(tmp_path / "run"))
    assert code == 0 and err == "", err
    assert (tmp_path / "run" / "report.html").is_file() and (tmp_path / "run" / "compliance_map.csv").is_file()
    assert dict(calls) == {
        "summary": 1,
        "waypoint_table": 1,
        "branch_table": 1,
        "branch_errors": 1,
        "KinematicModel": 1,
    }


def test_the_quick_figures_are_the_reports(machining_run, tmp_path):
    """``--no-report`` writes the report's figures 5 and 6, drawn by the same functions: one drawing
    of each figure."""
    import shutil

    from planner.report import write_report

    folder = tmp_path / "run"
    shutil.copytree(machining_run, folder)
    write_report(folder, map_options=False, workers=1)
    for quick, figure in (("branches.png", "fig5_branches"), ("trajectory.png", "fig6_trajectory")):
        assert (folder / quick).read_bytes() == (folder / "figures" / f"{figure}.png").read_bytes(), quick


def test_the_reference_method_s_unenforced_limits_are_not_warnings(paper_result):
    """Issue 24: TOPP-RA beside the controller's method is a reference; its jerk (not limited by it)
    is in the summary, not a warning on every plan. The controller's own would be warned about."""
    res = paper_result
    assert "toppra" in res.trajectories and res.controller != "toppra"
    assert not any(w.startswith("toppra") and "does not limit" in w for w in res.warnings), res.warnings
    assert res.view().summary["timing"]["toppra"]["within_all_limits"] in (True, False)


def test_binding_shares_below_half_a_percent_are_not_printed_as_zero():
    from problems.timing.limit_use import describe_binding

    use = {"binding": [{"limit": "jerk", "joint": 3, "fraction_of_time": 0.001}]}
    assert describe_binding(use) == "binds: jerk of joint 3 (under 0.5 % of the time)"


def test_long_warnings_are_one_short_terminal_line():
    """Issue 24: a ~2000-character warning was printed whole; the terminal line is cut at a clause
    boundary and points to the summary, which keeps it whole."""
    from planner.commands.plan import WARNING_TERMINAL_CHARS, terminal_warning

    short = "toppra does not limit jerk"
    assert terminal_warning(short) == short
    long = "the model was identified from unregistered data: " + ", ".join(f"param_{i} (x{i})" for i in range(200))
    line = terminal_warning(long)
    assert len(line) <= WARNING_TERMINAL_CHARS + 60 and "\n" not in line
    assert line.endswith("(in full: summary.json 'warnings')") and line.startswith(long[:40])
    assert ", ..." not in line and not line.split(" ...")[0].endswith(",")
