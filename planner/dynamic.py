"""The dynamic-compensation stage of a plan: motor-side commands for the timed trajectory.

After timing, with ``[timing] dynamic = true``: the *link-side* path (the deflected configuration
the exact compensation makes the arm take at every waypoint) is timed by the controller's
jerk-limited method; :func:`problems.dynamic.motor_command` turns it into the motor-side command
that makes the elastic joints carry the static and the inertial torques; the command's dynamic
part (command minus static compensation) is zero where the link side is at rest and smoothed
(:func:`problems.dynamic.command_with_rest`: centred moving averages of
:data:`~problems.dynamic.DYNAMIC_SMOOTHING_S` in the motion, one-sided ones next to a rest phase),
so the command at rest (start, end, dwells) *is* the static compensation.  The command's
velocity, acceleration and jerk columns are those of one smooth curve through its samples
(:func:`problems.dynamic.command_derivatives`: a quintic spline, zero velocity and acceleration
at rest), the curve a controller that interpolates positions, velocities and accelerations runs
(ROS 2's joint_trajectory_controller); its peaks, between the samples included
(:func:`problems.dynamic.curve_peaks`), are checked against the limits.  Each pass re-times the
link side with every limit the command exceeded scaled by ``(1 - DYNAMIC_RETIME_MARGIN) / ratio``,
and a scaled limit the command keeps with more than :data:`DYNAMIC_SETTLED_BAND` to spare scaled
back up the same way (``jerk_optimal``'s duration is not monotonic in its limits); the search ends
at a pass within every limit and within that band of each scaled one, or after
:data:`DYNAMIC_MAX_PASSES` passes, and keeps the fastest pass within every limit.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from models.arm import ArmModel
from models.errors import InfeasibleError
from models.load import Load
from models.status import Status
from planner.numbers import NUMERICAL_FLOOR_MM, headline_mm, mm_text
from problems.timing import JointLimits, Trajectory, TimingStatus, time_parametrize
from problems.dynamic import (
    DYNAMIC_BLEND_S,
    DYNAMIC_EDGE_SMOOTHING_S,
    DYNAMIC_SMOOTHING_S,
    MISMATCH_CASES,
    DynamicStatus,
    command_derivatives,
    curve_peaks,
    mismatch_errors,
    command_with_rest,
    motor_command,
    predicted_tcp_errors,
    rest_samples,
)

__all__ = [
    "HEADLINE_CASES",
    "HEADLINE_DEFINITION",
    "DynamicStageStatus",
    "dynamic_stage",
    "headline_text",
]

#: Re-timing passes at most, and the margin kept below a limit the command exceeded.
DYNAMIC_MAX_PASSES: int = 6
DYNAMIC_RETIME_MARGIN: float = 0.02
#: A command ratio above 1 + this fails the check (the timing's own tolerance).
DYNAMIC_RATIO_TOL: float = 1e-9
#: A pass within every limit ends the search when no scaled limit's peak ratio is below 1 - this: the
#: command uses the limit to within twice the margin (``jerk_optimal``'s duration is not monotonic in
#: its limits, so a pass far below a scaled limit is not taken as the answer: the scale is raised back).
DYNAMIC_SETTLED_BAND: float = 2.0 * DYNAMIC_RETIME_MARGIN
_KEYS = ("velocity", "acceleration", "jerk")
#: What the summary's predicted errors are, and the stage's assumptions (``summary.json``).
SUMMARY_DEFINITION = (
    "predicted (quasi-static) TCP position error against the planned link side at every sample of trajectory.csv, "
    "mm, under the torques the motor-side command carries (the load, the arm's own weight from its rigid-body model, "
    "the inertial torques of the motion), max and RMS during the motion and max at rest (the samples whose joint "
    "rates and accelerations are zero: start, end, dwells), for the link plan commanded as is (none: "
    "uncompensated), the static command (static: load and own weight, no inertial torques) and the motor-side "
    "command (static+dynamic: what trajectory.csv holds); vibrations excluded (docs/elastic-simulation.md); "
    "mismatch: the same during the motion on an arm whose joint stiffness and payload mass are the factors times "
    "the model's (the command unchanged)"
)
#: The headline's cases: (``predicted_tcp_error`` key, headline key part, words).
HEADLINE_CASES = (
    ("none", "uncompensated", "uncompensated"),
    ("static", "static_command", "static command"),
    ("static+dynamic", "motor_side_command", "motor-side command"),
)
#: What the dynamic headline's errors are (``summary.json`` ``headline.dynamic_compensation.definition``).
HEADLINE_DEFINITION = (
    "TCP position error |reached - planned| along the controller's trajectory (every sample of trajectory.csv), "
    "predicted quasi-statically (the link where the command and the deflection of the planned torques put it; "
    "vibrations excluded), under the torques the motor-side command carries: the load, the arm's own weight "
    "(rigid-body model) and the inertial torques of the timed motion. Max during the motion and max at rest "
    "(samples whose joint rates and accelerations are zero: start, end, dwells; there the motor-side command is "
    "the static command, by construction), for the link plan commanded as is (uncompensated), the static command "
    "(load and own weight, no inertial torques) and the motor-side command (trajectory.csv). The same numbers as "
    "dynamic_compensation.predicted_tcp_error, rounded to 4 significant digits, 0 below numerical_floor_mm. The "
    "waypoint errors error_before / error_after are another measure: the arm model's load alone (its own weight "
    "only if the model has a gravity effect), at the exact equilibrium, at the waypoints."
)
SUMMARY_ASSUMPTIONS = (
    "elastic joints between the motor-side position the servo holds and the link; joint damping "
    "and link compliance not compensated dynamically; payload a point mass"
)


def headline_text(h: dict[str, Any]) -> str:
    """The dynamic headline ``h`` (:meth:`DynamicStage.headline`, as in ``summary.json``) in words, for
    the terminal: the max errors during the motion and at rest of :data:`HEADLINE_CASES`, and what
    they are."""

    def chain(where: str, named: bool) -> str:
        values = [h.get(f"error_{where}_max_{key}_mm") for _case, key, _words in HEADLINE_CASES]
        texts = [mm_text(v) if v is not None else "n/a" for v in values]
        return " -> ".join(f"{t} {w}" if named else t for t, (_c, _k, w) in zip(texts, HEADLINE_CASES, strict=True))

    return (
        f"TCP error max during the motion {chain('motion', True)}; at rest (start, end, dwells) "
        f"{chain('rest', False)} (predicted along trajectory.csv under the load, the arm's own weight and the "
        "inertial torques; the waypoint errors before -> after exact compensation: the arm model's load alone)"
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
        rad/s, rad/s^2, rad/s^3) at ``dt``, the derivatives those of the quintic spline through the
        samples (zero velocity and acceleration at rest), limit ratios its peaks against the plan's
        limits.
    link : Trajectory or None
        The planned link side on the same samples (the link-side timing of the pass kept).
    passes : int
        Timings of the link side it took.
    limit_scale : dict
        Factor on each limit the link side was timed with in the pass kept.
    errors_m : dict of str to ndarray (M,)
        Predicted (quasi-static) TCP position error along the command for ``none`` (the link plan
        commanded as is), ``static`` (static compensation only) and ``static+dynamic``, m.
    moving : ndarray (M,) of bool
        Samples during the motion; the others are at rest (:func:`problems.dynamic.rest_samples` of the
        link side), where the command is the static command.
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
            "smoothing_edge_s": DYNAMIC_EDGE_SMOOTHING_S,
            "smoothing_blend_s": DYNAMIC_BLEND_S,
            "headline": self.headline(),
            "predicted_tcp_error": self.error_stats_mm(),
            "mismatch": self.mismatch,
            "definition": SUMMARY_DEFINITION,
            "assumptions": SUMMARY_ASSUMPTIONS,
            "link_columns": "trajectory.csv ql1..ql6: the planned link side",
            "file": "dynamic.csv",
        }

    def headline(self) -> dict[str, Any]:
        """The dynamic headline: max predicted TCP error during the motion and at rest for each of
        :data:`HEADLINE_CASES` (mm, ``error_motion_max_<case>_mm``, ``error_rest_max_<case>_mm``:
        :meth:`error_stats_mm` rounded by :func:`planner.numbers.headline_mm`), the keys below the
        numerical floor and :data:`HEADLINE_DEFINITION`.  The terminal, ``summary.json`` and the
        report show these numbers; none of them recomputes one."""
        stats = self.error_stats_mm()
        h: dict[str, Any] = {}
        for where in ("motion", "rest"):
            for case, key, _words in HEADLINE_CASES:
                value = stats[case][f"{where}_max_mm"] if case in stats else None
                h[f"error_{where}_max_{key}_mm"] = headline_mm(value)
        h["numerical_floor_mm"] = NUMERICAL_FLOOR_MM
        h["below_numerical_floor"] = [k for k, v in h.items() if k.startswith("error_") and v == 0.0]
        h["definition"] = HEADLINE_DEFINITION
        return h

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


def _command(arm: ArmModel, link: Trajectory, load: Load, path_q: np.ndarray) -> _Pass:
    """The link samples' load rows, the command (static at rest, :func:`~problems.dynamic.command_with_rest`),
    the predicted errors and the moving mask (not at rest: :func:`~problems.dynamic.rest_samples`).

    Raises
    ------
    InfeasibleError
        No motor-side command (the robot has no link masses); the message is the reason.
    """
    q, qd, qdd = link.q, link.qd, link.qdd
    rows = _sample_rows(load, path_q, q)
    dyn = motor_command(arm, q, qd, qdd, load, rows=rows)
    if dyn.status is not DynamicStatus.OK:
        raise InfeasibleError(dyn.reason)
    static = q - arm.torque_deflection(q, dyn.tau_static)  # the same command without the inertial torques
    rest = rest_samples(qd, qdd)
    rest[[0, -1]] = True  # every timing method runs rest to rest (Trajectory.t)
    theta = command_with_rest(static, dyn.theta, rest, link.dt)
    needed = q - dyn.theta  # the deflection the plan's torques cause
    errors = predicted_tcp_errors(arm, q, needed, {"none": q, "static": static, "static+dynamic": theta})
    return _Pass(q, qd, qdd, rows, theta, static, errors, ~rest)


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


@dataclass
class _Attempt:
    """One timing pass of the link side: its limit scales, the command and its peak ratios."""

    scale: dict[str, float]
    link: Trajectory
    ps: _Pass
    derivs: tuple[np.ndarray, np.ndarray, np.ndarray]
    ratio: dict[str, np.ndarray]

    @property
    def worst(self) -> dict[str, float]:
        return {k: float(r.max()) for k, r in self.ratio.items()}

    @property
    def ok(self) -> bool:
        return all(v <= 1.0 + DYNAMIC_RATIO_TOL for v in self.worst.values())

    @property
    def settled(self) -> bool:
        """Within every limit, and no scaled limit leaves more than :data:`DYNAMIC_SETTLED_BAND` unused."""
        return self.ok and all(self.scale[k] == 1.0 or v >= 1.0 - DYNAMIC_SETTLED_BAND for k, v in self.worst.items())


def _attempt(
    arm: ArmModel,
    path_q: np.ndarray,
    lim: dict[str, np.ndarray],
    scale: dict[str, float],
    dt: float,
    method: str,
    options: dict[str, Any],
    load: Load,
) -> _Attempt | str:
    """Time the link side with the limits ``lim`` times ``scale`` and build the command, its derivative
    columns (:func:`~problems.dynamic.command_derivatives`) and its peak ratios over the whole curve
    (:func:`~problems.dynamic.curve_peaks`); the failure's reason instead when the timing fails.

    Raises
    ------
    InfeasibleError
        No motor-side command (the robot has no link masses).
    """
    link = time_parametrize(path_q, JointLimits(*(lim[k] * scale[k] for k in _KEYS)), method, dt, **options)
    if link.status is not TimingStatus.OK:
        return f"the link side's {method} timing: {link.status.value}: {link.reason}"
    ps = _command(arm, link, load, path_q)
    derivs = command_derivatives(link.t, ps.theta, ~ps.moving)
    peaks = curve_peaks(link.t, ps.theta, derivs[0], derivs[1])
    return _Attempt(dict(scale), link, ps, derivs, {k: peaks[k] / lim[k] for k in _KEYS})


def dynamic_stage(
    arm: ArmModel, path_q: np.ndarray, limits: JointLimits, dt: float, method: str, options: dict[str, Any], load: Load
) -> DynamicStage:
    """Time the link-side path ``path_q`` (N, 6) rad and build the motor-side command (see module doc)."""
    scale = dict.fromkeys(_KEYS, 1.0)
    lim = {k: np.asarray(getattr(limits, k), float) for k in _KEYS}
    best: _Attempt | None = None
    last: _Attempt | None = None
    for p in range(1, DYNAMIC_MAX_PASSES + 1):
        try:
            got = _attempt(arm, path_q, lim, scale, dt, method, options, load)
        except InfeasibleError as exc:
            return DynamicStage(DynamicStageStatus.FAILED, str(exc), passes=p)
        if isinstance(got, str):
            if best is not None:  # an earlier pass is within every limit: keep it
                break
            return DynamicStage(DynamicStageStatus.FAILED, f"pass {p}: {got}", passes=p, limit_scale=dict(scale))
        last = got
        if got.ok and (best is None or got.link.duration_s < best.link.duration_s):
            best = got
        if got.settled:
            break
        for k, v in got.worst.items():
            if v > 1.0 + DYNAMIC_RATIO_TOL or scale[k] < 1.0:  # down where exceeded, back up where slack
                scale[k] = min(1.0, scale[k] * (1.0 - DYNAMIC_RETIME_MARGIN) / v) if v > 0.0 else 1.0
    assert last is not None
    return _stage(arm, best or last, p, method, dt, load)


def _stage(arm: ArmModel, a: _Attempt, passes: int, method: str, dt: float, load: Load) -> DynamicStage:
    """The stage's result from the chosen pass ``a`` after ``passes`` timings of the link side."""
    ok = a.ok
    text = ", ".join(f"{k} {v:.3f}" for k, v in a.worst.items())
    scaled = ", ".join(f"{k} x{v:.3f}" for k, v in a.scale.items() if v != 1.0) or "none"
    reason = (
        f"motor-side command after {passes} timing pass(es) of the link side (limits scaled: {scaled}"
        f"{'; the fastest pass within every limit' if ok and passes > 1 else ''}); command peak ratios {text} (on "
        "the quintic spline through its samples); dynamic part zero at rest (the command there is the "
        f"static one), smoothed over 2 x {DYNAMIC_SMOOTHING_S * 1e3:g} ms centred in the motion, 2 x "
        f"{DYNAMIC_EDGE_SMOOTHING_S * 1e3:g} ms one-sided next to rest, handed over within {DYNAMIC_BLEND_S * 1e3:g} ms"
    )
    t = a.link.t
    d1, d2, d3 = a.derivs
    command = Trajectory(
        method=method,
        status=TimingStatus.OK if ok else TimingStatus.LIMIT_EXCEEDED,
        reason=reason,
        t=t,
        q=a.ps.theta,
        qd=d1,
        qdd=d2,
        qddd=d3,
        duration_s=float(t[-1]),
        limit_ratio=a.ratio,
        dt=dt,
        iterations=passes,
    )
    return DynamicStage(
        DynamicStageStatus.OK if ok else DynamicStageStatus.LIMIT_EXCEEDED,
        reason,
        command,
        replace(a.link, method=f"{method} (link side)"),
        passes,
        dict(a.scale),
        a.ps.errors,
        a.ps.moving,
        _mismatch(arm, a.ps, load),
    )
