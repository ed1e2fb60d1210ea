"""The report's figures: which data of a :class:`~planner.record.RunRecord` each one draws.

:func:`build_figures` prepares one :class:`~planner.report.rendering.FigureItem`
per figure, in report order: its drawing job (a function of
:mod:`planner.report.plots` and its arrays) or, when the run lacks what the
figure needs, the reason it is absent.  Path figures are drawn from the run's
data, not recomputed; only the compliance map (:mod:`planner.report.maps`) and
the 3-D arm need the run's arm model (``Run.model``).  Figure 8 (:data:`DYNAMIC_FIGURE`)
exists only in the report of a run with dynamic compensation (summary.json key
``dynamic_compensation``).  ``compplan plan --no-report`` writes figures 5 and 6 as
``branches.png`` and ``trajectory.png`` (:func:`quick_figures`).
"""

from __future__ import annotations

import textwrap
from dataclasses import dataclass
from typing import Any
from collections.abc import Mapping

import numpy as np

from models import KinematicModel
from models.errors import InputError
from models.ik import BRANCH_LABELS

from planner.branches import legend
from planner.compliance_map import ProgressFn
from planner.numbers import NUMERICAL_FLOOR_MM, format_number, mm_text
from planner.report import dynamic_plot, motion_plots, plots
from planner.report.cell_view import cell_items
from planner.report.cut_plot import cut_items
from planner.report.maps import MAP_FIGURE, map_item
from planner.report.rendering import FigureItem, Job, job, render_items
from planner.record import DYNAMIC_KEY, RunRecord, method_name, method_order
from planner.report.tables import RATIO_KINDS, flat_numbers, load_words
from planner.report.toolpath_plot import program_items

#: File names of the figures, in report order.
FIGURE_NAMES = (
    MAP_FIGURE,
    "fig2_stiffness_error",
    "fig3_compensation_angles",
    "fig4_error_before_after",
    "fig5_branches",
    "fig6_trajectory",
    "fig7_arm_3d",
)

#: File name of the figure of the dynamic compensation (figure 8), drawn only for a run that has
#: it (``[timing] dynamic = true``); runs without it have no such figure, not an absent one.
DYNAMIC_FIGURE = "fig8_dynamic_compensation"

#: Number of poses drawn in figure 7 (start, middle, end).
ARM_POSES = 3


@dataclass
class _Context:
    """What several figures share: the run and its load, branch, names and path length."""

    run: RunRecord
    robot_name: str
    branch: str
    load: str

    @property
    def wp(self) -> dict[str, np.ndarray] | None:
        return self.run.waypoints

    @property
    def no_waypoints(self) -> str:
        return self.run.absent.get("waypoints", "")

    @property
    def s_mm(self) -> np.ndarray:
        """Path length from the first waypoint along the waypoints, mm."""
        return path_length_mm(_xyz(self.wp, ""))  # type: ignore[arg-type]


def build_figures(
    run: RunRecord,
    progress: ProgressFn | None = None,
    map_options: Mapping[str, Any] | None | bool = None,
    files: dict[str, bytes] | None = None,
    map_cache: bool = True,
) -> list[FigureItem]:
    """Prepare every figure the run allows (its ``job``); absent ones carry the reason.

    Only the compliance map is computed here (with progress); the figures are
    drawn by :func:`planner.report.rendering.render_items`.

    Parameters
    ----------
    map_options : mapping, None or False
        None (default): the map over the plane of the run's own path, at its attitude,
        on its IK branch (:func:`planner.report.maps.map_item`); a mapping: keyword
        arguments of :func:`planner.compliance_map.compliance_map` (an axis-aligned
        plane; the path is drawn projected onto it); ``False`` skips the map.
    files : dict, optional
        Extra data files produced on the way (``compliance_map.csv``) are added here.
    map_cache : bool
        Reuse a compliance map drawn earlier for the same robot and options (see
        :mod:`planner.report.maps`).
    """
    files = {} if files is None else files
    ctx = _context(run)
    items = [
        map_item(run, map_options, progress, files, map_cache),
        _stiffness_item(ctx),
        _compensation_item(ctx),
        _error_item(ctx),
        _branch_item(ctx),
        _trajectory_item(ctx),
        _arm_item(ctx),
    ]
    if isinstance(run.summary.get(DYNAMIC_KEY), Mapping):
        items.append(_dynamic_item(ctx))
    items += program_items(run)  # a program path's toolpath and feed (planner.report.toolpath_plot)
    items += cell_items(run)  # a problem with a [cell]: the 3-D cell view (planner.report.cell_view)
    # a predicted cut: force, toolpath, stock, error (planner.report.cut_plot); after the cell view (figure 11),
    # so that the figure numbers, taken from the file names, run in order
    items += cut_items(run)
    return items


