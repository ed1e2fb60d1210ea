"""Drawings of the placement study's report: pure functions from arrays to matplotlib Figures.

Every function takes plain arrays already in the units shown (mm, deg, m for the cell-frame
coordinates of the base and the path) and returns a :class:`matplotlib.figure.Figure` on the
Agg canvas: nothing here needs a display, touches pyplot's global state or prints.  Which
data goes into which figure is decided in :mod:`planner.report.placement`; :func:`png` turns a
figure into PNG bytes.

Map panels show the *base position* (x, y of the base origin in the cell frame, m): the value
of a cell is the score the study gives the robot standing there.  The path's x-y footprint
(cell frame) is drawn on top, so the part's position relative to the base positions is seen.
"""

from __future__ import annotations

import math
import textwrap
from dataclasses import dataclass, field
from typing import Any
from collections.abc import Sequence

import numpy as np
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch, Rectangle

from planner.report.figure_base import PNG_COMPRESS_LEVEL, PNG_DPI, STYLE, new_figure, png_bytes, styled

#: Infeasible cells by status code (:attr:`problems.placement.scores.PlacementStatus.code`):
#: face grey, hatch, legend text.
STATUS_STYLES: dict[int, tuple[str, str, str]] = {
    1: ("0.86", "///", "unreachable"),
    2: ("0.70", "xx", "flips on every branch"),
    3: ("0.55", "..", "joint limit on every branch"),
    4: ("0.40", "++", "collision (base on an object, or every branch)"),
}
#: Colour of the hatch lines of infeasible cells.
HATCH_COLOUR = "0.25"
#: Colour maps: load-induced error (dark = small error) and margins (bright = more margin).
ERROR_CMAP, MARGIN_CMAP = "viridis", "plasma"
#: Colours of the plan bars (max, RMS) of the studied placements and of the problem as written.
BAR_COLOURS = {"max": "tab:blue", "rms": "tab:cyan"}
BASELINE_BAR_COLOURS = {"max": "0.35", "rms": "0.65"}
#: Path overlay colour.
PATH_COLOUR = "crimson"
#: Most hatched rectangles on one map panel (beyond it the infeasible cells are plain grey).
MAX_HATCH_RUNS = 4000
#: Narrowest map figure, inches (room for the title and the legend).
MIN_WIDTH_IN = 10.5
#: A colour range whose (max - min) / |mean| is below this is widened (one colour shown).
CONSTANT_REL_SPREAD = 1e-6


@dataclass
class MapPanel:
    """One x-y map of base positions (rows = y, columns = x).

    Attributes
    ----------
    title : str
    values : ndarray, shape (ny, nx)
        In the unit shown; NaN where infeasible.
    status : ndarray of int, shape (ny, nx)
        :attr:`PlacementStatus.code` per cell (0 feasible).
    marks : list of (int, float, float)
        ``(rank, x_m, y_m)`` of the ranked placements on this panel.
    """

    title: str
    values: np.ndarray
    status: np.ndarray
    marks: list[tuple[int, float, float]] = field(default_factory=list)


#: Outline colours of the cell's objects on the maps (obstacles, the workpiece).
OBSTACLE_OUTLINE = "#444444"
WORKPIECE_OUTLINE = "#c05a00"


@dataclass
class MapFrame:
    """What every map panel shares: the base-position axes, the path and the problem as written.

    Attributes
    ----------
    x_m, y_m : ndarray, shapes (nx,), (ny,)
        Base-origin grid values in the cell frame, m (evenly spaced).
    path_xy_m : ndarray, shape (N, 2)
        The path's x-y footprint in the cell frame, m.
    baseline_label : str
        Legend text of the problem-as-written marker (at the cell origin).
    """

    x_m: np.ndarray
    y_m: np.ndarray
    path_xy_m: np.ndarray
    baseline_label: str = "as written (x=0, y=0)"
    #: The cell's objects seen from above: (name, role, closed outline (K, 2) of its x-y footprint in
    #: the cell frame, m); empty without a ``[cell]``.
    objects_xy_m: tuple[tuple[str, str, np.ndarray], ...] = ()


def png(fig: Figure, dpi: int = PNG_DPI) -> bytes:
    """PNG bytes of ``fig`` (no software metadata, so the output is reproducible)."""
    return png_bytes(fig, dpi, PNG_COMPRESS_LEVEL, STYLE)


