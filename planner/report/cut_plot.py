"""The report's figures of the predicted cut (``[material]`` + ``[stock]``, summary.json key ``cut``).

Drawn only for a run whose load is a predicted cut (a run without ``cut`` has none of these figures,
not absent ones), from the run's ``cut.csv`` columns (``RunRecord.cut``), ``cut_stock.npz``
(``RunRecord.cut_stock``) and its program (``RunRecord.program``: the waypoints in the program frame):

* :data:`CUT_FORCE_FIGURE`: the force along the program, |F| (mean over a revolution) and its peak
  over the revolution, and the components in the program frame, against the path length, with the
  program line on top and the air (no edge in material, rapids) shaded; below, the engagement
  (axial depth, radial width).
* :data:`CUT_TOOLPATH_FIGURE`: the XY view of the program frame, each move coloured by |F|, with
  arrows of the force's XY part at up to :data:`MAX_ARROWS` waypoints spread along the cutting moves.
* :data:`CUT_STOCK_FIGURE`: the stock's top before and after the program on one colour scale, and the
  depth removed.
* :data:`CUT_ERROR_FIGURE`: the TCP error under the predicted load along the program: uncompensated,
  compensated for the predicted force, and compensated for the constant stand-in (``[cut] stand_in``).

The series are reduced to :data:`SERIES_BINS` bins (smallest and largest of each) for a long program,
the toolpath to :data:`~planner.report.toolpath.MAX_DRAWN_SEGMENTS` chords and the stock images to
:data:`MAX_STOCK_PIXELS` a side (each block's lowest top: no cut is hidden); the captions say so.
The drawings are in :mod:`planner.report.cut_draw`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import PurePath
from typing import Any

import numpy as np

from planner.numbers import NUMERICAL_FLOOR_MM, format_number
from planner.record import RunRecord
from planner.record.columns import CUT_FILE, CUT_KEY, CUT_STOCK_FILE, PROGRAM_KEY
from planner.report.cut_draw import (
    Band,
    Series,
    cut_error_figure,
    cut_force_figure,
    cut_stock_figure,
    cut_toolpath_figure,
)
from planner.report.cut_tables import cutter_words
from planner.report.rendering import FigureItem, job
from planner.report.toolpath import MAX_DRAWN_SEGMENTS, bin_extrema, merge_segments

__all__ = [
    "CUT_ERROR_FIGURE",
    "CUT_FIGURES",
    "CUT_FORCE_FIGURE",
    "CUT_STOCK_FIGURE",
    "CUT_TOOLPATH_FIGURE",
    "cut_items",
]

#: File names of the cut figures (numbers after the cell view's ``fig11_cell``).
CUT_FORCE_FIGURE = "fig12_cut_force"
CUT_TOOLPATH_FIGURE = "fig13_cut_toolpath"
CUT_STOCK_FIGURE = "fig14_cut_stock"
CUT_ERROR_FIGURE = "fig15_cut_error"
CUT_FIGURES = (CUT_FORCE_FIGURE, CUT_TOOLPATH_FIGURE, CUT_STOCK_FIGURE, CUT_ERROR_FIGURE)
#: Most bins a series along the program is drawn with (more waypoints: each bin's min and max).
SERIES_BINS = 2000
#: Most force arrows drawn on the toolpath.
MAX_ARROWS = 40
#: Longest drawn arrow, as a fraction of the drawing's larger extent.
ARROW_FRACTION = 0.08
#: Most pixels a side of a drawn stock image.
MAX_STOCK_PIXELS = 600
#: Program line ticks on the series figures (about).
LINE_TICKS = 8
#: The error figure is in µm below this largest error, mm.
MICRONS_BELOW_MM = 1.0


# ---------------------------------------------------------------------------------- the items
def cut_items(run: RunRecord) -> list[FigureItem]:
    """The cut figures of ``run`` (force, toolpath, stock, error), in report order; none unless its
    summary has ``cut``.  A figure whose data the run lacks is absent with the reason."""
    if not isinstance(run.summary.get(CUT_KEY), Mapping):
        return []
    why = _why_no_series(run)
    return [_force_item(run, why), _toolpath_item(run, why), _stock_item(run), _error_item(run, why)]


def _why_no_series(run: RunRecord) -> str:
    """Why the per-waypoint cut cannot be drawn ('' when it can)."""
    if run.cut is None:
        return "the cut: " + run.absent.get("cut", f"{CUT_FILE} absent in this run")
    if run.program is None:
        return "the cut: " + run.absent.get(PROGRAM_KEY, "the program's waypoints are not available in this run")
    n = len(run.cut["line"])
    if n != run.program.n or n == 0:
        return f"the cut: {CUT_FILE} has {n} rows, the program {run.program.n} waypoints"
    return ""


def _path_mm(run: RunRecord) -> np.ndarray:
    """Path length from the first waypoint along the program's waypoints, mm, shape (N,)."""
    p = run.program.points_m  # type: ignore[union-attr]
    return np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))] * 1e3


