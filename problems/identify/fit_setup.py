"""Step 1 of an identification: its fixed inputs and the "before" fit.

:func:`setup_fit` builds the rows, weights, folds and torque scales of the data, the initial
registration (Kabsch on the nominal model; the measured frame's start with orientation data) and
the "before" fit (registration and measured point only) that :func:`~.engine.identify` starts
from; :func:`effect_lists` and :func:`known_parts` check ``identify``'s arguments.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from models import effects as fx
from models.effects import GROUP_SLICES, LIBRARY, make_const, make_layout, set_const
from models.effects.joint_error_map import MAP_COMPONENTS
from models.errors import InputError
from models.robot import Robot

from ..measurements import Measurements
from .evaluation import (
    Evaluator,
    FitProblem,
    evaluator_for,
    make_rows,
    row_weights,
    time_reference,
    torque_scale,
    with_orientation_rows,
)
from .identifiability import Known, priority_order
from .lsq import ModelFit, evaluate, jacobian, kabsch, levenberg_marquardt
from .orientation import measured_frame_start
from .results import DataError, Progress
from .selection_scores import assign_folds


#: Parts of the set-up that can be declared known (``identify(known=...)``).
KNOWN_PARTS = ("registration", "measured_point")


@dataclass
class FitSetup:
    """Fixed inputs of one identification and its "before" fit.

    Attributes
    ----------
    prob : FitProblem
    theta : ndarray, shape (N_PARAMS,)
        Start of the declared model (registration and measured point of the "before" fit).
    R0 : ndarray, shape (3, 3)
        Kabsch rotation of the registration (identity for registered data).
    tau_s : ndarray, shape (6,)
        Joint torque scales, N*m.
    t_ref : (float, float)
        Time reference ``(t_start, t_span)``, s.
    temp_ref : float
        Mean temperature of the data (20 deg C without a column).
    fit_b : ModelFit
        The "before" fit: the nominal model with only registration and measured point.
    order_b : list of int
        Its free parameters.
    n_poses : int
    total_steps : int
        Progress total.
    """

    prob: FitProblem
    theta: np.ndarray
    R0: np.ndarray
    tau_s: np.ndarray
    t_ref: tuple[float, float]
    temp_ref: float
    fit_b: ModelFit
    order_b: list[int]
    n_poses: int
    total_steps: int


def effect_lists(candidates: Sequence[str] | None, include: Sequence[str]) -> tuple[list[str], list[str], bool]:
    """Candidates, included effects (``outliers`` taken out) and whether the fit is robust."""
    cand = list(LIBRARY if candidates is None else candidates)
    for e in list(cand) + list(include):
        if e not in LIBRARY:
            raise InputError(f"unknown effect '{e}'; library: {', '.join(LIBRARY)}")
    robust = "outliers" in cand or "outliers" in include
    inc = [e for e in include if e != "outliers"]
    cand = [e for e in cand if e != "outliers" and e not in inc]
    return cand, inc, robust


def known_parts(registered: bool, known: Sequence[str], map_components: Sequence[str]) -> Known:
    """The :class:`Known` parts of the set-up of ``identify``'s arguments (checked, as the map
    components)."""
    bad_comp = [c for c in map_components if c not in MAP_COMPONENTS]
    if bad_comp or not map_components:
        raise InputError(
            f"map component(s) {bad_comp or list(map_components)}: expected one or more of {list(MAP_COMPONENTS)}"
        )
    bad_known = [k for k in known if k not in KNOWN_PARTS]
    if bad_known:
        raise InputError(f"known part(s) {bad_known}: expected any of {list(KNOWN_PARTS)}")
    return Known(bool(registered) or "registration" in known, bool(registered) or "measured_point" in known)


def _register(
    m: Measurements,
    n_poses: int,
    ev: Evaluator,
    rows: np.ndarray,
    theta: np.ndarray,
    const: np.ndarray,
    is_pos: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Start the registration from the nominal prediction (Kabsch): its rotation R0 (3, 3) and the
    constants holding it; its translation written into ``theta`` (in place)."""
    if n_poses < 3:
        raise DataError(
            f"{m.source}: {n_poses} distinct pose(s); the registration of the measurement "
            "frame and the measured point need at least 3 poses (many more for a useful fit); "
            "or declare the data registered"
        )
    pred0, _q = ev.measure(rows, theta, const)
    R0, t0 = kabsch(pred0[is_pos], m.p)
    theta[GROUP_SLICES["reg.t"]] = t0
    return R0, set_const(const, "registration.R0", R0)


