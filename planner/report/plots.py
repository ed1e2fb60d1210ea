"""The report's drawings: pure functions from arrays to matplotlib Figures.

Every function takes plain arrays (SI units: m, rad, N, s) and returns a
:class:`matplotlib.figure.Figure` attached to the Agg canvas, so nothing here
needs a display, touches pyplot's global state or prints.  Conversions to the
units shown (mm, deg, N/mm) happen here, at the edge, and every axis names its
unit.  Path figures are drawn against the path length (mm), not the waypoint
index.  :func:`render` turns a figure into PNG and PDF bytes.  Which data goes
into which figure is decided in :mod:`planner.report.figures`.

Figure numbering follows issue 3 (see ``docs/paper-reproduction.md`` for the
paper figure each one reproduces).
"""

from __future__ import annotations

import math
from typing import Any
from collections.abc import Mapping, Sequence

import matplotlib
import matplotlib.ticker
import numpy as np
from matplotlib.backends import backend_pdf  # noqa: F401  (imported once, before any fork)
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch, Rectangle
from mpl_toolkits.axes_grid1 import make_axes_locatable
from mpl_toolkits.mplot3d import Axes3D  # noqa: F401  (registers the 3-D projection)

from planner.numbers import NUMERICAL_FLOOR_MM, NUMERICAL_FLOOR_RAD, format_number
from planner.report.figure_base import PNG_COMPRESS_LEVEL, PNG_DPI, STYLE, new_figure, pdf_bytes, png_bytes, styled

#: Colours: one per base axis X, Y, Z and one per joint 1..6.
AXIS_COLOURS = ("tab:blue", "tab:orange", "tab:green")
JOINT_COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown")
#: Colours of the chosen and the default IK branch (figure 5).
CHOSEN_COLOUR, DEFAULT_COLOUR, OTHER_COLOUR = "tab:red", "tab:blue", "0.62"

#: A map whose (max - min) / |mean| is below this is drawn as one colour and labelled constant.
CONSTANT_REL_SPREAD = 1e-6
#: Angle units of figure 3, largest first: (name, degrees per unit); the first one in which the
#: largest magnitude is at least 0.1 is used.
ANGLE_UNITS = (("deg", 1.0), ("mdeg", 1e-3), ("µdeg", 1e-6))


def render(fig: Figure, dpi: int = PNG_DPI) -> tuple[bytes, bytes]:
    """PNG and PDF bytes of ``fig`` (metadata fixed so output is reproducible)."""
    png = render_png(fig, dpi)
    return png, pdf_bytes(fig, STYLE)


def render_png(fig: Figure, dpi: int = PNG_DPI) -> bytes:
    """PNG bytes of ``fig``, as :func:`render` writes them."""
    return png_bytes(fig, dpi, PNG_COMPRESS_LEVEL, STYLE)


def _angle_unit(values_rad: np.ndarray) -> tuple[str, float]:
    """Unit name and factor (rad -> unit) that shows ``values_rad`` readably (:data:`ANGLE_UNITS`)."""
    peak = float(np.nanmax(np.abs(values_rad))) if np.size(values_rad) else 0.0
    peak_deg = math.degrees(peak)
    for name, deg in ANGLE_UNITS:
        if peak_deg / deg >= 0.1:
            return name, 180.0 / math.pi / deg
    name, deg = ANGLE_UNITS[-1]
    return name, 180.0 / math.pi / deg


