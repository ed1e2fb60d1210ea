"""The placement study's page: ``report.html`` of ``compplan place``.

:func:`html` writes the page that references the figures of :mod:`planner.report.placement`
(``figures/<name>``): the headline (best placement, its error against the problem as written and the
improvement factor, from the sweep and from the full plans; whether collisions were checked and how
many placements were set aside), the full plans, the collisions (``summary.json`` ``collisions``),
the ranking, the sweep, the definitions and frames, on the reports' page base
(:mod:`planner.report.page`).  Numbers in the tables carry ``data-key`` (dotted path into
``summary.json``) and ``data-value`` like the run report's (:mod:`planner.report.table_base`).
Nothing here prints.
"""

from __future__ import annotations

import html as _html
import math
from typing import TYPE_CHECKING, Any
from collections.abc import Sequence


from planner.numbers import format_mm, format_number
from planner.report.page import PAGE_END, page_head, page_text
from planner.report.table_base import Cell
from planner.report.tables import provenance_table
from problems.placement.grid import GRID_AXES, describe_placement, placement_label
from problems.placement.scores import STATUS_REASONS, PlacementStatus

if TYPE_CHECKING:
    from planner.placement_result import PlacementStudy

__all__ = ["DIGITS", "ERROR_MAP", "FIGURE_ORDER", "MARGINS", "PLANS", "RANKING_ROWS", "html"]

#: File names of the figures, in report order.
ERROR_MAP, MARGINS, PLANS = "placement_error_map.png", "placement_margins.png", "placement_plans.png"
FIGURE_ORDER = (ERROR_MAP, MARGINS, PLANS)
#: Rows of the ranking table.
RANKING_ROWS = 10
#: Significant digits of displayed numbers (mm, deg, ratios).
DIGITS = 3
#: Extra CSS of this page (on top of the run report's).
_EXTRA_CSS = """
p.headline{font-size:1.12em;background:#eef5ec;border-left:4px solid #4a9a3a;padding:0.6em 1em;max-width:1100px}
p.warn,div.warn{background:#fff4e0;border-left:4px solid #e0a030;padding:0.5em 1em;max-width:1100px;
  margin-bottom:1em}
td.failed{color:#8a1c1c} dl.defs dt{font-weight:600;margin-top:0.4em} dl.defs dd{margin-left:1.5em;color:#333}
"""


def _esc(v: Any) -> str:
    return _html.escape(str(v))


def _sig(v: Any, digits: int = DIGITS) -> str:
    """Display text of a number (``digits`` significant digits; "n/a" for None or non-finite)."""
    if v is None or isinstance(v, bool) or not isinstance(v, (int, float)):
        return "n/a"
    return format_number(float(v), digits)


def _mm(v: Any) -> str:
    """Display text of a length in mm ("0 (numerical)" below the numerical floor)."""
    if v is None or not isinstance(v, (int, float)) or not math.isfinite(v):
        return "n/a"
    return format_mm(float(v), DIGITS)


def _num(text: str, key: str | None = None, value: Any = None) -> str:
    """A number's table cell; with ``key`` it carries ``data-key``/``data-value`` (path into summary.json)."""
    if key is None or value is None:
        return Cell(text, css="num").html()
    return Cell(text, key, value).html()


def _txt(text: Any) -> str:
    """A text cell."""
    return Cell("n/a" if text is None else str(text)).html()


def _table(header: Sequence[str], rows: Sequence[Sequence[str]], anchor: str = "") -> str:
    """An HTML table of the run report's style; ``rows`` hold rendered ``<td>`` cells."""
    out = [
        f'<table class="summary"{f" id={chr(34)}{anchor}{chr(34)}" if anchor else ""}>',
        "<tr>" + "".join(f"<th>{_esc(h)}</th>" for h in header) + "</tr>",
    ]
    out += ["<tr>" + "".join(r) + "</tr>" for r in rows]
    return "\n".join(out + ["</table>"])


