"""The content of a plan's ``summary.json``, built from its :class:`~planner.plan_result.PlanResult`.

:func:`plan_summary` is what :meth:`PlanResult.summary` returns (a plan builds it once, in
:meth:`PlanResult.view`); :func:`headline` is its opening block, what a cell engineer reads
first; :func:`timing_summary` the keys of the timing methods (read from the timing registry).
SI units unless a key says otherwise.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from problems.compensation import uncompensated
from problems.posture import BranchResult
from problems.timing import LIMIT_RATIO_TOL, get_method
from problems.timing.limit_use import limit_use
from problems.timing.trajectory import LIMIT_KEYS

from planner import branches as branch_words
from planner.numbers import NUMERICAL_FLOOR_MM, headline_mm, round_sig
from planner.record.columns import trajectory_file

if TYPE_CHECKING:
    from planner.plan_result import PlanResult
    from problems.problem import Problem
    from problems.timing import Trajectory

__all__ = [
    "HEADLINE_DEFINITION",
    "headline",
    "plan_summary",
    "within_limits",
]


def plan_summary(res: PlanResult, errors: Mapping[int, tuple[np.ndarray, np.ndarray]] | None = None) -> dict[str, Any]:
    """The content of ``summary.json`` (SI units unless a key says otherwise).

    It opens with ``headline`` (status, branch, TCP error before and after, duration:
    rounded to what they mean, units in the keys; see :func:`headline`) and
    ``provenance`` (compplan version, command line, date, input files with SHA-256).
    ``errors``: the branches' equilibrium errors of :meth:`PlanResult.branch_errors`, when the caller
    has them (else those the summary needs are computed).  Each call hashes the inputs and
    solves the equilibria again: build a plan's summary once (:meth:`PlanResult.view`).
    """
    pr = res.problem
    R = pr.robot.tcp2flange
    s: dict[str, Any] = {
        "command": "plan",
        "plan_status": res.status.value,
        "reason": res.reason,
        "scenario": f"{pr.name}: {pr.description}" if pr.description else pr.name,
        "problem": pr.to_dict(),
        "robot": pr.robot.name,
        "robot_file": pr.robot.to_dict(),
        "tcp": (
            "flange" if np.allclose(R, np.eye(4)) else f"tool: xyz {[float(v) for v in R[:3, 3]]} m in the flange frame"
        ),
        "orientation": pr.rule.value,
        "wrench": _wrench_keys(pr),
        "payload": _payload_keys(pr),
        "model": pr.model.describe(),
        "n_waypoints": pr.n,
        "limits": {
            "velocity": pr.limits.velocity,
            "acceleration": pr.limits.acceleration,
            "jerk": pr.limits.jerk,
            "max_joint_step": pr.limits.max_joint_step,
            "q_min": pr.robot.q_min,
            "q_max": pr.robot.q_max,
        },
        "dt": pr.timing.dt,
        "warnings": list(res.warnings),
        "stage_times_s": dict(res.stage_times_s),
    }
    if res.posture is not None:
        s.update(_posture_keys(res, errors))
    if res.exact is not None:
        assert res.before is not None and res.closed is not None
        s["error_before"] = res.before.stats_mm()
        s["error_after"] = {"closed_form": res.closed.stats_mm(), "exact": res.exact.stats_mm()}
        s["exact_residual_max_m"] = float(res.exact.error_norm_m.max())
        s["status"] = {"closed_form": res.closed.status.value, "exact": res.exact.status.value}
        s["warnings"] += list(res.closed.warnings)
    if res.model_sigma is not None:
        s["model_sigma"] = res.model_sigma.to_dict()
    if pr.program is not None:
        s["program"] = program_summary(res)
    if pr.cut is not None:
        from planner.plan_cut import cut_summary

        s["cut"] = cut_summary(res)
    if res.cell is not None and res.posture is not None:
        from planner.cell_check import cell_summary

        s["cell"] = cell_summary(res.cell, res.posture.labels)
    if res.trajectories:
        s.update(timing_summary(res))
        s["warnings"] += [f"{m}: {t['limit_use']['why']}" for m, t in s["timing"].items() if t["limit_use"]["why"]]
    head = {"headline": headline(s), "provenance": res.provenance()}
    return {**head, **s}


def _wrench_keys(pr: Problem) -> dict[str, Any]:
    """The summary's ``wrench``: frame, point, waypoint 0's force and moment, where every waypoint's is."""
    w = pr.wrench
    wrench: dict[str, Any] = {
        "frame": pr.wrench_frame,
        "point": "TCP",
        "F_N": w[0, :3],
        "M_Nm": w[0, 3:],
        "per_waypoint": bool(pr.wrench_per_waypoint),
    }
    if pr.wrench_per_waypoint and pr.program is not None:
        wrench["note"] = "F_N and M_Nm are waypoint 0's; the program's CL file gives every point's (TCP frame)"
    elif pr.wrench_per_waypoint:
        wrench["rows"] = w
        wrench["note"] = "F_N and M_Nm are waypoint 0's; rows holds every waypoint's wrench"
    return wrench