# ----------------------------------------------------------------------------- 1. compliance map
def _heat_panel(
    fig: Figure, ax: Any, values: np.ndarray, extent: tuple[float, float, float, float], label: str, unit: str
) -> None:
    """One heat map (rows = v, columns = u; NaN unreachable, hatched) with its colour bar; a map
    constant to :data:`CONSTANT_REL_SPREAD` gets one colour and its value written on it."""
    data = np.ma.masked_invalid(values)
    ax.add_patch(
        Rectangle(
            (extent[0], extent[2]),
            extent[1] - extent[0],
            extent[3] - extent[2],
            facecolor="white",
            edgecolor="0.6",
            hatch="///",
            linewidth=0,
            zorder=0,
        )
    )
    finite = data.compressed()
    if not finite.size:
        ax.text(0.5, 0.5, "no reachable point", transform=ax.transAxes, ha="center", va="center")
        return
    lo, hi = float(finite.min()), float(finite.max())
    mean = float(finite.mean())
    constant = hi - lo <= CONSTANT_REL_SPREAD * max(abs(mean), 1e-300)
    if constant:  # uniform colour; the value is written on the panel
        lo, hi = mean - 0.01 * abs(mean) - 1e-300, mean + 0.01 * abs(mean) + 1e-300
    mesh = ax.imshow(
        data,
        origin="lower",
        extent=extent,
        aspect="equal",
        cmap="viridis",
        norm=Normalize(lo, hi),
        interpolation="nearest",
        zorder=1,
    )
    cax = make_axes_locatable(ax).append_axes("right", size="5%", pad=0.06)
    cb = fig.colorbar(mesh, cax=cax)
    cb.set_label(label)
    cb.formatter.set_useOffset(False)
    cb.update_ticks()
    if constant:
        spread = (float(finite.max()) - float(finite.min())) / max(abs(mean), 1e-300)
        ax.text(
            0.5,
            0.5,
            f"constant over the plane:\n{mean:.4g} {unit}\n(relative spread {spread:.1e})",
            transform=ax.transAxes,
            ha="center",
            va="center",
            fontsize=8,
            bbox={"facecolor": "white", "alpha": 0.9, "edgecolor": "0.5"},
            zorder=8,
        )


def _path_overlay(ax: Any, path_uv_m: np.ndarray) -> None:
    """The run's path on a map panel (m, plane coordinates): a line, ● at the start, ▶ at the end."""
    ax.plot(path_uv_m[:, 0], path_uv_m[:, 1], color="white", lw=3.2, zorder=5)
    ax.plot(path_uv_m[:, 0], path_uv_m[:, 1], color="crimson", lw=1.6, zorder=6)
    ax.plot(*path_uv_m[0], marker="o", color="crimson", mec="white", ms=6, zorder=7)
    ax.plot(*path_uv_m[-1], marker=">", color="crimson", mec="white", ms=6, zorder=7)


#: The compliance map's six panels: factor from SI, unit, and what each diagonal compliance is.
_MAP_SCALE = (1e3, 1e3, 1e3, 180.0 / math.pi, 180.0 / math.pi, 180.0 / math.pi)
_MAP_UNITS = ("mm/N", "mm/N", "mm/N", "deg/(N·m)", "deg/(N·m)", "deg/(N·m)")
_MAP_WHAT = (
    "x displacement per N along x",
    "y displacement per N along y",
    "z displacement per N along z",
    "rotation about x per N·m about x",
    "rotation about y per N·m about y",
    "rotation about z per N·m about z",
)


def _map_handles(
    branch: np.ndarray | None, branch_labels: Sequence[str], path_uv_m: np.ndarray | None, path_label: str
) -> list[Any]:
    """The compliance map's legend: unreachable, the path if drawn, the branch boundaries if any (``branch``)."""
    handles: list[Any] = [
        Patch(facecolor="white", edgecolor="0.4", hatch="///", label="unreachable (no IK solution at this attitude)")
    ]
    if path_uv_m is not None and len(path_uv_m):
        handles.append(
            Line2D([], [], color="crimson", lw=1.6, marker="o", ms=5, label=path_label or "the run's path (● start)")
        )
    if branch is not None:
        used = sorted({branch_labels[int(b)] for b in np.unique(branch[branch >= 0])}) if branch_labels else []
        handles.append(Line2D([], [], color="k", lw=0.8, label=f"branch changes ({', '.join(used)})"))
    return handles