# ------------------------------------------------------------------------------ map geometry
def _cell_size(v: np.ndarray, other: np.ndarray, fallback_m: float = 0.1) -> float:
    """Cell width along an axis, m: the grid step, else the other axis' step, else ``fallback_m``."""
    for a in (v, other):
        if len(a) > 1:
            return float(a[1] - a[0])
    return fallback_m


def cell_extent(frame: MapFrame) -> tuple[float, float, float, float]:
    """(x0, x1, y0, y1) of the grid's cells, m (each value at its cell's centre)."""
    dx = _cell_size(frame.x_m, frame.y_m) / 2
    dy = _cell_size(frame.y_m, frame.x_m) / 2
    return frame.x_m[0] - dx, frame.x_m[-1] + dx, frame.y_m[0] - dy, frame.y_m[-1] + dy


def view_limits(frame: MapFrame) -> tuple[float, float, float, float]:
    """Axis limits showing the cells, the path and the cell origin, with a 6 % margin, m."""
    x0, x1, y0, y1 = cell_extent(frame)
    p = frame.path_xy_m
    xs = [x0, x1, 0.0] + ([float(p[:, 0].min()), float(p[:, 0].max())] if len(p) else [])
    ys = [y0, y1, 0.0] + ([float(p[:, 1].min()), float(p[:, 1].max())] if len(p) else [])
    mx, my = 0.06 * (max(xs) - min(xs)), 0.06 * (max(ys) - min(ys))
    return min(xs) - mx, max(xs) + mx, min(ys) - my, max(ys) + my


