"""The report's figures: which data of a :class:`~planner.report.run.Run` each one draws.

:func:`build_figures` prepares one :class:`~planner.report.rendering.FigureItem`
per figure, in report order: its drawing job (a function of
:mod:`planner.report.plots` and its arrays) or, when the run lacks what the
figure needs, the reason it is absent.  Path figures are drawn from the run's
data, not recomputed; only the compliance map (:mod:`planner.report.maps`) and
the 3-D arm need the robot.
"""

from __future__ import annotations

import textwrap
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from models import KinematicModel
from models.errors import InputError

from planner.compliance_map import ProgressFn
from planner.report import plots
from planner.report.maps import MAP_FIGURE, map_item
from planner.report.rendering import FigureItem, Job, job
from planner.report.run import METHOD_NAMES, Run
from planner.report.tables import RATIO_KINDS, flat_numbers

#: File names of the figures, in report order.
FIGURE_NAMES = (MAP_FIGURE, "fig2_stiffness_error", "fig3_compensation_angles",
                "fig4_error_before_after", "fig5_branches", "fig6_trajectory", "fig7_arm_3d")

#: Number of poses drawn in figure 7.
ARM_POSES = 4


@dataclass
class _Context:
    """What several figures share: the run and its load, branch and names."""

    run: Run
    robot_name: str
    branch: str
    wrench: np.ndarray | None
    load: str

    @property
    def wp(self) -> dict[str, np.ndarray] | None:
        return self.run.waypoints

    @property
    def no_waypoints(self) -> str:
        return self.run.absent.get("waypoints", "")


def build_figures(run: Run, progress: ProgressFn | None = None,
                  map_options: Mapping[str, Any] | None | bool = None,
                  files: dict[str, bytes] | None = None,
                  map_cache: bool = True) -> list[FigureItem]:
    """Prepare every figure the run allows (its ``job``); absent ones carry the reason.

    Only the compliance map is computed here (with progress); the figures are
    drawn by :func:`planner.report.rendering.render_items`.

    Parameters
    ----------
    map_options : mapping, None or False
        Keyword arguments of :func:`planner.compliance_map.compliance_map`
        (default: the paper's section-4.3 plane); ``False`` skips the map.
    files : dict, optional
        Extra data files produced on the way (``compliance_map.csv``) are added here.
    map_cache : bool
        Reuse a compliance map drawn earlier for the same robot and options (see
        :mod:`planner.report.maps`).
    """
    files = {} if files is None else files
    ctx = _context(run)
    return [map_item(run, map_options, progress, files, map_cache), _stiffness_item(ctx),
            _compensation_item(ctx), _error_item(ctx), _branch_item(ctx), _trajectory_item(ctx),
            _arm_item(ctx)]


def _context(run: Run) -> _Context:
    s = run.summary
    try:
        wrench = _wrench(s)
    except InputError as exc:
        wrench = None
        run.absent.setdefault("wrench", str(exc))
    load = (f"F = {_fmt_vec(wrench[:3], 'N')}, M = {_fmt_vec(wrench[3:], 'N·m')} (base frame, at the TCP)"
            if wrench is not None else "load unknown")
    if wrench is not None and s.get("wrench", {}).get("per_waypoint"):
        load = f"per-waypoint load, waypoint 0: {load}"
    return _Context(run, s.get("robot", "?"), s.get("chosen_branch", s.get("branch", "?")),
                    wrench, load)


def _wrench(summary: Mapping[str, Any]) -> np.ndarray:
    w = summary.get("wrench", {})
    try:
        return np.r_[np.asarray(w["F_N"], float), np.asarray(w["M_Nm"], float)]
    except (KeyError, TypeError, ValueError):
        raise InputError("summary.json: wrench.F_N / wrench.M_Nm missing or not numeric; "
                         "expected 3 + 3 numbers (N, N*m)") from None


def _fmt_vec(v: np.ndarray, unit: str) -> str:
    return "[" + ", ".join(f"{x:g}" for x in v) + f"] {unit}"


