"""The report of a program path (planner/report/toolpath.py, toolpath_plot.py): the toolpath and
feed figures exist for a program and not for a line, the program tables show summary.json's
numbers, the view from the plan equals the view from the folder, and the reductions for drawing
keep what the figures must show (peaks, corners, slow-downs) within their size bounds."""

from __future__ import annotations

import dataclasses
import json
import shutil
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from models.transforms import rpy_to_matrix
from planner.numbers import format_number
from planner.output import csv_bytes
from planner.plan_record import record_from_plan as run_from_plan
from planner.record import ProgramRecord as ProgramView
from planner.record import read_record as load_run
from planner.record import to_program_frame
from planner.report import lookup, write_report
from planner.report.program_tables import SLOWED_SHOWN, program_tables
from planner.report.figure_cache import FIGURE_CACHE_ENV, figure_key
from planner.report.toolpath import (
    FEED_BINS,
    MAX_DRAWN_SEGMENTS,
    bin_extrema,
    line_feed_m_s,
    sample_feed_m_s,
    merge_segments,
    slowed_lines_worst_first,
    tcp_speed_m_s,
)
from planner.report.feed_plot import SLOWED_STYLE
from planner.record.columns import MM_MIN_PER_M_S
from planner.report.toolpath_plot import FEED_FIGURE, PROGRAM_FIGURES, TOOLPATH_FIGURE, program_items

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"

#: A small part: straight cuts, an arc, a change of feed, a rapid across the part, a second cut.
PROGRAM = """%
(small part for the report tests)
G21 G90 G17 G94
G0 X0 Y0 Z5
G1 Z0 F1500
G1 X30
G1 Y10
G3 X30 Y30 I0 J10
G1 X0 F3000
G1 Y28
G1 X20
G0 Z5
G0 X10 Y15
G1 Z0 F600
G1 X20
G0 Z5
M30
%
"""

COMMON = """
[robot]
model = "ur10"
tool = { xyz = [0.1, 0.0, 0.05], rpy_deg = [0.0, 0.0, 0.0] }
[wrench]
frame = "tool"
force = [30.0, 20.0, 40.0]
[limits]
max_joint_step = 0.3
"""

PROGRAM_PROBLEM = (
    """name = "part"
description = "small program for the report tests"
[path]
kind = "gcode"
file = "part.ngc"
[workpiece]
xyz = [0.6, -0.1, 0.05]
rpy_deg = [0.0, 0.0, 30.0]
"""
    + COMMON
)

LINE_PROBLEM = (
    """name = "line"
[path]
kind = "line"
start = [0.60, -0.10, 0.05]
end = [0.64, -0.05, 0.05]
points = 12
[orientation]
rule = "free_tool_axis"
rpy_deg = [180.0, 0.0, 0.0]
"""
    + COMMON
)


class _Report(HTMLParser):
    """Embedded figures, absent-figure notes, value cells (data-key) and table rows of report.html."""

    def __init__(self) -> None:
        super().__init__()
        self.images: dict[str, str] = {}
        self.absent: dict[str, str] = {}
        self.cells: list[dict] = []
        self.rows: dict[str, list[list[str]]] = {}  # table anchor (its heading's id) -> rows
        self.anchors: set[str] = set()
        self._table = ""
        self._cell: dict | None = None
        self._absent: str | None = None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if "id" in a:
            self.anchors.add(a["id"])
            self._table = a["id"]
        if tag == "img" and "data-figure" in a:
            self.images[a["data-figure"]] = a["src"]
        elif tag == "p" and "data-absent" in a:
            self._absent = a["data-absent"]
            self.absent[self._absent] = ""
        elif tag == "tr":
            self.rows.setdefault(self._table, []).append([])
        elif tag == "td":
            self._cell = {"key": a.get("data-key"), "value": a.get("data-value"), "text": ""}

    def handle_data(self, data):
        if self._cell is not None:
            self._cell["text"] += data
        if self._absent is not None:
            self.absent[self._absent] += data

    def handle_endtag(self, tag):
        if tag == "td" and self._cell is not None:
            if self._cell["key"] is not None:
                self.cells.append(self._cell)
            if self.rows.get(self._table):
                self.rows[self._table][-1].append(self._cell["text"])
            self._cell = None
        elif tag == "p":
            self._absent = None
        elif tag == "table":
            self._table = ""


