"""Reports (issue 3): report.html/report.md/figures of a run folder, and compliance maps."""

from __future__ import annotations

import base64
import json
import math
import shutil
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from models import KinematicModel, load_robot
from models.errors import CompplanError, InputError
from models.ik import BRANCH_LABELS
from planner.cli import main
from planner.compliance_map import compliance_map
from planner.demo import run_demo, write_outputs
from planner.output import TRAJECTORY_COLUMNS, csv_bytes
from planner.report import (FIGURE_NAMES, build_figures, load_run, lookup, render_html,
                            render_markdown, run_from_plan, summary_tables, write_report)

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
#: A small map keeps the tests quick; the full 61x61 default is exercised by the demo report.
SMALL_MAP = {"points": 13}


class _ReportParser(HTMLParser):
    """Collects embedded images, value cells (data-key) and absent-figure notes."""

    def __init__(self) -> None:
        super().__init__()
        self.images: dict[str, str] = {}
        self.all_img_src: list[str] = []
        self.cells: list[dict] = []
        self.absent: dict[str, str] = {}
        self._cell: dict | None = None
        self._absent: str | None = None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "img":
            self.all_img_src.append(a.get("src", ""))
            if "data-figure" in a:
                self.images[a["data-figure"]] = a.get("src", "")
        if tag == "td" and "data-key" in a:
            self._cell = {"key": a["data-key"], "value": json.loads(a["data-value"]),
                          "agg": a.get("data-agg"), "text": ""}
        if tag == "p" and "data-absent" in a:
            self._absent = a["data-absent"]
            self.absent[self._absent] = ""

    def handle_data(self, data):
        if self._cell is not None:
            self._cell["text"] += data
        if self._absent is not None:
            self.absent[self._absent] += data

    def handle_endtag(self, tag):
        if tag == "td" and self._cell is not None:
            self.cells.append(self._cell)
            self._cell = None
        if tag == "p":
            self._absent = None


def parse(folder: Path) -> _ReportParser:
    p = _ReportParser()
    p.feed((folder / "report.html").read_text())
    return p


def _flat(v):
    if isinstance(v, list):
        return [x for item in v for x in _flat(item)]
    return [v]


def check_cells_match_summary(folder: Path) -> _ReportParser:
    """Every value cell of the HTML tables equals its summary.json entry."""
    summary = json.loads((folder / "summary.json").read_text())
    rep = parse(folder)
    assert rep.cells, "no machine-checkable cells in report.html"
    for c in rep.cells:
        expected = lookup(summary, c["key"])          # KeyError: cell names a key not in summary
        if c["agg"] == "max":
            expected = max(x for x in _flat(expected) if x is not None)
        assert c["value"] == expected, c
        text = c["text"].strip()
        if isinstance(expected, str):
            assert text == expected
        elif isinstance(expected, list):
            shown = [float(x) for x in text.strip("[]").split(",")]
            assert shown == pytest.approx([float(x) for x in expected], rel=1e-6, abs=0)
        elif expected is None:
            assert text == "n/a"
        else:
            assert float(text) == pytest.approx(float(expected), rel=1e-6, abs=0), c
    return rep


def check_figures_embedded(folder: Path, rep: _ReportParser, expected_present: set[str]) -> None:
    assert all(src.startswith("data:image/png;base64,") for src in rep.all_img_src)
    assert set(rep.images) == expected_present
    for name in FIGURE_NAMES:
        png, pdf = folder / "figures" / f"{name}.png", folder / "figures" / f"{name}.pdf"
        if name in expected_present:
            data = base64.b64decode(rep.images[name].split(",", 1)[1])
            assert data.startswith(PNG_MAGIC)
            assert data == png.read_bytes(), f"{name}: embedded PNG differs from the file"
            assert pdf.read_bytes().startswith(b"%PDF")
            assert f"figures/{name}.png" in (folder / "report.md").read_text()
        else:
            assert name in rep.absent and rep.absent[name].strip(), f"{name}: absence not stated"
            assert not png.exists() and not pdf.exists()


# --------------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def demo_result():
    """The plan of the demo (paper section 4.4 on ar5), in memory."""
    return run_demo(load_robot("ar5"))


@pytest.fixture(scope="module")
def demo_run(demo_result, tmp_path_factory) -> Path:
    """A demo output folder (paper section 4.4 on ar5), without report."""
    folder = tmp_path_factory.mktemp("demo")
    write_outputs(demo_result, folder)
    return folder