@styled
def compliance_map_figure(
    u_m: np.ndarray,
    v_m: np.ndarray,
    diag: np.ndarray,
    *,
    u_label: str,
    v_label: str,
    title: str,
    branch: np.ndarray | None = None,
    branch_labels: Sequence[str] = (),
    path_uv_m: np.ndarray | None = None,
    path_label: str = "",
) -> Figure:
    """Paper Fig. 5: the six diagonal compliances as a 2x3 grid of heat maps.

    Parameters
    ----------
    u_m, v_m : ndarray, shapes (nu,), (nv,)
        Grid coordinates, m (horizontal and vertical axes).
    diag : ndarray, shape (nu, nv, 6)
        ``C11..C33`` in m/N and ``C44..C66`` in rad/(N*m); NaN = unreachable
        (drawn hatched).
    u_label, v_label : str
        Axis names (e.g. ``"y"``); the unit [m] is appended.
    title : str
        Figure title (robot, plane, attitude, branch rule, unreachable count).
    branch : ndarray of int, shape (nu, nv), optional
        Branch index per point; where it changes, a black boundary is drawn.
    branch_labels : sequence of str
        Labels of the branch indices (for the boundary legend).
    path_uv_m : ndarray, shape (N, 2), optional
        The run's path in the plane's coordinates (m), drawn on every panel (start marked).
    path_label : str
        What the path line is (legend), e.g. "path (in the plane)".
    """
    aspect = float(np.clip((v_m[-1] - v_m[0]) / max(u_m[-1] - u_m[0], 1e-12), 0.4, 1.2))
    height = 2.0 * (2.75 * aspect + 0.85) + 1.7  # two rows of panels at equal scale, title, legend
    fig = new_figure(
        12.5,
        height,
        left=0.055,
        right=0.925,
        bottom=0.65 / height,
        top=1.0 - 1.2 / height,
        wspace=0.45,
        hspace=0.7 / (2.75 * aspect),
    )
    axs = fig.subplots(2, 3)
    du = (u_m[-1] - u_m[0]) / max(1, len(u_m) - 1) / 2
    dv = (v_m[-1] - v_m[0]) / max(1, len(v_m) - 1) / 2
    extent = (u_m[0] - du, u_m[-1] + du, v_m[0] - dv, v_m[-1] + dv)
    scale, units, what = _MAP_SCALE, _MAP_UNITS, _MAP_WHAT
    multi = branch is not None and len(np.unique(branch[branch >= 0])) > 1
    for i, ax in enumerate(axs.ravel()):
        _heat_panel(fig, ax, diag[..., i].T * scale[i], extent, f"C{i + 1}{i + 1} [{units[i]}]", units[i])
        if multi:
            ax.contour(
                u_m,
                v_m,
                np.ma.masked_less(branch.T, 0).astype(float),
                levels=np.arange(-0.5, 8.5, 1.0),
                colors="k",
                linewidths=0.8,
                zorder=2,
            )
        if path_uv_m is not None and len(path_uv_m):
            _path_overlay(ax, path_uv_m)
        ax.set_xlim(extent[0], extent[1])
        ax.set_ylim(extent[2], extent[3])
        ax.set_xlabel(f"{u_label} [m]")
        ax.set_ylabel(f"{v_label} [m]")
        ax.set_title(f"({'abcdef'[i]}) C{i + 1}{i + 1}: {what[i]}")
    handles = _map_handles(branch if multi else None, branch_labels, path_uv_m, path_label)
    fig.legend(handles=handles, loc="lower center", ncol=len(handles), frameon=False, bbox_to_anchor=(0.5, 0.0))
    fig.suptitle(title)
    return fig


