"""Motor-side commands that make the elastic joints' link side follow a timed trajectory.

Physics (``docs/conventions.md``, "Link inertias and rigid-body dynamics"): the link side of
an arm with elastic joints obeys

    M(q) q'' + c(q, q') = K (theta - q) + tau_s(q, L)

with ``theta`` the motor-side position (what the servo loop holds; on harmonic-drive arms the
position loop closes on the motor encoder, before the elastic element), ``tau_s`` the joint
torques the load and the arm's weight apply (the static model's :meth:`ArmModel.joint_torques`;
the links' weight from the rigid-body model when the arm model has no ``gravity`` effect, so
that statics and dynamics describe one body)
and ``M q'' + c`` the rigid-body inertial torques (:func:`models.dynamics.rnea_function` with
gravity and process wrench off, the payload's mass and inertia on).  For the link side to run
the planned ``q(t)`` exactly, the elastic element must carry ``tau_s - (M q'' + c)`` as an
*applied* torque, so

    theta(t) = q(t) - dq(q(t), tau_s(q(t)) - (M q'' + c)(q(t), q'(t), q''(t)))

with ``dq(q, tau)`` the model's deflection law (:meth:`ArmModel.torque_deflection`: linear
springs ``K^-1 tau``, and hardening / lost motion when the model has them).  At rest
(``q' = q'' = 0``) this is the static exact compensation ``q_c = q - dq(q, L)`` with the arm's
weight included.

Assumptions: the joint's elastic element sits between the motor-side position the servo
holds and the link (if the loop closed on a link-side encoder, the controller itself would
hold the link and no command correction of this kind would apply); joint damping is not
modelled (a damper ``D (theta' - q')`` in parallel adds ``D K^-1 tau'`` to the needed torque: the
residual it leaves is reported by the elastic-joint simulation); link compliance (beams) is
compensated statically only.
"""

from __future__ import annotations

import json
from dataclasses import dataclass

from typing import Any

import casadi as ca
import numpy as np
from scipy.interpolate import make_interp_spline
from scipy.signal import lfilter

from models.arm import ArmModel
from models.dynamics import gravity_torque_function, payload_vector, rnea_function
from models.load import Load, load_rows
from models.robot import Robot
from models.status import Status
from problems.quintic import curve_peaks

__all__ = [
    "DynamicStatus",
    "command_derivatives",
    "command_with_rest",
    "curve_peaks",
    "inertial_torques",
    "motor_command",
]


class DynamicStatus(Status):
    """Outcome of :func:`motor_command`."""

    OK = "ok"
    FAILED = "failed"


@dataclass(frozen=True)
class DynamicCommand:
    """Motor-side command of a timed link-side trajectory.

    Attributes
    ----------
    status : DynamicStatus
    reason : str
    theta : ndarray, shape (M, 6)
        Motor-side command, rad (what the controller runs).
    q_link : ndarray, shape (M, 6)
        The planned link side, rad.
    tau_inertial : ndarray, shape (M, 6)
        Rigid-body inertial torques ``M q'' + c`` the drives deliver, N*m.
    tau_static : ndarray, shape (M, 6)
        Joint torques of the load and the arm's weight (applied), N*m.
    """

    status: DynamicStatus
    reason: str
    theta: np.ndarray
    q_link: np.ndarray
    tau_inertial: np.ndarray
    tau_static: np.ndarray


_FN_CACHE: dict[str, ca.Function] = {}
#: CasADi functions kept (by kind and the robot's description).
FN_CACHE_SIZE = 16


def _cached(kind: str, robot: Robot, build: Any) -> ca.Function:
    """A CasADi function of ``robot`` built by ``build(robot)``, cached by kind and the robot's content."""
    key = kind + json.dumps(robot.to_dict(), sort_keys=True, default=lambda o: np.asarray(o).tolist())
    if key not in _FN_CACHE:
        if len(_FN_CACHE) >= FN_CACHE_SIZE:
            _FN_CACHE.pop(next(iter(_FN_CACHE)))
        _FN_CACHE[key] = build(robot)
    return _FN_CACHE[key]


