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

:func:`html` (:mod:`planner.report.placement_page`) writes the page that references them
(``figures/<name>``).  The drawing is in :mod:`planner.report.placement_plots`.  Nothing here prints.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any
from collections.abc import Sequence

import numpy as np

from planner.numbers import format_mm
from planner.report import placement_plots as pp
from planner.report.placement_page import DIGITS, ERROR_MAP, FIGURE_ORDER, MARGINS, PLANS, RANKING_ROWS, html
from problems.placement.grid import placement_label
from problems.placement.scores import RANK_RESOLUTION_M, PlacementStatus

if TYPE_CHECKING:
    from planner.placement_result import PlacementStudy

__all__ = [
    "ERROR_MAP",
    "FIGURE_ORDER",
    "MARGINS",
    "MAX_PANELS",
    "PLANS",
    "RANKING_ROWS",
    "error_map",
    "figures",
    "html",
]

#: Most panels of the error map (the panels with the best placements and the smallest errors are kept).
MAX_PANELS = 12


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


def _object_outlines(cell: Any) -> tuple[tuple[str, str, np.ndarray], ...]:
    """Each object's x-y footprint in the cell frame (the convex hull of its shape's
    :meth:`~models.collision.shapes.Shape.outline_xy`: a box's corners, a cylinder's end circles, a
    sphere's equator, a mesh's vertices), m."""
    if cell is None:
        return ()
    from scipy.spatial import ConvexHull

    out = []
    for o in cell.objects:
        xy = o.form.outline_xy(o.object2base)
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
