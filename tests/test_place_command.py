"""``compplan place``: the shipped example's claim, the files it writes, and their agreement with
each other and with the library.

The shipped ``placement_milling`` problem is written the way a cell is first drawn (the UR10
centred in front of the slot); its ``[placement]`` grid must hold a placement that cuts the
load-induced error by at least :data:`SHIPPED_MIN_FACTOR`, by the sweep's score and by the full
plans (posture NLP, exact equilibrium), and the report must state the factor.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

from planner.cli import main as cli_main
from planner.placement import SCORE_COLUMNS
from problems.placement.grid import GRID_AXES, parse_grid_text
from problems.placement.kernel import PlacementKernel
from problems.placement.scores import PlacementStatus, ranking
from problems.problem import load_problem

#: What the shipped example must show: the best placement's RMS load-induced error at most
#: 1/1.5 of the problem as written (measured: 2.38x by the sweep, 2.47x by the full plans).
SHIPPED_MIN_FACTOR = 1.5


def _run(argv: list[str], capsys) -> tuple[int, str, str]:
    code = cli_main(argv)
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def shipped_run(tmp_path_factory) -> Path:
    """``compplan place placement_milling`` with the file's own grid and the default settings."""
    out = tmp_path_factory.mktemp("place") / "study"
    assert cli_main(["place", "placement_milling", "--out", str(out)]) == 0
    return out


def test_shipped_example_cuts_the_error(shipped_run: Path):
    s = json.loads((shipped_run / "summary.json").read_text())
    h = s["headline"]
    assert s["command"] == "place" and h["status"] == "ok"
    assert h["as_written_status"] == "ok"
    assert h["improvement_rms_factor"] >= SHIPPED_MIN_FACTOR
    assert h["best_rms_error_mm"] * SHIPPED_MIN_FACTOR <= h["as_written_rms_error_mm"]
    # the full plans confirm it: posture NLP and exact equilibrium, before compensation
    best, base = h["best_plan"], h["as_written_plan"]
    assert best["status"] == base["status"] == "ok"
    assert best["error_before_rms_mm"] * SHIPPED_MIN_FACTOR <= base["error_before_rms_mm"]
    # and both are compensated exactly
    assert best["error_after_max_mm"] == base["error_after_max_mm"] == 0.0
    # the NLP can only improve on the sweep's analytic postures (first order vs exact equilibrium
    # differ by the second-order terms: well under 1 %)
    assert best["error_before_rms_mm"] <= h["best_rms_error_mm"] * 1.01
    # the report states the factor
    page = (shipped_run / "report.html").read_text()
    assert f"cuts the RMS load-induced error by {s['improvement_rms_factor']:.3g}×" in page
    for name in ("placement_error_map.png", "placement_margins.png", "placement_plans.png"):
        assert (shipped_run / "figures" / name).read_bytes().startswith(b"\x89PNG")


def test_shipped_summary_records_inputs_and_the_grid(shipped_run: Path):
    s = json.loads((shipped_run / "summary.json").read_text())
    prov = s["provenance"]
    assert prov["command_line"].startswith("compplan place placement_milling")
    roles = {e["role"]: e for e in prov["inputs"]}
    assert roles["problem"]["name"] == "placement_milling" and len(roles["problem"]["sha256"]) == 64
    assert roles["robot model"]["name"] == "ur10"
    g = s["grid"]
    assert g["x_m"] == [-0.6, 1.0, 17] and g["y_m"] == [-1.0, 1.0, 21] and g["yaw_deg"] == [0.0, 270.0, 4]
    assert s["sweep"]["placements"] == g["placements"] == 17 * 21 * 4
    assert sum(s["sweep"]["status_counts"].values()) == g["placements"]
    assert [p["label"] for p in s["plans"]] == ["best 1", "best 2", "best 3", "as written"]


def _read_csv(path: Path) -> tuple[list[str], list[dict[str, str]]]:
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    with open(path, newline="") as fh:
        header = next(csv.reader(fh))
    return header, rows


