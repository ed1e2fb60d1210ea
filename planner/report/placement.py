"""The placement study's report: ``report.html`` and ``figures/*.png`` of ``compplan place``.

:func:`figures` draws, from a :class:`~planner.placement.PlacementStudy` in memory:

* ``placement_error_map.png``: the best branch's RMS load-induced TCP error (mm) over the base
  positions (x, y of the base origin in the cell frame, m), one panel per yaw (and per z, tilt;
  yaws that give the same map share a panel), on one colour scale; infeasible placements hatched by
  status; the problem as written (the cell origin), the best placements (numbered) and the path's x-y
  footprint on every panel;
* ``placement_margins.png``: joint-limit and singularity margins on the rank-1 placement's panel;
* ``placement_plans.png``: the full plans (best 1..N, then as written): TCP error before
  compensation and cycle time.

:func:`html` writes the page that references them (``figures/<name>``): the headline (best
placement, its error against the problem as written and the improvement factor, from the sweep
and from the full plans; whether collisions were checked and how many placements were set aside),
the full plans, the collisions (``summary.json`` ``collisions``), the ranking, the sweep, the
definitions and frames.
Numbers in the tables carry ``data-key`` (dotted path into ``summary.json``) and ``data-value``
like the run report's (:mod:`planner.report.tables`).  The drawing is in
:mod:`planner.report.placement_plots`.  Nothing here prints.
"""

from __future__ import annotations

import html as _html
import math
from typing import TYPE_CHECKING, Any
from collections.abc import Sequence

import numpy as np

from planner.numbers import format_mm, format_number
from planner.report import placement_plots as pp
from planner.report.rendering import _CSS
from planner.report.table_base import Cell
from planner.report.tables import provenance_table
from problems.placement.grid import GRID_AXES, describe_placement, placement_label
from problems.placement.scores import RANK_RESOLUTION_M, STATUS_REASONS, PlacementStatus

if TYPE_CHECKING:
    from planner.placement import PlacementStudy

#: File names of the figures, in report order.
ERROR_MAP, MARGINS, PLANS = "placement_error_map.png", "placement_margins.png", "placement_plans.png"
FIGURE_ORDER = (ERROR_MAP, MARGINS, PLANS)
#: Most panels of the error map (the panels with the best placements and the smallest errors are kept).
MAX_PANELS = 12
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


# --------------------------------------------------------------------------------- figures
def _cube(st: PlacementStudy, values: np.ndarray) -> np.ndarray:
    """Per-placement values (P,) in grid order -> (tilt, yaw, z, y, x)."""
    nx, ny, nz, nyaw, nt = st.grid.shape
    return np.asarray(values).reshape(nt, nyaw, nz, ny, nx)


def _yaw_groups(st: PlacementStudy) -> dict[tuple[int, int, int], tuple[int, ...]]:
    """Error-map panels whose yaws give the same map: ``(tilt, yaw, z)`` of the first of each group
    -> the yaw indices of the group.  Two yaws share a panel when every placement has the same
    status and the same RMS error (to :data:`~problems.placement.scores.RANK_RESOLUTION_M`): on an
    arm whose joint 1 has room a base yaw only turns joint 1."""
    _, _, nz, nyaw, nt = st.grid.shape
    rms = _cube(st, st.sweep.scores.rms_error_m)
    status = _cube(st, st.sweep.scores.status)
    out: dict[tuple[int, int, int], tuple[int, ...]] = {}
    for t in range(nt):
        for z in range(nz):
            left = list(range(nyaw))
            while left:
                w0 = left.pop(0)
                a, sa = rms[t, w0, z], status[t, w0, z]
                same = [
                    w
                    for w in left
                    if np.array_equal(status[t, w, z], sa)
                    and np.array_equal(np.isnan(rms[t, w, z]), np.isnan(a))
                    and bool(np.all(np.abs(np.nan_to_num(rms[t, w, z] - a)) <= RANK_RESOLUTION_M))
                ]
                left = [w for w in left if w not in same]
                out[(t, w0, z)] = (w0, *same)
    return out