def _air(run: RunRecord) -> np.ndarray:
    """Waypoints whose move has no edge in material (or is a rapid), bool (N,)."""
    codes = list(run.summary[CUT_KEY].get("milling_codes") or ["air"])
    air_code = codes.index("air") if "air" in codes else 0
    return (run.cut["milling"] == air_code) | run.program.rapid  # type: ignore[index,union-attr]


def _plunge(run: RunRecord) -> np.ndarray:
    """Waypoints whose move plunges into material (no force from the model), bool (N,)."""
    codes = list(run.summary[CUT_KEY].get("milling_codes") or [])
    if "plunge" not in codes:
        return np.zeros(len(run.cut["milling"]), bool)  # type: ignore[index]
    return run.cut["milling"] == codes.index("plunge")  # type: ignore[index]


def _series(run: RunRecord) -> tuple[Series, np.ndarray, np.ndarray]:
    """The bins of the series figures, and the bins' first and last waypoint."""
    x = _path_mm(run)
    starts = bin_extrema(x, SERIES_BINS)[0]
    ends = np.r_[starts[1:], len(x)] - 1
    air, plunge = _air(run), _plunge(run)
    air_b = np.logical_and.reduceat(air, starts)
    plunge_b = np.logical_and.reduceat(air | plunge, starts) & np.logical_or.reduceat(plunge, starts)
    lines = run.program.line  # type: ignore[union-attr]
    # ticks at even steps of the path length, each labelled with the line run there
    pos = np.linspace(x[0], x[-1], LINE_TICKS + 1) if x[-1] > x[0] else x[:1]
    at = np.clip(np.searchsorted(x, pos), 0, len(x) - 1)
    keep = np.r_[True, lines[at][1:] != lines[at][:-1]]  # a line named once
    ticks = (pos[keep], [str(int(lines[i])) for i in at[keep]])
    return Series(x[ends], air_b, plunge_b, ticks, reduced=len(starts) < len(x)), starts, ends


def _band(v: np.ndarray, starts: np.ndarray, label: str, colour: str, scale: float = 1.0) -> Band:
    v = np.asarray(v, float) * scale
    if len(starts) == len(v):
        return Band(v, v, label, colour)
    lo = np.fmin.reduceat(np.where(np.isfinite(v), v, np.inf), starts)
    hi = np.fmax.reduceat(np.where(np.isfinite(v), v, -np.inf), starts)
    return Band(np.where(np.isfinite(lo), lo, np.nan), np.where(np.isfinite(hi), hi, np.nan), label, colour)


def _header(run: RunRecord) -> str:
    s = run.summary
    c = s[CUT_KEY]
    prog = s.get(PROGRAM_KEY) if isinstance(s.get(PROGRAM_KEY), Mapping) else {}
    cutter = c.get("cutter") if isinstance(c.get("cutter"), Mapping) else {}
    mat = c.get("material") if isinstance(c.get("material"), Mapping) else {}
    name = PurePath(str(prog.get("file", "?"))).name
    return f"{s.get('robot', '?')}: program {name}; {cutter_words(cutter)} in {mat.get('name', '?')}"


def _reduced_words(s: Series, n: int) -> str:
    if not s.reduced:
        return ""
    return (
        f" {n} waypoints drawn as {len(s.x_mm)} bins of consecutive waypoints: each band spans the bin's smallest "
        "to largest value, so no peak is hidden."
    )