def _xyz(wp: Mapping[str, np.ndarray], prefix: str) -> np.ndarray:
    """Columns ``<prefix>x, <prefix>y, <prefix>z`` of waypoints.csv as an (N, 3) array."""
    return np.column_stack([wp[f"{prefix}{a}"] for a in "xyz"])


def _joints(wp: Mapping[str, np.ndarray], prefix: str) -> np.ndarray:
    """Columns ``<prefix>1 .. <prefix>6`` of waypoints.csv as an (N, 6) array."""
    return np.column_stack([wp[f"{prefix}{i}"] for i in range(1, 7)])


def _wrap(text: str, width: int) -> str:
    return "\n".join(textwrap.wrap(text, width)) if text else ""


# -------------------------------------------------------------------------- path figures 2-5
def _stiffness_item(ctx: _Context) -> FigureItem:
    item = FigureItem(FIGURE_NAMES[1], "Directional stiffness and load-induced error along the path",
                      "Paper Figs. 6–7. (a) stiffness 1/(uᵀ C u) along base X, Y, Z (N/m); "
                      "(b) TCP error under load without compensation, per base axis and norm (mm).")
    wp = ctx.wp
    if wp is None:
        item.absent = ctx.no_waypoints
    else:
        item.job = job(plots.stiffness_error_figure, wp["k"], _xyz(wp, "k"), _xyz(wp, "eb"),
                       title=f"{ctx.robot_name}, branch {ctx.branch}, {ctx.load}")
    return item


def _compensation_item(ctx: _Context) -> FigureItem:
    item = FigureItem(FIGURE_NAMES[2], "Compensation angle per joint along the path",
                      "Paper Fig. 8. Δθ = q_command − q_target (deg): exact compensation (solid) "
                      "and the paper's closed form, eqs. 32/47 (dashed).")
    wp = ctx.wp
    if wp is None:
        item.absent = ctx.no_waypoints
    else:
        qt = _joints(wp, "qt")
        item.job = job(plots.compensation_figure, wp["k"], _joints(wp, "qc") - qt,
                       _joints(wp, "qf") - qt,
                       title=f"{ctx.robot_name}, branch {ctx.branch}: joint compensation angles, "
                             f"{ctx.load}")
    return item


def _error_item(ctx: _Context) -> FigureItem:
    item = FigureItem(FIGURE_NAMES[3], "TCP error before and after compensation",
                      "Paper Figs. 9 and 13. Top: error before (solid) and after compensation "
                      "(closed form dashed, exact dotted), mm; bottom: the residuals alone, µm.")
    wp = ctx.wp
    if wp is None:
        item.absent = ctx.no_waypoints
        return item
    eb, ef, ee = _xyz(wp, "eb"), _xyz(wp, "ef"), _xyz(wp, "ee")
    stats = (f"max |Δ|: before {np.linalg.norm(eb, axis=1).max() * 1e3:.4g} mm, closed form "
             f"{np.linalg.norm(ef, axis=1).max() * 1e3:.4g} mm, exact "
             f"{np.linalg.norm(ee, axis=1).max() * 1e3:.3g} mm")
    item.job = job(plots.error_before_after_figure, wp["k"], eb, ef, ee,
                   title=f"{ctx.robot_name}, branch {ctx.branch}, {ctx.load}\n{stats}")
    return item


