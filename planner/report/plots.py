"""The report's drawings: pure functions from arrays to matplotlib Figures.

Every function takes plain arrays (SI units: m, rad, N, s) and returns a
:class:`matplotlib.figure.Figure` attached to the Agg canvas, so nothing here
needs a display, touches pyplot's global state or prints.  Conversions to the
units shown (mm, deg, N/m) happen here, at the edge, and every axis names its
unit.  :func:`render` turns a figure into PNG and PDF bytes.  Which data goes
into which figure is decided in :mod:`planner.report.figures`.

Figure numbering follows issue 3 (see ``docs/paper-reproduction.md`` for the
paper figure each one reproduces).
"""

from __future__ import annotations

import functools
import io
import math
from typing import Mapping, Sequence

import matplotlib
import numpy as np
from matplotlib.backends import backend_pdf  # noqa: F401  (imported once, before any fork)
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle
from mpl_toolkits.mplot3d import Axes3D  # noqa: F401  (registers the 3-D projection)

#: PNG resolution (dots per inch): modest, keeps the report small and fast.
PNG_DPI = 100

#: Colours: one per base axis X, Y, Z and one per joint 1..6.
AXIS_COLOURS = ("tab:blue", "tab:orange", "tab:green")
JOINT_COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown")

#: A map whose (max - min) / |mean| is below this is drawn as one colour and labelled constant.
CONSTANT_REL_SPREAD = 1e-6

#: Style applied while a figure is built and saved (text sizes are fixed at creation).
STYLE = {"pdf.compression": 6, "font.size": 9, "axes.titlesize": 9, "legend.fontsize": 8,
         "figure.titlesize": 10}


def _styled(fn):
    """Build the figure under :data:`STYLE` without touching the global rc settings."""
    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        with matplotlib.rc_context(STYLE):
            return fn(*args, **kwargs)
    return wrapper


def _figure(width_in: float, height_in: float, **adjust: float) -> Figure:
    """A figure on the Agg canvas with fixed margins (``subplots_adjust`` keywords).

    Margins are set by hand rather than by the constrained-layout engine, which
    would double the drawing time (report generation has a time budget).
    """
    fig = Figure(figsize=(width_in, height_in))
    FigureCanvasAgg(fig)
    fig.subplots_adjust(**adjust)
    return fig


def render(fig: Figure, dpi: int = PNG_DPI) -> tuple[bytes, bytes]:
    """PNG and PDF bytes of ``fig`` (metadata fixed so output is reproducible)."""
    png, pdf = io.BytesIO(), io.BytesIO()
    with matplotlib.rc_context(STYLE):
        fig.savefig(png, format="png", dpi=dpi, metadata={"Software": None})
        fig.savefig(pdf, format="pdf", metadata={"CreationDate": None, "Creator": None,
                                                 "Producer": None})
    return png.getvalue(), pdf.getvalue()