# ------------------------------------------------------------------------------- a. the force
def _force_item(run: RunRecord, why: str) -> FigureItem:
    item = FigureItem(CUT_FORCE_FIGURE, "The cut: force and engagement along the program", "")
    if why:
        item.absent = why
        return item
    c, f = run.cut, run.summary[CUT_KEY].get("force_N") or {}
    s, starts, _ = _series(run)
    magnitude = [
        _band(c["peak_force_N"], starts, "peak over a revolution", "0.6"),
        _band(c["force_N"], starts, "mean over a revolution", "black"),
    ]
    components = [
        _band(c["fx_N"], starts, "Fx", "tab:red"),
        _band(c["fy_N"], starts, "Fy", "tab:green"),
        _band(c["fz_N"], starts, "Fz", "tab:blue"),
    ]
    engagement = [
        _band(c["axial_depth_mm"], starts, "axial depth of cut", "tab:purple"),
        _band(c["radial_width_mm"], starts, "radial width of cut", "tab:orange"),
    ]
    k = int(np.argmax(c["force_N"]))
    mark = (float(_path_mm(run)[k]), float(c["force_N"][k]), f"max |F|, line {int(c['line'][k])}")
    mean = f.get("mean_cutting")
    title = (
        _header(run)
        + f"\nforce on the tool: max {format_number(float(c['force_N'][k]))} N (line {int(c['line'][k])})"
        + (f", mean {format_number(float(mean))} N while cutting" if isinstance(mean, (int, float)) else "")
        + f", peak over a revolution {format_number(float(np.max(c['peak_force_N'])))} N"
    )
    item.caption = (
        "The force the cut puts on the tool at each waypoint (arriving along the move ending there), N: (a) the "
        "magnitude |F| of the force averaged over a spindle revolution (black) and the largest instantaneous "
        "magnitude over the revolution (grey); (b) the components of the mean force in the program frame; (c) the "
        "engagement, mm: the axial depth (the highest engaged edge above the tool tip) and the radial width of cut "
        "across the feed. "
        "Against the path length along the program's waypoints (rapids included), with the program line on top; "
        "grey background: moves without an edge in material (air) and rapids; yellow: plunges into material, for "
        "which the model (peripheral edges only) gives no force. "
        f"Data: {CUT_FILE} (force_N, peak_force_N, fx_N..fz_N, axial_depth_mm, radial_width_mm)."
        + _reduced_words(s, len(c["line"]))
    )
    item.job = job(cut_force_figure, s, magnitude, components, engagement, title=title, max_mark=mark)
    return item


# ---------------------------------------------------------------------------- b. the toolpath
def _arrow_rows(run: RunRecord, span_mm: float) -> tuple[np.ndarray, float, float]:
    """Up to :data:`MAX_ARROWS` arrows (x, y mm; fx, fy N) at cutting waypoints spread evenly along
    the path; the scale key (N) and the drawn length per newton (mm/N)."""
    c = run.cut
    fxy = np.column_stack([c["fx_N"], c["fy_N"]])  # type: ignore[index]
    mag = np.linalg.norm(fxy, axis=1)
    idx = np.flatnonzero(~_air(run) & (mag > 0))
    if not idx.size:
        return np.zeros((0, 4)), 1.0, 1.0
    x = _path_mm(run)[idx]
    targets = np.linspace(x[0], x[-1], min(MAX_ARROWS, idx.size))
    pick = idx[np.unique(np.clip(np.searchsorted(x, targets), 0, idx.size - 1))]
    mm_per_N = ARROW_FRACTION * span_mm / float(mag[idx].max())
    key = _nice(float(mag[idx].max()) / 2.0)
    pts = run.program.points_m[pick, :2] * 1e3  # type: ignore[union-attr]
    return np.column_stack([pts, fxy[pick]]), key, mm_per_N


def _nice(v: float) -> float:
    """A round value (1, 2 or 5 × 10^k) at most ``v``."""
    if not (v > 0 and math.isfinite(v)):
        return 1.0
    e = 10.0 ** math.floor(math.log10(v))
    return max(m for m in (1.0, 2.0, 5.0) if m * e <= v * (1 + 1e-12)) * e


