"""Compensation of load-induced TCP error under an arm model: closed form (paper eqs. 32/47) and exact.

Physics (:class:`models.arm.ArmModel`, see ``docs/conventions.md``): a joint command
``q_c`` under a load ``L`` (base- and tool-frame wrenches, payload, the arm's own weight
when the model has ``gravity``) settles at the deflected equilibrium
``q = q_c + dq(q, L)`` (:meth:`~models.arm.ArmModel.equilibrium`); the TCP of the loaded
arm is the rigid TCP of ``q`` plus the displacement of effects that do not pass through
the joints (link compliance).  The *target* of a waypoint is the rigid TCP pose of the
planned configuration ``q_t`` under the model's geometry.

* **Closed form** (paper eqs. 32/47, sign corrected): predict the first-order TCP
  deflection ``ds = [J dq + dp]`` at the pose the loaded, uncompensated arm takes
  (``linearize_at="deflected"``, the paper's procedure, the default) or at ``q_t``
  (``"target"``) and command ``q_c = q_t - J^+ ds``; ``J^+`` is ``J^-1``, or damped least
  squares above :data:`~models.constants.JACOBIAN_COND_WARN` (reported).  For linear joint
  springs and a constant base-frame wrench, ``"target"`` equals the exact solution.
* **Exact**: find the deflected configuration ``q*`` whose loaded TCP is the target
  (``q* = q_t`` when no effect displaces the TCP outside the joints; otherwise damped
  Newton on the 6-D pose error), then ``q_c = q* - dq(q*, L)``: the equilibrium reached
  from ``q_c`` is ``q*``.  The equilibrium is then solved independently and its TCP
  compared with the target: the residual is measured, not assumed.

This module is the only compensation engine of the product (plan, compensate, the
report and the identification's checks use it).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

import models.effects as fx
from models.arm import ArmModel, EquilibriumResult
from models.constants import DLS_DAMPING, EXACT_COMPENSATION_TOL, JACOBIAN_COND_WARN
from models.errors import InputError
from models.load import Load, load_rows
from models.robot import Robot
from models.status import Status
from models.transforms import rotation_angle

#: Damped-Newton iterations of the exact compensation's pose solve.
NEWTON_MAX_ITER = 50
#: Newton stops when every joint step is below this (rad).
NEWTON_STEP_TOL = 1e-13

__all__ = [
    "CompensationResult",
    "CompensationStatus",
    "EquilibriumResult",
    "closed_form",
    "equilibrium",
    "exact",
    "rigid_pose_solve",
    "uncompensated",
]


class CompensationStatus(Status):
    """Outcome of a compensation; ``usable``: ``OK`` or ``WARNING`` (the commands may be run)."""

    OK = "ok"
    WARNING = "warning"  # succeeded with a caveat (e.g. DLS near a singularity)
    NOT_CONVERGED = "not_converged"
    FAILED = "failed"

    @property
    def usable(self) -> bool:
        """True if the commands may be run (``OK``, or ``WARNING`` with its caveat)."""
        return self in (CompensationStatus.OK, CompensationStatus.WARNING)


@dataclass
class CompensationResult:
    """Outcome of a compensation over N waypoints.

    Attributes
    ----------
    method : str
        ``"none"``, ``"closed_form"`` or ``"exact"``.
    q_command : ndarray, shape (N, 6)
        Joint commands, rad.
    q_deflected : ndarray, shape (N, 6)
        Equilibrium the model reaches from ``q_command`` under the load, rad.
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
        return {"max_mm": float(e.max()), "rms_mm": float(np.sqrt(np.mean(e**2)))}


def _arm(model: ArmModel | Robot | object) -> ArmModel:
    if isinstance(model, ArmModel):
        return model
    if isinstance(model, Robot):
        return ArmModel.from_robot(model)
    arm = getattr(model, "arm", None)  # a KinematicModel
    if isinstance(arm, ArmModel):
        return arm
    raise InputError(f"model: expected an ArmModel, Robot or KinematicModel, got {type(model).__name__}")


def equilibrium(model: ArmModel | Robot, q_command: np.ndarray, load: Load | np.ndarray) -> EquilibriumResult:
    """The deflected equilibrium of ``q_command`` (see :meth:`models.arm.ArmModel.equilibrium`)."""
    return _arm(model).equilibrium(q_command, load)


def _targets(arm: ArmModel, q: np.ndarray) -> np.ndarray:
    return arm.kinematics.tcp(np.atleast_2d(q)).reshape(-1, 4, 4)