def _baseline_fit(prob: FitProblem, theta: np.ndarray, known: Known) -> tuple[np.ndarray, ModelFit, list[int]]:
    """The baseline fit (set-up parameters only, stiffness as declared): its parameters, fit and free order."""
    layout = prob.layout
    all_rows = np.ones(prob.m.n, dtype=bool)
    order_b = priority_order(layout, [], known)
    pred_b, q_b = evaluate(prob, theta)
    if not order_b:
        fit_b = ModelFit(
            theta=theta.copy(),
            free=np.zeros(0, dtype=int),
            held={},
            inliers=all_rows.copy(),
            pred=pred_b,
            q_eq=q_b,
            J=jacobian(prob, theta, q_b),
            converged=True,
            iterations=0,
        )
    else:
        order_b = [i for i in order_b if i not in layout.indices(("stiffness.s",))]
        fit_b = levenberg_marquardt(prob, theta, np.asarray(order_b), all_rows, pred_b, q_b)
        theta = fit_b.theta.copy()
    return theta, fit_b, order_b


def setup_fit(robot: Robot, m: Measurements, registered: Known, folds: int, n_cand: int, tick: Progress) -> FitSetup:
    """Step 1: problem inputs, initial registration (and measured frame) and the "before" fit."""
    known = Known.of(registered)
    n_poses = len(np.unique(m.pose_groups()))
    tau_s, knots = torque_scale(robot, m)
    t_ref = time_reference(m)
    temp_ref = float(np.mean(m.temperature)) if m.temperature is not None else fx.THERMAL_REFERENCE_C
    orient = m.rotation is not None
    mx, is_pos = with_orientation_rows(m) if orient else (m, np.ones(m.n, dtype=bool))
    R0 = np.eye(3)
    rows = make_rows(mx, t_ref, temp_ref)
    if orient:
        rows[~is_pos, 14] = 1.0
        rows[~is_pos, 15:18] = mx.rotation[~is_pos]
    const = make_const(robot, R0, tau_s, False, knots=knots)
    if orient:
        const = set_const(const, "measured_frame.on", [1.0])
    layout = make_layout(robot, const)
    ev = evaluator_for(robot, const)
    theta = layout.nominal.copy()
    weights = row_weights(mx, is_pos)
    lower, upper = layout.lower.copy(), layout.upper.copy()  # declared by the effect plug-ins
    fold_idx = assign_folds(mx, folds)
    total_steps = n_cand + 3
    tick("registration", 0, total_steps)
    if not known.registration:
        R0, const = _register(m, n_poses, ev, rows, theta, const, is_pos)
    if orient and not known.measured_point:
        const = set_const(const, "measured_frame.R0", measured_frame_start(robot, m, R0))
    prob = FitProblem(
        m=mx,
        layout=layout,
        ev=ev,
        rows=rows,
        const=const,
        weights=weights,
        folds=fold_idx,
        lower=lower,
        upper=upper,
        is_pos=is_pos,
    )
    theta, fit_b, order_b = _baseline_fit(prob, theta, known)
    return FitSetup(
        prob=prob,
        theta=theta,
        R0=R0,
        tau_s=tau_s,
        t_ref=t_ref,
        temp_ref=temp_ref,
        fit_b=fit_b,
        order_b=order_b,
        n_poses=n_poses,
        total_steps=total_steps,
    )
