"""The dynamic-compensation stage of a plan: motor-side commands for the timed trajectory.

After timing, with ``[timing] dynamic = true``: the *link-side* path (the deflected configuration
the exact compensation makes the arm take at every waypoint) is timed by the controller's
jerk-limited method; :func:`problems.dynamic.motor_command` turns it into the motor-side command
that makes the elastic joints carry the static and the inertial torques; the command's dynamic
part (command minus static compensation) is smoothed by two moving averages of
:data:`~problems.dynamic.DYNAMIC_SMOOTHING_S`, and the link trajectory is padded with that much
rest at both ends so that the command starts and ends exactly at the static compensation.  The
command's velocity, acceleration and jerk (central differences of the samples) are checked
against the limits; where the command exceeds one, the link side is re-timed with that limit
scaled by ``(1 - DYNAMIC_RETIME_MARGIN) / ratio`` and the command rebuilt, at most
:data:`DYNAMIC_MAX_PASSES` times.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from models.arm import ArmModel
from models.errors import InfeasibleError
from models.load import Load
from models.status import Status
from problems.timing import JointLimits, Trajectory, TimingStatus, time_parametrize
from problems.dynamic import (
    DYNAMIC_SMOOTHING_S,
    MISMATCH_CASES,
    DynamicStatus,
    finite_derivatives,
    mismatch_errors,
    motor_command,
    padded,
    predicted_tcp_errors,
    smooth,
)

__all__ = ["DYNAMIC_MAX_PASSES", "DYNAMIC_RETIME_MARGIN", "DynamicStage", "DynamicStageStatus", "dynamic_stage"]

#: Re-timing passes at most, and the margin kept below a limit the command exceeded.
DYNAMIC_MAX_PASSES: int = 6
DYNAMIC_RETIME_MARGIN: float = 0.02
#: A command ratio above 1 + this fails the check (the timing's own tolerance).
DYNAMIC_RATIO_TOL: float = 1e-9
_KEYS = ("velocity", "acceleration", "jerk")
#: What the summary's predicted errors are, and the stage's assumptions (``summary.json``).
SUMMARY_DEFINITION = (
    "predicted (quasi-static) TCP position error against the planned link side, mm, during the motion and at rest, "
    "for the link plan commanded as is (none), the static compensation only (static) and the motor-side command "
    "(static+dynamic); vibrations excluded (docs/elastic-simulation.md); mismatch: the same during the motion on an "
    "arm whose joint stiffness and payload mass are the factors times the model's (the command unchanged)"
)
SUMMARY_ASSUMPTIONS = (
    "elastic joints between the motor-side position the servo holds and the link; joint damping "
    "and link compliance not compensated dynamically; payload a point mass"
)


class DynamicStageStatus(Status):
    """Outcome of :func:`dynamic_stage`."""

    OK = "ok"
    LIMIT_EXCEEDED = "limit_exceeded"
    FAILED = "failed"


@dataclass
class DynamicStage:
    """Result of :func:`dynamic_stage`.

    Attributes
    ----------
    status : DynamicStageStatus
    reason : str
    command : Trajectory or None
        The motor-side command (what the controller runs): ``q``, ``qd``, ``qdd``, ``qddd`` (rad,
        rad/s, rad/s^2, rad/s^3) at ``dt``, derivatives by central differences, limit ratios
        against the plan's limits.
    link : Trajectory or None
        The planned link side on the same samples (rest padding included).
    passes : int
        Timings of the link side it took.
    limit_scale : dict
        Factor on each limit the link side was timed with in the last pass.
    errors_m : dict of str to ndarray (M,)
        Predicted (quasi-static) TCP position error along the command for ``none`` (the link plan
        commanded as is), ``static`` (static compensation only) and ``static+dynamic``, m.
    moving : ndarray (M,) of bool
        Samples during the motion (the others are at rest).
    mismatch : list of dict
        The predicted gain during the motion on arms whose stiffness and payload differ from the
        model's (``stiffness_factor``, ``payload_factor``, both max errors in mm, ``gain``).
    """

    status: DynamicStageStatus
    reason: str
    command: Trajectory | None = None
    link: Trajectory | None = None
    passes: int = 0
    limit_scale: dict[str, float] = field(default_factory=dict)
    errors_m: dict[str, np.ndarray] = field(default_factory=dict)
    moving: np.ndarray | None = None
    mismatch: list[dict[str, float]] = field(default_factory=list)

    def series(self, arm: ArmModel) -> tuple[list[str], np.ndarray]:
        """Columns and rows of ``dynamic.csv``: time (s), moving (0/1), the predicted TCP errors
        (m) and the planned TCP speed (m/s, base frame) at every command sample."""
        assert self.link is not None and self.moving is not None
        J = arm.kinematics.J(self.link.q)
        speed = np.linalg.norm(np.einsum("nij,nj->ni", J[:, :3, :], self.link.qd), axis=1)
        cols = ["t", "moving", "e_none_m", "e_static_m", "e_static_dynamic_m", "tcp_speed_m_s"]
        rows = np.column_stack(
            [
                self.link.t,
                self.moving.astype(float),
                self.errors_m["none"],
                self.errors_m["static"],
                self.errors_m["static+dynamic"],
                speed,
            ]
        )
        return cols, rows

    def summary(self) -> dict[str, Any]:
        """The ``dynamic_compensation`` block of ``summary.json``."""
        return {
            "status": self.status.value,
            "reason": self.reason,
            "passes": self.passes,
            "limit_scale": self.limit_scale,
            "smoothing_s": DYNAMIC_SMOOTHING_S,
            "predicted_tcp_error": self.error_stats_mm(),
            "mismatch": self.mismatch,
            "definition": SUMMARY_DEFINITION,
            "assumptions": SUMMARY_ASSUMPTIONS,
            "link_columns": "trajectory.csv ql1..ql6: the planned link side",
            "file": "dynamic.csv",
        }

    def error_stats_mm(self) -> dict[str, dict[str, float]]:
        """Max and RMS of each predicted error during the motion and at rest, mm."""
        out: dict[str, dict[str, float]] = {}
        mv = self.moving if self.moving is not None else np.ones(0, bool)
        for name, e in self.errors_m.items():
            em, er = e[mv] * 1e3, e[~mv] * 1e3
            out[name] = {
                "motion_max_mm": float(em.max(initial=0.0)),
                "motion_rms_mm": float(np.sqrt(np.mean(em**2))) if em.size else 0.0,
                "rest_max_mm": float(er.max(initial=0.0)),
            }
        return out


def _sample_rows(load: Load, path_q: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Load rows (M, 19) of the samples ``q``: those of the nearest waypoint of ``path_q`` (a load
    given per waypoint changes between waypoints at the nearest one)."""
    rows = load.rows(len(path_q))
    if np.all(rows == rows[:1]):
        return np.repeat(rows[:1], len(q), axis=0)
    near = np.argmin(np.linalg.norm(q[:, None, :] - path_q[None, :, :], axis=2), axis=1)
    return rows[near]