# ------------------------------------------------------------- 2. stiffness and error along path
@styled
def stiffness_error_figure(
    s_mm: np.ndarray, stiffness_n_per_m: np.ndarray, error_m: np.ndarray, *, title: str
) -> Figure:
    """Paper Figs. 6-7: directional stiffness and load-induced TCP error along the path.

    Parameters
    ----------
    s_mm : ndarray, shape (N,)
        Path length from the first waypoint, mm.
    stiffness_n_per_m : ndarray, shape (N, 3)
        ``1 / (u^T C_tt u)`` along base x, y, z, N/m (drawn in N/mm on a log axis).
    error_m : ndarray, shape (N, 3)
        TCP position error under load, uncompensated, base frame, m.
    """
    fig = new_figure(11.0, 4.6, left=0.07, right=0.985, bottom=0.12, top=0.83, wspace=0.24)
    a1, a2 = fig.subplots(1, 2, sharex=True)
    for j, name in enumerate("XYZ"):
        a1.plot(
            s_mm, stiffness_n_per_m[:, j] * 1e-3, color=AXIS_COLOURS[j], marker=".", ms=3, label=f"along base {name}"
        )
        a2.plot(
            s_mm, error_m[:, j] * 1e3, color=AXIS_COLOURS[j], marker=".", ms=3, label=f"Δ{name.lower()} (base {name})"
        )
    a2.plot(s_mm, np.linalg.norm(error_m, axis=1) * 1e3, color="k", ls="--", label="|Δ| (norm)")
    a1.set_yscale("log")
    a1.yaxis.set_major_locator(matplotlib.ticker.LogLocator(subs=(1.0, 2.0, 5.0)))
    a1.yaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _pos: f"{v:g}"))
    a1.yaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    a1.set_ylabel("directional stiffness 1/(uᵀCu) [N/mm], log scale")
    a1.set_title("(a) stiffness along base X, Y, Z (paper Fig. 6)")
    a2.set_ylabel("TCP position error [mm]")
    a2.set_title("(b) load-induced TCP error, no compensation (paper Fig. 7)")
    a2.axhline(0.0, color="0.5", lw=0.6)
    for a in (a1, a2):
        a.set_xlabel("path length from the first waypoint [mm]")
        a.grid(alpha=0.3, which="both")
        a.legend(loc="best")
    fig.suptitle(title)
    return fig


