"""What ``compplan place`` says about collisions (issue 25): with a ``[cell]``, how many placements
were checked, how many were set aside for collision and why (the base overlapping an object, or
every flip-free branch colliding), and the best placement's smallest clearance in its full plan,
in ``summary.json``, ``report.html`` and on the terminal; without one, that nothing was checked.

The counts are checked against the study's own statuses, and the split by reason against an
independent footprint test (the problem file's, :func:`problems.cell.footprint_overlaps`, on the
objects moved into each placement's base frame), never against numbers written here.  The cell
(a table under the slot, the part on it, a beam across the arm's way) is built so that both
reasons occur on the small grid; the full plans use analytic postures (fast).
"""

from __future__ import annotations

import html
import json
import re
from dataclasses import replace

import numpy as np
import pytest

from planner.cli import main as cli_main
from planner.commands.place import _collision_reason, print_study
from planner.placement import NO_CELL_NOTE, StudyStatus, study, write_study
from problems.cell import Cell, CellObject, base_footprint, footprint_overlaps
from problems.placement.grid import cell2base, parse_grid_text
from problems.placement.scores import PlacementStatus
from problems.problem import load_problem

#: A 7 x 7 grid around the slot (x = 0.65 m) at one yaw, one placement planned in full.
GRID = "x_m=-0.2:1.0:7,y_m=-0.6:0.6:7,yaw_deg=0,top=1"
#: Every base position over the table: nothing feasible.
OVER_THE_TABLE = "x_m=0.5:0.8:3,y_m=-0.3:0.3:3,yaw_deg=0,top=1"
#: The same grid without a cell, smaller (the no-cell line only).
NO_CELL_GRID = "x_m=0.6:1.0:3,y_m=-0.6:-0.2:3,yaw_deg=0,top=0"
#: Rounding of the clearance on the terminal and in the headline, mm.
CLEARANCE_PRINT_MM = 0.05


def _at(xyz) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = xyz
    return T


#: The cell in the problem frame: (name, shape, size m, centre m, role).
OBJECTS = (
    ("table", "box", (0.5, 1.0, 0.53), (0.65, 0.0, -0.235), "obstacle"),  # top 3 cm above the mounting plane
    ("part", "box", (0.12, 0.68, 0.07), (0.65, 0.0, 0.065), "workpiece"),
    ("beam", "box", (0.1, 2.0, 0.1), (0.45, 0.0, 0.35), "obstacle"),  # across the elbow's way to the slot
)


def _cell() -> Cell:
    return Cell(tuple(CellObject(n, s, np.array(z), _at(c), role=r) for n, s, z, c, r in OBJECTS))


@pytest.fixture(scope="module")
def milling():
    return load_problem("placement_milling")


@pytest.fixture(scope="module")
def with_cell(milling, tmp_path_factory):
    """The study, its folder and what ``print_study`` printed."""
    import contextlib
    import io

    problem = replace(milling, cell=_cell())
    st = study(problem, parse_grid_text(GRID, base=milling.placement), optimise=False)
    out = tmp_path_factory.mktemp("place_cell") / "study"
    write_study(st, out)
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        print_study(st)
    return st, out, buf.getvalue()


def _base_on_object(problem, placements: np.ndarray) -> np.ndarray:
    """Independent of the kernel: each placement's base footprint against each object moved into
    the placement's base frame, through the problem file's test."""
    radius, height = base_footprint(problem.robot)
    out = np.zeros(len(placements), dtype=bool)
    for i, c2b in enumerate(cell2base(placements)):
        out[i] = any(footprint_overlaps(o, radius, height) for o in problem.cell.moved(c2b).objects)
    return out


def _data_values(page: str) -> dict[str, object]:
    """``data-key`` -> ``data-value`` of the report's numbers."""
    return {k: json.loads(html.unescape(v)) for k, v in re.findall(r'data-key="([^"]+)" data-value="([^"]*)"', page)}


def test_counts_match_the_statuses_and_the_footprints(with_cell):
    st, out, _ = with_cell
    sc, pl = st.sweep.scores, st.sweep.placements
    coll = sc.status == PlacementStatus.COLLISION.code
    foot = _base_on_object(st.problem, pl)
    # the kernel sets aside every placement whose base overlaps an object
    assert not (foot & ~coll).any()
    n_foot, n_branch = int(foot.sum()), int((coll & ~foot).sum())
    assert n_foot > 0 and n_branch > 0  # both reasons occur: the test can tell them apart
    c = json.loads((out / "summary.json").read_text())["collisions"]
    assert c["checked"] is True
    assert c["placements_checked"] == len(pl)
    assert c["set_aside"] == int(coll.sum()) == n_foot + n_branch
    assert (c["base_on_object"], c["every_branch_colliding"]) == (n_foot, n_branch)
    assert c["feasible"] == int((sc.status == PlacementStatus.OK.code).sum())
    assert [o["name"] for o in c["objects"]] == [o[0] for o in OBJECTS]
    assert c["clearance_mm"] == pytest.approx(st.problem.cell.clearance * 1e3)
    assert c["colliding_pairs"] is None and "not the colliding pair" in c["colliding_pairs_note"]
    # the baseline's reason: the same independent test at the cell origin
    b0 = st.baseline.status_of(0)
    if b0 is PlacementStatus.COLLISION:
        on = bool(_base_on_object(st.problem, np.zeros((1, 5)))[0])
        assert c["as_written"]["collision"] == ("base_on_object" if on else "every_branch_colliding")
    else:
        assert c["as_written"] == {"status": b0.value, "collision": None}
    # scores.csv says the same
    rows = (out / "scores.csv").read_text().splitlines()[1:]
    assert sum(r.split(",")[6] == "collision" for r in rows) == c["set_aside"]