#: The report's figures that ``compplan plan --no-report`` writes as PNG beside the run's files
#: (:func:`quick_figures`): file name -> figure.
QUICK_FIGURES = {"branches.png": FIGURE_NAMES[4], "trajectory.png": FIGURE_NAMES[5]}


def quick_figures(run: RunRecord, workers: int | None = 1) -> dict[str, bytes]:
    """PNG bytes of the report's figures 5 (branch comparison) and 6 (trajectory) of ``run``,
    by the file names of :data:`QUICK_FIGURES`: the same drawings as the report's, without the
    rest of it (a figure the run does not allow is left out).  ``workers``: as for
    :func:`~planner.report.rendering.render_items` (default: in this process; for two figures
    a pool of forked processes costs about what it saves)."""
    ctx = _context(run)
    items = dict(zip(QUICK_FIGURES, (_branch_item(ctx), _trajectory_item(ctx))))
    render_items(list(items.values()), workers=workers, pdf=False)
    return {name: it.png for name, it in items.items() if it.png is not None}


def _context(run: RunRecord) -> _Context:
    s = run.summary
    try:
        _wrench(s)
    except InputError as exc:
        run.absent.setdefault("wrench", str(exc))
    return _Context(run, s.get("robot", "?"), s.get("chosen_branch", s.get("branch", "?")), load_words(s))


def _wrench(summary: Mapping[str, Any]) -> np.ndarray:
    w = summary.get("wrench", {})
    try:
        return np.r_[np.asarray(w["F_N"], float), np.asarray(w["M_Nm"], float)]
    except (KeyError, TypeError, ValueError):
        raise InputError(
            "summary.json: wrench.F_N / wrench.M_Nm missing or not numeric; expected 3 + 3 numbers (N, N*m)"
        ) from None


def path_length_mm(P: np.ndarray) -> np.ndarray:
    """Cumulative length (mm) along the polyline of the waypoints ``P`` (N, 3), m; 0 at the first."""
    P = np.asarray(P, float)
    if len(P) < 2:
        return np.zeros(len(P))
    return np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))] * 1e3


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
    item = FigureItem(
        FIGURE_NAMES[1],
        "Directional stiffness and load-induced error along the path",
        "Paper Figs. 6–7, against the path length (mm). (a) stiffness 1/(uᵀ C u) along "
        "base X, Y, Z in N/mm on a log axis (C: the translational compliance of the chosen "
        "posture); (b) TCP error under the load without compensation, per base axis and "
        "its norm (mm), at the exact deflected equilibrium.",
    )
    wp = ctx.wp
    if wp is None:
        item.absent = ctx.no_waypoints
    else:
        item.job = job(
            plots.stiffness_error_figure,
            ctx.s_mm,
            _xyz(wp, "k"),
            _xyz(wp, "eb"),
            title=_wrap(f"{ctx.robot_name}, branch {ctx.branch}; load: {ctx.load}", 130),
        )
    return item


