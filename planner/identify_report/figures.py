"""The report's figures rendered to PNG and PDF (:func:`render_figures`): residuals per axis before and
after, the selection history, the compensation check and the significant diagnostics (the joint
error maps are drawn by :mod:`planner.identify_report.maps`)."""

from __future__ import annotations

import itertools
import re
from typing import Any

import numpy as np

from planner.identify_report.canvas import RenderedFigure, render_figure, rms
from planner.report.figure_base import new_figure
from planner.identify_report.diagnostics import VARIABLE_UNITS, axis_diag, diag_groups, is_angle, var_name
from planner.identify_report.maps import maps_png
from planner.numbers import format_number
from problems.identify import Diagnostic, IdentificationResult

#: Bins of the binned-mean curves in the diagnostic plots.
REPORT_BINS = 12
#: Joint-angle plots use finer bins, up to this many (about 20 rows each), so the binned mean
#: follows harmonics of several cycles per revolution.
REPORT_ANGLE_BINS_MAX = 48
#: Axis colours (x, y, z), as in the plan report.
AXIS_COLOURS = ("tab:blue", "tab:orange", "tab:green")
#: Residual histograms whose largest value is below this (m) are drawn in micrometres.
RESIDUAL_UM_BELOW_M = 1e-4


def render_figures(res: IdentificationResult, rep: dict[str, Any] | None = None) -> dict[str, RenderedFigure]:
    """The report's figures, rendered: joint error maps, residuals per axis, selection history,
    compensation check, significant diagnostics (key -> :class:`RenderedFigure`)."""
    import matplotlib

    figs: dict[str, RenderedFigure] = {}
    with matplotlib.rc_context({"font.size": 9, "axes.titlesize": 9, "legend.fontsize": 8}):
        if getattr(res, "error_maps", None):
            figs["error_maps"] = maps_png(res)
        figs["residuals"] = _residual_png(res)
        if res.history:
            figs["history"] = _history_png(res)
        if res.compensation_check is not None:
            figs["compensation"] = _compensation_png(res, rep or {})
        for key, group in diag_groups(res):
            figs[f"diag_{key}"] = _axes_png(res, group) if key.endswith(".xyz") else _diag_png(res, group[0])
    return figs


def _residual_png(res: IdentificationResult) -> RenderedFigure:
    """Histograms of the residual per axis (x, y, z), before (nominal) and after (identified)."""
    inl = res.inliers
    fig = new_figure(11.0, 5.4, left=0.07, right=0.985, bottom=0.1, top=0.86, wspace=0.25, hspace=0.55)
    axs = fig.subplots(2, 3)
    for row, (name, R, colour) in enumerate(
        (
            ("before: nominal model", res.residual_before[inl], "tab:red"),
            ("after: identified model", res.residual_after[inl], "tab:green"),
        )
    ):
        # residuals below 0.1 mm are drawn in um, so the tick labels stay short and readable
        um = bool(np.max(np.abs(R[:, :3]), initial=0.0) < RESIDUAL_UM_BELOW_M)
        unit, k = ("µm", 1e6) if um else ("mm", 1e3)
        for j, ax_name in enumerate("xyz"):
            ax = axs[row, j]
            r = R[:, j] * k
            ax.hist(r, bins=40, color=colour, alpha=0.8)
            ax.axvline(0.0, color="0.3", lw=0.8)
            ax.set_title(f"{ax_name} axis, {name}: RMS {format_number(rms(r))} {unit}")
            ax.set_xlabel(f"residual r_{ax_name} = predicted − measured [{unit}]")
            ax.set_ylabel("rows [count]")
            ax.grid(alpha=0.3)
    fig.suptitle(
        f"Residual per axis of the measurement frame, {int(np.count_nonzero(inl))} inlier rows "
        f"(RMS per axis over x, y, z: before {format_number(res.rms_before_mm)} mm, after "
        f"{format_number(res.rms_after_mm)} mm)"
    )
    return render_figure(fig)


def _history_png(res: IdentificationResult) -> RenderedFigure:
    """Cross-validated and in-sample RMS at each selection step."""
    steps = list(res.history)
    fig = new_figure(8.0, 3.8, left=0.1, right=0.98, bottom=0.24, top=0.88)
    ax = fig.subplots()
    labels = ["nominal", "declared"]
    for prev, st in itertools.pairwise(steps):
        labels.append(
            f"+{prev.accepted}"
            if prev.accepted
            else ("backward" if st.reason.startswith("backward") else "(no change)")
        )
    cv = [res.cv_rms_before_m * 1e3] + [st.cv_rms_m * 1e3 for st in steps]
    ins = [res.rms_before_mm] + [st.rms_m * 1e3 for st in steps]
    xs = list(range(len(cv)))
    ax.plot(xs, cv, "o-", label="held-out (cross-validated) RMS")
    ax.plot(xs, ins, "s--", label="in-sample RMS")
    if res.noise_sigma_m:
        ax.axhline(res.noise_sigma_m * 1e3, color="k", lw=0.8, ls=":", label="noise floor")
    ax.set_xticks(xs, labels[: len(cv)], fontsize=8, rotation=20)
    ax.set_xlabel("selection step (effect added at that step)")
    ax.set_ylabel("RMS per axis [mm]" + (", log scale" if max(cv) > 5 * min(cv) else ""))
    if max(cv) > 5 * min(cv):
        import matplotlib.ticker as mt

        ax.set_yscale("log")
        ax.yaxis.set_major_locator(mt.LogLocator(subs=(1.0, 2.0, 5.0)))
        ax.yaxis.set_major_formatter(mt.FuncFormatter(lambda v, _pos: f"{v:g}"))
        ax.yaxis.set_minor_formatter(mt.NullFormatter())
    ax.grid(alpha=0.3, which="both")
    ax.legend()
    ax.set_title("Selection history")
    return render_figure(fig)


