"""6-D data in identification: the measured frame's start, the weighting of orientation rows and
what orientation made identifiable (``docs/identification.md`` section 6b).

Orientation rows (:func:`~.evaluation.with_orientation_rows`) carry the orientation error of the
measured frame, rad; position rows the measured point, m.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from models.effects import GROUP_SLICES, PARAM_NAMES
from models.robot import Robot
from models.transforms import rotvec_to_matrix

from ..measurements import Measurements
from .evaluation import FitProblem, nominal_tcp
from .identifiability import Known, select_identifiable
from .lsq import ModelFit, fit_model, rms, weighted_jacobian, weighted_residual


def balance_orientation(
    prob: FitProblem, fit: ModelFit, include: Sequence[str], registered: Known, robust: bool, notes: list[str]
) -> tuple[FitProblem, ModelFit]:
    """Without ``sigma_r`` columns, weigh the orientation rows so that the declared model's
    orientation residual counts as much as its position residual (per axis RMS, weighted units),
    then refit; the weight (m/rad) goes into the notes."""
    pos = prob.pos
    R = (fit.pred - prob.m.p) * prob.weights
    rp, rr = rms(R[pos & fit.inliers]), rms(R[~pos & fit.inliers])
    if not (rp > 0 and rr > 0):
        return prob, fit
    w = prob.weights.copy()
    w[~pos] *= rp / rr
    notes.append(
        f"orientation rows weighted {float(np.mean(w[~pos])):.4g} per rad against position rows' "
        f"{float(np.mean(w[pos])):.4g} per m (no sigma_r column: balanced on the declared model's residual; "
        "give sigma_r / sigma_rx.. columns to weigh by the instrument's accuracy)"
    )
    prob = replace(prob, weights=w)
    return prob, fit_model(prob, fit.theta, include, registered, np.ones(prob.m.n, dtype=bool), robust=robust)


def measured_frame_start(robot: Robot, m: Measurements, R0: np.ndarray) -> np.ndarray:
    """Start of the measured frame's rotation to the flange, (3, 3): the rotation closest to the
    mean of ``flange2base(q)^T R0^T R_measured`` over the rows (nominal kinematics)."""
    T = nominal_tcp(robot, m.q)
    R_f = T[:, :3, :3] @ np.asarray(robot.tcp2flange)[:3, :3].T
    R_m = np.array([rotvec_to_matrix(v) for v in m.rotation])
    M = np.einsum("nji,jk,nkl->il", R_f, R0.T, R_m)
    U, _s, Vt = np.linalg.svd(M)
    return U @ np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))]) @ Vt


def orientation_gain(prob: FitProblem, fit: ModelFit, order: Sequence[int]) -> list[str]:
    """Parameters identifiable with the orientation rows that position rows alone would hold."""
    sig = rms(weighted_residual(prob, fit.pred, fit.inliers))
    kept_all, _h = select_identifiable(
        weighted_jacobian(prob, fit.J, fit.inliers, np.asarray(order, dtype=int)), order, sig
    )
    pos_only = fit.inliers & prob.pos
    kept_pos, _h2 = select_identifiable(
        weighted_jacobian(prob, fit.J, pos_only, np.asarray(order, dtype=int)), order, sig
    )
    own = set(range(GROUP_SLICES["tool.r"].start, GROUP_SLICES["tool.r"].stop))
    # the measured frame's own rotation exists only with orientation data: not a gain
    return [PARAM_NAMES[i] for i in kept_all if i not in set(kept_pos) and i not in own]
