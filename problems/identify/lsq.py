"""Least squares of the identification: Levenberg-Marquardt and its helpers.

The residual is ``r = (p_model(theta) - p_meas) / sigma`` over the rows of a mask
(measurement frame; weights ``1/sigma`` in 1/m, or ones), the Jacobian comes from
CasADi AD (:class:`~problems.identify.evaluation.Evaluator`), and the steps are
taken on parameters scaled by their typical magnitudes (``ModelLayout.scale``), with
projected steps for bounded parameters.  :func:`fit_model` is one complete fit of
a model with given effects: identifiability, LM, robust exclusion of outliers and a
re-check of identifiability at the solution.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .evaluation import FitProblem
from .identifiability import priority_order, select_identifiable
from .outliers import OUTLIER_MAX_ROUNDS, outlier_mask

#: Levenberg-Marquardt: maximum iterations, initial damping, stop tolerances.
LM_MAX_ITER = 40
LM_LAMBDA0 = 1e-3
LM_COST_RTOL = 1e-9
#: LM convergence: every Gauss-Newton step component below this many standard
#: deviations of its parameter (further steps change nothing the data can resolve) ...
LM_STEP_STD_TOL = 0.2
#: ... or a cost decrease below this fraction of one residual's variance.
LM_COST_SIGMA_TOL = 0.01
#: Ridge added to normal equations (relative to their trace / size), numerical only.
NORMAL_RIDGE = 1e-12


def kabsch(P: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rigid transform ``(R, t)`` minimising ``sum |R P_i + t - Q_i|^2``.

    Parameters
    ----------
    P, Q : ndarray, shape (N, 3)
        Corresponding points (rows), e.g. base-frame model points and measured points, m.

    Returns
    -------
    R : ndarray, shape (3, 3)
        Proper rotation (det +1).
    t : ndarray, shape (3,)
        Translation, same unit as the points.
    """
    pc, qc = P.mean(axis=0), Q.mean(axis=0)
    H = (P - pc).T @ (Q - qc)
    U, _S, Vt = np.linalg.svd(H)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    R = Vt.T @ D @ U.T
    return R, qc - R @ pc


