"""The report of a run whose load is predicted from the cut (planner/report/cut_plot.py,
cut_draw.py, cut_tables.py): the cut figures and table exist for a cut run and not for a run
without ``cut``; ``compplan report DIR`` on the written folder gives the same figures (the record
read back from the files equals the one in memory); the figures draw the run's numbers (checked
against closed forms computed here from cut.csv and cut_stock.npz); a tampered cut.csv is refused
with one line naming the file, the line and the column."""

from __future__ import annotations

import contextlib
import io
import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from planner.cli import main
from planner.record import read_record
from planner.record.columns import CUT_COLUMNS
from planner.report import write_report
from planner.report.cut_draw import Band, Series
from planner.report.cut_plot import CUT_FIGURES, MAX_ARROWS, SERIES_BINS, cut_items
from planner.report.cut_tables import cut_tables
from planner.report.figure_cache import FIGURE_CACHE_ENV
from planner.report.figures import build_figures

#: Relative agreement of two RMS/max values computed from the same CSV numbers (summation order).
SAME_NUMBER_REL = 1e-9
#: Removed volume from the stored stock images against the simulation's (the images are a coarser
#: grid than the simulation, in float32).
VOLUME_REL = 0.03
#: The stored stock images are float32 (m): their rounding, m.
FLOAT32_M = 1e-8

PROGRAM = """%
G21 G90 G17 G94 G54
G64 P0.01
T1 M6
S10000 M3
G0 X-20. Y0.
G0 Z5.
G1 Z-2. F300.
G1 X20. F800.
G1 Y10.
G0 Z5.
G0 X-20. Y14.
G1 Z-2. F300.
G1 X20. Y14. F800.
G0 Z5.
M5
M30
%
"""

PROBLEM = """name = "slot_test"
description = "a slot and a side pass"
[robot]
model = "ur10"
[robot.tool]
xyz = [0.08, 0.0, 0.12]
rpy_deg = [0.0, 0.0, 0.0]
[robot.tool.cutter]
shape = "flat"
diameter = 0.008
flutes = 3
helix_deg = 30.0
flute_length = 0.026
length = 0.035
[path]
kind = "gcode"
file = "slot.ngc"
[workpiece]
xyz = [0.65, 0.0, 0.10]
[orientation]
rule = "free_tool_axis"
[material]
name = "al7075_t6"
[stock]
box_min = [-0.03, -0.01, -0.02]
box_max = [0.03, 0.03, 0.0]
[cut]
stand_in = { frame = "tool", force = [40.0, 25.0, 30.0] }
[limits]
max_joint_step = 0.3
"""


# ------------------------------------------------------------------------------------ helpers
def _cli(argv: list[str]) -> tuple[int, str]:
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        code = main(argv)
    return code, err.getvalue()


def _figure_ids(folder: Path) -> list[str]:
    return re.findall(r'<h3 id="(fig\d+_[a-z0-9_]+)"', (folder / "report.html").read_text(encoding="utf-8"))


def _embedded(folder: Path) -> set[str]:
    return set(re.findall(r'data-figure="(fig\d+_[a-z0-9_]+)"', (folder / "report.html").read_text(encoding="utf-8")))


def _item(items, name):
    return next(it for it in items if it.name == name)


