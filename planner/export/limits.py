"""What goes to a controller, checked against every limit (``docs/export.md``, "What is checked").

Two checks, both refusing with one line that names the joint, the quantity, the value, the limit
and the time:

* :func:`verify_limits`: the trajectory an export reads (``trajectory.csv`` or the plan in
  memory) is sampled every ``dt`` from 0, inside the joint range, its rate columns inside the
  limits the timing method enforced, and the finite differences of its positions inside them too.
* :func:`check_motion`: what a format sends, as written (times and positions after any
  resampling and rounding), against the robot's own rate limits (its robot file's, not the plan's
  ``[limits]``: :meth:`ExportData.robot_limit`, so a plan made with headroom exports within them),
  under the interpolation its controller applies, a
  :class:`ControllerMotion` the format builds (``ExportFormat.motion``): setpoints at their
  period (URScript ``servoj``), the quintic spline ROS 2's joint_trajectory_controller lays
  through points with positions, velocities and accelerations, the rest-to-rest trapezoid of a
  URScript ``movej`` without blend, and, where the vendor does not document what its controller
  does between points (ABB, KUKA, blended ``movej``), every motion through the points at their
  times (divided differences: what any such motion reaches at least), with a warning saying what
  is not checked.  A streamed motion over a rate limit is slowed down uniformly when the format's
  ``slow_down`` option allows it (``auto``: not a program plan's, whose feed it would change; ``yes``:
  any; and never a dynamic compensation's motor-side command, which is tied to its timing), saying
  so; otherwise it is refused, a program plan with the ``[limits]`` scale that plans it for its
  controller (:mod:`planner.export.headroom`).

The k-th divided difference of positions times ``k!`` equals the k-th derivative of any smooth
motion through them at some time between the first and the last of its points (the mean value
theorem for divided differences), so it is a lower bound of that derivative's peak there: a
trajectory inside its limits passes, a jump of the positions does not.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING
from collections.abc import Callable

import numpy as np

from planner.export.errors import ExportError, ExportLimitError
from planner.export.motion import (
    EXPORT_FD_TOL,
    EXPORT_LIMIT_TOL,
    EXPORT_POSITION_TOL,
    EXPORT_TIME_TOL,
    RATES,
    ControllerMotion,
    Interpolation,
    Peak,
)

if TYPE_CHECKING:
    from planner.export.data import ExportData

__all__ = ["check_motion", "motion_peaks", "verify_limits"]

#: Rounding of positions stored exactly (a CSV's 17 digits, float64 arrays), rad: the floor of the
#: finite differences' slack, ``2^k (eps + floor) / h^k`` for the k-th (``eps``: a format's printed
#: precision).  A float64 angle of a few rad carries about 1e-15 rad; sums of compensations more.
FD_ROUNDING = 1e-12
#: A slowed-down motion is slowed by this much more than the ratios ask (rounding of the new times).
SLOW_DOWN_MARGIN = 1e-3
#: Rounds of slowing down (the resampled setpoints of a slowed trajectory are checked again).
SLOW_DOWN_ROUNDS = 6
#: Most a trajectory is slowed down: beyond, the controller's interpolation is not the plan's motion.
SLOW_DOWN_MAX = 1.5

#: How an approach move's peaks are named (and told apart).
APPROACH = "of the move to the first point"
_ORDER = {name: n for name, _u, n in RATES}


# --------------------------------------------------------------------------------------
# The trajectory an export reads
# --------------------------------------------------------------------------------------


def verify_limits(data: ExportData, where: str) -> None:
    """Refuse a trajectory outside its limits, or not sampled every ``dt`` from 0.

    Checks the positions against ``q_min``/``q_max``, every rate in ``data.enforced`` against
    its limit (relative slack :data:`EXPORT_LIMIT_TOL`) and the positions against those limits
    by finite differences (:data:`EXPORT_FD_TOL`: a jump the rate columns do not show).

    Raises
    ------
    ExportError
        Naming ``where``, the quantity, the joint (1-based), the sample and its time, the value
        and the limit.
    """
    t = data.t
    if t.ndim != 1 or t.size < 2 or abs(t[0]) > EXPORT_TIME_TOL:
        raise ExportError(f"{where}: expected at least 2 samples starting at t = 0 s")
    step = np.diff(t)
    k = int(np.argmax(np.abs(step - data.dt)))
    if abs(step[k] - data.dt) > EXPORT_TIME_TOL + 1e-9 * t[-1]:
        raise ExportError(
            f"{where}: sample {k + 1} at t = {t[k + 1]:.9g} s is {step[k]:.9g} s after the previous "
            f"one; expected the period dt = {data.dt:.9g} s throughout"
        )
    for arr in (data.q, data.qd, data.qdd, data.qddd):
        if arr.shape != (t.size, 6) or not np.all(np.isfinite(arr)):
            raise ExportError(f"{where}: expected finite (samples, 6) joint arrays")
    # each excess array is made when its check runs (one (samples, 6) temporary at a time)
    checks: list[tuple[str, Callable[[], np.ndarray], np.ndarray, str, str]] = [
        ("position", lambda: data.q - data.q_max, data.q_max, "above q_max", "rad"),
        ("position", lambda: data.q_min - data.q, data.q_min, "below q_min", "rad"),
    ]
    for name, arr, lim, unit in (
        ("velocity", data.qd, data.v_max, "rad/s"),
        ("acceleration", data.qdd, data.a_max, "rad/s^2"),
        ("jerk", data.qddd, data.j_max, "rad/s^3"),
    ):
        if name in data.enforced:
            checks.append(
                (name, lambda a=arr, m=lim: np.abs(a) - m * (1.0 + EXPORT_LIMIT_TOL), lim, "above its limit", unit)
            )
    for name, make, lim, what, unit in checks:
        excess = make()
        tol = EXPORT_POSITION_TOL if name == "position" else 0.0
        if np.any(excess > tol):
            i, j = np.unravel_index(int(np.argmax(excess)), excess.shape)
            value = {"position": data.q, "velocity": data.qd, "acceleration": data.qdd, "jerk": data.qddd}[name][i, j]
            raise ExportError(
                f"{where}: joint {j + 1} {name} {value:.9g} {unit} at sample {i} (t = {t[i]:.6g} s) is "
                f"{what} ({lim[j]:.9g} {unit}); refusing to export a trajectory outside its limits"
            )
    for name, unit, order in RATES:
        if name != "velocity" and name not in data.enforced:
            continue
        d, slack = _divided(t, data.q, order, 0.0)
        score = np.abs(d) / (data.plan_limit(name) * (1.0 + EXPORT_FD_TOL) + slack)
        if np.any(score > 1.0):
            i, j = np.unravel_index(int(np.argmax(score)), score.shape)
            raise ExportError(
                f"{where}: joint {j + 1} {name} by finite differences of the positions, {d[i, j]:.9g} {unit} "
                f"over samples {i} to {i + order} (t = {t[i]:.6g} s), is above its limit "
                f"({data.plan_limit(name)[j]:.9g} {unit}): the positions jump where the rate columns do not say so; "
                "refusing to export"
            )


def _divided(t: np.ndarray, q: np.ndarray, order: int, eps: float) -> tuple[np.ndarray, float]:
    """``order! q[t_i, ..., t_{i+order}]`` (the divided difference), (M - order, 6), and the most
    that rounding the positions by ``eps`` (plus :data:`FD_ROUNDING`) can change it:
    ``2^order (eps + FD_ROUNDING) / h_min^order`` (its coefficients' magnitudes sum to at most
    ``2^order / h_min^order``)."""
    d = q
    for k in range(1, order + 1):
        d = k * np.diff(d, axis=0) / (t[k:] - t[:-k])[:, None]
    h = float(np.min(np.diff(t)))
    return d, 2.0**order * (eps + FD_ROUNDING) / h**order


# --------------------------------------------------------------------------------------
# What a format sends
# --------------------------------------------------------------------------------------


def motion_peaks(data: ExportData, motion: ControllerMotion) -> list[Peak]:
    """The worst position and the worst value of each checked rate of ``motion`` (velocity always;
    acceleration and jerk when the plan's method enforced them), under its interpolation."""
    peaks = [_position_peak(data, motion.q, motion.t, motion.eps, f"at {motion.label}")]
    rates = [r for r in RATES if r[0] == "velocity" or r[0] in data.enforced]
    if motion.qd is not None:
        peaks.append(_column_peak(data, "velocity", motion.qd, motion.t, f"written with {motion.label}"))
    if motion.qdd is not None and "acceleration" in data.enforced:
        peaks.append(_column_peak(data, "acceleration", motion.qdd, motion.t, f"written with {motion.label}"))
    if motion.approach is not None:
        peaks += _approach_peaks(data, *motion.approach)
    if motion.t is None or len(motion.t) < 2:
        return peaks
    if motion.interpolation is Interpolation.QUINTIC:
        if motion.qd is None or motion.qdd is None:
            raise ValueError("a quintic motion needs the velocities and accelerations of its points")
        from planner.export.quintic import quintic_peaks

        peaks += quintic_peaks(data, motion, [r[0] for r in rates], f"on {motion.label}")
    elif motion.interpolation is Interpolation.REST_TO_REST:
        peaks += _rest_to_rest_peaks(data, motion, [r[0] for r in rates])
    else:
        how = (
            f"by finite differences of {motion.label}"
            if motion.interpolation is Interpolation.SETPOINTS
            else f"through {motion.label} at their times (divided differences: any motion through them reaches it)"
        )
        for name, _unit, order in rates:
            if len(motion.t) > order:
                d, slack = _divided(motion.t, motion.q, order, motion.eps)
                peaks.append(_rate_peak(data, name, d, slack, motion.t[: len(d)], how))
    return peaks


def _position_peak(data: ExportData, q: np.ndarray, t: np.ndarray | None, eps: float, how: str) -> Peak:
    up = q - data.q_max
    down = data.q_min - q
    worst = np.maximum(up, down)
    i, j = np.unravel_index(int(np.argmax(worst)), worst.shape)
    limit = data.q_max[j] if up[i, j] >= down[i, j] else data.q_min[j]
    tol = EXPORT_POSITION_TOL + eps
    return Peak("position", int(j), float(q[i, j]), float(limit), 1.0 + (worst[i, j] - tol), _at(t, i), how)


def _at(t: np.ndarray | None, i: int) -> float:
    return float(t[i]) if t is not None else float("nan")


def _rate_peak(data: ExportData, name: str, values: np.ndarray, slack: float, t: np.ndarray | None, how: str) -> Peak:
    lim = data.robot_limit(name)
    score = np.abs(values) / (lim * (1.0 + EXPORT_FD_TOL) + slack)
    i, j = np.unravel_index(int(np.argmax(score)), score.shape)
    return Peak(name, int(j), float(values[i, j]), float(lim[j]), float(score[i, j]), _at(t, i), how)


def _column_peak(data: ExportData, name: str, values: np.ndarray, t: np.ndarray | None, how: str) -> Peak:
    lim = data.robot_limit(name)
    score = np.abs(values) / (lim * (1.0 + EXPORT_LIMIT_TOL))
    i, j = np.unravel_index(int(np.argmax(score)), score.shape)
    return Peak(name, int(j), float(values[i, j]), float(lim[j]), float(score[i, j]), _at(t, i), how)


def _approach_peaks(data: ExportData, speed: float, acceleration: float) -> list[Peak]:
    """The move to the first point at ``speed`` and ``acceleration`` of its leading axis, which may
    be any joint (the program does not know where the arm starts): against the lowest limit."""
    out = []
    for name, value in (("velocity", speed), ("acceleration", acceleration)):
        if name == "velocity" or name in data.enforced:
            lim = data.robot_limit(name)
            j = int(np.argmin(lim))
            how = f"{APPROACH} (approach_{'speed' if name == 'velocity' else name}, its leading axis)"
            out.append(
                Peak(name, j, float(value), float(lim[j]), value / (lim[j] * (1.0 + EXPORT_LIMIT_TOL)), 0.0, how)
            )
    return out


def _rest_to_rest_peaks(data: ExportData, motion: ControllerMotion, names: list[str]) -> list[Peak]:
    """Each move from rest to rest in its time ``T`` over ``|dq|`` on a trapezoidal speed profile:
    at least the acceleration ``4 |dq| / T^2`` (the triangle), at least the peak speed of the
    trapezoid at the acceleration limit, ``(a T - sqrt(a^2 T^2 - 4 a |dq|)) / 2`` (``2 |dq| / T``
    when even the triangle needs more than ``a``), and a jerk without bound (acceleration steps)."""
    t, q = motion.t, motion.q
    dq = np.abs(np.diff(q, axis=0)) + 2.0 * motion.eps
    T = np.diff(t)[:, None]
    a = data.robot_limit("acceleration")[None, :]
    acc = 4.0 * dq / T**2
    disc = a**2 * T**2 - 4.0 * a * dq
    vel = np.where(disc >= 0.0, (a * T - np.sqrt(np.maximum(disc, 0.0))) / 2.0, 2.0 * dq / T)
    how = f"on {motion.label}"
    out = [_rate_peak(data, "velocity", vel, 0.0, t, how)]
    if "acceleration" in names:
        out.append(_rate_peak(data, "acceleration", acc, 0.0, t, how))
    if "jerk" in names:
        moving = np.abs(np.diff(q, axis=0)) > 2.0 * (motion.eps + EXPORT_POSITION_TOL)
        if np.any(moving):
            i, j = np.unravel_index(int(np.argmax(moving)), moving.shape)
            out.append(Peak("jerk", int(j), math.inf, float(data.robot_limit("jerk")[j]), math.inf, float(t[i]), how))
    return out


def check_motion(
    data: ExportData, fmt: str, motion_of: Callable[[ExportData], ControllerMotion], slow_down: str | bool
) -> tuple[ExportData, list[str], list[str]]:
    """Check what format ``fmt`` sends (``motion_of(data)``) against every limit; slow the
    trajectory down uniformly when that is allowed and enough, else refuse.

    Slowing by ``k`` (times ``k t``) divides every velocity by ``k``, acceleration by ``k^2`` and
    jerk by ``k^3`` on the same path: it is allowed for streamed motions (setpoints, quintic) with
    ``slow_down`` ``"yes"``, or ``"auto"`` unless the plan runs a CAM program at its programmed feed
    (``data.program``: slowing it changes the feed), never with ``"no"``, never for positions and
    never for a dynamic compensation's motor-side command (``data.link_q``: its compensation is
    computed for its timing).  ``True``/``False`` are ``"auto"``/``"no"``.

    Returns
    -------
    (ExportData, list of str, list of str)
        The data to write (``data`` or slowed down), the warnings (what the controller's vendor
        does not document) and the changes, one short line each (a slow-down: factor, durations,
        the peak that asked for it).

    Raises
    ------
    ExportLimitError
        One line: the format, the joint, the quantity, the value, the limit, the time, what to do.
    """
    mode = ("auto" if slow_down else "no") if isinstance(slow_down, bool) else slow_down
    motion = motion_of(data)
    notes = [f"{fmt}: {motion.unchecked}"] if motion.unchecked else []
    over = [p for p in motion_peaks(data, motion) if p.over]
    if not over:
        return data, notes, []
    worst = _worst(over)
    reason = _refusal(data, motion, worst, mode != "no")
    if reason is not None:
        advice = "" if _is_approach(worst) else motion.advice + _plan_advice(data, worst, over, motion)
        raise ExportLimitError(f"{fmt}: {worst.sentence()}; refusing to export{reason}{advice}")
    at_plan = over
    k = 1.0
    for _ in range(SLOW_DOWN_ROUNDS):
        k *= max(p.ratio ** (1.0 / _ORDER[p.quantity]) for p in over) * (1.0 + SLOW_DOWN_MARGIN)
        if k > SLOW_DOWN_MAX:
            break
        slowed = data.slowed(k)
        over = [p for p in motion_peaks(slowed, motion_of(slowed)) if p.over]
        if not over:
            if data.program and mode == "auto":
                plan = _plan_advice(data, worst, at_plan, motion)
                raise ExportLimitError(_feed_refusal(data, fmt, worst, k, motion, plan))
            feed = f"; {data.program} below its programmed feed (slow_down=yes)" if data.program else ""
            change = (
                f"slowed down x{k:.4f} ({data.t[-1]:.6g} s -> {slowed.t[-1]:.6g} s): joint {worst.joint + 1} "
                f"{worst.quantity} {worst.ratio:.4g}x its limit at the plan's timing{feed}"
            )
            return slowed, notes, [change]
        reason = _refusal(slowed, motion, _worst(over), True)
        if reason is not None:  # slowed, what is left cannot be slowed away (a position, an unbounded jerk)
            raise ExportLimitError(f"{fmt}: {_worst(over).sentence()}; refusing to export{reason}{motion.advice}")
    raise ExportLimitError(
        f"{fmt}: {worst.sentence()}; refusing to export: slowing down by up to x{SLOW_DOWN_MAX:g} does not keep "
        f"it within the limits{motion.advice}{_plan_advice(data, worst, at_plan, motion)}"
    )


def _feed_refusal(data: ExportData, fmt: str, worst: Peak, k: float, motion: ControllerMotion, plan: str) -> str:
    """The refusal of a program plan that only a slow-down by ``k`` would export (its feed changed):
    the format's own way to plan for its controller (``motion.advice``: its period), else the plan's
    headroom for its controller (``plan``, :func:`_plan_advice`) and the way that holds the feed
    (setpoints at the plan's period)."""
    how = motion.advice or (
        f"{plan}; or send the plan's samples as setpoints at its period (--format urscript), which "
        "this controller's interpolation between them does not change"
    )
    return (
        f"{fmt}: {worst.sentence()}; refusing to slow a program plan down (x{k:.4f} would run {data.program} below "
        f"its programmed feed){how}; or give --set slow_down=yes to accept the slower feed"
    )


def _plan_advice(data: ExportData, worst: Peak, over: list[Peak], motion: ControllerMotion) -> str:
    """How to plan a program for the controller whose interpolation exceeds a rate limit (the
    ``[limits]`` scales of :func:`~planner.export.headroom.headroom_advice`), or empty: for a
    program plan only, not when a position or the approach move is the worst, nor for moves from
    rest to rest (headroom on the plan's rates fixes none of them: a stop at every point is the
    interpolation's, whatever the plan's limits)."""
    if not data.program or worst.quantity == "position" or _is_approach(worst):
        return ""
    if motion.interpolation is Interpolation.REST_TO_REST:
        return ""
    from planner.export.headroom import headroom_advice

    return headroom_advice(data, [p for p in over if not _is_approach(p)])


def _worst(over: list[Peak]) -> Peak:
    """The peak to name: a bad approach or position first (slowing down cannot help), else the largest."""
    first = [p for p in over if p.quantity == "position" or _is_approach(p)]
    return first[0] if first else max(over, key=lambda p: (math.isfinite(p.score), p.score))


def _is_approach(p: Peak) -> bool:
    return p.how.startswith(APPROACH)


def _refusal(data: ExportData, motion: ControllerMotion, worst: Peak, allowed: bool) -> str | None:
    """Why an over-limit motion is refused rather than slowed down (the middle of the refusal, maybe
    empty), or None when it may be slowed down."""
    if _is_approach(worst):
        option = "approach_speed" if worst.quantity == "velocity" else "approach_acceleration"
        return f" (give {option} <= {worst.limit:.6g})"
    if worst.quantity == "position":
        return " (slowing down does not move a position)"
    if motion.interpolation not in (Interpolation.SETPOINTS, Interpolation.QUINTIC):
        return ""
    if not allowed:
        if data.program:
            return f" (--set slow_down=yes slows it down, below the programmed feed of {data.program})"
        return " (--set slow_down=auto slows the trajectory down to keep it)"
    if data.link_q is not None:
        return (
            " (the motor-side command of the run's dynamic compensation is computed for its timing, so it is not "
            "slowed down)"
        )
    if not math.isfinite(worst.value):
        return ""
    return None
