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
from planner.output import TRAJECTORY_COLUMNS, csv_bytes
from planner.numbers import (
    DISPLAY_DIGITS,
    NUMERICAL_FLOOR_MM,
    NUMERICAL_ZERO_TEXT,
    format_value,
    is_error_key,
    round_sig,
)
from planner.report import (
    FIGURE_NAMES,
    build_figures,
    lookup,
    render_html,
    render_markdown,
    summary_tables,
    write_report,
)
from planner.plan_record import record_from_plan as run_from_plan
from planner.record import read_record as load_run

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
#: A number shown with DISPLAY_DIGITS significant digits is within this of its value (relative).
DISPLAY_REL = 0.5 * 10.0 ** (1 - DISPLAY_DIGITS)
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
            self._cell = {
                "key": a["data-key"],
                "value": json.loads(a["data-value"]),
                "agg": a.get("data-agg"),
                "text": "",
            }
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


def _shown_matches(text: str, value: float | int, key: str) -> None:
    """A displayed number is the value rounded to DISPLAY_DIGITS significant digits (an integer
    in full), or, for a TCP error below the numerical floor, "0 (numerical)"."""
    expected = float(value)
    if text == NUMERICAL_ZERO_TEXT:
        assert is_error_key(key), f"{key}: only TCP errors are shown as numerically zero"
        floor = NUMERICAL_FLOOR_MM if key.endswith("_mm") else NUMERICAL_FLOOR_MM * 1e-3
        assert abs(expected) < floor, (key, expected)
        return
    assert float(text) == pytest.approx(expected, rel=DISPLAY_REL, abs=0), (key, text, expected)
    if isinstance(value, float) and expected != 0.0:  # rounded to what it means, not more
        digits = len(text.split("e")[0].replace("-", "").replace(".", "").lstrip("0"))
        assert digits <= DISPLAY_DIGITS, (key, text)


def check_cells_match_summary(folder: Path) -> _ReportParser:
    """Every value cell of the HTML tables equals its summary.json entry (data-value, full
    precision) and shows it rounded to what it means (text)."""
    summary = json.loads((folder / "summary.json").read_text())
    rep = parse(folder)
    assert rep.cells, "no machine-checkable cells in report.html"
    for c in rep.cells:
        expected = lookup(summary, c["key"])  # KeyError: cell names a key not in summary
        if c["agg"] == "max":
            expected = max(x for x in _flat(expected) if x is not None)
        assert c["value"] == expected, c
        text = c["text"].strip()
        if isinstance(expected, str):
            assert text == expected
        elif isinstance(expected, list):
            for t, e in zip(text.strip("[]").split(","), expected, strict=True):
                _shown_matches(t.strip(), e, c["key"])
        elif expected is None:
            assert text == "n/a"
        elif isinstance(expected, bool):
            assert text == str(expected).lower()
        else:
            _shown_matches(text, expected, c["key"])
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
@pytest.fixture
def demo_result(paper_result):
    """The plan of the demo (paper section 4.4 on ar5), in memory (once per session: conftest.py)."""
    return paper_result


@pytest.fixture
def demo_run(paper_folder) -> Path:
    """A demo output folder (paper section 4.4 on ar5), without report.  Shared: copy to change."""
    return paper_folder