def _toolpath_item(run: RunRecord, why: str) -> FigureItem:
    item = FigureItem(CUT_TOOLPATH_FIGURE, "The cut: force on the toolpath", "")
    if why:
        item.absent = why
        return item
    view, c = run.program, run.cut
    xy = view.points_m[:, :2] * 1e3  # type: ignore[union-attr]
    segs, vals, rap, tol = merge_segments(xy, c["force_N"], view.rapid)  # type: ignore[index,union-attr]
    stock = None
    if run.cut_stock is not None:
        e = np.asarray(run.cut_stock["extent"], float) * 1e3
        stock = (float(e[0]), float(e[1]), float(e[2]), float(e[3]))
    pts = np.vstack([xy, [[stock[0], stock[2]], [stock[1], stock[3]]]]) if stock else xy
    span = float(np.max(pts.max(axis=0) - pts.min(axis=0)))
    arrows, key, mm_per_N = _arrow_rows(run, max(span, 1e-3))
    item.caption = (
        "The programmed path in the XY view of the program (workpiece) frame, mm, each move coloured by the "
        "magnitude |F| of the predicted cutting force (mean over a revolution; a move carries the larger |F| of "
        f"its two ends); arrows: the XY part of the force on the tool at {len(arrows)} waypoints spread evenly "
        f"along the cutting moves, drawn {format_number(mm_per_N, 3)} mm per N (the key: {key:g} N). Rapids: "
        "thin grey dashed; the stock's outline in grey. Where passes at different depths overlap in this view, the "
        "move with the larger |F| is drawn on top. "
        f"Data: {CUT_FILE} (fx_N, fy_N, force_N), the program's waypoints (path.csv)."
    )
    if tol > 0:
        item.caption += (
            f" Decimated for drawing: {len(segs)} chords for the {view.n - 1} moves (more than "  # type: ignore[union-attr]
            f"{MAX_DRAWN_SEGMENTS}), every waypoint left out within {format_number(tol * 2**0.5, 3)} mm of its "
            "chord, each chord coloured by the largest |F| of the moves it replaces."
        )
    title = _header(run) + f"\n|F| up to {format_number(float(np.max(c['force_N'])))} N; arrows: XY part of the force"
    item.job = job(
        cut_toolpath_figure,
        segs,
        np.asarray(vals, float).reshape(len(segs), -1)[:, 0] if len(segs) else np.zeros(0),
        rap,
        arrows,
        key,
        mm_per_N,
        title=title,
        stock_xy_mm=stock,
        start_end_mm=xy[[0, -1]],
    )
    return item


