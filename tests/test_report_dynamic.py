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
from planner.numbers import format_mm
from planner.record import read_record as load_run
from planner.report import FIGURE_NAMES
from planner.report.figures import DYNAMIC_FIGURE
from planner.record import DYNAMIC_COLUMNS
from planner.report.dynamic_tables import DYNAMIC_CASES
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
    label = dict(DYNAMIC_CASES)["static+dynamic"]
    row = next(line for line in md.splitlines() if line.startswith(f"| {label} |"))
    shown = [c.strip() for c in row.strip("|").split("|")][1:]
    for text, m in zip(shown, MEASURES, strict=True):
        assert text == format_mm(dyn["predicted_tcp_error"]["static+dynamic"][m])


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


def test_one_dynamic_headline_on_the_terminal_in_the_summary_and_the_report(shared_cli):
    """Issue 24: the dynamic headline is computed once (DynamicStage.headline) and the terminal, both
    places of summary.json and the report show the same numbers, each with its definition; at rest
    the motor-side command's error is zero."""
    from planner.dynamic import HEADLINE_CASES, HEADLINE_DEFINITION, headline_text
    from planner.numbers import format_mm, headline_mm, mm_text
    from tests.conftest import FAST_PAYLOAD_ARGV

    run = shared_cli.run(*FAST_PAYLOAD_ARGV)  # the run of the dynamic_run fixture
    s = json.loads((run.folder / "summary.json").read_text())
    h, d = s["headline"]["dynamic_compensation"], s["dynamic_compensation"]
    assert h == d["headline"] and h["definition"] == HEADLINE_DEFINITION
    shown = {}
    for where in ("motion", "rest"):
        for case, key, _words in HEADLINE_CASES:
            k = f"error_{where}_max_{key}_mm"
            assert h[k] == headline_mm(d["predicted_tcp_error"][case][f"{where}_max_mm"]), k
            shown[k] = h[k]
    assert shown["error_rest_max_motor_side_command_mm"] == 0.0 < shown["error_rest_max_uncompensated_mm"]
    # the terminal: the headline's own text, every number in it
    line = next(x.strip() for x in run.out.splitlines() if x.strip().startswith("dynamic compensation:"))
    assert line == f"dynamic compensation: {headline_text(h)}"
    for v in shown.values():
        assert mm_text(v) in line
    # the report: the headline rows are cells of the same keys and values, and the table below shows
    # the same rounded numbers
    cells = {c["key"]: c for c in parse(run.folder).cells}
    for k, v in shown.items():
        cell = cells[f"headline.dynamic_compensation.{k}"]
        assert cell["value"] == v and cell["text"].strip() == format_mm(v), k
    for where in ("motion", "rest"):
        for case, key, _words in HEADLINE_CASES:
            table = cells[f"dynamic_compensation.predicted_tcp_error.{case}.{where}_max_mm"]["text"].strip()
            assert table == format_mm(shown[f"error_{where}_max_{key}_mm"]), (case, where)