def _factor_text(f: float) -> str:
    if f >= 1.0:
        return f"cuts the RMS load-induced error by {f:.3g}×"
    return (
        f"does not beat the problem as written: its RMS load-induced error is {1.0 / f:.3g}× the "
        "as-written one (the cell origin is not on the grid or is better)"
    )


def _sweep_headline(st: PlacementStudy, s: dict[str, Any]) -> str:
    """The sweep's sentence: best placement vs the problem as written, and the factor (or why none)."""
    base, base_ok = s["baseline"], st.baseline.status_of(0).ok
    base_txt = (
        f"{_mm(base['rms_error_mm'])} mm for the problem as written (x=0, y=0, yaw=0)"
        if base_ok
        else f"the problem as written (x=0, y=0, yaw=0) is infeasible ({base['status_reason']})"
    )
    if not len(st.ranked):
        why = st.reason or "no placement of the grid is feasible"
        return (
            f"No placement of the grid is feasible: {why}. No improvement factor; "
            f"{'RMS error ' + base_txt if base_ok else base_txt}."
        )
    best = s["ranking"][0]
    head = (
        f"Best placement: <b>{_esc(placement_label(st.sweep.placements[st.ranked[0]]))}</b> "
        f"(IK branch {_esc(best['best_branch'])}): RMS load-induced TCP error {_mm(best['rms_error_mm'])} mm"
    )
    if st.improvement is None:
        return f"{head}; no improvement factor: {_esc(base_txt)}."
    return f"{head} against {_esc(base_txt)}: it <b>{_esc(_factor_text(st.improvement))}</b> (sweep)."


def _plans_headline(st: PlacementStudy) -> str:
    """The full plans' sentence: best 1 vs as written, error before compensation (RMS)."""
    best = next((p for p in st.plans if p.rank == 1), None)
    base = next((p for p in st.plans if p.rank is None), None)

    def rms(p: Any) -> float | None:
        v = p.headline().get("error_before_rms_mm") if p is not None and p.result.ok else None
        return float(v) if isinstance(v, (int, float)) else None

    failed = [
        f"the full plan of {p.label} failed ({_esc(p.result.reason or p.result.status.value)})"
        for p in (best, base)
        if p is not None and not p.result.ok
    ]
    if best is None:
        b = rms(base)
        tail = f"; the problem as written: {_mm(b)} mm RMS before compensation" if b is not None else ""
        why = "nothing is feasible" if not len(st.ranked) else f"top = {st.grid.top}"
        return (
            f"Full plans: no placement was planned in full ({why})"
            + tail
            + ("; " + "; ".join(failed) if failed else "")
            + "."
        )
    if failed:
        return "Full plans: " + "; ".join(failed) + "."
    a, b = rms(best), rms(base)
    if a is None or b is None:
        return "Full plans: the RMS error before compensation is missing from a plan's headline."
    f = f", {b / a:.3g}×" if a > 0 else ""
    return (
        f"Full plans (posture optimisation, exact equilibrium): RMS load-induced error before compensation "
        f"{_mm(a)} mm (best 1) against {_mm(b)} mm (as written){f}."
    )


def _plan_row(i: int, p: Any, e: dict[str, Any]) -> list[str]:
    """One row of the full-plans table (``e``: the plan's entry in summary.json)."""
    sw, k = e["sweep"], f"plans.{i}"
    label = p.label if p.rank is None or p.label == f"best {p.rank}" else f"{p.label} (rank {p.rank})"
    row = [
        _txt(label),
        _txt(e["placement_text"]),
        _txt(e["plan"].get("branch") or sw.get("best_branch")),
        _num(_mm(sw.get("rms_error_mm")), f"{k}.sweep.rms_error_mm", sw.get("rms_error_mm")),
        _num(_mm(sw.get("max_error_mm")), f"{k}.sweep.max_error_mm", sw.get("max_error_mm")),
    ]
    if p.result.ok:
        h = e["plan"]
        row += [
            _num(_mm(h.get(n)), f"{k}.plan.{n}", h.get(n))
            for n in ("error_before_max_mm", "error_before_rms_mm", "error_after_max_mm")
        ]
        row.append(_num(_sig(h.get("duration_s"), 4), f"{k}.plan.duration_s", h.get("duration_s")))
    else:
        why = f"failed ({p.result.status.value}): {p.result.reason}"
        row.append(f'<td class="failed" colspan="4">{_esc(why)}</td>')
    row += [
        _num(_sig(sw.get("joint_margin_deg")), f"{k}.sweep.joint_margin_deg", sw.get("joint_margin_deg")),
        _num(_sig(sw.get("singular_margin")), f"{k}.sweep.singular_margin", sw.get("singular_margin")),
    ]
    if "clearance" in e:
        c = e["clearance"] or {}
        d = c.get("min_clearance_mm")
        row.append(_num(_clearance_mm(d), f"{k}.clearance.min_clearance_mm", d))
        row.append(_txt(f"{c['pair']} ({c['where']})" if d is not None else "not recorded"))
    return row


