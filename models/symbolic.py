"""Symbolic CasADi model of a 6R arm: FK, geometric Jacobian, compliance.

:class:`KinematicModel` is the working data built from a :class:`~models.robot.Robot`
description.  Every quantity is a named :class:`casadi.Function`; batch helpers
evaluate them over many poses in one call (``Function.map`` with threads), so
NumPy arrays are converted once per batch, not once per pose.

Frames and signs (see ``docs/conventions.md``):

* ``base2frame_i`` (i = 1..6): DH frame *i* in the base frame; frame 6 is the flange.
* ``base2tcp = base2flange @ flange2tcp``.
* Jacobian ``J`` (6, 6): geometric, at the TCP point, base frame, rows
  ``[v_x, v_y, v_z, w_x, w_y, w_z]`` (linear velocity first), ``twist = J qdot``.
* A wrench ``F = [f; m]`` (N, N*m), base frame, acts on the TCP; joint torques
  ``tau = J^T F``; joint deflection ``dq = K^-1 tau`` (a joint yields in the
  direction of the torque applied to it); TCP deflection ``D = J dq = C F`` with
  ``C = J K^-1 J^T`` (eq. 15 of the paper), ``D = [dp (m); dphi (rad)]``.
"""

from __future__ import annotations

from typing import Any, Sequence

import casadi as ca
import numpy as np

from .codegen import BatchFunction, CompileError, compile_batch
from .robot import Robot

#: Threads used by batch evaluation (``Function.map(..., "thread", N)``).
BATCH_THREADS = 2


def link_transform(theta: Any, d: Any, a: Any, alpha: Any, convention: str) -> ca.SX:
    """DH link transform A_i as a 4x4 CasADi expression.

    ``standard_dh``: ``Rz(theta) Tz(d) Tx(a) Rx(alpha)``;
    ``modified_dh``: ``Rx(alpha) Tx(a) Rz(theta) Tz(d)`` (a, alpha of the previous link).
    """
    ct, st = ca.cos(theta), ca.sin(theta)
    ca_, sa = ca.cos(alpha), ca.sin(alpha)
    if convention == "standard_dh":
        return ca.vertcat(
            ca.horzcat(ct, -st * ca_, st * sa, a * ct),
            ca.horzcat(st, ct * ca_, -ct * sa, a * st),
            ca.horzcat(0, sa, ca_, d),
            ca.horzcat(0, 0, 0, 1),
        )
    if convention == "modified_dh":
        return ca.vertcat(
            ca.horzcat(ct, -st, 0, a),
            ca.horzcat(st * ca_, ct * ca_, -sa, -sa * d),
            ca.horzcat(st * sa, ct * sa, ca_, ca_ * d),
            ca.horzcat(0, 0, 0, 1),
        )
    raise ValueError(f"unknown DH convention {convention!r}")


def dh_chain(q: Any, a: Any, alpha: Any, d: Any, theta_offset: Any,
             convention: str) -> list[Any]:
    """Frames ``base2frame_i`` (i = 1..6) of a DH chain, as CasADi expressions.

    All arguments are length-6 CasADi vectors (SX or MX), symbolic or numeric,
    so that the same code serves kinematics and parameter identification.
    """
    frames = []
    T = ca.SX.eye(4) if isinstance(q, ca.SX) else ca.MX.eye(4)
    for i in range(6):
        T = ca.mtimes(T, link_transform(q[i] + theta_offset[i], d[i], a[i], alpha[i], convention))
        frames.append(T)
    return frames


def joint_axes(frames: Sequence[Any], convention: str) -> tuple[list[Any], list[Any]]:
    """Unit axis ``z`` and a point ``p`` of each joint, base frame (3-vectors)."""
    if convention == "standard_dh":
        origin = [ca.DM.eye(4)] + list(frames[:-1])   # joint i turns about z_{i-1}
    else:
        origin = list(frames)                          # joint i turns about z_i
    return [T[:3, 2] for T in origin], [T[:3, 3] for T in origin]


def geometric_jacobian(frames: Sequence[Any], p_tcp: Any, convention: str) -> Any:
    """Geometric Jacobian at point ``p_tcp`` by the vector-product method (paper eq. 10).

    Column i is ``[z_i x (p_tcp - p_i); z_i]`` (base frame).
    """
    zs, ps = joint_axes(frames, convention)
    cols = [ca.vertcat(ca.cross(z, p_tcp - p), z) for z, p in zip(zs, ps)]
    return ca.horzcat(*cols)