def _compensation_item(ctx: _Context) -> FigureItem:
    item = FigureItem(
        FIGURE_NAMES[2],
        "Compensation angle per joint along the path",
        "Paper Fig. 8. Δθ = q_command − q_target per joint against the path length: exact "
        "compensation (solid) and the paper's closed form q − K⁻¹Jᵀ(q)F, eqs. 32/47 (dashed); "
        "under each joint, the difference exact − closed form. Each panel has its own unit "
        "(deg, mdeg = 0.001°, µdeg = 10⁻⁶°) so every joint is readable.",
    )
    wp = ctx.wp
    if wp is None:
        item.absent = ctx.no_waypoints
    else:
        qt = _joints(wp, "qt")
        item.job = job(
            plots.compensation_figure,
            ctx.s_mm,
            _joints(wp, "qc") - qt,
            _joints(wp, "qf") - qt,
            title=_wrap(f"{ctx.robot_name}, branch {ctx.branch}: joint compensation angles; load: {ctx.load}", 130),
        )
    return item


def _error_item(ctx: _Context) -> FigureItem:
    item = FigureItem(
        FIGURE_NAMES[3],
        "TCP error before and after compensation",
        "Paper Figs. 9 and 13, against the path length. Top: error per base axis before "
        "compensation (solid) and after it (closed form dashed, exact dotted), mm; bottom: "
        "the residuals alone, µm. Errors at the exact deflected equilibrium; a residual below "
        f"{format_number(NUMERICAL_FLOOR_MM)} mm is 0 (numerical).",
    )
    wp = ctx.wp
    if wp is None:
        item.absent = ctx.no_waypoints
        return item
    eb, ef, ee = _xyz(wp, "eb"), _xyz(wp, "ef"), _xyz(wp, "ee")
    stats = (
        f"max |Δ|: before {mm_text(np.linalg.norm(eb, axis=1).max() * 1e3)}, after closed form "
        f"{mm_text(np.linalg.norm(ef, axis=1).max() * 1e3)}, after exact "
        f"{mm_text(np.linalg.norm(ee, axis=1).max() * 1e3)}"
    )
    item.job = job(
        plots.error_before_after_figure,
        ctx.s_mm,
        eb,
        ef,
        ee,
        title=_wrap(f"{ctx.robot_name}, branch {ctx.branch}; load: {ctx.load}", 130) + f"\n{stats}",
    )
    return item


def _rms(v: np.ndarray) -> float:
    v = np.asarray(v, float)
    return float(np.sqrt(np.mean(v**2))) if np.isfinite(v).all() and v.size else float("nan")


def _branch_item(ctx: _Context) -> FigureItem:
    item = FigureItem(
        FIGURE_NAMES[4],
        "Branch comparison",
        "(a) RMS load-induced TCP error of every IK branch (exact deflected equilibrium, "
        "from branches.csv: the measure of the error table; the branch table's first-order "
        "values differ by the second-order terms); branches that cannot follow the path are "
        "marked not feasible. (b) The error along the path of the chosen branch and of the "
        "default branch (the one nearest the home pose). "
        + legend(list((ctx.run.summary or {}).get("branches") or [])),
    )
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
    s = run.summary
    rej = s.get("rejected_branches") or {}
    chosen, default = ctx.branch, s.get("default_branch")
    order = [str(lab) for lab in (s.get("branch_labels") or BRANCH_LABELS)]  # the IK family's order
    known = [lab for lab in order if lab in ana or lab in rej]
    labels = known + sorted(lab for lab in set(ana) | set(rej) if lab not in known)
    labels = [lab for lab in labels if lab in ana or lab in rej]
    r_ana = [_rms(ana[lab]) if lab in ana else float("nan") for lab in labels]
    r_opt = [_rms(opt[lab]) if lab in opt else float("nan") for lab in labels] if opt else None
    if ctx.wp is not None and len(ctx.wp["k"]) == len(run.branches["k"]):
        x, x_label = ctx.s_mm, "path length from the first waypoint [mm]"
    else:
        x, x_label = run.branches["k"], "waypoint k [-]"
    curves: dict[str, np.ndarray] = {}
    for lab, kind in ((chosen, "chosen"), (default, "default")):
        if lab not in ana or (kind == "default" and lab == chosen):
            continue
        if lab in opt:
            info = (s.get("branches") or {}).get(lab) or {}
            what = "IK solution (fixed orientation)" if info.get("status") == "no_freedom" else "optimised posture"
            curves[f"{lab} ({kind}), {what}"] = opt[lab] * 1e3
        if np.isfinite(ana[lab]).all() and (
            lab not in opt or not np.allclose(ana[lab], opt[lab], rtol=1e-9, atol=1e-15)
        ):
            curves[f"{lab} ({kind}), analytic posture"] = ana[lab] * 1e3
    if default == chosen and chosen in ana:
        item.caption += " The chosen branch is the default one."
    by_reason: dict[str, list[str]] = {}
    for b, r in rej.items():
        by_reason.setdefault(str(r), []).append(str(b))
    note = "not feasible: " + "; ".join(f"{', '.join(bs)} ({r})" for r, bs in by_reason.items()) if rej else ""
    if not opt:
        item.caption += " No optimised postures in this run."
    item.job = job(
        plots.branch_figure,
        labels,
        np.asarray(r_ana) * 1e3,
        None if r_opt is None else np.asarray(r_opt) * 1e3,
        {str(k): str(v) for k, v in rej.items()},
        x,
        curves,
        chosen,
        default,
        x_label=x_label,
        title=_wrap(f"{ctx.robot_name}: load-induced TCP error per IK branch; load: {ctx.load}", 130),
        note=_wrap(note, 160),
    )
    return item