def _errors(
    arm: ArmModel, q_reached: np.ndarray, L: np.ndarray, target2base: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    p, R = arm.loaded_tcp(q_reached, L)
    return p - target2base[:, :3, 3], rotation_angle(R, target2base[:, :3, :3])


def uncompensated(model: ArmModel | Robot, q_target: np.ndarray, load: Load | np.ndarray) -> CompensationResult:
    """Command the target configuration as is; the load deflects the TCP."""
    arm = _arm(model)
    qt = np.atleast_2d(np.asarray(q_target, dtype=float))
    L = load_rows(load, len(qt))
    eq = arm.equilibrium(qt, L)
    e, r = _errors(arm, eq.q, L, _targets(arm, qt))
    status = CompensationStatus.OK if eq.converged.all() else CompensationStatus.NOT_CONVERGED
    return CompensationResult(
        "none",
        qt.copy(),
        eq.q,
        e,
        r,
        status,
        "no compensation" if eq.converged.all() else "equilibrium did not converge",
    )


def closed_form(
    model: ArmModel | Robot, q_target: np.ndarray, load: Load | np.ndarray, linearize_at: str = "deflected"
) -> CompensationResult:
    """First-order compensation ``q_c = q_t - J^-1 ds`` (paper eqs. 32/47, sign corrected).

    Parameters
    ----------
    q_target : ndarray, shape (N, 6)
        Configurations whose rigid TCP is the target, rad.
    load : Load, load rows (N, 19), or a base-frame wrench (6,) / (N, 6)
    linearize_at : {"deflected", "target"}
        Where ``J`` and ``ds`` are evaluated: at the pose the loaded, uncompensated arm
        takes (the paper's procedure) or at the target configuration.
    """
    arm = _arm(model)
    qt = np.atleast_2d(np.asarray(q_target, dtype=float))
    L = load_rows(load, len(qt))
    if linearize_at == "deflected":
        q_lin = arm.equilibrium(qt, L).q
    elif linearize_at == "target":
        q_lin = qt
    else:
        raise InputError(f"linearize_at: expected 'deflected' or 'target', got {linearize_at!r}")
    J = arm.kinematics.J(q_lin).reshape(-1, 6, 6)
    ds = arm.load_error(q_lin, L)  # (N, 6) [m; rad]
    cond = np.linalg.cond(J)
    warnings: list[str] = []
    dq = np.empty_like(qt)
    for i in range(len(qt)):
        if cond[i] > JACOBIAN_COND_WARN or not np.isfinite(cond[i]):
            Ji = J[i]
            dq[i] = Ji.T @ np.linalg.solve(Ji @ Ji.T + DLS_DAMPING**2 * np.eye(6), ds[i])
            warnings.append(
                f"waypoint {i}: Jacobian condition number {cond[i]:.3g} > "
                f"{JACOBIAN_COND_WARN:.0e}; damped least squares used (damping {DLS_DAMPING:g})"
            )
        else:
            dq[i] = np.linalg.solve(J[i], ds[i])
    qc = qt - dq
    eq = arm.equilibrium(qc, L)
    e, r = _errors(arm, eq.q, L, _targets(arm, qt))
    if not eq.converged.all():
        status, reason = CompensationStatus.NOT_CONVERGED, "deflected equilibrium did not converge"
    elif warnings:
        status, reason = CompensationStatus.WARNING, f"{len(warnings)} waypoint(s) near a singularity"
    else:
        status, reason = CompensationStatus.OK, "first-order compensation"
    return CompensationResult("closed_form", qc, eq.q, e, r, status, reason, warnings, cond)


def _stack(R: np.ndarray) -> np.ndarray:
    n = R.shape[0]
    return R.transpose(1, 0, 2).reshape(3, 3 * n)


def _pose_solve(arm: ArmModel, q0: np.ndarray, L: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Damped Newton: joints whose loaded TCP pose is ``target`` (N, 4, 4), from ``q0``."""
    f = arm.kinematics.fn["loaded_pose_error"]
    n = len(q0)
    fm = f.map(n, "thread", 2)
    pt, Rt = target[:, :3, 3].T, _stack(target[:, :3, :3])

    def err(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        e, J = fm(q.T, L.T, pt, Rt)
        return np.asarray(e).T, np.asarray(J).reshape(6, n, 6).transpose(1, 0, 2)

    q = q0.copy()
    mu = np.zeros(n)
    e, J = err(q)
    for _ in range(NEWTON_MAX_ITER):
        JtJ = np.einsum("nki,nkj->nij", J, J)
        Jte = np.einsum("nki,nk->ni", J, e)
        step = -np.linalg.solve(JtJ + (mu**2)[:, None, None] * np.eye(6), Jte[:, :, None])[:, :, 0]
        e_t, J_t = err(q + step)
        better = np.linalg.norm(e_t, axis=1) < np.linalg.norm(e, axis=1)
        q[better] += step[better]
        e[better], J[better] = e_t[better], J_t[better]
        mu = np.where(better, mu / 10.0, np.maximum(mu * 10.0, 1e-6))
        mu[mu < 1e-9] = 0.0
        if (
            np.max(np.abs(step[better]), initial=0.0) < NEWTON_STEP_TOL
            and (better | (np.linalg.norm(e, axis=1) < 1e-12)).all()
        ):
            break
    return q


def rigid_pose_solve(model: ArmModel | Robot, q0: np.ndarray, target2base: np.ndarray) -> np.ndarray:
    """Joints (N, 6) whose *unloaded* TCP under the model's geometry is ``target2base`` (N, 4, 4),
    by damped Newton from ``q0`` (an IK solution of a nearby chain, e.g. the nominal one)."""
    arm = _arm(model)
    q0 = np.atleast_2d(np.asarray(q0, dtype=float))
    return _pose_solve(
        arm,
        q0,
        np.zeros((len(q0), load_rows(np.zeros(6), 1).shape[1])),
        np.asarray(target2base, dtype=float).reshape(-1, 4, 4),
    )


def exact(
    model: ArmModel | Robot,
    q_target: np.ndarray,
    load: Load | np.ndarray,
    tol_m: float = EXACT_COMPENSATION_TOL,
    target2base: np.ndarray | None = None,
) -> CompensationResult:
    """Exact compensation: commands whose deflected, loaded TCP is on the target.

    Parameters
    ----------
    q_target : ndarray, shape (N, 6)
        Configurations whose rigid TCP (model geometry) is the target, rad; with
        ``target2base`` given, the start of the pose solve instead.
    load : Load, load rows (N, 19), or a base-frame wrench (6,) / (N, 6)
    tol_m : float
        Largest position residual accepted, m.
    target2base : ndarray, shape (N, 4, 4), optional
        Target TCP poses (base frame; TCP-frame coordinates -> base-frame coordinates).

    Returns
    -------
    CompensationResult
        Status ``FAILED`` if any residual exceeds ``tol_m``, naming the waypoint.
    """
    arm = _arm(model)
    qt = np.atleast_2d(np.asarray(q_target, dtype=float))
    L = load_rows(load, len(qt))
    target = _targets(arm, qt) if target2base is None else np.asarray(target2base, dtype=float).reshape(-1, 4, 4)
    # an effect that moves the TCP other than through the joints (link compliance, joint tilt)
    displaces = any(fx.EFFECTS[e].overrides("point_displacement") for e in arm.active_effects if e in fx.EFFECTS)
    q_star = _pose_solve(arm, qt, L, target) if (displaces or target2base is not None) else qt
    qc = q_star - arm.load_deflection(q_star, L)
    eq = arm.equilibrium(qc, L)
    e, r = _errors(arm, eq.q, L, target)
    en = np.linalg.norm(e, axis=1)
    cond = np.linalg.cond(arm.kinematics.J(q_star).reshape(-1, 6, 6))
    if not eq.converged.all():
        bad = int(np.argmin(eq.converged))
        return CompensationResult(
            "exact",
            qc,
            eq.q,
            e,
            r,
            CompensationStatus.NOT_CONVERGED,
            f"waypoint {bad}: deflected equilibrium did not converge (load too large for the joint stiffness?)",
            [],
            cond,
        )
    if not np.all(np.isfinite(en)) or np.any(en > tol_m):
        bad = int(np.argmax(np.where(np.isfinite(en), en, np.inf)))
        return CompensationResult(
            "exact",
            qc,
            eq.q,
            e,
            r,
            CompensationStatus.FAILED,
            f"waypoint {bad}: residual {en[bad]:.3g} m > {tol_m:g} m (target at the edge "
            "of the model's reach or near a singularity)",
            [],
            cond,
        )
    return CompensationResult(
        "exact", qc, eq.q, e, r, CompensationStatus.OK, f"max residual {en.max():.3g} m", [], cond
    )
