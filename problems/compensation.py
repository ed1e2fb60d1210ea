"""Compensation of load-induced TCP error: closed form (paper eqs. 32/47) and exact.

Physics (joint-compliance model, see ``docs/conventions.md``): a joint command
``q_c`` under a wrench ``F`` (base frame, on the TCP) settles at the deflected
equilibrium ``q = q_c + dq(q, F)`` with ``dq(q, F) = K^-1 J(q)^T F`` by default.
The deflection is evaluated at the *deflected* pose, since that is where the
load acts.

* **Closed form** (paper eqs. 32/47, sign corrected): predict the TCP deflection
  ``ds = C(q) F`` of the loaded arm (eq. 16) and command ``q_c = q_t - J(q)^+ ds``,
  with ``q_t`` the IK solution of the target.  ``J^+`` is ``J^-1``, or damped least
  squares when the condition number exceeds
  :data:`~models.constants.JACOBIAN_COND_WARN` (reported in ``warnings``).
  The paper's procedure linearises at the pose the loaded arm actually takes
  when commanded ``q_t`` (``linearize_at="deflected"``, the default): this leaves
  a second-order residual, because after compensation the arm settles at another
  pose.  Linearising at ``q_t`` itself (``linearize_at="target"``) gives
  ``J^-1 C F = K^-1 J^T F`` evaluated at the final pose, which for the pure
  linear joint-spring model coincides with the exact solution below (a fact
  documented in ``docs/paper-reproduction.md``); it stops being exact as soon as
  the deflection model is nonlinear (gravity, hardening, lost motion).
* **Exact**: the deflected pose must be ``q_t`` itself (it puts the TCP on the
  target), so ``q_c = q_t - dq(q_t, F)``; then the equilibrium reached from
  ``q_c`` is ``q_t`` (the fixed point is unique while the map is a contraction,
  which is checked by solving it).  The residual is measured, not assumed.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from models.constants import (DLS_DAMPING, EQUILIBRIUM_MAX_ITER, EQUILIBRIUM_STEP_TOL,
                              EXACT_COMPENSATION_TOL, JACOBIAN_COND_WARN)
from models.symbolic import KinematicModel
from models.transforms import rotation_angle

#: ``dq = deflection(q_deflected (N,6), F (N,6) or (6,)) -> (N,6)`` rad.
DeflectionFn = Callable[[np.ndarray, np.ndarray], np.ndarray]


class CompensationStatus(enum.Enum):
    OK = "ok"
    WARNING = "warning"          # succeeded with a caveat (e.g. DLS near a singularity)
    NOT_CONVERGED = "not_converged"
    FAILED = "failed"


@dataclass
class EquilibriumResult:
    """Deflected equilibrium ``q = q_c + dq(q, F)`` for N commands.

    Attributes
    ----------
    q : ndarray, shape (N, 6)
        Deflected joint angles, rad.
    converged : ndarray of bool, shape (N,)
    iterations : int
    """

    q: np.ndarray
    converged: np.ndarray
    iterations: int


@dataclass
class CompensationResult:
    """Outcome of a compensation over N waypoints.

    Attributes
    ----------
    method : str
        ``"closed_form"`` or ``"exact"``.
    q_command : ndarray, shape (N, 6)
        Compensated joint commands, rad.
    q_deflected : ndarray, shape (N, 6)
        Equilibrium actually reached from ``q_command`` under the load, rad.
    error_m : ndarray, shape (N, 3)
        TCP position error (reached - target), base frame, m.
    error_rad : ndarray, shape (N,)
        TCP orientation error angle, rad.
    status : CompensationStatus
    reason : str
    warnings : list of str
    jacobian_cond : ndarray, shape (N,)
        Condition number of J at the target configuration.
    """

    method: str
    q_command: np.ndarray
    q_deflected: np.ndarray
    error_m: np.ndarray
    error_rad: np.ndarray
    status: CompensationStatus
    reason: str
    warnings: list[str] = field(default_factory=list)
    jacobian_cond: np.ndarray | None = None

    @property
    def error_norm_m(self) -> np.ndarray:
        """(N,) Euclidean TCP position error, m."""
        return np.linalg.norm(self.error_m, axis=1)

    def stats_mm(self) -> dict[str, float]:
        """Max and RMS of the Euclidean TCP position error, mm (the summary.json form)."""
        e = self.error_norm_m * 1e3
        return {"max_mm": float(e.max()), "rms_mm": float(np.sqrt(np.mean(e ** 2)))}


def linear_deflection(model: KinematicModel) -> DeflectionFn:
    """The joint-compliance deflection ``dq = K^-1 J(q)^T F`` of a model."""
    def dq(q: np.ndarray, F: np.ndarray) -> np.ndarray:
        return model.batch(model.joint_deflection, q, F)[0]
    return dq


def equilibrium(q_command: np.ndarray, wrench: np.ndarray, deflection: DeflectionFn,
                max_iter: int = EQUILIBRIUM_MAX_ITER, tol: float = EQUILIBRIUM_STEP_TOL) -> EquilibriumResult:
    """Solve ``q = q_c + dq(q, F)`` by fixed-point iteration (vectorised over N).

    The map is a contraction with factor ``|K^-1 d(J^T F)/dq|`` (about 1e-2 for
    the paper's arm and load), so a few iterations reach machine precision.

    Parameters
    ----------
    q_command : ndarray, shape (N, 6), rad
    wrench : ndarray, shape (6,) or (N, 6); [N, N*m], base frame, on the TCP
    deflection : callable
        ``dq(q, F)``, see :data:`DeflectionFn`.
    """
    qc = np.atleast_2d(np.asarray(q_command, dtype=float))
    q = qc + deflection(qc, wrench)
    converged = np.zeros(len(qc), dtype=bool)
    it = 0
    for it in range(1, max_iter + 1):
        q_new = qc + deflection(q, wrench)
        step = np.max(np.abs(q_new - q), axis=1)
        q = q_new
        converged = step <= tol
        if converged.all():
            break
    return EquilibriumResult(q=q, converged=converged, iterations=it)


def _errors(model: KinematicModel, q_reached: np.ndarray, base2target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    T = model.tcp(q_reached)
    return T[:, :3, 3] - base2target[:, :3, 3], rotation_angle(T[:, :3, :3], base2target[:, :3, :3])


def uncompensated(model: KinematicModel, q_target: np.ndarray, wrench: np.ndarray,
                  deflection: DeflectionFn | None = None) -> CompensationResult:
    """Command the target configuration as is; the load deflects the TCP."""
    dfl = deflection or linear_deflection(model)
    qt = np.atleast_2d(q_target)
    eq = equilibrium(qt, wrench, dfl)
    e, r = _errors(model, eq.q, model.tcp(qt))
    status = CompensationStatus.OK if eq.converged.all() else CompensationStatus.NOT_CONVERGED
    return CompensationResult("none", qt.copy(), eq.q, e, r, status,
                              "no compensation" if eq.converged.all() else "equilibrium did not converge")


def closed_form(model: KinematicModel, q_target: np.ndarray, wrench: np.ndarray,
                deflection: DeflectionFn | None = None,
                linearize_at: str = "deflected") -> CompensationResult:
    """First-order compensation ``q_c = q_t - J^-1 C F`` (paper eqs. 32/47, sign corrected).

    Parameters
    ----------
    q_target : ndarray, shape (N, 6)
        Configurations that put the unloaded TCP on the targets, rad.
    wrench : ndarray, shape (6,) or (N, 6)
        [f (N); m (N*m)], base frame, on the TCP.
    linearize_at : {"deflected", "target"}
        Where J and C are evaluated: at the pose the loaded, uncompensated arm
        takes (the paper's procedure) or at the target configuration.
    """
    qt = np.atleast_2d(np.asarray(q_target, dtype=float))
    F = np.broadcast_to(np.asarray(wrench, dtype=float), (len(qt), 6))
    dfl = deflection or linear_deflection(model)
    if linearize_at == "deflected":
        q_lin = equilibrium(qt, F, dfl).q
    elif linearize_at == "target":
        q_lin = qt
    else:
        raise ValueError(f"linearize_at must be 'deflected' or 'target', got {linearize_at!r}")
    J = model.J(q_lin)
    Cs = model.C(q_lin)
    ds = np.einsum("nij,nj->ni", Cs, F)                   # (N, 6) [m; rad]
    cond = np.linalg.cond(J)
    warnings: list[str] = []
    dq = np.empty_like(qt)
    for i in range(len(qt)):
        if cond[i] > JACOBIAN_COND_WARN or not np.isfinite(cond[i]):
            Ji = J[i]
            dq[i] = Ji.T @ np.linalg.solve(Ji @ Ji.T + DLS_DAMPING ** 2 * np.eye(6), ds[i])
            warnings.append(f"waypoint {i}: Jacobian condition number {cond[i]:.3g} > "
                            f"{JACOBIAN_COND_WARN:.0e}; damped least squares used (damping {DLS_DAMPING:g})")
        else:
            dq[i] = np.linalg.solve(J[i], ds[i])
    qc = qt - dq
    eq = equilibrium(qc, F, dfl)
    e, r = _errors(model, eq.q, model.tcp(qt))
    if not eq.converged.all():
        status, reason = CompensationStatus.NOT_CONVERGED, "deflected equilibrium did not converge"
    elif warnings:
        status, reason = CompensationStatus.WARNING, f"{len(warnings)} waypoint(s) near a singularity"
    else:
        status, reason = CompensationStatus.OK, "first-order compensation"
    return CompensationResult("closed_form", qc, eq.q, e, r, status, reason, warnings, cond)


def exact(model: KinematicModel, q_target: np.ndarray, wrench: np.ndarray,
          deflection: DeflectionFn | None = None,
          tol_m: float = EXACT_COMPENSATION_TOL) -> CompensationResult:
    """Exact compensation: commands whose deflected equilibrium is the target.

    ``q_c = q_t - dq(q_t, F)``; the equilibrium reached from ``q_c`` is then
    solved independently and its TCP compared with the target.

    Returns
    -------
    CompensationResult
        Status ``FAILED`` if any residual exceeds ``tol_m`` (m), naming the waypoint.
    """
    qt = np.atleast_2d(np.asarray(q_target, dtype=float))
    F = np.broadcast_to(np.asarray(wrench, dtype=float), (len(qt), 6))
    dfl = deflection or linear_deflection(model)
    qc = qt - dfl(qt, F)
    eq = equilibrium(qc, F, dfl)
    e, r = _errors(model, eq.q, model.tcp(qt))
    en = np.linalg.norm(e, axis=1)
    cond = np.linalg.cond(model.J(qt))
    if not eq.converged.all():
        bad = int(np.argmin(eq.converged))
        return CompensationResult("exact", qc, eq.q, e, r, CompensationStatus.NOT_CONVERGED,
                                  f"waypoint {bad}: deflected equilibrium did not converge "
                                  "(load too large for the joint stiffness?)", [], cond)
    if np.any(en > tol_m):
        bad = int(np.argmax(en))
        return CompensationResult("exact", qc, eq.q, e, r, CompensationStatus.FAILED,
                                  f"waypoint {bad}: residual {en[bad]:.3g} m > {tol_m:g} m", [], cond)
    return CompensationResult("exact", qc, eq.q, e, r, CompensationStatus.OK,
                              f"max residual {en.max():.3g} m", [], cond)
