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

from models.arm import ArmModel
from models.dynamics import gravity_torque_function, payload_vector, rnea_function
from models.load import Load, load_rows
from models.robot import Robot
from models.status import Status

__all__ = ["DynamicCommand", "DynamicStatus", "inertial_torques", "motor_command"]


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
# The command the controller runs: smoothed dynamic part, rest padding, predictions
# --------------------------------------------------------------------------- #

#: Width of each of the two centred moving averages applied to the dynamic part of the command, s.
#: The motor-side jerk contains ``K^-1 M q^(5)``: the jerk-limited law's jerk steps (at its
#: gridpoints) and the cubic path's third-derivative steps (at its knots) make it unbounded; two
#: moving averages of this width bound it by about ``K^-1 M dJ / w^2`` at a path deviation of about
#: ``K^-1 M dJ w / 8`` (measured on a UR5 with 5 kg: jerk ratio 4.6 -> 1.3, TCP error during the
#: motion 4.6 -> 12 um against 419 um with static compensation only).
DYNAMIC_SMOOTHING_S: float = 0.02


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
    one-sided at the ends)."""
    d1 = np.gradient(x, dt, axis=0)
    d2 = np.gradient(d1, dt, axis=0)
    return d1, d2, np.gradient(d2, dt, axis=0)


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