def _clearance_mm(v: Any) -> str:
    """A clearance in mm to 0.1 mm (negative: penetration), "n/a" without one."""
    return "n/a" if v is None or not isinstance(v, (int, float)) or not math.isfinite(v) else f"{v:.1f}"


def _plans_section(st: PlacementStudy, s: dict[str, Any]) -> list[str]:
    header = [
        "plan",
        "placement (cell frame)",
        "IK branch",
        "sweep RMS [mm]",
        "sweep max [mm]",
        "before comp. max [mm]",
        "before comp. RMS [mm]",
        "after comp. max [mm]",
        "duration [s]",
        "joint-limit margin [deg]",
        "singularity margin",
    ]
    with_cell = s["collisions"]["checked"]
    if with_cell:
        header += ["smallest clearance [mm]", "nearest pair (where)"]
    rows = [_plan_row(i, p, e) for i, (p, e) in enumerate(zip(st.plans, s["plans"]))]
    return [
        '<h2 id="plans">Full plans</h2>',
        _table(header, rows, "plans-table"),
        '<p class="note">Sweep columns: the placement kernel (first-order load-induced error at the analytic '
        "postures of the best branch). Plan columns: the full plan (posture optimisation; errors at the exact "
        "deflected equilibrium, before and after exact compensation; duration of the controller's "
        "trajectory). Margins from the sweep."
        + (
            " Clearance: the full plan's cell check, the smaller of the chosen branch's commanded joints at the "
            "waypoints and the controller's trajectory at every sample (negative: penetration).</p>"
            if with_cell
            else "</p>"
        ),
    ]


def _collisions_headline(s: dict[str, Any]) -> str:
    """The headline's collision sentence (HTML)."""
    c = s["collisions"]
    if not c["checked"]:
        return f"Collisions: <b>{_esc(c['note'])}</b>."
    k, n = c["set_aside"], c["placements_checked"]
    text = f"Collisions: checked against the cell; {k:,} of {n:,} placements set aside for collision"
    if k and c["base_on_object"] is not None:
        text += (
            f" ({c['base_on_object']:,} base overlapping an object, {c['every_branch_colliding']:,} every "
            "flip-free branch colliding)"
        )
    b = c["best_plan"]
    cl = None if b is None else b["clearance"]
    if cl is not None and cl["min_clearance_mm"] is not None:
        text += f"; smallest clearance of {b['label']}: {_clearance_mm(cl['min_clearance_mm'])} mm ({cl['pair']})"
    return _esc(text) + "."


