"""The report's drawings of the motion: figure 6 (the timed joint trajectories of every method
against their limits) and figure 7 (the arm in 3-D at chosen waypoints, its deflection magnified).

Pure functions from arrays (SI units) to matplotlib Figures on the Agg canvas, as
:mod:`planner.report.plots`; which data goes into them is decided in :mod:`planner.report.figures`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import matplotlib
import matplotlib.ticker
import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from planner.numbers import format_number
from planner.report.figure_base import new_figure, styled
from planner.report.plots import JOINT_COLOURS

__all__ = [
    "JERK_VIEW_LIMITS",
    "arm_figure",
    "nice_factor",
    "trajectory_figure",
]

#: Jerk panels of figure 6 show at most this multiple of the jerk limit (a method that does not
#: limit jerk, TOPP-RA, would squash the others); what is cut off is stated on the panel.
JERK_VIEW_LIMITS = 1.6
#: Figure 7 looks at the path from its side, turned by this much (deg) so the arms do not overlap.
ARM_VIEW_TURN_DEG = 35.0


# ----------------------------------------------------------------------------- 6. trajectory
def _limit_lines(ax, lim: np.ndarray | None, colours: Sequence[str]) -> None:
    if lim is None:
        return
    lim = np.asarray(lim, dtype=float)
    if np.allclose(lim, lim[0]):
        for s in (1, -1):
            ax.axhline(s * lim[0], color="k", ls="--", lw=1.0, label="limit" if s == 1 else None)
    else:
        for j, l in enumerate(lim):
            for s in (1, -1):
                ax.axhline(
                    s * l,
                    color=colours[j],
                    ls="--",
                    lw=0.8,
                    label="limits (per joint, dashed)" if (j == 0 and s == 1) else None,
                )


@styled
def trajectory_figure(
    trajs: Mapping[str, Mapping[str, np.ndarray]],
    limits: Mapping[str, np.ndarray | None],
    *,
    title: str,
    headers: Mapping[str, str] | None = None,
) -> Figure:
    """Joint position, velocity, acceleration and jerk against time, with limits.

    All panels share the time axis (the methods' durations compare at a glance) and
    each row its value axis; the jerk row shows at most :data:`JERK_VIEW_LIMITS` times
    the jerk limit and says what a method that does not limit jerk leaves outside.

    Parameters
    ----------
    trajs : mapping method -> {"t": (M,), "q", "qd", "qdd", "qddd": (M, 6)}
        One column per method (e.g. TOPP-RA, Ruckig); SI units (s, rad, rad/s ...).
        ``"qddd"`` is the jerk as the timing computed it; when it is None (a file
        written before the jerk was recorded) the jerk panel says so.
    limits : mapping with keys "q_min", "q_max", "velocity", "acceleration", "jerk"
        Arrays (6,) or None; drawn as dashed lines (position limits only if in view).
    headers : mapping method -> str, optional
        Column titles (duration, limit ratios).
    """
    methods = list(trajs)
    fig = new_figure(
        5.8 * max(1, len(methods)) + 0.8, 10.5, left=0.08, right=0.985, bottom=0.05, top=0.88, wspace=0.12, hspace=0.25
    )
    axs = np.atleast_2d(fig.subplots(4, len(methods), sharex="all", sharey="row", squeeze=False))
    rows = (
        ("q", "q [rad]", None),
        ("qd", "q̇ [rad/s]", "velocity"),
        ("qdd", "q̈ [rad/s²]", "acceleration"),
        ("jerk", "jerk [rad/s³]", "jerk"),
    )
    q_all = np.concatenate([np.asarray(trajs[m]["q"], float).ravel() for m in methods]) if methods else np.zeros(1)
    qlo, qhi = float(np.nanmin(q_all)), float(np.nanmax(q_all))
    qpad = 0.1 * max(qhi - qlo, 1e-3)
    jlim = limits.get("jerk")
    jview = JERK_VIEW_LIMITS * float(np.max(jlim)) if jlim is not None else None
    for c, m in enumerate(methods):
        tr = trajs[m]
        t = np.asarray(tr["t"], float)
        data = {"q": tr["q"], "qd": tr["qd"], "qdd": tr["qdd"], "jerk": tr.get("qddd")}
        for r, (key, ylabel, lim_key) in enumerate(rows):
            ax = axs[r, c]
            if c == 0:
                ax.set_ylabel(ylabel)
            ax.grid(alpha=0.3)
            if r == 3:
                ax.set_xlabel("time t [s]")
            if data[key] is None:
                ax.text(
                    0.5,
                    0.5,
                    "jerk not recorded in this trajectory file\n(no qddd columns)",
                    transform=ax.transAxes,
                    ha="center",
                    va="center",
                )
                continue
            y = np.asarray(data[key], float)
            for j in range(y.shape[1]):
                ax.plot(t, y[:, j], color=JOINT_COLOURS[j % 6], lw=1.0, label=f"joint {j + 1}")
            if key == "q":
                _position_panel(ax, limits, qlo, qhi, qpad, (headers or {}).get(m, m))
            else:
                _limit_lines(ax, limits.get(lim_key), JOINT_COLOURS)
            if key == "jerk" and jview is not None:
                _jerk_cut_note(ax, y, jview, float(np.max(jlim)))
    if jview is not None:
        axs[3, 0].set_ylim(-jview, jview)
    handles, labels = axs[1, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", ncol=len(labels), bbox_to_anchor=(0.5, 0.965), frameon=False)
    fig.suptitle(title)
    return fig


def _position_panel(
    ax: Any, limits: Mapping[str, np.ndarray | None], qlo: float, qhi: float, qpad: float, header: str
) -> None:
    """The position panel's view, the joint limits within it, and its column title (``header``)."""
    ax.set_ylim(qlo - qpad, qhi + qpad)
    qmin, qmax = limits.get("q_min"), limits.get("q_max")
    shown = False
    if qmin is not None and qmax is not None:
        for j in range(len(qmin)):
            for v in (qmin[j], qmax[j]):
                if qlo - qpad <= v <= qhi + qpad:
                    ax.axhline(v, color=JOINT_COLOURS[j], ls="--", lw=0.8)
                    shown = True
    note = ""
    if qmin is not None and qmax is not None and not shown:
        note = (
            f"\nposition limits outside the view (joint ranges "
            f"{format_number(float(np.min(qmin)))} … {format_number(float(np.max(qmax)))} rad)"
        )
    ax.set_title(header + note)


def _jerk_cut_note(ax: Any, y: np.ndarray, jview: float, jerk_limit: float) -> None:
    """Say on the jerk panel what is cut off when the samples' peak |jerk| passes the view ``jview``."""
    peak = float(np.nanmax(np.abs(y))) if y.size else 0.0
    if peak > jview:
        ax.text(
            0.5,
            0.97,
            f"peak |jerk| of the samples {format_number(peak)} rad/s³ = "
            f"{format_number(peak / jerk_limit)}× the limit: cut off "
            "(this method does not limit jerk)",
            transform=ax.transAxes,
            ha="center",
            va="top",
            fontsize=8,
            bbox={"facecolor": "#fff4e0", "edgecolor": "#e0a030"},
        )


# --------------------------------------------------------------------------------- 7. arm 3-D
def nice_factor(max_deflection_m: float, target_m: float = 0.05) -> float:
    """An exaggeration factor 1, 2 or 5 x 10^k that makes the deflection about ``target_m``."""
    if not (max_deflection_m > 0 and math.isfinite(max_deflection_m)):
        return 1.0
    raw = target_m / max_deflection_m
    if raw <= 1.0:
        return 1.0
    e = 10 ** math.floor(math.log10(raw))
    for m in (5, 2, 1):
        if m * e <= raw:
            return float(m * e)
    return float(e)


@styled
def arm_figure(
    nominal_m: np.ndarray,
    deflected_m: np.ndarray,
    path_m: np.ndarray,
    labels: Sequence[str],
    factor: float,
    *,
    title: str,
    joint_index: Sequence[int] | None = None,
) -> Figure:
    """The arm drawn in 3-D at a few poses: links between joint centres, nominal and
    (exaggerated) deflected, on equal axes.

    Parameters
    ----------
    nominal_m, deflected_m : ndarray, shape (P, L, 3)
        Polyline points per pose, m: base, the joint centres along the chain, the TCP.
    path_m : ndarray, shape (N, 3)
        Target TCP path, m.
    labels : sequence of str, length P
        Pose names (e.g. ``"k = 0"``), written at each pose's TCP.
    factor : float
        Deflection exaggeration factor (stated in the legend).
    joint_index : sequence of int, optional
        Which polyline points are joint centres (drawn as dots); default all but the
        first (base) and the last (TCP).
    """
    fig = new_figure(9.5, 7.4)
    ax = fig.add_axes((0.0, 0.05, 1.0, 0.83), projection="3d")
    P, L = nominal_m.shape[:2]
    joints = list(joint_index) if joint_index is not None else list(range(1, L - 1))
    # look at the path from its side, turned by ARM_VIEW_TURN_DEG so the depth shows
    azim = _view_azimuth(path_m)
    size = float(np.ptp(np.concatenate([nominal_m.reshape(-1, 3), path_m]), axis=0).max())
    label_offset = np.array([0.0, 0.0, -0.06 * size])
    ax.plot(*path_m.T, color="0.35", lw=1.2, ls="-", zorder=1)
    for p in range(P):
        c = f"C{p % 10}"
        nom, dfl = nominal_m[p], deflected_m[p]
        _draw_pose(ax, nom, dfl, joints, labels[p], c, label_offset)
    ax.scatter([0.0], [0.0], [0.0], color="k", marker="s", s=40, depthshade=False)
    pts = np.concatenate([nominal_m.reshape(-1, 3), deflected_m.reshape(-1, 3), path_m, np.zeros((1, 3))])
    _equal_axes(ax, pts)
    for setter in (ax.xaxis, ax.yaxis, ax.zaxis):
        setter.set_major_locator(matplotlib.ticker.MaxNLocator(4))
        setter.pane.set_alpha(0.15)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    handles = _arm_handles(factor)
    fig.legend(handles=handles, loc="upper center", ncol=3, bbox_to_anchor=(0.5, 0.925), frameon=False, fontsize=8)
    ax.view_init(elev=18, azim=azim)
    fig.suptitle(title, y=0.985)
    return fig


def _view_azimuth(path_m: np.ndarray) -> float:
    """The 3-D view's azimuth, deg: the path (N, 3), m, seen from its side, turned by ARM_VIEW_TURN_DEG."""
    run_xy = path_m[-1, :2] - path_m[0, :2] if len(path_m) > 1 else np.array([1.0, 0.0])
    return (
        math.degrees(math.atan2(run_xy[1], run_xy[0])) - 90.0 - ARM_VIEW_TURN_DEG
        if np.linalg.norm(run_xy) > 1e-6
        else -60.0
    )


def _draw_pose(
    ax: Any, nom: np.ndarray, dfl: np.ndarray, joints: Sequence[int], label: str, c: str, label_offset: np.ndarray
) -> None:
    """One pose: the deflected polyline dashed, the nominal one solid with joint dots, the TCP marked and named."""
    ax.plot(*dfl.T, color=c, lw=1.1, ls="--", alpha=0.9)
    ax.plot(*nom.T, color=c, lw=3.0, solid_capstyle="round")
    ax.scatter(*nom[joints].T, color="white", edgecolor=c, s=22, depthshade=False, zorder=5)
    ax.scatter(*nom[-1], color=c, marker="v", s=40, depthshade=False)
    ax.text(
        *(nom[-1] + label_offset),
        label,
        color=c,
        fontsize=9,
        ha="center",
        va="center",
        bbox={"facecolor": "white", "alpha": 0.8, "edgecolor": "none", "pad": 1.0},
        zorder=10,
    )


def _equal_axes(ax: Any, pts: np.ndarray) -> None:
    """Limits around ``pts`` (K, 3), m, padded, at equal scale on the three axes."""
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = 0.05 * float(np.max(hi - lo))
    lo, hi = lo - pad, hi + pad
    span = np.maximum(hi - lo, 1e-3)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_zlim(lo[2], hi[2])
    ax.set_box_aspect(span)  # equal scale on the three axes


def _arm_handles(factor: float) -> list[Line2D]:
    """The arm figure's legend entries (the deflection exaggerated ×``factor``)."""
    return [
        Line2D(
            [],
            [],
            color="0.2",
            lw=3.0,
            marker="o",
            mfc="white",
            ms=5,
            label="planned pose, TCP on the path (links between joint centres)",
        ),
        Line2D(
            [],
            [],
            color="0.2",
            lw=1.1,
            ls="--",
            label=f"the same command under the load, uncompensated: joint deflection ×{factor:g}",
        ),
        Line2D([], [], color="0.35", lw=1.2, label="target TCP path"),
        Line2D([], [], color="k", marker="s", ls="", label="base origin"),
        Line2D([], [], color="0.2", marker="v", ls="", label="TCP"),
    ]
