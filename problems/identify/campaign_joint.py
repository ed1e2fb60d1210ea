"""The joint problem of several campaigns (:mod:`.campaigns`, steps 3 and 5).

:class:`JointFit`: Gauss-Newton steps on the joint least-squares objective over the model's free
parameters and every non-reference campaign's transform (small motions :func:`perturbed`, their
size :func:`transform_change`); :func:`joint_covariance`, the covariance of that problem, and
:func:`registration_cov`, a campaign's registration covariance carried from it
(:func:`campaign_registration`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from models import effects as fx
from models.arm import ArmModel
from models.transforms import invert, matrix_to_rotvec, rotvec_to_matrix, transform

from ..measurements import Measurements
from .evaluation import evaluator_for, make_rows, row_weights
from .results import IdentificationResult, ParameterStatus

#: Convergence of the campaigns' transforms: translation change, m ...
CAMPAIGN_TOL_M = 1e-7
#: ... and rotation change, rad.
CAMPAIGN_TOL_RAD = 1e-7
#: Gauss-Newton steps of the joint problem per round.
CAMPAIGN_GN_MAX_ITER = 12
#: A Gauss-Newton run stops when its step is below this fraction of the tolerances above (so that two
#: runs from different starts agree to within the tolerances).
CAMPAIGN_GN_TOL_RATIO = 0.1
#: Step halvings of a Gauss-Newton step that does not lower the joint cost.
CAMPAIGN_GN_HALVINGS = 8
#: Directions of the joint problem (column-normalised Jacobian) with a singular value below this
#: fraction of the largest are left out of its covariance (taken as determined by the model's holds:
#: a parameter the engine freed can become inseparable from a campaign's transform).
CAMPAIGN_COV_RCOND = 1e-6
#: Central-difference step of the map to a campaign's registration parameters (m and rad).
REG_FD_STEP = 1e-6


def _skew(v: np.ndarray) -> np.ndarray:
    """``[v]x`` of vectors (..., 3) -> (..., 3, 3)."""
    v = np.asarray(v, dtype=float)
    S = np.zeros(v.shape[:-1] + (3, 3))
    S[..., 0, 1], S[..., 0, 2] = -v[..., 2], v[..., 1]
    S[..., 1, 0], S[..., 1, 2] = v[..., 2], -v[..., 0]
    S[..., 2, 0], S[..., 2, 1] = -v[..., 1], v[..., 0]
    return S


def perturbed(A: np.ndarray, dt: np.ndarray, dphi: np.ndarray) -> np.ndarray:
    """``A`` followed by the small motion ``x -> exp([dphi]x) x + dt`` (of the reference frame)."""
    return transform(rotvec_to_matrix(dphi), dt) @ A


def transform_change(A: np.ndarray, B: np.ndarray) -> tuple[float, float]:
    """Translation (m) and rotation (rad) difference of two rigid transforms."""
    D = B @ invert(A)
    return float(np.linalg.norm(D[:3, 3])), float(np.linalg.norm(matrix_to_rotvec(D[:3, :3])))


def free_names(res: IdentificationResult) -> list[str]:
    """Free parameters of an identification (the covariance's names, else the FREE table rows)."""
    if res.model.covariance_names:
        return list(res.model.covariance_names)
    return [p.name for p in res.parameters if p.status is ParameterStatus.FREE]


class JointFit:
    """The joint least-squares problem of the robot's free parameters and the campaigns' transforms
    (every campaign but the reference: 6 columns each, ``[dt (m), dphi (rad)]``)."""

    def __init__(
        self,
        model: ArmModel,
        names: list[str],
        campaigns: Sequence[Measurements],
        campaign: np.ndarray,
        merged: Measurements,
        inliers: np.ndarray,
    ) -> None:
        self.model = model
        self.names = names
        self.idx = np.array([fx.PARAM_NAMES.index(n) for n in names], dtype=int)
        self.const = model.const
        self.ev = evaluator_for(model.nominal, self.const)
        self.rows = make_rows(merged, model.time_ref, model.temperature_ref)
        self.raw = np.concatenate([m.p for m in campaigns])
        self.campaign = campaign
        self.C = len(campaigns)
        self.w = row_weights(merged, np.ones(merged.n, dtype=bool))
        self.mask = np.asarray(inliers, dtype=bool)

    def mapped(self, A: Sequence[np.ndarray]) -> np.ndarray:
        """The raw measured points in the reference frame, (N, 3), m."""
        out = np.empty_like(self.raw)
        for c in range(self.C):
            sel = self.campaign == c
            out[sel] = self.raw[sel] @ A[c][:3, :3].T + A[c][:3, 3]
        return out

    def residual(self, theta: np.ndarray, A: Sequence[np.ndarray]) -> np.ndarray:
        """Unweighted residual ``p_model - A p``, (N, 3), m, reference frame."""
        p, _q = self.ev.measure(self.rows, theta, self.const)
        return p - self.mapped(A)

    def rms(self, theta: np.ndarray, A: Sequence[np.ndarray]) -> float:
        """RMS per axis of the unweighted residual over the inlier rows, m: the rounds' comparison."""
        r = self.residual(theta, A)[self.mask]
        return float(np.sqrt(np.mean(r**2))) if r.size else 0.0

    def cost(self, theta: np.ndarray, A: Sequence[np.ndarray]) -> float:
        r = (self.residual(theta, A) * self.w)[self.mask]
        return float(np.sum(r**2))

    def jacobian(self, theta: np.ndarray, A: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """Weighted residual (3n,) and weighted Jacobian (3n, k + 6 (C - 1)) over the inlier rows:
        the free parameters (SI) then ``[dt, dphi]`` per non-reference campaign."""
        p, q_eq = self.ev.measure(self.rows, theta, self.const)
        _p, J = self.ev.jacobian(self.rows, q_eq, theta, self.const)
        n = len(self.rows)
        J3 = np.asarray(J).reshape(n, 3, -1)[:, :, self.idx]
        pm = self.mapped(A)
        cols = [J3]
        for c in range(self.C - 1):
            JA = np.zeros((n, 3, 6))
            sel = self.campaign == c
            JA[sel, :, 0:3] = -np.eye(3)
            JA[sel, :, 3:6] = _skew(pm[sel])
            cols.append(JA)
        Jall = np.concatenate(cols, axis=2) * self.w[:, :, None]
        r = (p - pm) * self.w
        return r[self.mask].reshape(-1), Jall[self.mask].reshape(-1, Jall.shape[2])

    def solve(self, theta: np.ndarray, A: list[np.ndarray]) -> tuple[np.ndarray, list[np.ndarray], int]:
        """Gauss-Newton (with step halving) on the joint problem from ``theta`` and ``A``; returns
        the parameters, the transforms and the steps taken."""
        theta, A = theta.copy(), [a.copy() for a in A]
        k = len(self.idx)
        cost = self.cost(theta, A)
        for it in range(1, CAMPAIGN_GN_MAX_ITER + 1):
            r, J = self.jacobian(theta, A)
            norm = np.maximum(np.linalg.norm(J, axis=0), 1e-300)
            d = -np.linalg.lstsq(J / norm, r, rcond=CAMPAIGN_COV_RCOND)[0] / norm
            step = 1.0
            for _h in range(CAMPAIGN_GN_HALVINGS):
                th_n = theta.copy()
                th_n[self.idx] += step * d[:k]
                A_n = [
                    perturbed(A[c], step * d[k + 6 * c : k + 6 * c + 3], step * d[k + 6 * c + 3 : k + 6 * c + 6])
                    for c in range(self.C - 1)
                ] + [A[-1]]
                cost_n = self.cost(th_n, A_n)
                if cost_n <= cost:
                    break
                step /= 2.0
            else:
                return theta, A, it
            dA = d[k:].reshape(-1, 6) * step if self.C > 1 else np.zeros((0, 6))
            theta, A, cost = th_n, A_n, cost_n
            if np.all(np.linalg.norm(dA[:, :3], axis=1) < CAMPAIGN_GN_TOL_RATIO * CAMPAIGN_TOL_M) and np.all(
                np.linalg.norm(dA[:, 3:], axis=1) < CAMPAIGN_GN_TOL_RATIO * CAMPAIGN_TOL_RAD
            ):
                return theta, A, it
        return theta, A, CAMPAIGN_GN_MAX_ITER


def _registration_params(base2meas: np.ndarray, around: np.ndarray) -> np.ndarray:
    """``[reg.t (m), reg.w (Cayley)]`` of a registration ``base2meas`` with the correction around
    the rotation ``around`` (3, 3)."""
    return np.concatenate([base2meas[:3, 3], fx.cayley_vector(base2meas[:3, :3] @ around.T)])


def campaign_registration(model: ArmModel, x: np.ndarray, A: np.ndarray | None) -> np.ndarray:
    """Registration of a campaign (4, 4) from the model's reference registration perturbed by
    ``x[:6]`` (``reg.t``, ``reg.w`` of the model) and, for a non-reference campaign, its transform
    ``A`` (its frame -> the reference frame) perturbed by ``x[6:12]`` (``dt``, ``dphi``)."""
    theta = model.theta.copy()
    theta[fx.GROUP_SLICES["reg.t"]] += x[0:3]
    theta[fx.GROUP_SLICES["reg.w"]] += x[3:6]
    B = transform(fx.cayley_np(theta[fx.GROUP_SLICES["reg.w"]]) @ model.R0, theta[fx.GROUP_SLICES["reg.t"]])
    if A is None:
        return B
    return invert(perturbed(A, x[6:9], x[9:12])) @ B


def registration_jacobian(model: ArmModel, n: int, A: np.ndarray | None) -> np.ndarray:
    """Jacobian (6, n) of a campaign's registration parameters ``[reg.t, reg.w]`` (around its own rotation)
    w.r.t. ``[reg.t, reg.w of the model, (dt, dphi of A)]`` (``n`` = 6, or 12 for a non-reference campaign),
    by central differences."""
    x0 = np.zeros(n)
    B0 = campaign_registration(model, x0, A)
    G = np.zeros((6, n))
    for j in range(n):
        e = np.zeros(n)
        e[j] = REG_FD_STEP
        hi = _registration_params(campaign_registration(model, x0 + e, A), B0[:3, :3])
        lo = _registration_params(campaign_registration(model, x0 - e, A), B0[:3, :3])
        G[:, j] = (hi - lo) / (2.0 * REG_FD_STEP)
    return G


def registration_cov(model: ArmModel, cov: np.ndarray, A: np.ndarray | None) -> np.ndarray:
    """6x6 covariance of a campaign's registration in ``[reg.t, reg.w]`` around its own rotation,
    from the joint covariance ``cov`` of ``[reg.t, reg.w of the model, (dt, dphi of A)]``."""
    G = registration_jacobian(model, cov.shape[0], A)
    return G @ cov @ G.T


def joint_covariance(joint: JointFit, theta: np.ndarray, A: Sequence[np.ndarray]) -> tuple[np.ndarray, float, int]:
    """``s^2 (J^T J)^-1`` of the joint problem (free parameters, then 6 per non-reference campaign),
    ``s^2`` (weighted residual variance) and the degrees of freedom."""
    r, J = joint.jacobian(theta, A)
    dof = max(r.size - J.shape[1], 1)
    s2 = float(r @ r) / dof
    norm = np.maximum(np.linalg.norm(J, axis=0), 1e-300)
    _u, sv, vt = np.linalg.svd(J / norm, full_matrices=False)
    keep = sv > CAMPAIGN_COV_RCOND * sv[0] if len(sv) else np.zeros(0, dtype=bool)
    V = vt[keep].T / sv[keep]
    cov = (V @ V.T) / np.outer(norm, norm) * s2
    return 0.5 * (cov + cov.T), s2, dof