def _parse(folder: Path) -> _Report:
    rep = _Report()
    rep.feed((folder / "report.html").read_text())
    return rep


def _plan(folder: Path, toml: str, files: dict[str, str]):
    from planner.plan import plan, write_outputs
    from problems.problem import load_problem

    folder.mkdir(parents=True)
    for name, text in files.items():
        (folder / name).write_text(text)
    (folder / "problem.toml").write_text(toml)
    res = plan(load_problem(folder / "problem.toml")).raise_for_status()
    view = res.view()
    out = folder / "out"
    write_outputs(res, out, with_figures=False, view=view)
    return res, view, out


@pytest.fixture(scope="module")
def figure_cache(tmp_path_factory):
    """The module's own figure cache (as the other report tests: never the user's)."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv(FIGURE_CACHE_ENV, str(tmp_path_factory.mktemp("figure-cache")))
        yield


@pytest.fixture(scope="module")
def program_run(tmp_path_factory, figure_cache):
    """The small program planned, its outputs written and its report built from the plan."""
    res, view, out = _plan(tmp_path_factory.mktemp("program") / "p", PROGRAM_PROBLEM, {"part.ngc": PROGRAM})
    write_report(out, record=res.record(out, view), map_options=False, workers=1)
    return res, view, out


@pytest.fixture(scope="module")
def line_run(tmp_path_factory, figure_cache):
    res, view, out = _plan(tmp_path_factory.mktemp("line") / "p", LINE_PROBLEM, {})
    write_report(out, record=res.record(out, view), map_options=False, workers=1)
    return res, view, out


# ------------------------------------------------------------------------------- the report
def test_a_program_report_has_the_toolpath_and_feed_figures(program_run):
    _, _, out = program_run
    rep = _parse(out)
    md = (out / "report.md").read_text()
    for name in PROGRAM_FIGURES:
        assert name in rep.images, f"{name} not embedded; absent: {rep.absent.get(name)}"
        png = (out / "figures" / f"{name}.png").read_bytes()
        assert png.startswith(PNG_MAGIC)
        assert (out / "figures" / f"{name}.pdf").read_bytes().startswith(b"%PDF")
        assert f"figures/{name}.png" in md
    assert {"program", "program-feed", "program-slowed"} <= rep.anchors
    assert "### Program" in md and "### Program: feed" in md and "### Program: slowed lines and path deviation" in md


def test_the_program_tables_show_the_summary_numbers(program_run):
    _, _, out = program_run
    summary = json.loads((out / "summary.json").read_text())
    rep = _parse(out)
    cells = {c["key"]: c for c in rep.cells if c["key"].startswith("program.")}
    method = summary["controller_trajectory"]
    wanted = [
        "program.file",
        "program.n_waypoints",
        "program.n_stops",
        "program.path_tolerance_mm",
        "program.path_tolerance_source",
        f"program.feed.{method}.programmed_time_s",
        f"program.feed.{method}.duration_s",
    ]
    assert set(wanted) <= set(cells), sorted(cells)
    for key, cell in cells.items():
        assert json.loads(cell["value"]) == lookup(summary, key), key  # full precision, machine-checkable
    entry = summary["program"]["feed"][method]
    (row,) = [r for r in rep.rows["program-feed"] if r]  # one timing method
    assert row[3] == format_number(entry["duration_s"] / entry["programmed_time_s"])  # achieved / programmed
    (srow,) = [r for r in rep.rows["program-slowed"] if r]  # the slowed lines by cause: a table of their own
    col = _columns(program_tables(summary)[2].header)
    worst = sorted(entry["slowed_lines"], key=lambda lf: (lf[1], lf[0]))
    assert worst, "the small part's arc and short moves are slowed (else the test shows nothing)"
    shown = [f"line {L}: {format_number(100.0 * f, 3)} %" for L, f in worst[:SLOWED_SHOWN]]
    assert srow[col["slowed program lines"]] == f"{len(worst)}: " + ", ".join(shown) + (
        f" and {len(worst) - SLOWED_SHOWN} more" if len(worst) > SLOWED_SHOWN else ""
    )
    assert [L for L, _ in slowed_lines_worst_first(entry)] == [L for L, _ in worst]
    assert srow[col["of which slowed only by their neighbours"]] == str(entry["n_lines_slowed_by_neighbours"])
    assert srow[col["path deviation against"]].startswith("✓ within: ")  # the plan keeps its samples within


def _columns(header: list[str]) -> dict[str, int]:
    """The feed table's column index by the start of its header (unique starts)."""
    starts = [
        "slowed program lines",
        "of which held down by a joint limit",
        "of which slowed only by their neighbours",
        "largest path deviation",
        "path deviation against",
    ]
    return {s: i for s in starts for i, h in enumerate(header) if h.startswith(s)}