def _payload_keys(pr: Problem) -> dict[str, Any] | None:
    """The summary's ``payload`` (a point mass), None without one."""
    return (
        {
            "mass_kg": float(pr.payload_mass_kg),
            "com_m_tcp_frame": pr.payload_com_m,
            "gravity_m_s2": pr.load.gravity,
            "inertia_kg_m2_about_com_tcp_axes": [0.0] * 6,
            "inertia_note": "a point mass (ixx, iyy, izz, ixy, ixz, iyz = 0)",
        }
        if pr.payload_mass_kg
        else None
    )


def within_limits(tr: Trajectory, keys: tuple[str, ...]) -> bool:
    """Whether every limit ratio of ``tr`` named in ``keys`` is finite and at most 1 (within
    :data:`~problems.timing.LIMIT_RATIO_TOL`) at every sample."""
    return all(
        np.all(np.isfinite(tr.limit_ratio[k])) and float(np.max(tr.limit_ratio[k])) <= 1.0 + LIMIT_RATIO_TOL
        for k in keys
    )


def program_summary(res: PlanResult) -> dict[str, Any]:
    """The ``program`` keys of a program path: the file, its waypoints and stops, the path tolerance,
    and per timing method the programmed and achieved times and the slowed program lines."""
    sec = res.problem.program
    w = sec.waypoints
    cut = ~w.rapid
    out: dict[str, Any] = {
        "file": sec.file,
        "kind": sec.kind,
        "units_note": sec.units_note,
        "n_waypoints": int(w.n),
        "n_lines": int(len(np.unique(w.line))),
        "n_stops": int(np.count_nonzero(w.stop)),
        "dwell_s": float(np.sum(w.dwell_s)),
        "path_tolerance_mm": w.tolerance_m * 1e3,
        "path_tolerance_source": w.tolerance_source,
        "cutting_length_m": float(np.sum(np.linalg.norm(np.diff(w.points_m, axis=0), axis=1)[cut[1:]])),
        "workpiece": {"xyz_m": sec.workpiece.xyz_m, "rpy_rad": sec.workpiece.rpy_rad},
        "feed": {},
    }
    for m, fl in res.feed.items():
        worst = fl.slowed_lines(w.line)
        by_limit = fl.slowed_by_limit(w.line)
        dur = fl.trajectory.duration_s
        t = fl.trajectory.t
        on_cut = cut[fl.sample_move[1:]] if len(t) > 1 else np.zeros(0, dtype=bool)
        cutting = float(np.sum(np.diff(t)[on_cut])) if len(t) > 1 else 0.0
        out["feed"][m] = {
            "programmed_time_s": fl.programmed_time_s,
            "cutting_time_s": cutting,
            "cutting_time_over_programmed": cutting / fl.programmed_time_s if fl.programmed_time_s > 0 else None,
            "cutting_time_note": "time of the samples on cutting moves (their accelerations and stops included)",
            "duration_s": dur,
            "peak_feed_ratio": fl.feed_ratio,
            "n_stretches": fl.n_stretches,
            "n_stretches_by_fallback": fl.n_substituted,
            "slowed_lines": [[L, round_sig(worst[L], 3)] for L in sorted(worst)],
            "slowed_note": "program line, peak TCP speed over F on it, where below 1 - FEED_SLOW_TOL (0.95)",
            "slowed_by_limit": [
                [L, round_sig(by_limit[L][0], 3), by_limit[L][1], by_limit[L][2]] for L in sorted(by_limit)
            ],
            "slowed_by_limit_note": (
                "the slowed lines a joint limit holds down (line, peak TCP speed over F, joint, derivative): the "
                "joints cannot cruise at F there; the other slowed lines are slowed only by what surrounds them: a "
                "stop, or a line held down next to them"
            ),
            "n_lines_slowed_by_neighbours": len(worst) - len(by_limit),
            "path_deviation_mm": fl.path_deviation_m * 1e3 if np.isfinite(fl.path_deviation_m) else None,
            "path_deviation_note": (
                "largest distance of a trajectory sample's TCP (forward kinematics of the commands) from the "
                "programmed path (the chords through the waypoints; on an arc, plus the chords' sagitta bound), mm"
            ),
            "n_stretches_fitted": int(fl.n_fitted),
            "n_rows_added": int(fl.n_rows_added),
        }
    return out