def _panel_keys(st: PlacementStudy) -> list[tuple[int, int, int]]:
    """``(tilt, yaw, z)`` indices of the error-map panels (the first yaw of each group of
    :func:`_yaw_groups`), in grid order; at most :data:`MAX_PANELS`: the panels of the marked
    placements first, then those with the smallest errors."""
    groups = _yaw_groups(st)
    keys = sorted(groups, key=lambda k: (k[0], k[2], k[1]))
    if len(keys) <= MAX_PANELS:
        return keys
    rms = _cube(st, st.sweep.scores.rms_error_m)
    best = {k: float(np.nanmin(rms[k])) if np.isfinite(rms[k]).any() else math.inf for k in keys}
    chosen = list(dict.fromkeys(_group_of(groups, _grid_index(st, i)[:3]) for _, i in _marks(st)))
    chosen += [k for k in sorted(keys, key=lambda k: best[k]) if k not in chosen]
    keep = set(chosen[:MAX_PANELS])
    return [k for k in keys if k in keep]


def _group_of(groups: dict[tuple[int, int, int], tuple[int, ...]], key: tuple[int, int, int]) -> tuple[int, int, int]:
    """The panel (first key of its yaw group) that shows ``key``."""
    t, w, z = key
    return next(k for k, ws in groups.items() if k[0] == t and k[2] == z and w in ws)


def _grid_index(st: PlacementStudy, i: int) -> tuple[int, int, int, int, int]:
    """Grid index ``i`` -> ``(tilt, yaw, z, y, x)`` indices."""
    nx, ny, nz, nyaw, nt = st.grid.shape
    t, w, z, y, x = np.unravel_index(i, (nt, nyaw, nz, ny, nx))
    return int(t), int(w), int(z), int(y), int(x)


def _marks(st: PlacementStudy) -> list[tuple[int, int]]:
    """``(number, grid index)`` of the placements the maps number: the ones planned in full
    (``best n`` is ``n``), else the rank-1 placement (none when nothing is feasible)."""
    planned = [(n, int(p.index)) for n, p in enumerate((p for p in st.plans if p.index is not None), start=1)]
    if planned:
        return planned
    return [(1, int(st.ranked[0]))] if len(st.ranked) else []


def _marks_label(st: PlacementStudy) -> str:
    """Legend text of the numbered circles."""
    n = len(_marks(st))
    if not n:
        return ""
    if any(p.index is not None for p in st.plans):
        return (
            f"1..{n}: the best {n} placements (planned in full)" if n > 1 else "1: the best placement (planned in full)"
        )
    return "1: best placement (rank 1; none planned in full)"


def _panel_title(st: PlacementStudy, key: tuple[int, int, int], yaws: Sequence[int] = ()) -> str:
    """``yaw 90°`` (with z and tilt when the grid varies them or they are not 0); with ``yaws``
    (the panel's yaw group) ``yaw 0°, 90°, 180° (same map)``."""
    t, w, z = key
    ax = st.grid.axes
    ws = list(yaws) or [w]
    deg = ", ".join(f"{math.degrees(ax['yaw_deg'][i]):.4g}°" for i in ws)
    parts = [f"yaw {deg}" + (" (same map)" if len(ws) > 1 else "")]
    if len(ax["z_m"]) > 1 or ax["z_m"][z] != 0:
        parts.append(f"z {ax['z_m'][z]:.3g} m")
    if len(ax["tilt_deg"]) > 1 or ax["tilt_deg"][t] != 0:
        parts.append(f"tilt {math.degrees(ax['tilt_deg'][t]):.4g}°")
    return ", ".join(parts)