#: Slowed lines of a made-up feed entry: (line, fraction of F); the first three held down by a limit.
SLOWED = [[12, 0.3], [13, 0.9], [37, 0.864], [444, 0.55], [445, 0.524]]
BY_LIMIT = [[37, 0.864, 2, "velocity"], [444, 0.55, 4, "jerk"], [445, 0.524, 4, "jerk"]]


def _feed_summary(split: bool) -> dict:
    """A summary's program block with three timing methods; ``split``: with the slowed lines by cause
    and the path deviation (within, outside and not measured against a 0.02 mm tolerance)."""

    def entry(deviation_mm):
        e = {"programmed_time_s": 10.0, "duration_s": 11.0, "peak_feed_ratio": 1.0, "n_stretches": 3}
        e["slowed_lines"] = SLOWED
        if split:
            e |= {"slowed_by_limit": BY_LIMIT, "n_lines_slowed_by_neighbours": 2, "path_deviation_mm": deviation_mm}
        return e

    feed = {"lookahead": entry(0.0184), "ruckig": entry(0.03), "toppra": entry(None)}
    return {
        "controller_trajectory": "lookahead",
        "program": {"file": "f.ngc", "kind": "gcode", "path_tolerance_mm": 0.02, "feed": feed},
    }


def test_the_feed_table_splits_the_slowed_lines_by_cause_and_marks_the_path_deviation():
    tables = program_tables(_feed_summary(split=True))
    assert [t.anchor for t in tables] == ["program", "program-feed", "program-slowed"]
    assert not any(h.startswith("slowed") for h in tables[1].header)  # the feed table: times only
    table = tables[2]
    col = _columns(table.header)
    assert len(col) == 5, table.header
    rows = [[c.text for c in r] for r in table.rows]  # look-ahead (controller), Ruckig, TOPP-RA
    assert len(rows) == 3 and rows[0][0].endswith("(controller)")
    for row in rows:
        assert row[col["of which held down by a joint limit"]] == (
            "3: line 445: 52.4 % (J4 jerk), line 444: 55 % (J4 jerk), line 37: 86.4 % (J2 velocity)"
        )
        assert row[col["of which slowed only by their neighbours"]] == "2"
        assert row[col["slowed program lines"]].startswith("5: line 12: 30 %, line 445: 52.4 %")
    look, ruck, topp = (row[col["path deviation against"]] for row in rows)
    assert look == "✓ within: 0.0184 mm ≤ 0.02 mm"
    assert ruck == "✗ OUTSIDE: 0.03 mm > 0.02 mm (×1.5)"
    assert topp == "not measured"
    assert rows[1][col["largest path deviation"]] == "0.03"
    assert "joint limit" in table.note and "✗ OUTSIDE" in table.note


def test_the_feed_table_of_a_summary_without_the_causes_lists_the_slowed_lines_as_before():
    tables = program_tables(_feed_summary(split=False))
    assert [t.anchor for t in tables] == ["program", "program-feed"]  # no table of slowed lines by cause
    table = tables[1]
    assert not {"of which held down by a joint limit", "path deviation against"} & set(_columns(table.header))
    assert table.header[-1].startswith("slowed program lines")
    for row in table.rows:
        assert row[-1].text == "5: line 12: 30 %, line 445: 52.4 %, line 444: 55 %, line 37: 86.4 %, line 13: 90 %"
    assert "joint limit" not in table.note