def solve_normal(G: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Solve ``G x = g`` (G symmetric positive semi-definite, (k, k)) with a tiny ridge."""
    n = G.shape[0]
    if n == 0:
        return np.zeros(0)
    ridge = NORMAL_RIDGE * max(np.trace(G) / n, 1e-300)
    try:
        L = np.linalg.cholesky(G + ridge * np.eye(n))
        return np.linalg.solve(L.T, np.linalg.solve(L, g))
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(G, g, rcond=None)[0]


def rms(r: np.ndarray) -> float:
    """Root mean square of every element (per-axis RMS of an (N, 3) residual); NaN if empty."""
    return float(np.sqrt(np.mean(np.square(r)))) if r.size else float("nan")


@dataclass
class ModelFit:
    """A fitted model.

    Attributes
    ----------
    theta : ndarray, shape (N_PARAMS,)
        Parameters, SI.
    free : ndarray of int
        Indices of the fitted parameters.
    held : dict
        Held parameter index -> reason.
    inliers : ndarray of bool, shape (N,)
    pred : ndarray, shape (N, 3)
        Predicted measurement, measurement frame, m.
    q_eq : ndarray, shape (N, 6)
        Equilibrium joints, rad.
    J : ndarray, shape (3N, N_PARAMS) or None
        Jacobian of ``pred`` at ``theta``.
    converged : bool
    iterations : int
    """

    theta: np.ndarray
    free: np.ndarray
    held: dict[int, str]
    inliers: np.ndarray
    pred: np.ndarray
    q_eq: np.ndarray
    J: np.ndarray | None
    converged: bool
    iterations: int

    def residual(self, prob: FitProblem) -> np.ndarray:
        """Unweighted residual ``pred - measured``, (N, 3), m, measurement frame."""
        return self.pred - prob.m.p


def weighted_residual(prob: FitProblem, pred: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Weighted residual of the rows in ``mask``, flattened ``[x0, y0, z0, x1, ...]``."""
    r = (pred - prob.m.p) * prob.weights
    return r[mask].reshape(-1)


def weighted_jacobian(prob: FitProblem, J: np.ndarray, mask: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """Weighted Jacobian of the rows in ``mask`` and columns ``cols``, times the parameter scales."""
    W = prob.weights.reshape(-1)[:, None]
    rows3 = np.repeat(mask, 3)
    return (J[rows3][:, cols] * W[rows3]) * prob.layout.scale[cols][None, :]


def evaluate(prob: FitProblem, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Prediction (N, 3) m and equilibrium joints (N, 6) rad of every row."""
    return prob.ev.measure(prob.rows, theta, prob.const)


def jacobian(prob: FitProblem, theta: np.ndarray, q_eq: np.ndarray) -> np.ndarray:
    """Jacobian (3N, N_PARAMS) of the prediction at ``theta`` (equilibrium ``q_eq``)."""
    _p, J = prob.ev.jacobian(prob.rows, q_eq, theta, prob.const)
    return J


def _param_std(G: np.ndarray, cost: float, n_res: int) -> np.ndarray:
    """Standard deviations (scaled units) of the parameters of the normal matrix ``G``."""
    try:
        var = np.diag(np.linalg.inv(G)) * cost / max(n_res - G.shape[0], 1)
        return np.sqrt(np.maximum(var, 1e-300))
    except np.linalg.LinAlgError:
        return np.full(G.shape[0], np.inf)


def _active(prob: FitProblem, theta: np.ndarray, free: np.ndarray, Js_all: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Positions in ``free`` of the parameters not frozen on a bound this iteration (projected Gauss-Newton).

    A parameter on a bound whose Gauss-Newton step points outwards is frozen.
    """
    G0 = Js_all.T @ Js_all
    gn0 = -solve_normal(G0, Js_all.T @ r)
    th_f = theta[free]
    at_bound = ((th_f <= prob.lower[free]) & (gn0 < 0)) | ((th_f >= prob.upper[free]) & (gn0 > 0))
    return np.flatnonzero(~at_bound)


def _damped_step(
    prob: FitProblem,
    theta: np.ndarray,
    fa: np.ndarray,
    sc: np.ndarray,
    G: np.ndarray,
    g: np.ndarray,
    dG: np.ndarray,
    lam: float,
    mask: np.ndarray,
    cost: float,
) -> tuple[bool, float, tuple[Any, ...]]:
    """Raise the damping until a step of the parameters ``fa`` lowers the cost (at most 12 tries).

    Returns whether one did, the damping reached, and the last trial's parameters, prediction,
    equilibrium, weighted residual and cost.
    """
    improved = False
    trial = p_t = q_t = r_t = None
    c_t = cost
    for _ in range(12):
        step = -solve_normal(G + lam * np.diag(dG), g)
        trial = theta.copy()
        trial[fa] = np.clip(theta[fa] + step * sc, prob.lower[fa], prob.upper[fa])
        p_t, q_t = evaluate(prob, trial)
        r_t = weighted_residual(prob, p_t, mask)
        c_t = float(r_t @ r_t)
        if np.isfinite(c_t) and c_t < cost:
            improved = True
            break
        lam *= 4.0
    return improved, lam, (trial, p_t, q_t, r_t, c_t)


def levenberg_marquardt(
    prob: FitProblem,
    theta0: np.ndarray,
    free: np.ndarray,
    mask: np.ndarray,
    pred0: np.ndarray | None = None,
    q0: np.ndarray | None = None,
    J0: np.ndarray | None = None,
    max_iter: int = LM_MAX_ITER,
) -> ModelFit:
    """Levenberg-Marquardt over the parameters ``free`` on the rows ``mask``.

    Stops when the Gauss-Newton step is below :data:`LM_STEP_STD_TOL` standard
    deviations in every parameter (statistically converged), or the relative cost
    decrease falls below :data:`LM_COST_RTOL` (or :data:`LM_COST_SIGMA_TOL` of one
    residual's variance).  ``pred0, q0, J0``: the prediction, equilibrium and
    Jacobian at ``theta0`` when already known.
    """
    theta = theta0.copy()
    if pred0 is None or q0 is None:
        pred0, q0 = evaluate(prob, theta)
        J0 = None
    pred, q = pred0, q0
    r = weighted_residual(prob, pred, mask)
    cost = float(r @ r)
    J = jacobian(prob, theta, q) if J0 is None else J0
    lam = LM_LAMBDA0
    converged = len(free) == 0
    it = 0
    free = np.asarray(free, dtype=int)
    sc = prob.layout.scale[free]
    for it in range(1, max_iter + 1):  # noqa: B007 - the count is reported after the loop
        if len(free) == 0:
            break
        Js_all = weighted_jacobian(prob, J, mask, free)
        act = _active(prob, theta, free, Js_all, r)
        if len(act) == 0:
            converged = True
            break
        Js = Js_all[:, act]
        G = Js.T @ Js
        g = Js.T @ r
        dG = np.diag(G).copy()
        dG[dG <= 0] = 1.0
        gn = -solve_normal(G, g)
        std = _param_std(G, cost, r.size)
        if np.all(np.abs(gn) <= LM_STEP_STD_TOL * std):
            converged = True
            break
        improved, lam, (trial, p_t, q_t, r_t, c_t) = _damped_step(
            prob, theta, free[act], sc[act], G, g, dG, lam, mask, cost
        )
        if not improved:
            converged = True
            break
        rel = (cost - c_t) / max(cost, 1e-300)
        cost_prev = cost
        theta, pred, q, r, cost = trial, p_t, q_t, r_t, c_t
        J = jacobian(prob, theta, q)
        lam = max(lam / 3.0, 1e-12)
        if rel < LM_COST_RTOL or (cost_prev - cost) < LM_COST_SIGMA_TOL * cost / max(r.size, 1):
            converged = True
            break
    return ModelFit(
        theta=theta,
        free=np.asarray(free, dtype=int),
        held={},
        inliers=mask.copy(),
        pred=pred,
        q_eq=q,
        J=J,
        converged=converged,
        iterations=it,
    )


def fit_model(
    prob: FitProblem,
    theta0: np.ndarray,
    effects: Sequence[str],
    registered: bool,
    mask0: np.ndarray,
    robust: bool = True,
    sigma_hint: float | None = None,
    max_iter: int = LM_MAX_ITER,
    passes: int = 3,
    rounds: int = OUTLIER_MAX_ROUNDS,
) -> ModelFit:
    """Fit the model with ``effects``: identifiability, LM, robust exclusion, and a
    re-check of identifiability at the solution (nonlinear parameters, up to
    ``passes`` times).

    Parameters
    ----------
    theta0 : ndarray, shape (N_PARAMS,)
        Start, SI.
    mask0 : ndarray of bool, shape (N,)
        Rows that may be used (outliers are excluded among them).
    robust : bool
        Exclude outliers (:func:`~problems.identify.outliers.outlier_mask`), up to
        ``rounds`` refits.
    sigma_hint : float, optional
        Residual scale (weighted units) of the identifiability test; default the
        current residual RMS.
    """
    order = priority_order(prob.layout, effects, registered)
    mask = mask0.copy()
    theta = theta0.copy()
    pred, q = evaluate(prob, theta)
    J = jacobian(prob, theta, q)
    fit: ModelFit | None = None
    for _round in range(rounds):
        for _pass in range(passes):
            r = weighted_residual(prob, pred, mask)
            sig = rms(r) if sigma_hint is None else sigma_hint
            Js = weighted_jacobian(prob, J, mask, np.asarray(order, dtype=int))
            kept, held = select_identifiable(Js, order, sig)
            moved = [i for i in held if theta[i] != prob.layout.nominal[i]]
            if moved:
                # a parameter freed in an earlier pass and held now goes back to its nominal value
                # (held means "at its nominal value"), and the model is re-evaluated there
                theta = theta.copy()
                theta[moved] = prob.layout.nominal[moved]
                pred, q = evaluate(prob, theta)
                J = jacobian(prob, theta, q)
            fit = levenberg_marquardt(prob, theta, np.asarray(kept, dtype=int), mask, pred, q, J, max_iter=max_iter)
            fit.held = held
            theta, pred, q = fit.theta, fit.pred, fit.q_eq
            # nonlinear parameters may become identifiable at the solution
            J = fit.J
            Js2 = weighted_jacobian(prob, J, mask, np.asarray(order, dtype=int))
            kept2, _held2 = select_identifiable(Js2, order, rms(weighted_residual(prob, pred, mask)))
            if set(kept2) <= set(kept):
                break
        if not robust:
            break
        new_mask = outlier_mask(prob, pred) & mask0
        if _round > 0:
            # after the first round rows may come back but no new ones leave: trimming a
            # misspecified fit again and again would feed on its own bias
            new_mask |= mask
        if np.array_equal(new_mask, mask):
            break
        mask = new_mask
    assert fit is not None
    fit.inliers = mask
    return fit