# ----------------------------------------------------------------------------- 6. trajectory
def _trajectory_item(ctx: _Context) -> FigureItem:
    item = FigureItem(
        FIGURE_NAMES[5],
        "Trajectory: q, q̇, q̈ and jerk against time",
        "Joint position, velocity, acceleration and jerk (the qddd columns of the "
        "trajectory file, as the timing computed them) for each timing method, with "
        "the limits dashed; the methods share the time axis and, per row, the value axis. "
        "The jerk row shows at most "
        f"{format_number(motion_plots.JERK_VIEW_LIMITS)}× the jerk limit; a method that does not "
        "limit jerk (TOPP-RA) is cut off there and its peak is written on the panel.",
    )
    run, s = ctx.run, ctx.run.summary
    if not run.trajectories:
        item.absent = run.absent.get("trajectory", "no trajectory in this run")
        return item
    limits, src = _limits(run)
    item.caption += f" Limits: {src}."
    trajs, headers = {}, {}
    for method, tr in run.trajectories.items():
        pretty = method_name(s, method)
        trajs[pretty] = tr
        headers[pretty] = _traj_header(s, method, pretty, run.trajectory_files[method], tr)
    no_jerk = [run.trajectory_files[m] for m, tr in run.trajectories.items() if tr.get("qddd") is None]
    if no_jerk:
        item.caption += f" Jerk not recorded in {', '.join(no_jerk)} (no qddd columns)."
    missing = [method_name(s, m) for m in method_order() if m not in run.trajectories]
    if missing:
        item.caption += f" No {', '.join(missing)} trajectory in this run."
    item.job = job(
        motion_plots.trajectory_figure, trajs, limits, title=f"{ctx.robot_name}: joint trajectories", headers=headers
    )
    return item


def _limits(run: RunRecord) -> tuple[dict[str, np.ndarray | None], str]:
    """The limits drawn in figure 6 (summary.json's, else the robot file's) and where from."""
    lim: dict[str, np.ndarray | None] = {
        "q_min": None,
        "q_max": None,
        "velocity": None,
        "acceleration": None,
        "jerk": None,
    }
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
        for k, v in (
            ("q_min", r.q_min),
            ("q_max", r.q_max),
            ("velocity", r.v_max),
            ("acceleration", r.a_max),
            ("jerk", r.j_max),
        ):
            if lim[k] is None:
                lim[k] = v
                src.append(f"{k} from the robot file")
    return lim, "; ".join(src) or "none available"