def _with_slowed(run, split: bool):
    """``run`` with its controller's feed entry replaced: three of its program lines slowed, one of
    them (the slowest) by joint 4's jerk when ``split``, the others by the stops; the lines chosen."""
    ctrl = run.summary["controller_trajectory"]
    lines = np.unique(run.program.sample_line[ctrl])
    chosen = [int(L) for L in lines[[1, len(lines) // 2, -2]]]
    summary = json.loads(json.dumps(run.summary))
    entry = summary["program"]["feed"][ctrl]
    for key in ("slowed_by_limit", "n_lines_slowed_by_neighbours", "path_deviation_mm"):
        entry.pop(key, None)
    entry["slowed_lines"] = [[chosen[0], 0.4], [chosen[1], 0.6], [chosen[2], 0.8]]
    if split:
        entry |= {"slowed_by_limit": [[chosen[0], 0.4, 4, "jerk"]], "n_lines_slowed_by_neighbours": 2}
    return dataclasses.replace(run, summary=summary), chosen


def _drawn(item):
    """The feed figure of a figure item, drawn: (its speed panel, the job's arguments)."""
    fn, args, kwargs = item.job
    fig = fn(*args, **kwargs)
    return fig.axes[0], args


@pytest.mark.parametrize("split", [True, False])
def test_the_feed_figure_draws_the_slowed_lines_by_cause(program_run, split):
    """With ``slowed_by_limit`` the lines a joint limit holds down (red, named with joint and
    derivative) and those slowed by the stops (orange) are drawn apart, in both panels, and the
    title and caption count them; a summary without it draws every slowed line in one colour."""
    res, view, out = program_run
    run, chosen = _with_slowed(run_from_plan(res, out, view), split)
    item = program_items(run)[1]
    ax, args = _drawn(item)
    kinds, slow_bins, line_bands, marks = args[4], args[5], args[6], args[7]
    lines = run.program.sample_line[run.summary["controller_trajectory"]]
    starts = bin_extrema(np.zeros(len(lines)))[0]
    groups = [[chosen[0]], chosen[1:]] if split else [chosen]
    assert kinds == (("limit", "stops") if split else ("slowed",))
    for group, bins, (_, hi), speed in zip(groups, slow_bins, line_bands[1:], args[2][1:-1]):
        want = np.logical_or.reduceat(np.isin(lines, group), starts)
        assert np.array_equal(bins, want)  # the bins of that kind's lines, no other
        assert np.array_equal(np.isfinite(hi), want) and set(hi[want]) <= set(group)  # (b): those lines
        assert np.array_equal(np.isfinite(speed[1]), want)  # (a): their speed
    labels = {t.get_text(): t.get_color() for t in ax.texts}
    legend = [t.get_text() for t in ax.figure.legends[0].get_texts()]
    title = ax.figure._suptitle.get_text()
    if split:
        assert [m[1] for m in marks] == [f"line {chosen[0]}: 40 % (J4 jerk)"]  # the stops' lines are not named
        assert labels == {f"line {chosen[0]}: 40 % (J4 jerk)": SLOWED_STYLE["limit"][0]}
        (note,) = ax.texts  # its arrow points at the line's peak speed, 40 % of its F, on its own stretch
        assert note.xy[1] == pytest.approx(0.4 * marks[0][2] * MM_MIN_PER_M_S)
        assert "TCP speed on a line slowed by a joint limit" in legend
        assert "TCP speed on a line slowed only by its neighbours (a stop, a held line)" in legend
        assert (
            "3 slowed lines: 1 held down by a joint limit (red), "
            "2 slowed only by their neighbours, a stop or a held line (orange)" in title
        )
        assert "red, the 1 line a joint limit holds down" in item.caption
        assert "orange, the 2 lines slowed only by their neighbours" in item.caption
    else:
        assert sorted(m[1] for m in marks) == sorted(f"line {L}: {p} %" for L, p in zip(chosen, (40, 60, 80)))
        assert set(labels.values()) == {SLOWED_STYLE["slowed"][0]}
        assert "TCP speed on a line slowed (limit or stops)" in legend
        assert title.endswith("\n3 slowed lines")
        assert "Red: the 3 program lines the summary lists as slowed" in item.caption
        assert "does not tell the two apart" in item.caption


def test_a_line_path_has_no_program_figures_nor_tables(line_run):
    res, view, out = line_run
    assert res.problem.program is None and "program" not in view.summary
    rep = _parse(out)
    for name in PROGRAM_FIGURES:
        assert name not in rep.images and name not in rep.absent
        assert not (out / "figures" / f"{name}.png").exists()
    assert not {"program", "program-feed", "program-slowed"} & rep.anchors
    assert "### Program" not in (out / "report.md").read_text()
    assert run_from_plan(res, out, view).program is None and load_run(out).program is None


def test_the_view_from_the_plan_equals_the_view_from_the_folder(program_run):
    res, view, out = program_run
    a, b = run_from_plan(res, out, view), load_run(out)
    assert a.program is not None and b.program is not None
    for field in ("points_m", "line", "rapid", "feed_m_s"):
        np.testing.assert_array_equal(getattr(a.program, field), getattr(b.program, field), err_msg=field)
    assert a.program.sample_line.keys() == b.program.sample_line.keys() == {res.controller}
    np.testing.assert_array_equal(a.program.sample_line[res.controller], b.program.sample_line[res.controller])
    np.testing.assert_array_equal(a.program.sample_waypoint[res.controller], b.program.sample_waypoint[res.controller])
    assert all("line" not in tr and "waypoint" not in tr for tr in b.trajectories.values())  # as from a plan
    ia, ib = program_items(a), program_items(b)
    assert [it.name for it in ia] == [it.name for it in ib] == list(PROGRAM_FIGURES)
    for x, y in zip(ia, ib):
        assert x.job is not None and y.job is not None, (x.absent, y.absent)
        assert figure_key(x.job, True) == figure_key(y.job, True), x.name  # the same drawing
        assert x.caption == y.caption


def test_the_program_points_are_in_the_program_frame(program_run):
    res, _, out = program_run
    prog = load_run(out).program
    w = res.problem.program.waypoints
    np.testing.assert_allclose(prog.points_m, w.points_m, atol=1e-12)
    np.testing.assert_array_equal(prog.line, w.line)
    np.testing.assert_array_equal(prog.rapid, w.rapid)
    np.testing.assert_allclose(prog.feed_m_s, w.feed_m_s, rtol=1e-15, equal_nan=True)
    fl = res.feed[res.controller]
    np.testing.assert_array_equal(prog.sample_line[res.controller], w.line[fl.sample_move])


def test_a_trajectory_without_program_lines_states_why_the_feed_is_absent(program_run, tmp_path):
    _, _, out = program_run
    folder = tmp_path / "copy"
    shutil.copytree(out, folder)
    path = folder / "trajectory.csv"
    cols = np.genfromtxt(path, delimiter=",", names=True)
    names = [n for n in cols.dtype.names if n not in ("line", "waypoint")]
    path.write_bytes(csv_bytes(names, np.column_stack([cols[n] for n in names])))
    write_report(folder, map_options=False, workers=1)
    rep = _parse(folder)
    assert TOOLPATH_FIGURE in rep.images
    assert FEED_FIGURE not in rep.images and "no 'line' and 'waypoint' columns" in rep.absent[FEED_FIGURE]


def test_the_feed_figure_speed_is_the_forward_kinematics_speed(program_run):
    """The figure's largest speed on cutting lines is the TCP speed of the controller's samples by
    forward kinematics (as tests/test_feed.py checks it), never above the feed by more than 2 %."""
    res, view, out = program_run
    run = run_from_plan(res, out, view)
    tr = res.trajectories[res.controller]
    p = res.problem.model.kinematics.tcp(tr.q)[:, :3, 3]
    v = np.linalg.norm(np.diff(p, axis=0), axis=1) / np.diff(tr.t)
    speed = tcp_speed_m_s(res.problem.model.kinematics.tcp, tr.t, tr.q)
    np.testing.assert_allclose(speed[1:], v, rtol=1e-12)
    feed = sample_feed_m_s(run.program, run.program.sample_waypoint[res.controller])
    cut = np.isfinite(feed)
    assert np.max(speed[cut] / feed[cut]) <= 1.02
    item = program_items(run)[1]
    bands = item.job[1][2]
    assert max(np.nanmax(hi) for _, hi in bands if np.isfinite(hi).any()) == pytest.approx(speed.max())


# --------------------------------------------------------------------------- the reductions
def _raster(rows: int, per_row: int, pitch: float = 1e-3, step: float = 5e-4) -> np.ndarray:
    """A zig-zag raster in the plane (m): rows of ``per_row`` moves joined at alternate ends."""
    pts = []
    for r in range(rows):
        x = np.arange(per_row + 1) * step
        pts.append(np.column_stack([x if r % 2 == 0 else x[::-1], np.full(per_row + 1, r * pitch)]))
    return np.vstack(pts)


def test_merging_for_drawing_bounds_the_segments_and_keeps_peaks_and_corners():
    P = _raster(200, 500)  # 100 200 waypoints
    n = len(P)
    rng = np.random.default_rng(1)
    v = np.column_stack([rng.random(n), rng.random(n) * 1e-10])
    v[12345, 0] = 7.0  # a peak inside a row
    rapid = np.zeros(n, bool)
    rapid[50_000:50_003] = True
    segs, vals, rap, tol = merge_segments(P, v, rapid)
    assert 0 < tol and len(segs) <= MAX_DRAWN_SEGMENTS
    assert vals[:, 0].max() == 7.0 and np.nanmax(vals[:, 1]) == v[:, 1].max()  # no peak lost
    np.testing.assert_array_equal(segs[0, 0], P[0])
    np.testing.assert_array_equal(segs[-1, 1], P[-1])
    np.testing.assert_array_equal(segs[1:, 0], segs[:-1, 1])  # one connected polyline
    assert rap.sum() >= 1 and not rap[: np.argmax(rap)].any()
    ends = {tuple(p) for p in segs.reshape(-1, 2)}
    corners = [P[r * 501 + k] for r in range(200) for k in (0, 500)]
    assert all(tuple(c) in ends for c in corners)  # every row end drawn where it is
    # a path within the bound is drawn as it is
    segs, vals, rap, tol = merge_segments(P[:1000], v[:1000], rapid[:1000])
    assert tol == 0.0 and len(segs) == 999
    np.testing.assert_array_equal(vals[:, 0], np.fmax(v[:999, 0], v[1:1000, 0]))


def test_bins_keep_the_extremes_of_a_million_samples():
    rng = np.random.default_rng(2)
    y = rng.random(1_000_003)
    y[777_777] = 5.0
    y[123_456] = -3.0
    y[10:20] = np.nan
    starts, lo, hi = bin_extrema(y)
    assert len(starts) == FEED_BINS and starts[0] == 0
    assert np.nanmax(hi) == 5.0 and np.nanmin(lo) == -3.0
    b = np.searchsorted(starts, 777_777, side="right") - 1
    assert hi[b] == 5.0
    short = np.array([1.0, np.nan, 3.0])
    s, lo, hi = bin_extrema(short)
    np.testing.assert_array_equal(s, [0, 1, 2])
    np.testing.assert_array_equal(hi, short)


def test_tcp_speed_of_a_uniform_motion():
    t = np.arange(50) * 0.008

    def tcp(q):  # a TCP moving along x at 0.05 m/s (q[:, 0] is the position)
        T = np.tile(np.eye(4), (len(q), 1, 1))
        T[:, 0, 3] = q[:, 0]
        return T

    q = np.zeros((50, 6))
    q[:, 0] = 0.05 * t
    speed = tcp_speed_m_s(tcp, t, q)
    assert speed[0] == 0.0
    np.testing.assert_allclose(speed[1:], 0.05, rtol=1e-9)


def test_program_frame_is_the_inverse_of_the_workpiece_placement():
    rpy = np.array([0.1, -0.2, 0.7])
    xyz = np.array([0.6, -0.1, 0.05])
    P = np.random.default_rng(3).random((20, 3)) * 0.1
    base = P @ rpy_to_matrix(rpy).T + xyz
    np.testing.assert_allclose(to_program_frame(base, {"xyz_m": xyz, "rpy_rad": rpy}), P, atol=1e-15)


def test_the_feed_of_a_line_is_its_cutting_feed():
    view = ProgramView(
        points_m=np.zeros((6, 3)),
        line=np.array([4, 5, 6, 6, 6, 7]),
        rapid=np.array([True, False, True, False, True, True]),
        feed_m_s=np.array([np.nan, 0.025, np.nan, 0.01, np.nan, np.nan]),
    )
    got = line_feed_m_s(view, np.array([5, 6, 6, 7, 99]))
    np.testing.assert_array_equal(got, [0.025, 0.01, 0.01, np.nan, np.nan])