@pytest.fixture(scope="module")
def figure_cache(tmp_path_factory):
    """The module's own figure cache (as the other report tests: never the user's)."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv(FIGURE_CACHE_ENV, str(tmp_path_factory.mktemp("figure-cache")))
        yield


@pytest.fixture(scope="module")
def slot_run(tmp_path_factory, figure_cache):
    """The slot problem planned, its files written and its report built from the plan in memory."""
    from planner.plan import plan, write_outputs
    from problems.problem import load_problem

    folder = tmp_path_factory.mktemp("slot")
    (folder / "slot.ngc").write_text(PROGRAM)
    (folder / "slot.toml").write_text(PROBLEM)
    res = plan(load_problem(folder / "slot.toml")).raise_for_status()
    view = res.view()
    out = folder / "out"
    write_outputs(res, out, with_figures=False, view=view)
    record = res.record(out, view)
    write_report(out, record=record, map_options=False, workers=1)
    return record, out


@pytest.fixture
def copy_of(slot_run, tmp_path):
    """A private copy of the written run folder, without its report."""
    _, out = slot_run
    folder = tmp_path / "run"
    shutil.copytree(out, folder, ignore=shutil.ignore_patterns("report.*", "figures", "compliance_map.csv"))
    return folder


# ------------------------------------------------------------------------------ the figures
def test_a_cut_run_has_the_cut_figures_and_table(slot_run):
    _, out = slot_run
    ids = _figure_ids(out)
    assert [n for n in ids if n in CUT_FIGURES] == list(CUT_FIGURES)
    assert set(CUT_FIGURES) <= _embedded(out), "a cut figure is not drawn"
    for name in CUT_FIGURES:
        assert (out / "figures" / f"{name}.png").read_bytes().startswith(b"\x89PNG")
        assert (out / "figures" / f"{name}.pdf").read_bytes().startswith(b"%PDF")
        assert f"figures/{name}.png" in (out / "report.md").read_text(encoding="utf-8")
    numbers = [int(re.match(r"fig(\d+)_", n).group(1)) for n in ids]
    assert numbers == sorted(numbers), f"figure numbers out of order: {ids}"
    html = (out / "report.html").read_text(encoding="utf-8")
    summary = json.loads((out / "summary.json").read_text())
    assert '<h3 id="cut">The cut</h3>' in html
    for key in ("cut.force_N.max", "cut.removed_mm3", "cut.error_mm.stand_in_compensated.rms", "cut.spindle_rpm.max"):
        cell = re.search(rf'data-key="{re.escape(key)}" data-value="([^"]+)"', html)
        assert cell is not None, f"{key} not in the cut table"
        node: object = summary
        for part in key.split("."):
            node = node[part]  # type: ignore[index]
        assert json.loads(cell.group(1)) == node


def test_a_run_without_cut_has_no_cut_figures_nor_table(copy_of):
    doc = json.loads((copy_of / "summary.json").read_text())
    del doc["cut"]
    (copy_of / "summary.json").write_text(json.dumps(doc))
    (copy_of / "cut.csv").unlink()
    (copy_of / "cut_stock.npz").unlink()
    run = read_record(copy_of)
    assert run.cut is None and run.cut_stock is None and "cut" not in run.absent
    assert cut_items(run) == [] and cut_tables(run.summary) == []
    names = [it.name for it in build_figures(run, map_options=False)]
    assert not set(names) & set(CUT_FIGURES) and "fig9_toolpath" in names


def test_an_absent_cut_file_is_stated_in_place_of_its_figures(copy_of):
    (copy_of / "cut.csv").unlink()
    items = cut_items(read_record(copy_of))
    assert [it.name for it in items] == list(CUT_FIGURES)
    by_name = {it.name: it for it in items}
    for name in CUT_FIGURES:
        if name == "fig14_cut_stock":  # drawn from cut_stock.npz, which is there
            assert by_name[name].job is not None and not by_name[name].absent
        else:
            assert by_name[name].job is None and "cut.csv absent" in by_name[name].absent


def test_compplan_report_on_the_folder_gives_the_same_figures(slot_run, copy_of):
    record, out = slot_run
    back = read_record(copy_of)
    for col in CUT_COLUMNS:
        assert np.array_equal(back.cut[col], record.cut[col], equal_nan=True), col
    for key in ("before", "after"):  # stored as float32
        assert back.cut_stock[key].shape == record.cut_stock[key].shape
        assert np.allclose(back.cut_stock[key], record.cut_stock[key], rtol=0, atol=FLOAT32_M, equal_nan=True)
    assert np.array_equal(back.cut_stock["extent"], record.cut_stock["extent"])
    code, err = _cli(["report", str(copy_of), "--no-map", "--jobs", "1"])
    assert code == 0, err
    assert _figure_ids(copy_of)[1:] == _figure_ids(out)[1:]  # (the compliance map is skipped here)
    assert _embedded(copy_of) >= set(CUT_FIGURES)
    assert sorted(p.name for p in (copy_of / "figures").glob("fig1[2-5]_*")) == sorted(
        p.name for p in (out / "figures").glob("fig1[2-5]_*")
    )


# ----------------------------------------------------------------------- what the figures draw
def test_the_force_figure_draws_the_csv_forces(slot_run):
    record, out = slot_run
    items = cut_items(read_record(out))
    s, magnitude, components, engagement = _item(items, "fig12_cut_force").job[1]
    assert isinstance(s, Series) and not s.reduced  # 83 waypoints: one a bin
    n = len(record.cut["line"])
    assert n < SERIES_BINS and len(s.x_mm) == n
    # path length along the program frame waypoints, mm (closed form here)
    p = record.program.points_m
    x = np.concatenate([[0.0], np.cumsum(np.sqrt(np.sum(np.diff(p, axis=0) ** 2, axis=1)))]) * 1e3
    assert np.allclose(s.x_mm, x, rtol=0, atol=1e-9)
    mean = next(b for b in magnitude if b.label.startswith("mean"))
    F = np.sqrt(record.cut["fx_N"] ** 2 + record.cut["fy_N"] ** 2 + record.cut["fz_N"] ** 2)
    assert np.allclose(mean.hi, F, rtol=1e-12, atol=1e-9) and np.array_equal(mean.lo, mean.hi)
    assert [b.label for b in components] == ["Fx", "Fy", "Fz"]
    assert np.array_equal(components[0].hi, record.cut["fx_N"])
    assert np.array_equal(engagement[0].hi, record.cut["axial_depth_mm"])
    # the air: the bins whose milling is "air" (index 0 of summary cut.milling_codes) or a rapid
    summary = json.loads((out / "summary.json").read_text())
    air = (record.cut["milling"] == summary["cut"]["milling_codes"].index("air")) | record.program.rapid
    assert np.array_equal(s.air, air)
    assert not np.any(F[air] > 0), "force drawn on the air"
    # the max mark: the largest |F| at its line, as the summary says
    x_max, f_max, label = _item(items, "fig12_cut_force").job[2]["max_mark"]
    assert f_max == pytest.approx(summary["cut"]["force_N"]["max"], rel=SAME_NUMBER_REL)
    assert f"line {summary['cut']['force_N']['max_line']}" in label


def test_a_long_program_is_drawn_in_bins_that_keep_the_extremes(slot_run):
    """The series reduction (bins of consecutive waypoints, their min and max) on a record made long:
    the slot's cut repeated; the global extremes survive and the bins are at most SERIES_BINS."""
    import dataclasses

    record, _ = slot_run
    reps = 3 * SERIES_BINS // len(record.cut["line"]) + 1
    long_cut = {c: np.tile(v, reps) for c, v in record.cut.items()}
    k = len(long_cut["force_N"]) // 2 + 7
    long_cut["fy_N"] = long_cut["fy_N"].copy()
    long_cut["fy_N"][k] = -1234.5  # one spike inside a bin
    prog = record.program
    shift = np.repeat(np.arange(reps), prog.n)[:, None] * np.array([[0.0, 0.04, 0.0]])  # passes side by side
    long_prog = dataclasses.replace(
        prog,
        points_m=np.tile(prog.points_m, (reps, 1)) + shift,
        line=np.tile(prog.line, reps),
        rapid=np.tile(prog.rapid, reps),
        feed_m_s=np.tile(prog.feed_m_s, reps),
    )
    long = dataclasses.replace(record, cut=long_cut, program=long_prog)
    items = cut_items(long)
    s, magnitude, components, _ = _item(items, "fig12_cut_force").job[1]
    assert s.reduced and len(s.x_mm) <= SERIES_BINS
    fy = components[1]
    assert isinstance(fy, Band) and np.nanmin(fy.lo) == -1234.5 and np.nanmax(fy.hi) == np.max(long_cut["fy_N"])
    assert np.nanmax(magnitude[0].hi) == np.max(long_cut["peak_force_N"])
    assert "bins" in _item(items, "fig12_cut_force").caption
    arrows = _item(items, "fig13_cut_toolpath").job[1][3]
    assert 0 < len(arrows) <= MAX_ARROWS


