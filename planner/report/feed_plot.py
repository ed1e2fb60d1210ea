"""The drawing of the feed figure of a program run (``fig10_feed``): the TCP speed against the
programmed feed over time, above the program line, the slowed lines in the colour of their kind.

The data are chosen and reduced to bins in :mod:`planner.report.toolpath_plot`; this module draws
them (SI arrays in, mm/min on the axes) and prints nothing.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from planner.numbers import format_number
from planner.report.figure_base import new_figure, styled
from planner.report.toolpath import MM_MIN_PER_M_S

__all__ = ["SLOWED_STYLE", "feed_figure"]

#: Rows of labels naming the slowest lines, at most.
MARK_LEVELS = 3
#: Two labels of the feed figure closer than this share of the time axis go on different rows.
MARK_CLEAR = 0.14
#: Each kind of slowed line (:data:`~planner.report.toolpath.SLOWED_KINDS`) on the feed figure: its
#: colour, that colour in words (for the title and caption) and the words after "line" in the legend.
SLOWED_STYLE = {
    "limit": ("tab:red", "red", "slowed by a joint limit"),
    "stops": ("tab:orange", "orange", "slowed only by its neighbours (a stop, a held line)"),
    "slowed": ("tab:red", "red", "slowed (limit or stops)"),
}
#: Width of the slowed lines' curves (pt; the others 1): a line held down for a few samples stays visible.
SLOWED_LW = 1.8
#: The feed figure's speed axis ends at this multiple of the largest programmed feed when the
#: rapids go faster than :data:`RAPID_CUT` times it (what is cut off is written on the panel).
FEED_VIEW_TOP = 1.25
RAPID_CUT = 1.5
#: The bins running a slowed line are shaded while they are at most this share of all bins (beyond,
#: the shading would cover the panel: a long program slowed at every row end).
SLOWED_SHADE_MAX = 0.5


@styled
def feed_figure(
    t_start_s: np.ndarray,
    t_end_s: np.ndarray,
    speed_bands_m_s: Sequence[tuple[np.ndarray, np.ndarray]],
    feed_m_s: np.ndarray,
    kinds: Sequence[str],
    slowed: Sequence[np.ndarray],
    line_bands: Sequence[tuple[np.ndarray, np.ndarray]],
    marks: Sequence[tuple[float, str, float, float, str]],
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
    speed_bands_m_s : K + 2 (lo, hi) pairs of np.ndarray
        Shape ``(B,)`` each, m/s: the TCP speed of the samples on cutting lines that are not slowed,
        on the slowed lines of each kind in ``kinds``, and on rapids.
    feed_m_s : np.ndarray
        Shape ``(B,)``, m/s: the largest programmed feed in the bin; NaN for a bin of rapids only.
    kinds : K str
        The kinds of slowed lines drawn (:data:`~planner.report.toolpath.SLOWED_KINDS`: ``"limit"``
        and ``"stops"``, or ``"slowed"`` alone for a summary that does not tell them apart), each in
        its colour (:data:`SLOWED_STYLE`).
    slowed : K np.ndarray
        Shape ``(B,)`` each, bool: the bin runs a slowed program line of that kind.
    line_bands : K + 1 (lo, hi) pairs of np.ndarray
        Shape ``(B,)`` each: the program line of the samples on lines not slowed, and on the slowed
        lines of each kind.
    marks : sequence of (t, label, F, fraction, kind)
        The slowest lines to name: the time of the line's middle (s), the label, the line's F (m/s),
        its peak speed over F (the label's line points there, on the line's own stretch of the
        speed) and its kind (the label's colour).
    title : str
    """
    t0, t1 = np.asarray(t_start_s, float), np.asarray(t_end_s, float)
    bands = [
        (np.asarray(lo, float) * MM_MIN_PER_M_S, np.asarray(hi, float) * MM_MIN_PER_M_S) for lo, hi in speed_bands_m_s
    ]
    F = np.asarray(feed_m_s, float) * MM_MIN_PER_M_S
    fig = new_figure(12.0, 7.0, left=0.075, right=0.985, bottom=0.08, top=0.79, hspace=0.08)
    a1, a2 = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": (2.6, 1.0)})
    x = np.r_[t0, t1[-1:]] if len(t0) else t0  # bin edges: bin i spans x[i] .. x[i + 1]
    for kind, slow in zip(kinds, slowed):
        slow = np.asarray(slow, bool)
        if slow.any() and slow.mean() <= SLOWED_SHADE_MAX:  # one artist per panel, however many lines
            _shade_slowed((a1, a2), x, slow, SLOWED_STYLE[kind][0])
    styles = (
        [("tab:blue", "TCP speed at F (forward kinematics)", 2.0)]
        + [
            (SLOWED_STYLE[k][0], f"TCP speed on a line {SLOWED_STYLE[k][2]}", 2.6 - 0.1 * i)
            for i, k in enumerate(kinds)
        ]
        + [("0.55", "TCP speed on rapids", 1.5)]
    )
    for i, ((lo, hi), (colour, label, z)) in enumerate(zip(bands, styles)):
        _band(a1, x, lo, hi, colour, label, z, SLOWED_LW if 0 < i <= len(kinds) else 1.0)
    f_max, note = _feed_and_speed_axis(a1, x, F, bands)
    _mark_slowed_lines(a1, x, marks, f_max)
    a1.set_ylabel("TCP speed [mm/min]")
    a1.set_title(f"(a) TCP speed against the programmed feed{note}", loc="left")
    a1.grid(alpha=0.3)
    fig.legend(*a1.get_legend_handles_labels(), loc="upper center", ncol=3, bbox_to_anchor=(0.5, 0.905), frameon=False)
    _line_panel(a2, x, line_bands, kinds)
    fig.suptitle(title)
    return fig