def _traj_header(s: Mapping[str, Any], method: str, pretty: str, fname: str, tr: Mapping[str, Any]) -> str:
    """Column title of one method in figure 6: file, duration, peak limit ratios."""
    dur = s.get("duration_s")
    d = dur.get(method) if isinstance(dur, Mapping) else None
    if d is None:
        d = float(tr["t"][-1] - tr["t"][0])
    ctrl = " — controller" if s.get("controller_trajectory") == method else ""
    head = f"{pretty} ({fname}{ctrl}): duration {format_number(float(d))} s"
    lr = s.get("limit_ratio")
    if isinstance(lr, Mapping):
        sub = lr.get(method) if method in lr else (lr if any(k in lr for k in RATIO_KINDS) else None)
        if isinstance(sub, Mapping):
            parts = []
            for k, short in zip(RATIO_KINDS, ("v", "a", "j")):
                nums = flat_numbers(sub.get(k))
                if nums:
                    parts.append(f"{short} {format_number(max(nums), 3)}")
            if parts:
                head += "\npeak |value|/limit: " + ", ".join(parts)
    return head


# --------------------------------------------------------------------------------- 7. the arm
def _arm_item(ctx: _Context) -> FigureItem:
    item = FigureItem(FIGURE_NAMES[6], "The arm in 3-D, planned and deflected", "")
    run = ctx.run
    if run.model is None:
        item.absent = f"arm not drawn: {run.absent.get('model') or run.absent.get('robot')}"
    elif ctx.wp is None:
        item.absent = f"arm not drawn: {ctx.no_waypoints}"
    else:
        item.job, item.caption = _arm(run, ctx.wp, ctx.branch, ctx.load)
    return item


def _polylines(model: KinematicModel, q: np.ndarray) -> tuple[np.ndarray, list[int]]:
    """Points of the arm drawn as its links, (P, L, 3), and which of them are joint centres.

    The polyline runs from the base through a point on every joint axis (each DH frame
    origin and, where a link has an offset d along the previous joint axis, the point
    that offset reaches) to the TCP: the links as straight segments between joint centres.
    """
    frames = model.batch(model.fk_frames, q)  # 6 x (P, 4, 4)
    tcp = model.tcp(q)[:, :3, 3]
    P = len(q)
    pts = [np.zeros((P, 3))]
    prev_o, prev_z = np.zeros((P, 3)), np.tile([0.0, 0.0, 1.0], (P, 1))
    d = model.robot.d
    for i, Tf in enumerate(frames):
        if model.robot.convention == "standard_dh" and abs(d[i]) > 0:
            pts.append(prev_o + d[i] * prev_z)  # the d_i offset along z_{i-1}
        o = Tf[:, :3, 3]
        if not np.allclose(o, pts[-1], atol=1e-12):  # a zero-length link adds no point
            pts.append(o)
        prev_o, prev_z = o, Tf[:, :3, 2]
    if not np.allclose(tcp, pts[-1], atol=1e-12):
        pts.append(tcp)
    out = np.stack(pts, axis=1)
    return out, list(range(1, out.shape[1] - 1))