def _inertial_fn(robot: Robot) -> ca.Function:
    """``tau(q, qd, qdd, payload)`` without gravity and wrench (cached by the robot's content)."""
    return _cached("inertial:", robot, _build_inertial)


def _build_inertial(robot: Robot) -> ca.Function:
    f = rnea_function(robot, gravity_input=True)
    q, qd, qdd = ca.SX.sym("q", 6), ca.SX.sym("qd", 6), ca.SX.sym("qdd", 6)
    pl = ca.SX.sym("payload", f.size1_in(3))
    tau = f(q, qd, qdd, pl, ca.SX.zeros(f.size1_in(4)), ca.SX.zeros(3))
    return ca.Function("inertial_torques", [q, qd, qdd, pl], [tau], ["q", "qd", "qdd", "payload"], ["tau"])


def inertial_torques(
    robot: Robot, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, payload: np.ndarray | None = None
) -> np.ndarray:
    """Rigid-body inertial joint torques ``M(q) q'' + c(q, q')`` (N, 6), N*m (gravity excluded).

    Parameters
    ----------
    robot : Robot
        Masses, centres of mass and inertias (DH link frames).
    q, qd, qdd : ndarray, shape (N, 6)
        rad, rad/s, rad/s^2.
    payload : ndarray, shape (10,), optional
        ``models.dynamics.payload_vector`` (mass, centre of mass in the TCP frame, inertia).
    """
    f = _inertial_fn(robot)
    n = len(q)
    pl = np.zeros(f.size1_in(3)) if payload is None else np.asarray(payload, dtype=float)
    out = f.map(n)(
        np.asarray(q, float).T, np.asarray(qd, float).T, np.asarray(qdd, float).T, np.repeat(pl[:, None], n, axis=1)
    )
    return np.asarray(out).T


def link_weight_torques(robot: Robot, q: np.ndarray) -> np.ndarray:
    """Joint torques the links' own weight applies at ``q`` (N, 6), N*m (``-rnea(q, 0, 0)`` without
    payload and wrench, ``robot.gravity``)."""
    f = _static_fn(robot)
    return -np.asarray(f.map(len(q))(np.asarray(q, float).T, np.zeros((f.size1_in(1), len(q))))).T


def _static_fn(robot: Robot) -> ca.Function:
    return _cached("static:", robot, gravity_torque_function)


def motor_command(
    arm: ArmModel,
    q: np.ndarray,
    qd: np.ndarray,
    qdd: np.ndarray,
    load: Load,
    payload_inertia: np.ndarray | None = None,
    rows: np.ndarray | None = None,
) -> DynamicCommand:
    """Motor-side command ``theta(t)`` that makes the link side run ``q(t)`` (see module doc).

    Parameters
    ----------
    arm : ArmModel
        The arm model (deflection law, static torques); its ``robot()`` gives the inertias.
    q, qd, qdd : ndarray, shape (M, 6)
        Planned link side sampled at the controller period: rad, rad/s, rad/s^2.
    load : Load
        The process wrench and payload (mass, centre of mass in the TCP frame).
    payload_inertia : ndarray, shape (3, 3), optional
        The payload's inertia about its centre of mass, TCP axes, kg*m^2 (default: a point mass).
    rows : ndarray, shape (M, 19), optional
        The load rows of every sample (``models.load``) when the load varies along the path
        (per-waypoint wrenches); default ``load.rows(M)``.

    Returns
    -------
    DynamicCommand
        FAILED (with the reason) when the arm has no link masses.
    """
    robot = arm.robot()
    q = np.atleast_2d(np.asarray(q, dtype=float))
    empty = np.zeros((0, 6))
    if not robot.has_masses:
        return DynamicCommand(
            DynamicStatus.FAILED, f"robot {robot.name}: no link masses, no inertial torques", empty, q, empty, empty
        )
    pl = payload_vector(load.payload_mass_kg, load.payload_com_m, payload_inertia)
    tau_i = inertial_torques(robot, q, qd, qdd, pl)
    tau_s = arm.joint_torques(q, load_rows(load, len(q)) if rows is None else rows)
    if not arm.gravity_on:  # the arm's own weight: the rigid-body model's, not the effect's
        tau_s = tau_s + link_weight_torques(robot, q)
    theta = q - arm.torque_deflection(q, tau_s - tau_i)
    reason = (
        f"motor-side command of {len(q)} samples; peak inertial torque "
        f"{np.max(np.abs(tau_i)):.3g} N*m (joint {int(np.argmax(np.abs(tau_i).max(axis=0))) + 1})"
    )
    return DynamicCommand(DynamicStatus.OK, reason, theta, q, tau_i, tau_s)