def _runs(mask_row: np.ndarray) -> list[tuple[int, int]]:
    """``(start, stop)`` of the runs of True in a 1-D bool array."""
    d = np.diff(np.concatenate([[0], mask_row.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def _run_count(mask: np.ndarray) -> int:
    """Number of runs of True along the rows of a 2-D bool array."""
    return int(mask[:, 0].sum() + (mask[:, 1:] & ~mask[:, :-1]).sum()) if mask.size else 0


def _infeasible_cells(ax: Any, frame: MapFrame, status: np.ndarray) -> None:
    """Infeasible cells in one grey per status and, unless that takes more than
    :data:`MAX_HATCH_RUNS` rectangles (a very fine grid: the greys alone tell the statuses apart),
    hatched (runs along x merged into one rectangle)."""
    ext = cell_extent(frame)
    rgba = np.zeros(status.shape + (4,))
    for code, (face, _, _) in STATUS_STYLES.items():
        rgba[status == code] = (float(face),) * 3 + (1.0,)
    ax.imshow(rgba, origin="lower", extent=ext, interpolation="nearest", aspect="equal", zorder=1.5)
    if sum(_run_count(status == c) for c in STATUS_STYLES) > MAX_HATCH_RUNS:
        return
    w, h = (ext[1] - ext[0]) / status.shape[1], (ext[3] - ext[2]) / status.shape[0]
    for code, (_, hatch, _) in STATUS_STYLES.items():
        for j, row in enumerate(status == code):
            for a, b in _runs(row):
                ax.add_patch(
                    Rectangle(
                        (ext[0] + a * w, ext[2] + j * h),
                        (b - a) * w,
                        h,
                        fill=False,
                        edgecolor=HATCH_COLOUR,
                        hatch=hatch,
                        linewidth=0,
                        zorder=2,
                    )
                )


def _overlay(ax: Any, frame: MapFrame, marks: Sequence[tuple[int, float, float]]) -> None:
    """The cell's objects (outlines seen from above), the path footprint, the problem-as-written
    marker (cell origin) and the numbered ranks."""
    for name, role, outline in frame.objects_xy_m:
        colour = WORKPIECE_OUTLINE if role == "workpiece" else OBSTACLE_OUTLINE
        ax.fill(outline[:, 0], outline[:, 1], facecolor="none", edgecolor=colour, lw=1.4, ls="--", zorder=4)
        corner = outline[np.argmax(outline[:, 1] - 1e-3 * outline[:, 0])]  # the top (left) corner
        ax.text(
            corner[0], corner[1], name, color=colour, fontsize=7, ha="left", va="bottom", zorder=9,
            bbox={"boxstyle": "round,pad=0.15", "facecolor": "white", "edgecolor": "none", "alpha": 0.8},
        )  # fmt: skip
    p = frame.path_xy_m
    if len(p):
        ax.plot(p[:, 0], p[:, 1], color="white", lw=3.4, zorder=5, solid_capstyle="round")
        ax.plot(p[:, 0], p[:, 1], color=PATH_COLOUR, lw=1.8, zorder=6)
        ax.plot(*p[0], marker="o", color=PATH_COLOUR, mec="white", ms=5, zorder=7)
        ax.plot(*p[-1], marker=">", color=PATH_COLOUR, mec="white", ms=6, zorder=7)
    ax.plot(0.0, 0.0, marker="*", ms=14, mfc="white", mec="black", mew=1.0, zorder=8, ls="none")
    for rank, x, y in marks:
        ax.text(
            x,
            y,
            str(rank),
            ha="center",
            va="center",
            fontsize=8.5,
            fontweight="bold",
            zorder=9,
            bbox={"boxstyle": "circle,pad=0.25", "facecolor": "white", "edgecolor": "black", "lw": 0.8},
        )


def _draw_panel(ax: Any, frame: MapFrame, panel: MapPanel, norm: Normalize, cmap: str) -> Any:
    """One map panel: the feasible values as colours, infeasible cells hatched, the overlay."""
    ext = cell_extent(frame)
    im = ax.imshow(
        np.ma.masked_invalid(panel.values),
        origin="lower",
        extent=ext,
        cmap=cmap,
        norm=norm,
        interpolation="nearest",
        aspect="equal",
        zorder=1,
    )
    ax.add_patch(
        Rectangle((ext[0], ext[2]), ext[1] - ext[0], ext[3] - ext[2], fill=False, edgecolor="0.4", lw=0.6, zorder=3)
    )
    _infeasible_cells(ax, frame, panel.status)
    _overlay(ax, frame, panel.marks)
    lim = view_limits(frame)
    ax.set_xlim(lim[0], lim[1])
    ax.set_ylim(lim[2], lim[3])
    ax.set_title(panel.title)
    ax.tick_params(labelsize=7.5)
    return im


def _norm(values: Sequence[np.ndarray], extra: Sequence[float] = ()) -> Normalize | None:
    """A colour scale over the finite values (and ``extra``), widened when constant; None if none."""
    finite = np.concatenate([np.asarray(v, dtype=float).ravel() for v in values] + [np.asarray(extra, float)])
    finite = finite[np.isfinite(finite)]
    if not finite.size:
        return None
    lo, hi = float(finite.min()), float(finite.max())
    mid = 0.5 * (lo + hi)
    if hi - lo <= CONSTANT_REL_SPREAD * max(abs(mid), 1e-300):
        half = max(0.01 * abs(mid), 1e-9)
        lo, hi = mid - half, mid + half
    return Normalize(lo, hi)


def _legend_handles(
    statuses: Sequence[int], counts: dict[int, int], baseline_label: str, marks_label: str, objects: bool = False
) -> list[Any]:
    """Legend proxies: path, problem as written, ranks, the cell's objects, and each infeasible
    status present."""
    hs: list[Any] = [
        Line2D([], [], color=PATH_COLOUR, lw=1.8, marker=">", ms=5, label="path x-y footprint (cell frame, ▶ end)"),
        Line2D([], [], ls="none", marker="*", ms=12, mfc="white", mec="black", label=baseline_label),
    ]
    if marks_label:
        hs.append(Line2D([], [], ls="none", marker="o", ms=10, mfc="white", mec="black", label=marks_label))
    if objects:
        hs.append(Line2D([], [], color=OBSTACLE_OUTLINE, ls="--", lw=1.4, label="cell objects seen from above"))
        hs.append(Line2D([], [], color=WORKPIECE_OUTLINE, ls="--", lw=1.4, label="the workpiece"))
    for code in statuses:
        face, hatch, text = STATUS_STYLES[code]
        hs.append(
            Patch(facecolor=face, edgecolor=HATCH_COLOUR, hatch=hatch, lw=0, label=f"{text} ({counts.get(code, 0)})")
        )
    return hs


def _axes_grid(
    fig: Figure, nrows: int, ncols: int, box_in: tuple[float, float, float, float], gap_in: tuple[float, float]
) -> list[Any]:
    """Axes laid out in a grid inside ``box_in`` = (left, bottom, panel width, panel height), inches."""
    W, H = fig.get_size_inches()
    left, bottom, pw, ph = box_in
    out = []
    for r in range(nrows):
        for c in range(ncols):
            x = left + c * (pw + gap_in[0])
            y = bottom + (nrows - 1 - r) * (ph + gap_in[1])
            out.append(fig.add_axes((x / W, y / H, pw / W, ph / H)))
    return out


def _panel_size(frame: MapFrame, ncols: int, width_in: float) -> tuple[float, float]:
    """Panel width and height (inches) at equal x/y scale for ``ncols`` panels in ``width_in``."""
    lim = view_limits(frame)
    aspect = float(np.clip((lim[3] - lim[2]) / max(lim[1] - lim[0], 1e-12), 0.35, 2.5))
    pw = min(width_in / ncols, 4.4)
    ph = pw * aspect
    if ph > 5.0:
        pw, ph = 5.0 / aspect, 5.0
    return pw, ph


# ------------------------------------------------------------------------------- the figures
def _colour_bar(
    fig: Figure, im: Any, rect_in: tuple[float, float, float, float], label: str, mark: float | None = None
) -> None:
    """A colour bar in ``rect_in`` (left, bottom, width, height; inches), with an optional marked
    value (the problem as written's) drawn as a line across it and the map's ☆ beside it."""
    W, H = fig.get_size_inches()
    cax = fig.add_axes((rect_in[0] / W, rect_in[1] / H, rect_in[2] / W, rect_in[3] / H))
    cb = fig.colorbar(im, cax=cax)
    cb.set_label(label)
    cb.formatter.set_useOffset(False)
    cb.update_ticks()
    if mark is not None and im.norm.vmin <= mark <= im.norm.vmax:
        cax.axhline(mark, color="white", lw=2.6)
        cax.axhline(mark, color="black", lw=1.2)
        cax.plot(
            -0.9,
            mark,
            transform=cax.get_yaxis_transform(),
            marker="*",
            ms=11,
            mfc="white",
            mec="black",
            clip_on=False,
            zorder=5,
        )


@styled
def error_map_figure(
    frame: MapFrame,
    panels: Sequence[MapPanel],
    *,
    title: str,
    cbar_label: str,
    counts: dict[int, int],
    marks_label: str,
    baseline_value: float | None = None,
) -> Figure:
    """Figure 1: the best branch's RMS load-induced TCP error over the base positions, one panel per
    (yaw, z, tilt), on one shared colour scale.

    Parameters
    ----------
    frame : MapFrame
        Base-position axes (cell frame, m), path footprint, problem-as-written label.
    panels : sequence of MapPanel
        Values in mm (NaN infeasible); at most a dozen (the caller chooses which).
    title : str
        Figure title (says when panels were left out).
    cbar_label : str
    counts : dict int -> int
        Placements per status code over the whole grid (legend).
    marks_label : str
        Legend text of the numbered circles (empty: none).
    baseline_value : float, optional
        The problem as written's value (mm), marked on the colour bar.
    """
    n = len(panels)
    ncols = min(4, n)
    nrows = math.ceil(n / ncols)
    pw, ph = _panel_size(frame, ncols, 10.2)
    left, gap_w, gap_h, top, bottom, right = 0.75, 0.6, 0.75, 0.85, 1.3, 1.55
    W = left + ncols * pw + (ncols - 1) * gap_w + right
    H = bottom + nrows * ph + (nrows - 1) * gap_h + top
    left += max(0.0, MIN_WIDTH_IN - W) / 2  # narrow maps centred in the minimum width
    fig = new_figure(max(W, MIN_WIDTH_IN), H)
    axs = _axes_grid(fig, nrows, ncols, (left, bottom, pw, ph), (gap_w, gap_h))
    norm = _norm([p.values for p in panels])
    if norm is not None and baseline_value is not None:  # the as-written value on the scale too
        norm = _norm([p.values for p in panels], [baseline_value])
    im = None
    for i, ax in enumerate(axs):
        if i >= n:
            ax.remove()
            continue
        im = _draw_panel(ax, frame, panels[i], norm or Normalize(0, 1), ERROR_CMAP)
        if not np.isfinite(panels[i].values).any():
            ax.text(
                0.5,
                0.5,
                "no feasible placement" if norm is None else "no feasible placement\non this panel",
                transform=ax.transAxes,
                ha="center",
                va="center",
                fontsize=8,
                bbox={"facecolor": "white", "edgecolor": "0.5"},
                zorder=10,
            )
        if i % ncols == 0:
            ax.set_ylabel("base y [m]")
        if i >= n - ncols:
            ax.set_xlabel("base x [m]")
    x_cb = left + ncols * pw + (ncols - 1) * gap_w + 0.45
    if norm is not None and im is not None:
        _colour_bar(fig, im, (x_cb, bottom, 0.18, nrows * ph + (nrows - 1) * gap_h), cbar_label, baseline_value)
    present = [c for c in STATUS_STYLES if any((p.status == c).any() for p in panels)]
    fig.legend(
        handles=_legend_handles(present, counts, frame.baseline_label, marks_label, bool(frame.objects_xy_m)),
        loc="lower center",
        ncol=min(3, 3 + len(present)),
        frameon=False,
        bbox_to_anchor=(0.5, 0.02),
    )
    fig.suptitle(title, y=1.0 - 0.12 / H, va="top")
    return fig


@styled
def margin_map_figure(
    frame: MapFrame, joint: MapPanel, singular: MapPanel, *, title: str, counts: dict[int, int], marks_label: str
) -> Figure:
    """Figure 2: joint-limit margin (deg) and singularity margin (ratio to the guard) over the base
    positions of one (yaw, z, tilt), side by side, each with its own colour bar (bright = more
    margin); infeasible cells hatched by status."""
    pw, ph = _panel_size(frame, 2, 8.6)
    left, gap_w, top, bottom = 0.75, 1.75, 0.85, 1.25
    W, H = left + 2 * pw + gap_w + 1.3, bottom + ph + top
    left += max(0.0, MIN_WIDTH_IN - W) / 2
    fig = new_figure(max(W, MIN_WIDTH_IN), H)
    axs = _axes_grid(fig, 1, 2, (left, bottom, pw, ph), (gap_w, 0.0))
    labels = ("joint-limit margin, deg", "singularity margin (1 = at the guard)")
    for k, (ax, panel, label) in enumerate(zip(axs, (joint, singular), labels)):
        norm = _norm([panel.values])
        im = _draw_panel(ax, frame, panel, norm or Normalize(0, 1), MARGIN_CMAP)
        ax.set_xlabel("base x [m]")
        ax.set_ylabel("base y [m]")
        if norm is None:
            ax.text(
                0.5,
                0.5,
                "no feasible placement",
                transform=ax.transAxes,
                ha="center",
                va="center",
                bbox={"facecolor": "white", "edgecolor": "0.5"},
                zorder=10,
            )
            continue
        _colour_bar(fig, im, (left + k * (pw + gap_w) + pw + 0.12, bottom, 0.16, ph), label)
    present = [c for c in STATUS_STYLES if (joint.status == c).any()]
    fig.legend(
        handles=_legend_handles(present, counts, frame.baseline_label, marks_label, bool(frame.objects_xy_m)),
        loc="lower center",
        ncol=3,
        frameon=False,
        bbox_to_anchor=(0.5, 0.02),
    )
    fig.suptitle(title, y=1.0 - 0.12 / H, va="top")
    return fig


@dataclass
class PlanBar:
    """One full plan in figure 3.

    Attributes
    ----------
    label : str
        ``best 1`` .. or ``as written``.
    placement : str
        Short placement text.
    max_mm, rms_mm, duration_s : float or None
        Load-induced TCP error before compensation (max, RMS; mm) and cycle time (s); None if failed.
    failed : str
        Why the plan failed (empty when it did not).
    baseline : bool
        The problem as written.
    """

    label: str
    placement: str
    max_mm: float | None = None
    rms_mm: float | None = None
    duration_s: float | None = None
    failed: str = ""
    baseline: bool = False


def _bar_text(ax: Any, x: float, v: float, digits: int = 3) -> None:
    ax.text(x, v, f"{v:.{digits}g}", ha="center", va="bottom", fontsize=7, clip_on=False)


def _failed_text(ax: Any, x: float, text: str) -> None:
    lines = textwrap.wrap(f"failed: {text}", 20)
    wrapped = "\n".join(lines[:9] + (["…"] if len(lines) > 9 else []))
    ax.text(
        x,
        0.5,
        wrapped,
        transform=ax.get_xaxis_transform(),
        ha="center",
        va="center",
        fontsize=7,
        color="darkred",
        bbox={"facecolor": "#fff4f0", "edgecolor": "darkred", "lw": 0.6},
    )


def _error_bars(ax: Any, bars: Sequence[PlanBar]) -> None:
    """Grouped bars (max, RMS before compensation) per plan; failed plans as text."""
    w = 0.38
    for i, b in enumerate(bars):
        if b.failed or b.max_mm is None or b.rms_mm is None:
            _failed_text(ax, i, b.failed or "no error in the plan's headline")
            continue
        cols = BASELINE_BAR_COLOURS if b.baseline else BAR_COLOURS
        for dx, key, v in ((-w / 2, "max", b.max_mm), (w / 2, "rms", b.rms_mm)):
            ax.bar(i + dx, v, w, color=cols[key], edgecolor="black", lw=0.5)
            _bar_text(ax, i + dx, v)
    base = next((b for b in bars if b.baseline and b.rms_mm is not None and not b.failed), None)
    if base is not None and len(bars) > 1:
        ax.axhline(base.rms_mm, color="0.15", ls="--", lw=1.2, zorder=1.5)
    ax.set_ylabel("load-induced TCP error, mm")
    ax.set_title("TCP error before compensation (exact equilibrium, full plan)")
    hs = [
        Patch(facecolor=BAR_COLOURS["max"], edgecolor="black", lw=0.5, label="max"),
        Patch(facecolor=BAR_COLOURS["rms"], edgecolor="black", lw=0.5, label="RMS"),
        Patch(facecolor=BASELINE_BAR_COLOURS["max"], edgecolor="black", lw=0.5, label="max, as written"),
        Patch(facecolor=BASELINE_BAR_COLOURS["rms"], edgecolor="black", lw=0.5, label="RMS, as written"),
    ]
    if base is not None and len(bars) > 1:
        hs.append(Line2D([], [], color="0.15", ls="--", lw=1.2, label="RMS as written"))
    ax.legend(handles=hs, loc="upper left", ncol=3, fontsize=7, framealpha=0.9)


def _duration_bars(ax: Any, bars: Sequence[PlanBar]) -> None:
    """One bar per plan: the cycle time (s); failed plans as text."""
    for i, b in enumerate(bars):
        if b.failed or b.duration_s is None:
            _failed_text(ax, i, "(see left)" if b.failed else "no duration in the plan's headline")
            continue
        ax.bar(i, b.duration_s, 0.6, color="0.6" if b.baseline else "tab:green", edgecolor="black", lw=0.5)
        _bar_text(ax, i, b.duration_s)
    ax.set_ylabel("cycle time, s")
    ax.set_title("cycle time (the controller's trajectory)")


def _placement_lines(text: str) -> str:
    """``x=.., y=.., yaw=..`` on lines of two items."""
    parts = text.split(", ")
    return "\n".join(", ".join(parts[i : i + 2]) for i in range(0, len(parts), 2))


def _plan_ticks(ax: Any, bars: Sequence[PlanBar], with_placement: bool) -> None:
    ax.set_xticks(range(len(bars)))
    ax.set_xticklabels(
        [b.label + ("\n" + _placement_lines(b.placement) if with_placement and b.placement else "") for b in bars],
        fontsize=7.5,
    )
    ax.set_xlim(-0.6, len(bars) - 0.4)
    top = ax.get_ylim()[1]
    ax.set_ylim(0.0, top * 1.25 if top > 0 else 1.0)


@styled
def plans_figure(bars: Sequence[PlanBar], *, title: str) -> Figure:
    """Figure 3: the full plans side by side: load-induced TCP error before compensation (max and
    RMS, mm) and cycle time (s); a failed plan is shown as its reason."""
    n = max(1, len(bars))
    W = min(14.0, max(9.0, 3.5 + 1.25 * n * 1.45))
    fig = new_figure(W, 4.6)
    fig.subplots_adjust(left=0.7 / W, right=1 - 0.25 / W, bottom=0.2, top=0.86, wspace=0.2)
    gs = fig.add_gridspec(1, 2, width_ratios=(1.6, 1.0))
    ax_e, ax_t = fig.add_subplot(gs[0]), fig.add_subplot(gs[1])
    _error_bars(ax_e, bars)
    _duration_bars(ax_t, bars)
    for ax, full in ((ax_e, True), (ax_t, False)):
        _plan_ticks(ax, bars, full)
        ax.grid(axis="y", color="0.9", zorder=0)
        ax.set_axisbelow(True)
    fig.suptitle(title)
    return fig


__all__ = [
    "MapFrame",
    "MapPanel",
    "PlanBar",
    "error_map_figure",
    "margin_map_figure",
    "plans_figure",
    "png",
]