def test_scores_csv_is_the_librarys_sweep(shipped_run: Path):
    """scores.csv: one row per grid placement in grid order, the library's scores to the last digit
    (shortest round-trip text);
    ranking.csv: the feasible ones in the library's ranking order."""
    header, rows = _read_csv(shipped_run / "scores.csv")
    assert header == list(SCORE_COLUMNS)
    problem = load_problem("placement_milling")
    pls = problem.placement.placements()
    assert len(rows) == len(pls)
    sc = PlacementKernel(problem).evaluate(pls)
    labels = PlacementKernel(problem).ik.labels
    for i in (0, 151, len(rows) // 2, len(rows) - 1) + tuple(np.flatnonzero(sc.feasible)[:5]):
        r = rows[i]
        assert int(r["index"]) == i
        for j, k in enumerate(GRID_AXES):
            assert math.isclose(float(r[k]), pls[i, j] / GRID_AXES[k][0], abs_tol=1e-12)
        assert r["status"] == sc.status_of(i).value
        if sc.status[i] == PlacementStatus.OK.code:
            assert r["best_branch"] == labels[int(sc.best_branch[i])]
            assert float(r["rms_error_mm"]) == sc.rms_error_m[i] * 1e3
            assert float(r["max_error_mm"]) == sc.max_error_m[i] * 1e3
            assert r["blocked_waypoint"] == ""
        else:
            assert r["best_branch"] == r["rms_error_mm"] == r["joint_margin_deg"] == ""
    header, ranked = _read_csv(shipped_run / "ranking.csv")
    assert header == ["rank"] + list(SCORE_COLUMNS)
    assert [int(r["index"]) for r in ranked] == ranking(sc).tolist()
    assert [int(r["rank"]) for r in ranked] == list(range(1, len(ranked) + 1))
    assert {r["status"] for r in ranked} == {"ok"}


@pytest.mark.slow
def test_place_prints_the_result_and_writes_whole(tmp_path, capsys):
    """A small grid with analytic full plans: stdout names the best placement and the factor; the
    folder holds exactly the files it says; a second run replaces it whole."""
    out = tmp_path / "o"
    argv = [
        "place",
        "placement_milling",
        "--out",
        str(out),
        "--grid",
        "x_m=0.7:0.9:3,y_m=-0.3:0.3:3,yaw_deg=0",
        "--top",
        "1",
        "--no-optimise",
    ]
    code, text, err = _run(argv, capsys)
    assert code == 0, err
    assert "placement study of placement_milling (robot ur10): 9 placements" in text
    assert "cuts the RMS load-induced error" in text and "as written" in text
    names = sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file())
    assert names == [
        "figures/placement_error_map.png",
        "figures/placement_margins.png",
        "figures/placement_plans.png",
        "ranking.csv",
        "report.html",
        "scores.csv",
        "summary.json",
    ]
    s = json.loads((out / "summary.json").read_text())
    assert [p["label"] for p in s["plans"]] == ["best 1", "as written"]
    code, _, err = _run(argv[:4] + ["--grid", "x_m=0.8,y_m=0,yaw_deg=0", "--top", "0", "--no-report"], capsys)
    assert code == 0, err
    assert sorted(p.name for p in out.iterdir()) == ["ranking.csv", "scores.csv", "summary.json"]
    s = json.loads((out / "summary.json").read_text())
    assert s["grid"]["top"] == 0 and [p["label"] for p in s["plans"]] == ["as written"]  # --top 0
    assert s["headline"]["best_plan"] is None and s["headline"]["as_written_plan"]["status"] == "ok"


def test_grid_option_over_the_file(capsys, tmp_path):
    """--grid replaces only the axes it names; --top overrides the file's."""
    from planner.commands.place import grid_for

    p = load_problem("placement_milling")
    g = grid_for(p, ["x_m=0.5", "yaw_deg=0:90:2,top=1"], None)
    np.testing.assert_array_equal(g.axes["x_m"], [0.5])
    np.testing.assert_allclose(g.axes["yaw_deg"], np.radians([0.0, 90.0]))
    np.testing.assert_array_equal(g.axes["y_m"], p.placement.axes["y_m"])
    assert g.top == 1 and grid_for(p, [], 5).top == 5


def test_default_grid_surrounds_the_path():
    """A problem without [placement]: 21 x 21 base positions around the path's centroid within the
    arm's reach, 8 yaws."""
    from planner.commands.place import grid_for

    p = load_problem("machining_offaxis")
    assert p.placement is None
    g = grid_for(p, [], None)
    assert g.shape == (21, 21, 1, 8, 1)
    c = p.positions.mean(axis=0)
    assert math.isclose(float(np.mean(g.axes["x_m"])), float(c[0]), abs_tol=1e-12)
    assert math.isclose(float(np.mean(g.axes["y_m"])), float(c[1]), abs_tol=1e-12)
    sub = parse_grid_text("x_m=0,y_m=0,yaw_deg=0", base=g)
    assert sub.size == 1
