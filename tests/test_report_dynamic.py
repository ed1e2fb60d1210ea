"""The report of a plan with dynamic compensation (``[timing] dynamic = true``): figure 8 (TCP
deviation from the planned path against time) and the "Dynamic compensation" tables, drawn
from ``summary.json``'s ``dynamic_compensation`` and ``dynamic.csv``; a run without dynamic
compensation has neither (no empty figure, no empty table)."""

from __future__ import annotations

import base64
import html as html_text
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from planner.cli import main
from planner.report import FIGURE_NAMES, load_run
from planner.report.figures import DYNAMIC_FIGURE
from planner.report.run import DYNAMIC_COLUMNS
from tests.test_report import PNG_MAGIC, check_cells_match_summary, check_figures_embedded, parse

CASES = ("none", "static", "static+dynamic")
MEASURES = ("motion_max_mm", "motion_rms_mm", "rest_max_mm")


@pytest.fixture
def dynamic_run(fast_payload_run) -> Path:
    """``compplan plan ur5_fast_payload``: the report built from the plan in memory (once per
    session: conftest.py; copy to change)."""
    return fast_payload_run


@pytest.fixture
def static_run(paper_report) -> Path:
    """A plan without dynamic compensation, with its report (the demo's; shared)."""
    return paper_report


def _dynamic_cells(folder: Path) -> dict[str, dict]:
    return {c["key"]: c for c in parse(folder).cells if c["key"].startswith("dynamic_compensation.")}


def _check_dynamic_report(folder: Path, with_map: bool = True) -> None:
    summary = json.loads((folder / "summary.json").read_text())
    dyn = summary["dynamic_compensation"]
    rep = check_cells_match_summary(folder)  # every cell equals summary.json, rounded
    present = (set(FIGURE_NAMES) if with_map else set(FIGURE_NAMES) - {"fig1_compliance_map"}) | {DYNAMIC_FIGURE}
    check_figures_embedded(folder, rep, present)
    png, pdf = folder / "figures" / f"{DYNAMIC_FIGURE}.png", folder / "figures" / f"{DYNAMIC_FIGURE}.pdf"
    assert png.read_bytes().startswith(PNG_MAGIC) and pdf.read_bytes().startswith(b"%PDF")
    assert base64.b64decode(rep.images[DYNAMIC_FIGURE].split(",", 1)[1]) == png.read_bytes()
    html = (folder / "report.html").read_text()
    assert "Figure 8. TCP deviation from the planned path against time" in html
    cells = _dynamic_cells(folder)
    for case in CASES:
        for m in MEASURES:
            key = f"dynamic_compensation.predicted_tcp_error.{case}.{m}"
            assert cells[key]["value"] == dyn["predicted_tcp_error"][case][m]
    for key in ("passes", "smoothing_s", "status", *(f"limit_scale.{k}" for k in dyn["limit_scale"])):
        assert f"dynamic_compensation.{key}" in cells, key
    assert "Dynamic compensation: predicted TCP error [mm]" in html
    for text in (dyn["definition"], dyn["assumptions"]):  # the table's note
        assert html_text.escape(text) in html
    md = (folder / "report.md").read_text()
    assert f"figures/{DYNAMIC_FIGURE}.png" in md
    row = next(line for line in md.splitlines() if line.startswith("| static + dynamic"))
    shown = [c.strip() for c in row.strip("|").split("|")][1:]
    for text, m in zip(shown, MEASURES, strict=True):
        assert float(text) == pytest.approx(dyn["predicted_tcp_error"]["static+dynamic"][m], rel=1e-3)


def test_dynamic_plan_report_has_figure_and_table(dynamic_run):
    _check_dynamic_report(dynamic_run)


def test_report_of_a_dynamic_folder(dynamic_run, tmp_path):
    """``compplan report DIR`` reads dynamic.csv and gives the same figure as the plan's report."""
    folder = tmp_path / "again"
    shutil.copytree(dynamic_run, folder)
    run = load_run(folder)
    assert run.dynamic is not None and set(run.dynamic) == set(DYNAMIC_COLUMNS)
    csv = np.genfromtxt(folder / "dynamic.csv", delimiter=",", names=True)
    assert np.array_equal(run.dynamic["e_static_dynamic_m"], csv["e_static_dynamic_m"])
    assert main(["report", str(folder), "--no-map", "--jobs", "1"]) == 0
    _check_dynamic_report(folder, with_map=False)
    a = (dynamic_run / "figures" / f"{DYNAMIC_FIGURE}.png").read_bytes()
    assert (folder / "figures" / f"{DYNAMIC_FIGURE}.png").read_bytes() == a


def test_dynamic_folder_without_its_csv_says_so(dynamic_run, tmp_path):
    folder = tmp_path / "nocsv"
    shutil.copytree(dynamic_run, folder)
    (folder / "dynamic.csv").unlink()
    assert main(["report", str(folder), "--no-map", "--jobs", "1"]) == 0
    rep = parse(folder)
    assert "dynamic.csv absent" in rep.absent[DYNAMIC_FIGURE]
    assert not (folder / "figures" / f"{DYNAMIC_FIGURE}.png").exists()
    assert _dynamic_cells(folder)  # the table still comes from summary.json


def test_run_without_dynamic_compensation_has_neither(static_run):
    summary = json.loads((static_run / "summary.json").read_text())
    assert "dynamic_compensation" not in summary
    rep = check_cells_match_summary(static_run)
    check_figures_embedded(static_run, rep, set(FIGURE_NAMES))
    assert DYNAMIC_FIGURE not in rep.absent
    assert not list((static_run / "figures").glob("fig8*"))
    assert not _dynamic_cells(static_run)
    for text in ((static_run / "report.html").read_text(), (static_run / "report.md").read_text()):
        assert "Dynamic compensation" not in text and "Figure 8" not in text
    assert load_run(static_run).dynamic is None
