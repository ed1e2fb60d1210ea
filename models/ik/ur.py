"""Analytic inverse kinematics of UR-type 6R arms, all 8 branches, vectorised.

A UR-type arm, in standard DH, has ``alpha = [pi/2, 0, 0, pi/2, -pi/2, 0]`` and
``a1 = a4 = a5 = a6 = 0``; joints 2, 3, 4 are parallel and their offsets along
that axis add up to the lateral offset ``D = d2 + d3 + d4`` (the paper's eq. 37
uses d4 alone, which is only right when d2 = d3 = 0).  A ``modified_dh`` file
describing the same structure is converted exactly: its first-row ``Rx(alpha0)
Tx(a0)`` becomes a constant base pre-transform and the other rows shift by one.
A chain with end transforms (``frame02base``, ``flange2frame6``: a URDF chain) is solved
in DH frame 0 for DH frame 6.  Frames whose x axis is the opposite of the UR pattern's
(``alpha_i`` of the other sign, e.g. a chain read from a URDF) are turned by pi about
their z axis (``a_i, alpha_i -> -a_i, -alpha_i``, ``theta_offset_i += pi``,
``theta_offset_{i+1} -= pi``), an exact re-description of the same chain.

Branches are labelled ``s{+-}w{+-}e{+-}`` and indexed ``4*shoulder + 2*wrist +
elbow`` (0 for ``+``):

* shoulder: ``theta1 = psi + asin(D/r)`` (+) or ``psi + pi - asin(D/r)`` (-),
  with ``psi, r`` the polar angle and radius of the wrist centre;
* wrist: ``theta5 = +acos(c5)`` (+) or ``-acos(c5)`` (-);
* elbow: ``theta3 = +acos(c3)`` (+) or ``-acos(c3)`` (-).

The labels are a property of the formula, so they are stable along a path.
Returned angles are ``q = theta - theta_offset`` wrapped into the joint limits,
nearest to 0 (``(-pi, pi]`` when the limits allow it).
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from ..codegen import BatchFunction, VMBatchFunction, batch_function
from ..constants import IK_CLIP_TOL, IK_SHOULDER_SINGULAR_TOL, IK_WRIST_SINGULAR_TOL
from ..robot import Robot
from ..transforms import invert
from .base import IKSolution, IKSolver, IKStatus, IKStructureError, check_poses, register_family

BRANCH_LABELS: tuple[str, ...] = tuple(
    f"s{'+-'[s]}w{'+-'[w]}e{'+-'[e]}" for s in (0, 1) for w in (0, 1) for e in (0, 1)
)

#: alpha pattern of a UR-type arm in standard DH, rad.
UR_ALPHA = np.array([np.pi / 2, 0.0, 0.0, np.pi / 2, -np.pi / 2, 0.0])
_STRUCT_TOL = 1e-9
#: Threads of the batch evaluation of the closed form (compiled or virtual machine).
IK_BATCH_THREADS = 2


def _sdh_inv_sx(ct: ca.SX, st: ca.SX, d: float, a: float, alpha: float) -> ca.SX:
    """Inverse of a standard-DH link transform, given cos and sin of theta (CasADi)."""
    c, s = np.cos(alpha), np.sin(alpha)
    R = ca.vertcat(ca.horzcat(ct, -st * c, st * s), ca.horzcat(st, ct * c, -ct * s), ca.horzcat(0, s, c))
    p = ca.vertcat(a * ct, a * st, d)
    return ca.vertcat(ca.horzcat(R.T, -ca.mtimes(R.T, p)), ca.horzcat(0, 0, 0, 1))


def _rx_tx(alpha: float, a: float) -> np.ndarray:
    c, s = np.cos(alpha), np.sin(alpha)
    return np.array([[1.0, 0.0, 0.0, a], [0.0, c, -s, 0.0], [0.0, s, c, 0.0], [0.0, 0.0, 0.0, 1.0]])


def _branch_codes(oks: list, c3s: list, s5s: list, c5s: list, r: Any, ratio: Any) -> list:
    """Status code of each of the 8 branches, most fundamental reason first (see IKStatus)."""
    codes = []
    for b in range(8):
        sh, w = b // 4, (b // 2) % 2
        code = ca.if_else(oks[b], float(IKStatus.OK.code), float(IKStatus.JOINT_LIMIT.code))
        code = ca.if_else(ca.fabs(c3s[2 * sh + w]) > 1 + IK_CLIP_TOL, float(IKStatus.ELBOW_UNREACHABLE.code), code)
        code = ca.if_else(ca.fabs(s5s[2 * sh + w]) < IK_WRIST_SINGULAR_TOL, float(IKStatus.WRIST_SINGULAR.code), code)
        code = ca.if_else(ca.fabs(c5s[sh]) > 1 + IK_CLIP_TOL, float(IKStatus.WRIST_UNREACHABLE.code), code)
        code = ca.if_else(r < IK_SHOULDER_SINGULAR_TOL, float(IKStatus.SHOULDER_SINGULAR.code), code)
        code = ca.if_else(ca.fabs(ratio) > 1 + IK_CLIP_TOL, float(IKStatus.SHOULDER_UNREACHABLE.code), code)
        codes.append(code)
    return codes


@register_family
class AnalyticIK(IKSolver):
    """Closed-form IK of a UR-type arm described by a robot file.

    Parameters
    ----------
    robot : Robot
        Must be UR-type (see module docstring); otherwise :class:`IKStructureError`
        names the parameter that breaks the structure.
    """

    family = "ur"
    order = 10
    description = "UR-type: joints 2, 3, 4 parallel, offset wrist (closed form, 8 branches)"
    labels = BRANCH_LABELS
    guard_names = ("shoulder", "wrist", "elbow")  # rho (m), sin(theta5), sin(theta3)
    guard_kinds = ("length", "sine", "sine")

    def __init__(self, robot: Robot) -> None:
        super().__init__(robot)
        a, alpha, d, off = robot.a, robot.alpha, robot.d, robot.theta_offset.copy()
        if robot.convention == "modified_dh":
            # Row i holds a_{i-1}, alpha_{i-1}: shift to an equivalent standard chain whose base
            # frame "sdh0" is DH frame 0 turned by Rx(alpha_0) Tx(a_0) (sdh0 -> frame 0).
            sdh02frame0 = _rx_tx(alpha[0], a[0])
            a = np.r_[a[1:], 0.0]
            alpha = np.r_[alpha[1:], 0.0]
        else:
            sdh02frame0 = np.eye(4)
        a, alpha, off = _flip_to_pattern(a, alpha, off)
        bad = [
            f"alpha{i + 1} = {alpha[i]:.6g} rad (expected {UR_ALPHA[i]:.6g})"
            for i in range(6)
            if abs(alpha[i] - UR_ALPHA[i]) > _STRUCT_TOL
        ]
        bad += [f"a{i + 1} = {a[i]:.6g} m (expected 0)" for i in (0, 3, 4, 5) if abs(a[i]) > _STRUCT_TOL]
        bad += [f"a{i + 1} = 0 (expected non-zero)" for i in (1, 2) if abs(a[i]) <= _STRUCT_TOL]
        if abs(d[5]) <= _STRUCT_TOL:
            bad.append("d6 = 0 (expected non-zero)")
        if bad:
            raise IKStructureError(
                f"robot '{robot.name}' is not UR-type, analytic IK does not apply: " + "; ".join(bad)
            )
        self.a, self.alpha, self.d, self.offset = a, alpha, d, off
        self.D = float(d[1] + d[2] + d[3])
        self._base2sdh0 = invert(robot.frame02base @ sdh02frame0)
        self._frame62tcp = invert(robot.flange2frame6 @ robot.tcp2flange)
        self.function = self._build_function()
        self._evaluator: BatchFunction | VMBatchFunction | None = None

    def branch_meaning(self) -> dict[str, str]:
        return {
            lab: (
                f"theta1 = psi {'+ asin(D/r)' if lab[1] == '+' else '+ pi - asin(D/r)'}, "
                f"theta5 = {lab[3]}acos(c5), theta3 = {lab[5]}acos(c3)"
            )
            for lab in self.labels
        }

    def guard_factors(self, q: Any) -> Any:
        """The three factors of ``det J`` whose signs are the branch.

        ``det J = a2 a3 * sin(theta3) * sin(theta5) * rho`` with
        ``rho = a2 cos(theta2) + a3 cos(theta2 + theta3) + d5 sin(theta2 + theta3 + theta4)``
        (m) and ``theta = q + theta_offset`` in the standard-DH reading of this solver.

        Parameters
        ----------
        q : casadi SX/MX (6,) or ndarray (6,) or (N, 6), rad

        Returns
        -------
        ``[rho (m), sin(theta5), sin(theta3)]``: CasADi (3,) or ndarray (3,) / (N, 3).
        """
        a, d, off = self.a, self.d, self.offset
        if isinstance(q, (ca.SX, ca.MX)):
            th = [q[i] + off[i] for i in range(6)]
            rho = a[1] * ca.cos(th[1]) + a[2] * ca.cos(th[1] + th[2]) + d[4] * ca.sin(th[1] + th[2] + th[3])
            return ca.vertcat(rho, ca.sin(th[4]), ca.sin(th[2]))
        th = np.asarray(q, dtype=float) + off
        rho = (
            a[1] * np.cos(th[..., 1])
            + a[2] * np.cos(th[..., 1] + th[..., 2])
            + d[4] * np.sin(th[..., 1] + th[..., 2] + th[..., 3])
        )
        return np.stack([rho, np.sin(th[..., 4]), np.sin(th[..., 2])], axis=-1)

    def _build_function(self) -> ca.Function:
        """The closed form as a named CasADi Function of the flange pose.

        ``tcp2base (4x4) -> q (6x8, column = branch, rad, within the limits),
        status (8, IKStatus codes)``.  Cosines are clipped before acos/asin; the
        unclipped values decide the status.
        """
        a, d, alpha, D = self.a, self.d, self.alpha, self.D
        Tt = ca.SX.sym("tcp2base", 4, 4)
        Tf = ca.mtimes([ca.DM(self._base2sdh0), Tt, ca.DM(self._frame62tcp)])
        X, Y, Z, P = Tf[:3, 0], Tf[:3, 1], Tf[:3, 2], Tf[:3, 3]
        p5 = P - d[5] * Z
        r = ca.sqrt(p5[0] ** 2 + p5[1] ** 2)
        psi = ca.atan2(p5[1], p5[0])
        ratio = D / r
        # Sines and cosines of the acos/asin results are formed algebraically
        # (cos(acos(c)) = c, sin(acos(c)) = sqrt(1 - c^2)): fewer transcendental calls.
        rc = ca.fmin(ca.fmax(ratio, -1), 1)
        asr = ca.asin(rc)
        cas = ca.sqrt(1 - rc**2)
        spsi, cpsi = p5[1] / r, p5[0] / r
        thetas, c5s, s5s, c3s = [], [], [], []
        # theta1 = psi + asr  or  psi + pi - asr
        for th1, s1, c1 in (
            (psi + asr, spsi * cas + cpsi * rc, cpsi * cas - spsi * rc),
            (psi + np.pi - asr, -(spsi * cas - cpsi * rc), -(cpsi * cas + spsi * rc)),
        ):
            c5 = (P[0] * s1 - P[1] * c1 - D) / d[5]
            c5s.append(c5)
            c5c = ca.fmin(ca.fmax(c5, -1), 1)
            a5 = ca.acos(c5c)
            sa5 = ca.sqrt(1 - c5c**2)
            A1inv = _sdh_inv_sx(c1, s1, d[0], a[0], alpha[0])
            for th5, s5 in ((a5, sa5), (-a5, -sa5)):
                s5s.append(s5)
                s5safe = ca.if_else(ca.fabs(s5) < IK_WRIST_SINGULAR_TOL, 1.0, s5)
                num = -(s1 * Y[0] - c1 * Y[1]) / s5safe
                den = (s1 * X[0] - c1 * X[1]) / s5safe
                th6 = ca.atan2(num, den)
                h6 = ca.sqrt(num**2 + den**2)
                h6 = ca.if_else(h6 > 0, h6, 1.0)
                T14 = ca.mtimes(
                    [
                        A1inv,
                        Tf,
                        _sdh_inv_sx(den / h6, num / h6, d[5], a[5], alpha[5]),
                        _sdh_inv_sx(c5c, s5, d[4], a[4], alpha[4]),
                    ]
                )
                px, py = T14[0, 3], T14[1, 3]
                c3 = (px**2 + py**2 - a[1] ** 2 - a[2] ** 2) / (2.0 * a[1] * a[2])
                c3s.append(c3)
                c3c = ca.fmin(ca.fmax(c3, -1), 1)
                a3 = ca.acos(c3c)
                sa3 = ca.sqrt(1 - c3c**2)
                phi = ca.atan2(T14[1, 0], T14[0, 0])
                gamma = ca.atan2(py, px)
                for th3, s3 in ((a3, sa3), (-a3, -sa3)):
                    th2 = gamma - ca.atan2(a[2] * s3, a[1] + a[2] * c3c)
                    thetas.append(ca.vertcat(th1, th2, th3, phi - th2 - th3, th5, th6))
        # Joint variables wrapped to (-pi, pi], then shifted by 2*pi*k into the limits.
        two_pi = 2.0 * np.pi
        qs, oks = [], []
        for th in thetas:
            qb = th - ca.DM(self.offset)
            qb = qb - two_pi * ca.floor((qb + np.pi) / two_pi)
            lo, hi = ca.DM(self.q_min), ca.DM(self.q_max)
            qb = ca.if_else(qb < lo, qb + two_pi * ca.ceil((lo - qb) / two_pi), qb)
            qb = ca.if_else(qb > hi, qb - two_pi * ca.ceil((qb - hi) / two_pi), qb)
            qs.append(qb)
            oks.append(ca.mmin(ca.fmin(qb - lo, hi - qb)) >= -1e-12)
        codes = _branch_codes(oks, c3s, s5s, c5s, r, ratio)
        return ca.Function("ik_branches", [Tt], [ca.horzcat(*qs), ca.vertcat(*codes)], ["tcp2base"], ["q", "status"])

    @property
    def evaluator(self) -> BatchFunction | VMBatchFunction:
        """The batch evaluator of :attr:`function`, built on first use: compiled C, or
        CasADi's virtual machine without a C compiler (its ``compiled`` attribute says which)."""
        if self._evaluator is None:
            self._evaluator = batch_function(self.function, IK_BATCH_THREADS)
        return self._evaluator

    def _batch(self, flat: np.ndarray) -> list[np.ndarray]:
        """``q`` (N, 6, 8) and ``status`` (N, 8) for column-major flattened poses ``flat`` (N, 16)."""
        return self.evaluator(flat)

    def solve(self, tcp2base: np.ndarray) -> IKSolution:
        """All 8 branches for target TCP pose(s).

        Parameters
        ----------
        tcp2base : ndarray, shape (4, 4) or (N, 4, 4)
            Target TCP poses in the base frame.

        Returns
        -------
        IKSolution
            ``q`` (N, 8, 6) rad and ``status`` (N, 8).
        """
        T = check_poses(tcp2base)
        n = T.shape[0]
        # Column-major flattening of each 4x4, as CasADi expects.
        qc, st = self._batch(T.transpose(0, 2, 1).reshape(n, 16))
        q = qc.transpose(0, 2, 1)  # (n, 8, 6), contiguous (the C output is branch-major)
        status = st.astype(int)
        q[status != IKStatus.OK.code] = np.nan
        return IKSolution(q=q, status=status, labels=self.labels)


def _flip_to_pattern(a: np.ndarray, alpha: np.ndarray, off: np.ndarray) -> tuple[np.ndarray, ...]:
    """Turn standard-DH frames 1..5 by pi about z where ``alpha_i`` is the UR pattern's negative."""
    a, alpha, off = a.copy(), alpha.copy(), off.copy()
    for i in range(5):
        if UR_ALPHA[i] != 0.0 and abs(alpha[i] + UR_ALPHA[i]) <= _STRUCT_TOL:
            a[i], alpha[i] = -a[i], -alpha[i]
            off[i] += np.pi
            off[i + 1] -= np.pi
    return a, alpha, off
