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
  with the program line below; the slowed lines of the summary marked.  Long trajectories are
  drawn as the minimum and maximum over :data:`~planner.report.toolpath.FEED_BINS` bins.

The arrays are prepared (and reduced) in :func:`program_items`, so a figure job stays small; the
drawing functions take SI arrays and convert at the edge.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from problems.toolpath.feed import FEED_SLOW_TOL

from planner.numbers import NUMERICAL_FLOOR_M, format_number, mm_text
from planner.report.figure_base import new_figure, styled
from planner.report.rendering import FigureItem, job
from planner.record import RunRecord, method_name
from planner.report.tables import load_words
from planner.report.toolpath import (
    MAX_DRAWN_SEGMENTS,
    MM_MIN_PER_M_S,
    PROGRAM_KEY,
    bin_extrema,
    sample_feed_m_s,
    merge_segments,
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
#: Slowed lines named on the feed figure (slowest first), on at most MARK_LEVELS rows of labels.
FEED_MARKED = 5
MARK_LEVELS = 3
#: The feed figure's speed axis ends at this multiple of the largest programmed feed when the
#: rapids go faster than :data:`RAPID_CUT` times it (what is cut off is written on the panel).
FEED_VIEW_TOP = 1.25
RAPID_CUT = 1.5
#: The bins running a slowed line are shaded while they are at most this share of all bins (beyond,
#: the shading would cover the panel: a long program slowed at every row end).
SLOWED_SHADE_MAX = 0.5
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
    return f"{s.get('robot', '?')}, branch {branch}: program {prog.get('file', '?')}; load: {load_words(s)}"


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
    title = _header(run) + (
        f"\n{view.n} waypoints, {int(np.count_nonzero(view.rapid[1:]))} rapid moves; "
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
    worst = slowed_lines_worst_first(entry)
    slowed = np.isin(lines, np.array([L for L, _ in worst], dtype=int))
    rapid = ~np.isfinite(feed)
    starts = bin_extrema(speed)[0]
    ends = np.r_[starts[1:], len(t)] - 1
    speed_bands = [  # per kind of sample: the smallest and largest speed of each bin (NaN: none of that kind)
        bin_extrema(np.where(mask, speed, np.nan))[1:] for mask in (~rapid & ~slowed, slowed, rapid & ~slowed)
    ]
    line_f = lines.astype(float)
    line_bands = [bin_extrema(np.where(mask, line_f, np.nan))[1:] for mask in (~slowed, slowed)]
    f_hi = bin_extrema(feed)[2]
    slow_bin = np.logical_or.reduceat(slowed, starts) if len(t) else np.zeros(0, bool)
    marks = _feed_marks(worst, lines, t, feed)
    cut = np.isfinite(feed) & (feed > 0)
    measured = float(np.max(speed[cut] / feed[cut])) if cut.any() else float("nan")
    per_bin = int(np.ceil(len(t) / max(len(starts), 1)))
    name = method_name(s, ctrl)
    item.caption = _feed_caption(name, fname, len(t), len(starts), per_bin)
    item.job = job(
        feed_figure,
        t[starts],
        t[ends],
        speed_bands,
        f_hi,
        slow_bin,
        line_bands,
        marks,
        title=_header(run) + "\n" + _feed_head(name, entry, worst, measured),
    )
    return item


def _feed_marks(
    worst: Sequence[tuple[int, float]], lines: np.ndarray, t: np.ndarray, feed: np.ndarray
) -> list[tuple[float, int, float, float]]:
    """The slowest lines to name on the feed figure: (time at the line's middle s, line, fraction, F m/s)."""
    marks = []
    for L, frac in worst[:FEED_MARKED]:
        idx = np.flatnonzero(lines == L)
        if idx.size:  # named at the middle of the line's time
            marks.append((0.5 * float(t[idx[0]] + t[idx[-1]]), int(L), float(frac), float(feed[idx[0]])))
    return marks


def _feed_caption(name: str, fname: str, n_samples: int, n_bins: int, per_bin: int) -> str:
    """The feed figure's caption."""
    caption = (
        f"The controller's trajectory ({name}, {fname}): (a) the TCP speed it reaches, from forward kinematics "
        "of its sampled joint commands (the arm model's rigid kinematics; |Δp|/Δt between samples), against the "
        "programmed feed F of the program line each sample runs (dashed; the largest F of the line's cutting "
        "moves; none on rapids), mm/min, over time; (b) that program line. Red: the program lines the summary "
        f"lists as slowed (peak TCP speed below {format_number(100.0 * (1.0 - FEED_SLOW_TOL))} % of F: the joint "
        "limits, or the stops around them, keep the "
        f"feed down), the {FEED_MARKED} slowest named with the summary's measure (the peak speed on the line's "
        "slowest move, % of F: a move starting or ending at a stop counts). Grey: rapids."
    )
    if per_bin > 1:
        caption += (
            f" {n_samples} samples drawn as {n_bins} bins of {per_bin}: each bin's band spans its smallest to "
            "largest speed (the line is the largest), so no peak and no slow-down is hidden."
        )
    return caption


def _feed_head(name: str, entry: Mapping[str, Any], worst: Sequence[tuple[int, float]], measured: float) -> str:
    """The feed figure's second title line: duration against the programmed time, slowed lines, peak speed / F."""
    prog_t, dur = entry.get("programmed_time_s"), entry.get("duration_s")
    head = f"{name}: duration {format_number(float(dur))} s" if isinstance(dur, (int, float)) else name
    if isinstance(prog_t, (int, float)) and isinstance(dur, (int, float)) and prog_t > 0:
        head += f" against {format_number(float(prog_t))} s programmed (×{format_number(float(dur) / float(prog_t))})"
    head += f"; {len(worst)} slowed line{'' if len(worst) == 1 else 's'}"
    if np.isfinite(measured):
        head += f"; peak TCP speed / F on cutting moves {measured:.3f} (forward kinematics)"
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


@styled
def feed_figure(
    t_start_s: np.ndarray,
    t_end_s: np.ndarray,
    speed_bands_m_s: Sequence[tuple[np.ndarray, np.ndarray]],
    feed_m_s: np.ndarray,
    slowed: np.ndarray,
    line_bands: Sequence[tuple[np.ndarray, np.ndarray]],
    marks: Sequence[tuple[float, int, float, float]],
    *,
    title: str,
) -> Figure:
    """The TCP speed against the programmed feed over time (mm/min), above the program line.

    Every series is per bin of consecutive samples (one sample a bin for a short trajectory), as
    the smallest and largest value of the bin's samples of one kind (NaN: the bin has none).

    Parameters
    ----------
    t_start_s, t_end_s : np.ndarray
        Shape ``(B,)``, s: time of the first and last sample of each bin.
    speed_bands_m_s : three (lo, hi) pairs of np.ndarray
        Shape ``(B,)`` each, m/s: the TCP speed of the samples on cutting lines that are not slowed,
        on slowed lines, and on rapids.
    feed_m_s : np.ndarray
        Shape ``(B,)``, m/s: the largest programmed feed in the bin; NaN for a bin of rapids only.
    slowed : np.ndarray
        Shape ``(B,)``, bool: the bin runs a slowed program line.
    line_bands : two (lo, hi) pairs of np.ndarray
        Shape ``(B,)`` each: the program line of the samples on lines not slowed, and on slowed lines.
    marks : sequence of (t, line, fraction, F)
        The slowest lines to name: the time of the line's peak speed (s), its number, that peak
        over F, and F (m/s).
    title : str
    """
    t0, t1 = np.asarray(t_start_s, float), np.asarray(t_end_s, float)
    bands = [
        (np.asarray(lo, float) * MM_MIN_PER_M_S, np.asarray(hi, float) * MM_MIN_PER_M_S) for lo, hi in speed_bands_m_s
    ]
    F = np.asarray(feed_m_s, float) * MM_MIN_PER_M_S
    slow = np.asarray(slowed, bool)
    fig = new_figure(12.0, 7.0, left=0.075, right=0.985, bottom=0.08, top=0.82, hspace=0.08)
    a1, a2 = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": (2.6, 1.0)})
    x = np.r_[t0, t1[-1:]] if len(t0) else t0  # bin edges: bin i spans x[i] .. x[i + 1]
    if slow.any() and slow.mean() <= SLOWED_SHADE_MAX:  # one artist per panel, however many lines
        _shade_slowed((a1, a2), x, slow)
    styles = (
        ("tab:blue", "TCP speed (forward kinematics)", 2.0),
        ("tab:red", "TCP speed on a slowed line", 2.5),
        ("0.55", "TCP speed on rapids", 1.5),
    )
    for (lo, hi), (colour, label, z) in zip(bands, styles):
        _band(a1, x, lo, hi, colour, label, z)
    f_max, note = _feed_and_speed_axis(a1, x, F, bands)
    _mark_slowed_lines(a1, x, marks, f_max)
    a1.set_ylabel("TCP speed [mm/min]")
    a1.set_title(f"(a) TCP speed against the programmed feed{note}", loc="left")
    a1.grid(alpha=0.3)
    fig.legend(*a1.get_legend_handles_labels(), loc="upper center", ncol=4, bbox_to_anchor=(0.5, 0.905), frameon=False)
    for (lo, hi), (colour, label, z) in zip(
        line_bands, (("0.3", "program line", 2.0), ("tab:red", "slowed line", 2.5))
    ):
        _band(a2, x, np.asarray(lo, float), np.asarray(hi, float), colour, label, z)
    a2.set_ylabel("program line")
    a2.set_xlabel("time [s]")
    a2.set_title("(b) the program line each sample runs", loc="left", y=0.8, x=0.01, fontsize=8.5)
    a2.grid(alpha=0.3)
    if len(x) > 1:
        a2.set_xlim(float(x[0]), float(x[-1]))
    fig.suptitle(title)
    return fig


def _band(ax: Any, x: np.ndarray, y_lo: np.ndarray, y_hi: np.ndarray, colour: str, label: str, z: float) -> None:
    """A per-bin band from ``y_lo`` to ``y_hi`` over the bin edges ``x``, its top line labelled."""
    if not np.isfinite(y_hi).any():
        return
    lo_e, hi_e = np.r_[y_lo, y_lo[-1:]], np.r_[y_hi, y_hi[-1:]]
    ax.fill_between(x, lo_e, hi_e, step="post", color=colour, alpha=0.35, lw=0, zorder=z)
    ax.step(x, hi_e, where="post", color=colour, lw=1.0, label=label, zorder=z + 0.1)


def _shade_slowed(axes: Sequence[Any], x: np.ndarray, slow: np.ndarray) -> None:
    """Shade the bins running a slowed line on each of ``axes`` (one artist per panel)."""
    for ax in axes:
        ax.fill_between(
            x,
            0,
            1,
            where=np.r_[slow, False],
            step="post",
            transform=ax.get_xaxis_transform(),
            color="tab:red",
            alpha=0.1,
            lw=0,
            zorder=0,
        )


def _feed_and_speed_axis(
    a1: Any, x: np.ndarray, F: np.ndarray, bands: Sequence[tuple[np.ndarray, np.ndarray]]
) -> tuple[float, str]:
    """Draw the programmed feed and set the speed axis; (largest feed mm/min or NaN, title note)."""
    cutting = np.isfinite(F)
    if cutting.any():
        a1.step(x, np.r_[F, F[-1:]], where="post", color="k", lw=1.1, ls="--", label="programmed feed F", zorder=3)
    f_max = float(np.nanmax(F)) if cutting.any() else float("nan")
    tops = [float(np.nanmax(hi)) if np.isfinite(hi).any() else 0.0 for _, hi in bands]
    note = ""
    if np.isfinite(f_max) and max(tops[:2]) <= RAPID_CUT * f_max < tops[2]:
        a1.set_ylim(0.0, FEED_VIEW_TOP * f_max)
        note = f"; rapids reach {format_number(tops[2])} mm/min, above the axis"
    else:
        a1.set_ylim(0.0, max(max(tops), f_max if np.isfinite(f_max) else 0.0, 1e-9) * 1.12)
    return f_max, note


def _mark_slowed_lines(a1: Any, x: np.ndarray, marks: Sequence[tuple[float, int, float, float]], f_max: float) -> None:
    """Name the slowest lines on the speed panel, on at most :data:`MARK_LEVELS` rows of labels."""
    span = float(x[-1] - x[0]) if len(x) > 1 else 1.0
    placed: list[tuple[float, int]] = []
    for tm, L, frac, f_line in sorted(marks):
        level = 0  # a label close to one already placed goes one level up, at most MARK_LEVELS
        while level < MARK_LEVELS and any(abs(tm - tp) < 0.1 * span and lv == level for tp, lv in placed):
            level += 1
        if level == MARK_LEVELS:  # no room: the table lists it
            continue
        placed.append((tm, level))
        y = f_line * MM_MIN_PER_M_S if np.isfinite(f_line) else (f_max if np.isfinite(f_max) else 0.0)
        a1.annotate(
            f"line {L}: {format_number(100.0 * frac, 3)} %",
            xy=(tm, y),
            xytext=(  # kept clear of the panel's sides
                float(np.clip(tm, x[0] + 0.045 * span, x[-1] - 0.045 * span)) if len(x) > 1 else tm,
                y + f_max * (0.02 + 0.065 * level) if np.isfinite(f_max) else y,
            ),
            ha="center",
            va="bottom",
            fontsize=7.5,
            color="tab:red",
            arrowprops={"arrowstyle": "-", "color": "tab:red", "lw": 0.6, "alpha": 0.6},
            zorder=6,
        )
    if placed and np.isfinite(f_max):  # room for the labels above the feed
        a1.set_ylim(0.0, max(a1.get_ylim()[1], FEED_VIEW_TOP * f_max))