def test_the_best_placements_clearance_is_its_full_plans(with_cell):
    st, out, _ = with_cell
    best = next(p for p in st.plans if p.rank == 1)
    assert best.result.ok and best.result.cell is not None
    check = best.result.cell
    found = [(c.distance, c.pair) for c in (check.waypoints, check.trajectory) if c is not None]
    d_m, pair = min(found)
    s = json.loads((out / "summary.json").read_text())
    cl = s["collisions"]["best_plan"]["clearance"]
    assert cl["min_clearance_mm"] == pytest.approx(d_m * 1e3) and cl["pair"] == pair
    assert cl["min_clearance_mm"] >= s["collisions"]["clearance_mm"]  # an ok plan keeps the clearance
    assert s["headline"]["best_plan"]["min_clearance_mm"] == pytest.approx(d_m * 1e3)
    assert s["plans"][0]["clearance"] == cl  # the plans' entries carry the same
    # on the terminal and in the report
    _, _, text = with_cell
    line = next(x for x in text.splitlines() if "smallest clearance" in x and best.label in x)
    shown = float(re.search(r"smallest clearance (-?[\d.]+) mm", line).group(1))
    assert abs(shown - d_m * 1e3) <= CLEARANCE_PRINT_MM and pair in line
    vals = _data_values((out / "report.html").read_text())
    assert vals["collisions.best_plan.clearance.min_clearance_mm"] == pytest.approx(d_m * 1e3)
    assert vals["plans.0.clearance.min_clearance_mm"] == pytest.approx(d_m * 1e3)


def test_terminal_and_report_say_the_counts(with_cell):
    st, out, text = with_cell
    c = st.collisions()
    n, k, a, b = c["placements_checked"], c["set_aside"], c["base_on_object"], c["every_branch_colliding"]
    assert (
        f"collisions: checked against the cell (table, part (workpiece), beam; clearance 5 mm): {n} placements" in text
    )
    assert (
        f"collisions: {k} set aside for collision: {a} with the base overlapping an object, "
        f"{b} with every flip-free branch colliding along the path"
    ) in text
    assert "not the colliding pair" in text
    assert "not checked" not in text
    page = (out / "report.html").read_text()
    vals = _data_values(page)
    for key in ("placements_checked", "set_aside", "base_on_object", "every_branch_colliding", "feasible"):
        assert vals[f"collisions.{key}"] == c[key], key
    assert '<h2 id="collisions">Collisions</h2>' in page and 'href="#collisions"' in page
    head = re.search(r'<p class="headline">(.*?)</p>', page, re.S).group(1)
    assert f"{k} of {n} placements set aside for collision ({a} base overlapping an object, {b} every" in head


def test_nothing_feasible_says_why_by_reason(milling):
    """Every base over the table: the one-line error counts the placements set aside by reason."""
    problem = replace(milling, cell=_cell())
    st = study(problem, parse_grid_text(OVER_THE_TABLE, base=milling.placement), optimise=False)
    assert st.status is StudyStatus.NO_FEASIBLE
    coll = st.sweep.scores.status == PlacementStatus.COLLISION.code
    foot = _base_on_object(problem, st.sweep.placements)
    tail = _collision_reason(st)
    assert tail == (
        f"; of the {int(coll.sum())} set aside for collision, {int((foot & coll).sum())} have the base "
        f"overlapping an object and {int((coll & ~foot).sum())} every flip-free branch colliding"
    )


def test_without_a_cell_one_line_says_not_checked(milling, tmp_path):
    import contextlib
    import io

    st = study(milling, parse_grid_text(NO_CELL_GRID, base=milling.placement), optimise=False)
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        print_study(st)
    lines = [x for x in buf.getvalue().splitlines() if "collision" in x]
    assert lines == [f"  collisions: {NO_CELL_NOTE}"]  # one line, and no count of a status never checked
    write_study(st, tmp_path / "o")
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["collisions"] == {"checked": False, "note": NO_CELL_NOTE}
    assert s["headline"]["collisions_checked"] is False and s["headline"]["collision_set_aside"] is None
    page = (tmp_path / "o" / "report.html").read_text()
    assert f"Collisions: <b>{html.escape(NO_CELL_NOTE)}</b>" in page
    assert "Collisions were not checked" in page and "smallest clearance" not in page


@pytest.mark.slow
def test_the_command_prints_what_its_files_hold(milling, tmp_path, capsys):
    """``compplan place`` on a problem file with a ``[cell]``: the terminal's counts are those of
    the scores.csv it wrote."""
    from importlib import resources

    text = resources.files("problems").joinpath("files/placement_milling.toml").read_text(encoding="utf-8")
    cell = ["", "[cell]", "clearance = 0.005"]
    for n, s, z, c, r in OBJECTS:
        cell += ["[[cell.objects]]", f'name = "{n}"', f'shape = "{s}"', f"size = {list(z)}", f"xyz = {list(c)}"]
        cell += [f'role = "{r}"'] if r != "obstacle" else []
    f = tmp_path / "cell_milling.toml"
    f.write_text(text + "\n".join(cell) + "\n")
    out = tmp_path / "o"
    argv = ["place", str(f), "--out", str(out), "--grid", GRID, "--no-optimise", "--no-report"]
    assert cli_main(argv) == 0
    printed = capsys.readouterr().out
    status = [r.split(",")[6] for r in (out / "scores.csv").read_text().splitlines()[1:]]
    k = status.count("collision")
    assert k > 0
    assert f"{len(status)} placements checked" in printed
    assert f"collisions: {k} set aside for collision: " in printed
    s = json.loads((out / "summary.json").read_text())
    c = s["collisions"]
    assert f"{c['base_on_object']} with the base overlapping an object, {c['every_branch_colliding']} with" in printed
