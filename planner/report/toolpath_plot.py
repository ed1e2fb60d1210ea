"""The report's program figures: the toolpath coloured by the TCP error, and the feed along the
program.

Drawn only for a run whose path is a CAM program (``summary.json`` key ``program``; a line path
has neither figure, not an absent one), from the run's :class:`~planner.record.ProgramRecord`
(``RunRecord.program``), its waypoint table and the controller's trajectory:

* :data:`TOOLPATH_FIGURE`: the programmed path in the program (workpiece) frame, mm, seen along the
  program axis it extends least along (Z for a 3-axis program: the XY view), coloured by the
  load-induced TCP error before compensation (left) and the residual after exact compensation
  (right), µm (mm for errors of 1 mm or more); rapids thin grey dashed.  More than
  :data:`~planner.report.toolpath.MAX_DRAWN_SEGMENTS` moves are merged into chords for drawing
  (the caption says so and by how much).
* :data:`FEED_FIGURE`: the TCP speed the controller's trajectory reaches (forward kinematics of
  its sampled joints) against the programmed feed of the line each sample runs, mm/min, over time,
  with the program line below; the slowed lines of the summary in two colours, those a joint limit
  holds down (``slowed_by_limit``; the slowest named with the joint and derivative) and those slowed
  only by their neighbours, a stop or a held line (one colour for a summary written before that split).  Long
  trajectories are drawn as the minimum and maximum over
  :data:`~planner.report.toolpath.FEED_BINS` bins; :mod:`planner.report.feed_plot` draws it.

The arrays are prepared (and reduced) in :func:`program_items`, so a figure job stays small; the
drawing functions take SI arrays and convert at the edge.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import PurePath
from typing import Any

import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from problems.toolpath.feed import FEED_SLOW_TOL

from planner.numbers import NUMERICAL_FLOOR_M, format_number, mm_text
from planner.report.feed_plot import SLOWED_STYLE, feed_figure
from planner.report.figure_base import new_figure, styled
from planner.report.rendering import FigureItem, job
from planner.record import RunRecord, method_name
from planner.report.tables import load_words
from planner.report.toolpath import (
    MAX_DRAWN_SEGMENTS,
    PROGRAM_KEY,
    bin_extrema,
    sample_feed_m_s,
    merge_segments,
    rapid_move_count,
    slowed_by_limit_worst_first,
    slowed_line_text,
    slowed_lines_worst_first,
    tcp_speed_m_s,
    view_axes,
)

__all__ = [
    "FEED_FIGURE",
    "PROGRAM_FIGURES",
    "TOOLPATH_FIGURE",
    "program_items",
]

#: File names of the program figures (fixed, like figure 8's, whichever optional figures a run has).
TOOLPATH_FIGURE = "fig9_toolpath"
FEED_FIGURE = "fig10_feed"
PROGRAM_FIGURES = (TOOLPATH_FIGURE, FEED_FIGURE)
#: Slowed lines named on the feed figure (slowest first; :mod:`planner.report.feed_plot` draws the labels).
FEED_MARKED = 5
_AXES = "XYZ"


# ---------------------------------------------------------------------------------- the items
def program_items(run: RunRecord) -> list[FigureItem]:
    """The program figures of ``run`` (toolpath, feed), in report order; none unless its path is
    a program (``summary.json`` key ``program``)."""
    if not isinstance(run.summary.get(PROGRAM_KEY), Mapping):
        return []
    return [_toolpath_item(run), _feed_item(run)]


def _no_program(run: RunRecord) -> str:
    return run.absent.get(PROGRAM_KEY, "program path: the program's waypoints are not available in this run")


def _norms(wp: Mapping[str, np.ndarray], prefix: str) -> np.ndarray:
    return np.linalg.norm(np.column_stack([wp[f"{prefix}{a}"] for a in "xyz"]), axis=1)


def _header(run: RunRecord) -> str:
    s = run.summary
    prog = s.get(PROGRAM_KEY) or {}
    branch = s.get("chosen_branch", s.get("branch", "?"))
    name = PurePath(str(prog.get("file", "?"))).name  # (a built-in problem's program has a long absolute path)
    return f"{s.get('robot', '?')}, branch {branch}: program {name}; load: {load_words(s)}"


def _toolpath_item(run: RunRecord) -> FigureItem:
    item = FigureItem(
        TOOLPATH_FIGURE,
        "Toolpath: TCP error before and after compensation",
        "",
    )
    view, wp = run.program, run.waypoints
    if view is None:
        item.absent = _no_program(run)
        return item
    if wp is None or len(wp["k"]) != view.n:
        item.absent = run.absent.get("waypoints") or (
            f"program path: waypoints.csv has {0 if wp is None else len(wp['k'])} rows, the program {view.n} "
            "waypoints: the toolpath is not drawn"
        )
        return item
    a, b, normal = view_axes(view.points_m, view.rapid)
    errors = np.column_stack([_norms(wp, "eb"), _norms(wp, "ee")])
    segs, vals, rap, tol = merge_segments(view.points_m[:, [a, b]], errors, view.rapid)
    n_moves = view.n - 1
    plane = f"{_AXES[a]}{_AXES[b]}"
    item.caption = (
        f"The programmed path in the program (workpiece) frame, mm, seen along the program's {_AXES[normal]} axis "
        f"(the {plane} view: the axis the cutting moves extend least along), coloured by the norm of the "
        "load-induced TCP position error at each waypoint's exact deflected equilibrium: (a) before "
        "compensation (the chosen posture commanded as is), (b) the residual after exact compensation; each "
        "move carries the larger error of its two ends, in µm (mm for errors of 1 mm or more; each panel "
        "has its own colour bar). Rapids: thin grey dashed (a move along the view axis, a plunge or a retract, "
        "is a point in this view). ● start, ▶ end. The errors are the waypoint table's (waypoints.csv eb*, ee*, "
        "base frame; a norm is the same in any frame)."
    )
    if tol > 0:
        item.caption += (
            f" Decimated for drawing: {len(segs)} chords for the {n_moves} moves (more than {MAX_DRAWN_SEGMENTS}), "
            f"a waypoint kept where the path enters another {format_number(tol * 1e3, 3)} mm square of the "
            f"drawing plane (every waypoint left out lies within {format_number(tol * 1e3 * 2**0.5, 3)} mm of its "
            "chord), each chord coloured by the largest error of the moves it replaces."
        )
    eb_max, ee_max = float(np.nanmax(errors[:, 0])), float(np.nanmax(errors[:, 1]))
    n_rapid = rapid_move_count(view)
    title = _header(run) + (
        f"\n{view.n} waypoints, {n_rapid} rapid move{'' if n_rapid == 1 else 's'} (G0); "
        f"max TCP error {mm_text(eb_max * 1e3)} before, {mm_text(ee_max * 1e3)} after exact compensation"
    )
    item.job = job(
        toolpath_figure,
        segs,
        vals,
        rap,
        (_AXES[a], _AXES[b]),
        title=title,
        start_end=view.points_m[[0, -1]][:, [a, b]],
    )
    return item


def _feed_item(run: RunRecord) -> FigureItem:
    s = run.summary
    item = FigureItem(FEED_FIGURE, "Feed along the program: TCP speed against the programmed feed", "")
    ctrl = s.get("controller_trajectory")
    view = run.program
    if view is None:
        item.absent = _no_program(run)
        return item
    tr = run.trajectories.get(ctrl) if isinstance(ctrl, str) else None
    if tr is None:
        item.absent = run.absent.get("trajectory", "no controller trajectory in this run: the feed is not drawn")
        return item
    lines = view.sample_line.get(ctrl)
    wps = view.sample_waypoint.get(ctrl)
    fname = run.trajectory_files.get(ctrl, "trajectory.csv")
    if lines is None or wps is None or len(lines) != len(tr["t"]) or len(wps) != len(tr["t"]):
        item.absent = (
            f"program path: {fname} has no program line and waypoint per sample (no 'line' and 'waypoint' "
            "columns: a motor-side command of the dynamic compensation, or a run written before): the feed is "
            "not drawn"
        )
        return item
    if run.model is None:
        item.absent = (
            f"program path: the TCP speed needs the run's arm model "
            f"({run.absent.get('model') or run.absent.get('robot') or 'not available'})"
        )
        return item
    t = np.asarray(tr["t"], float)
    speed = tcp_speed_m_s(run.model.kinematics.tcp, t, np.asarray(tr["q"], float))
    feed = sample_feed_m_s(view, wps)
    entry = ((s.get(PROGRAM_KEY) or {}).get("feed") or {}).get(ctrl) or {}
    groups = _slowed_groups(entry)
    masks = [np.isin(lines, np.array(group, dtype=int)) for _, group, _ in groups]
    slowed = np.logical_or.reduce(masks) if masks else np.zeros(len(t), bool)
    rapid = ~np.isfinite(feed)
    starts = bin_extrema(speed)[0]
    ends = np.r_[starts[1:], len(t)] - 1
    speed_bands = [  # per kind of sample: the smallest and largest speed of each bin (NaN: none of that kind)
        bin_extrema(np.where(mask, speed, np.nan))[1:] for mask in [~rapid & ~slowed, *masks, rapid & ~slowed]
    ]
    line_f = lines.astype(float)
    line_bands = [bin_extrema(np.where(mask, line_f, np.nan))[1:] for mask in [~slowed, *masks]]
    f_hi = bin_extrema(feed)[2]
    slow_bins = [np.logical_or.reduceat(mask, starts) if len(t) else np.zeros(0, bool) for mask in masks]
    marks = _feed_marks(groups, lines, t, feed)
    cut = np.isfinite(feed) & (feed > 0)
    measured = float(np.max(speed[cut] / feed[cut])) if cut.any() else float("nan")
    per_bin = int(np.ceil(len(t) / max(len(starts), 1)))
    name = method_name(s, ctrl)
    counts = {kind: len(group) for kind, group, _ in groups}
    item.caption = _feed_caption(name, fname, counts, len(marks), len(t), len(starts), per_bin)
    item.job = job(
        feed_figure,
        t[starts],
        t[ends],
        speed_bands,
        f_hi,
        tuple(kind for kind, _, _ in groups),
        slow_bins,
        line_bands,
        marks,
        title=_header(run) + "\n" + _feed_head(name, entry, counts, measured),
    )
    return item


def _slowed_groups(entry: Mapping[str, Any]) -> list[tuple[str, list[int], list[tuple[int, float, str]]]]:
    """The slowed lines of a feed entry by kind (:data:`~planner.report.toolpath.SLOWED_KINDS`):
    ``(kind, its lines, the lines to name as (line, fraction of F, label), slowest first)``.

    With ``slowed_by_limit`` (newer summaries): the lines a joint limit holds down, named with the
    joint and derivative, and the lines slowed only by their neighbours (not named: the slow-down
    comes from a stop or a held line nearby); without it, every slowed line, named with its
    fraction."""
    worst = slowed_lines_worst_first(entry)
    by_limit = slowed_by_limit_worst_first(entry)
    if by_limit is None:
        return [("slowed", [L for L, _ in worst], [(L, f, slowed_line_text(L, f)) for L, f in worst[:FEED_MARKED]])]
    held = {row[0] for row in by_limit}
    named = [(L, f, slowed_line_text(L, f, j, d)) for L, f, j, d in by_limit[:FEED_MARKED]]
    return [("limit", [row[0] for row in by_limit], named), ("stops", [L for L, _ in worst if L not in held], [])]


def _feed_marks(
    groups: Sequence[tuple[str, list[int], list[tuple[int, float, str]]]],
    lines: np.ndarray,
    t: np.ndarray,
    feed: np.ndarray,
) -> list[tuple[float, str, float, float, str]]:
    """The slowest lines to name on the feed figure: (time at the line's middle s, label, F m/s,
    the line's peak speed over F, kind)."""
    marks = []
    for kind, _, named in groups:
        for L, frac, label in named:
            idx = np.flatnonzero(lines == L)
            if idx.size:  # named at the middle of the line's time
                marks.append((0.5 * float(t[idx[0]] + t[idx[-1]]), label, float(feed[idx[0]]), frac, kind))
    return marks


def _feed_caption(
    name: str, fname: str, counts: Mapping[str, int], n_marked: int, n_samples: int, n_bins: int, per_bin: int
) -> str:
    """The feed figure's caption: what is drawn, what each colour means and how many lines of each kind."""
    pct = format_number(100.0 * (1.0 - FEED_SLOW_TOL))
    below = f"peak TCP speed below {pct} % of F"
    caption = (
        f"The controller's trajectory ({name}, {fname}): (a) the TCP speed it reaches, from forward kinematics "
        "of its sampled joint commands (the arm model's rigid kinematics; |Δp|/Δt between samples), against the "
        "programmed feed F of the program line each sample runs (dashed; the largest F of the line's cutting "
        "moves; none on rapids), mm/min, over time; (b) that program line. Blue in (a), dark grey in (b): the "
        f"lines whose peak TCP speed reaches {pct} % of F. "
    )
    measure = "(the peak speed on the line's slowest move, % of F: a move starting or ending at a stop counts)"
    if "limit" in counts:
        n_lim, n_stop = counts["limit"], counts["stops"]
        named = (
            f"the {n_marked} slowest named with the summary's measure {measure} and the joint (Jn) and derivative "
            "(velocity, acceleration or jerk) that binds; "
            if n_marked
            else ""
        )
        caption += (
            f"The summary's slowed lines ({below}), by cause: {_colour('limit')}, the {n_lim} line{_plural(n_lim)} "
            "a joint limit holds down (the joints cannot cruise at F there; summary.json slowed_by_limit), "
            f"{named}{_colour('stops')}, the {n_stop} line{_plural(n_stop)} slowed only by their neighbours "
            "(no limit binds on them: the accelerations out of or into a stop, or into or out of a neighbouring line "
            "a limit holds down, reach into them; summary.json n_lines_slowed_by_neighbours; not named). "
        )
    else:
        n = counts.get("slowed", 0)
        caption += (
            f"{_colour('slowed').capitalize()}: the {n} program line{_plural(n)} the summary lists as slowed "
            f"({below}: the joint limits, or the stops around them, keep the feed down; this summary does not "
            f"tell the two apart), the {n_marked} slowest named with the summary's measure {measure}. "
        )
    caption += "Grey in (a): rapids."
    if per_bin > 1:
        caption += (
            f" {n_samples} samples drawn as {n_bins} bins of {per_bin}: each bin's band spans its smallest to "
            "largest speed (the line is the largest), so no peak and no slow-down is hidden."
        )
    return caption


def _colour(kind: str) -> str:
    """The colour of a kind of slowed line, in words."""
    return SLOWED_STYLE[kind][1]


def _plural(n: int) -> str:
    return "" if n == 1 else "s"


def _feed_head(name: str, entry: Mapping[str, Any], counts: Mapping[str, int], measured: float) -> str:
    """The feed figure's second and third title lines: duration against the programmed time, peak
    speed / F; the slowed lines by kind."""
    prog_t, dur = entry.get("programmed_time_s"), entry.get("duration_s")
    head = f"{name}: duration {format_number(float(dur))} s" if isinstance(dur, (int, float)) else name
    if isinstance(prog_t, (int, float)) and isinstance(dur, (int, float)) and prog_t > 0:
        head += f" against {format_number(float(prog_t))} s programmed (×{format_number(float(dur) / float(prog_t))})"
    if np.isfinite(measured):
        head += f"; peak TCP speed / F on cutting moves {measured:.3f} (forward kinematics)"
    n = sum(counts.values())
    head += f"\n{n} slowed line{_plural(n)}"
    if "limit" in counts:
        head += (
            f": {counts['limit']} held down by a joint limit ({_colour('limit')}), {counts['stops']} slowed only by "
            f"their neighbours, a stop or a held line ({_colour('stops')})"
        )
    return head


# ------------------------------------------------------------------------------- the drawings
def _error_unit(values_m: np.ndarray) -> tuple[str, float]:
    """µm, or mm when the largest error reaches 1 mm; (name, factor m -> unit)."""
    finite = np.asarray(values_m, float)
    finite = finite[np.isfinite(finite)]
    peak = float(finite.max()) if finite.size else 0.0
    return ("mm", 1e3) if peak >= 1e-3 else ("µm", 1e6)


def _path_panel(
    fig: Figure, ax: Any, cax: Any, segs_mm: np.ndarray, vals: np.ndarray, rapid: np.ndarray, label: str
) -> None:
    """One panel of the toolpath figure: cutting moves coloured by ``vals`` (m), rapids grey dashed."""
    unit, k = _error_unit(vals)
    v = np.asarray(vals, float) * k
    cut = ~rapid
    finite = v[cut & np.isfinite(v)]
    floor = NUMERICAL_FLOOR_M * k
    below = finite.size > 0 and float(finite.max()) < floor
    lo, hi = (0.0, float(finite.max())) if finite.size else (0.0, 1.0)
    if below or hi <= lo:
        hi = max(hi, floor, 1e-300)
    lw = 1.4 if len(segs_mm) <= 2000 else (1.0 if len(segs_mm) <= 12000 else 0.7)
    cmap = "viridis"
    lc = LineCollection(segs_mm[cut], linewidths=lw, cmap=cmap, norm=Normalize(lo, hi), zorder=2)
    lc.set_array(np.zeros(int(cut.sum())) if below else v[cut])
    ax.add_collection(lc)
    if rapid.any():
        ax.add_collection(
            LineCollection(segs_mm[rapid], colors="0.5", linewidths=0.6, linestyles=(0, (3, 3)), zorder=1)
        )
    cb = fig.colorbar(lc, cax=cax)
    cb.set_label(f"{label} [{unit}]")
    cb.formatter.set_useOffset(False)
    cb.update_ticks()
    if below:
        peak = float(finite.max())
        ax.text(
            0.5,
            0.5,
            "0 (numerical) everywhere:\n"
            + (f"largest {format_number(peak, 3)} {unit},\n" if peak > 0 else "exactly 0,\n")
            + f"below the numerical\nfloor {format_number(floor)} {unit}",
            transform=ax.transAxes,
            ha="center",
            va="center",
            fontsize=8,
            bbox={"facecolor": "white", "alpha": 0.9, "edgecolor": "0.5"},
            zorder=8,
        )


#: A panel shows the path at equal scale unless its width over height would pass this (or its
#: inverse): then the shorter axis is stretched to it, and the panel says by how much.
MAX_PANEL_RATIO = 6.0
MIN_PANEL_RATIO = 0.33
#: A path at least this much wider than tall gets its panels one above the other.
STACK_RATIO = 1.5


@styled
def toolpath_figure(
    segments_m: np.ndarray,
    values_m: np.ndarray,
    rapid: np.ndarray,
    axis_names: Sequence[str],
    *,
    title: str,
    start_end: np.ndarray | None = None,
) -> Figure:
    """The toolpath in the program frame (mm) in two panels: coloured by the TCP error before
    compensation and by the residual after exact compensation.

    The panels are side by side, or one above the other for a path at least
    :data:`STACK_RATIO` times wider than tall; the scale is equal on both axes unless the path is
    more elongated than :data:`MAX_PANEL_RATIO` (:data:`MIN_PANEL_RATIO` side by side), when the
    shorter axis is stretched and the panel title says by how much.

    Parameters
    ----------
    segments_m : np.ndarray
        Shape ``(S, 2, 2)``, m: start and end of each drawn move (or chord) in the drawing plane.
    values_m : np.ndarray
        Shape ``(S, 2)``, m: the TCP error norm of each segment before compensation and after exact
        compensation.
    rapid : np.ndarray
        Shape ``(S,)``, bool: the segment is a rapid (drawn thin grey dashed, not coloured).
    axis_names : two str
        The program axes drawn (horizontal, vertical).
    title : str
    start_end : np.ndarray, optional
        Shape ``(2, 2)``, m: the first and last waypoint (marked ● and ▶).
    """
    segs = np.asarray(segments_m, float) * 1e3
    vals = np.asarray(values_m, float)
    rap = np.asarray(rapid, bool)
    pts = segs.reshape(-1, 2) if len(segs) else np.zeros((1, 2))
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = 0.03 * max(float(np.max(hi - lo)), 1e-3)
    lo, hi = lo - pad, hi + pad
    ratio = float((hi[0] - lo[0]) / (hi[1] - lo[1]))  # width / height of the data
    stacked = ratio >= STACK_RATIO
    shown = min(ratio, MAX_PANEL_RATIO) if stacked else max(ratio, MIN_PANEL_RATIO)
    stretch = ratio / shown  # display length of a vertical mm over a horizontal one
    W, H, pw, ph, boxes = _panel_boxes(shown, stacked)
    fig = new_figure(W, H)
    axes: list[Any] = []
    caxes: list[Any] = []
    for bx, by in boxes:
        axes.append(fig.add_axes((bx / W, by / H, pw / W, ph / H), sharex=axes[0] if axes else None))
        caxes.append(fig.add_axes(((bx + pw + 0.12) / W, by / H, 0.17 / W, ph / H)))
    x_note, y_note = _stretch_notes(stretch)
    sep = "\n" if pw < 3.3 else " "
    labels = (f"TCP error{sep}before compensation", f"residual after{sep}exact compensation")
    for i, (ax, label) in enumerate(zip(axes, labels)):
        _path_panel(fig, ax, caxes[i], segs, vals[:, i], rap, ("before", "residual")[i])
        ax.set_title(f"({'ab'[i]}) {label}", loc="left")
        ax.set_ylabel(f"program {axis_names[1]} [mm{y_note}]")
        ax.grid(alpha=0.25, zorder=0)
        if start_end is not None:
            se = np.asarray(start_end, float) * 1e3
            ax.plot(*se[0], marker="o", color="crimson", mec="white", ms=6, ls="none", zorder=5)
            ax.plot(*se[1], marker=">", color="crimson", mec="white", ms=6, ls="none", zorder=5)
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
    for ax in axes if not stacked else axes[1:]:
        ax.set_xlabel(f"program {axis_names[0]} [mm{x_note}]")
    if stacked:
        axes[0].tick_params(labelbottom=False)
    fig.legend(handles=_toolpath_handles(), loc="lower center", ncol=3, frameon=False, bbox_to_anchor=(0.5, 0.0))
    fig.suptitle(title)
    return fig


def _panel_boxes(shown: float, stacked: bool) -> tuple[float, float, float, float, list[tuple[float, float]]]:
    """The toolpath figure laid out by hand, in inches, so that each panel's box has the drawn
    width/height ratio ``shown`` exactly: (figure width, height, panel width, height, lower-left
    corner of each panel)."""
    W, left, cbar_room, gap, top_room, bottom_room = 12.0, 0.85, 1.25, 0.25, 1.05, 0.9
    if stacked:
        ph = min((W - left - cbar_room) / shown, 4.2)
        pw = ph * shown
        H = top_room + 2.0 * ph + 0.6 + bottom_room
        x0 = left + (W - left - cbar_room - pw) / 2.0
        boxes = [(x0, bottom_room + ph + 0.6), (x0, bottom_room)]
    else:
        ph = min((W - left - 2.0 * cbar_room - gap) / 2.0 / shown, 6.0)
        pw = ph * shown
        H = top_room + 0.15 + ph + bottom_room
        x0 = left + (W - (left + 2.0 * (pw + cbar_room) + gap)) / 2.0  # centred
        boxes = [(x0, bottom_room), (x0 + pw + cbar_room + gap, bottom_room)]
    return W, H, pw, ph, boxes


def _stretch_notes(stretch: float) -> tuple[str, str]:
    """The axis-label notes (x, y) saying by how much the shorter axis is stretched."""
    x_note = y_note = ""
    if stretch > 1.0 + 1e-9:
        y_note = f", drawn ×{format_number(stretch, 3)}"
    elif stretch < 1.0 - 1e-9:
        x_note = f", drawn ×{format_number(1.0 / stretch, 3)}"
    return x_note, y_note


def _toolpath_handles() -> list[Line2D]:
    """The toolpath figure's legend entries: rapid, start, end."""
    return [
        Line2D([], [], color="0.5", lw=0.8, ls=(0, (3, 3)), label="rapid"),
        Line2D([], [], marker="o", color="crimson", mec="white", ls="none", label="start"),
        Line2D([], [], marker=">", color="crimson", mec="white", ls="none", label="end"),
    ]