# --------------------------------------------------------------------- 3. compensation angles
@styled
def compensation_figure(
    s_mm: np.ndarray, dq_exact_rad: np.ndarray, dq_closed_rad: np.ndarray | None, *, title: str
) -> Figure:
    """Paper Fig. 8: compensation angle ``q_command - q_target`` per joint along the path, and
    the difference exact minus closed form, each joint in the unit that shows it (deg, mdeg, µdeg).

    Parameters
    ----------
    s_mm : ndarray, shape (N,)
        Path length from the first waypoint, mm.
    dq_exact_rad, dq_closed_rad : ndarray, shape (N, 6)
        Exact and closed-form compensation angles, rad (closed form optional).
    """
    rows = 4 if dq_closed_rad is not None else 2
    height = 2.35 * rows + 1.2
    fig = new_figure(
        12.0, height, left=0.075, right=0.985, bottom=0.6 / height, top=1.0 - 0.75 / height, wspace=0.36, hspace=0.55
    )
    axs = fig.subplots(rows, 3, sharex=True)
    legend_done = False
    for j in range(6):
        r0 = (j // 3) * (2 if dq_closed_rad is not None else 1)
        ax = axs[r0, j % 3]
        y = dq_exact_rad[:, j]
        if np.all(np.abs(y) < NUMERICAL_FLOOR_RAD):
            ax.plot(s_mm, np.zeros_like(s_mm), color=JOINT_COLOURS[j], lw=1.8)
            ax.text(
                0.5,
                0.72,
                f"Δθ{j + 1} = 0 on the whole path\n(|Δθ{j + 1}| < {NUMERICAL_FLOOR_RAD:g} rad: "
                f"no load torque on joint {j + 1})",
                transform=ax.transAxes,
                ha="center",
                va="center",
                fontsize=8,
                bbox={"facecolor": "white", "alpha": 0.9, "edgecolor": "0.6"},
            )
            ax.set_ylim(-1.0, 1.0)
            ax.set_yticks([-1.0, 0.0, 1.0])
            unit, f = "deg", 180.0 / math.pi
        else:
            both = y if dq_closed_rad is None else np.r_[y, dq_closed_rad[:, j]]
            unit, f = _angle_unit(both)
            ax.plot(s_mm, y * f, color=JOINT_COLOURS[j], lw=1.8, label="exact")
            if dq_closed_rad is not None:
                ax.plot(
                    s_mm, dq_closed_rad[:, j] * f, color="k", lw=1.0, ls="--", label="closed form (paper eqs. 32/47)"
                )
            ax.axhline(0.0, color="0.5", lw=0.6)
        ax.set_title(f"joint {j + 1}: compensation angle Δθ{j + 1}")
        ax.set_ylabel(f"Δθ{j + 1} [{unit}]")
        ax.grid(alpha=0.3)
        ax.ticklabel_format(axis="y", useOffset=False, style="plain")
        if not legend_done and ax.get_legend_handles_labels()[0]:
            ax.legend(loc="best")
            legend_done = True
        if dq_closed_rad is not None:
            _difference_panel(axs[r0 + 1, j % 3], s_mm, dq_exact_rad[:, j] - dq_closed_rad[:, j], j)
    for ax in axs[-1]:
        ax.set_xlabel("path length from the first waypoint [mm]")
    fig.suptitle(title)
    return fig


def _difference_panel(bx: Any, s_mm: np.ndarray, d: np.ndarray, j: int) -> None:
    """One joint's exact minus closed-form compensation angle (``d`` (N,), rad) on ``bx``."""
    if np.all(np.abs(d) < NUMERICAL_FLOOR_RAD):
        bx.plot(s_mm, np.zeros_like(s_mm), color="0.25", lw=1.2)
        bx.text(
            0.5,
            0.72,
            f"0 (numerical: < {NUMERICAL_FLOOR_RAD:g} rad)",
            transform=bx.transAxes,
            ha="center",
            va="center",
            fontsize=8,
        )
        bx.set_ylim(-1.0, 1.0)
        bx.set_yticks([-1.0, 0.0, 1.0])
        du = "deg"
    else:
        du, fd = _angle_unit(d)
        bx.plot(s_mm, d * fd, color="0.25", lw=1.2)
        bx.axhline(0.0, color="0.5", lw=0.6)
    bx.set_title(f"joint {j + 1}: exact − closed form", fontsize=8.5)
    bx.set_ylabel(f"difference [{du}]")
    bx.grid(alpha=0.3)
    bx.ticklabel_format(axis="y", useOffset=False, style="plain")


# ---------------------------------------------------------------------- 4. error before/after
@styled
def error_before_after_figure(
    s_mm: np.ndarray, before_m: np.ndarray, closed_m: np.ndarray, exact_m: np.ndarray, *, title: str
) -> Figure:
    """Paper Figs. 9 and 13: TCP error before and after compensation, per axis.

    Top row: before vs. after (mm, one scale).  Bottom row: after only, in µm,
    so the residual of the closed form is readable; the exact residual, at the
    level of the equilibrium solve, is stated as 0 (numerical) when it is below
    :data:`~planner.numbers.NUMERICAL_FLOOR_MM`.

    Parameters
    ----------
    s_mm : ndarray, shape (N,)
        Path length from the first waypoint, mm.
    before_m, closed_m, exact_m : ndarray, shape (N, 3)
        TCP position error (reached - target), base frame, m.
    """
    fig = new_figure(12.0, 7.0, left=0.065, right=0.985, bottom=0.08, top=0.86, wspace=0.3, hspace=0.32)
    axs = fig.subplots(2, 3, sharex=True)
    exact_zero = bool(np.all(np.abs(exact_m) * 1e3 < NUMERICAL_FLOOR_MM))
    exact_label = "after exact compensation: 0 (numerical)" if exact_zero else "after exact compensation"
    for j, name in enumerate("xyz"):
        top, bot = axs[0, j], axs[1, j]
        top.plot(s_mm, before_m[:, j] * 1e3, color=AXIS_COLOURS[j], lw=1.8, label="before compensation")
        top.plot(s_mm, closed_m[:, j] * 1e3, color="k", ls="--", lw=1.0, label="after closed-form compensation (paper)")
        top.plot(s_mm, exact_m[:, j] * 1e3, color="tab:red", ls=":", lw=1.4, label=exact_label)
        top.set_ylabel(f"Δ{name} [mm]")
        top.set_title(f"base {name.upper()}: before and after")
        bot.plot(s_mm, closed_m[:, j] * 1e6, color="k", ls="--", lw=1.0, label="after closed-form compensation (paper)")
        bot.plot(s_mm, exact_m[:, j] * 1e6, color="tab:red", ls=":", lw=1.4, label=exact_label)
        bot.set_ylabel(f"Δ{name} after compensation [µm]")
        bot.set_xlabel("path length from the first waypoint [mm]")
        bot.set_title(f"base {name.upper()}: residual after compensation")
        for a in (top, bot):
            a.axhline(0.0, color="0.5", lw=0.6)
            a.grid(alpha=0.3)
            if j == 0:  # same styles in every column: one legend per row
                a.legend(loc="best")
    fig.suptitle(title)
    return fig


# ----------------------------------------------------------------------- 5. branch comparison
@styled
def _branch_ticks(labels: Sequence[str], chosen: str | None, default: str | None) -> list[str]:
    """Tick labels of the branch bars: long labels (OPW: front-up-noflip) two parts a line, so
    neighbouring ticks do not overlap; the chosen and the default branch marked."""
    return [
        (lab.replace("-", "\n", 2).replace("\n", "-", 1) if len(lab) > 8 else lab)
        + ("\nchosen" if lab == chosen else "\ndefault" if lab == default else "")
        for lab in labels
    ]


def branch_figure(
    labels: Sequence[str],
    rms_analytic_mm: Sequence[float],
    rms_optimised_mm: Sequence[float] | None,
    infeasible: Mapping[str, str],
    s_mm: np.ndarray,
    curves_mm: Mapping[str, np.ndarray],
    chosen: str | None,
    default: str | None,
    *,
    title: str,
    note: str = "",
    x_label: str = "path length from the first waypoint [mm]",
) -> Figure:
    """IK branch comparison: RMS load-induced error per branch (bars) and, along the path, the
    chosen and the default branch.

    Parameters
    ----------
    labels : sequence of str
        Every branch label, in order (feasible or not).
    rms_analytic_mm, rms_optimised_mm : sequence of float
        RMS error (mm, exact equilibrium) of each branch at its analytic and its optimised
        posture (NaN where the branch is not feasible or has no analytic posture);
        ``rms_optimised_mm`` None when the run has no optimised postures.
    infeasible : mapping label -> str
        Why a branch cannot follow the path (written on its empty bar slot).
    s_mm : ndarray, shape (N,)
        Path length, mm.
    curves_mm : mapping name -> ndarray (N,)
        Error norm along the path (mm) to draw in panel (b), e.g. ``"s-w-e- (chosen), optimised"``.
    chosen, default : str, optional
        Labels of the chosen and the default branch (coloured and marked).
    note : str
        Extra line at the bottom (e.g. why branches are not feasible).
    x_label : str
        Label of the path axis of panel (b) (the path length, or the waypoint index when
        the run has no waypoint positions).
    """
    ticks = _branch_ticks(labels, chosen, default)
    n_lines = max(t.count("\n") + 1 for t in ticks) if ticks else 1
    fig = new_figure(
        12.5,
        5.2 + 0.15 * max(0, n_lines - 2),
        left=0.06,
        right=0.985,
        bottom=0.2 + 0.035 * max(0, n_lines - 2),
        top=0.84,
        wspace=0.22,
    )
    a1, a2 = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.15, 1.0]})
    x = np.arange(len(labels))
    ana = np.asarray(rms_analytic_mm, float)
    opt = None if rms_optimised_mm is None else np.asarray(rms_optimised_mm, float)
    same = opt is None or np.allclose(np.nan_to_num(opt, nan=-1.0), np.nan_to_num(ana, nan=-1.0), rtol=1e-9, atol=1e-12)
    colours = [CHOSEN_COLOUR if lab == chosen else DEFAULT_COLOUR if lab == default else OTHER_COLOUR for lab in labels]
    top = (
        np.nanmax(np.r_[ana, opt if opt is not None else []])
        if np.isfinite(ana).any() or (opt is not None and np.isfinite(opt).any())
        else 1.0
    )
    _branch_bars(a1, x, labels, ana, opt, colours, same, infeasible, top)
    a1.set_xticks(x, ticks, fontsize=8)
    a1.set_ylabel("RMS load-induced TCP error [mm]")
    a1.set_ylim(0.0, top * 1.15 if top > 0 else 1.0)  # no load: every error 0
    a1.set_title("(a) RMS error per IK branch" + ("" if same else " (analytic hatched, optimised solid)"))
    a1.grid(alpha=0.3, axis="y")
    _branch_curves(a2, s_mm, curves_mm)
    a2.set_xlabel(x_label)
    a2.set_ylabel("load-induced TCP error |Δ| [mm]")
    a2.set_ylim(bottom=0.0)
    a2.set_title("(b) along the path: the chosen and the default branch")
    a2.grid(alpha=0.3)
    a2.legend(loc="best")
    if note:
        fig.text(0.5, 0.015, note, ha="center", va="bottom", fontsize=8, color="0.3")
    fig.suptitle(title)
    return fig