def _branch_item(ctx: _Context) -> FigureItem:
    item = FigureItem(FIGURE_NAMES[4], "Branch comparison",
                      "Load-induced TCP error norm along the path for every feasible IK branch "
                      "(analytic posture solid, optimised posture dashed when present); the branch "
                      "used is thick with markers.")
    run = ctx.run
    if run.branches is None:
        item.absent = run.absent.get("branches", "branches.csv absent")
        return item
    ana = {c[: -len("_analytic_m")]: v for c, v in run.branches.items() if c.endswith("_analytic_m")}
    opt = {c[: -len("_optimised_m")]: v for c, v in run.branches.items() if c.endswith("_optimised_m")}
    for lab in opt:
        ana.setdefault(lab, np.full_like(opt[lab], np.nan))
    if not ana:
        item.absent = "branches.csv has no <branch>_analytic_m columns"
        return item
    rej = run.summary.get("rejected_branches") or {}
    by_reason: dict[str, list[str]] = {}
    for b, r in rej.items():
        by_reason.setdefault(str(r), []).append(str(b))
    note = ("not feasible: " + "; ".join(f"{', '.join(bs)} ({r})" for r, bs in by_reason.items())
            if rej else "")
    if not opt:
        item.caption += " No optimised postures in this run."
    item.job = job(plots.branch_figure, run.branches["k"], ana, opt or None, ctx.branch,
                   title=f"{ctx.robot_name}: load-induced error per IK branch, {ctx.load}",
                   note=_wrap(note, 120))
    return item


# ----------------------------------------------------------------------------- 6. trajectory
def _trajectory_item(ctx: _Context) -> FigureItem:
    item = FigureItem(FIGURE_NAMES[5], "Trajectory: q, q̇, q̈ and jerk against time",
                      "Joint position, velocity, acceleration and jerk (the qddd columns of the "
                      "trajectory file, as the timing computed them) for each timing method, with "
                      "the limits dashed.")
    run, s = ctx.run, ctx.run.summary
    if not run.trajectories:
        item.absent = run.absent.get("trajectory", "no trajectory in this run")
        return item
    limits, src = _limits(run)
    item.caption += f" Limits: {src}."
    trajs, headers = {}, {}
    for method, tr in run.trajectories.items():
        pretty = METHOD_NAMES.get(method, method)
        trajs[pretty] = tr
        headers[pretty] = _traj_header(s, method, pretty, run.trajectory_files[method], tr)
    no_jerk = [run.trajectory_files[m] for m, tr in run.trajectories.items() if tr.get("qddd") is None]
    if no_jerk:
        item.caption += f" Jerk not recorded in {', '.join(no_jerk)} (no qddd columns)."
    missing = [METHOD_NAMES.get(m, m) for m in METHOD_NAMES if m not in run.trajectories]
    if missing:
        item.caption += f" No {', '.join(missing)} trajectory in this run."
    item.job = job(plots.trajectory_figure, trajs, limits,
                   title=f"{ctx.robot_name}: joint trajectories", headers=headers)
    return item


def _limits(run: Run) -> tuple[dict[str, np.ndarray | None], str]:
    """The limits drawn in figure 6 (summary.json's, else the robot file's) and where from."""
    lim: dict[str, np.ndarray | None] = {"q_min": None, "q_max": None, "velocity": None,
                                         "acceleration": None, "jerk": None}
    src = []
    given = run.summary.get("limits")
    if isinstance(given, Mapping):
        found = []
        for k in lim:
            try:
                v = np.broadcast_to(np.asarray(given.get(k), float), (6,)).copy()
            except (TypeError, ValueError):
                continue
            if np.all(np.isfinite(v)):
                lim[k] = v
                found.append(k)
        if found:
            src.append(f"{', '.join(found)} from summary.json limits")
    if run.robot is not None:
        r = run.robot
        for k, v in (("q_min", r.q_min), ("q_max", r.q_max), ("velocity", r.v_max),
                     ("acceleration", r.a_max), ("jerk", r.j_max)):
            if lim[k] is None:
                lim[k] = v
                src.append(f"{k} from the robot file")
    return lim, "; ".join(src) or "none available"


def _traj_header(s: Mapping[str, Any], method: str, pretty: str, fname: str,
                 tr: Mapping[str, Any]) -> str:
    """Column title of one method in figure 6: file, duration, peak limit ratios."""
    dur = s.get("duration_s")
    d = dur.get(method) if isinstance(dur, Mapping) else None
    if d is None:
        d = float(tr["t"][-1] - tr["t"][0])
    ctrl = " — controller" if s.get("controller_trajectory") == method else ""
    head = f"{pretty} ({fname}{ctrl}): duration {float(d):.4g} s"
    lr = s.get("limit_ratio")
    if isinstance(lr, Mapping):
        sub = lr.get(method) if method in lr else (lr if any(k in lr for k in RATIO_KINDS) else None)
        if isinstance(sub, Mapping):
            parts = []
            for k, short in zip(RATIO_KINDS, ("v", "a", "j")):
                nums = flat_numbers(sub.get(k))
                if nums:
                    parts.append(f"{short} {max(nums):.3g}")
            if parts:
                head += "\npeak |value|/limit: " + ", ".join(parts)
    return head