# ------------------------------------------------------------------------------- c. the stock
def _block_min(z: np.ndarray, step: int) -> np.ndarray:
    """``z`` (ny, nx) in blocks of ``step`` × ``step``: each block's smallest finite value (NaN: none)."""
    if step <= 1:
        return z
    ny, nx = z.shape
    py, px = -ny % step, -nx % step
    zz = np.pad(np.where(np.isfinite(z), z, np.inf), ((0, py), (0, px)), constant_values=np.inf)
    out = zz.reshape((ny + py) // step, step, (nx + px) // step, step).min(axis=(1, 3))
    return np.where(np.isfinite(out), out, np.nan)


def _stock_item(run: RunRecord) -> FigureItem:
    item = FigureItem(CUT_STOCK_FIGURE, "The cut: the stock before and after", "")
    st = run.cut_stock
    if st is None:
        item.absent = "the stock: " + run.absent.get("cut_stock", f"{CUT_STOCK_FILE} absent in this run")
        return item
    before, after = np.asarray(st["before"], float), np.asarray(st["after"], float)
    step = max(1, math.ceil(max(before.shape) / MAX_STOCK_PIXELS))
    b, a = _block_min(before, step) * 1e3, _block_min(after, step) * 1e3
    e = np.asarray(st["extent"], float) * 1e3
    extent = (float(e[0]), float(e[1]), float(e[2]), float(e[3]))
    c = run.summary[CUT_KEY]
    removed, volume = c.get("removed_mm3"), c.get("stock_volume_mm3")
    vol = ""
    if isinstance(removed, (int, float)):
        vol = f"removed {format_number(float(removed) / 1e3)} cm³"
        if isinstance(volume, (int, float)) and volume > 0:
            vol += f" of {format_number(float(volume) / 1e3)} cm³ ({format_number(100.0 * removed / volume, 3)} %)"
    path = None
    if not _why_no_series(run):
        p = run.program.points_m[:, :2] * 1e3  # type: ignore[union-attr]
        path = np.where(_air(run)[:, None], np.nan, p)
    pixel = (e[1] - e[0]) / before.shape[1]
    item.caption = (
        "The top of the stock (program z, mm; white: no material) before and after the program, on one colour "
        "scale, and the depth removed (before − after; the cutting moves' waypoints drawn thin), as the run stored "
        f"them: {before.shape[1]} × {before.shape[0]} cells of {format_number(pixel, 3)} mm ({CUT_STOCK_FILE}; the "
        "cut was simulated at summary.json cut.resolution_mm). Volumes: summary.json cut."
    )
    if step > 1:
        item.caption += f" Drawn in blocks of {step} × {step} cells, each block showing its lowest top (no cut hidden)."
    item.job = job(cut_stock_figure, b, a, extent, title=_header(run) + (f"\n{vol}" if vol else ""), path_xy_mm=path)
    return item


# ------------------------------------------------------------------------------- d. the error
def _stats_words(v_mm: np.ndarray, unit: str, scale: float) -> str:
    """``"RMS x, max y unit"`` of a series in mm (``"0 (numerical)"`` below the floor)."""
    v = np.asarray(v_mm, float)
    v = v[np.isfinite(v)]
    if not v.size:
        return "n/a"
    rms, mx = float(np.sqrt(np.mean(v**2))), float(v.max())
    if mx < NUMERICAL_FLOOR_MM:
        return "0 (numerical)"
    return f"RMS {format_number(rms * scale)} {unit}, max {format_number(mx * scale)} {unit}"


def _error_item(run: RunRecord, why: str) -> FigureItem:
    item = FigureItem(CUT_ERROR_FIGURE, "The cut: TCP error under the predicted load", "")
    if why:
        item.absent = why
        return item
    c = run.cut
    cols = [
        ("error_uncompensated_mm", "uncompensated", "tab:red"),
        ("error_compensated_mm", "compensated for the predicted force", "tab:green"),
    ]
    stand = run.summary[CUT_KEY].get("stand_in")
    has_stand = isinstance(stand, Mapping) and np.isfinite(c["error_stand_in_mm"]).any()  # type: ignore[index]
    if has_stand:
        cols.append(("error_stand_in_mm", "compensated for the constant stand-in", "tab:blue"))
    top = max(float(np.nanmax(c[k])) if np.isfinite(c[k]).any() else 0.0 for k, _, _ in cols)  # type: ignore[index]
    unit, scale = ("µm", 1e3) if top < MICRONS_BELOW_MM else ("mm", 1.0)
    s, starts, _ = _series(run)
    bands = [
        _band(c[k], starts, f"{label}: {_stats_words(c[k], unit, scale)}", colour, scale)  # type: ignore[index]
        for k, label, colour in cols
    ]
    item.caption = (
        "The load-induced TCP position error (norm, at the exact deflected equilibrium) under the predicted "
        f"cutting wrench at each waypoint, {unit}: the arm commanded as planned (uncompensated); compensated for "
        "the predicted wrench (the plan's exact compensation: numerically zero)"
        + (
            f"; and compensated for the constant stand-in wrench {_stand_words(stand)} instead (the residual a "
            "compensation for a constant guess of the load would leave under the predicted cut)"
            if has_stand
            else "; no [cut] stand_in in this problem, so no comparison with a constant load"
        )
        + ". Grey background: air and rapids; yellow: plunges (no force predicted). "
        + f"Data: {CUT_FILE} (error_*_mm); RMS and max over all waypoints."
        + _reduced_words(s, len(c["line"]))  # type: ignore[index]
    )
    item.job = job(cut_error_figure, s, bands, unit=unit, title=_header(run) + "\nTCP error under the predicted load")
    return item


def _stand_words(stand: Mapping[str, Any]) -> str:
    F = stand.get("F_N") or []
    M = stand.get("M_Nm") or []
    frame = "tool frame" if stand.get("frame") == "tool" else "base frame"
    text = f"F = [{', '.join(format_number(float(v)) for v in F)}] N"
    if any(float(v) != 0.0 for v in M):
        text += f", M = [{', '.join(format_number(float(v)) for v in M)}] N·m"
    return f"({text}, {frame})"