def _collisions_section(s: dict[str, Any]) -> list[str]:
    """The collisions: what the sweep checked against the cell, the placements set aside by reason,
    the best placement's smallest clearance in its full plan (``summary.json`` ``collisions``)."""
    c = s["collisions"]
    out = ['<h2 id="collisions">Collisions</h2>']
    if not c["checked"]:
        return out + [
            f'<p class="warn">Collisions were {_esc(c["note"])}: no placement was checked against the robot\'s '
            "surroundings, and a placement close to the path must be checked in the cell's CAD.</p>"
        ]
    k = "collisions"
    rows = [
        [_txt("checked against"), _txt(", ".join(f"{o['name']} ({o['role']}, {o['shape']})" for o in c["objects"]))],
        [_txt("clearance [mm]"), _num(f"{c['clearance_mm']:g}", f"{k}.clearance_mm", c["clearance_mm"])],
        [
            _txt("placements checked"),
            _num(f"{c['placements_checked']:,}", f"{k}.placements_checked", c["placements_checked"]),
        ],
        [_txt("set aside for collision"), _num(f"{c['set_aside']:,}", f"{k}.set_aside", c["set_aside"])],
    ]
    for key, what in (
        ("base_on_object", "of which: the base overlaps an object"),
        ("every_branch_colliding", "of which: every flip-free branch collides along the path"),
    ):
        v = c[key]
        rows.append([_txt(what), _num("n/a" if v is None else f"{v:,}", f"{k}.{key}", v)])
    rows.append(
        [
            _txt("feasible (collision-free along their scored path)"),
            _num(f"{c['feasible']:,}", f"{k}.feasible", c["feasible"]),
        ]
    )
    a = c["as_written"]
    why0 = {
        "base_on_object": "collision: its base overlaps an object",
        "every_branch_colliding": "collision: every flip-free branch collides",
    }
    rows.append(
        [
            _txt("the problem as written (sweep)"),
            _txt(why0.get(a["collision"] or "", (a["status"] or "n/a").replace("_", " "))),
        ]
    )
    rows.append([_txt("colliding pairs"), _txt(c["colliding_pairs_note"])])
    b = c["best_plan"]
    cl = None if b is None else b["clearance"]
    if b is None:
        rows.append([_txt("smallest clearance of the best placement"), _txt("no placement planned in full")])
    else:
        d = None if cl is None else cl["min_clearance_mm"]
        rows.append(
            [
                _txt(f"smallest clearance of {b['label']} ({b['placement_text']}), full plan [mm]"),
                _num(_clearance_mm(d), f"{k}.best_plan.clearance.min_clearance_mm", d),
            ]
        )
        if d is not None:
            rows.append(
                [
                    _txt("its nearest pair, where"),
                    _txt(f"{cl['pair']}, {cl['where']} ({cl['status'].replace('_', ' ')})"),
                ]
            )
    return out + [
        _table(["", "value"], rows, "collisions-table"),
        f'<p class="note">What the sweep checks: {_esc(c["what"])}. Every placement set aside is in scores.csv '
        "(status collision).</p>",
    ]


def _ranking_section(st: PlacementStudy, s: dict[str, Any]) -> list[str]:
    out = ['<h2 id="ranking">Ranking</h2>']
    if not len(st.ranked):
        return out + ['<p class="warn">No feasible placement: the ranking is empty.</p>']
    header = [
        "rank",
        "x [m]",
        "y [m]",
        "z [m]",
        "yaw [deg]",
        "tilt [deg]",
        "IK branch",
        "RMS [mm]",
        "max [mm]",
        "joint-limit margin [deg]",
        "singularity margin",
        "full plan",
    ]
    planned = {p.index: p.label for p in st.plans if p.index is not None}
    rows = []
    for r, e in enumerate(s["ranking"][:RANKING_ROWS]):
        d, k = describe_placement(st.sweep.placements[e["index"]]), f"ranking.{r}"
        rows.append(
            [_num(str(e["rank"]), f"{k}.rank", e["rank"])]
            + [_num(_sig(d[a])) for a in GRID_AXES]
            + [
                _txt(e["best_branch"]),
                _num(_mm(e["rms_error_mm"]), f"{k}.rms_error_mm", e["rms_error_mm"]),
                _num(_mm(e["max_error_mm"]), f"{k}.max_error_mm", e["max_error_mm"]),
                _num(_sig(e["joint_margin_deg"]), f"{k}.joint_margin_deg", e["joint_margin_deg"]),
                _num(_sig(e["singular_margin"]), f"{k}.singular_margin", e["singular_margin"]),
                _txt(planned.get(e["index"], "")),
            ]
        )
    n = len(st.ranked)
    return out + [
        _table(header, rows, "ranking-table"),
        f'<p class="note">Top {len(rows)} of {n} feasible placements, smallest RMS error first '
        "(ties: smaller max error, then larger singularity and joint-limit margins). Placements that "
        "differ only in yaw often tie (joint 1 absorbs a yaw unless a joint limit binds): the full plans "
        "take the best placements at distinct base positions. Every placement: scores.csv; the feasible "
        "ones in order: ranking.csv.</p>",
    ]