def _compensation_png(res: IdentificationResult, rep: dict[str, Any]) -> RenderedFigure:
    """The compensation re-measured on the virtual robot: RMS before/after, measurement frame (the
    figure to read, left) and base frame (marked not checkable for unregistered data with aliases)."""
    c = res.compensation_check or {}
    aliases = rep.get("base_frame_aliases") or []
    blind = bool(aliases) and not res.model.registered
    fig = new_figure(9.0, 3.8, left=0.08, right=0.98, bottom=0.14, top=0.8, wspace=0.3)
    axs = fig.subplots(1, 2)
    for ax, title, what, b, a, note in (
        (
            axs[0],
            "measurement frame (measured point): read this",
            "measured-point position error",
            c.get("meas_frame_rms_before_mm"),
            c.get("meas_frame_rms_after_mm"),
            "",
        ),
        (
            axs[1],
            "base frame of the virtual robot (TCP)",
            "TCP position error",
            c.get("rms_before_mm"),
            c.get("rms_after_mm"),
            (f"not checkable with unregistered data:\n{len(aliases)} aliased parameters are held at nominal")
            if blind
            else "",
        ),
    ):
        vals = [float(b or 0.0), float(a or 0.0)]
        bars = ax.bar(
            [0, 1], vals, color=["tab:red", "tab:green"], alpha=0.35 if note else 0.85, hatch="//" if note else None
        )
        for rect, v in zip(bars, vals):
            ax.text(
                rect.get_x() + rect.get_width() / 2, v, f"{format_number(v)} mm", ha="center", va="bottom", fontsize=8
            )
        ax.set_xticks([0, 1], ["before (command as is)", "after compensation"])
        ax.set_ylabel(f"{what}, RMS [mm]")
        ax.set_title(title)
        ax.set_ylim(0, max(vals + [1e-9]) * 1.2)
        ax.grid(alpha=0.3, axis="y")
        if note:
            ax.text(
                0.5,
                0.22,  # below the value labels of the bars
                note,
                transform=ax.transAxes,
                ha="center",
                va="center",
                fontsize=8,
                bbox={"facecolor": "#fff4e0", "edgecolor": "#e0a030"},
            )
    fig.suptitle(f"Compensation re-measured on the virtual robot: {c.get('n_poses', '?')} new poses and loads")
    return render_figure(fig)


def _length_scale(R: np.ndarray) -> tuple[str, float]:
    """Unit and factor from metres for residuals drawn: µm when every value is below 0.1 mm."""
    small = bool(np.max(np.abs(np.nan_to_num(R)), initial=0.0) < RESIDUAL_UM_BELOW_M)
    return ("µm", 1e6) if small else ("mm", 1e3)