# ----------------------------------------------------------------------------- 1. compliance map
@_styled
def compliance_map_figure(u_m: np.ndarray, v_m: np.ndarray, diag: np.ndarray, *,
                          u_label: str, v_label: str, title: str,
                          branch: np.ndarray | None = None,
                          branch_labels: Sequence[str] = ()) -> Figure:
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
    """
    fig = _figure(12.5, 8.2, left=0.055, right=0.93, bottom=0.065, top=0.83, wspace=0.55,
                  hspace=0.36)
    axs = fig.subplots(2, 3)
    du = (u_m[-1] - u_m[0]) / max(1, len(u_m) - 1) / 2
    dv = (v_m[-1] - v_m[0]) / max(1, len(v_m) - 1) / 2
    extent = (u_m[0] - du, u_m[-1] + du, v_m[0] - dv, v_m[-1] + dv)
    scale = (1e3, 1e3, 1e3, 180.0 / math.pi, 180.0 / math.pi, 180.0 / math.pi)
    units = ("mm/N", "mm/N", "mm/N", "deg/(N·m)", "deg/(N·m)", "deg/(N·m)")
    what = ("x displacement per N along x", "y displacement per N along y",
            "z displacement per N along z", "rotation about x per N·m about x",
            "rotation about y per N·m about y", "rotation about z per N·m about z")
    multi = branch is not None and len(np.unique(branch[branch >= 0])) > 1
    for i, ax in enumerate(axs.ravel()):
        data = np.ma.masked_invalid(diag[..., i].T * scale[i])   # rows = v, columns = u
        ax.add_patch(Rectangle((extent[0], extent[2]), extent[1] - extent[0], extent[3] - extent[2],
                               facecolor="white", edgecolor="0.6", hatch="///", linewidth=0,
                               zorder=0))
        finite = data.compressed()
        if finite.size:
            lo, hi = float(finite.min()), float(finite.max())
            mean = float(finite.mean())
            constant = hi - lo <= CONSTANT_REL_SPREAD * max(abs(mean), 1e-300)
            if constant:           # uniform colour; the value is written on the panel
                lo, hi = mean - 0.01 * abs(mean) - 1e-300, mean + 0.01 * abs(mean) + 1e-300
            mesh = ax.imshow(data, origin="lower", extent=extent, aspect="equal",
                             cmap="viridis", norm=Normalize(lo, hi), interpolation="nearest",
                             zorder=1)
            cb = fig.colorbar(mesh, ax=ax, fraction=0.046, pad=0.03)
            cb.set_label(f"C{i + 1}{i + 1} [{units[i]}]")
            cb.formatter.set_useOffset(False)
            cb.update_ticks()
            if constant:
                spread = (float(finite.max()) - float(finite.min())) / max(abs(mean), 1e-300)
                ax.text(0.5, 0.5, f"constant over the plane:\n{mean:.5g} {units[i]}\n"
                        f"(relative spread {spread:.1e})",
                        transform=ax.transAxes, ha="center", va="center", fontsize=8,
                        bbox={"facecolor": "white", "alpha": 0.85, "edgecolor": "0.5"})
        if multi:
            ax.contour(u_m, v_m, np.ma.masked_less(branch.T, 0).astype(float),
                       levels=np.arange(-0.5, 8.5, 1.0), colors="k", linewidths=0.8, zorder=2)
        ax.set_xlim(extent[0], extent[1])
        ax.set_ylim(extent[2], extent[3])
        ax.set_xlabel(f"{u_label} [m]")
        ax.set_ylabel(f"{v_label} [m]")
        ax.set_title(f"({'abcdef'[i]}) C{i + 1}{i + 1}: {what[i]}")
    note = "hatched: unreachable"
    if multi:
        used = sorted({branch_labels[int(b)] for b in np.unique(branch[branch >= 0])}) \
            if branch_labels else []
        note += f"; black lines: branch changes ({', '.join(used)})"
    fig.suptitle(f"{title}\n{note}")
    return fig


# ------------------------------------------------------------- 2. stiffness and error along path
@_styled
def stiffness_error_figure(k: np.ndarray, stiffness_n_per_m: np.ndarray, error_m: np.ndarray,
                           *, title: str) -> Figure:
    """Paper Figs. 6-7: directional stiffness and load-induced TCP error along the path.

    Parameters
    ----------
    k : ndarray, shape (N,)
        Waypoint index.
    stiffness_n_per_m : ndarray, shape (N, 3)
        ``1 / (u^T C_tt u)`` along base x, y, z, N/m.
    error_m : ndarray, shape (N, 3)
        TCP position error under load, uncompensated, base frame, m.
    """
    fig = _figure(11.0, 4.6, left=0.07, right=0.985, bottom=0.12, top=0.83, wspace=0.22)
    a1, a2 = fig.subplots(1, 2)
    for j, name in enumerate("XYZ"):
        a1.plot(k, stiffness_n_per_m[:, j], color=AXIS_COLOURS[j], marker=".", ms=3,
                label=f"k{name.lower()} (along base {name})")
        a2.plot(k, error_m[:, j] * 1e3, color=AXIS_COLOURS[j], marker=".", ms=3,
                label=f"Δ{name.lower()}")
    a2.plot(k, np.linalg.norm(error_m, axis=1) * 1e3, color="k", ls="--", label="|Δ|")
    a1.set_ylabel("directional stiffness [N/m]")
    a1.set_title("(a) stiffness along X, Y, Z (paper Fig. 6)")
    a2.set_ylabel("TCP position error [mm]")
    a2.set_title("(b) load-induced error, no compensation (paper Fig. 7)")
    a2.axhline(0.0, color="0.5", lw=0.6)
    for a in (a1, a2):
        a.set_xlabel("waypoint k [-]")
        a.grid(alpha=0.3)
        a.legend(loc="best")
    fig.suptitle(title)
    return fig


# --------------------------------------------------------------------- 3. compensation angles
@_styled
def compensation_figure(k: np.ndarray, dq_exact_rad: np.ndarray,
                        dq_closed_rad: np.ndarray | None, *, title: str) -> Figure:
    """Paper Fig. 8: compensation angle ``q_command - q_target`` per joint along the path.

    Parameters
    ----------
    k : ndarray, shape (N,)
        Waypoint index.
    dq_exact_rad, dq_closed_rad : ndarray, shape (N, 6)
        Exact and closed-form compensation angles, rad (closed form optional).
    """
    fig = _figure(11.0, 5.8, left=0.075, right=0.985, bottom=0.09, top=0.87, wspace=0.38,
                  hspace=0.28)
    axs = fig.subplots(2, 3, sharex=True)
    for j, ax in enumerate(axs.ravel()):
        ax.plot(k, np.degrees(dq_exact_rad[:, j]), color=JOINT_COLOURS[j], lw=1.6, label="exact")
        if dq_closed_rad is not None:
            ax.plot(k, np.degrees(dq_closed_rad[:, j]), color="k", lw=1.0, ls="--",
                    label="closed form")
        ax.axhline(0.0, color="0.5", lw=0.6)
        ax.set_title(f"joint {j + 1}: Δθ{j + 1}")
        ax.set_ylabel("compensation angle [deg]")
        ax.grid(alpha=0.3)
        ax.ticklabel_format(axis="y", useOffset=False)
        if j >= 3:
            ax.set_xlabel("waypoint k [-]")
        if j == 0:
            ax.legend(loc="best")
    fig.suptitle(title)
    return fig


# ---------------------------------------------------------------------- 4. error before/after
@_styled
def error_before_after_figure(k: np.ndarray, before_m: np.ndarray, closed_m: np.ndarray,
                              exact_m: np.ndarray, *, title: str) -> Figure:
    """Paper Figs. 9 and 13: TCP error before and after compensation, per axis.

    Top row: before vs. after (mm, one scale).  Bottom row: after only, in µm,
    so the residual of the closed form is readable (the exact residual sits at
    rounding level).

    Parameters
    ----------
    before_m, closed_m, exact_m : ndarray, shape (N, 3)
        TCP position error (reached - target), base frame, m.
    """
    fig = _figure(12.0, 7.0, left=0.065, right=0.985, bottom=0.08, top=0.86, wspace=0.3,
                  hspace=0.3)
    axs = fig.subplots(2, 3, sharex=True)
    for j, name in enumerate("xyz"):
        top, bot = axs[0, j], axs[1, j]
        top.plot(k, before_m[:, j] * 1e3, color=AXIS_COLOURS[j], lw=1.6, label="before (solid)")
        top.plot(k, closed_m[:, j] * 1e3, color="k", ls="--", lw=1.0,
                 label="after, closed form (paper's _SM)")
        top.plot(k, exact_m[:, j] * 1e3, color="tab:red", ls=":", lw=1.2, label="after, exact")
        top.set_ylabel(f"Δ{name} [mm]")
        top.set_title(f"{name.upper()} direction: before and after")
        bot.plot(k, closed_m[:, j] * 1e6, color="k", ls="--", lw=1.0, label="after, closed form")
        bot.plot(k, exact_m[:, j] * 1e6, color="tab:red", ls=":", lw=1.2, label="after, exact")
        bot.set_ylabel(f"Δ{name} after [µm]")
        bot.set_xlabel("waypoint k [-]")
        bot.set_title(f"{name.upper()} direction: residual after compensation")
        for a in (top, bot):
            a.axhline(0.0, color="0.5", lw=0.6)
            a.grid(alpha=0.3)
            if j == 0:                 # same styles in every column: one legend per row
                a.legend(loc="best")
    fig.suptitle(title)
    return fig


# ----------------------------------------------------------------------- 5. branch comparison
@_styled
def branch_figure(k: np.ndarray, analytic_m: Mapping[str, np.ndarray],
                  optimised_m: Mapping[str, np.ndarray] | None, chosen: str | None,
                  *, title: str, note: str = "") -> Figure:
    """Load-induced TCP error norm along the path for every feasible IK branch.

    Parameters
    ----------
    analytic_m : mapping label -> ndarray (N,)
        Error norm (m) at the analytic IK posture of each branch.
    optimised_m : mapping label -> ndarray (N,), optional
        Error norm (m) after posture optimisation (dashed, same colour).
    chosen : str, optional
        The branch used; drawn thick and marked in the legend.
    note : str
        Extra line under the title (e.g. rejected branches).
    """
    fig = _figure(11.0, 5.2, left=0.07, right=0.74, bottom=0.1, top=0.84)
    ax = fig.subplots()
    for i, (label, e) in enumerate(analytic_m.items()):
        c = f"C{i % 10}"
        is_chosen = label == chosen
        ax.plot(k, e * 1e3, color=c, lw=2.8 if is_chosen else 1.2,
                marker="o" if is_chosen else None, ms=3,
                label=f"{label} analytic" + ("  ◀ chosen" if is_chosen else ""), zorder=3 if is_chosen else 2)
        if optimised_m and label in optimised_m:
            same = np.allclose(optimised_m[label], e, rtol=1e-9, atol=1e-15, equal_nan=True)
            ax.plot(k, optimised_m[label] * 1e3, color=c, ls="--", lw=2.0 if is_chosen else 1.0,
                    label=f"{label} optimised" + (" (= analytic)" if same else ""))
    ax.set_xlabel("waypoint k [-]")
    ax.set_ylabel("load-induced TCP error |Δ| [mm]")
    ax.set_ylim(bottom=0.0)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0)
    fig.suptitle(title + (f"\n{note}" if note else ""))
    return fig


# ----------------------------------------------------------------------------- 6. trajectory
def _limit_lines(ax, lim: np.ndarray | None, colours: Sequence[str]) -> None:
    if lim is None:
        return
    lim = np.asarray(lim, dtype=float)
    if np.allclose(lim, lim[0]):
        for s in (1, -1):
            ax.axhline(s * lim[0], color="k", ls="--", lw=1.0,
                       label="limit" if s == 1 else None)
    else:
        for j, l in enumerate(lim):
            for s in (1, -1):
                ax.axhline(s * l, color=colours[j], ls="--", lw=0.8,
                           label="limits (per joint, dashed)" if (j == 0 and s == 1) else None)


@_styled
def trajectory_figure(trajs: Mapping[str, Mapping[str, np.ndarray]],
                      limits: Mapping[str, np.ndarray | None], *, title: str,
                      headers: Mapping[str, str] | None = None) -> Figure:
    """Joint position, velocity, acceleration and jerk against time, with limits.

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
    fig = _figure(5.8 * max(1, len(methods)) + 0.8, 10.5, left=0.08, right=0.985, bottom=0.05,
                  top=0.88, wspace=0.25, hspace=0.25)
    axs = np.atleast_2d(fig.subplots(4, len(methods), sharex="col", squeeze=False))
    rows = (("q", "q [rad]", None), ("qd", "q̇ [rad/s]", "velocity"),
            ("qdd", "q̈ [rad/s²]", "acceleration"), ("jerk", "jerk [rad/s³]", "jerk"))
    for c, m in enumerate(methods):
        tr = trajs[m]
        t = np.asarray(tr["t"], float)
        data = {"q": tr["q"], "qd": tr["qd"], "qdd": tr["qdd"], "jerk": tr.get("qddd")}
        for r, (key, ylabel, lim_key) in enumerate(rows):
            ax = axs[r, c]
            if data[key] is None:
                ax.text(0.5, 0.5, "jerk not recorded in this trajectory file\n(no qddd columns)",
                        transform=ax.transAxes, ha="center", va="center")
                ax.set_yticks([])
                ax.set_ylabel(ylabel)
                ax.set_xlabel("time t [s]")
                continue
            y = np.asarray(data[key], float)
            for j in range(y.shape[1]):
                ax.plot(t, y[:, j], color=JOINT_COLOURS[j % 6], lw=1.0, label=f"joint {j + 1}")
            if key == "q":
                lo, hi = float(np.nanmin(y)), float(np.nanmax(y))
                pad = 0.1 * max(hi - lo, 1e-3)
                ax.set_ylim(lo - pad, hi + pad)
                qmin, qmax = limits.get("q_min"), limits.get("q_max")
                shown = False
                if qmin is not None and qmax is not None:
                    for j in range(len(qmin)):
                        for v in (qmin[j], qmax[j]):
                            if lo - pad <= v <= hi + pad:
                                ax.axhline(v, color=JOINT_COLOURS[j], ls="--", lw=0.8)
                                shown = True
                ax.set_title((headers or {}).get(m, m) + ("" if shown or qmin is None
                                                           else "\nposition limits outside the view"))
            else:
                _limit_lines(ax, limits.get(lim_key), JOINT_COLOURS)
            ax.set_ylabel(ylabel)
            ax.grid(alpha=0.3)
            if r == 3:
                ax.set_xlabel("time t [s]")
    handles, labels = axs[1, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", ncol=len(labels), bbox_to_anchor=(0.5, 0.965),
               frameon=False)
    fig.suptitle(title)
    return fig


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


