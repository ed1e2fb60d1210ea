"""The drawings of the cut figures (:mod:`planner.report.cut_plot` prepares their arrays).

Every function takes arrays already reduced for drawing and in display units (mm along the path and
in the program frame, N, the error in the unit given), and returns a matplotlib Figure on the Agg
canvas.  A reduced series comes as the smallest and largest value of each bin
(:class:`Band`): drawn as a band from one to the other, so no peak is hidden; an unreduced one
(both the same) as a line.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from matplotlib.collections import LineCollection, PolyCollection
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from planner.report.figure_base import new_figure, styled

__all__ = ["Band", "Series", "cut_error_figure", "cut_force_figure", "cut_stock_figure", "cut_toolpath_figure"]

#: Shade of the air (no edge in material) and the rapids behind the series.
AIR_COLOUR = "0.9"
PLUNGE_COLOUR = "#f3e6b3"
#: A stock at least this much wider than deep (in Y) is drawn in panels one above the other.
STACK_RATIO = 2.5
#: Colour map of the force on the toolpath and of the stock's top.
FORCE_CMAP = "plasma"
STOCK_CMAP = "viridis"


@dataclass(frozen=True)
class Band:
    """One series along the path for drawing: the smallest and largest value of each bin (equal when
    each bin holds one waypoint), shape ``(B,)`` each, in display units."""

    lo: np.ndarray
    hi: np.ndarray
    label: str
    colour: str


@dataclass(frozen=True)
class Series:
    """What the series figures share: the bins' positions along the path, mm, shape ``(B,)``; the
    bins that are all air or rapids, and those all air, rapids or plunges with a plunge (bool,
    ``(B,)``); the program line ticks (positions mm, labels); whether the bins hold more than one
    waypoint."""

    x_mm: np.ndarray
    air: np.ndarray
    plunge: np.ndarray
    line_ticks: tuple[np.ndarray, list[str]]
    reduced: bool


def _draw_band(ax, x: np.ndarray, b: Band, lw: float = 1.0) -> None:
    if np.array_equal(b.lo, b.hi, equal_nan=True):
        ax.plot(x, b.hi, color=b.colour, lw=lw, label=b.label)
    else:
        ax.fill_between(x, b.lo, b.hi, color=b.colour, alpha=0.5, lw=0.3, edgecolor=b.colour, label=b.label)


def _shade_air(ax, s: Series) -> None:
    """Grey behind the bins that are all air (rapids and moves without an edge in material), yellow
    behind those that plunge (no force from the model)."""
    for where, colour in ((s.air, AIR_COLOUR), (s.plunge, PLUNGE_COLOUR)):
        if not where.any():
            continue
        # runs of marked bins i..j span from the end of bin i - 1 to the end of bin j (the moves ending there)
        w = np.r_[False, np.asarray(where, bool), False].astype(int)
        first, last = np.flatnonzero(np.diff(w) == 1), np.flatnonzero(np.diff(w) == -1) - 1
        lo, hi = s.x_mm[np.maximum(first - 1, 0)], s.x_mm[last]
        verts = [[(a, 0.0), (a, 1.0), (b, 1.0), (b, 0.0)] for a, b in zip(lo, hi)]
        coll = PolyCollection(verts, facecolors=colour, edgecolors="none", transform=ax.get_xaxis_transform())
        coll.set_zorder(0)
        ax.add_collection(coll, autolim=False)


def _line_axis(ax, s: Series) -> None:
    """The program line on a secondary axis on top of ``ax``."""
    top = ax.secondary_xaxis("top")
    pos, labels = s.line_ticks
    top.set_xticks(pos, labels)
    top.set_xlabel("program line", labelpad=2)


def _shade_handles(s: Series) -> list[Line2D]:
    out = [Line2D([], [], color=AIR_COLOUR, lw=6, label="air or rapid (no edge in material)")]
    if s.plunge.any():
        out.append(Line2D([], [], color=PLUNGE_COLOUR, lw=6, label="plunge (the model gives no force)"))
    return out


def _xlim(ax, s: Series) -> None:
    x0, x1 = min(0.0, float(s.x_mm[0])), float(s.x_mm[-1])  # the path starts at 0
    ax.set_xlim(x0, x1 if x1 > x0 else x0 + 1.0)


@styled
def cut_force_figure(
    s: Series,
    magnitude: Sequence[Band],
    components: Sequence[Band],
    engagement: Sequence[Band],
    *,
    title: str,
    max_mark: tuple[float, float, str] | None = None,
) -> Figure:
    """The force along the program, its magnitude (a) and components (b), and the engagement (c)
    against the path length.

    Parameters
    ----------
    s : Series
        The bins' positions (mm along the path), air, program line ticks.
    magnitude, components : sequence of Band
        N: |F| mean over a revolution and its peak; the components in the program frame.
    engagement : sequence of Band
        mm: axial depth and radial width of cut.
    title : str
    max_mark : (x mm, |F| N, label), optional
        The largest |F|, marked.
    """
    fig = new_figure(12.0, 8.6, left=0.07, right=0.79, top=0.86, bottom=0.07, hspace=0.16)
    axes = fig.subplots(3, 1, sharex=True, gridspec_kw={"height_ratios": [1.3, 1.3, 1.0]})
    for a in axes:
        _shade_air(a, s)
        a.grid(alpha=0.3)
    for b in magnitude:
        _draw_band(axes[0], s.x_mm, b)
    if max_mark is not None:
        x, f, label = max_mark
        axes[0].plot([x], [f], marker="v", color="crimson", ms=7, ls="none", label=label, zorder=5)
    axes[0].set_ylim(bottom=0.0)
    axes[0].set_ylabel("|F| [N]")
    axes[0].set_title("(a) magnitude of the force on the tool", loc="left", pad=22)
    _line_axis(axes[0], s)
    for b in components:
        _draw_band(axes[1], s.x_mm, b, lw=0.9)
    axes[1].axhline(0.0, color="0.3", lw=0.6)
    axes[1].set_ylabel("component [N]")
    axes[1].set_title("(b) components of the mean force, program frame", loc="left")
    for b in engagement:
        _draw_band(axes[2], s.x_mm, b)
    axes[2].set_ylim(bottom=0.0)
    axes[2].set_ylabel("engagement [mm]")
    axes[2].set_xlabel("path length along the program (cutting moves and rapids) [mm]")
    axes[2].set_title("(c) engagement", loc="left")
    _xlim(axes[0], s)
    h, _ = axes[0].get_legend_handles_labels()
    axes[0].legend(handles=[*h, *_shade_handles(s)], loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    for a in axes[1:]:
        a.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    fig.suptitle(title)
    return fig


def _draw_arrows(ax, arrows: np.ndarray, key_N: float, mm_per_N: float) -> None:
    """The force arrows (rows x, y mm, fx, fy N) drawn ``mm_per_N`` long per newton, and the key."""
    if not len(arrows):
        return
    q = ax.quiver(
        arrows[:, 0],
        arrows[:, 1],
        arrows[:, 2],
        arrows[:, 3],
        angles="xy",
        scale_units="xy",
        scale=1.0 / mm_per_N,
        color="black",
        width=0.0025,
        zorder=4,
    )
    ax.quiverkey(q, 0.86, 1.03, key_N, f"{key_N:g} N", labelpos="E", coordinates="axes")


@styled
def cut_toolpath_figure(
    segments_mm: np.ndarray,
    force_N: np.ndarray,
    rapid: np.ndarray,
    arrows: np.ndarray,
    key_N: float,
    mm_per_N: float,
    *,
    title: str,
    stock_xy_mm: tuple[float, float, float, float] | None = None,
    start_end_mm: np.ndarray | None = None,
) -> Figure:
    """The toolpath in the XY view of the program frame, coloured by |F|, with arrows of the force.

    Parameters
    ----------
    segments_mm : np.ndarray
        Shape ``(S, 2, 2)``, mm: start and end of each drawn move (or chord).
    force_N : np.ndarray
        Shape ``(S,)``, N: |F| of each segment (the larger of its ends').
    rapid : np.ndarray
        Shape ``(S,)``, bool: drawn thin grey dashed.
    arrows : np.ndarray
        Shape ``(A, 4)``: x, y (mm) and the in-plane force fx, fy (N) at the waypoints chosen.
    key_N, mm_per_N : float
        The force of the scale key (N), and the drawn arrow length per newton (mm/N).
    title : str
    stock_xy_mm : (x0, x1, y0, y1), optional
        The stock's outline, mm.
    start_end_mm : np.ndarray, optional
        Shape ``(2, 2)``, mm: the first and last waypoint.
    """
    fig = new_figure(11.0, 8.0, left=0.08, right=0.88, top=0.86, bottom=0.1)
    ax = fig.add_subplot(1, 1, 1)
    cax = fig.add_axes((0.9, 0.15, 0.015, 0.6))
    segs = np.asarray(segments_mm, float)
    rap = np.asarray(rapid, bool)
    cut = ~rap
    vmax = float(np.nanmax(force_N[cut])) if cut.any() and np.isfinite(force_N[cut]).any() else 1.0
    norm = Normalize(0.0, max(vmax, 1e-9))
    if stock_xy_mm is not None:
        x0, x1, y0, y1 = stock_xy_mm
        ax.plot([x0, x1, x1, x0, x0], [y0, y0, y1, y1, y0], color="0.45", lw=0.8, label="stock outline")
    ax.add_collection(LineCollection(segs[rap], colors="0.55", linewidths=0.6, linestyles=(0, (3, 3))))
    f_cut = np.nan_to_num(np.asarray(force_N, float)[cut])
    order = np.argsort(f_cut, kind="stable")  # where passes overlap in this view, the larger |F| on top
    lc = LineCollection(segs[cut][order], cmap=FORCE_CMAP, norm=norm, linewidths=1.6)
    lc.set_array(f_cut[order])
    ax.add_collection(lc)
    fig.colorbar(lc, cax=cax, label="|F| on the tool [N]")
    _draw_arrows(ax, arrows, key_N, mm_per_N)
    if start_end_mm is not None:
        se = np.asarray(start_end_mm, float)
        ax.plot(*se[0], marker="o", color="crimson", mec="white", ms=6, ls="none", zorder=5, label="start")
        ax.plot(*se[1], marker=">", color="crimson", mec="white", ms=6, ls="none", zorder=5, label="end")
    pts = segs.reshape(-1, 2) if len(segs) else np.zeros((1, 2))
    if stock_xy_mm is not None:
        pts = np.vstack([pts, [[stock_xy_mm[0], stock_xy_mm[2]], [stock_xy_mm[1], stock_xy_mm[3]]]])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = 0.04 * max(float(np.max(hi - lo)), 1e-3)
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("program X [mm]")
    ax.set_ylabel("program Y [mm]")
    ax.grid(alpha=0.25)
    h, _ = ax.get_legend_handles_labels()
    rapid_h = Line2D([], [], color="0.55", lw=0.8, ls=(0, (3, 3)), label="rapid")
    arrow_h = Line2D([], [], color="black", marker=r"$\rightarrow$", ms=12, ls="none", label="force in XY")
    fig.legend(handles=[rapid_h, arrow_h, *h], loc="lower center", ncol=5, frameon=False)
    fig.suptitle(title)
    return fig


@styled
def cut_stock_figure(
    before_mm: np.ndarray,
    after_mm: np.ndarray,
    extent_mm: tuple[float, float, float, float],
    *,
    title: str,
    path_xy_mm: np.ndarray | None = None,
) -> Figure:
    """The stock's top before and after the program, and the depth removed, program frame.

    Parameters
    ----------
    before_mm, after_mm : np.ndarray
        Shape ``(ny, nx)``, mm: the top height (program z); NaN where there is no material.
    extent_mm : (x0, x1, y0, y1)
        The grid's extent, mm, program frame.
    title : str
    path_xy_mm : np.ndarray, optional
        Shape ``(P, 2)``, mm: the cutting moves' waypoints (drawn thin on the removed depth; NaN rows
        break the line).
    """
    x0, x1, y0, y1 = extent_mm
    ratio = max(x1 - x0, 1e-9) / max(y1 - y0, 1e-9)
    stacked = ratio > STACK_RATIO
    if stacked:  # one above the other, each as wide as the figure allows
        pw = 9.0
        ph = max(pw / ratio, 0.8)
        fig = new_figure(12.0, 3 * (ph + 0.75) + 0.9, left=0.1, right=0.88, top=1 - 0.8 / (3 * (ph + 0.75) + 0.9))
        axes = fig.subplots(3, 1, sharex=True, sharey=True)
    else:  # side by side
        pw = 3.3
        ph = pw / ratio
        fig = new_figure(13.0, ph + 2.0, left=0.06, right=0.97, top=1 - 0.9 / (ph + 2.0), bottom=0.7 / (ph + 2.0))
        axes = fig.subplots(1, 3, sharex=True, sharey=True)
    both = np.concatenate([before_mm[np.isfinite(before_mm)], after_mm[np.isfinite(after_mm)]])
    lo, hi = (float(both.min()), float(both.max())) if both.size else (0.0, 1.0)
    norm = Normalize(lo, hi if hi > lo else lo + 1e-3)
    import matplotlib

    cmap = matplotlib.colormaps[STOCK_CMAP].with_extremes(bad="white")
    removed = before_mm - after_mm
    removed = np.where(np.isfinite(before_mm) & ~np.isfinite(after_mm), np.nan, removed)
    r_hi = float(np.nanmax(removed)) if np.isfinite(removed).any() else 0.0
    panels = (
        ("(a) top of the stock before", before_mm, cmap, norm),
        ("(b) top of the stock after", after_mm, cmap, norm),
        (
            "(c) depth removed (before − after)",
            removed,
            matplotlib.colormaps["Reds"].with_extremes(bad="white"),
            Normalize(0.0, r_hi if r_hi > 0 else 1e-3),
        ),
    )
    for i, (ax, (label, z, cm, nm)) in enumerate(zip(axes, panels)):
        im = ax.imshow(z, origin="lower", extent=extent_mm, cmap=cm, norm=nm, interpolation="nearest", aspect="equal")
        ax.set_title(label, loc="left")
        fig.colorbar(im, ax=ax, shrink=0.9, pad=0.03, label="depth [mm]" if i == 2 else "top z [mm]")
        if stacked or i == 0:
            ax.set_ylabel("program Y [mm]")
        if not stacked or i == 2:
            ax.set_xlabel("program X [mm]")
        if i == 2 and path_xy_mm is not None:
            ax.plot(path_xy_mm[:, 0], path_xy_mm[:, 1], color="0.2", lw=0.3, alpha=0.6)
        ax.set_xlim(x0, x1)
        ax.set_ylim(y0, y1)
    fig.suptitle(title)
    return fig


@styled
def cut_error_figure(s: Series, errors: Sequence[Band], *, unit: str, title: str) -> Figure:
    """The TCP error under the predicted load along the program, in ``unit`` (µm or mm).

    Parameters
    ----------
    s : Series
    errors : sequence of Band
        In ``unit``: uncompensated, compensated for the predicted force, compensated for the stand-in
        (when there is one); the labels carry RMS and max.
    unit : str
    title : str
    """
    fig = new_figure(12.0, 5.0, left=0.07, right=0.97, top=0.8, bottom=0.24)
    ax = fig.add_subplot(1, 1, 1)
    _shade_air(ax, s)
    for b in errors:
        _draw_band(ax, s.x_mm, b, lw=1.2)
    top = max((float(np.nanmax(b.hi)) for b in errors if np.isfinite(b.hi).any()), default=1.0)
    ax.set_ylim(-0.02 * top, 1.05 * top)  # the numerically zero curve stays visible above the axis
    _xlim(ax, s)
    ax.set_ylabel(f"TCP position error [{unit}]")
    ax.set_xlabel("path length along the program (cutting moves and rapids) [mm]")
    ax.grid(alpha=0.3)
    _line_axis(ax, s)
    h, _ = ax.get_legend_handles_labels()
    fig.legend(handles=[*h, *_shade_handles(s)], loc="lower center", ncol=2, frameon=False)
    fig.suptitle(title)
    return fig
