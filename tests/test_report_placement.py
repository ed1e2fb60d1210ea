"""The placement study's report (``planner.report.placement``): figures and report.html.

Small grids and analytic postures (``optimise=False``) keep the module fast; the studies are
built once per module.
"""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

from planner.placement import study, write_study
from planner.plan import PlanStatus
from planner.report import placement as rp
from planner.report import placement_plots as pp
from problems.placement.grid import parse_grid_text, placement_label
from problems.problem import load_problem

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: Feasible everywhere but for a corner or two; two yaws.
SMALL = "x_m=-0.4:0.4:3,y_m=-0.6:0.6:3,yaw_deg=0:90:2,top=2"
#: Mostly out of reach (the slot is at x = 0.65 m).
WIDE = "x_m=-1.5:1.5:5,y_m=-1.5:1.5:5,top=1"
#: Nothing reachable.
FAR = "x_m=3:4:2,y_m=3:4:2,top=1"


@pytest.fixture(scope="module")
def problem():
    return load_problem("placement_milling")


def _study(problem, text: str):
    return study(problem, parse_grid_text(text, base=problem.placement), optimise=False)


@pytest.fixture(scope="module")
def small(problem):
    return _study(problem, SMALL)


@pytest.fixture(scope="module")
def wide(problem):
    return _study(problem, WIDE)


def _check_pngs(figs: dict[str, bytes]) -> None:
    assert set(figs) == {rp.ERROR_MAP, rp.MARGINS, rp.PLANS}
    for name, data in figs.items():
        assert data.startswith(PNG_SIGNATURE), name
        assert len(data) > 10_000, name


def _check_html(page: str, st, names) -> None:
    assert page.startswith("<!DOCTYPE html>") and page.rstrip().endswith("</html>")
    for n in names:
        assert f'src="figures/{n}"' in page
    for p in st.plans:
        assert f"<td>{p.label}" in page
    rows = re.findall(r'data-key="ranking\.(\d+)\.rank"', page)
    assert len(rows) == min(rp.RANKING_ROWS, len(st.ranked))


@pytest.mark.slow
def test_figures_and_html(small, capsys):
    figs = rp.figures(small)
    _check_pngs(figs)
    page = rp.html(small, sorted(figs))
    _check_html(page, small, sorted(figs))
    assert small.improvement is not None
    assert f"{small.improvement:.3g}×" in page
    assert placement_label(small.sweep.placements[small.ranked[0]]) in page
    assert "Definitions and frames" in page and "base2cell" in page
    assert capsys.readouterr() == ("", "")  # the library is silent


@pytest.mark.slow
def test_html_escapes_text(small):
    st = dataclasses.replace(small, problem=dataclasses.replace(small.problem, name="<b>slot & co</b>"))
    page = rp.html(st, [rp.ERROR_MAP])
    assert "&lt;b&gt;slot &amp; co&lt;/b&gt;" in page and "<b>slot" not in page


@pytest.mark.slow
def test_infeasible_placements(wide):
    counts = wide.summary()["sweep"]["status_counts"]
    assert counts["unreachable"] > 0 and counts["ok"] > 0
    figs = rp.figures(wide)
    _check_pngs(figs)
    page = rp.html(wide, sorted(figs))
    _check_html(page, wide, sorted(figs))
    assert "<td>unreachable</td>" in page
    assert f'data-key="sweep.status_counts.unreachable" data-value="{counts["unreachable"]}"' in page


@pytest.mark.slow
def test_no_best_plans_renders(small):
    """top = 0: only the problem as written is planned in full."""
    st = dataclasses.replace(
        small, grid=dataclasses.replace(small.grid, top=0), plans=[p for p in small.plans if p.rank is None]
    )
    figs = rp.figures(st)
    _check_pngs(figs)
    page = rp.html(st, sorted(figs))
    _check_html(page, st, sorted(figs))
    assert "no placement was planned in full (top = 0)" in page


@pytest.mark.slow
def test_top_zero_study_renders(problem, tmp_path):
    st = _study(problem, "x_m=-0.4:0.4:2,y_m=-0.6:0.6:2,top=0")
    written = write_study(st, tmp_path / "out")
    assert (tmp_path / "out" / "report.html").is_file()
    for n in (rp.ERROR_MAP, rp.MARGINS, rp.PLANS):
        assert (tmp_path / "out" / "figures" / n).read_bytes().startswith(PNG_SIGNATURE)
    assert written