@_styled
def arm_figure(nominal_m: np.ndarray, deflected_m: np.ndarray, path_m: np.ndarray,
               labels: Sequence[str], factor: float, *, title: str) -> Figure:
    """The arm drawn in 3-D at a few poses, nominal and (exaggerated) deflected.

    Parameters
    ----------
    nominal_m, deflected_m : ndarray, shape (P, L, 3)
        Polyline points (base, DH frame origins, TCP) per pose, m.
    path_m : ndarray, shape (N, 3)
        Target TCP path, m.
    labels : sequence of str, length P
        Pose names (e.g. ``"k = 0"``).
    factor : float
        Deflection exaggeration factor (stated in the title).
    """
    fig = _figure(10.0, 7.2)
    ax = fig.add_axes((0.0, 0.07, 0.72, 0.82), projection="3d")
    ax.plot(*path_m.T, color="0.5", lw=1.0, label="target TCP path")
    for p in range(len(nominal_m)):
        c = f"C{p % 10}"
        ax.plot(*nominal_m[p].T, color=c, lw=2.2, marker="o", ms=3,
                label=f"{labels[p]} nominal (no load)")
        ax.plot(*deflected_m[p].T, color=c, lw=1.2, ls="--",
                label=f"{labels[p]} loaded, ×{factor:g}")
    ax.scatter([0.0], [0.0], [0.0], color="k", marker="s", s=30, label="base origin")
    pts = np.concatenate([nominal_m.reshape(-1, 3), deflected_m.reshape(-1, 3), path_m,
                          np.zeros((1, 3))])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    span = np.maximum(hi - lo, 1e-3)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_zlim(lo[2], hi[2])
    ax.set_box_aspect(span)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    fig.legend(*ax.get_legend_handles_labels(), loc="upper left", bbox_to_anchor=(0.72, 0.86),
               fontsize=8)
    ax.view_init(elev=22, azim=-55)
    fig.suptitle(title)
    return fig