def test_the_toolpath_arrows_are_the_force_at_their_waypoints(slot_run):
    record, out = slot_run
    jb = _item(cut_items(read_record(out)), "fig13_cut_toolpath").job
    segs, force, rapid, arrows, key_N, mm_per_N = jb[1]
    xy = record.program.points_m[:, :2] * 1e3
    for x, y, fx, fy in arrows:
        at = np.flatnonzero(np.hypot(xy[:, 0] - x, xy[:, 1] - y) < 1e-9)  # a plunge's waypoints share their XY
        assert at.size and any((fx, fy) == (record.cut["fx_N"][k], record.cut["fy_N"][k]) for k in at)
    assert len(arrows) >= 10  # spread along the two cuts
    # the longest arrow is ARROW-sized: 8 % of the drawing's larger extent (stock outline included)
    longest = np.max(np.hypot(arrows[:, 2], arrows[:, 3])) * mm_per_N
    assert 0.0 < longest <= 0.08 * 60.0 + 1e-9
    # segments: one per move (no decimation), coloured by the larger |F| of their ends
    F = record.cut["force_N"]
    assert len(segs) == len(F) - 1
    assert np.allclose(force, np.maximum(F[:-1], F[1:]))
    assert key_N in (1, 2, 5, 10, 20, 50, 100, 200, 500)