@pytest.fixture
def demo_report(paper_report) -> Path:
    """The demo's files and report, the report built from the result (as compplan demo).  Shared."""
    return paper_report


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
    rows = np.column_stack(
        [
            t,
            q0 + np.outer(10 * x**3 - 15 * x**4 + 6 * x**5, d),
            np.outer((30 * x**2 - 60 * x**3 + 30 * x**4) / T, d),
            np.outer((60 * x - 180 * x**2 + 120 * x**3) / T**2, d),
            np.outer((60 - 360 * x + 360 * x**2) / T**3, d),
        ]
    )
    (dst / "trajectory.csv").write_bytes(csv_bytes(TRAJECTORY_COLUMNS, rows))  # default: Ruckig
    s["duration_s"] = T
    s["limit_ratio"] = {"velocity": [0.4] * 6, "acceleration": [0.7] * 6, "jerk": [0.1, 0.2, 0.99, 0.3, 0.0, 0.5]}
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
    for k in (
        "robot",
        "wrench.F_N",
        "wrench.M_Nm",
        "error_before.max_mm",
        "error_before.rms_mm",
        "error_after.closed_form.max_mm",
        "error_after.closed_form.rms_mm",
        "error_after.exact.max_mm",
        "error_after.exact.rms_mm",
    ):
        assert k in keys, f"table lacks {k}"
    assert {"branch", "chosen_branch"} & keys
    summary = json.loads((demo_report / "summary.json").read_text())
    for m in summary.get("duration_s", {}):  # a timed run: durations and ratios
        assert f"duration_s.{m}" in keys
        for kind in ("velocity", "acceleration", "jerk"):
            assert f"limit_ratio.{m}.{kind}" in keys