# --------------------------------------------------------------------------- #
# The command the controller runs: smoothed dynamic part, static at rest, predictions
# --------------------------------------------------------------------------- #

#: Width of each of the two centred moving averages applied to the dynamic part of the command, s.
#: The motor-side jerk contains ``K^-1 M q^(5)``: the jerk-limited law's jerk steps (at its
#: gridpoints) and the cubic path's third-derivative steps (at its knots) make it unbounded; two
#: moving averages of this width bound it by about ``K^-1 M dJ / w^2`` at a path deviation of about
#: ``K^-1 M dJ w / 8`` (measured on a UR5 with 5 kg: jerk ratio 4.6 -> 1.3, TCP error during the
#: motion 4.6 -> 12 um against 419 um with static compensation only).
DYNAMIC_SMOOTHING_S: float = 0.02


#: A sample of the planned link side is at rest where every joint rate is at most this (rad/s) and
#: every joint acceleration at most :data:`REST_ACCEL_TOL` (rad/s^2): there the inertial torques
#: ``M q'' + c(q, q')`` vanish (to ``K^-1 M`` times the tolerances, < 1e-12 rad on a UR5) and the
#: command is the static one.  The timing methods start and end at exact zeros; a jerk-limited law's
#: first sample off rest at 1 ms has rates of ~1e-5 rad/s.
REST_RATE_TOL: float = 1e-9
#: See :data:`REST_RATE_TOL`, rad/s^2.
REST_ACCEL_TOL: float = 1e-9
#: Width of each of the two *one-sided* moving averages of the dynamic part next to a rest phase, s
#: (trailing after a rest phase, leading before one).  The centred averages of
#: :data:`DYNAMIC_SMOOTHING_S` would start the command before the link side moves (7 um of predicted
#: TCP error at the rest samples next to the motion on ``ur5_fast_payload``); one-sided ones leave the
#: rest samples at the static command, at the price of a lag at the start and the end of the motion
#: (their mean lag is this width: :func:`trailing`).  The command's jerk there is the link side's plus
#: about ``K^-1 M j / w^2``.  Measured on ``ur5_fast_payload`` (the plan, every timing pass) through the
#: elastic-joint simulation, TCP error during the motion and duration: 17.6 um and 1.582 s with 10 ms,
#: 11.2 um and 1.642 s with 8 ms, 3.3 um and 2.238 s with 6 ms, 21.8 um and 1.606 s with 12 ms; the
#: command's peak jerk in the first timing pass 1.27, 1.55, 2.18 and 1.12 times the limit (20 ms: 1.01,
#: predicted error 26 um against 15.8 um with 10 ms).
DYNAMIC_EDGE_SMOOTHING_S: float = 0.01
#: Time over which the one-sided averages next to a rest phase hand over to the centred ones, s (C2
#: quintic weights).  The hand-over's own jerk is the lag times the weights' third derivative: on
#: ``ur5_fast_payload`` (10 ms one-sided averages, the first timing pass) the command's peak jerk (on
#: its spline, :func:`curve_peaks`) is 1.49, 1.32, 1.27 and 1.24 times the limit with 40, 60, 80 and
#: 160 ms; the predicted error during the motion 12.9, 14.9, 15.8 and 16.8 um.
DYNAMIC_BLEND_S: float = 0.08