@pytest.fixture(scope="module")
def demo_report(demo_result, tmp_path_factory) -> Path:
    """The demo's files and report, the report built from the result (as compplan demo)."""
    folder = tmp_path_factory.mktemp("demo_report") / "run"
    write_outputs(demo_result, folder, report=True)        # report defaults, as the CLI runs it
    return folder


def _has_trajectory(folder: Path) -> bool:
    return any(folder.glob("trajectory*.csv"))


def strip_timing(src: Path, dst: Path) -> Path:
    """A run without any trajectory (as a plan without timing, or an older demo)."""
    shutil.copytree(src, dst)
    for p in dst.glob("trajectory*.csv"):
        p.unlink()
    s = json.loads((dst / "summary.json").read_text())
    for k in ("duration_s", "limit_ratio", "timing", "controller_trajectory"):
        s.pop(k, None)
    (dst / "summary.json").write_text(json.dumps(s))
    return dst


def synthetic_timing(src: Path, dst: Path) -> Path:
    """A run whose timing keys take the other accepted shapes: one method, scalar duration,
    per-joint ratios directly under ``limit_ratio``, no ``timing`` file map."""
    strip_timing(src, dst)
    s = json.loads((dst / "summary.json").read_text())
    wp = np.genfromtxt(dst / "waypoints.csv", delimiter=",", names=True)
    q0 = np.array([wp[f"qc{i}"][0] for i in range(1, 7)])
    q1 = np.array([wp[f"qc{i}"][-1] for i in range(1, 7)])
    T = 1.2
    t = np.arange(0.0, T + 1e-9, 0.008)
    x = t / T
    d = q1 - q0
    rows = np.column_stack([t, q0 + np.outer(10 * x**3 - 15 * x**4 + 6 * x**5, d),
                            np.outer((30 * x**2 - 60 * x**3 + 30 * x**4) / T, d),
                            np.outer((60 * x - 180 * x**2 + 120 * x**3) / T**2, d),
                            np.outer((60 - 360 * x + 360 * x**2) / T**3, d)])
    (dst / "trajectory.csv").write_bytes(csv_bytes(TRAJECTORY_COLUMNS, rows))  # default: Ruckig
    s["duration_s"] = T
    s["limit_ratio"] = {"velocity": [0.4] * 6, "acceleration": [0.7] * 6,
                        "jerk": [0.1, 0.2, 0.99, 0.3, 0.0, 0.5]}
    s["limits"] = {"velocity": [2.0] * 6, "acceleration": [4.0] * 6, "jerk": [40.0] * 6}
    (dst / "summary.json").write_text(json.dumps(s))
    return dst


# ------------------------------------------------------------------------------ the demo report
def test_demo_report_renders_every_figure_and_embeds_it(demo_report):
    rep = parse(demo_report)
    present = set(FIGURE_NAMES)
    if not _has_trajectory(demo_report):
        present.discard("fig6_trajectory")
        assert "no trajectory in this run" in rep.absent["fig6_trajectory"]
    check_figures_embedded(demo_report, rep, present)
    assert (demo_report / "compliance_map.csv").is_file()


def test_demo_report_table_equals_summary(demo_report):
    rep = check_cells_match_summary(demo_report)
    keys = {c["key"] for c in rep.cells}
    for k in ("robot", "wrench.F_N", "wrench.M_Nm", "error_before.max_mm",
              "error_before.rms_mm", "error_after.closed_form.max_mm",
              "error_after.closed_form.rms_mm", "error_after.exact.max_mm",
              "error_after.exact.rms_mm"):
        assert k in keys, f"table lacks {k}"
    assert {"branch", "chosen_branch"} & keys
    summary = json.loads((demo_report / "summary.json").read_text())
    for m in summary.get("duration_s", {}):                  # a timed run: durations and ratios
        assert f"duration_s.{m}" in keys
        for kind in ("velocity", "acceleration", "jerk"):
            assert f"limit_ratio.{m}.{kind}" in keys