@pytest.mark.slow
def test_failed_plan_shown_with_reason(small):
    p0 = small.plans[0]
    reason = "posture NLP failed on every branch <at waypoint 3>"
    bad = dataclasses.replace(p0, result=dataclasses.replace(p0.result, status=PlanStatus.SOLVER_FAILED, reason=reason))
    st = dataclasses.replace(small, plans=[bad] + small.plans[1:])
    figs = rp.figures(st)
    _check_pngs(figs)
    page = rp.html(st, sorted(figs))
    assert "failed (solver_failed): posture NLP failed on every branch &lt;at waypoint 3&gt;" in page


@pytest.mark.slow
def test_nothing_feasible(problem):
    st = _study(problem, FAR)
    assert not len(st.ranked) and st.improvement is None
    figs = rp.figures(st)
    _check_pngs(figs)
    page = rp.html(st, sorted(figs))
    assert "No placement of the grid is feasible" in page and "No improvement factor" in page
    assert "the ranking is empty" in page


def _tiled(small, n_yaws: int, step_m: float):
    """``small`` on ``n_yaws`` yaws, the scores of its first yaw repeated, the RMS error of yaw k
    raised by ``k * step_m``."""
    grid = dataclasses.replace(small.grid, axes={**small.grid.axes, "yaw_deg": np.radians(np.linspace(0, 340, n_yaws))})
    sc = small.sweep.scores
    per = len(sc.status) // len(small.grid.axes["yaw_deg"])
    tiled = {}
    for f in dataclasses.fields(sc):
        a = getattr(sc, f.name)[:per]
        tiled[f.name] = np.concatenate([a] * n_yaws)
    tiled["rms_error_m"] = tiled["rms_error_m"] + np.repeat(np.arange(n_yaws) * step_m, per)
    scores = dataclasses.replace(sc, **tiled)
    sweep = dataclasses.replace(small.sweep, placements=grid.placements(), scores=scores)
    ranked = np.flatnonzero(scores.feasible)[np.argsort(scores.rms_error_m[scores.feasible], kind="stable")]
    return dataclasses.replace(
        small, grid=grid, sweep=sweep, ranked=ranked, plans=[p for p in small.plans if p.rank is None]
    )


@pytest.mark.slow
def test_panels_capped(small):
    """More distinct (yaw, z, tilt) maps than MAX_PANELS: the best placement's panel is kept."""
    st = _tiled(small, 18, 1e-4)
    keys = rp._panel_keys(st)
    assert len(rp._yaw_groups(st)) == 18
    assert len(keys) == rp.MAX_PANELS
    assert rp._grid_index(st, int(st.ranked[0]))[:3] in keys
    assert rp.error_map(st).startswith(PNG_SIGNATURE)


@pytest.mark.slow
def test_yaws_with_the_same_map_share_a_panel(small):
    """Yaws whose maps agree to RANK_RESOLUTION_M share one panel titled with all of them; a yaw
    whose map differs gets its own."""
    same = _tiled(small, 4, 0.1 * rp.RANK_RESOLUTION_M)
    groups = rp._yaw_groups(same)
    assert list(groups.values()) == [(0, 1, 2, 3)]
    key = rp._panel_keys(same)[0]
    assert rp._panel_title(same, key, groups[key]) == "yaw 0°, 113.3°, 226.7°, 340° (same map)"
    apart = _tiled(small, 4, 10 * rp.RANK_RESOLUTION_M)
    assert list(rp._yaw_groups(apart).values()) == [(0,), (1,), (2,), (3,)]
    assert rp._panel_title(apart, (0, 1, 0)) == "yaw 113.3°"


def test_every_status_drawn():
    """Unreachable, flip and joint-limit cells each get their own grey and hatch, with a legend entry."""
    x, y = np.linspace(-0.5, 0.5, 6), np.linspace(-0.5, 0.5, 5)
    status = np.zeros((5, 6), dtype=int)
    status[:, 0], status[0, 3:], status[-1, 3:] = 1, 2, 3
    values = np.where(status == 0, 0.5, np.nan)
    frame = pp.MapFrame(x, y, np.array([[0.6, -0.3], [0.6, 0.3]]))
    fig = pp.error_map_figure(
        frame,
        [pp.MapPanel("yaw 0°", values, status, [(1, 0.1, 0.0)])],
        title="t",
        cbar_label="RMS load-induced error, mm",
        counts={1: 5, 2: 3, 3: 3},
        marks_label="1: best",
        baseline_value=0.7,
    )
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert any(lab.startswith("unreachable (5)") for lab in labels)
    assert any(lab.startswith("flips") for lab in labels) and any(lab.startswith("joint limit") for lab in labels)
    assert pp.png(fig).startswith(PNG_SIGNATURE)
