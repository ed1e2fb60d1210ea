"""Rigid-body inverse dynamics of the arm: the recursive Newton-Euler algorithm as CasADi.

``tau = M(q) qdd + c(q, qd) + g(q) - J(q)^T F`` (N*m): the joint torques the drives must
deliver to move the rigid arm, carrying a payload, along ``(q, qd, qdd)`` against gravity and
a process wrench ``F`` on the TCP.  Built from the same robot description and the same DH chain
(:func:`models.effects.graph.chain`, standard or modified DH, with ``frame02base``,
``flange2frame6`` and the tool) as the rest of the library.

Conventions (see ``docs/conventions.md``, "Link inertias and rigid-body dynamics"):

* link *i* (the body that joint *i* turns) has mass ``m_i`` (kg), centre of mass ``com_i``
  (m, DH link frame *i*) and inertia tensor ``I_i`` about its centre of mass, axes of DH link
  frame *i* (kg*m^2);
* ``payload`` (:data:`PAYLOAD_SIZE`) ``= [m, cx, cy, cz, ixx, iyy, izz, ixy, ixz, iyz]``: mass
  (kg), centre of mass (m, TCP frame, as :class:`models.load.Load`'s ``payload_com_m``) and
  inertia tensor about its centre of mass, axes of the TCP frame (kg*m^2), rigidly fixed to
  link 6; the tensor entries are the matrix entries (``ixy = I[0, 1]``, the URDF and robot-file
  convention);
* ``wrench`` ``[f (N); m (N*m)]``: the process wrench **acting on the arm** at the TCP, base
  frame, moment about the TCP point: the wrench ``F`` of the static model, whose joint torques
  are ``J^T F`` (``models.effects.graph.Graph.torques``); the drives deliver ``-J^T F`` of it;
* gravity: ``robot.gravity`` (m/s^2, base frame), baked in as a constant, or an input ``g``.

Computation: the recursion runs in the base frame.  Each link's angular velocity and
acceleration are propagated through the joint axes (``z_i``, points ``p_i`` of
:func:`models.effects.graph.joint_axes`), the linear acceleration through a point on each
joint axis (fixed in both neighbouring links); gravity enters as the base acceleration
``-g``.  Then the links' inertial forces and moments are summed from the tip, about the base
origin, and projected on the joint axes.  All functions are SX-based (``f.map(N)``, code
generation by :mod:`models.codegen`).
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from .effects.graph import chain, joint_axes
from .errors import InputError
from .robot import Robot, RobotFileError

#: Length of the payload vector ``[m, c (3), ixx, iyy, izz, ixy, ixz, iyz]``.
PAYLOAD_SIZE = 10
#: Length of the wrench vector ``[f (3), m (3)]``.
WRENCH_SIZE = 6


def link_inertials(robot: Robot, strict: bool = False) -> list[tuple[float, np.ndarray, np.ndarray]]:
    """Mass, centre of mass and inertia of each link, DH link frame *i*.

    Parameters
    ----------
    robot : Robot
    strict : bool
        Raise instead of filling in a missing mass or inertia.

    Returns
    -------
    list of (float, ndarray (3,), ndarray (3, 3)), length 6
        ``(m_i kg, com_i m, I_i kg*m^2 about the centre of mass)``.  A link without
        ``mass`` is massless (zeros); a link with ``mass`` and ``com`` but no ``inertia`` is a
        point mass at its centre of mass (``I_i = 0``).

    Raises
    ------
    RobotFileError
        ``strict`` and some link has no mass or no inertia tensor.
    """
    out = []
    for i, j in enumerate(robot.joints):
        if strict and (j.mass is None or j.inertia is None):
            raise RobotFileError(
                f"robot '{robot.name}': joints[{i + 1}] has no "
                f"{'mass/com' if j.mass is None else 'inertia'}; the rigid-body "
                "dynamics needs mass, com and inertia of every link"
            )
        m = 0.0 if j.mass is None else float(j.mass)
        c = np.zeros(3) if j.com is None else np.asarray(j.com, dtype=float)
        I = np.zeros((3, 3)) if j.inertia is None or j.mass is None else np.asarray(j.inertia, dtype=float)
        out.append((m, c, I))
    return out


def inertia_from_vector(v: Any) -> Any:
    """Symmetric 3x3 inertia (CasADi) from ``[ixx, iyy, izz, ixy, ixz, iyz]`` (kg*m^2)."""
    return ca.vertcat(ca.horzcat(v[0], v[3], v[4]), ca.horzcat(v[3], v[1], v[5]), ca.horzcat(v[4], v[5], v[2]))


def payload_vector(mass_kg: float, com_m: Any = (0.0, 0.0, 0.0), inertia: Any = None) -> np.ndarray:
    """The payload input ``[m, c (3), ixx, iyy, izz, ixy, ixz, iyz]``, shape (10,).

    Parameters
    ----------
    mass_kg : float
    com_m : array_like, shape (3,)
        Centre of mass, TCP frame, m.
    inertia : array_like, shape (3, 3) or (6,), optional
        About the centre of mass, axes of the TCP frame, kg*m^2 (a matrix, or
        ``[ixx, iyy, izz, ixy, ixz, iyz]``); default zero (a point mass).
    """
    I = np.zeros(6) if inertia is None else np.asarray(inertia, dtype=float)
    if I.shape == (3, 3):
        I = np.array([I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]])
    if I.shape != (6,):
        raise InputError(
            f"payload inertia: expected a 3x3 matrix or 6 values [ixx, iyy, izz, ixy, ixz, iyz] "
            f"(kg*m^2), got shape {I.shape}"
        )
    return np.r_[float(mass_kg), np.asarray(com_m, dtype=float).reshape(3), I]


def _kinematics(robot: Robot, q: Any) -> tuple[list[Any], list[Any], list[Any], Any]:
    """DH frames 1..6 (base frame), joint axes and points, and ``tcp2base`` as SX."""
    f0 = None if np.array_equal(robot.frame02base, np.eye(4)) else ca.DM(robot.frame02base)
    frames = chain(q, robot.nominal_dh(f0), robot.convention)
    zs, ps = joint_axes(frames, robot.convention, f0)
    tcp = ca.mtimes(frames[-1], ca.DM(robot.flange2frame6 @ robot.tcp2flange))
    return frames, zs, ps, tcp


def _bodies(robot: Robot, frames: list[Any], tcp: Any, payload: Any, strict: bool) -> list[list[tuple[Any, Any, Any]]]:
    """Per link, its bodies ``(m, c, I)``: mass (kg), centre of mass (m) and inertia about it
    (kg*m^2), all in the base frame; the payload is a second body of link 6."""
    out: list[list[tuple[Any, Any, Any]]] = []
    for (m, c, I), T in zip(link_inertials(robot, strict), frames):
        if m == 0.0:
            out.append([])
            continue
        R = T[:3, :3]
        out.append([(m, T[:3, 3] + ca.mtimes(R, ca.DM(c)), ca.mtimes([R, ca.DM(I), R.T]))])
    Rt = tcp[:3, :3]
    Ip = ca.mtimes([Rt, inertia_from_vector(payload[4:10]), Rt.T])
    out[-1].append((payload[0], tcp[:3, 3] + ca.mtimes(Rt, payload[1:4]), Ip))
    return out


def _rnea_expr(robot: Robot, q: Any, qd: Any, qdd: Any, payload: Any, wrench: Any, g: Any, strict: bool = False) -> Any:
    """Joint torques (N*m, SX (6,)) of the rigid arm; see :func:`rnea_function`."""
    frames, zs, ps, tcp = _kinematics(robot, q)
    bodies = _bodies(robot, frames, tcp, payload, strict)
    w = ca.SX.zeros(3)  # angular velocity of the previous link, rad/s
    dw = ca.SX.zeros(3)  # its angular acceleration, rad/s^2
    a_p, p_prev = -g, ps[0]  # acceleration (m/s^2) of a point of the previous link
    forces, moments = [], []  # per link: inertial force (N), moment about the base origin
    for i in range(6):
        r = ps[i] - p_prev  # the axis point of joint i is fixed in links i-1 and i
        a_p = a_p + ca.cross(dw, r) + ca.cross(w, ca.cross(w, r))
        p_prev = ps[i]
        dw = dw + zs[i] * qdd[i] + ca.cross(w, zs[i] * qd[i])
        w = w + zs[i] * qd[i]
        f, n = ca.SX.zeros(3), ca.SX.zeros(3)
        for m, c, I in bodies[i]:
            rc = c - ps[i]
            fb = m * (a_p + ca.cross(dw, rc) + ca.cross(w, ca.cross(w, rc)))
            Iw = ca.mtimes(I, w)
            f = f + fb
            n = n + ca.mtimes(I, dw) + ca.cross(w, Iw) + ca.cross(c, fb)
        forces.append(f)
        moments.append(n)
    f_e, m_e = wrench[0:3], wrench[3:6]
    F = -f_e  # the process wrench carries part of the load
    N = -(m_e + ca.cross(tcp[:3, 3], f_e))
    tau: list[Any] = [None] * 6
    for i in range(5, -1, -1):
        F = F + forces[i]
        N = N + moments[i]
        tau[i] = ca.dot(zs[i], N - ca.cross(ps[i], F))
    return ca.vertcat(*tau)


def rnea_function(
    robot: Robot, *, name: str = "rnea", gravity_input: bool = False, strict: bool = False
) -> ca.Function:
    """Inverse dynamics ``tau(q, qd, qdd, payload, wrench)`` by recursive Newton-Euler.

    Parameters
    ----------
    robot : Robot
        DH table (standard or modified), ``frame02base``, ``flange2frame6``, tool
        ``tcp2flange``, link masses, centres of mass and inertias.  A link without ``mass``
        is massless; a link without ``inertia`` is a point mass at its ``com``
        (see :func:`link_inertials`).
    name : str
        Name of the CasADi Function.
    gravity_input : bool
        False: gravity is ``robot.gravity`` (base frame, m/s^2), a constant of the function.
        True: the function takes it as a sixth input ``g`` (3,).
    strict : bool
        Raise :class:`~models.robot.RobotFileError` when a link has no mass or inertia.

    Returns
    -------
    casadi.Function
        SX-based, ``map``-able. Inputs ``q`` (6,) rad, ``qd`` (6,) rad/s, ``qdd`` (6,) rad/s^2,
        ``payload`` (:data:`PAYLOAD_SIZE`,) ``[m kg, com (3) m in the TCP frame,
        ixx, iyy, izz, ixy, ixz, iyz kg*m^2 about the payload's centre of mass, TCP axes]``,
        ``wrench`` (6,) ``[f N, m N*m]`` acting on the arm at the TCP, base frame, moment
        about the TCP (and ``g`` (3,) m/s^2 with ``gravity_input``).  Output ``tau`` (6,)
        N*m: the joint torques the drives deliver, ``M qdd + c + g(q) - J^T F``.  At rest
        (``qd = qdd = 0``) ``tau = -(tau_g + J^T F)``: minus the torques the loads apply to
        the joints in the static model, i.e. the joint deflection of the springs is
        ``dq = -K^-1 tau``.
    """
    q, qd, qdd = ca.SX.sym("q", 6), ca.SX.sym("qd", 6), ca.SX.sym("qdd", 6)
    pl, wr = ca.SX.sym("payload", PAYLOAD_SIZE), ca.SX.sym("wrench", WRENCH_SIZE)
    g = ca.SX.sym("g", 3) if gravity_input else ca.SX(ca.DM(np.asarray(robot.gravity, dtype=float)))
    tau = _rnea_expr(robot, q, qd, qdd, pl, wr, g, strict)
    ins, names = [q, qd, qdd, pl, wr], ["q", "qd", "qdd", "payload", "wrench"]
    if gravity_input:
        ins, names = ins + [g], names + ["g"]
    return ca.Function(name, ins, [tau], names, ["tau"])


def mass_matrix_function(robot: Robot, *, name: str = "mass_matrix", strict: bool = False) -> ca.Function:
    """Joint-space mass matrix ``M(q, payload)`` of the rigid arm, ``d tau / d qdd``.

    Parameters
    ----------
    robot : Robot
        As for :func:`rnea_function`.
    name : str
        Name of the CasADi Function.
    strict : bool
        As for :func:`rnea_function`.

    Returns
    -------
    casadi.Function
        SX-based; inputs ``q`` (6,) rad and ``payload`` (:data:`PAYLOAD_SIZE`,); output ``M``
        (6, 6) kg*m^2: the Jacobian of the RNEA torques with respect to ``qdd`` (exact: the
        torques are linear in ``qdd``), upper triangle mirrored so that ``M`` is exactly
        symmetric.
    """
    q, qdd = ca.SX.sym("q", 6), ca.SX.sym("qdd", 6)
    pl = ca.SX.sym("payload", PAYLOAD_SIZE)
    zero = ca.SX.zeros(6)
    tau = _rnea_expr(robot, q, zero, qdd, pl, ca.SX.zeros(WRENCH_SIZE), ca.SX.zeros(3), strict)
    J = ca.jacobian(tau, qdd)
    M = ca.vertcat(*[ca.horzcat(*[J[min(i, j), max(i, j)] for j in range(6)]) for i in range(6)])
    return ca.Function(name, [q, pl], [M], ["q", "payload"], ["M"])


def gravity_torque_function(robot: Robot, *, name: str = "gravity_torque", strict: bool = False) -> ca.Function:
    """Static holding torques ``tau(q, payload) = rnea(q, 0, 0, payload, 0)`` (N*m, (6,)):
    what the drives deliver to hold the arm and payload still against ``robot.gravity``."""
    q, pl = ca.SX.sym("q", 6), ca.SX.sym("payload", PAYLOAD_SIZE)
    g = ca.SX(ca.DM(np.asarray(robot.gravity, dtype=float)))
    zero = ca.SX.zeros(6)
    tau = _rnea_expr(robot, q, zero, zero, pl, ca.SX.zeros(WRENCH_SIZE), g, strict)
    return ca.Function(name, [q, pl], [tau], ["q", "payload"], ["tau"])
