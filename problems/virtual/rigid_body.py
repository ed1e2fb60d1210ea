"""NumPy rigid-body dynamics of the virtual robot's arm (the elastic-joint simulation's model).

Written independently of the CasADi model (:mod:`models.dynamics`): NumPy kinematics of
:mod:`problems.virtual.geometry`, a NumPy recursive Newton-Euler (moments about the joint points,
propagated from the tip) for ``c + g - J^T W``, and the mass matrix summed from body Jacobians
(``M = sum m Jv^T Jv + Jw^T I Jw``), so the two are cross-checks of each other and of pinocchio
(``tests/test_elastic_sim.py``).  :class:`ElasticArm` also gives the static equilibrium of the
elastic joints and the static command.  SI units; base frame unless stated.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from models.errors import InputError
from models.robot import Robot

from .geometry import ArmGeometry, joint_axes, link_frames

#: Fixed-point tolerance of the static equilibrium (rad).
EQUILIBRIUM_TOL_RAD = 1e-14

#: Maximum fixed-point iterations of the static equilibrium.
EQUILIBRIUM_MAX_ITER = 200

#: Length of the payload vector ``[m, c (3), ixx, iyy, izz, ixy, ixz, iyz]``.
PAYLOAD_LEN = 10


def as_vector(x: object, n: int, name: str) -> np.ndarray:
    a = np.asarray(x, dtype=float).reshape(-1)
    if a.shape != (n,) or not np.all(np.isfinite(a)):
        raise InputError(f"{name} must be {n} finite numbers, got {np.asarray(x).shape}")
    return a


@dataclass
class _Kin:
    """Kinematics of N states: frames (N, 6, 4, 4), joint axes z and points p (N, 6, 3), TCP
    (N, 4, 4), body centres of mass (N, B, 3) and inertias (N, B, 3, 3), base frame."""

    frames: np.ndarray
    z: np.ndarray
    p: np.ndarray
    tcp: np.ndarray
    c: np.ndarray
    inertia: np.ndarray


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product over the last axis (broadcast; faster than np.cross for small arrays)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a1 * b2 - a2 * b1
    out[..., 1] = a2 * b0 - a0 * b2
    out[..., 2] = a0 * b1 - a1 * b0
    return out


def _inertia3(v: np.ndarray) -> np.ndarray:
    return np.array([[v[0], v[3], v[4]], [v[3], v[1], v[5]], [v[4], v[5], v[2]]])


class ElasticArm:
    """NumPy rigid-body model of a robot with a payload and a process wrench.

    Parameters
    ----------
    robot : Robot
        DH rows, ``frame02base``, ``flange2frame6``, tool, link masses / COMs / inertias (a link
        without mass is massless, one without inertia a point mass), ``gravity``.
    payload : array_like, shape (10,), optional
        ``[m kg, c (3) m in the TCP frame, ixx, iyy, izz, ixy, ixz, iyz kg*m^2 about the payload's
        COM, TCP axes]`` (``models.dynamics.payload_vector`` builds one); default none.
    wrench : array_like, shape (6,), optional
        ``[f N; m N*m]`` acting on the arm at the TCP, base frame, moment about the TCP; default 0.
    """

    def __init__(self, robot: Robot, payload: np.ndarray | None = None, wrench: np.ndarray | None = None) -> None:
        self.robot = robot
        self.convention = robot.convention
        self.gravity = np.asarray(robot.gravity, dtype=float).reshape(3)
        self.wrench = np.zeros(6) if wrench is None else as_vector(wrench, 6, "wrench")
        pl = np.zeros(PAYLOAD_LEN) if payload is None else as_vector(payload, PAYLOAD_LEN, "payload")
        self.frame02base = np.asarray(robot.frame02base, dtype=float)
        self.tcp2frame6 = np.asarray(robot.flange2frame6, dtype=float) @ np.asarray(robot.tcp2flange, dtype=float)
        link, m, c, inertia = [], [], [], []
        for i, j in enumerate(robot.joints):
            if j.mass is None or float(j.mass) == 0.0:
                continue
            link.append(i)
            m.append(float(j.mass))
            c.append(np.zeros(3) if j.com is None else np.asarray(j.com, dtype=float))
            inertia.append(np.zeros((3, 3)) if j.inertia is None else np.asarray(j.inertia, dtype=float))
        if pl[0] != 0.0:  # the payload: a second body of link 6, expressed in DH frame 6
            R, o = self.tcp2frame6[:3, :3], self.tcp2frame6[:3, 3]
            link.append(5)
            m.append(float(pl[0]))
            c.append(o + R @ pl[1:4])
            inertia.append(R @ _inertia3(pl[4:10]) @ R.T)
        self.body_link = np.array(link, dtype=int)
        self.body_mass = np.array(m, dtype=float)
        self.body_com = np.array(c, dtype=float).reshape(-1, 3)
        self.body_inertia = np.array(inertia, dtype=float).reshape(-1, 3, 3)

    def _geometry(self, n: int) -> ArmGeometry:
        r = self.robot

        def row(v: np.ndarray) -> np.ndarray:
            return np.broadcast_to(np.asarray(v, dtype=float), (n, 6))

        return ArmGeometry(
            a=row(r.a),
            alpha=row(r.alpha),
            d=row(r.d),
            toff=row(r.theta_offset),
            beta=row(np.zeros(6)),
            frame02base=self.frame02base,
        )

    def kinematics(self, q: np.ndarray) -> _Kin:
        """Frames, axes, TCP and bodies of the states ``q`` (N, 6) rad."""
        q = np.atleast_2d(q)
        fr = link_frames(q, self._geometry(q.shape[0]), self.convention)
        z, p = joint_axes(fr, self.convention, self.frame02base)
        Tb = fr[:, self.body_link]  # (N, B, 4, 4)
        Rb = Tb[:, :, :3, :3]
        c = Tb[:, :, :3, 3] + np.einsum("nbij,bj->nbi", Rb, self.body_com)
        inertia = Rb @ self.body_inertia[None] @ np.swapaxes(Rb, -1, -2)
        return _Kin(frames=fr, z=z, p=p, tcp=fr[:, 5] @ self.tcp2frame6, c=c, inertia=inertia)

    def tcp_position(self, q: np.ndarray) -> np.ndarray:
        """TCP positions (N, 3), base frame, m, of link angles ``q`` (N, 6) rad."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        fr = link_frames(q, self._geometry(q.shape[0]), self.convention)
        return (fr[:, 5] @ self.tcp2frame6)[:, :3, 3]

    def inverse_dynamics(
        self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, kin: _Kin | None = None, gravity: bool = True
    ) -> np.ndarray:
        """Joint torques ``M qdd + c + g - J^T W`` (N, 6) N*m of states (N, 6) rad, rad/s, rad/s^2:
        what the joints deliver to the links (recursive Newton-Euler; the recursions as cumulative
        sums over the chain).  ``gravity=False`` drops gravity and the wrench (``M qdd + c``)."""
        q, qd, qdd = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (q, qd, qdd))
        k = self.kinematics(q) if kin is None else kin
        n = q.shape[0]
        zqd = k.z * qd[:, :, None]
        w = np.cumsum(zqd, axis=1)  # link angular velocities
        w_prev = np.concatenate([np.zeros((n, 1, 3)), w[:, :-1]], axis=1)
        dw = np.cumsum(k.z * qdd[:, :, None] + _cross(w_prev, zqd), axis=1)
        dw_prev = np.concatenate([np.zeros((n, 1, 3)), dw[:, :-1]], axis=1)
        r = np.diff(k.p, axis=1, prepend=k.p[:, :1])  # p_i - p_(i-1), fixed in link i-1
        acc = np.cumsum(_cross(dw_prev, r) + _cross(w_prev, _cross(w_prev, r)), axis=1)
        acc = acc - (self.gravity if gravity else 0.0)  # at p_i; gravity as base acceleration
        L = self.body_link
        rc = k.c - k.p[:, L]
        wb, dwb = w[:, L], dw[:, L]
        f = self.body_mass[None, :, None] * (acc[:, L] + _cross(dwb, rc) + _cross(wb, _cross(wb, rc)))
        Iw = (k.inertia @ wb[..., None])[..., 0]
        m = (k.inertia @ dwb[..., None])[..., 0] + _cross(wb, Iw) + _cross(k.c, f)  # about the base origin
        W = self.wrench if gravity else np.zeros(6)
        tip_f = np.broadcast_to(-W[:3], (n, 3))  # what link 6 supplies against W
        tip_m = -W[3:] + _cross(k.tcp[:, :3, 3], tip_f)
        onto = (L[:, None] >= np.arange(6)[None, :]).astype(float)  # (B, 6): body b is distal to joint i
        F = np.einsum("nba,bi->nia", f, onto) + tip_f[:, None]
        N = np.einsum("nba,bi->nia", m, onto) + tip_m[:, None]
        return np.einsum("nia,nia->ni", k.z, N - _cross(k.p, F))

    def mass_matrix(self, q: np.ndarray, kin: _Kin | None = None) -> np.ndarray:
        """Joint-space mass matrix (N, 6, 6) kg*m^2 of ``q`` (N, 6) rad, from body Jacobians:
        ``sum_b m_b Jv_b^T Jv_b + Jw_b^T I_b Jw_b``."""
        k = self.kinematics(q) if kin is None else kin
        moves = (self.body_link[:, None] >= np.arange(6)[None, :]).astype(float)[None, :, :, None]  # (1, B, 6, 1)
        Jw = k.z[:, None] * moves  # (N, B, 6, 3)
        Jv = _cross(Jw, k.c[:, :, None] - k.p[:, None])
        n, nb = Jw.shape[0], Jw.shape[1]

        def rows(J: np.ndarray) -> np.ndarray:  # (N, 6, 3B)
            return J.transpose(0, 2, 1, 3).reshape(n, 6, 3 * nb)

        A = rows(Jv * np.sqrt(self.body_mass)[None, :, None, None])
        Bw = rows(Jw @ k.inertia)
        return A @ A.transpose(0, 2, 1) + Bw @ rows(Jw).transpose(0, 2, 1)

    def static_torque(self, q: np.ndarray) -> np.ndarray:
        """``g(q) - J^T W`` (N, 6) N*m: what the joints hold at rest at ``q`` (N, 6) rad."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        z = np.zeros_like(q)
        return self.inverse_dynamics(q, z, z)

    def equilibrium(self, theta: np.ndarray, stiffness: np.ndarray) -> tuple[np.ndarray, bool]:
        """Static equilibrium ``K (theta - q) = g(q) - J^T W`` of motor angles ``theta`` (6,) rad:
        the link angles (6,) rad and whether the fixed point ``q = theta - K^-1 tau_s(q)``
        converged to :data:`EQUILIBRIUM_TOL_RAD`."""
        theta = np.asarray(theta, dtype=float).reshape(6)
        q = theta.copy()
        for _ in range(EQUILIBRIUM_MAX_ITER):
            q_new = theta - self.static_torque(q)[0] / stiffness
            step = float(np.max(np.abs(q_new - q)))
            q = q_new
            if step <= EQUILIBRIUM_TOL_RAD:
                return q, True
        return q, False


def static_command(
    robot: Robot,
    q: np.ndarray,
    *,
    payload: np.ndarray | None = None,
    wrench: np.ndarray | None = None,
    stiffness: np.ndarray | None = None,
) -> np.ndarray:
    """Exact static compensation: motor angles ``theta = q + K^-1 (g(q) - J^T W)`` (N, 6) rad whose
    static equilibrium is the link pose ``q`` (N, 6) rad."""
    arm = ElasticArm(robot, payload, wrench)
    k = np.asarray(robot.stiffness if stiffness is None else stiffness, dtype=float)
    q = np.atleast_2d(np.asarray(q, dtype=float))
    return q + arm.static_torque(q) / k


# --------------------------------------------------------------------------------------
# The simulation
# --------------------------------------------------------------------------------------
