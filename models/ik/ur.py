"""Analytic inverse kinematics of UR-type 6R arms, all 8 branches, vectorised.

A UR-type arm, in standard DH, has ``alpha = [pi/2, 0, 0, pi/2, -pi/2, 0]`` and
``a1 = a4 = a5 = a6 = 0``; joints 2, 3, 4 are parallel and their offsets along
that axis add up to the lateral offset ``D = d2 + d3 + d4`` (the paper's eq. 37
uses d4 alone, which is only right when d2 = d3 = 0).  A ``modified_dh`` file
describing the same structure is converted exactly: its first-row ``Rx(alpha0)
Tx(a0)`` becomes a constant base pre-transform and the other rows shift by one.

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

import enum
from dataclasses import dataclass

import casadi as ca
import numpy as np

from .codegen import BatchFunction, VMBatchFunction, batch_function
from .errors import InputError
from .constants import IK_CLIP_TOL, IK_SHOULDER_SINGULAR_TOL, IK_WRIST_SINGULAR_TOL
from .robot import Robot
from .transforms import invert

BRANCH_LABELS: tuple[str, ...] = tuple(
    f"s{'+-'[s]}w{'+-'[w]}e{'+-'[e]}" for s in (0, 1) for w in (0, 1) for e in (0, 1))

#: alpha pattern of a UR-type arm in standard DH, rad.
UR_ALPHA = np.array([np.pi / 2, 0.0, 0.0, np.pi / 2, -np.pi / 2, 0.0])
_STRUCT_TOL = 1e-9
#: Threads of the batch evaluation of the closed form (compiled or virtual machine).
IK_BATCH_THREADS = 2


class IKStatus(enum.IntEnum):
    """Why a branch has (or has no) solution."""

    OK = 0
    SHOULDER_UNREACHABLE = 1   # wrist centre inside the lateral-offset cylinder
    WRIST_UNREACHABLE = 2      # |cos(theta5)| > 1
    WRIST_SINGULAR = 3         # sin(theta5) ~ 0: theta6 undetermined (joints 4, 6 aligned)
    ELBOW_UNREACHABLE = 4      # target beyond the reach of links 2-3
    JOINT_LIMIT = 5            # a solution exists but no 2*pi shift puts it in the limits
    SHOULDER_SINGULAR = 6      # wrist centre on the joint-1 axis: theta1 undetermined


IK_REASONS = {
    IKStatus.OK: "ok",
    IKStatus.SHOULDER_UNREACHABLE: "unreachable: wrist centre closer to the base axis than the lateral offset",
    IKStatus.WRIST_UNREACHABLE: "unreachable: no theta5 (|cos theta5| > 1)",
    IKStatus.WRIST_SINGULAR: "singular: wrist (sin theta5 = 0), theta4 and theta6 not separable",
    IKStatus.ELBOW_UNREACHABLE: "unreachable: beyond the reach of the upper arm and forearm",
    IKStatus.JOINT_LIMIT: "outside the joint limits",
    IKStatus.SHOULDER_SINGULAR: "singular: wrist centre on the joint-1 axis (shoulder singularity)",
}


class IKStructureError(InputError):
    """The robot is not UR-type, so the analytic IK does not apply."""


@dataclass
class IKSolution:
    """All 8 branches for N target poses.

    Attributes
    ----------
    q : ndarray, shape (N, 8, 6)
        Joint angles (rad); NaN where the branch has no solution.
    status : ndarray of int, shape (N, 8)
        :class:`IKStatus` per branch.
    """

    q: np.ndarray
    status: np.ndarray

    @property
    def valid(self) -> np.ndarray:
        """(N, 8) bool: branch has a solution within the limits."""
        return self.status == IKStatus.OK

    @property
    def labels(self) -> tuple[str, ...]:
        return BRANCH_LABELS

    def reason(self, i: int, branch: int) -> str:
        """Human-readable reason for pose ``i``, branch ``branch``."""
        return IK_REASONS[IKStatus(int(self.status[i, branch]))]

    def summary(self, i: int) -> str:
        """One line per pose: the worst reason if no branch is valid."""
        if self.valid[i].any():
            return f"{int(self.valid[i].sum())} branch(es)"
        codes = sorted({int(c) for c in self.status[i]})
        return "; ".join(IK_REASONS[IKStatus(c)] for c in codes)


def _sdh_inv_sx(ct: ca.SX, st: ca.SX, d: float, a: float, alpha: float) -> ca.SX:
    """Inverse of a standard-DH link transform, given cos and sin of theta (CasADi)."""
    c, s = np.cos(alpha), np.sin(alpha)
    R = ca.vertcat(ca.horzcat(ct, -st * c, st * s), ca.horzcat(st, ct * c, -ct * s), ca.horzcat(0, s, c))
    p = ca.vertcat(a * ct, a * st, d)
    return ca.vertcat(ca.horzcat(R.T, -ca.mtimes(R.T, p)), ca.horzcat(0, 0, 0, 1))


def _rx_tx(alpha: float, a: float) -> np.ndarray:
    c, s = np.cos(alpha), np.sin(alpha)
    return np.array([[1.0, 0.0, 0.0, a], [0.0, c, -s, 0.0], [0.0, s, c, 0.0], [0.0, 0.0, 0.0, 1.0]])


class AnalyticIK:
    """Closed-form IK of a UR-type arm described by a robot file.

    Parameters
    ----------
    robot : Robot
        Must be UR-type (see module docstring); otherwise :class:`IKStructureError`
        names the parameter that breaks the structure.
    """

    def __init__(self, robot: Robot) -> None:
        self.robot = robot
        a, alpha, d, off = robot.a, robot.alpha, robot.d, robot.theta_offset
        if robot.convention == "modified_dh":
            # Row i holds a_{i-1}, alpha_{i-1}: shift to an equivalent standard chain whose base
            # frame "sdh0" is the robot base turned by Rx(alpha_0) Tx(a_0) (sdh0 -> base).
            self._sdh02base = _rx_tx(alpha[0], a[0])
            a = np.r_[a[1:], 0.0]
            alpha = np.r_[alpha[1:], 0.0]
        else:
            self._sdh02base = np.eye(4)
        bad = [f"alpha{i + 1} = {alpha[i]:.6g} rad (expected {UR_ALPHA[i]:.6g})"
               for i in range(6) if abs(alpha[i] - UR_ALPHA[i]) > _STRUCT_TOL]
        bad += [f"a{i + 1} = {a[i]:.6g} m (expected 0)" for i in (0, 3, 4, 5) if abs(a[i]) > _STRUCT_TOL]
        bad += [f"a{i + 1} = 0 (expected non-zero)" for i in (1, 2) if abs(a[i]) <= _STRUCT_TOL]
        if abs(d[5]) <= _STRUCT_TOL:
            bad.append("d6 = 0 (expected non-zero)")
        if bad:
            raise IKStructureError(
                f"robot '{robot.name}' is not UR-type, analytic IK does not apply: " + "; ".join(bad))
        self.a, self.alpha, self.d, self.offset = a, alpha, d, off
        self.D = float(d[1] + d[2] + d[3])
        self._base2sdh0 = invert(self._sdh02base)
        self._flange2tcp = invert(robot.tcp2flange)
        self.q_min, self.q_max = robot.q_min, robot.q_max
        self.function = self._build_function()
        self._evaluator: BatchFunction | VMBatchFunction | None = None

    def _build_function(self) -> ca.Function:
        """The closed form as a named CasADi Function of the flange pose.

        ``tcp2base (4x4) -> q (6x8, column = branch, rad, within the limits),
        status (8, IKStatus codes)``.  Cosines are clipped before acos/asin; the
        unclipped values decide the status.
        """
        a, d, alpha, D = self.a, self.d, self.alpha, self.D
        Tt = ca.SX.sym("tcp2base", 4, 4)
        Tf = ca.mtimes([ca.DM(self._base2sdh0), Tt, ca.DM(self._flange2tcp)])
        X, Y, Z, P = Tf[:3, 0], Tf[:3, 1], Tf[:3, 2], Tf[:3, 3]
        p5 = P - d[5] * Z
        r = ca.sqrt(p5[0] ** 2 + p5[1] ** 2)
        psi = ca.atan2(p5[1], p5[0])
        ratio = D / r
        # Sines and cosines of the acos/asin results are formed algebraically
        # (cos(acos(c)) = c, sin(acos(c)) = sqrt(1 - c^2)): fewer transcendental calls.
        rc = ca.fmin(ca.fmax(ratio, -1), 1)
        asr = ca.asin(rc)
        cas = ca.sqrt(1 - rc ** 2)
        spsi, cpsi = p5[1] / r, p5[0] / r
        thetas, c5s, s5s, c3s = [], [], [], []
        # theta1 = psi + asr  or  psi + pi - asr
        for th1, s1, c1 in ((psi + asr, spsi * cas + cpsi * rc, cpsi * cas - spsi * rc),
                            (psi + np.pi - asr, -(spsi * cas - cpsi * rc), -(cpsi * cas + spsi * rc))):
            c5 = (P[0] * s1 - P[1] * c1 - D) / d[5]
            c5s.append(c5)
            c5c = ca.fmin(ca.fmax(c5, -1), 1)
            a5 = ca.acos(c5c)
            sa5 = ca.sqrt(1 - c5c ** 2)
            A1inv = _sdh_inv_sx(c1, s1, d[0], a[0], alpha[0])
            for th5, s5 in ((a5, sa5), (-a5, -sa5)):
                s5s.append(s5)
                s5safe = ca.if_else(ca.fabs(s5) < IK_WRIST_SINGULAR_TOL, 1.0, s5)
                num = -(s1 * Y[0] - c1 * Y[1]) / s5safe
                den = (s1 * X[0] - c1 * X[1]) / s5safe
                th6 = ca.atan2(num, den)
                h6 = ca.sqrt(num ** 2 + den ** 2)
                h6 = ca.if_else(h6 > 0, h6, 1.0)
                T14 = ca.mtimes([A1inv, Tf, _sdh_inv_sx(den / h6, num / h6, d[5], a[5], alpha[5]),
                                 _sdh_inv_sx(c5c, s5, d[4], a[4], alpha[4])])
                px, py = T14[0, 3], T14[1, 3]
                c3 = (px ** 2 + py ** 2 - a[1] ** 2 - a[2] ** 2) / (2.0 * a[1] * a[2])
                c3s.append(c3)
                c3c = ca.fmin(ca.fmax(c3, -1), 1)
                a3 = ca.acos(c3c)
                sa3 = ca.sqrt(1 - c3c ** 2)
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
        # Status per branch, most fundamental reason first (see IKStatus).
        codes = []
        for b in range(8):
            sh, w = b // 4, (b // 2) % 2
            code = ca.if_else(oks[b], float(IKStatus.OK), float(IKStatus.JOINT_LIMIT))
            code = ca.if_else(ca.fabs(c3s[2 * sh + w]) > 1 + IK_CLIP_TOL, float(IKStatus.ELBOW_UNREACHABLE), code)
            code = ca.if_else(ca.fabs(s5s[2 * sh + w]) < IK_WRIST_SINGULAR_TOL, float(IKStatus.WRIST_SINGULAR), code)
            code = ca.if_else(ca.fabs(c5s[sh]) > 1 + IK_CLIP_TOL, float(IKStatus.WRIST_UNREACHABLE), code)
            code = ca.if_else(r < IK_SHOULDER_SINGULAR_TOL, float(IKStatus.SHOULDER_SINGULAR), code)
            code = ca.if_else(ca.fabs(ratio) > 1 + IK_CLIP_TOL, float(IKStatus.SHOULDER_UNREACHABLE), code)
            codes.append(code)
        return ca.Function("ik_branches", [Tt], [ca.horzcat(*qs), ca.vertcat(*codes)],
                           ["tcp2base"], ["q", "status"])

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
        T = np.asarray(tcp2base, dtype=float)
        if T.shape[-2:] != (4, 4):
            raise ValueError(f"target poses must have shape (N, 4, 4), got {T.shape}")
        T = T.reshape(-1, 4, 4)
        if not np.all(np.isfinite(T)):
            bad = int(np.where(~np.isfinite(T).all(axis=(1, 2)))[0][0])
            raise ValueError(f"target pose {bad} is not finite")
        n = T.shape[0]
        # Column-major flattening of each 4x4, as CasADi expects.
        qc, st = self._batch(T.transpose(0, 2, 1).reshape(n, 16))
        q = qc.transpose(0, 2, 1)   # (n, 8, 6), contiguous (the C output is branch-major)
        status = st.astype(int)
        q[status != IKStatus.OK] = np.nan
        return IKSolution(q=q, status=status)

    def _into_limits(self, q: np.ndarray, seed: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Shift each angle by 2*pi*k into [q_min, q_max], nearest to ``seed`` (default 0)."""
        ref = np.zeros_like(q) if seed is None else np.broadcast_to(seed, q.shape)
        two_pi = 2.0 * np.pi
        with np.errstate(invalid="ignore"):
            k = np.round((ref - q) / two_pi)
            cand = q + two_pi * k
            # Pull into the limits when the nearest copy lies outside.
            lo = cand < self.q_min
            cand = np.where(lo, cand + two_pi * np.ceil((self.q_min - cand) / two_pi), cand)
            hi = cand > self.q_max
            cand = np.where(hi, cand - two_pi * np.ceil((cand - self.q_max) / two_pi), cand)
            ok = (cand >= self.q_min - 1e-12) & (cand <= self.q_max + 1e-12)
        return cand, ok.all(axis=-1) | np.isnan(q).any(axis=-1)

    def nearest(self, tcp2base: np.ndarray, seed: np.ndarray,
                branch: int | None = None) -> tuple[np.ndarray, np.ndarray, IKSolution]:
        """The solution nearest a seed configuration.

        Parameters
        ----------
        tcp2base : ndarray, shape (N, 4, 4) or (4, 4)
        seed : ndarray, shape (N, 6) or (6,)
            Each joint of every branch is shifted by 2*pi*k (within limits) to lie
            nearest the seed; the branch with the smallest Euclidean distance wins.
        branch : int, optional
            Restrict to one branch index (0..7).

        Returns
        -------
        q : ndarray, shape (N, 6)
            NaN rows where no branch is valid.
        chosen : ndarray of int, shape (N,)
            Branch index, -1 where none.
        sol : IKSolution
            All branches (shifted to the seed).
        """
        sol = self.solve(tcp2base)
        n = sol.q.shape[0]
        seed = np.broadcast_to(np.asarray(seed, dtype=float).reshape(-1, 6), (n, 6))
        qs, ok = self._into_limits(sol.q, seed[:, None, :])
        valid = sol.valid & ok
        dist = np.linalg.norm(qs - seed[:, None, :], axis=-1)
        dist = np.where(valid, dist, np.inf)
        if branch is not None:
            mask = np.zeros(8, bool)
            mask[branch] = True
            dist = np.where(mask, dist, np.inf)
        chosen = np.argmin(dist, axis=1)
        none = ~np.isfinite(dist[np.arange(n), chosen])
        q = qs[np.arange(n), chosen].copy()
        q[none] = np.nan
        chosen = np.where(none, -1, chosen)
        return q, chosen, IKSolution(q=np.where(valid[..., None], qs, np.nan), status=sol.status)