def rest_samples(qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
    """Samples (M,) bool of a link-side trajectory at rest: every joint rate ``qd`` (M, 6) rad/s and
    acceleration ``qdd`` (M, 6) rad/s^2 within :data:`REST_RATE_TOL` / :data:`REST_ACCEL_TOL`
    (start, end, dwells)."""
    return np.all(np.abs(qd) <= REST_RATE_TOL, axis=1) & np.all(np.abs(qdd) <= REST_ACCEL_TOL, axis=1)


def smootherstep(x: np.ndarray) -> np.ndarray:
    """``10 x^3 - 15 x^4 + 6 x^5`` on [0, 1], 0 below, 1 above: C2, first and second derivatives
    zero at both ends."""
    x = np.clip(x, 0.0, 1.0)
    return x**3 * (10.0 + x * (6.0 * x - 15.0))


def rest_distance_weights(rest: np.ndarray, dt: float, width: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`smootherstep` of the time since the last and until the next sample at rest, over ``width``
    s: two (M,) weights of M samples ``dt`` s apart, 0 at rest, 1 ``width`` s or more from rest (and
    where there is no rest on that side)."""
    rest = np.asarray(rest, dtype=bool)
    i = np.arange(len(rest), dtype=float)
    last = np.maximum.accumulate(np.where(rest, i, -np.inf))
    nxt = np.minimum.accumulate(np.where(rest, i, np.inf)[::-1])[::-1]
    return smootherstep((i - last) * dt / width), smootherstep((nxt - i) * dt / width)


def trailing_kernel(n: int) -> np.ndarray:
    """Weights ``W_m``, ``m = 0 .. 2n``, of :func:`trailing`: two trailing moving averages of width
    ``n`` periods (a triangle ``T`` over ``2n`` periods) applied to the piecewise-linear interpolant of
    the samples, at the samples: ``W_m = (T_(m-1) + 4 T_m + T_(m+1)) / 6`` (the triangle's integral
    against a sample's hat function), summing to 1."""
    tri = np.r_[np.arange(n + 1), np.arange(n - 1, -1, -1)] / float(n * n)
    return np.convolve(tri, [1.0 / 6.0, 2.0 / 3.0, 1.0 / 6.0])[1:-1]


def trailing(x: np.ndarray, n: int) -> np.ndarray:
    """Two trailing moving averages of width ``n`` samples over the rows of ``x`` (M, k), the first row
    held before the start: a row depends on no later row.

    They act on the piecewise-linear interpolant of the rows (:func:`trailing_kernel`), so the result
    is the samples of a C2 piecewise cubic with knots at the samples: where the rows were zero up to
    a sample (a rest phase), it leaves that sample with zero rate and acceleration.  (Averaging the
    samples themselves, the first row after rest would carry ``1 / n^2`` of the next sample's value
    instead of ``1 / (6 n^2)``: a start no curve at rest can take within the jerk limit.)
    """
    w = trailing_kernel(max(1, n))
    pad = np.concatenate([np.repeat(x[:1], len(w) - 1, axis=0), x])
    return lfilter(w, [1.0], pad, axis=0)[len(w) - 1 :]


def command_with_rest(
    static: np.ndarray,
    theta: np.ndarray,
    rest: np.ndarray,
    dt: float,
    smoothing_s: float = DYNAMIC_SMOOTHING_S,
    edge_s: float = DYNAMIC_EDGE_SMOOTHING_S,
    blend_s: float = DYNAMIC_BLEND_S,
) -> np.ndarray:
    """The command the controller runs (M, 6) rad, samples ``dt`` s apart: the static command
    ``static`` (M, 6) plus the dynamic part ``theta - static`` (``theta`` the exact motor-side command
    of :func:`motor_command`), smoothed.

    The dynamic part is set to zero at the samples at rest (``rest``, (M,) bool; where the inertial
    torques vanish) and smoothed by two centred moving averages of ``smoothing_s`` (:func:`smooth`)
    away from rest, two trailing ones of ``edge_s`` after a rest phase and two leading ones before
    one, handed over by C2 weights over ``blend_s`` (:func:`rest_distance_weights`); no average
    reaches from a rest sample into the motion, so at rest the result *is* ``static``, by
    construction.
    """
    rest = np.asarray(rest, dtype=bool)
    part = np.where(rest[:, None], 0.0, theta - static)
    n, n_edge = (max(1, int(round(w / dt))) for w in (smoothing_s, edge_s))
    after, before = rest_distance_weights(rest, dt, blend_s)
    w_trail, w_mid, w_lead = (1.0 - after) * before, after * before, after * (1.0 - before)
    total = w_trail + w_mid + w_lead  # > 0 off rest
    mix = (
        w_trail[:, None] * trailing(part, n_edge)
        + w_mid[:, None] * smooth(part, n)
        + w_lead[:, None] * trailing(part[::-1], n_edge)[::-1]
    )
    return static + np.where(rest[:, None], 0.0, mix / np.where(rest, 1.0, total)[:, None])


def smooth(x: np.ndarray, n: int) -> np.ndarray:
    """Two centred moving averages of ``n`` samples over the rows of ``x`` (M, k), the ends held
    constant (the trajectory is at rest there)."""
    if n <= 1:
        return x.copy()
    for _ in range(2):
        pad = padded(x, n)
        c = np.concatenate([np.zeros((1, x.shape[1])), np.cumsum(pad, axis=0)])
        y = (c[n:] - c[:-n]) / n  # y[i] = mean(pad[i:i+n])
        off = n - (n - 1) // 2  # window centred on pad[i + n]
        x = y[off : off + len(x)]
    return x


def padded(x: np.ndarray, n: int) -> np.ndarray:
    """``x`` (M, k) with ``n`` copies of its first and last rows added (rest before and after)."""
    return np.concatenate([np.repeat(x[:1], n, axis=0), x, np.repeat(x[-1:], n, axis=0)])


def finite_derivatives(x: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """First three time derivatives of samples ``x`` (M, 6) every ``dt`` (central differences,
    one-sided at the ends).  Estimates only: they are not the derivatives of one curve through the
    samples (at a sample at rest the one-sided difference is not zero); a command's columns are
    :func:`command_derivatives`'."""
    d1 = np.gradient(x, dt, axis=0)
    d2 = np.gradient(d1, dt, axis=0)
    return d1, d2, np.gradient(d2, dt, axis=0)


# --------------------------------------------------------------------------- #
# The command's derivatives: one smooth curve through its samples
# --------------------------------------------------------------------------- #

#: Degree of the curve the command's derivatives come from: a quintic spline, C4, whose piece between
#: two samples is the quintic through both samples' positions, velocities and accelerations -- the
#: curve ROS 2's joint_trajectory_controller lays between points (``splines``).
COMMAND_SPLINE_DEGREE = 5
#: The orders of the derivatives the spline sets to zero at an end at rest: velocity and
#: acceleration (a quintic takes two conditions at each end).
REST_END: tuple[int, int] = (1, 2)
#: ... at an end that is not at rest (a trajectory that does not start or end at rest): the third
#: and fourth (the quintic natural spline).
FREE_END: tuple[int, int] = (3, 4)


def moving_stretches(rest: np.ndarray) -> list[tuple[int, int]]:
    """First and last sample (inclusive) of each stretch of samples not at rest, widened by the
    sample at rest on either side where there is one: the spans of :func:`command_derivatives`'
    splines.  ``rest`` (M,) bool."""
    moving = ~np.asarray(rest, dtype=bool)
    edges = np.flatnonzero(np.diff(np.r_[0, moving.astype(np.int8), 0]))
    last = len(moving) - 1
    return [(max(a - 1, 0), min(b, last)) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def command_derivatives(t: np.ndarray, x: np.ndarray, rest: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Velocity, acceleration and jerk (M, 6 each; rad/s, rad/s^2, rad/s^3) of the command ``x``
    (M, 6) rad at the sample times ``t`` (M,) s, from one smooth curve through the samples.

    Each stretch of motion, with the samples at rest that bound it (:func:`moving_stretches`), is
    interpolated by a quintic spline (:data:`COMMAND_SPLINE_DEGREE`, knots at the samples, C4) whose
    velocity and acceleration are zero at a bounding sample at rest (:data:`REST_END`;
    :data:`FREE_END` at an end of ``x`` that is not at rest); the columns are its derivatives at the
    samples.  At the samples at rest (``rest`` (M,) bool: the start, the end, dwells) velocity and
    acceleration are exactly zero; the jerk there is the adjacent spline's (the larger one between
    two motions, zero inside a dwell).  So the positions, velocities and accelerations describe one
    curve: the quintic through two consecutive samples' ``(x, v, a)`` is the spline's own piece
    (:func:`problems.quintic.quintic_pieces`), and between two samples at rest, where ``x`` is still, a constant.
    """
    t, x = np.asarray(t, dtype=float), np.asarray(x, dtype=float)
    rest = np.asarray(rest, dtype=bool)
    out = [np.zeros_like(x) for _ in range(3)]
    for a, b in moving_stretches(rest):
        span = slice(a, b + 1)
        bc = tuple([(k, np.zeros(x.shape[1:])) for k in (REST_END if rest[i] else FREE_END)] for i in (a, b))
        # relative to the first sample: the spline's coefficients then carry no large offset
        spline = make_interp_spline(t[span], x[span] - x[a], k=COMMAND_SPLINE_DEGREE, bc_type=bc, axis=0)
        for order, arr in enumerate(out[:2], 1):
            arr[span] = spline(t[span], nu=order)
        jerk = spline(t[span], nu=3)
        out[2][span] = np.where(np.abs(jerk) > np.abs(out[2][span]), jerk, out[2][span])
    out[0][rest] = 0.0
    out[1][rest] = 0.0
    return out[0], out[1], out[2]


def predicted_tcp_errors(
    arm: ArmModel, q: np.ndarray, dq_needed: np.ndarray, commands: dict[str, np.ndarray]
) -> dict[str, np.ndarray]:
    """Quasi-static TCP position error along the motion (M,), m, for each command.

    A command ``theta`` puts the link at ``theta + dq_needed`` to first order (the joints wind up by
    the deflection the static and inertial torques of the plan cause, ``dq_needed = dq(q, tau_s -
    tau_i)``); the error is that pose's rigid TCP position against the plan's.  Vibrations are not in
    it (the elastic-joint simulation has them: ``docs/elastic-simulation.md``).
    """
    km = arm.kinematics
    p_plan = km.tcp(q)[:, :3, 3]
    return {
        name: np.linalg.norm(km.tcp(theta + dq_needed)[:, :3, 3] - p_plan, axis=1) for name, theta in commands.items()
    }


#: Mismatches between the model and the arm the summary reports the gain under:
#: (stiffness factor, payload-mass factor) of the real arm against the model.
MISMATCH_CASES: tuple[tuple[float, float], ...] = ((0.8, 1.2), (1.2, 0.8), (0.8, 0.8), (1.2, 1.2))
#: Column of the payload mass in a load row (``models.load.Load.rows``).
PAYLOAD_MASS_COLUMN = 12


def mismatch_errors(
    arm: ArmModel,
    q: np.ndarray,
    qd: np.ndarray,
    qdd: np.ndarray,
    load: Load,
    rows: np.ndarray,
    commands: dict[str, np.ndarray],
    stiffness_factor: float,
    payload_factor: float,
) -> dict[str, np.ndarray]:
    """Predicted TCP errors (M,) m of ``commands`` on an arm whose joints are ``stiffness_factor``
    times as stiff and whose payload is ``payload_factor`` times as heavy as the model's.

    Quasi-static like :func:`predicted_tcp_errors`; the deflection law is divided by the stiffness
    factor (exact for linear springs).
    """
    rows_m = np.array(rows, dtype=float)
    rows_m[:, PAYLOAD_MASS_COLUMN] *= payload_factor
    load_m = Load(
        wrench_base=load.wrench_base,
        wrench_tool=load.wrench_tool,
        payload_mass_kg=load.payload_mass_kg * payload_factor,
        payload_com_m=load.payload_com_m,
        gravity=load.gravity,
    )
    real = motor_command(arm, q, qd, qdd, load_m, rows=rows_m)
    needed = (q - real.theta) / stiffness_factor
    return predicted_tcp_errors(arm, q, needed, commands)
