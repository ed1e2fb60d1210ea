"""The report draws the plan's arm model (issue 22): the compliance map of a plan made with
``--robot MODEL`` is the model's, from the plan in memory and from its folder
(``compplan report DIR`` reads the model file the summary records, checked by SHA-256).

The model: ar5 with every joint twice as compliant (``stiffness.s = 1``), so its translational
compliance ``C = J K^-1 J^T`` is exactly twice the nominal one at the same pose.
"""

from __future__ import annotations

import json
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import models.effects as fx
from models import load_robot
from models.arm import ArmModel
from models.arm_file import model_toml
from models.errors import InputError
from planner.cli import main
from planner.demo import demo_problem
from planner.plan import plan, write_outputs
from planner.plan_record import record_from_plan as run_from_plan
from planner.record import read_record as load_run
from planner.report import maps

#: Waypoints of the plans (few: the map, not the path, is under test).
POINTS = 12
#: The model's joint compliance over the nominal one.
COMPLIANCE_FACTOR = 2.0
#: The model's map over the nominal one at the same grid point (same poses; float rounding only).
MAP_RATIO_RTOL = 1e-9
#: Grid points per side in the cache keys compared here.
MAP_POINTS = 9


def _soft_ar5() -> ArmModel:
    r = load_robot("ar5")
    th = fx.make_layout(r).nominal.copy()
    th[fx.GROUP_SLICES["stiffness.s"]] = COMPLIANCE_FACTOR - 1.0
    return ArmModel(nominal=r, theta=th)


def _c11(run) -> np.ndarray:
    """C11 (m/N) over the report's map of ``run`` (path plane, uncached); NaN where unreachable."""
    files: dict[str, bytes] = {}
    item = maps.map_item(run, None, None, files, map_cache=False)
    assert item.job is not None, item.absent
    lines = files["compliance_map.csv"].decode().splitlines()
    col = lines[0].split(",").index("C11_m_per_N")
    return np.loadtxt(lines[1:], delimiter=",")[:, col]


def _ratio_is_the_model_s(c_model: np.ndarray, c_nominal: np.ndarray) -> None:
    ok = np.isfinite(c_nominal)
    assert ok.sum() >= 3 and np.array_equal(ok, np.isfinite(c_model))
    np.testing.assert_allclose(c_model[ok], COMPLIANCE_FACTOR * c_nominal[ok], rtol=MAP_RATIO_RTOL)


@pytest.fixture(scope="module")
def nominal_result():
    return plan(demo_problem(n_points=POINTS)).raise_for_status()


@pytest.fixture(scope="module")
def model_file(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("model") / "ar5_soft.toml"
    path.write_text(model_toml(_soft_ar5()))
    return path


@pytest.fixture(scope="module")
def model_run(model_file, tmp_path_factory) -> Path:
    """``compplan demo --robot MODEL`` (the paper's problem on the soft model file)."""
    folder = tmp_path_factory.mktemp("model_run") / "run"
    assert (
        main(
            [
                "demo",
                "--robot",
                str(model_file),
                "--points",
                str(POINTS),
                "--out",
                str(folder),
                "--no-report",
                "--no-figures",
            ]
        )
        == 0
    )
    return folder


def test_the_report_of_a_plan_draws_its_models_map(nominal_result, tmp_path):
    res = plan(demo_problem(n_points=POINTS).with_robot(_soft_ar5())).raise_for_status()
    run = run_from_plan(res, tmp_path)
    assert run.model is res.problem.model  # the plan's model, not its robot file
    nominal = run_from_plan(nominal_result, tmp_path)
    _ratio_is_the_model_s(_c11(run), _c11(nominal))
    # the maps' cache tells the two models apart
    opts = {"mode": "path plane", "points": MAP_POINTS}
    assert maps._map_cache_key(run.model, opts) != maps._map_cache_key(nominal.model, opts)
    assert maps._map_cache_key(nominal.model, opts) == maps._map_cache_key(nominal.robot, opts)


def test_compplan_report_reads_the_model_the_summary_records(model_run, model_file, monkeypatch, tmp_path):
    s = json.loads((model_run / "summary.json").read_text())
    assert s["model"]["identified"] and Path(s["model"]["file"]) == model_file.resolve()
    run = load_run(model_run)
    assert run.model is not None and run.model.sha256 == s["model"]["sha256"]
    np.testing.assert_allclose(run.model.joint_compliance(), COMPLIANCE_FACTOR / run.robot.stiffness)
    nominal = replace(run, model=ArmModel.from_robot(run.robot))  # what the report drew before
    _ratio_is_the_model_s(_c11(run), _c11(nominal))
    # the command itself: its compliance_map.csv is the model's
    monkeypatch.setattr(maps, "_map_cache_dir", lambda key: tmp_path / "cache" / key)
    folder = tmp_path / "copy"
    shutil.copytree(model_run, folder)
    assert main(["report", str(folder), "--jobs", "1"]) == 0
    lines = (folder / "compliance_map.csv").read_text().splitlines()
    col = lines[0].split(",").index("C11_m_per_N")
    _ratio_is_the_model_s(np.loadtxt(lines[1:], delimiter=",")[:, col], _c11(nominal))


def test_a_changed_or_moved_model_file_is_a_clear_error(model_run, model_file, tmp_path):
    folder, moved = tmp_path / "run", tmp_path / "elsewhere" / "ar5_soft.toml"
    shutil.copytree(model_run, folder)
    moved.parent.mkdir()
    shutil.copy(model_file, moved)
    s = json.loads((folder / "summary.json").read_text())
    sha = s["model"]["sha256"]
    s["model"]["file"] = str(moved)  # the run as if planned with the copy
    (folder / "summary.json").write_text(json.dumps(s))
    assert load_run(folder).model is not None  # the same bytes: accepted
    moved.write_text(moved.read_text() + "\n# edited after the plan\n")
    with pytest.raises(InputError) as exc:
        load_run(folder)
    msg = str(exc.value)
    import hashlib

    now = hashlib.sha256(moved.read_bytes()).hexdigest()
    for part in (str(moved), sha, now, "changed", "restore", "plan again"):
        assert part in msg, (part, msg)
    moved.unlink()
    with pytest.raises(InputError, match="cannot be read") as exc:
        load_run(folder)
    assert str(moved) in str(exc.value) and sha in str(exc.value) and "restore" in str(exc.value)
    assert main(["report", str(folder), "--no-map"]) == 2  # the command says so, exit 2


def test_an_identified_model_without_a_file_is_not_drawn_as_the_nominal(tmp_path):
    res = plan(demo_problem(n_points=POINTS).with_robot(_soft_ar5())).raise_for_status()
    write_outputs(res, tmp_path, with_figures=False)
    run = load_run(tmp_path)
    assert run.model is None and "built in memory" in run.absent["model"]
    item = maps.map_item(run, None, None, {}, map_cache=False)
    assert item.job is None and "built in memory" in item.absent