def _panel(
    st: PlacementStudy, key: tuple[int, int, int], values_si: np.ndarray, scale: float, yaws: Sequence[int] = ()
) -> pp.MapPanel:
    """The map panel ``key`` of per-placement values (SI, times ``scale`` for display); with
    ``yaws`` it stands for those yaws too (their marks are drawn on it)."""
    pl = st.sweep.placements
    t, w, z = key
    shown = {(t, y, z) for y in (yaws or (w,))}
    marks = [(n, float(pl[i, 0]), float(pl[i, 1])) for n, i in _marks(st) if _grid_index(st, i)[:3] in shown]
    return pp.MapPanel(
        _panel_title(st, key, yaws),
        _cube(st, values_si)[key] * scale,
        _cube(st, st.sweep.scores.status)[key].astype(int),
        marks,
    )


def _frame(st: PlacementStudy) -> pp.MapFrame:
    """What the map panels share: grid axes (m), path footprint (cell frame, m), as-written label."""
    b = st.baseline
    if b.status_of(0).ok:
        text = f"as written (x=0, y=0, yaw=0): {format_mm(float(b.rms_error_m[0] * 1e3), DIGITS)} mm RMS"
    else:
        text = f"as written (x=0, y=0, yaw=0): {b.status_of(0).value.replace('_', ' ')}"
    return pp.MapFrame(
        np.asarray(st.grid.axes["x_m"], float),
        np.asarray(st.grid.axes["y_m"], float),
        np.asarray(st.problem.positions, float)[:, :2],
        text,
        _object_outlines(st.problem.cell),
    )


#: Points on a cylinder's or sphere's circle when its footprint is drawn.
OUTLINE_CIRCLE_POINTS = 48


def _object_outlines(cell: Any) -> tuple[tuple[str, str, np.ndarray], ...]:
    """Each object's x-y footprint in the cell frame (the convex hull of its points seen from
    above: a box's corners, a cylinder's end circles, a sphere's equator, a mesh's vertices), m."""
    if cell is None:
        return ()
    from scipy.spatial import ConvexHull

    a = np.linspace(0.0, 2.0 * np.pi, OUTLINE_CIRCLE_POINTS, endpoint=False)
    ring = np.column_stack([np.cos(a), np.sin(a)])
    out = []
    for o in cell.objects:
        s = np.asarray(o.size, float)
        if o.shape == "box":
            pts = 0.5 * s * np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)
        elif o.shape == "cylinder":
            pts = np.vstack([np.column_stack([s[0] * ring, np.full(len(a), z)]) for z in (-0.5 * s[1], 0.5 * s[1])])
        elif o.shape == "sphere":
            pts = np.vstack([np.column_stack([s[0] * ring, np.zeros(len(a))]), [[0, 0, s[0]], [0, 0, -s[0]]]])
        else:
            pts = np.asarray(o.mesh.vertices, float)
        xy = (pts @ o.object2base[:3, :3].T + o.object2base[:3, 3])[:, :2]
        if o.shape == "sphere":  # a sphere seen from above is its equator's circle about its centre
            xy = o.object2base[:2, 3] + s[0] * ring
        hull = xy[ConvexHull(xy).vertices]
        out.append((o.name, o.role, np.vstack([hull, hull[:1]])))
    return tuple(out)


def _counts(st: PlacementStudy) -> dict[int, int]:
    """Placements per status code over the whole grid."""
    s = st.sweep.scores.status
    return {c.code: int((s == c.code).sum()) for c in PlacementStatus}


def _feasible_text(st: PlacementStudy) -> str:
    n, ok = len(st.sweep.placements), int(st.sweep.scores.feasible.sum())
    return f"{ok} of {n} placements feasible"


def error_map(st: PlacementStudy) -> bytes:
    """``placement_error_map.png`` (see the module docstring)."""
    groups = _yaw_groups(st)
    keys = _panel_keys(st)
    panels = [_panel(st, k, st.sweep.scores.rms_error_m, 1e3, groups[k]) for k in keys]
    title = (
        f"{st.problem.robot.name}, {st.problem.name}: RMS load-induced TCP error of the best IK branch "
        f"against the base position (cell frame)\n{_feasible_text(st)}"
    )
    if len(keys) < len(groups):
        title += (
            f"; {len(keys)} of {len(groups)} (yaw, z, tilt) maps shown (those with the best placements "
            "and the smallest errors; all in scores.csv)"
        )
    base = st.baseline
    bval = float(base.rms_error_m[0] * 1e3) if base.status_of(0).ok else None
    fig = pp.error_map_figure(
        _frame(st),
        panels,
        title=title,
        cbar_label="RMS load-induced error, mm",
        counts=_counts(st),
        marks_label=_marks_label(st),
        baseline_value=bval,
    )
    return pp.png(fig)