def _grid_text(g: dict[str, Any]) -> str:
    """The grid in words: ``x_m -0.4..0.4 (5), ...`` (edge units)."""
    parts = []
    for k in GRID_AXES:
        v = g[k]
        parts.append(f"{k} {_sig(v[0])}..{_sig(v[1])} ({v[2]})" if isinstance(v, list) else f"{k} {_sig(v)}")
    return ", ".join(parts) + f"; top {g['top']}"


def _sweep_section(s: dict[str, Any]) -> list[str]:
    w = s["sweep"]
    facts = [
        ("grid", _grid_text(s["grid"]), None),
        ("placements", f"{w['placements']:,}", "sweep.placements"),
        (
            "poses (placements × waypoints × scanned orientations, each on every branch)",
            f"{w['poses']:,}",
            "sweep.poses",
        ),
        ("poses per second", f"{w['poses_per_second']:,.0f}", "sweep.poses_per_second"),
        ("wall time of scoring [s]", _sig(w["elapsed_s"]), "sweep.elapsed_s"),
        ("scheduler", str(w["scheduler"]), None),
        ("workers", str(w["workers"]), "sweep.workers"),
        ("chunk size [placements]", str(w["chunk_placements"]), "sweep.chunk_placements"),
        ("chunks", str(w["chunks"]), "sweep.chunks"),
        ("model functions", "compiled C" if w["compiled"] else "CasADi virtual machine (no compiler)", None),
    ]
    rows = [[_txt(name), _num(text, key, _lookup(s, key)) if key else _txt(text)] for name, text, key in facts]
    counts = w["status_counts"]
    srows = [
        [
            _txt(st.value.replace("_", " ")),
            _num(str(counts.get(st.value, 0)), f"sweep.status_counts.{st.value}", counts.get(st.value, 0)),
            _txt(
                STATUS_REASONS[st]
                if st is not PlacementStatus.COLLISION or s["collisions"]["checked"]
                else f"{STATUS_REASONS[st]}; {s['collisions']['note']}"
            ),
        ]
        for st in PlacementStatus
    ]
    return [
        '<h2 id="sweep">Sweep</h2>',
        _table(["", "value"], rows, "sweep-table"),
        "<h3>Placements by status</h3>",
        _table(["status", "placements", "meaning"], srows, "status-table"),
    ]


def _lookup(s: dict[str, Any], key: str | None) -> Any:
    """The value at a dotted ``key`` of the summary (None without a key)."""
    if key is None:
        return None
    cur: Any = s
    for part in key.split("."):
        cur = cur[part]
    return cur


def _definitions_section(s: dict[str, Any]) -> list[str]:
    items = "".join(f"<dt>{_esc(k)}</dt><dd>{_esc(v)}</dd>" for k, v in s["definitions"].items())
    return [
        '<h2 id="definitions">Definitions and frames</h2>',
        f'<dl class="defs">{items}</dl>',
        f"<p><b>Frames.</b> {_esc(s['frames'])}. The problem as written is the placement at the cell "
        "origin (x=0, y=0, z=0, yaw=0, tilt=0): the base frame is the cell frame.</p>",
    ]