def test_the_stock_figure_holds_the_removed_volume(slot_run):
    record, out = slot_run
    jb = _item(cut_items(read_record(out)), "fig14_cut_stock").job
    before, after, extent = jb[1]
    summary = json.loads((out / "summary.json").read_text())
    ny, nx = before.shape
    cell_mm2 = (extent[1] - extent[0]) / nx * (extent[3] - extent[2]) / ny
    removed = np.nansum(before - after) * cell_mm2
    assert removed == pytest.approx(summary["cut"]["removed_mm3"], rel=VOLUME_REL)
    shown = float(f"{summary['cut']['removed_mm3'] / 1e3:.4g}")
    assert f"removed {shown:g} cm³ of {summary['cut']['stock_volume_mm3'] / 1e3:g} cm³" in jb[2]["title"]
    # the stock box of the problem, mm, is the images' extent
    assert extent == pytest.approx((-30.0, 30.0, -10.0, 30.0), abs=1e-6)
    assert np.nanmax(before) == pytest.approx(0.0, abs=1e-6) and np.nanmin(after) == pytest.approx(-2.0, abs=1e-3)


def test_the_error_figure_shows_the_three_cases_with_their_rms_and_max(slot_run):
    record, out = slot_run
    item = _item(cut_items(read_record(out)), "fig15_cut_error")
    s, bands = item.job[1]
    unit = item.job[2]["unit"]
    summary = json.loads((out / "summary.json").read_text())["cut"]["error_mm"]
    assert len(bands) == 3  # a stand-in in this problem
    top = max(np.nanmax(record.cut[c]) for c in ("error_uncompensated_mm", "error_stand_in_mm"))
    assert unit == ("mm" if top >= 1.0 else "µm")
    for band, col, key in zip(
        bands,
        ("error_uncompensated_mm", "error_compensated_mm", "error_stand_in_mm"),
        ("uncompensated", "compensated", "stand_in_compensated"),
    ):
        v = record.cut[col]
        assert np.array_equal(band.hi, v * (1.0 if unit == "mm" else 1e3), equal_nan=True)
        rms = float(np.sqrt(np.mean(v**2)))
        assert rms == pytest.approx(summary[key]["rms"], rel=SAME_NUMBER_REL, abs=1e-15)
        if key == "compensated":
            assert "0 (numerical)" in band.label
        else:
            assert f"RMS {float(f'{rms:.4g}'):g}" in band.label.replace("e-0", "e-")


# --------------------------------------------------------------------------- a tampered cut.csv
def _rewrite(path: Path, line: int, column: str, value: str | None) -> None:
    rows = [r.split(",") for r in path.read_text().splitlines()]
    j = rows[0].index(column)
    if value is None:  # drop the column
        rows = [r[:j] + r[j + 1 :] for r in rows]
    else:
        rows[line - 1][j] = value
    path.write_text("\n".join(",".join(r) for r in rows) + "\n")


@pytest.mark.parametrize(
    "line,column,value,needle",
    [
        (12, "force_N", "nan", "cut.csv: line 12, column force_N: nan; expected a finite number"),
        (1, "radial_width_mm", None, "cut.csv: column(s) radial_width_mm missing"),
        (5, "milling", "9", "cut.csv: line 5, column milling: 9.0; expected a whole number from 0 to 5"),
    ],
)
def test_a_tampered_cut_file_is_refused_with_one_line(copy_of, line, column, value, needle):
    _rewrite(copy_of / "cut.csv", line, column, value)
    code, err = _cli(["report", str(copy_of), "--no-map", "--jobs", "1"])
    assert code == 2, err
    assert err.startswith("compplan: error:") and err.count("\n") == 1, err
    assert needle in err and "Traceback" not in err, err
    assert not (copy_of / "report.html").exists() and not (copy_of / "figures").exists()


def test_a_cut_file_with_a_row_missing_is_refused(copy_of):
    path = copy_of / "cut.csv"
    rows = path.read_text().splitlines()
    path.write_text("\n".join(rows[:-1]) + "\n")
    code, err = _cli(["report", str(copy_of), "--no-map", "--jobs", "1"])
    assert code == 2 and err.count("\n") == 1, err
    assert f"cut.csv: {len(rows) - 2} rows; expected one per waypoint of the program ({len(rows) - 1}" in err