# --------------------------------------------------------------------------------- 7. the arm
def _arm_item(ctx: _Context) -> FigureItem:
    item = FigureItem(FIGURE_NAMES[6], "The arm in 3-D, nominal and deflected", "")
    run = ctx.run
    if run.robot is None:
        item.absent = f"arm not drawn: {run.absent.get('robot')}"
    elif ctx.wp is None:
        item.absent = f"arm not drawn: {ctx.no_waypoints}"
    elif ctx.wrench is None:
        item.absent = f"arm not drawn: {run.absent.get('wrench')}"
    else:
        item.job, item.caption = _arm(run, ctx.wp, ctx.wrench, ctx.branch, ctx.load)
    return item


def _polylines(model: KinematicModel, q: np.ndarray) -> np.ndarray:
    """(P, L, 3) points through the base, each link's offset corner, the frame origins and the TCP."""
    frames = model.batch(model.fk_frames, q)          # 6 x (P, 4, 4)
    tcp = model.tcp(q)[:, :3, 3]
    P = len(q)
    pts = [np.zeros((P, 3))]
    prev_o, prev_z = np.zeros((P, 3)), np.tile([0.0, 0.0, 1.0], (P, 1))
    d = model.robot.d
    for i, Tf in enumerate(frames):
        if model.robot.convention == "standard_dh" and abs(d[i]) > 0:
            pts.append(prev_o + d[i] * prev_z)         # the d_i offset along z_{i-1}
        o = Tf[:, :3, 3]
        pts.append(o)
        prev_o, prev_z = o, Tf[:, :3, 2]
    pts.append(tcp)
    return np.stack(pts, axis=1)


def _arm(run: Run, wp: Mapping[str, np.ndarray], wrench: np.ndarray, branch: str,
         load: str) -> tuple[Job, str]:
    model = KinematicModel(run.robot)                  # type: ignore[arg-type]
    qt = _joints(wp, "qt")
    n = len(qt)
    idx = np.unique(np.round(np.linspace(0, n - 1, min(ARM_POSES, n))).astype(int))
    q = qt[idx]
    W = np.broadcast_to(wrench, (len(idx), 6))
    rows = run.summary.get("wrench", {}).get("rows")
    if rows is not None:                              # a per-waypoint wrench (plan)
        try:
            W = np.asarray(rows, float)[idx].reshape(len(idx), 6)
        except (ValueError, IndexError, TypeError):
            pass
    dq = model.batch(model.joint_deflection, q, np.ascontiguousarray(W))[0]  # K^-1 J^T F, rad
    eb = _xyz(wp, "eb")
    true_max = float(np.linalg.norm(eb, axis=1).max())
    factor = plots.nice_factor(true_max)
    nominal = _polylines(model, q)
    deflected = _polylines(model, q + factor * dq)
    labels = [f"k = {int(wp['k'][i])}" for i in idx]
    title = (f"{run.summary.get('robot', '?')}, branch {branch}: poses along the path, "
             f"deflection exaggerated ×{factor:g}\n(true TCP deflection up to "
             f"{true_max * 1e3:.3g} mm under {load})")
    jb = job(plots.arm_figure, nominal, deflected, _xyz(wp, ""), labels, factor, title=title)
    caption = (f"Links drawn through the DH frame origins (with each link's d offset) at "
               f"{len(idx)} waypoints: nominal configuration q_target (solid) and loaded "
               f"q_target + {factor:g}·K⁻¹Jᵀ(q)F (dashed), i.e. the joint deflection exaggerated "
               f"×{factor:g}.")
    return jb, caption