def test_markdown_table_has_the_same_numbers(demo_report):
    md = (demo_report / "report.md").read_text()
    s = json.loads((demo_report / "summary.json").read_text())
    row = next(line for line in md.splitlines() if line.startswith("| before compensation"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert float(cells[1]) == pytest.approx(s["error_before"]["max_mm"], rel=DISPLAY_REL)
    assert float(cells[2]) == pytest.approx(s["error_before"]["rms_mm"], rel=DISPLAY_REL)
    row = next(line for line in md.splitlines() if line.startswith("| after exact compensation"))
    assert [c.strip() for c in row.strip("|").split("|")][1:] == [NUMERICAL_ZERO_TEXT] * 2


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
    import planner.record.read as run_module

    def no_reading(*args, **kwargs):
        raise AssertionError("the view of a plan result read a file")

    with monkeypatch.context() as m:  # from the result: no file is read
        for name in ("read_csv", "read_run_summary", "read_trajectory"):
            m.setattr(run_module, name, no_reading)
        mem = run_from_plan(demo_result, demo_run)
    disk = load_run(demo_run)

    assert mem.summary == disk.summary == json.loads((demo_run / "summary.json").read_text())
    assert mem.folder == disk.folder and mem.absent == disk.absent == {}
    assert mem.trajectory_files == disk.trajectory_files and list(mem.trajectories) == ["toppra", "jerk_optimal"]
    for piece in ("waypoints", "branches", "trajectories"):
        assert _same(getattr(mem, piece), getattr(disk, piece)), piece
    assert mem.robot.to_dict() == disk.robot.to_dict()
    assert mem.model is demo_result.problem.model  # the plan's model (its kinematics built once)
    assert np.array_equal(mem.model.theta, disk.model.theta)
    assert mem.model.nominal.to_dict() == disk.model.nominal.to_dict()

    t_mem, t_disk = summary_tables(mem.summary, mem.absent), summary_tables(disk.summary, disk.absent)
    assert [t.html() for t in t_mem] == [t.html() for t in t_disk]
    assert [t.markdown() for t in t_mem] == [t.markdown() for t in t_disk]
    f_mem, f_disk = build_figures(mem, map_options=False), build_figures(disk, map_options=False)
    assert [(f.name, f.title, f.caption, f.absent) for f in f_mem] == [
        (f.name, f.title, f.caption, f.absent) for f in f_disk
    ]
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
        method = {"TOPP-RA": "toppra", "Ruckig": "ruckig", "jerk-optimal": "jerk_optimal"}[pretty]
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
    rows[0][-1] = "qddd1"  # part of the jerk columns: malformed
    p.write_text("\n".join(",".join(r) for r in rows) + "\n")
    with pytest.raises(InputError, match="qddd2"):
        write_report(folder, map_options=False, workers=1)


# ------------------------------------------------------------------- runs with and without timing
def test_run_without_trajectory_says_so(demo_run, tmp_path):
    folder = strip_timing(demo_run, tmp_path / "untimed")
    calls: list[tuple[str, int, int]] = []
    write_report(folder, progress=lambda *a: calls.append(a), map_options=SMALL_MAP, workers=1)
    assert {c[0] for c in calls} == {"compliance map", "figures"}  # progress reaches the end
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
    assert "TOPP-RA" in (folder / "report.md").read_text()  # stated as absent in the caption


def test_serial_and_parallel_rendering_give_the_same_files(demo_run, tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    shutil.copytree(demo_run, a)
    shutil.copytree(demo_run, b)
    write_report(a, map_options=SMALL_MAP, workers=1, map_cache=False)
    write_report(b, map_options=SMALL_MAP, workers=2, map_cache=False)
    for name in FIGURE_NAMES:  # the demo run has every figure: none may be missing
        for ext in ("png", "pdf"):
            fa, fb = a / "figures" / f"{name}.{ext}", b / "figures" / f"{name}.{ext}"
            assert fa.is_file() and fb.is_file(), f"{name}.{ext} not drawn"
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
    for name in ("figures/fig1_compliance_map.png", "figures/fig1_compliance_map.pdf", "compliance_map.csv"):
        assert (a / name).read_bytes() == (b / name).read_bytes()
    check_cells_match_summary(b)
    with pytest.raises(AssertionError, match="computed again"):  # other options: a new map
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
    assert not (folder / "report.html").exists()  # all or nothing


# ------------------------------------------------------------------------------ compliance map
def test_map_diagonal_equals_model_compliance_at_grid_points():
    robot = load_robot("ar5")
    cm = compliance_map(robot, points=(7, 5))
    assert cm.diag.shape == (7, 5, 6) and cm.n_unreachable == 0
    model = KinematicModel(robot)
    for i, j in ((0, 0), (3, 2), (6, 4)):
        C = model.C(cm.q[i, j])
        assert np.allclose(cm.diag[i, j], np.diag(C), rtol=1e-12, atol=0)
        T = model.tcp(cm.q[i, j])  # the configuration hits the target
        assert np.allclose(T[:3, 3], [0.3, cm.u_m[i], cm.v_m[j]], atol=1e-9)


def test_map_fixed_branch_and_home_rule():
    robot = load_robot("ar5")
    fixed = compliance_map(robot, points=5, branch="s+w+e+")
    assert set(np.unique(fixed.branch)) == {BRANCH_LABELS.index("s+w+e+")}
    home = compliance_map(robot, points=5)
    assert (home.branch >= 0).all()


def test_map_marks_unreachable_points(tmp_path):
    robot = load_robot("ar5")
    cm = compliance_map(
        robot,
        plane="z",
        offset_m=0.2,
        u_range_m=(-1.2, 1.2),
        v_range_m=(-1.2, 1.2),
        points=9,
        rpy_rad=(math.pi, 0.0, 0.0),
    )
    assert 0 < cm.n_unreachable < cm.n_points
    assert np.isnan(cm.diag[cm.branch < 0]).all()
    assert np.isfinite(cm.diag[cm.branch >= 0]).all()
    assert sum(cm.unreachable_reasons.values()) == cm.n_unreachable


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"plane": "w"}, "plane = 'w'"),
        ({"u_range_m": (0.3, -0.3)}, "u range"),
        ({"v_range_m": (-300.0, 300.0)}, "millimetres"),
        ({"points": 1}, "points"),
        ({"branch": "s+"}, "branch = 's\\+'"),
        ({"rpy_rad": (0.0, 1.0)}, "rpy"),
    ],
)
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
    assert (
        main(
            [
                "map",
                "--out",
                str(tmp_path / "map"),
                "--points",
                "7",
                "--rpy-deg",
                "-90",
                "0",
                "90",
                "--branch",
                "s+w-e+",
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "C11" in out and "mm/N" in out
    assert (tmp_path / "map" / "figures" / "fig1_compliance_map.png").is_file()
    meta = json.loads((tmp_path / "map" / "compliance_map.json").read_text())
    assert meta["rpy_rad"] == pytest.approx([-math.pi / 2, 0.0, math.pi / 2])
    assert main(["report", str(tmp_path / "missing")]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert main(["map", "--out", str(tmp_path / "m2"), "--branch", "xyz"]) == 2


# -------------------------------------------------- headline, provenance, figures (issue 9)
def _sha256(path: Path) -> str:
    import hashlib

    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def test_summary_opens_with_the_headline_in_units_and_rounded(demo_run):
    s = json.loads((demo_run / "summary.json").read_text())
    assert list(s)[:2] == ["headline", "provenance"]
    h = s["headline"]
    assert h["status"] == s["plan_status"] == "ok"
    assert h["branch"] == s["chosen_branch"] == "s-w-e-"
    assert "shoulder −" in h["branch_meaning"] and "elbow −" in h["branch_meaning"]
    assert h["branch_posture"] == s["branches"]["s-w-e-"]["posture"]
    for tag, full in (
        ("error_before", s["error_before"]),
        ("error_after", s["error_after"]["exact"]),
        ("error_after_closed_form", s["error_after"]["closed_form"]),
    ):
        for k in ("max", "rms"):
            key, v = f"{tag}_{k}_mm", full[f"{k}_mm"]
            assert h[key] == (0.0 if abs(v) < NUMERICAL_FLOOR_MM else round_sig(v)), key
    assert h["error_before_max_mm"] == 1.779 and h["error_after_max_mm"] == 0.0
    assert h["numerical_floor_mm"] == NUMERICAL_FLOOR_MM == 1e-6
    assert set(h["below_numerical_floor"]) == {"error_after_max_mm", "error_after_rms_mm"}
    assert h["duration_method"] == s["controller_trajectory"] == "jerk_optimal"
    assert h["duration_s"] == round_sig(s["duration_s"]["jerk_optimal"])
    # the time-optimal reference is the registry's (TOPP-RA), named in the headline
    assert h["duration_time_optimal_method"] == "toppra"
    assert h["duration_time_optimal_s"] == round_sig(s["duration_s"]["toppra"])
    # units in every numeric key of the headline
    for k, v in h.items():
        if isinstance(v, float) and k != "gain_vs_default":
            assert k.endswith(("_mm", "_s")), k
    assert "first order" in h["definition"]  # the two "before" errors explained


def test_branch_entries_say_what_the_branch_is_and_both_errors(demo_result, demo_run):
    s = json.loads((demo_run / "summary.json").read_text())
    for e in s["branches"].values():
        assert e["meaning"].startswith("shoulder") and e["status_meaning"].startswith("fixed orientation")
        assert "elbow up" in e["posture"] or "elbow down" in e["posture"]
        assert e["rms_error_equilibrium_mm"] > 0 and e["rms_error_mm"] > 0
    chosen = s["branches"]["s-w-e-"]
    # the exact-equilibrium branch error is the error table's "before"; the NLP's is first order
    assert chosen["rms_error_equilibrium_mm"] == pytest.approx(s["error_before"]["rms_mm"], rel=1e-12)
    assert chosen["rms_error_mm"] != pytest.approx(chosen["rms_error_equilibrium_mm"], rel=1e-6)
    # the UR home pose (the demo's default branch) is elbow up
    assert "elbow up" in s["branches"][s["default_branch"]]["posture"]


def test_provenance_names_version_date_and_hashed_inputs(demo_run):
    from datetime import datetime

    from planner.provenance import version

    p = json.loads((demo_run / "summary.json").read_text())["provenance"]
    assert p["compplan_version"] == version() != "unknown"
    assert p["command_line"] is None and p["argv"] is None  # a library call, not a command
    when = datetime.fromisoformat(p["date_utc"].replace("Z", "+00:00"))
    assert p["date_utc"].endswith("Z") and when.utcoffset().total_seconds() == 0
    roles = {e["role"]: e for e in p["inputs"]}
    assert roles["problem"]["name"] == "paper_4_4" and roles["robot model"]["name"] == "ar5"
    for e in p["inputs"]:
        assert Path(e["path"]).is_file() and e["sha256"] == _sha256(e["path"])


def test_report_opens_with_the_headline_and_closes_the_summary_with_provenance(demo_report):
    text = (demo_report / "report.html").read_text()
    first_table = text.index("<table")
    assert 'class="summary headline"' in text[first_table : first_table + 60]
    assert (
        text.index('id="headline"')
        < text.index("Run details")
        < text.index('id="provenance"')
        < text.index("<h2>Figures</h2>")
    )
    rep = check_cells_match_summary(demo_report)
    head = [c for c in rep.cells if c["key"].startswith("headline.")]
    assert [c["key"] for c in head][:3] == ["headline.status", "headline.branch", "headline.error_before_max_mm"]
    shown = {c["key"]: c["text"].strip() for c in head}
    assert shown["headline.error_before_max_mm"] == "1.779"
    assert shown["headline.error_after_max_mm"] == NUMERICAL_ZERO_TEXT
    assert shown["headline.duration_s"] == "1.584"
    keys = {c["key"] for c in rep.cells}
    assert {
        "provenance.compplan_version",
        "provenance.date_utc",
        "provenance.inputs.0.sha256",
        "provenance.inputs.1.sha256",
    } <= keys
    assert not [c for c in rep.cells if "e-1" in c["text"]]  # no rounding residue shown
    assert "fixed orientation: the IK solution, nothing to optimise" in text
    assert "shoulder left/right" in text  # the branch labels decoded
    md = (demo_report / "report.md").read_text()
    assert md.index("### Headline") < md.index("## Run details") < md.index("### Provenance")


def test_numbers_are_shown_rounded_to_what_they_mean():
    assert format_value(5.551115123125783e-14, "error_after.exact.max_mm") == NUMERICAL_ZERO_TEXT
    assert format_value(8.8e-15, "exact_residual_max_m") == NUMERICAL_ZERO_TEXT
    assert format_value(1.779017464983031, "error_before.max_mm") == "1.779"
    assert format_value(6.251752085921565e-05, "branches.s-w-e-.cost") == "6.252e-5"
    assert format_value(5.5e-14, "cost") == "5.5e-14"  # only errors have the floor
    assert format_value([5.0, 10.0, 20.0], "wrench.F_N") == "[5, 10, 20]"
    assert round_sig(0.025092427957477882) == 0.02509 and round_sig(2.36) == 2.36


def test_path_figures_are_drawn_against_the_path_length(demo_run):
    run = load_run(demo_run)
    items = {it.name: it for it in build_figures(run, map_options=False)}
    P = np.column_stack([run.waypoints[a] for a in "xyz"])
    s_mm = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))] * 1e3
    for name in ("fig2_stiffness_error", "fig3_compensation_angles", "fig4_error_before_after"):
        fn, args, _ = items[name].job
        assert np.array_equal(args[0], s_mm), name
    assert s_mm[-1] == pytest.approx(np.linalg.norm(P[-1] - P[0]) * 1e3)  # a line: its length
    # figure 5: a bar per IK branch (infeasible ones marked) plus the chosen and default curves
    fn, args, kw = items["fig5_branches"].job
    labels, r_ana, r_opt, infeasible, x, curves, chosen, default = args
    assert fn.__name__ == "branch_figure" and list(labels) == list(BRANCH_LABELS)
    s = run.summary
    assert set(infeasible) == set(s["rejected_branches"]) and chosen == "s-w-e-" and default == "s-w-e+"
    for lab, v in zip(labels, r_opt):
        if lab in s["branches"]:
            assert v == pytest.approx(s["branches"][lab]["rms_error_equilibrium_mm"], rel=1e-9)
        else:
            assert math.isnan(v)
    assert any("(chosen)" in k for k in curves) and any("(default)" in k for k in curves)
    assert all("optimised" not in k for k in curves)  # no_freedom: the IK solution
    # figure 3: exact and closed form, and their difference drawn per joint
    fn, args, _ = items["fig3_compensation_angles"].job
    assert args[2] is not None and "exact − closed form" in items["fig3_compensation_angles"].caption


def test_compliance_map_is_drawn_on_the_plane_of_the_path(demo_run, tmp_path, monkeypatch):
    import planner.report.maps as maps

    monkeypatch.setattr(maps, "_map_cache_dir", lambda key: tmp_path / "cache" / key)
    run = load_run(demo_run)
    files: dict[str, bytes] = {}
    item = maps.map_item(run, None, None, files, map_cache=False)
    fn, args, kw = item.job
    P = np.column_stack([run.waypoints[a] for a in "xyz"])
    plane = maps.path_plane(P)
    assert plane.off_plane_m < 1e-12  # the line lies in its plane
    assert np.allclose(plane.origin + plane.uv(P) @ np.stack([plane.e_u, plane.e_v]), P, atol=1e-12)
    assert np.allclose(kw["path_uv_m"], plane.uv(P), atol=1e-12)
    assert abs(plane.normal[2]) < 1e-12 and plane.e_v[2] > 0  # a line: the vertical plane through it
    assert "plane of this run's path" in item.caption and "outside its reach" in item.caption
    header = files["compliance_map.csv"].decode().splitlines()[0].split(",")
    assert header[:6] == ["u_m", "v_m", "x_m", "y_m", "z_m", "branch"]
    rows = np.loadtxt(files["compliance_map.csv"].decode().splitlines()[1:], delimiter=",")
    n_bad = int(np.sum(rows[:, 5] < 0))
    assert f"{n_bad} of {len(rows)} points are outside its reach" in item.caption
    assert np.allclose((rows[:, 2:5] - plane.origin) @ plane.normal, 0.0, atol=1e-12)
    # a planar path whose plane is a base plane keeps the base axes' names
    ur10 = maps.path_plane(np.array([[0.7, -0.3, 0.3], [0.7, 0.0, 0.35], [0.7, 0.3, 0.3]]))
    assert (ur10.u_label, ur10.v_label, ur10.description) == ("y", "z", "x = 0.7 m")


def test_payload_and_tool_frame_loads_are_named_not_a_zero_base_force(demo_run, tmp_path):
    from planner.report.tables import load_words

    folder = tmp_path / "payload"
    shutil.copytree(demo_run, folder)
    s = json.loads((folder / "summary.json").read_text())
    s["wrench"].update({"F_N": [0.0, 0.0, 0.0], "M_Nm": [0.0, 0.0, 0.0]})
    s["payload"] = {"mass_kg": 5.0, "com_m_tcp_frame": [0.0, 0.05, 0.08], "gravity_m_s2": [0, 0, -9.80665]}
    (folder / "summary.json").write_text(json.dumps(s))
    assert load_words(s) == "payload 5 kg (centre of mass [0, 0.05, 0.08] m, TCP frame)"
    run = load_run(folder)
    items = build_figures(run, map_options=False)
    for it in items[1:]:
        title = it.job[2].get("title", "")
        assert "F = [0, 0, 0]" not in title and "F = [0, 0, 0]" not in it.caption, it.name
        if it.name != "fig6_trajectory":  # the joint trajectories name no load
            assert "payload 5 kg" in title, it.name
    tool = {**s, "payload": None, "wrench": {**s["wrench"], "frame": "tool", "F_N": [0.0, 0.0, -40.0]}}
    assert load_words(tool).startswith("tool-frame wrench (turns with the tool) F = [0, 0, -40] N")
    write_report(folder, map_options=False, workers=1)
    html_text = (folder / "report.html").read_text()
    assert "F = [0, 0, 0]" not in html_text and "process wrench</td><td>none (the payload is the load)" in html_text


def test_arm_figure_draws_the_deflection_the_plan_computed(demo_run):
    """Figure 7 deflects q_target by q_target - q_command (whatever the load's kind), the arm as
    links between joint centres at the start, middle and end."""
    run = load_run(demo_run)
    fn, args, kw = build_figures(run, map_options=False)[6].job
    nominal, deflected, path, labels, factor = args
    assert fn.__name__ == "arm_figure" and labels == ["k = 0", "k = 20", "k = 39"]
    from planner.report.figures import _polylines

    model = KinematicModel(run.robot)
    qt = np.column_stack([run.waypoints[f"qt{i}"] for i in range(1, 7)])[[0, 20, 39]]
    qc = np.column_stack([run.waypoints[f"qc{i}"] for i in range(1, 7)])[[0, 20, 39]]
    expect, joints = _polylines(model, qt + factor * (qt - qc))
    assert np.allclose(deflected, expect) and kw["joint_index"] == joints
    assert np.allclose(nominal[:, -1], path[[0, 20, 39]], atol=1e-9)  # the TCP on the path


def test_version_and_robot_show(capsys, tmp_path):
    from planner.provenance import builtin_robot_file, version

    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0 and capsys.readouterr().out.strip() == f"compplan {version()}"
    assert main(["robot", "show", "ur5"]) == 0
    text = capsys.readouterr().out
    assert text == builtin_robot_file("ur5").read_text()
    (tmp_path / "my_ur5.toml").write_text(text)
    assert load_robot(str(tmp_path / "my_ur5.toml")).to_dict() == load_robot("ur5").to_dict()
    assert main(["robot", "list"]) == 0
    names = [ln.split()[0] for ln in capsys.readouterr().out.splitlines() if ln and not ln[0].isspace()]
    assert names == ["ar5", "ur5", "ur10", "ur5e", "kr6_r900"]  # descriptions wrap on indented lines
    assert main(["robot", "show", "ur7"]) == 2
    assert "not a built-in robot" in capsys.readouterr().err


def test_command_outputs_record_their_command_line(tmp_path, capsys):
    out = tmp_path / "map"
    argv = ["map", "--out", str(out), "--points", "5"]
    assert main(argv) == 0
    p = json.loads((out / "compliance_map.json").read_text())["provenance"]
    assert p["argv"] == ["compplan", *argv] and p["command_line"].startswith("compplan map --out ")
    assert p["inputs"][0]["name"] == "ar5" and p["inputs"][0]["sha256"] == _sha256(p["inputs"][0]["path"])


def test_examples_in_the_docs_exist_and_run(tmp_path, capsys):
    root = Path(__file__).resolve().parents[1]
    cli_doc = (root / "docs" / "cli.md").read_text() + (root / "README.md").read_text()
    for name in ("docs/examples/commands.csv", "docs/examples/my_task.toml"):
        assert name in cli_doc and (root / name).is_file(), name
    assert (
        main(
            [
                "predict",
                "--model",
                "ur5",
                "--input",
                str(root / "docs/examples/commands.csv"),
                "--out",
                str(tmp_path / "p.csv"),
            ]
        )
        == 0
    )
    assert (
        main(
            [
                "compensate",
                "--model",
                "ur5",
                "--input",
                str(root / "docs/examples/commands.csv"),
                "--out",
                str(tmp_path / "c.csv"),
            ]
        )
        == 0
    )
    from problems.problem import load_problem

    assert load_problem(root / "docs/examples/my_task.toml").n == 40


def test_robot_file_doc_example_is_a_complete_loadable_file(tmp_path):
    root = Path(__file__).resolve().parents[1]
    text = (root / "docs" / "robot-file.md").read_text()
    block = text.split("## Example")[1].split("```toml\n")[1].split("```")[0]
    f = tmp_path / "my_ur5.toml"
    f.write_text(block)
    robot = load_robot(str(f))
    assert robot.name == "my_ur5" and len(robot.d) == 6
    assert np.allclose(robot.a, load_robot("ur5").a) and np.allclose(robot.d, load_robot("ur5").d)
    from models import AnalyticIK

    AnalyticIK(robot)  # UR-type: plan, pose and demo accept it


def test_identification_report_is_styled_and_explains_itself(tmp_path):
    """The identify report: headline first, provenance, per-axis residual figure, units on the axes,
    and the compensation sentence that says what unregistered data cannot check."""
    from planner.identify_report import VARIABLE_UNITS, compensation_sentence, write_report as write_identify
    from problems.identify import compensation_check, identify
    from problems.virtual import VirtualRobot

    cfg = {
        "campaign": {"poses": 40},
        "noise": {"sigma_m": 2e-5},
        "registration": {"registered": False},
        "effects": {"gravity": {}},
    }
    vr = VirtualRobot(load_robot("ur5"), cfg, seed=4)
    data = vr.campaign()
    res = identify(load_robot("ur5"), data, candidates=[])
    res.compensation_check = compensation_check(vr, res.model, n_poses=12)
    csv_file = tmp_path / "data.csv"
    csv_file.write_text("q1\n")  # a stand-in file to hash
    rep = write_identify(res, tmp_path / "rep", model_path=str(tmp_path / "m.toml"), data_path=str(csv_file))
    assert list(rep)[:2] == ["headline", "provenance"]
    h = rep["headline"]
    assert h["rms_before_mm"] == round_sig(rep["rms_before_mm"]) and h["registered"] is False
    assert h["compensation"] == compensation_sentence(rep)
    if rep["base_frame_aliases"]:
        assert " mm RMS in the measurement frame " in h["compensation"].split(";")[0]  # the figure to read first
        assert "aliased parameters held at nominal" in h["compensation"] or "in the base frame" in h["compensation"]
    roles = {e["role"]: e for e in rep["provenance"]["inputs"]}
    assert roles["measurements"]["sha256"] == _sha256(csv_file) and roles["declared robot"]["name"] == "ur5"
    assert roles["declared robot"]["sha256"] == _sha256(roles["declared robot"]["path"])
    html_text = (tmp_path / "rep" / "report.html").read_text()
    assert html_text.index('class="summary headline"') < html_text.index("<h2>Figures</h2>")
    for key in ("residuals", "history", "compensation"):
        assert f'data-figure="{key}"' in html_text
    assert "meas_frame_" not in (tmp_path / "rep" / "report.md").read_text()  # no raw keys in prose
    assert set(VARIABLE_UNITS) >= {"q1", "q6", "load_magnitude", "pose", "time", "position"}


def test_an_unknown_map_branch_is_the_users_error(paper_folder, tmp_path, capsys):
    """Issue 24: ``report --map-branch banana`` exits 2 naming the labels, as docs/cli.md says (it
    wrote a report with the map left out, exit 0)."""
    import shutil

    from planner.cli import main

    folder = tmp_path / "run"
    shutil.copytree(paper_folder, folder)
    before = sorted(p.name for p in folder.rglob("*"))
    capsys.readouterr()
    assert main(["report", str(folder), "--map-branch", "banana"]) == 2
    err = capsys.readouterr().err
    assert "branch = 'banana'" in err and "s+w+e+" in err and "Traceback" not in err
    assert sorted(p.name for p in folder.rglob("*")) == before