def _bin_edges(x: np.ndarray, variable: str) -> np.ndarray:
    """Edges of the binned-mean curve (none for the pose index); joint angles get finer bins."""
    if variable == "pose" or np.ptp(x) <= 0:
        return np.array([])
    bins = max(REPORT_BINS, min(REPORT_ANGLE_BINS_MAX, len(x) // 20)) if is_angle(variable) else REPORT_BINS
    return np.unique(np.quantile(x, np.linspace(0, 1, bins + 1)))


def _scatter_panel(ax: Any, x: np.ndarray, y: np.ndarray, edges: np.ndarray, colour: str) -> None:
    """Rows as dots and their binned mean, the zero line and the grid."""
    ax.plot(x, y, ".", ms=2.5, color=colour, alpha=0.35)
    if len(edges) > 2:
        idx = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, len(edges) - 2)
        centres = 0.5 * (edges[:-1] + edges[1:])
        means = np.array([y[idx == b].mean() if np.any(idx == b) else np.nan for b in range(len(edges) - 1)])
        ax.plot(centres, means, "-", color="k", lw=1.6, label="binned mean")
        ax.legend(loc="best")
    ax.axhline(0.0, color="0.4", lw=0.6)
    ax.grid(alpha=0.3)


def x_of(d: Diagnostic) -> tuple[np.ndarray, str]:
    """The diagnostic's x for a plot and its axis label: joint angles in degrees."""
    x = np.asarray(d.x, dtype=float)
    if is_angle(d.variable):
        return np.degrees(x), f"joint {d.variable[1]} angle q{d.variable[1]} [deg]"
    return x, f"{var_name(d.variable)} [{VARIABLE_UNITS.get(d.variable, '-')}]"


def _diag_png(res: IdentificationResult, d: Diagnostic) -> RenderedFigure:
    """Residual (one panel per axis) or its projected joint error against a diagnostic variable."""
    if d.y is not None:
        y = np.asarray(d.y, dtype=float)
        label = re.sub(r"\s*\((m|µ|u)?rad\)\s*$", "", d.y_label or "projected residual")
        if "rad" in (d.y_label or ""):  # an equivalent joint error, rad: µrad when small
            unit, k = ("µrad", 1e6) if np.max(np.abs(np.nan_to_num(y)), initial=0.0) < 1e-4 else ("mrad", 1e3)
        else:
            unit, k = "-", 1.0
        R = y[:, None] * k
        names = [f"{label} [{unit}]"]
        titles = [label]
        colours: tuple[str, ...] = ("tab:purple",)
    else:
        Rm = res.residual_after[res.inliers]
        unit, k = _length_scale(Rm[:, :3])
        R = Rm * k
        names = [f"residual r_{c} [{unit}]" for c in "xyz"]
        titles = [f"{c} axis of the measurement frame" for c in "xyz"]
        colours = AXIS_COLOURS
    x, xlabel = x_of(d)
    n = len(names)
    fig = new_figure(
        3.7 * n + 0.6 if n > 1 else 7.0,
        3.4,
        left=0.08 if n > 1 else 0.1,
        right=0.985,
        bottom=0.16,
        top=0.76,
        wspace=0.3,
    )
    axs = np.atleast_1d(fig.subplots(1, n))
    edges = _bin_edges(x, d.variable)
    for j, ax in enumerate(axs):
        _scatter_panel(ax, x, R[:, j], edges, colours[j])
        if n == 1 or j == n // 2:  # one x label under the middle panel: long names do not collide
            ax.set_xlabel(xlabel)
        ax.set_ylabel(names[j])
        ax.set_title(titles[j])
    flag = "significant structure" if d.significant else "no significant structure"
    fig.suptitle(
        f"Residual after identification against {var_name(d.variable)}\ncross-validated explained share "
        f"{100 * d.explained_fraction:.0f} % (p = {d.p_value:.2g}, {flag})"
    )
    return render_figure(fig)


def _axes_png(res: IdentificationResult, group: list[Diagnostic]) -> RenderedFigure:
    """The residual per axis against one joint angle (the per-axis diagnostics ``q{j}.x/y/z``, one
    panel each, with its own explained share and significance)."""
    joint = axis_diag(group[0].variable)[0]  # type: ignore[index]
    by_axis: dict[str, Diagnostic] = {}
    for d in res.diagnostics:
        ad = axis_diag(d.variable)
        if ad is not None and ad[0] == joint:
            by_axis[ad[1]] = d
    Rm = np.asarray(res.residual_after, dtype=float)[res.inliers]
    x_rad = np.asarray(group[0].x, dtype=float)
    if len(Rm) != len(x_rad):  # not the inlier rows: draw the tested y
        Rm = np.column_stack(
            [
                np.asarray(
                    by_axis[a].y if a in by_axis and by_axis[a].y is not None else np.full(len(x_rad), np.nan),
                    dtype=float,
                )
                for a in "xyz"
            ]
        )
    unit, k = _length_scale(Rm)
    x = np.degrees(x_rad)
    fig = new_figure(11.7, 3.4, left=0.06, right=0.985, bottom=0.16, top=0.74, wspace=0.3)
    axs = fig.subplots(1, 3)
    edges = _bin_edges(x, group[0].variable)
    for i, (ax, a) in enumerate(zip(axs, "xyz")):
        _scatter_panel(ax, x, Rm[:, i] * k, edges, AXIS_COLOURS[i])
        d = by_axis.get(a)
        if d is None:
            ax.set_title(f"{a} axis")
        else:
            ax.set_title(
                f"{a} axis: {100 * d.explained_fraction:.0f} % explained, p = {d.p_value:.2g}"
                + (" (significant)" if d.significant else "")
            )
        ax.set_xlabel(f"joint {joint} angle q{joint} [deg]")
        ax.set_ylabel(f"residual r_{a} = predicted − measured [{unit}]")
    sig = [a for a in "xyz" if a in by_axis and by_axis[a].significant]
    weighted = " (tested on the residual weighted by 1/σ)" if res.data.sigma is not None else ""
    fig.suptitle(
        f"Residual after identification per axis against joint {joint} angle alone{weighted}\n"
        + (f"significant structure on {', '.join(sig)}" if sig else "no significant structure on any axis")
        + " (cross-validated P-spline of each axis on the angle)"
    )
    return render_figure(fig)