def _posture_keys(res: PlanResult, errors: Mapping[int, tuple[np.ndarray, np.ndarray]] | None) -> dict[str, Any]:
    """The posture keys of a summary: the NLP, every branch, the choice and its gain."""
    ps = res.posture
    assert ps is not None
    pr = res.problem
    out: dict[str, Any] = {}
    out["posture"] = {
        "status": ps.status.value,
        "reason": ps.reason,
        "rule": pr.rule.value,
        "freedom": ps.freedom,
        "note": ps.freedom_note,
        "solver": pr.solver.name,
        "build_time_s": ps.build_time_s,
        "solve_time_s": float(sum(r.solve_time_s for r in ps.branches.values())),
        "objective": (
            "sum_k ||S C(q_k) F_k||^2 + smoothness * sum_k ||q_{k+1} - q_k||^2, "
            "S = [I3 0] (translational TCP deflection, m); costs reported "
            "in m^2 without the smoothness term"
        ),
    }
    out["branches"] = {r.label: _branch_entry(r) for r in ps.branches.values()}
    _add_branch_postures(res, out["branches"], errors)
    out["ik_family"] = ps.ik_family
    out["branch_labels"] = list(ps.labels)
    out["rejected_branches"] = {ps.labels[b]: r for b, r in ps.rejected.items()}
    out["default_branch"] = ps.labels[ps.default] if ps.default is not None else None
    if ps.chosen is not None:
        out["chosen_branch"] = ps.best.label
        out["branch"] = ps.best.label
        g = ps.gains()
        out["gain"] = {
            **g,
            "definition": (
                "ratio of RMS load-induced TCP error (the *_cost keys: of summed squared error): "
                "vs_default = default branch (nearest branch.home) at its analytic posture over the "
                "chosen optimised posture; vs_best_analytic = best branch at its analytic posture "
                "over the chosen optimised posture (what the continuous freedom buys)"
            ),
        }
    return out


def timing_summary(res: PlanResult) -> dict[str, Any]:
    """The timing keys of the summary: durations, limit ratios, per-method status and limit use,
    the controller's method and (with dynamic compensation) its block."""
    pr = res.problem
    out: dict[str, Any] = {
        "duration_s": {m: tr.duration_s for m, tr in res.trajectories.items()},
        "limit_ratio": {m: dict(tr.limit_ratio.items()) for m, tr in res.trajectories.items()},
        "timing": {
            m: {
                "status": tr.status.value,
                "reason": tr.reason,
                "limits_enforced": list(get_method(m).checked_limits),
                "within_all_limits": within_limits(tr, LIMIT_KEYS),
                "iterations": tr.iterations,
                "dt": tr.dt,
                "limit_use": limit_use(tr, pr.limits, get_method(m).checked_limits),
                "display_name": get_method(m).display_name,
                "file": trajectory_file(m, res.controller),
            }
            for m, tr in res.trajectories.items()
        },
        "controller_trajectory": res.controller,
    }
    if res.dynamic is not None:
        out["dynamic_compensation"] = res.dynamic.summary()
    return out


#: What the headline's errors are (``summary.json`` ``headline.definition``).
HEADLINE_DEFINITION = (
    "TCP position error |reached - target| over the waypoints, at the exact deflected equilibrium of the arm "
    "model under the whole load (the same numbers as error_before / error_after.exact at full precision): "
    "before = the chosen posture commanded as is, after = with exact compensation. Rounded to 4 significant "
    "digits; an error below numerical_floor_mm (the exact-compensation contract, 1e-9 m) is 0: the accuracy "
    "of the equilibrium solve, not an error of the arm. The IK branch table's RMS errors are first order "
    "(|S C(q) F|, the posture NLP's objective), its rms_error_equilibrium_mm the exact equilibrium."
)