def test_markdown_table_has_the_same_numbers(demo_report):
    md = (demo_report / "report.md").read_text()
    s = json.loads((demo_report / "summary.json").read_text())
    row = next(line for line in md.splitlines() if line.startswith("| before compensation"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert float(cells[1]) == pytest.approx(s["error_before"]["max_mm"], rel=1e-6)
    assert float(cells[2]) == pytest.approx(s["error_before"]["rms_mm"], rel=1e-6)


# ------------------------------------------------------------- the view from a plan and a folder
def _same(a, b) -> bool:
    """Deep equality of views and figure jobs: arrays exactly (NaN equal to NaN)."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        return a.shape == b.shape and np.array_equal(a, b, equal_nan=a.dtype.kind == "f")
    if isinstance(a, dict) and isinstance(b, dict):
        return list(a) == list(b) and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    return type(a) is type(b) and a == b


def test_view_from_the_plan_equals_the_view_from_its_folder(demo_result, demo_run, monkeypatch):
    """compplan plan/demo build the report from the PlanResult, compplan report from the files
    written from it: the two views, their tables and figure data are the same."""
    import planner.report.run as run_module

    def no_reading(*args, **kwargs):
        raise AssertionError("the view of a plan result read a file")
    with monkeypatch.context() as m:                   # from the result: no file is read
        for name in ("_read_csv", "_read_summary", "_read_trajectory"):
            m.setattr(run_module, name, no_reading)
        mem = run_from_plan(demo_result, demo_run)
    disk = load_run(demo_run)

    assert mem.summary == disk.summary == json.loads((demo_run / "summary.json").read_text())
    assert mem.folder == disk.folder and mem.absent == disk.absent == {}
    assert mem.trajectory_files == disk.trajectory_files and list(mem.trajectories) == ["toppra", "ruckig"]
    for piece in ("waypoints", "branches", "trajectories"):
        assert _same(getattr(mem, piece), getattr(disk, piece)), piece
    assert mem.robot.to_dict() == disk.robot.to_dict()

    t_mem, t_disk = summary_tables(mem.summary, mem.absent), summary_tables(disk.summary, disk.absent)
    assert [t.html() for t in t_mem] == [t.html() for t in t_disk]
    assert [t.markdown() for t in t_mem] == [t.markdown() for t in t_disk]
    f_mem, f_disk = build_figures(mem, map_options=False), build_figures(disk, map_options=False)
    assert [(f.name, f.title, f.caption, f.absent) for f in f_mem] == \
        [(f.name, f.title, f.caption, f.absent) for f in f_disk]
    assert all(f.job is not None for f in f_mem[1:])
    for a, b in zip(f_mem, f_disk):
        assert _same(a.job, b.job), f"{a.name}: the figure data differ"
    assert render_markdown(mem, t_mem, f_mem) == render_markdown(disk, t_disk, f_disk)
    assert render_html(mem, t_mem, f_mem) == render_html(disk, t_disk, f_disk)


def test_report_draws_the_jerk_the_timing_computed(demo_result, demo_run):
    """trajectory*.csv keeps each method's jerk qddd; figure 6 draws it, not a derivative."""
    run = load_run(demo_run)
    assert run.trajectories, "the demo is timed"
    for method, tr in demo_result.trajectories.items():
        name = run.trajectory_files[method]
        header = (demo_run / name).read_text().splitlines()[0].split(",")
        assert header == list(TRAJECTORY_COLUMNS) and header[-6:] == [f"qddd{i}" for i in range(1, 7)]
        assert np.array_equal(run.trajectories[method]["qddd"], tr.qddd)
    fig6 = build_figures(run, map_options=False)[5]
    fn, (trajs, _limits), _ = fig6.job
    assert fn.__name__ == "trajectory_figure"
    for pretty, tr in trajs.items():
        method = {"TOPP-RA": "toppra", "Ruckig": "ruckig"}[pretty]
        assert tr["qddd"] is run.trajectories[method]["qddd"]
    assert "qddd columns of the trajectory file" in fig6.caption


def test_trajectory_file_without_jerk_columns_is_stated(demo_run, tmp_path):
    """A trajectory file written before the jerk was recorded: the jerk panel says so."""
    folder = synthetic_timing(demo_run, tmp_path / "old")
    p = folder / "trajectory.csv"
    rows = [line.split(",")[:19] for line in p.read_text().splitlines()]
    p.write_text("\n".join(",".join(r) for r in rows) + "\n")
    run = load_run(folder)
    assert run.trajectories["ruckig"]["qddd"] is None
    write_report(folder, map_options=False, workers=1)
    rep = check_cells_match_summary(folder)
    check_figures_embedded(folder, rep, set(FIGURE_NAMES) - {"fig1_compliance_map"})
    assert "Jerk not recorded in trajectory.csv" in (folder / "report.md").read_text()
    rows[0][-1] = "qddd1"                                # part of the jerk columns: malformed
    p.write_text("\n".join(",".join(r) for r in rows) + "\n")
    with pytest.raises(InputError, match="qddd2"):
        write_report(folder, map_options=False, workers=1)


# ------------------------------------------------------------------- runs with and without timing
def test_run_without_trajectory_says_so(demo_run, tmp_path):
    folder = strip_timing(demo_run, tmp_path / "untimed")
    calls: list[tuple[str, int, int]] = []
    write_report(folder, progress=lambda *a: calls.append(a), map_options=SMALL_MAP, workers=1)
    assert {c[0] for c in calls} == {"compliance map", "figures"}      # progress reaches the end
    for st in ("compliance map", "figures"):
        last = [c for c in calls if c[0] == st][-1]
        assert last[1] == last[2]
    rep = check_cells_match_summary(folder)
    check_figures_embedded(folder, rep, set(FIGURE_NAMES) - {"fig6_trajectory"})
    assert "no trajectory in this run" in rep.absent["fig6_trajectory"]
    md = (folder / "report.md").read_text()
    assert "No trajectory in this run" in md


def test_other_timing_shapes_are_rendered(demo_run, tmp_path):
    folder = synthetic_timing(demo_run, tmp_path / "synthetic")
    write_report(folder, map_options=SMALL_MAP, workers=1)
    rep = check_cells_match_summary(folder)
    check_figures_embedded(folder, rep, set(FIGURE_NAMES))
    keys = {c["key"]: c for c in rep.cells}
    assert keys["duration_s"]["value"] == 1.2
    assert keys["limit_ratio.jerk"]["value"] == 0.99 and keys["limit_ratio.jerk"]["agg"] == "max"
    assert "TOPP-RA" in (folder / "report.md").read_text()      # stated as absent in the caption


def test_serial_and_parallel_rendering_give_the_same_files(demo_run, tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    shutil.copytree(demo_run, a)
    shutil.copytree(demo_run, b)
    write_report(a, map_options=SMALL_MAP, workers=1, map_cache=False)
    write_report(b, map_options=SMALL_MAP, workers=2, map_cache=False)
    for name in FIGURE_NAMES:
        for ext in ("png", "pdf"):
            fa, fb = a / "figures" / f"{name}.{ext}", b / "figures" / f"{name}.{ext}"
            assert fa.exists() == fb.exists()
            if fa.exists():
                assert fa.read_bytes() == fb.read_bytes(), f"{name}.{ext}"


def test_compliance_map_is_cached_per_robot_and_options(demo_run, tmp_path, monkeypatch):
    import planner.report.maps as report
    monkeypatch.setattr(report, "_map_cache_dir", lambda key: tmp_path / "cache" / key)
    a, b = tmp_path / "a", tmp_path / "b"
    shutil.copytree(demo_run, a)
    shutil.copytree(demo_run, b)
    write_report(a, map_options=SMALL_MAP, workers=1)
    assert len(list((tmp_path / "cache").iterdir())) == 1

    def fail(*args, **kwargs):
        raise AssertionError("the cached map was computed again")
    monkeypatch.setattr(report, "compliance_map", fail)
    write_report(b, map_options=SMALL_MAP, workers=1)
    for name in ("figures/fig1_compliance_map.png", "figures/fig1_compliance_map.pdf",
                 "compliance_map.csv"):
        assert (a / name).read_bytes() == (b / name).read_bytes()
    check_cells_match_summary(b)
    with pytest.raises(AssertionError, match="computed again"):     # other options: a new map
        write_report(b, map_options={"points": 9}, workers=1)


def test_absent_pieces_are_stated_not_fatal(demo_run, tmp_path):
    folder = tmp_path / "bare"
    folder.mkdir()
    s = json.loads((demo_run / "summary.json").read_text())
    del s["robot_file"]
    (folder / "summary.json").write_text(json.dumps(s))
    write_report(folder, workers=1)
    rep = check_cells_match_summary(folder)
    check_figures_embedded(folder, rep, set())
    assert "robot_file" in rep.absent["fig1_compliance_map"]
    assert "waypoints.csv" in rep.absent["fig2_stiffness_error"]
    assert "branches.csv" in rep.absent["fig5_branches"]
    assert "no trajectory in this run" in rep.absent["fig6_trajectory"]


def test_stale_figures_of_an_earlier_report_are_removed(demo_run, tmp_path):
    folder = synthetic_timing(demo_run, tmp_path / "run")
    write_report(folder, map_options=SMALL_MAP, workers=1)
    assert (folder / "figures" / "fig6_trajectory.png").exists()
    (folder / "trajectory.csv").unlink()
    write_report(folder, map_options=False, workers=1)
    assert not (folder / "figures" / "fig6_trajectory.png").exists()
    assert not (folder / "figures" / "fig1_compliance_map.pdf").exists()
    assert not (folder / "compliance_map.csv").exists()


def test_bad_folders_raise_user_errors(tmp_path, demo_run):
    with pytest.raises(InputError, match="does not exist"):
        write_report(tmp_path / "nope")
    with pytest.raises(InputError, match="summary.json not found"):
        write_report(tmp_path)
    folder = tmp_path / "bad"
    shutil.copytree(demo_run, folder)
    text = (folder / "waypoints.csv").read_text().splitlines()
    text[3] = text[3].replace(text[3].split(",")[2], "abc", 1)
    (folder / "waypoints.csv").write_text("\n".join(text) + "\n")
    with pytest.raises(InputError, match=r"waypoints.csv: line 4, column x: 'abc'"):
        write_report(folder)
    assert not (folder / "report.html").exists()        # all or nothing


# ------------------------------------------------------------------------------ compliance map
def test_map_diagonal_equals_model_compliance_at_grid_points():
    robot = load_robot("ar5")
    cm = compliance_map(robot, points=(7, 5))
    assert cm.diag.shape == (7, 5, 6) and cm.n_unreachable == 0
    model = KinematicModel(robot)
    for i, j in ((0, 0), (3, 2), (6, 4)):
        C = model.C(cm.q[i, j])
        assert np.allclose(cm.diag[i, j], np.diag(C), rtol=1e-12, atol=0)
        T = model.tcp(cm.q[i, j])                               # the configuration hits the target
        assert np.allclose(T[:3, 3], [0.3, cm.u_m[i], cm.v_m[j]], atol=1e-9)


def test_map_fixed_branch_and_home_rule():
    robot = load_robot("ar5")
    fixed = compliance_map(robot, points=5, branch="s+w+e+")
    assert set(np.unique(fixed.branch)) == {BRANCH_LABELS.index("s+w+e+")}
    home = compliance_map(robot, points=5)
    assert (home.branch >= 0).all()


def test_map_marks_unreachable_points(tmp_path):
    robot = load_robot("ar5")
    cm = compliance_map(robot, plane="z", offset_m=0.2, u_range_m=(-1.2, 1.2),
                        v_range_m=(-1.2, 1.2), points=9, rpy_rad=(math.pi, 0.0, 0.0))
    assert 0 < cm.n_unreachable < cm.n_points
    assert np.isnan(cm.diag[cm.branch < 0]).all()
    assert np.isfinite(cm.diag[cm.branch >= 0]).all()
    assert sum(cm.unreachable_reasons.values()) == cm.n_unreachable


@pytest.mark.parametrize("kwargs, match", [
    ({"plane": "w"}, "plane = 'w'"),
    ({"u_range_m": (0.3, -0.3)}, "u range"),
    ({"v_range_m": (-300.0, 300.0)}, "millimetres"),
    ({"points": 1}, "points"),
    ({"branch": "s+"}, "branch = 's\\+'"),
    ({"rpy_rad": (0.0, 1.0)}, "rpy"),
])
def test_map_bad_input_names_the_key(kwargs, match):
    with pytest.raises(CompplanError, match=match):
        compliance_map(load_robot("ar5"), **kwargs)


# ------------------------------------------------------------------------------------- CLI
def test_cli_report_and_map(demo_run, tmp_path, capsys):
    folder = tmp_path / "run"
    shutil.copytree(demo_run, folder)
    assert main(["report", str(folder), "--no-map", "--jobs", "1"]) == 0
    assert (folder / "report.html").is_file()
    assert "no trajectory" not in capsys.readouterr().err
    assert main(["map", "--out", str(tmp_path / "map"), "--points", "7", "--rpy-deg", "-90", "0",
                 "90", "--branch", "s+w-e+"]) == 0
    out = capsys.readouterr().out
    assert "C11" in out and "mm/N" in out
    assert (tmp_path / "map" / "figures" / "fig1_compliance_map.png").is_file()
    meta = json.loads((tmp_path / "map" / "compliance_map.json").read_text())
    assert meta["rpy_rad"] == pytest.approx([-math.pi / 2, 0.0, math.pi / 2])
    assert main(["report", str(tmp_path / "missing")]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert main(["map", "--out", str(tmp_path / "m2"), "--branch", "xyz"]) == 2