def compliance_from_jacobian(J: Any, kinv: Any) -> Any:
    """``C = J diag(kinv) J^T`` built entry by entry on the upper triangle and mirrored,
    so it is exactly symmetric and costs 21 instead of 36 dot products."""
    n = J.shape[0]
    entries = {}
    for i in range(n):
        for j in range(i, n):
            entries[i, j] = sum(J[i, k] * kinv[k] * J[j, k] for k in range(J.shape[1]))
    return ca.vertcat(*[ca.horzcat(*[entries[min(i, j), max(i, j)] for j in range(n)])
                        for i in range(n)])


class KinematicModel:
    """Named CasADi functions of one robot (working data built from a description).

    Parameters
    ----------
    robot : Robot
        The description; its DH table, stiffness and tool are baked in as constants.

    Attributes
    ----------
    fk_frames : casadi.Function
        ``q (6) -> base2frame1 ... base2frame6`` (4x4 each).
    fk_tcp : casadi.Function
        ``q (6) -> base2tcp`` (4x4).
    jacobian : casadi.Function
        ``q (6) -> J`` (6x6), geometric, TCP point, base frame.
    compliance : casadi.Function
        ``q (6) -> C`` (6x6), ``C = J K^-1 J^T`` (m/N, rad/N, m/(N*m), rad/(N*m) blocks).
    deflection : casadi.Function
        ``(q (6), F (6)) -> D (6)``, ``D = C F``: TCP displacement [m; rad] under wrench F.
    joint_deflection : casadi.Function
        ``(q (6), F (6)) -> dq (6)``, ``dq = K^-1 J^T F`` (rad).
    kinetostatics : casadi.Function
        ``q (6) -> p (3), R (3x3), J (6x6), C (6x6)`` in one pass (batch workhorse).
    """

    def __init__(self, robot: Robot) -> None:
        self.robot = robot
        q = ca.SX.sym("q", 6)
        F = ca.SX.sym("F", 6)
        frames = dh_chain(q, ca.DM(robot.a), ca.DM(robot.alpha), ca.DM(robot.d),
                          ca.DM(robot.theta_offset), robot.convention)
        base2tcp = ca.mtimes(frames[-1], ca.DM(robot.flange2tcp))
        J = geometric_jacobian(frames, base2tcp[:3, 3], robot.convention)
        kinv = ca.DM(1.0 / robot.stiffness)
        C = compliance_from_jacobian(J, 1.0 / robot.stiffness)
        tau = ca.mtimes(J.T, F)
        dq = kinv * tau

        names = [f"base2frame{i + 1}" for i in range(6)]
        self.fk_frames = ca.Function("fk_frames", [q], frames, ["q"], names)
        self.fk_tcp = ca.Function("fk_tcp", [q], [base2tcp], ["q"], ["base2tcp"])
        self.fk_position = ca.Function("fk_position", [q], [base2tcp[:3, 3]], ["q"], ["p_tcp"])
        self.jacobian = ca.Function("jacobian", [q], [J], ["q"], ["J"])
        self.compliance = ca.Function("compliance", [q], [C], ["q"], ["C"])
        self.deflection = ca.Function("deflection", [q, F], [ca.mtimes(C, F)], ["q", "F"], ["D"])
        self.joint_deflection = ca.Function("joint_deflection", [q, F], [dq], ["q", "F"], ["dq"])
        self.kinetostatics = ca.Function(
            "kinetostatics", [q], [base2tcp[:3, 3], base2tcp[:3, :3], J, C],
            ["q"], ["p_tcp", "R_tcp", "J", "C"])
        self._maps: dict[tuple[str, int], ca.Function] = {}
        self._compiled: dict[str, BatchFunction | None] = {}

    # ------------------------------------------------------------------ batch helpers
    def _mapped(self, f: ca.Function, n: int) -> ca.Function:
        key = (f.name(), n)
        fm = self._maps.get(key)
        if fm is None:
            fm = f.map(n, "thread", BATCH_THREADS)
            if len(self._maps) > 64:
                self._maps.clear()
            self._maps[key] = fm
        return fm

    def batch(self, f: ca.Function, *args: np.ndarray) -> list[np.ndarray]:
        """Evaluate ``f`` over a batch without a Python loop.

        Parameters
        ----------
        f : casadi.Function
            One of this model's functions.
        *args : ndarray, shape (N, n_in_k) or (n_in_k,)
            One row per pose; a 1-D argument is broadcast to every pose.

        Returns
        -------
        list of ndarray
            One per output, shape (N, rows, cols) (or (N, rows) for vectors).
        """
        arrs = [np.atleast_2d(np.asarray(a, dtype=float)) for a in args]
        n = max(a.shape[0] for a in arrs)
        compiled = self.compiled(f)
        if compiled is not None:
            return compiled(*[a if a.shape[0] == n else a.reshape(-1) for a in arrs])
        cols = []
        for a in arrs:
            if a.shape[0] not in (1, n):
                raise ValueError(f"batch arguments have {a.shape[0]} and {n} rows")
            cols.append(np.ascontiguousarray(a.T) if a.shape[0] == n else a.reshape(-1, 1))
        fm = self._mapped(f, n)
        res = fm.call(cols)
        out = []
        for k, r in enumerate(res):
            sh = f.size_out(k)
            arr = np.asarray(r)  # (rows, cols*n), column blocks per pose
            if sh[1] == 1:
                out.append(arr.T.reshape(n, sh[0]))
            else:
                out.append(arr.reshape(sh[0], n, sh[1]).transpose(1, 0, 2))
        return out

    def compiled(self, f: ca.Function) -> BatchFunction | None:
        """The compiled batch evaluator of ``f`` (built once, cached on disk), or
        None if no C compiler is available (then ``batch`` uses ``Function.map``)."""
        name = f.name()
        if name not in self._compiled:
            try:
                self._compiled[name] = compile_batch(f, BATCH_THREADS)
            except CompileError:
                self._compiled[name] = None
        return self._compiled[name]

    # ------------------------------------------------------------- numeric conveniences
    def tcp(self, q: np.ndarray) -> np.ndarray:
        """``base2tcp`` for one pose (6,) -> (4, 4), or a batch (N, 6) -> (N, 4, 4)."""
        q = np.asarray(q, dtype=float)
        if q.ndim == 1:
            return np.asarray(self.fk_tcp(q))
        return self.batch(self.fk_tcp, q)[0]

    def J(self, q: np.ndarray) -> np.ndarray:
        """Geometric Jacobian, (6,) -> (6, 6) or (N, 6) -> (N, 6, 6)."""
        q = np.asarray(q, dtype=float)
        if q.ndim == 1:
            return np.asarray(self.jacobian(q))
        return self.batch(self.jacobian, q)[0]

    def C(self, q: np.ndarray) -> np.ndarray:
        """Compliance, (6,) -> (6, 6) or (N, 6) -> (N, 6, 6)."""
        q = np.asarray(q, dtype=float)
        if q.ndim == 1:
            return np.asarray(self.compliance(q))
        return self.batch(self.compliance, q)[0]

    def D(self, q: np.ndarray, F: np.ndarray) -> np.ndarray:
        """TCP deflection [m; rad] under wrench F (base frame), (N, 6) -> (N, 6)."""
        q = np.asarray(q, dtype=float)
        if q.ndim == 1:
            return np.asarray(self.deflection(q, F)).reshape(6)
        return self.batch(self.deflection, q, F)[0]