@dataclass
class _Pass:
    """One pass's padded link samples, load rows, commands, predicted errors and moving mask."""

    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    rows: np.ndarray
    theta: np.ndarray
    static: np.ndarray
    errors: dict[str, np.ndarray]
    moving: np.ndarray


def _command(arm: ArmModel, link: Trajectory, load: Load, path_q: np.ndarray, n_smooth: int, n_pad: int) -> _Pass:
    """Padded link samples, the smoothed command, the predicted errors and the moving mask.

    Raises
    ------
    InfeasibleError
        No motor-side command (the robot has no link masses); the message is the reason.
    """
    q, qd, qdd = (padded(x, n_pad) for x in (link.q, link.qd, link.qdd))
    rows = _sample_rows(load, path_q, q)
    dyn = motor_command(arm, q, qd, qdd, load, rows=rows)
    if dyn.status is not DynamicStatus.OK:
        raise InfeasibleError(dyn.reason)
    static = q - arm.torque_deflection(q, dyn.tau_static)  # the same command without the inertial torques
    theta = static + smooth(dyn.theta - static, n_smooth)
    needed = q - dyn.theta  # the deflection the plan's torques cause
    errors = predicted_tcp_errors(arm, q, needed, {"none": q, "static": static, "static+dynamic": theta})
    moving = np.zeros(len(q), dtype=bool)
    moving[n_pad : n_pad + len(link.q)] = np.linalg.norm(link.qd, axis=1) > 0.0
    return _Pass(q, qd, qdd, rows, theta, static, errors, moving)