def _line_panel(
    a2: Any, x: np.ndarray, line_bands: Sequence[tuple[np.ndarray, np.ndarray]], kinds: Sequence[str]
) -> None:
    """Panel (b) of the feed figure: the program line each sample runs, the slowed kinds coloured."""
    line_styles = [("0.3", "program line", 2.0)] + [
        (SLOWED_STYLE[k][0], f"line {SLOWED_STYLE[k][2]}", 2.6 - 0.1 * i) for i, k in enumerate(kinds)
    ]
    for i, ((lo, hi), (colour, label, z)) in enumerate(zip(line_bands, line_styles)):
        _band(a2, x, np.asarray(lo, float), np.asarray(hi, float), colour, label, z, SLOWED_LW if i else 1.0)
    a2.set_ylabel("program line")
    a2.set_xlabel("time [s]")
    a2.set_title("(b) the program line each sample runs", loc="left", y=0.8, x=0.01, fontsize=8.5)
    a2.grid(alpha=0.3)
    if len(x) > 1:
        a2.set_xlim(float(x[0]), float(x[-1]))


def _band(
    ax: Any, x: np.ndarray, y_lo: np.ndarray, y_hi: np.ndarray, colour: str, label: str, z: float, lw: float = 1.0
) -> None:
    """A per-bin band from ``y_lo`` to ``y_hi`` over the bin edges ``x``, its top line (width ``lw``,
    pt) labelled."""
    if not np.isfinite(y_hi).any():
        return
    lo_e, hi_e = np.r_[y_lo, y_lo[-1:]], np.r_[y_hi, y_hi[-1:]]
    ax.fill_between(x, lo_e, hi_e, step="post", color=colour, alpha=0.35, lw=0, zorder=z)
    ax.step(x, hi_e, where="post", color=colour, lw=lw, label=label, zorder=z + 0.1)


def _shade_slowed(axes: Sequence[Any], x: np.ndarray, slow: np.ndarray, colour: str) -> None:
    """Shade the bins running a slowed line of one kind on each of ``axes`` (one artist per panel)."""
    for ax in axes:
        ax.fill_between(
            x,
            0,
            1,
            where=np.r_[slow, False],
            step="post",
            transform=ax.get_xaxis_transform(),
            color=colour,
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
    if np.isfinite(f_max) and max(tops[:-1]) <= RAPID_CUT * f_max < tops[-1]:  # the rapids' band is the last
        a1.set_ylim(0.0, FEED_VIEW_TOP * f_max)
        note = f"; rapids reach {format_number(tops[-1])} mm/min, above the axis"
    else:
        a1.set_ylim(0.0, max(max(tops), f_max if np.isfinite(f_max) else 0.0, 1e-9) * 1.12)
    return f_max, note


def _mark_slowed_lines(
    a1: Any, x: np.ndarray, marks: Sequence[tuple[float, str, float, float, str]], f_max: float
) -> None:
    """Name the slowest lines on the speed panel, on at most :data:`MARK_LEVELS` rows of labels
    above the feed, each with an arrow to the line's peak speed."""
    span = float(x[-1] - x[0]) if len(x) > 1 else 1.0
    if marks and np.isfinite(f_max):  # room for the labels above the feed
        a1.set_ylim(0.0, max(a1.get_ylim()[1], FEED_VIEW_TOP * f_max))
    step = a1.get_ylim()[1]  # the rows of labels are spaced by a share of the axis height
    placed: list[tuple[float, int]] = []
    for tm, label, f_line, frac, kind in sorted(marks):
        level = 0  # a label close to one already placed goes one level up, at most MARK_LEVELS
        while level < MARK_LEVELS and any(abs(tm - tp) < MARK_CLEAR * span and lv == level for tp, lv in placed):
            level += 1
        if level == MARK_LEVELS:  # no room: the table lists it
            continue
        placed.append((tm, level))
        y = f_line * MM_MIN_PER_M_S if np.isfinite(f_line) else (f_max if np.isfinite(f_max) else 0.0)
        colour = SLOWED_STYLE[kind][0]
        a1.annotate(
            label,
            xy=(tm, y * frac),
            xytext=(  # kept clear of the panel's sides
                float(np.clip(tm, x[0] + 0.07 * span, x[-1] - 0.07 * span)) if len(x) > 1 else tm,
                y + step * (0.015 + 0.052 * level),
            ),
            ha="center",
            va="bottom",
            fontsize=7.5,
            color=colour,
            bbox={"facecolor": "white", "alpha": 0.8, "edgecolor": "none", "pad": 0.5},
            arrowprops={"arrowstyle": "->", "color": colour, "lw": 0.7, "alpha": 0.8, "shrinkA": 0, "shrinkB": 1},
            zorder=6,
        )