def _arm(run: RunRecord, wp: Mapping[str, np.ndarray], branch: str, load: str) -> tuple[Job, str]:
    """Figure 7: the planned poses q_target at the start, middle and end of the path, and the
    same commands under the load without compensation, their joint deflection exaggerated.

    The joint deflection is ``q_target - q_command`` of the exact compensation (the
    equilibrium reached from ``q_command`` is ``q_target``): the deflection the whole load
    (wrench in its frame, payload) causes at ``q_target``, whatever the load's kind.
    """
    model = run.model.kinematics  # type: ignore[union-attr]
    qt, qc = _joints(wp, "qt"), _joints(wp, "qc")
    n = len(qt)
    idx = np.unique(np.round(np.linspace(0, n - 1, min(ARM_POSES, n))).astype(int))
    dq = qt[idx] - qc[idx]  # joint deflection under the load, rad
    eb = _xyz(wp, "eb")
    true_max = float(np.linalg.norm(eb, axis=1).max())
    factor = motion_plots.nice_factor(true_max)
    nominal, joints = _polylines(model, qt[idx])
    deflected, _ = _polylines(model, qt[idx] + factor * dq)
    labels = [f"k = {int(wp['k'][i])}" for i in idx]
    title = (
        f"{run.summary.get('robot', '?')}, branch {branch}: the arm at the start, middle and end of the path"
        "\n"
        + _wrap(f"load: {load}; true TCP deflection up to {format_number(true_max * 1e3)} mm, drawn ×{factor:g}", 115)
    )
    jb = job(motion_plots.arm_figure, nominal, deflected, _xyz(wp, ""), labels, factor, title=title, joint_index=joints)
    caption = (
        f"The arm as its links (straight segments between joint centres: the DH frame origins and "
        f"the link offsets along the joint axes) at {len(idx)} waypoints, equal scale on x, y, z: the "
        f"planned pose q_target that puts the TCP on the path (solid), and the same joint angles "
        f"under the load without compensation (dashed), their joint deflection q_target − q_command "
        f"exaggerated ×{factor:g}."
    )
    return jb, caption


# ------------------------------------------------------------------ 8. dynamic compensation
def _dynamic_item(ctx: _Context) -> FigureItem:
    """Figure 8: the predicted TCP error against time with no, static and static + dynamic
    compensation, and the planned TCP speed (``dynamic.csv``)."""
    run, s = ctx.run, ctx.run.summary
    entry = s.get(DYNAMIC_KEY) or {}
    item = FigureItem(
        DYNAMIC_FIGURE,
        "TCP deviation from the planned path against time (dynamic compensation)",
        "Predicted (quasi-static) TCP position error against the planned link side at every "
        "command sample, in µm on a log axis: the link plan commanded as is (uncompensated), with the "
        "static command (load and own weight), and with the motor-side command of the dynamic compensation "
        "(static + dynamic), which also makes the joints carry the inertial torques; below, the "
        "planned TCP speed (m/s) on the same time axis. Grey: the arm at rest (start, end, dwells), where "
        "the motor-side command is the static command. Vibrations are "
        f"not included. Data: {entry.get('file') or 'dynamic.csv'}; max and RMS in the table "
        "'Dynamic compensation'.",
    )
    d = run.dynamic
    if d is None:
        item.absent = run.absent.get("dynamic", "dynamic compensation: dynamic.csv absent in this run")
        return item
    if len(d["t"]) == 0:
        item.absent = "dynamic compensation: dynamic.csv has no samples"
        return item
    passes = entry.get("passes")
    scale = entry.get("limit_scale") if isinstance(entry.get("limit_scale"), Mapping) else {}
    parts = [
        f"{passes} timing pass{'' if passes == 1 else 'es'}" if passes is not None else "",
        (
            "limits scaled "
            + ", ".join(f"{k} ×{format_number(float(v), 3)}" for k, v in scale.items() if isinstance(v, (int, float)))
            if scale
            else ""
        ),
        (
            f"dynamic part smoothed over {format_number(1e3 * float(entry['smoothing_s']))} ms"
            + (
                f" ({format_number(1e3 * float(entry['smoothing_edge_s']))} ms one-sided next to rest)"
                if isinstance(entry.get("smoothing_edge_s"), (int, float))
                else ""
            )
            if isinstance(entry.get("smoothing_s"), (int, float))
            else ""
        ),
    ]
    sub = "; ".join(p for p in parts if p)
    title = _wrap(
        f"{ctx.robot_name}, branch {ctx.branch}: TCP deviation from the planned path; load: {ctx.load}", 130
    ) + (f"\n{sub}" if sub else "")
    item.job = job(
        dynamic_plot.dynamic_figure,
        d["t"],
        d["moving"],
        (d["e_none_m"], d["e_static_m"], d["e_static_dynamic_m"]),
        d["tcp_speed_m_s"],
        title=title,
    )
    return item