def _mismatch(arm: ArmModel, ps: _Pass, load: Load) -> list[dict[str, float]]:
    """The gain (static-only over static+dynamic max TCP error during the motion) on arms whose
    stiffness and payload differ from the model's (:data:`~problems.dynamic.MISMATCH_CASES`)."""
    out = []
    for kf, pf in MISMATCH_CASES:
        e = mismatch_errors(arm, ps.q, ps.qd, ps.qdd, load, ps.rows, {"static": ps.static, "dynamic": ps.theta}, kf, pf)
        st, dy = float(e["static"][ps.moving].max(initial=0.0)), float(e["dynamic"][ps.moving].max(initial=0.0))
        out.append(
            {
                "stiffness_factor": kf,
                "payload_factor": pf,
                "static_motion_max_mm": st * 1e3,
                "static_dynamic_motion_max_mm": dy * 1e3,
                "gain": st / dy if dy > 0 else float("inf"),
            }
        )
    return out


def dynamic_stage(
    arm: ArmModel, path_q: np.ndarray, limits: JointLimits, dt: float, method: str, options: dict[str, Any], load: Load
) -> DynamicStage:
    """Time the link-side path ``path_q`` (N, 6) rad and build the motor-side command (see module doc)."""
    n_smooth = max(1, int(round(DYNAMIC_SMOOTHING_S / dt)))
    n_pad = n_smooth
    scale = dict.fromkeys(_KEYS, 1.0)
    lim = {k: np.asarray(getattr(limits, k), float) for k in _KEYS}
    ratio: dict[str, np.ndarray] = {}
    for p in range(1, DYNAMIC_MAX_PASSES + 1):
        link = time_parametrize(path_q, JointLimits(*(lim[k] * scale[k] for k in _KEYS)), method, dt, **options)
        if link.status is not TimingStatus.OK:
            return DynamicStage(
                DynamicStageStatus.FAILED,
                f"pass {p}: the link side's {method} timing: {link.status.value}: {link.reason}",
                passes=p,
                limit_scale=dict(scale),
            )
        try:
            ps = _command(arm, link, load, path_q, n_smooth, n_pad)
        except InfeasibleError as exc:
            return DynamicStage(DynamicStageStatus.FAILED, str(exc), passes=p)
        q, theta = ps.q, ps.theta
        derivs = finite_derivatives(theta, dt)
        ratio = {k: np.abs(x).max(axis=0) / lim[k] for k, x in zip(_KEYS, derivs)}
        worst = {k: float(r.max()) for k, r in ratio.items()}
        if all(v <= 1.0 + DYNAMIC_RATIO_TOL for v in worst.values()):
            break
        for k, v in worst.items():
            if v > 1.0:
                scale[k] *= (1.0 - DYNAMIC_RETIME_MARGIN) / v
    t = np.arange(len(q)) * dt
    ok = all(float(r.max()) <= 1.0 + DYNAMIC_RATIO_TOL for r in ratio.values())
    text = ", ".join(f"{k} {float(r.max()):.3f}" for k, r in ratio.items())
    scaled = ", ".join(f"{k} x{v:.3f}" for k, v in scale.items() if v != 1.0) or "none"
    reason = (
        f"motor-side command after {p} timing pass(es) of the link side "
        f"(limits scaled: {scaled}); command peak ratios {text}; dynamic part smoothed over 2 x "
        f"{n_smooth * dt * 1e3:g} ms, {n_pad * dt * 1e3:g} ms rest added at both ends"
    )
    status = TimingStatus.OK if ok else TimingStatus.LIMIT_EXCEEDED
    d1, d2, d3 = derivs
    command = Trajectory(
        method=method,
        status=status,
        reason=reason,
        t=t,
        q=theta,
        qd=d1,
        qdd=d2,
        qddd=d3,
        duration_s=float(t[-1]),
        limit_ratio=ratio,
        dt=dt,
        iterations=p,
    )
    lq, lqd, lqdd, lqddd = (padded(x, n_pad) for x in (link.q, link.qd, link.qdd, link.qddd))
    link_tr = Trajectory(
        method=f"{method} (link side)",
        status=link.status,
        reason=link.reason,
        t=t,
        q=lq,
        qd=lqd,
        qdd=lqdd,
        qddd=lqddd,
        duration_s=float(t[-1]),
        limit_ratio=link.limit_ratio,
        dt=dt,
        iterations=link.iterations,
    )
    return DynamicStage(
        DynamicStageStatus.OK if ok else DynamicStageStatus.LIMIT_EXCEEDED,
        reason,
        command,
        link_tr,
        p,
        dict(scale),
        ps.errors,
        ps.moving,
        _mismatch(arm, ps, load),
    )