def _branch_bars(
    a1: Any,
    x: np.ndarray,
    labels: Sequence[str],
    ana: np.ndarray,
    opt: np.ndarray | None,
    colours: Sequence[str],
    same: bool,
    infeasible: Mapping[str, str],
    top: float,
) -> None:
    """Panel (a) of the branch figure: the RMS bars (analytic hatched beside optimised unless the
    same), each with its value or "not feasible"."""
    if same:
        vals = opt if opt is not None else ana
        a1.bar(x, np.nan_to_num(vals), color=colours, width=0.7)
        shown = vals
    else:
        a1.bar(
            x - 0.18,
            np.nan_to_num(ana),
            color=colours,
            alpha=0.35,
            width=0.36,
            hatch="//",
            edgecolor="0.3",
            label="analytic posture",
        )
        a1.bar(x + 0.18, np.nan_to_num(opt), color=colours, width=0.36, label="optimised posture")
        shown = opt
        a1.legend(loc="upper left")
    for i, lab in enumerate(labels):
        v = shown[i] if shown is not None else np.nan
        if np.isfinite(v):
            a1.text(x[i], v + 0.015 * top, format_number(v), ha="center", va="bottom", fontsize=8)
        elif lab in infeasible:
            a1.text(x[i], 0.03 * top, "not feasible", rotation=90, ha="center", va="bottom", fontsize=8, color="0.35")


def _branch_curves(a2: Any, s_mm: np.ndarray, curves_mm: Mapping[str, np.ndarray]) -> None:
    """Panel (b) of the branch figure: the error along the path of each curve, styled by its name."""
    styles = {"chosen": (CHOSEN_COLOUR, "-", 2.4), "default": (DEFAULT_COLOUR, "--", 1.6)}
    for name, y in curves_mm.items():
        kind = "chosen" if "chosen" in name else "default" if "default" in name else ""
        c, ls, lw = styles.get(kind, (OTHER_COLOUR, ":", 1.2))
        if "analytic" in name and kind == "chosen":
            ls, lw = ":", 1.4
        a2.plot(s_mm, y, color=c, ls=ls, lw=lw, label=name)


__all__ = [
    "JOINT_COLOURS",
    "PNG_DPI",
    "branch_figure",
    "compensation_figure",
    "compliance_map_figure",
    "error_before_after_figure",
    "render",
    "stiffness_error_figure",
]
