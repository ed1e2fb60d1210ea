"""Singularity guards, and the verification of a posture against its task.

The guard factors are the IK family's (:meth:`models.ik.IKSolver.guard_factors`: smooth
functions of q whose signs are the branch); :func:`guard_bounds` gives the margins the NLP
keeps them from zero, per kind of factor.  :func:`verify` checks every constraint of a
:class:`~problems.posture.task.PostureTask` at a posture with the model's own forward
kinematics, after the solver.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from models.ik import IKSolver
from models.symbolic import KinematicModel
from models.transforms import rotation_angle
from problems.posture.task import (
    JOINT_TOL_RAD,
    ORIENTATION_TOL_RAD,
    POSITION_TOL_M,
    SINGULAR_DET_MIN,
    SINGULAR_RHO_MIN_M,
    SINGULAR_SIN_MIN,
    OrientationRule,
    PostureTask,
)

#: Margin of each kind of guard factor (see :attr:`models.ik.IKSolver.guard_kinds`).
GUARD_MARGINS = {"length": SINGULAR_RHO_MIN_M, "sine": SINGULAR_SIN_MIN, "det": SINGULAR_DET_MIN}


def singular_factors(ik: IKSolver, q: Any) -> Any:
    """The IK family's guard factors at ``q`` (CasADi (6,) -> (G,), ndarray (..., 6) -> (..., G))."""
    return ik.guard_factors(q)


def guard_bounds(ik: IKSolver) -> np.ndarray:
    """Lower bounds of ``sigma_i * factor_i`` for the family of ``ik``, shape (G,)."""
    return np.array([GUARD_MARGINS[k] for k in ik.guard_kinds])


def _orientation_problems(task: PostureTask, T: np.ndarray) -> tuple[list[str], float]:
    """The orientation rule's check at the TCP poses ``T`` (N, 4, 4), base frame.

    Returns
    -------
    problems : list of str
        At most one line (the worst waypoint).
    residual_rad : float
        Largest orientation residual, rad (0 for ``position_only``).
    """
    out: list[str] = []
    z = T[:, :3, 2]
    a = task.axes
    ang = np.arctan2(np.linalg.norm(np.cross(z, a), axis=1), np.einsum("ij,ij->i", z, a))
    res_rad = 0.0
    if task.rule is OrientationRule.FIXED:
        r = rotation_angle(T[:, :3, :3], task.rotations)
        res_rad = float(r.max())
        if res_rad > ORIENTATION_TOL_RAD:
            k = int(np.argmax(r))
            out.append(f"waypoint {k}: orientation off by {r[k]:.3g} rad > {ORIENTATION_TOL_RAD:g} rad")
    elif task.rule is OrientationRule.FREE_TOOL_AXIS:
        res_rad = float(ang.max())
        if res_rad > ORIENTATION_TOL_RAD:
            k = int(np.argmax(ang))
            out.append(f"waypoint {k}: tool axis off by {ang[k]:.3g} rad > {ORIENTATION_TOL_RAD:g} rad")
    elif task.rule is OrientationRule.CONE:
        over = ang - task.cone_half_angle
        res_rad = float(max(over.max(), 0.0))
        if res_rad > ORIENTATION_TOL_RAD:
            k = int(np.argmax(over))
            out.append(
                f"waypoint {k}: tool axis {math.degrees(ang[k]):.6g} deg from the nominal axis "
                f"> cone half-angle {math.degrees(task.cone_half_angle):g} deg"
            )
    return out, res_rad


def _joint_problems(
    task: PostureTask,
    q: np.ndarray,
    q_min: np.ndarray,
    q_max: np.ndarray,
    ik: IKSolver | None,
    signs: np.ndarray | None,
) -> list[str]:
    """Joint limits (rad), singularity guards (with ``ik`` and ``signs``) and joint steps (rad)
    of ``q`` (N, 6), each with slack :data:`~problems.posture.task.JOINT_TOL_RAD`."""
    out: list[str] = []
    lo = q < q_min - JOINT_TOL_RAD
    hi = q > q_max + JOINT_TOL_RAD
    if lo.any() or hi.any():
        k, j = (int(v) for v in np.argwhere(lo | hi)[0])
        out.append(f"waypoint {k}: joint {j + 1} = {q[k, j]:.6g} rad outside [{q_min[j]:.6g}, {q_max[j]:.6g}]")
    if ik is not None and signs is not None:
        g = ik.guard_factors(q) * signs - guard_bounds(ik)
        if np.any(g < -JOINT_TOL_RAD):
            k, i = (int(v) for v in np.unravel_index(np.argmin(g), g.shape))
            out.append(
                f"waypoint {k}: the {ik.guard_names[i]} guard factor crosses its singularity guard "
                f"(margin {g[k, i]:.3g})"
            )
    if len(q) > 1:
        steps = np.abs(np.diff(q, axis=0))
        if steps.max() > task.max_joint_step + JOINT_TOL_RAD:
            k, j = (int(v) for v in np.unravel_index(np.argmax(steps), steps.shape))
            out.append(
                f"waypoints {k}-{k + 1}: joint {j + 1} steps {steps[k, j]:.4g} rad > {task.max_joint_step:g} rad"
            )
    return out


def verify(
    model: KinematicModel,
    task: PostureTask,
    q: np.ndarray,
    q_min: np.ndarray,
    q_max: np.ndarray,
    ik: IKSolver | None = None,
    signs: np.ndarray | None = None,
) -> tuple[list[str], float, float]:
    """Check every constraint of the task at ``q`` (N, 6), rad.

    With ``ik`` and ``signs`` (the branch's guard-factor signs, shape (G,)) the
    singularity guards are checked as well.

    Parameters
    ----------
    model : KinematicModel
        Its forward kinematics (base frame) is the reference.
    task : PostureTask
    q : ndarray, shape (N, 6)
        Joint angles, rad.
    q_min, q_max : ndarray, shape (6,)
        Joint limits, rad.
    ik : IKSolver, optional
    signs : ndarray, shape (G,), optional

    Returns
    -------
    problems : list of str
        One line per violated constraint (empty if all hold), in the order position,
        orientation, joint limits, singularity guards, joint steps.
    residual_m, residual_rad : float
        Largest position residual (m) and orientation residual (rad).
    """
    out: list[str] = []
    T = model.tcp(q) if q.shape[0] > 1 else model.tcp(q[0])[None]
    e = np.linalg.norm(T[:, :3, 3] - task.positions, axis=1)
    k = int(np.argmax(e))
    if e[k] > POSITION_TOL_M:
        out.append(f"waypoint {k}: TCP {e[k]:.3g} m from the waypoint > {POSITION_TOL_M:g} m")
    orientation, res_rad = _orientation_problems(task, T)
    out += orientation
    out += _joint_problems(task, q, q_min, q_max, ik, signs)
    return out, float(e.max()), res_rad