def headline(s: dict[str, Any]) -> dict[str, Any]:
    """The ``headline`` block of a summary: what a cell engineer reads first.

    Status, chosen IK branch (decoded), TCP error before and after compensation (max and
    RMS, mm, rounded; 0 below :data:`~planner.numbers.NUMERICAL_FLOOR_MM`) and the
    duration of the controller's trajectory (s).  Units are in every key.
    """
    h: dict[str, Any] = {"status": s.get("plan_status"), "reason": s.get("reason") or None}
    label = s.get("chosen_branch")
    h["branch"] = label
    h["branch_meaning"] = branch_words.decode(label) if label else None
    if label and isinstance(s.get("branches"), dict) and label in s["branches"]:
        h["branch_posture"] = s["branches"][label].get("posture")
    h["default_branch"] = s.get("default_branch")
    g = s.get("gain") or {}
    h["gain_vs_default"] = round_sig(g["vs_default"]) if np.isfinite(g.get("vs_default", np.nan)) else None
    eb, ea = s.get("error_before"), (s.get("error_after") or {})
    for tag, st in (
        ("error_before", eb),
        ("error_after", ea.get("exact")),
        ("error_after_closed_form", ea.get("closed_form")),
    ):
        for k in ("max", "rms"):
            h[f"{tag}_{k}_mm"] = headline_mm(st[f"{k}_mm"]) if st else None
    h["numerical_floor_mm"] = NUMERICAL_FLOOR_MM
    h["below_numerical_floor"] = [k for k, v in h.items() if k.startswith("error_") and v == 0.0]
    ctrl = s.get("controller_trajectory")
    dur = s.get("duration_s") or {}
    h["duration_s"] = round_sig(dur[ctrl]) if ctrl in dur else None
    h["duration_method"] = ctrl
    h["duration_note"] = f"{get_method(ctrl).duration_note} (trajectory.csv)" if ctrl else "not timed"
    ref = next((m for m in dur if m != ctrl and get_method(m).time_optimal_reference), None)
    if ref is not None:
        h["duration_time_optimal_s"] = round_sig(dur[ref])
        h["duration_time_optimal_method"] = ref
    h["definition"] = HEADLINE_DEFINITION
    dyn = s.get("dynamic_compensation")
    if isinstance(dyn, dict) and isinstance(dyn.get("headline"), dict):  # computed once: DynamicStage.headline
        h["dynamic_compensation"] = dyn["headline"]
    return h


def _add_branch_postures(
    res: PlanResult,
    entries: dict[str, dict[str, Any]],
    errors: Mapping[int, tuple[np.ndarray, np.ndarray]] | None = None,
) -> None:
    """Add to each branch entry its meaning, its posture in words (at waypoint 0) and its
    load-induced TCP error at the exact deflected equilibrium (RMS and max, mm): the same
    measure as ``error_before``, where ``rms_error_mm`` is the NLP's first-order one
    (``errors``: :meth:`PlanResult.branch_errors`, when the caller has them)."""
    assert res.posture is not None
    pr = res.problem
    arm = pr.model
    km = arm.kinematics
    L = pr.load.rows(pr.n)
    for b, r in res.posture.branches.items():
        e = entries[r.label]
        e["meaning"] = branch_words.decode(r.label)
        e["status_meaning"] = branch_words.status_text(r.status.value)
        e["posture"] = e["rms_error_equilibrium_mm"] = e["max_error_equilibrium_mm"] = None
        if not np.all(np.isfinite(r.q)):  # a branch without a posture along the whole path
            continue
        frames = [f[0] for f in km.batch(km.fk_frames, r.q[:1])]
        e["posture"] = branch_words.posture_words(frames, r.q[0], r.label, pr.robot.convention, pr.robot.frame02base)
        err = errors[b][1] if errors is not None else uncompensated(arm, r.q, L).error_norm_m
        e["rms_error_equilibrium_mm"] = float(np.sqrt(np.mean(err**2)) * 1e3)
        e["max_error_equilibrium_mm"] = float(err.max() * 1e3)


def _branch_entry(r: BranchResult) -> dict[str, Any]:
    return {
        "status": r.status.value,
        "cost": r.cost,
        "cost_analytic": r.cost_analytic,
        "cost_warm_start": r.cost_warm,
        "rms_error_mm": r.rms_error_m * 1e3,
        "rms_error_analytic_mm": r.rms_error_analytic_m * 1e3,
        "max_error_mm": float(r.error_m.max() * 1e3),
        "iterations": r.iterations,
        "solve_time_s": r.solve_time_s,
        "warm_start": r.warm_offset,
        "reason": r.reason,
        "active_singularity_guards": (", ".join(f"{k}: {v} waypoint(s)" for k, v in r.active_guards.items()) or "none"),
    }