#: Figure titles and captions by file name.
_CAPTIONS = {
    ERROR_MAP: (
        "RMS load-induced TCP error over the base positions",
        "Each cell is a base position (x, y of the base origin in the cell frame, m) at the panel's yaw "
        "(yaws that give the same map, e.g. on an arm whose joint 1 absorbs the yaw, share one panel); "
        "its colour is the RMS load-induced TCP error (mm) of the best feasible IK branch along the path "
        "as the sweep scores it (darker = smaller error; one colour scale for every panel, the problem "
        "as written marked on the colour bar). Grey hatched cells are infeasible: /// unreachable, "
        "xx flips on every branch, ·· joint limit on every branch, ++ collision (with a [cell]: the base on "
        "an object, or every branch colliding; dashed outlines: the cell's objects seen from above). ☆ the "
        "problem as written (base at the cell origin, yaw 0); numbered circles: the best placements by rank, "
        "on the panel of their yaw; red line: the path's x–y footprint (● start, ▶ end).",
    ),
    MARGINS: (
        "Joint-limit and singularity margins on the best placement's panel",
        "Same cells as the error map, at the yaw (z, tilt) of the rank-1 placement. Left: the smallest "
        "distance of a joint to its limit along the path (deg). Right: the smallest ratio of a singularity "
        "guard factor to its guard bound (1 = at the guard the posture optimisation keeps). Brighter = "
        "more margin.",
    ),
    PLANS: (
        "Full plans: error before compensation and cycle time",
        "The best placements and the problem as written (grey), each planned in full. Left: max and RMS "
        "load-induced TCP error before compensation (exact equilibrium, mm; dashed: RMS as written). "
        "Right: the cycle time of the controller's trajectory (s). A plan that failed shows its reason.",
    ),
}


def _figures_section(names: Sequence[str]) -> list[str]:
    order = [n for n in FIGURE_ORDER if n in names] + [n for n in names if n not in FIGURE_ORDER]
    out = ['<h2 id="figures">Figures</h2>']
    for i, n in enumerate(order, start=1):
        title, cap = _CAPTIONS.get(n, (n, ""))
        out += [
            f'<h3 id="fig-{i}">Figure {i}. {_esc(title)}</h3>',
            f'<figure><img data-figure="{_esc(n)}" alt="{_esc(title)}" src="figures/{_esc(n)}">'
            f'<figcaption>{_esc(cap)} File: <a href="figures/{_esc(n)}">figures/{_esc(n)}</a>.'
            "</figcaption></figure>",
        ]
    return out


def html(study: PlacementStudy, figure_names: list[str], summary: dict[str, Any] | None = None) -> str:
    """``report.html`` of a placement study (figures referenced as ``figures/<name>``).

    Parameters
    ----------
    study : PlacementStudy
    figure_names : list of str
        File names under ``figures/`` (from :func:`figures`).
    summary : dict, optional
        ``study.summary()`` when the caller has it already.

    Returns
    -------
    str
        The page: headline, full plans, collisions, figures, ranking, sweep, definitions and frames.
    """
    st, s = study, study.summary() if summary is None else summary
    title = f"compplan placement study: {s['robot']}, {s['problem']}"
    out = page_head(title, css=_EXTRA_CSS) + [
        f'<p class="{"headline" if st.ok else "warn"}">{_sweep_headline(st, s)}<br>{_plans_headline(st)}'
        f"<br>{_collisions_headline(s)}</p>",
    ]
    warnings = s.get("warnings") or []
    if warnings:
        out.append(
            '<div class="warn"><b>Warnings</b><ul>' + "".join(f"<li>{_esc(w)}</li>" for w in warnings) + "</ul></div>"
        )
    out.append(
        '<nav class="toc"><a href="#plans">Full plans</a> <a href="#collisions">Collisions</a> '
        '<a href="#figures">Figures</a> '
        '<a href="#ranking">Ranking</a> <a href="#sweep">Sweep</a> '
        '<a href="#definitions">Definitions and frames</a> <a href="#provenance">Provenance</a></nav>'
    )
    out += _plans_section(st, s) + _collisions_section(s) + _figures_section(figure_names) + _ranking_section(st, s)
    out += _sweep_section(s) + _definitions_section(s)
    out.append(provenance_table(s).html())
    out.append(
        '<p class="note">Numbers from summary.json (full precision in its data-value attributes); '
        "SI inside, mm and deg in the displays.</p>"
    )
    out.append(PAGE_END)
    return page_text(out)