def margins_map(st: PlacementStudy) -> bytes:
    """``placement_margins.png``: the margins on the rank-1 placement's (yaw, z, tilt) panel."""
    key = _grid_index(st, int(st.ranked[0]))[:3] if len(st.ranked) else (0, 0, 0)
    sc = st.sweep.scores
    joint = _panel(st, key, sc.joint_margin_rad, 180.0 / math.pi)
    sing = _panel(st, key, sc.singular_margin, 1.0)
    joint.title, sing.title = "joint-limit margin", "singularity margin"
    which = "the rank-1 placement's panel" if len(st.ranked) else "no feasible placement"
    title = (
        f"Margins of the best IK branch against the base position, {_panel_title(st, key)} ({which})\n"
        "joint-limit margin: closest approach of a joint to its limit along the path; "
        "singularity margin: smallest guard factor / guard bound"
    )
    fig = pp.margin_map_figure(
        _frame(st), joint, sing, title=title, counts=_counts(st), marks_label=_marks_label(st) if joint.marks else ""
    )
    return pp.png(fig)


def _plan_bar(p: Any) -> pp.PlanBar:
    """A :class:`~planner.placement.PlacementPlan` as a bar of figure 3."""
    text = placement_label(p.placement)
    if not p.result.ok:
        return pp.PlanBar(p.label, text, failed=str(p.result.reason or p.result.status.value), baseline=p.rank is None)
    h = p.headline()

    def num(k: str) -> float | None:
        v = h.get(k)
        return float(v) if isinstance(v, (int, float)) and math.isfinite(v) else None

    return pp.PlanBar(
        p.label,
        text,
        num("error_before_max_mm"),
        num("error_before_rms_mm"),
        num("duration_s"),
        baseline=p.rank is None,
    )


def plans_chart(st: PlacementStudy) -> bytes:
    """``placement_plans.png``: the full plans' errors before compensation and cycle times."""
    bars = [_plan_bar(p) for p in st.plans]
    n = sum(p.rank is not None for p in st.plans)
    title = (
        f"Full plans (posture optimisation, exact equilibrium, timing) of the best {n} "
        f"placement{'s' if n > 1 else ''} and of the problem as written"
        if n
        else "Full plan (posture optimisation, exact equilibrium, timing) of the problem as written "
        "(no placement planned in full: top = 0 or nothing feasible)"
    )
    if not bars:
        bars = [pp.PlanBar("no plan", "", failed="no placement was planned in full")]
    return pp.png(pp.plans_figure(bars, title=title))


def figures(study: PlacementStudy) -> dict[str, bytes]:
    """The report's figures as PNG bytes, keyed by file name (written under ``figures/``).

    Parameters
    ----------
    study : PlacementStudy

    Returns
    -------
    dict str -> bytes
        :data:`ERROR_MAP`, :data:`MARGINS` and :data:`PLANS`.
    """
    return {ERROR_MAP: error_map(study), MARGINS: margins_map(study), PLANS: plans_chart(study)}


# ------------------------------------------------------------------------------------ HTML
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
    out = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>{_esc(title)}</title><style>{_CSS}{_EXTRA_CSS}</style></head><body>",
        f"<h1>{_esc(title)}</h1>",
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
    out.append("</body></html>")
    return "\n".join(out) + "\n"


__all__ = [
    "ERROR_MAP",
    "FIGURE_ORDER",
    "MARGINS",
    "MAX_PANELS",
    "PLANS",
    "error_map",
    "figures",
    "html",
    "margins_map",
    "plans_chart",
]