def directional_stiffness(C: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Translational stiffness along unit direction(s) ``u``: ``1 / (u^T C_tt u)`` (N/m).

    Parameters
    ----------
    C : ndarray, shape (..., 6, 6)
        Compliance matrices.
    u : ndarray, shape (3,) or (..., 3)
        Direction in the base frame (normalised here).
    """
    u = np.asarray(u, dtype=float)
    u = u / np.linalg.norm(u, axis=-1, keepdims=True)
    ctt = C[..., :3, :3]
    return 1.0 / np.einsum("...i,...ij,...j->...", u, ctt, u)


def cartesian_stiffness(C: np.ndarray, max_cond: float = 1e12) -> np.ndarray:
    """Cartesian stiffness ``K_x = C^-1`` (paper eq. 20) where it exists.

    Raises
    ------
    np.linalg.LinAlgError
        If C is singular (condition number above ``max_cond``): at a singular
        pose the arm is infinitely compliant in some direction and K_x does not exist.
    """
    cond = np.linalg.cond(C)
    if np.any(~np.isfinite(cond)) or np.any(cond > max_cond):
        raise np.linalg.LinAlgError(
            f"compliance is singular (condition number {np.max(cond):.3g} > {max_cond:.1g}): "
            "the Cartesian stiffness does not exist at this pose")
    return np.linalg.inv(C)
