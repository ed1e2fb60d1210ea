"""Identification from measured data, residual diagnosis and effect selection.

The engine (see ``docs/identification.md``):

1. **Declared model** -- joint compliances (as the paper), plus for absolute data
   the registration ``base2meas`` (a Cayley-vector correction around a Kabsch
   estimate, and a translation) and the measured point in the flange frame.
2. **Least squares** on the residual ``r = p_model(theta) - p_meas`` of all rows,
   built as one CasADi function mapped over rows; Jacobian by CasADi AD;
   Levenberg-Marquardt on scaled parameters.
3. **Identifiability** -- pivoted Gram-Schmidt on the scaled Jacobian columns in
   priority order (registration, measured point, stiffness, effects in the order
   added): a parameter whose column is (numerically) a combination of earlier ones
   is *held* at its nominal value and reported with the parameters it cannot be
   told apart from; one the data do not excite is held and reported too.
   Covariance ``s^2 (J^T J)^-1`` on the identifiable set.
4. **Robust fit** -- rows whose standardised residual exceeds a Bonferroni
   chi-square bound are excluded and listed (never silently).
5. **Effect selection** -- forward stepwise: every library effect is scored by
   K-fold cross-validated RMS (folds of whole poses) and BIC; the best is accepted
   when the cross-validated RMS drops by a significant factor, BIC decreases, an
   F-test passes and the effect explains a real share of the structure left; the
   loop stops at the noise floor or when nothing is significant.
6. **Diagnostics** -- the final residual is regressed on time, load, load sign,
   each joint angle, gravity torque, temperature, workspace position and pose;
   cross-validated structure that no effect explains is reported as
   ``unexplained``.

Everything here is SI; the library never prints -- progress goes to an optional
callback ``progress(message, done, total)``.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import casadi as ca
import numpy as np
from scipy import stats

from models import effects as fx
from models.arm import ArmModel
from models.arm_file import MODEL_FORMAT, load_model, model_from_robot, model_to_dict, model_toml  # noqa: F401
from models.effects import (
    EFFECTS,
    GROUP_SLICES,
    LIBRARY,
    N_PARAMS,
    PARAM_NAMES,
    ModelLayout,
    get_const,
    make_const,
    make_layout,
    set_const,
)
from models.errors import InputError
from models.robot import Robot
from models.symbolic import KinematicModel

from .compensation import CompensationStatus
from .compensation import exact as exact_compensation
from .measurements import Measurements

# ----------------------------------------------------------------------------------
# Named constants (thresholds of the method)
# ----------------------------------------------------------------------------------

#: Folds of the cross-validation (whole poses are held out together).
CV_FOLDS = 5
#: Seed of the fold assignment (reproducible results).
CV_SEED = 12345
#: A parameter whose scaled Jacobian column keeps less than this fraction of its
#: norm after projection on the columns of higher priority is redundant (held):
#: its variance would be inflated by more than ``1/IDENT_REL_TOL^2`` and its
#: estimate would rest on second-order effects of the model.
IDENT_REL_TOL = 1e-2
#: A parameter whose predicted standard deviation exceeds this many typical
#: magnitudes (``ModelLayout.scale``) is not determined by the data (held).
IDENT_MAX_STD_RATIO = 10.0
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
#: Outlier rejection: family-wise false-alarm probability of the chi-square bound.
OUTLIER_FALSE_ALARM = 0.01
#: At most this fraction of rows may be excluded as outliers; more rows beyond the
#: bound means the model is incomplete, not that the data are bad (then none is).
OUTLIER_MAX_FRACTION = 0.10
#: Tail check of the robust fit: rows with a standardised chi-square (3 dof) above
#: the ``1 - OUTLIER_TAIL_QUANTILE`` quantile but below the outlier bound may number
#: at most ``OUTLIER_TAIL_FACTOR`` times the expected count plus ``OUTLIER_TAIL_SLACK``.
#: A heavy shoulder is tolerated when the rows beyond the bound outnumber it by
#: ``1/OUTLIER_SEPARATION`` (gross errors stand apart from the bulk).
OUTLIER_TAIL_QUANTILE = 1e-3
OUTLIER_TAIL_FACTOR = 3.0
OUTLIER_TAIL_SLACK = 3
OUTLIER_SEPARATION = 0.5
#: Quantile of the squared residual norms that sets the robust scale (with the MAD).
OUTLIER_SCALE_QUANTILE = 0.8
#: An outlier is at least this many robust standard deviations from the bulk, whatever
#: the Bonferroni bound (gross errors, not the shoulder of a slightly heavy bulk).
OUTLIER_MIN_SIGMAS = 8.0
#: Gross errors: this many robust standard deviations from the bulk (scale from a
#: quantile, so a heavy bulk only raises it) are excluded even when the bulk is not
#: Gaussian.
OUTLIER_GROSS_SIGMAS = 20.0
#: Poses with at least this many rows are tested row against row.
OUTLIER_MIN_POSE_ROWS = 3
#: Robust-exclusion refits per model.
OUTLIER_MAX_ROUNDS = 5
#: Acceptance of an effect: the cross-validated RMS must drop by at least this
#: fraction ...
CV_MIN_REL_GAIN = 0.05
#: ... the F-test of the added parameters must pass at this level ...
F_TEST_ALPHA = 1e-3
#: ... and the effect must explain at least this share of the cross-validated
#: residual variance above the noise floor (of the whole variance when the noise
#: floor is unknown): a small partial fit of structure it does not describe is a
#: wrong attribution.
MIN_EXPLAINED_SHARE = 0.30
#: LM iterations of the saturated (all effects) fit: a diagnostic, not an estimate.
SATURATED_MAX_ITER = 8
#: Candidates refined with a full nonlinear fit after the linearised ranking.
REFINE_TOP = 2
#: Among refined candidates, one with fewer parameters whose CV RMS is within this
#: relative margin of the best is preferred (parsimony).
PARSIMONY_REL_TOL = 0.02
#: Stop when the cross-validated RMS is below this multiple of the noise floor.
NOISE_FLOOR_STOP_RATIO = 1.10
#: Diagnostics: family-wise significance level and minimum cross-validated
#: explained fraction of the residual variance for "structure".
DIAG_ALPHA = 1e-3
DIAG_MIN_FRACTION = 0.05
#: Structure is reported as unexplained when a significant diagnostic explains at
#: least this fraction, or the residual RMS exceeds this multiple of a known noise floor.
UNEXPLAINED_MIN_FRACTION = 0.10
UNEXPLAINED_RMS_RATIO = 1.5
#: Temperature range below which ``thermal`` cannot be tested, K.
THERMAL_MIN_RANGE_K = 0.5
#: Compensation: Newton iterations and tolerance on the joint step (rad).
COMPENSATION_MAX_ITER = 50
COMPENSATION_STEP_TOL = 1e-13
#: Compensation fails for a row if the model-predicted residual exceeds this (m).
COMPENSATION_RESIDUAL_TOL = 1e-6
#: The compensation check on a virtual robot avoids poses whose nominal Jacobian
#: condition number exceeds this (targets at the edge of the reach may be
#: unreachable for the true arm).
COMPENSATION_CHECK_MAX_COND = 80.0
#: The parameter of a rotation about the last joint axis (held first when aliased).
LAST_AXIS_ROTATION = "dtheta[6]"

#: Rows of the synthetic design used to tell structural from data-caused
#: unidentifiability.
STRUCTURAL_DESIGN_ROWS = 240

Progress = Callable[[str, int, int], None]


class IdentifyStatus(enum.Enum):
    OK = "ok"                       # the model explains the data (noise floor or no structure left)
    UNEXPLAINED = "unexplained"     # structure remains that no library effect explains
    NOT_CONVERGED = "not_converged"


class DataError(InputError):
    """The data cannot support the identification asked (message names what is missing)."""


# ----------------------------------------------------------------------------------
# Result objects
# ----------------------------------------------------------------------------------

@dataclass
class ParameterEstimate:
    """One model parameter after identification (SI units).

    ``status`` is ``"free"`` (identified), ``"held"`` (kept at ``value``, see
    ``reason``) or ``"inactive"`` (its effect was not added).
    """

    name: str
    effect: str
    value: float
    std: float | None
    unit: str
    status: str
    reason: str = ""


@dataclass
class CandidateScore:
    """Score of one candidate effect at one step of the selection."""

    effect: str
    n_params: int
    cv_rms_m: float | None
    rms_m: float | None
    bic: float | None
    delta_bic: float | None
    f_pvalue: float | None
    explained_share: float | None
    refined: bool = False
    accepted: bool = False
    reason: str = ""
    held: list[str] = field(default_factory=list)


@dataclass
class SelectionStep:
    """One step of the forward selection."""

    index: int
    effects: list[str]
    n_params: int
    rms_m: float
    cv_rms_m: float
    bic: float
    n_excluded: int
    candidates: list[CandidateScore]
    accepted: str | None
    reason: str


@dataclass
class Diagnostic:
    """Cross-validated regression of the residual on one explanatory variable.

    Attributes
    ----------
    variable : str
    explained_fraction : float
        ``1 - CV RSS / RSS`` of the residual (can be negative: no structure).
    p_value : float
        F-test of the regression against a constant.
    significant : bool
    x : ndarray
        The variable (per row), for plots.
    """

    variable: str
    explained_fraction: float
    p_value: float
    significant: bool
    x: np.ndarray | None = None
    description: str = ""
    #: Per-row quantity to plot against ``x`` (None: the residual components), and its label.
    y: np.ndarray | None = None
    y_label: str = ""


#: An identified model is an :class:`models.arm.ArmModel` (the one model of the arm).
IdentifiedModel = ArmModel


@dataclass
class IdentificationResult:
    """Everything ``compplan identify`` reports.

    RMS values are per axis (``sqrt(mean(r_ij^2))`` over rows and x, y, z), m.
    """

    status: IdentifyStatus
    reason: str
    model: IdentifiedModel
    effects_added: list[str]
    history: list[SelectionStep]
    parameters: list[ParameterEstimate]
    rms_before_m: float
    rms_after_m: float
    cv_rms_before_m: float
    cv_rms_after_m: float
    noise_sigma_m: float | None
    noise_source: str
    excluded: list[dict[str, Any]]
    unexplained: dict[str, Any]
    diagnostics: list[Diagnostic]
    identifiability: dict[str, Any]
    residual_before: np.ndarray
    residual_after: np.ndarray
    inliers: np.ndarray
    data: Measurements
    notes: list[str] = field(default_factory=list)
    validation: dict[str, Any] | None = None
    compensation_check: dict[str, Any] | None = None

    @property
    def rms_before_mm(self) -> float:
        return self.rms_before_m * 1e3

    @property
    def rms_after_mm(self) -> float:
        return self.rms_after_m * 1e3


# ----------------------------------------------------------------------------------
# Forward evaluation
# ----------------------------------------------------------------------------------

class Evaluator:
    """Evaluate the model over many rows (CasADi ``map`` with threads), cached per size."""

    THREADS = 2

    def __init__(self, convention: str, eligible: np.ndarray | None = None) -> None:
        el = np.ones(N_PARAMS, dtype=bool) if eligible is None else np.asarray(eligible, dtype=bool)
        self.eligible_idx = np.flatnonzero(el)
        self.fns = fx.identification_functions(convention, tuple(bool(x) for x in el))
        self._maps: dict[tuple[str, int], ca.Function] = {}

    def _map(self, name: str, n: int) -> ca.Function:
        key = (name, n)
        f = self._maps.get(key)
        if f is None:
            f = self.fns[name].map(n, "thread", self.THREADS)
            if len(self._maps) > 16:
                self._maps.clear()
            self._maps[key] = f
        return f

    def measure(self, rows: np.ndarray, theta: np.ndarray, const: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Predicted measurement (N, 3) m and equilibrium joints (N, 6) rad."""
        n = len(rows)
        p, q = self._map("measure", n)(rows.T, theta, const)
        return np.asarray(p).T, np.asarray(q).T

    def jacobian(self, rows: np.ndarray, q_eq: np.ndarray, theta: np.ndarray,
                 const: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Predicted measurement (N, 3) and its Jacobian (3N, N_PARAMS), rows [x0,y0,z0,x1,...]."""
        n = len(rows)
        p, J = self._map("measure_jac", n)(rows.T, q_eq.T, theta, const)
        ne = len(self.eligible_idx)
        Je = np.asarray(J).reshape(3, n, ne).transpose(1, 0, 2).reshape(3 * n, ne)
        if ne == N_PARAMS:
            return np.asarray(p).T, Je
        Jf = np.zeros((3 * n, N_PARAMS))
        Jf[:, self.eligible_idx] = Je
        return np.asarray(p).T, Jf

    def call(self, name: str, *args: np.ndarray) -> list[np.ndarray]:
        """Evaluate a per-row function over rows; 2-D args are (N, k), 1-D are broadcast."""
        n = max(a.shape[0] for a in args if a.ndim == 2)
        ins = [a.T if a.ndim == 2 else a for a in args]
        out = self._map(name, n)(*ins)
        out = out if isinstance(out, (list, tuple)) else [out]
        return [np.asarray(o) for o in out]


_EVALUATORS: dict[tuple, Evaluator] = {}


def evaluator(convention: str, eligible: np.ndarray | None = None) -> Evaluator:
    """Shared :class:`Evaluator` per convention and parameter eligibility."""
    key = (convention, None if eligible is None else tuple(bool(x) for x in eligible))
    ev = _EVALUATORS.get(key)
    if ev is None:
        if len(_EVALUATORS) > 8:
            _EVALUATORS.clear()
        ev = _EVALUATORS[key] = Evaluator(convention, eligible)
    return ev


def _ev_for(robot: Robot) -> Evaluator:
    return evaluator(robot.convention, make_layout(robot).eligible)


def time_reference(m: Measurements) -> tuple[float, float]:
    """``(t_start, t_span)`` of the campaign (row numbers when there is no ``t``).

    Drift is measured from the first measurement, where the instrument (and, for
    registered data, the registration) is taken as exact."""
    t = m.t if m.t is not None else np.arange(m.n, dtype=float)
    lo, hi = float(np.min(t)), float(np.max(t))
    return lo, max(hi - lo, 1e-9)


def make_rows(m: Measurements, time_ref: tuple[float, float] | None, temperature_ref: float,
              use_time: bool = True) -> np.ndarray:
    """Per-row inputs ``[q_c (6), F (6), tn, dT]`` of the CasADi functions, (N, 14)."""
    rows = np.zeros((m.n, fx.ROW_SIZE))
    rows[:, 0:6] = m.q
    rows[:, 6:12] = m.wrench
    if use_time and time_ref is not None:
        t = m.t if m.t is not None else np.arange(m.n, dtype=float)
        rows[:, 12] = (t - time_ref[0]) / time_ref[1]
    temp = m.temperature if m.temperature is not None else np.full(m.n, temperature_ref)
    rows[:, 13] = temp - fx.THERMAL_REFERENCE_C
    return rows


# ----------------------------------------------------------------------------------
# Numerical helpers
# ----------------------------------------------------------------------------------

def kabsch(P: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rigid transform (R, t) minimising ``|R P_i + t - Q_i|`` (rows are points)."""
    pc, qc = P.mean(axis=0), Q.mean(axis=0)
    H = (P - pc).T @ (Q - qc)
    U, _S, Vt = np.linalg.svd(H)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    R = Vt.T @ D @ U.T
    return R, qc - R @ pc


def _solve_normal(G: np.ndarray, g: np.ndarray) -> np.ndarray:
    n = G.shape[0]
    if n == 0:
        return np.zeros(0)
    ridge = NORMAL_RIDGE * max(np.trace(G) / n, 1e-300)
    try:
        L = np.linalg.cholesky(G + ridge * np.eye(n))
        return np.linalg.solve(L.T, np.linalg.solve(L, g))
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(G, g, rcond=None)[0]


def _rms(r: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(r)))) if r.size else float("nan")


@dataclass
class _Problem:
    """Data and fixed inputs of one identification."""

    m: Measurements
    layout: ModelLayout
    ev: Evaluator
    rows: np.ndarray
    const: np.ndarray
    weights: np.ndarray          # (N,) 1/sigma (1/m) or ones
    folds: np.ndarray            # (N,) fold index per row
    lower: np.ndarray            # (P,) bounds
    upper: np.ndarray


@dataclass
class _Fit:
    theta: np.ndarray
    free: np.ndarray             # indices of fitted parameters
    held: dict[int, str]         # index -> reason
    inliers: np.ndarray          # (N,) bool
    pred: np.ndarray             # (N, 3)
    q_eq: np.ndarray             # (N, 6)
    J: np.ndarray | None         # (3N, P) at theta
    converged: bool
    iterations: int

    def residual(self, prob: _Problem) -> np.ndarray:
        """Unweighted residual (N, 3), m."""
        return self.pred - prob.m.p


def _wres(prob: _Problem, pred: np.ndarray, mask: np.ndarray) -> np.ndarray:
    r = (pred - prob.m.p) * prob.weights[:, None]
    return r[mask].reshape(-1)


def _wjac(prob: _Problem, J: np.ndarray, mask: np.ndarray, cols: np.ndarray) -> np.ndarray:
    W = np.repeat(prob.weights, 3)[:, None]
    rows3 = np.repeat(mask, 3)
    return (J[rows3][:, cols] * W[rows3]) * prob.layout.scale[cols][None, :]


# ----------------------------------------------------------------------------------
# Identifiability
# ----------------------------------------------------------------------------------

def select_identifiable(Js: np.ndarray, order: Sequence[int], sigma: float,
                        names: Sequence[str] = PARAM_NAMES) -> tuple[list[int], dict[int, str]]:
    """Pivoted Gram-Schmidt on scaled Jacobian columns in priority order.

    Parameters
    ----------
    Js : ndarray, shape (n, len(order))
        Columns of the weighted residual Jacobian times the parameter scales, in
        the order of ``order``.
    order : sequence of int
        Parameter indices (priority order: earlier ones are kept first).
    sigma : float
        Current residual RMS (weighted units), for the excitation test.

    Returns
    -------
    kept : list of int
        Identifiable parameter indices.
    held : dict
        Held parameter index -> reason (names the parameters it cannot be told
        apart from, or states that the data do not excite it).
    """
    n = Js.shape[0]
    Q = np.zeros((n, 0))
    kept: list[int] = []
    kept_cols: list[int] = []
    held: dict[int, str] = {}
    for k, idx in enumerate(order):
        c = Js[:, k]
        nrm = float(np.linalg.norm(c))
        if nrm == 0.0 or not np.isfinite(nrm):
            held[idx] = "not excited by the data (no sensitivity)"
            continue
        res = c - Q @ (Q.T @ c)
        res = res - Q @ (Q.T @ res)
        rn = float(np.linalg.norm(res))
        if rn < IDENT_REL_TOL * nrm:
            if kept_cols:
                # kept parameters whose (orthogonalised) directions carry the column
                contrib = np.abs(Q.T @ c)
                top = np.argsort(contrib)[::-1][:4]
                alias = [names[kept[j]] for j in top if contrib[j] > 0.05 * contrib.max()]
                held[idx] = "cannot be told apart from " + ", ".join(alias)
            else:
                held[idx] = "not excited by the data"
            continue
        if sigma > 0 and sigma / rn > IDENT_MAX_STD_RATIO:
            held[idx] = (f"not determined by the data (predicted std {sigma / rn:.3g} typical magnitudes > "
                         f"{IDENT_MAX_STD_RATIO:g})")
            continue
        Q = np.column_stack([Q, res / rn])
        kept.append(idx)
        kept_cols.append(k)
    return kept, held


# ----------------------------------------------------------------------------------
# Least squares
# ----------------------------------------------------------------------------------

def _evaluate(prob: _Problem, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return prob.ev.measure(prob.rows, theta, prob.const)


def _jac(prob: _Problem, theta: np.ndarray, q_eq: np.ndarray) -> np.ndarray:
    _p, J = prob.ev.jacobian(prob.rows, q_eq, theta, prob.const)
    return J


def _order_for(layout: ModelLayout, effects: Sequence[str], registered: bool) -> list[int]:
    """Parameter indices in priority order: registration, point, stiffness, effects."""
    order: list[int] = []
    if not registered:
        order += list(layout.indices(("reg.t", "reg.w", "tool.p")))
    order += list(layout.indices(("stiffness.s",)))
    for e in effects:
        for i in layout.effect_indices(e):
            if i not in order:
                order.append(int(i))
    # The rotation of the flange about the last joint axis is what position data of a point
    # near that axis cannot see: its sensitivity is the point's distance from the axis, and it
    # then aliases with dalpha[6] and da[6], which move the point the same way.  Last in
    # priority, it is the one held, so the identified flange is not turned about the tool axis
    # (which would turn the tool frame, and every tool-frame load and payload with it).
    last = [i for i in order if PARAM_NAMES[i] == LAST_AXIS_ROTATION]
    return [i for i in order if i not in last] + last


def _lm(prob: _Problem, theta0: np.ndarray, free: np.ndarray, mask: np.ndarray,
        pred0: np.ndarray | None = None, q0: np.ndarray | None = None, J0: np.ndarray | None = None,
        max_iter: int = LM_MAX_ITER) -> _Fit:
    """Levenberg-Marquardt over the parameters ``free`` on the rows ``mask``.

    Stops when the Gauss-Newton step is below :data:`LM_STEP_STD_TOL` standard
    deviations in every parameter (statistically converged), or the relative cost
    decrease falls below :data:`LM_COST_RTOL`.
    """
    theta = theta0.copy()
    if pred0 is None or q0 is None:
        pred0, q0 = _evaluate(prob, theta)
        J0 = None
    pred, q = pred0, q0
    r = _wres(prob, pred, mask)
    cost = float(r @ r)
    J = _jac(prob, theta, q) if J0 is None else J0
    lam = LM_LAMBDA0
    converged = len(free) == 0
    it = 0
    free = np.asarray(free, dtype=int)
    sc = prob.layout.scale[free]
    for it in range(1, max_iter + 1):
        if len(free) == 0:
            break
        Js_all = _wjac(prob, J, mask, free)
        # active bounds: parameters on a bound whose Gauss-Newton step points outwards are
        # frozen for this iteration (projected Gauss-Newton)
        G0 = Js_all.T @ Js_all
        gn0 = -_solve_normal(G0, Js_all.T @ r)
        th_f = theta[free]
        at_bound = (((th_f <= prob.lower[free]) & (gn0 < 0)) | ((th_f >= prob.upper[free]) & (gn0 > 0)))
        act = np.flatnonzero(~at_bound)
        if len(act) == 0:
            converged = True
            break
        Js = Js_all[:, act]
        G = Js.T @ Js
        g = Js.T @ r
        dG = np.diag(G).copy()
        dG[dG <= 0] = 1.0
        gn = -_solve_normal(G, g)
        try:
            var = np.diag(np.linalg.inv(G)) * cost / max(r.size - len(act), 1)
            std = np.sqrt(np.maximum(var, 1e-300))
        except np.linalg.LinAlgError:
            std = np.full(len(act), np.inf)
        if np.all(np.abs(gn) <= LM_STEP_STD_TOL * std):
            converged = True
            break
        improved = False
        fa = free[act]
        for _ in range(12):
            step = -_solve_normal(G + lam * np.diag(dG), g)
            trial = theta.copy()
            trial[fa] = np.clip(theta[fa] + step * sc[act], prob.lower[fa], prob.upper[fa])
            p_t, q_t = _evaluate(prob, trial)
            r_t = _wres(prob, p_t, mask)
            c_t = float(r_t @ r_t)
            if np.isfinite(c_t) and c_t < cost:
                improved = True
                break
            lam *= 4.0
        if not improved:
            converged = True
            break
        rel = (cost - c_t) / max(cost, 1e-300)
        cost_prev = cost
        theta, pred, q, r, cost = trial, p_t, q_t, r_t, c_t
        J = _jac(prob, theta, q)
        lam = max(lam / 3.0, 1e-12)
        if rel < LM_COST_RTOL or (cost_prev - cost) < LM_COST_SIGMA_TOL * cost / max(r.size, 1):
            converged = True
            break
    return _Fit(theta=theta, free=np.asarray(free, dtype=int), held={}, inliers=mask.copy(), pred=pred, q_eq=q,
                J=J, converged=converged, iterations=it)


def _robust_d2(r: np.ndarray) -> np.ndarray:
    """Squared robust standardised norms of 3-D residual rows (chi-square, 3 dof, under H0).

    The scale is the larger of the median-absolute-deviation scale and the one implied
    by the :data:`OUTLIER_SCALE_QUANTILE` quantile of the squared norms, so that a
    bulk slightly heavier than Gaussian (model error) does not put its shoulder
    beyond the bound; both ignore up to 20 % contamination.
    """
    med = np.median(r, axis=0)
    s_mad = 1.4826 * np.median(np.abs(r - med))
    raw = np.sum(np.square(r - med), axis=1)
    s2_q = float(np.quantile(raw, OUTLIER_SCALE_QUANTILE)) / stats.chi2.ppf(OUTLIER_SCALE_QUANTILE, df=3)
    s2 = max(s_mad ** 2, s2_q)
    if not np.isfinite(s2) or s2 <= 0:
        return np.zeros(len(r))
    return raw / s2


def _outlier_mask(prob: _Problem, pred: np.ndarray, gross_only: bool = False) -> np.ndarray:
    """Inlier mask of the robust fit.

    Rows of a pose measured at least :data:`OUTLIER_MIN_POSE_ROWS` times are tested
    against the other rows of their pose (the residual minus the median of the
    others), so that pose-level model error -- shared by every row of a pose -- is
    never mistaken for bad measurements and gross errors show even while the model
    is still incomplete; other rows are tested against all rows.  Scales are robust
    (median absolute deviation); the bound is the Bonferroni chi-square quantile
    (3 dof, family-wise false alarm :data:`OUTLIER_FALSE_ALARM`), and at least
    :data:`OUTLIER_MIN_SIGMAS` robust standard deviations.

    Contamination presumes a Gaussian bulk: when the band between the
    ``1 - OUTLIER_TAIL_QUANTILE`` quantile and the Bonferroni bound holds many more
    rows than chance allows (and not clearly fewer than lie beyond the bound), the
    residual is model error with heavy tails and only gross errors
    (:data:`OUTLIER_GROSS_SIGMAS`) are called outliers; none are when more than
    :data:`OUTLIER_MAX_FRACTION` of the rows would be.  ``gross_only``: only gross
    errors (used when the residual is known to hold structure the model lacks).
    """
    r = (pred - prob.m.p) * prob.weights[:, None]
    n = len(r)
    bonf = stats.chi2.isf(OUTLIER_FALSE_ALARM / max(n, 1), df=3)
    bound = max(bonf, OUTLIER_MIN_SIGMAS ** 2)
    lo = stats.chi2.isf(OUTLIER_TAIL_QUANTILE, df=3)
    out = np.zeros(n, dtype=bool)
    groups = prob.m.pose_groups()
    _ug, inv, counts = np.unique(groups, return_inverse=True, return_counts=True)
    multi = counts[inv] >= OUTLIER_MIN_POSE_ROWS

    def test(d2: np.ndarray) -> np.ndarray:
        gross = d2 > OUTLIER_GROSS_SIGMAS ** 2
        mid = int(np.sum((d2 > lo) & (d2 <= bonf)))
        above = int(np.sum(d2 > bound))
        heavy = mid > OUTLIER_TAIL_FACTOR * len(d2) * OUTLIER_TAIL_QUANTILE + OUTLIER_TAIL_SLACK
        separated = mid <= OUTLIER_SEPARATION * above
        if gross_only or (heavy and not separated):
            return gross
        return d2 > bound

    if multi.any():
        dev = np.zeros_like(r)
        for g in np.flatnonzero(counts >= OUTLIER_MIN_POSE_ROWS):
            idx = np.flatnonzero(inv == g)
            for i in idx:
                dev[i] = r[i] - np.median(r[idx[idx != i]], axis=0)
        out[multi] = test(_robust_d2(dev[multi]))
    if (~multi).any():
        out[~multi] = test(_robust_d2(r[~multi]))
    if out.sum() > int(OUTLIER_MAX_FRACTION * n):
        return np.ones(n, dtype=bool)
    return ~out


def _fit_model(prob: _Problem, theta0: np.ndarray, effects: Sequence[str], registered: bool,
               mask0: np.ndarray, robust: bool = True, sigma_hint: float | None = None,
               max_iter: int = LM_MAX_ITER, passes: int = 3, rounds: int = OUTLIER_MAX_ROUNDS) -> _Fit:
    """Fit the model with ``effects``: identifiability, LM, robust exclusion, and a
    re-check of identifiability at the solution (nonlinear parameters, up to
    ``passes`` times)."""
    order = _order_for(prob.layout, effects, registered)
    mask = mask0.copy()
    theta = theta0.copy()
    pred, q = _evaluate(prob, theta)
    J = _jac(prob, theta, q)
    fit: _Fit | None = None
    for _round in range(rounds):
        for _pass in range(passes):
            r = _wres(prob, pred, mask)
            sig = _rms(r) if sigma_hint is None else sigma_hint
            Js = _wjac(prob, J, mask, np.asarray(order, dtype=int))
            kept, held = select_identifiable(Js, order, sig)
            fit = _lm(prob, theta, np.asarray(kept, dtype=int), mask, pred, q, J, max_iter=max_iter)
            fit.held = held
            theta, pred, q = fit.theta, fit.pred, fit.q_eq
            # nonlinear parameters may become identifiable at the solution
            J = fit.J
            Js2 = _wjac(prob, J, mask, np.asarray(order, dtype=int))
            kept2, _held2 = select_identifiable(Js2, order, _rms(_wres(prob, pred, mask)))
            if set(kept2) <= set(kept):
                break
        if not robust:
            break
        new_mask = _outlier_mask(prob, pred) & mask0
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


# ----------------------------------------------------------------------------------
# Cross-validation and scores
# ----------------------------------------------------------------------------------

@dataclass
class _Score:
    rss: float             # weighted, in-sample (linearised)
    cv_rss: float          # weighted
    cv_rms_m: float        # unweighted per-axis RMS of held-out residuals
    rms_m: float           # unweighted in-sample per-axis RMS
    n: int                 # residual scalars
    k: int                 # free parameters

    @property
    def bic(self) -> float:
        return self.n * math.log(max(self.rss, 1e-300) / self.n) + self.k * math.log(self.n)


def _linear_scores(prob: _Problem, J: np.ndarray, pred: np.ndarray, mask: np.ndarray,
                   cols: np.ndarray, shift: np.ndarray | None = None) -> _Score:
    """In-sample and K-fold CV scores of the model linearised at the current point.

    The full-data Gauss-Newton step and one per fold (fold rows removed) are taken
    from the same Jacobian; held-out residuals are predicted linearly.  At a
    least-squares optimum this is the standard linearised cross-validation; for a
    candidate whose parameters start at their nominal values it is the one-step
    Gauss-Newton fit.
    """
    r = _wres(prob, pred, mask)
    if shift is not None:
        # parameters moved by ``shift`` (linearly), e.g. an effect removed
        nz = np.flatnonzero(shift)
        r = r + _wjac(prob, J, mask, nz) @ (shift[nz] / prob.layout.scale[nz])
    w3 = np.repeat(prob.weights[mask], 3)
    Js = _wjac(prob, J, mask, cols)
    G = Js.T @ Js
    g = Js.T @ r
    step = -_solve_normal(G, g)
    r_in = r + Js @ step
    folds3 = np.repeat(prob.folds[mask], 3)
    cv_rss = 0.0
    cv_un = 0.0
    for k in np.unique(folds3):
        sel = folds3 == k
        Jk, rk = Js[sel], r[sel]
        Gk = G - Jk.T @ Jk
        gk = g - Jk.T @ rk
        dk = -_solve_normal(Gk, gk)
        ek = rk + Jk @ dk
        cv_rss += float(ek @ ek)
        cv_un += float(np.sum(np.square(ek / w3[sel])))
    n = r.size
    return _Score(rss=float(r_in @ r_in), cv_rss=cv_rss, cv_rms_m=math.sqrt(cv_un / n),
                  rms_m=math.sqrt(float(np.sum(np.square(r_in / w3))) / n), n=n, k=len(cols))


def _assign_folds(m: Measurements, k: int, seed: int = CV_SEED) -> np.ndarray:
    groups = m.pose_groups()
    ug = np.unique(groups)
    rng = np.random.default_rng(seed)
    perm = rng.permutation(len(ug))
    kk = max(2, min(k, len(ug)))
    fold_of_group = np.empty(len(ug), dtype=int)
    fold_of_group[perm] = np.arange(len(ug)) % kk
    lookup = {g: fold_of_group[i] for i, g in enumerate(ug)}
    return np.array([lookup[g] for g in groups], dtype=int)


# ----------------------------------------------------------------------------------
# Noise floor
# ----------------------------------------------------------------------------------

def noise_floor(m: Measurements) -> tuple[float | None, str]:
    """Per-axis measurement noise (m) and where it comes from.

    ``sigma`` column (RMS of the declared values), else repeated measurements
    (rows with the same pose and the same wrench: pooled within-group scatter),
    else unknown.
    """
    if m.sigma is not None:
        return float(np.sqrt(np.mean(m.sigma ** 2))), "sigma column"
    groups = m.pose_groups()
    key = np.column_stack([groups, np.round(m.wrench, 9)])
    _u, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    inv = np.asarray(inv).reshape(-1)
    rep = counts[inv] > 1
    if rep.sum() >= 6 and m.p is not None:
        ss, dof = 0.0, 0
        for g in np.unique(inv[rep]):
            P = m.p[inv == g]
            ss += float(np.sum(np.square(P - P.mean(axis=0))))
            dof += 3 * (len(P) - 1)
        if dof >= 6:
            return math.sqrt(ss / dof), f"repeated measurements ({dof // 3} degrees of freedom per axis)"
    return None, "unknown (no sigma column, no repeated measurements)"


# ----------------------------------------------------------------------------------
# Diagnostics
# ----------------------------------------------------------------------------------

def _fourier(x: np.ndarray, order: int = 3) -> np.ndarray:
    return np.column_stack([f(k * x) for k in range(1, order + 1) for f in (np.sin, np.cos)])


def _poly(x: np.ndarray, deg: int) -> np.ndarray:
    s = np.std(x)
    z = (x - np.mean(x)) / (s if s > 0 else 1.0)
    return np.column_stack([z ** k for k in range(1, deg + 1)])


def _scalar_design(B: np.ndarray) -> np.ndarray:
    """Scalar basis (n, b) with a free 3-D coefficient each -> vector design (n, 3, 3b)."""
    n, b = B.shape
    X = np.zeros((n, 3, 3 * b))
    for k in range(3):
        X[:, k, k::3] = B
    return X


def _joint_design(Jp: np.ndarray, j: int, B: np.ndarray) -> np.ndarray:
    """Joint-error design: column j of the positional Jacobian times each basis function,
    (n, 3, b): the signature of an error of joint j that is a function of the basis."""
    return Jp[:, :, j][:, :, None] * B[:, None, :]


def _regress_cv(R: np.ndarray, X: np.ndarray, folds: np.ndarray) -> tuple[float, float]:
    """CV explained fraction and F-test p-value of residual R (n, 3) on design X (n, 3, b).

    A constant 3-D offset is always part of the model (it is the reference).
    """
    n = len(R)
    X = np.concatenate([_scalar_design(np.ones((n, 1))), X], axis=2)
    b = X.shape[2]
    y = R.reshape(-1)
    A = X.reshape(3 * n, b)
    y0 = (R - R.mean(axis=0)).reshape(-1)
    rss0 = float(y0 @ y0)
    if rss0 <= 0 or b >= 3 * n - 3:
        return 0.0, 1.0
    coef = np.linalg.lstsq(A, y, rcond=None)[0]
    e = y - A @ coef
    rss1 = float(e @ e)
    f3 = np.repeat(folds, 3)
    cv = 0.0
    for k in np.unique(folds):
        tr, te = f3 != k, f3 == k
        c = np.linalg.lstsq(A[tr], y[tr], rcond=None)[0]
        cv += float(np.sum((y[te] - A[te] @ c) ** 2))
    rank = np.linalg.matrix_rank(A)
    df1, df2 = max(rank - 3, 1), 3 * n - rank
    if rss1 <= 0 or df2 <= 0:
        return 1.0 - cv / rss0, 0.0
    F = ((rss0 - rss1) / df1) / (rss1 / df2)
    return 1.0 - cv / rss0, float(stats.f.sf(F, df1, df2))


def diagnostic_variables(m: Measurements, Jp: np.ndarray, tau: np.ndarray, tau_g: np.ndarray | None,
                         p_nominal: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray, str]]:
    """Explanatory variables: name -> (x for plots, design (n, 3, b), description).

    Parameters
    ----------
    Jp : ndarray, shape (n, 3, 6)
        Positional Jacobian of the measured point, measurement frame (m/rad).
    tau : ndarray, shape (n, 6)
        Joint torques of the applied wrench, N*m.
    tau_g : ndarray, shape (n, 6) or None
        Nominal gravity torques, N*m.
    p_nominal : ndarray, shape (n, 3)
        Nominal TCP positions, base frame, m.
    """
    out: dict[str, tuple[np.ndarray, np.ndarray, str]] = {}
    n = m.n
    t = m.t if m.t is not None else np.arange(n, dtype=float)
    if np.ptp(t) > 0:
        out["time"] = (t, _scalar_design(_poly(t, 4)),
                       "time (s, or row number without a t column): polynomial of degree 4 per axis")
    f = m.wrench[:, :3]
    fm = np.linalg.norm(f, axis=1)
    if fm.max() > 0:
        sc = fm.max()
        B = np.column_stack([f / sc, f * fm[:, None] / sc ** 2, f * (fm ** 2)[:, None] / sc ** 3])
        out["load_magnitude"] = (fm, _scalar_design(B),
                                 "applied force |f| (N): f, f|f|, f|f|^2 with free 3-D coefficients")
        sg = np.sign(np.where(np.abs(f) > 1e-6 * sc, f, 0.0))
        ts = np.maximum(np.abs(tau).max(axis=0), 1e-12)
        sgt = np.sign(np.where(np.abs(tau) > 1e-3 * ts, tau, 0.0))
        X = np.concatenate([_scalar_design(sg)] + [_joint_design(Jp, j, sgt[:, j:j + 1]) for j in range(6)], axis=2)
        out["load_sign"] = (sg @ np.array([1.0, 2.0, 4.0]), X,
                            "sign of each force component and of each joint torque")
        X = np.concatenate([_joint_design(Jp, j, np.column_stack([tau[:, j] / ts[j], (tau[:, j] / ts[j]) ** 3]))
                            for j in range(6)], axis=2)
        out["joint_torque"] = (np.abs(tau).max(axis=1), X,
                               "joint deflection as an odd cubic of each joint torque (J_j (a tau_j + b tau_j^3))")
    for j in range(6):
        if np.ptp(m.q[:, j]) > 1e-3:
            B = np.column_stack([np.ones(n), _fourier(m.q[:, j], 3)])
            out[f"q{j + 1}"] = (m.q[:, j], _joint_design(Jp, j, B),
                                (f"joint {j + 1} angle: an error of joint {j + 1} periodic in q{j + 1} "
                                 "(Fourier order 3)"))
    if tau_g is not None:
        cols = [j for j in range(6) if np.ptp(tau_g[:, j]) > 1e-9]
        if cols:
            X = np.concatenate([_joint_design(Jp, j, _poly(tau_g[:, j], 2)) for j in cols], axis=2)
            big = cols[int(np.argmax([np.ptp(tau_g[:, j]) for j in cols]))]
            out["gravity_torque"] = (tau_g[:, big], X,
                                     "nominal gravity torque of each joint: J_j (a tau_g,j + b tau_g,j^2)")
    if m.temperature is not None and np.ptp(m.temperature) > 0:
        out["temperature"] = (m.temperature, _scalar_design(_poly(m.temperature, 2)),
                              "temperature (deg C): quadratic per axis")
    P = p_nominal
    if np.ptp(P, axis=0).max() > 0:
        Z = (P - P.mean(axis=0)) / np.maximum(P.std(axis=0), 1e-9)
        quad = [Z[:, i] * Z[:, j] for i in range(3) for j in range(i, 3)]
        out["position"] = (np.linalg.norm(P[:, :2], axis=1), _scalar_design(np.column_stack([Z] + quad)),
                           "nominal TCP position in the workspace: quadratic in x, y, z per axis")
    return out


def _pose_anova(R: np.ndarray, groups: np.ndarray) -> tuple[float, float]:
    """Adjusted fraction of residual variance explained by per-pose means, and p-value."""
    ug, inv, counts = np.unique(groups, return_inverse=True, return_counts=True)
    if len(ug) < 2 or np.all(counts < 2):
        return 0.0, 1.0
    means = np.zeros((len(ug), 3))
    np.add.at(means, inv, R)
    means /= counts[:, None]
    within = float(np.sum((R - means[inv]) ** 2))
    total = float(np.sum((R - R.mean(axis=0)) ** 2))
    between = total - within
    n, g = len(R), len(ug)
    df1, df2 = 3 * (g - 1), 3 * (n - g)
    if df2 <= 0 or within <= 0 or total <= 0:
        return 0.0, 1.0
    F = (between / df1) / (within / df2)
    adj = 1.0 - (within / df2) / (total / (3 * (n - 1)))
    return adj, float(stats.f.sf(F, df1, df2))


def run_diagnostics(R: np.ndarray, m: Measurements, variables: Mapping[str, tuple[np.ndarray, np.ndarray, str]],
                    folds: np.ndarray) -> list[Diagnostic]:
    """Regress the residual on each variable; significance with a Bonferroni correction.

    Returned sorted by explained fraction (largest first).
    """
    out: list[Diagnostic] = []
    n_tests = len(variables) + 1
    for name, (x, X, desc) in variables.items():
        frac, p = _regress_cv(R, X, folds)
        sig = (p < DIAG_ALPHA / n_tests) and frac > DIAG_MIN_FRACTION
        out.append(Diagnostic(name, frac, p, sig, x, desc))
    groups = m.pose_groups()
    frac, p = _pose_anova(R, groups)
    out.append(Diagnostic("pose", frac, p, (p < DIAG_ALPHA / n_tests) and frac > DIAG_MIN_FRACTION,
                          groups.astype(float),
                          "per-pose mean of the residual (one-way ANOVA, adjusted R^2): an error that "
                          "depends on the pose and that the model does not describe"))
    out.sort(key=lambda d: -d.explained_fraction)
    return out


def structure_left(diags: Sequence[Diagnostic]) -> Diagnostic | None:
    """The most specific significant diagnostic (a named variable before 'pose'), or None."""
    sig = [d for d in diags if d.significant]
    if not sig:
        return None
    named = [d for d in sig if d.variable != "pose"]
    return named[0] if named else sig[0]


# ----------------------------------------------------------------------------------
# The identification
# ----------------------------------------------------------------------------------

def _candidate_applicable(effect: str, m: Measurements) -> tuple[bool, str]:
    spec = EFFECTS[effect]
    if "load" in spec.needs and not m.load_varies():
        return False, "the applied wrench does not vary in the data"
    if "temperature" in spec.needs:
        if m.temperature is None:
            return False, "no temperature column"
        if np.ptp(m.temperature) < THERMAL_MIN_RANGE_K:
            return False, f"temperature varies by less than {THERMAL_MIN_RANGE_K} K"
    return True, ""


def _knots_from(tau: np.ndarray, ts: np.ndarray) -> np.ndarray:
    """Hardening knots (6, N_KNOTS), N*m: quantiles of the nonzero |tau| per joint."""
    tau = np.abs(tau)
    knots = np.outer(ts, fx.HARDENING_KNOT_QUANTILES)
    for j in range(6):
        nz = tau[:, j][tau[:, j] > 1e-9 * ts[j]]
        if len(nz) >= 10:
            knots[j] = np.quantile(nz, fx.HARDENING_KNOT_QUANTILES)
    return knots


def _update_knots(prob: _Problem, fit: _Fit) -> _Problem:
    """Place the hardening knots on the joint torques the current model applies (external
    plus, when ``gravity`` is on, self-weight): only while hardening is not active."""
    rows = prob.rows
    te, tg, _q = prob.ev.call("torques", rows[:, 0:6], rows[:, 6:12], rows[:, 13:14], fit.theta, prob.const)
    tau = np.asarray(te).T + np.asarray(tg).T
    c = set_const(prob.const, "hardening.knots", _knots_from(tau, get_const(prob.const, "tau_scale")).reshape(-1))
    return _Problem(m=prob.m, layout=prob.layout, ev=prob.ev, rows=prob.rows, const=c, weights=prob.weights,
                    folds=prob.folds, lower=prob.lower, upper=prob.upper)


def _torque_scale(prob_robot: Robot, m: Measurements) -> tuple[np.ndarray, np.ndarray]:
    """Per-joint torque scale (90th percentile of |J^T F| over the data), N*m, (6,),
    and hardening knots (quantiles of the nonzero |J^T F|), N*m, (6, N_KNOTS)."""
    layout = make_layout(prob_robot)
    const = make_const(prob_robot, np.eye(3), np.ones(6), False)
    te, _tg, _q = _ev_for(prob_robot).call(
        "torques", m.q, m.wrench, np.zeros((m.n, 1)), np.zeros(N_PARAMS) + layout.nominal, const)
    tau = np.abs(np.asarray(te).T)
    ts = np.maximum(np.percentile(tau, 90, axis=0), fx.TORQUE_SCALE_FLOOR_NM)
    return ts, _knots_from(tau, ts)


def _structural_held(robot: Robot, effects: Sequence[str], registered: bool) -> set[int]:
    """Parameters held on a rich synthetic design (structural redundancy)."""
    rng = np.random.default_rng(7)
    n = STRUCTURAL_DESIGN_ROWS
    lo, hi = np.maximum(robot.q_min, -np.pi), np.minimum(robot.q_max, np.pi)
    q = rng.uniform(lo, hi, (n, 6))
    F = np.zeros((n, 6))
    F[:, :3] = rng.normal(0, 50.0, (n, 3))
    F[::3] = 0.0
    m = Measurements(q=q, wrench=F, p=np.zeros((n, 3)), t=np.linspace(0, 1, n),
                     temperature=np.linspace(15, 35, n))
    layout = make_layout(robot)
    tau_s, knots = _torque_scale(robot, m)
    const = make_const(robot, np.eye(3), tau_s, True, knots=knots)
    ev = _ev_for(robot)
    theta = layout.nominal.copy()
    rows = make_rows(m, time_reference(m), 20.0)
    _pred, qe = ev.measure(rows, theta, const)
    _p, J = ev.jacobian(rows, qe, theta, const)
    order = _order_for(layout, effects, registered)
    Js = J[:, order] * layout.scale[order][None, :]
    _kept, held = select_identifiable(Js, order, 0.0)
    return set(held)


def identify(robot: Robot, data: Measurements, registered: bool = False,
             candidates: Sequence[str] | None = None, include: Sequence[str] = (),
             folds: int = CV_FOLDS, progress: Progress | None = None,
             max_steps: int = 12) -> IdentificationResult:
    """Identify the declared model and select effects from the library.

    Parameters
    ----------
    robot : Robot
        Nominal description (DH, stiffness, tool, masses).
    data : Measurements
        With positions ``p`` (measurement frame, m).
    registered : bool
        True when the measurement frame is the base frame and the measured point is
        the robot file's TCP; otherwise both are identified.
    candidates : sequence of str, optional
        Library effects the selection may add (default: all, ``outliers`` included).
    include : sequence of str
        Effects added without a test (their parameters must be identifiable from
        the data; otherwise :class:`DataError` names them).
    folds : int
        K of the K-fold cross-validation.
    progress : callable, optional
        ``progress(message, done, total)``.

    Returns
    -------
    IdentificationResult

    Raises
    ------
    DataError
        Too few rows/poses for the declared model or an included effect (names the
        unidentifiable parameters), or no measured positions.
    """
    def tick(msg: str, k: int, total: int) -> None:
        if progress is not None:
            progress(msg, k, total)

    m = data
    if m.p is None:
        raise DataError(f"{m.source}: no measured positions (columns x, y, z) to identify from")
    cand = list(LIBRARY if candidates is None else candidates)
    for e in list(cand) + list(include):
        if e not in LIBRARY:
            raise InputError(f"unknown effect '{e}'; library: {', '.join(LIBRARY)}")
    robust = "outliers" in cand or "outliers" in include
    include = [e for e in include if e != "outliers"]
    cand = [e for e in cand if e != "outliers" and e not in include]
    notes: list[str] = []
    if robot.identified is not None:
        notes.append("the robot file carries an [identified] table; identification starts from its "
                     "ordinary fields and ignores that table")
    n_poses = len(np.unique(m.pose_groups()))
    layout = make_layout(robot)
    tau_s, knots = _torque_scale(robot, m)
    t_ref = time_reference(m)
    temp_ref = float(np.mean(m.temperature)) if m.temperature is not None else fx.THERMAL_REFERENCE_C
    ev = _ev_for(robot)
    theta = layout.nominal.copy()
    R0 = np.eye(3)
    rows = make_rows(m, t_ref, temp_ref)
    weights = 1.0 / m.sigma if m.sigma is not None else np.ones(m.n)
    lower, upper = layout.lower.copy(), layout.upper.copy()      # declared by the effect plug-ins
    fold_idx = _assign_folds(m, folds)
    total_steps = len(cand) + 3
    tick("registration", 0, total_steps)
    # --- initial registration (Kabsch on the nominal model)
    if not registered:
        if n_poses < 3:
            raise DataError(f"{m.source}: {n_poses} distinct pose(s); the registration of the measurement "
                            "frame and the measured point need at least 3 poses (many more for a useful fit); "
                            "or declare the data registered")
        pred0, _q = ev.measure(rows, theta, make_const(robot, R0, tau_s, False, knots=knots))
        R0, t0 = kabsch(pred0, m.p)
        theta[GROUP_SLICES["reg.t"]] = t0
    prob = _Problem(m=m, layout=layout, ev=ev, rows=rows, const=make_const(robot, R0, tau_s, False, knots=knots),
                    weights=weights, folds=fold_idx, lower=lower, upper=upper)
    all_rows = np.ones(m.n, dtype=bool)
    # --- "before": the nominal model, only the registration and measured point fitted
    order_b = [] if registered else list(layout.indices(("reg.t", "reg.w", "tool.p")))
    pred_b, q_b = _evaluate(prob, theta)
    if registered:
        fit_b = _Fit(theta=theta.copy(), free=np.zeros(0, dtype=int), held={}, inliers=all_rows.copy(),
                     pred=pred_b, q_eq=q_b, J=_jac(prob, theta, q_b), converged=True, iterations=0)
    else:
        fit_b = _lm(prob, theta, np.asarray(order_b), all_rows, pred_b, q_b)
        theta = fit_b.theta.copy()
    # structural redundancy (to tell it from too-few-data)
    structural = _structural_held(robot, list(include) + cand, registered)
    # --- declared model (and effects included without a test)
    tick("declared model", 1, total_steps)
    gravity_on = "gravity" in include
    if gravity_on:
        prob = _gravity_problem(prob, True)
    fit = _fit_model(prob, theta, include, registered, all_rows, robust=robust)
    reg_idx = set(layout.indices(("reg.t", "reg.w", "tool.p"))) if not registered else set()
    bad = [i for i in fit.held if i in reg_idx and i not in structural]
    if bad:
        raise DataError(f"{m.source}: too few or too similar poses ({n_poses} distinct): cannot identify "
                        + ", ".join(f"{PARAM_NAMES[i]} ({fit.held[i]})" for i in bad)
                        + "; measure more poses spread over the workspace, or declare the data registered")
    inc_idx = {int(i): e for e in include for i in layout.effect_indices(e)}
    bad = [i for i in fit.held if i in inc_idx and i not in structural]
    if bad:
        raise DataError(f"{m.source}: the data ({m.n} rows, {n_poses} poses) cannot identify "
                        + ", ".join(f"{PARAM_NAMES[i]} [{inc_idx[i]}] ({fit.held[i]})" for i in bad[:8])
                        + (f" and {len(bad) - 8} more" if len(bad) > 8 else "")
                        + "; add poses/loads that excite them or do not include the effect")
    if all(i in fit.held for i in layout.indices(("stiffness.s",))):
        notes.append("joint stiffness is held at the robot file's values: the applied wrench does not excite it"
                     if not m.load_varies() else "joint stiffness cannot be identified from these data")
    sigma_noise, noise_src = noise_floor(m)
    sigma_w = None if sigma_noise is None else (1.0 if m.sigma is not None else sigma_noise)
    applicable: dict[str, str] = {}
    for e in cand:
        ok, why = _candidate_applicable(e, m)
        if not ok:
            applicable[e] = why
    # --- saturated model: every applicable library effect at once.  Its residual tells
    # whether the library can explain the data at all (then no attribution can be a
    # partial fit of something else), and its robust fit finds the outliers against the
    # most flexible model available.
    tick("saturated library model", 2, total_steps)
    sat_effects = list(include) + [e for e in cand if e not in applicable]
    if "geometric" in sat_effects and "joint_offset" in sat_effects:
        sat_effects.remove("joint_offset")
    sat_clean = False
    sat_info: dict[str, Any] = {"effects": sat_effects}
    mask_sel = fit.inliers.copy()
    if len(sat_effects) > len(include):
        prob_s = _gravity_problem(prob, True) if "gravity" in sat_effects else prob
        th_s = fit.theta.copy()
        if "gravity" in sat_effects and not gravity_on:
            gi = layout.effect_indices("gravity")
            th_s[gi] = layout.nominal[gi]
        fit_s = _fit_model(prob_s, th_s, sat_effects, registered, all_rows, robust=robust,
                           max_iter=SATURATED_MAX_ITER, passes=1, rounds=2)
        diags_s = _diagnose(prob_s, fit_s, robot)
        left = structure_left(diags_s)
        sat_clean = left is None or left.explained_fraction < UNEXPLAINED_MIN_FRACTION
        if robust and not sat_clean and (~fit_s.inliers).any():
            # structure outside the library: only gross errors count as outliers
            gross = _outlier_mask(prob_s, fit_s.pred, gross_only=True)
            fit_s.inliers = gross
        sc_s, _fr = _score_p(prob_s, layout, fit_s, sat_effects, registered)
        sat_info.update({"cv_rms_mm": sc_s.cv_rms_m * 1e3, "clean": sat_clean,
                         "structure": None if left is None else left.variable,
                         "n_excluded": int((~fit_s.inliers).sum())})
        if robust:
            mask_sel = fit_s.inliers.copy()
            if (~mask_sel).any():
                fit = _fit_model(prob, fit.theta, include, registered, mask_sel, robust=robust)
    active: list[str] = list(include)
    effects_added: list[str] = []
    history: list[SelectionStep] = []
    score_b = _linear_scores(prob, fit_b.J, fit_b.pred, fit.inliers, np.asarray(order_b, dtype=int))

    def refit(p: _Problem, th: np.ndarray, effs: Sequence[str], mask: np.ndarray) -> _Fit:
        return _fit_model(p, th, effs, registered, mask, robust=robust)

    def score_of(p: _Problem, f: _Fit, effs: Sequence[str]) -> tuple[_Score, list[int]]:
        return _score_p(p, layout, f, effs, registered)

    def with_effect(p: _Problem, th: np.ndarray, e: str) -> tuple[_Problem, np.ndarray]:
        if e == "gravity" and get_const(p.const, "gravity.on")[0] < 0.5:
            th = th.copy()
            gi = layout.effect_indices("gravity")
            th[gi] = layout.nominal[gi]
            return _gravity_problem(p, True), th
        return p, th

    step_idx = 0
    stop_reason = "no candidate left"
    while True:
        if "stiffness_hardening" not in active and get_const(prob.const, "gravity.on")[0] > 0.5:
            prob = _update_knots(prob, fit)
            fit.J = _jac(prob, fit.theta, fit.q_eq)
        score_m, free_m = score_of(prob, fit, active)
        tick(f"step {step_idx}: CV RMS {score_m.cv_rms_m * 1e3:.4g} mm", min(3 + step_idx, total_steps),
             total_steps)
        cands_scores: list[CandidateScore] = []
        accepted = None
        reason = ""
        at_floor = sigma_noise is not None and score_m.cv_rms_m <= NOISE_FLOOR_STOP_RATIO * sigma_noise
        remaining = [e for e in cand if e not in active]
        if at_floor:
            stop_reason = (f"cross-validated RMS {score_m.cv_rms_m * 1e3:.4g} mm is at the noise floor "
                           f"({NOISE_FLOOR_STOP_RATIO:g} x {sigma_noise * 1e3:.4g} mm)")
        elif not remaining or step_idx >= max_steps:
            stop_reason = "no candidate left" if not remaining else "step limit"
        else:
            sig_now = _rms(_wres(prob, fit.pred, fit.inliers))
            cur_order = _order_for(layout, active, registered)
            prelim: list[CandidateScore] = []
            for e in remaining:
                if e in applicable:
                    cands_scores.append(CandidateScore(e, 0, None, None, None, None, None, None,
                                                       reason=f"not testable: {applicable[e]}"))
                    continue
                new = [int(i) for i in layout.effect_indices(e) if i not in cur_order]
                if not new:
                    cands_scores.append(CandidateScore(e, 0, None, None, None, None, None, None,
                                                       reason="subsumed by an effect already added"))
                    continue
                prob_e, th_e = with_effect(prob, fit.theta, e)
                if prob_e is prob:
                    J_e, pred_e = fit.J, fit.pred
                else:
                    pred_e, q_g = _evaluate(prob_e, th_e)
                    J_e = _jac(prob_e, th_e, q_g)
                order = _order_for(layout, active + [e], registered)
                Js = _wjac(prob_e, J_e, fit.inliers, np.asarray(order, dtype=int))
                kept, held = select_identifiable(Js, order, sig_now)
                kept_new = [i for i in kept if i in new]
                if not kept_new:
                    cands_scores.append(CandidateScore(e, 0, None, None, None, None, None, None,
                                                       reason="no parameter identifiable from these data",
                                                       held=[PARAM_NAMES[i] for i in new]))
                    continue
                sc = _linear_scores(prob_e, J_e, pred_e, fit.inliers, np.asarray(kept, dtype=int))
                cs = _candidate_score(e, sc, score_m, sigma_w, len(kept_new))
                cs.held = [f"{PARAM_NAMES[i]}: {held[i]}" for i in new if i in held]
                prelim.append(cs)
                cands_scores.append(cs)
            # refine the best few (and gravity, whose switch-on defeats linearisation)
            ranked = sorted(prelim, key=lambda c: c.cv_rms_m)
            to_refine = [c for c in ranked[:REFINE_TOP] if c.cv_rms_m < score_m.cv_rms_m]
            # gravity switches on at the file's masses: when its linearisation is visibly
            # off (worse in-sample than the current model) it is refined anyway
            to_refine += [c for c in ranked if c.effect == "gravity" and c not in to_refine
                          and c.rms_m > score_m.rms_m]
            refined: list[tuple[CandidateScore, _Fit, _Problem]] = []
            for cs in to_refine:
                e = cs.effect
                tick(f"step {step_idx}: fitting {e}", min(3 + step_idx, total_steps), total_steps)
                prob_e, th_e = with_effect(prob, fit.theta, e)
                f_e = _fit_model(prob_e, th_e, active + [e], registered, fit.inliers, robust=False)
                sc_e, free_e = score_of(prob_e, f_e, active + [e])
                cs2 = _candidate_score(e, sc_e, score_m, sigma_w, len([i for i in free_e if i not in free_m]))
                cs.cv_rms_m, cs.rms_m, cs.bic, cs.delta_bic = cs2.cv_rms_m, cs2.rms_m, cs2.bic, cs2.delta_bic
                cs.f_pvalue, cs.explained_share, cs.n_params = cs2.f_pvalue, cs2.explained_share, cs2.n_params
                cs.refined = True
                cs.held = [f"{PARAM_NAMES[i]}: {f_e.held[i]}" for i in layout.effect_indices(e) if i in f_e.held]
                refined.append((cs, f_e, prob_e))
            best = None
            if refined:
                refined.sort(key=lambda x: x[0].cv_rms_m)
                best = refined[0]
                for alt in refined[1:]:
                    if (alt[0].n_params < best[0].n_params
                            and alt[0].cv_rms_m <= best[0].cv_rms_m * (1 + PARSIMONY_REL_TOL)):
                        best = alt
            for cs in cands_scores:
                if cs.cv_rms_m is not None and not cs.reason:
                    cs.reason = _significance(cs, score_m)[2]
            if best is None or best[0].cv_rms_m >= score_m.cv_rms_m:
                stop_reason = "no candidate lowers the cross-validated residual"
            else:
                basic, share_ok, why = _significance(best[0], score_m)
                ok = basic and share_ok
                if basic and not share_ok:
                    if sat_clean:
                        ok = True
                        why += ("; accepted: the whole library leaves no structure in the residual, so the "
                                "share is small only because other effects are present")
                    else:
                        left = structure_left(_diagnose(best[2], best[1], robot))
                        if left is None:
                            ok = True
                            why += "; accepted: no diagnostic shows structure left after it"
                        else:
                            why += (f"; rejected: structure outside the library remains (residual vs "
                                    f"{left.variable}) and this effect would explain only a small part")
                best[0].reason = why
                if ok:
                    best[0].accepted = True
                    accepted = best[0].effect
                    prob = best[2]
                    active.append(accepted)
                    effects_added.append(accepted)
                    fit = refit(prob, best[1].theta, active, mask_sel)
                    reason = f"added {accepted}: {why}"
                else:
                    stop_reason = f"best candidate {best[0].effect} not significant: {why}"
        history.append(SelectionStep(index=step_idx, effects=list(active), n_params=score_m.k,
                                     rms_m=score_m.rms_m, cv_rms_m=score_m.cv_rms_m, bic=score_m.bic,
                                     n_excluded=int((~fit.inliers).sum()), candidates=cands_scores,
                                     accepted=accepted, reason=reason or stop_reason))
        step_idx += 1
        if accepted is None:
            break
    # --- backward pass: drop an added effect, or replace it by a nested smaller one,
    # when the cross-validated RMS does not get worse by more than PARSIMONY_REL_TOL
    changed = True
    while changed and len(effects_added) > 0:
        changed = False
        score_m, _free = score_of(prob, fit, active)
        for e in [x for x in reversed(effects_added) if x not in include]:
            options: list[list[str]] = [[x for x in active if x != e]]
            if e == "geometric":
                options.insert(0, [x if x != "geometric" else "joint_offset" for x in active])
            for alt in options:
                p_alt = prob
                th_alt = fit.theta.copy()
                gone = [int(i) for i in layout.effect_indices(e) if i not in _order_for(layout, alt, registered)]
                # linearised screen first (setting first moments to zero switches gravity off)
                shift = np.zeros(N_PARAMS)
                shift[gone] = (0.0 if e == "gravity" else layout.nominal[gone]) - fit.theta[gone]
                keep = [i for i in _order_for(layout, alt, registered) if i not in fit.held]
                sc_lin = _linear_scores(prob, fit.J, fit.pred, fit.inliers, np.asarray(keep, dtype=int), shift)
                if sc_lin.cv_rms_m > score_m.cv_rms_m * (1 + 2 * PARSIMONY_REL_TOL):
                    continue
                if e == "gravity":
                    p_alt = _gravity_problem(prob, False)
                th_alt[gone] = layout.nominal[gone]
                f_alt = _fit_model(p_alt, th_alt, alt, registered, fit.inliers, robust=False)
                sc_alt, _fa = score_of(p_alt, f_alt, alt)
                if sc_alt.cv_rms_m <= score_m.cv_rms_m * (1 + PARSIMONY_REL_TOL) and sc_alt.bic <= score_m.bic + \
                        2.0 * math.log(sc_alt.n):
                    what = "replaced by joint_offset" if "joint_offset" in alt and "joint_offset" not in active \
                        else "removed"
                    history.append(SelectionStep(
                        index=step_idx, effects=list(alt), n_params=sc_alt.k, rms_m=sc_alt.rms_m,
                        cv_rms_m=sc_alt.cv_rms_m, bic=sc_alt.bic, n_excluded=int((~fit.inliers).sum()),
                        candidates=[], accepted=None,
                        reason=(f"backward step: {e} {what} (CV RMS {score_m.cv_rms_m * 1e3:.4g} -> "
                                f"{sc_alt.cv_rms_m * 1e3:.4g} mm, within {100 * PARSIMONY_REL_TOL:.0f} %)")))
                    step_idx += 1
                    prob, fit = p_alt, refit(p_alt, f_alt.theta, alt, mask_sel)
                    effects_added = [x for x in effects_added if x != e]
                    if "joint_offset" in alt and "joint_offset" not in active:
                        effects_added.append("joint_offset")
                    active = list(alt)
                    changed = True
                    break
            if changed:
                break
    # --- final robust check on all rows: every row is tested against the final model
    tick("final fit and diagnostics", total_steps, total_steps)
    if robust:
        # a residual with structure the library lacks is not a Gaussian bulk: gross errors only
        structured = structure_left(_diagnose(prob, fit, robot)) is not None
        final_mask = _outlier_mask(prob, fit.pred, gross_only=structured)
        if not np.array_equal(final_mask, fit.inliers):
            fit = _fit_model(prob, fit.theta, active, registered, final_mask, robust=False)
            fit.inliers = final_mask
    else:
        fit = _fit_model(prob, fit.theta, active, registered, all_rows, robust=False)
    if robust and (~fit.inliers).any():
        effects_added.append("outliers")
    score_f, free_f = score_of(prob, fit, active)
    order_f = _order_for(layout, active, registered)
    r_w = _wres(prob, fit.pred, fit.inliers)
    n_res, k_f = r_w.size, len(free_f)
    s2 = float(r_w @ r_w) / max(n_res - k_f, 1)
    Js = _wjac(prob, fit.J, fit.inliers, np.asarray(free_f, dtype=int))
    std = np.full(N_PARAMS, np.nan)
    cond = float("nan")
    if k_f:
        G = Js.T @ Js
        try:
            cov = np.linalg.inv(G) * s2
            std[free_f] = np.sqrt(np.maximum(np.diag(cov), 0.0)) * layout.scale[free_f]
        except np.linalg.LinAlgError:
            pass
        Jn = Js / np.maximum(np.linalg.norm(Js, axis=0), 1e-300)
        sv = np.linalg.svd(Jn, compute_uv=False)
        cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")
    R_un = fit.residual(prob)
    R_in = R_un[fit.inliers]
    model = IdentifiedModel(nominal=robot, theta=fit.theta.copy(), R0=R0, tau_scale=tau_s,
                            gravity_on=bool(get_const(prob.const, "gravity.on")[0] > 0.5), beams=fx.beam_frames(robot),
                            knots=get_const(prob.const, "hardening.knots").reshape(6, fx.N_KNOTS).copy(),
                            time_ref=t_ref, temperature_ref=temp_ref, effects=list(active),
                            registered=registered, std={PARAM_NAMES[i]: float(std[i]) for i in free_f},
                            noise_sigma_m=sigma_noise,
                            held={PARAM_NAMES[i]: r for i, r in fit.held.items() if i in order_f},
                            tcp_correction_m=(fit.theta[GROUP_SLICES["tool.p"]] - robot.flange2tcp[:3, 3]
                                              if registered else np.zeros(3)))
    params = _parameter_table(layout, fit, order_f, std, active, registered)
    # diagnostics on the final residual (inliers)
    diags = _diagnose(prob, fit, robot)
    top = structure_left(diags)
    above_floor = sigma_noise is not None and score_f.cv_rms_m > UNEXPLAINED_RMS_RATIO * sigma_noise
    strong = top is not None and top.explained_fraction >= UNEXPLAINED_MIN_FRACTION
    if strong or above_floor:
        if top is None:
            top = diags[0]
        unexplained = {
            "present": True, "diagnostic": f"residual vs {top.variable}", "variable": top.variable,
            "explained_fraction": top.explained_fraction, "p_value": top.p_value,
            "description": top.description,
            "rms_over_noise": (score_f.cv_rms_m / sigma_noise) if sigma_noise else None,
            "message": (f"structure remains that no library effect explains: the residual depends on "
                        f"{top.variable} (cross-validated regression explains {100 * top.explained_fraction:.0f} % "
                        f"of its variance, p = {top.p_value:.2g})"
                        + (f"; held-out RMS is {score_f.cv_rms_m / sigma_noise:.2f} x the noise floor"
                           if sigma_noise else "")),
        }
        status = IdentifyStatus.UNEXPLAINED
        reason = unexplained["message"]
    else:
        unexplained = {"present": False, "diagnostic": None, "variable": None,
                       "explained_fraction": (diags[0].explained_fraction if diags else None),
                       "message": "no diagnostic shows structure the model leaves unexplained"}
        status = IdentifyStatus.OK
        reason = stop_reason
    if not fit.converged:
        status = IdentifyStatus.NOT_CONVERGED
        reason = "the final least-squares fit did not converge"
    excluded = []
    for i in np.flatnonzero(~fit.inliers):
        excluded.append({"row": int(i), "line": int(m.line[i]),
                         "residual_mm": float(np.linalg.norm(R_un[i]) * 1e3),
                         "residual_xyz_mm": (R_un[i] * 1e3).tolist()})
    ident = {
        "rank": k_f, "condition_number": cond, "n_rows": int(m.n), "n_inliers": int(fit.inliers.sum()),
        "n_poses": int(n_poses), "saturated_model": sat_info,
        "held": [{"name": PARAM_NAMES[i], "effect": _effect_of(i), "reason": r}
                 for i, r in fit.held.items() if i in order_f],
    }
    res_b = fit_b.residual(prob)
    return IdentificationResult(
        status=status, reason=reason, model=model, effects_added=effects_added, history=history,
        parameters=params, rms_before_m=_rms(res_b[fit.inliers]), rms_after_m=_rms(R_in),
        cv_rms_before_m=score_b.cv_rms_m, cv_rms_after_m=score_f.cv_rms_m, noise_sigma_m=sigma_noise,
        noise_source=noise_src, excluded=excluded, unexplained=unexplained, diagnostics=diags,
        identifiability=ident, residual_before=res_b, residual_after=R_un, inliers=fit.inliers, data=m,
        notes=notes)


def _score_p(prob: _Problem, layout: ModelLayout, f: _Fit, effs: Sequence[str],
             registered: bool) -> tuple[_Score, list[int]]:
    """Linearised in-sample and CV scores of a fitted model (its free parameters)."""
    order = _order_for(layout, effs, registered)
    free = [i for i in order if i not in f.held]
    return _linear_scores(prob, f.J, f.pred, f.inliers, np.asarray(free, dtype=int)), free


def _gravity_problem(prob: _Problem, on: bool) -> _Problem:
    c = set_const(prob.const, "gravity.on", [1.0 if on else 0.0])
    return _Problem(m=prob.m, layout=prob.layout, ev=prob.ev, rows=prob.rows, const=c, weights=prob.weights,
                    folds=prob.folds, lower=prob.lower, upper=prob.upper)


def _candidate_score(effect: str, sc: _Score, cur: _Score, sigma_w: float | None, k_new: int) -> CandidateScore:
    """Scores of a candidate against the current model (same rows, same folds)."""
    dbic = sc.bic - cur.bic
    df1 = max(sc.k - cur.k, 1)
    df2 = max(sc.n - sc.k, 1)
    if sc.rss > 0 and cur.rss > sc.rss:
        F = ((cur.rss - sc.rss) / df1) / (sc.rss / df2)
        p = float(stats.f.sf(F, df1, df2))
    else:
        p = 1.0
    cv_cur = cur.cv_rss / cur.n
    cv_new = sc.cv_rss / sc.n
    floor = (sigma_w ** 2) if sigma_w is not None else 0.0
    excess = cv_cur - floor
    share = (cv_cur - cv_new) / excess if excess > 0 else 0.0
    return CandidateScore(effect=effect, n_params=k_new, cv_rms_m=sc.cv_rms_m, rms_m=sc.rms_m, bic=sc.bic,
                          delta_bic=dbic, f_pvalue=p, explained_share=float(share))


def _significance(cs: CandidateScore, cur: _Score) -> tuple[bool, bool, str]:
    """(basic tests pass, share test passes, explanation).

    Basic: CV RMS gain >= CV_MIN_REL_GAIN, BIC decreases, F-test p < F_TEST_ALPHA.
    Share: the effect explains >= MIN_EXPLAINED_SHARE of the CV variance above the
    noise floor (of all of it when the floor is unknown).
    """
    gain = 1.0 - cs.cv_rms_m / cur.cv_rms_m
    parts = [f"CV RMS {cur.cv_rms_m * 1e3:.4g} -> {cs.cv_rms_m * 1e3:.4g} mm ({100 * gain:+.1f} %)",
             f"dBIC {cs.delta_bic:.1f}", f"F-test p = {cs.f_pvalue:.2g}",
             f"explains {100 * cs.explained_share:.0f} % of the excess variance"]
    basic = True
    if gain < CV_MIN_REL_GAIN:
        basic = False
        parts.append(f"gain below {100 * CV_MIN_REL_GAIN:.0f} %")
    if cs.delta_bic >= 0:
        basic = False
        parts.append("BIC does not decrease")
    if cs.f_pvalue >= F_TEST_ALPHA:
        basic = False
        parts.append(f"F-test not significant at {F_TEST_ALPHA:g}")
    share_ok = cs.explained_share >= MIN_EXPLAINED_SHARE
    if not share_ok:
        parts.append(f"explains less than {100 * MIN_EXPLAINED_SHARE:.0f} % of the structure left")
    return basic, share_ok, "; ".join(parts)


def _diagnose(prob: _Problem, fit: _Fit, robot: Robot) -> list[Diagnostic]:
    """Diagnostics of the residual of ``fit`` (inlier rows)."""
    mask = fit.inliers
    m = prob.m.subset(mask)
    n = m.n
    ev = prob.ev
    rows = prob.rows[mask]
    dT = rows[:, 13:14]
    _p, Jp = ev.call("point_jacobian", m.q, dT, fit.theta, prob.const)
    Jp = np.asarray(Jp).reshape(3, n, 6).transpose(1, 0, 2)
    te, _tg, _q = ev.call("torques", m.q, m.wrench, dT, fit.theta, prob.const)
    tau = np.asarray(te).T
    tau_g = _nominal_gravity_torque(robot, m)
    p_nom = _nominal_points(robot, m.q)
    variables = diagnostic_variables(m, Jp, tau, tau_g, p_nom)
    R = (fit.pred[mask] - m.p) * prob.weights[mask][:, None]
    diags = run_diagnostics(R, m, variables, prob.folds[mask])
    # joint-angle diagnostics are shown as the equivalent error of that joint: the residual
    # projected on the joint's column of the positional Jacobian, (J_j . r) / |J_j|^2 (rad)
    Ru = fit.pred[mask] - m.p
    for d in diags:
        if d.variable.startswith("q") and d.variable[1:].isdigit():
            j = int(d.variable[1:]) - 1
            Jj = Jp[:, :, j]
            d.y = np.einsum("ni,ni->n", Jj, Ru) / np.maximum(np.einsum("ni,ni->n", Jj, Jj), 1e-12)
            d.y_label = f"equivalent joint-{j + 1} error (mrad)"
    return diags


def _nominal_points(robot: Robot, q: np.ndarray) -> np.ndarray:
    """Nominal TCP positions (base frame, m), (N, 3), without compiling anything."""
    layout = make_layout(robot)
    rows = np.zeros((len(q), fx.ROW_SIZE))
    rows[:, :6] = q
    const = make_const(robot, np.eye(3), np.ones(6), False)
    p, _q = _ev_for(robot).measure(rows, layout.nominal, const)
    return p


def _nominal_tcp(robot: Robot, q: np.ndarray) -> np.ndarray:
    """Nominal-FK TCP frames (base frame), (N, 4, 4), via ``Function.map`` (no compilation)."""
    km = KinematicModel(robot)
    n = len(q)
    T = np.asarray(km.fk_tcp.map(n, "thread", 2)(q.T))
    return T.reshape(4, n, 4).transpose(1, 0, 2)


def _effect_of(i: int) -> str:
    for g, e, _names, _u in fx.PARAMETER_GROUPS:
        s = GROUP_SLICES[g]
        if s.start <= i < s.stop:
            return e
    return "?"


def _parameter_table(layout: ModelLayout, fit: _Fit, order: Sequence[int], std: np.ndarray,
                     active: Sequence[str], registered: bool) -> list[ParameterEstimate]:
    out = []
    order_set = set(order)
    for i in order:
        name = PARAM_NAMES[i]
        if i in fit.held:
            out.append(ParameterEstimate(name, _effect_of(i), float(fit.theta[i]), None, layout.units[i], "held",
                                         fit.held[i]))
        else:
            out.append(ParameterEstimate(name, _effect_of(i), float(fit.theta[i]),
                                         float(std[i]) if np.isfinite(std[i]) else None, layout.units[i], "free"))
    if registered:
        for i in layout.indices(("reg.t", "reg.w", "tool.p")):
            if i not in order_set:
                out.insert(0, ParameterEstimate(PARAM_NAMES[i], _effect_of(i), float(fit.theta[i]), None,
                                                layout.units[i], "held", "data declared registered"))
    return out


def _nominal_gravity_torque(robot: Robot, m: Measurements) -> np.ndarray | None:
    """Nominal gravity torques (N*m, (N, 6)) from the robot's masses, or a generic
    proxy (unit masses at the link mid-points) when the file gives none."""
    layout = make_layout(robot)
    theta = layout.nominal.copy()
    if not robot.has_masses:
        s = GROUP_SLICES["gravity.m"]
        theta[s] = 1.0
        h = np.zeros((6, 3))
        h[:, 0] = -robot.a / 2.0
        theta[GROUP_SLICES["gravity.h"]] = h.reshape(-1)
    const = make_const(robot, np.eye(3), np.ones(6), True)
    ev = _ev_for(robot)
    _te, tg, _q = ev.call("torques", m.q, np.zeros((m.n, 6)), np.zeros((m.n, 1)), theta, const)
    return np.asarray(tg).T


# ----------------------------------------------------------------------------------
# Model files
# ----------------------------------------------------------------------------------

# Model files: models/arm_file.py (model_to_dict, model_from_robot, load_model, model_toml).


# ----------------------------------------------------------------------------------
# Predict and compensate
# ----------------------------------------------------------------------------------

def predict(model: IdentifiedModel, m: Measurements) -> np.ndarray:
    """Predicted measurement of the measured point, measurement frame, m, (N, 3).

    Registration, measured point and every identified effect are applied; drift
    only when the input has a ``t`` column (same clock as the identification data;
    otherwise the state at the campaign's first row), temperature from the input or
    the identification data's mean.
    """
    ev = _ev_for(model.nominal)
    rows = make_rows(m, model.time_ref if m.t is not None else None, model.temperature_ref)
    p, _q = ev.measure(rows, model.theta, model.const)
    return p


@dataclass
class CompensationOutcome:
    """Compensated commands under an identified model.

    Attributes
    ----------
    q_command : ndarray, shape (N, 6)
        Commands, rad.
    q_deflected : ndarray, shape (N, 6)
        Joint angles the identified model reaches from them under the load, rad.
    target : ndarray, shape (N, 4, 4)
        Target TCP poses, base frame (TCP-frame coordinates -> base-frame coordinates).
    residual_m, residual_rad : ndarray, shape (N,)
        Model-predicted TCP position (m) and orientation (rad) error after compensation.
    status : CompensationStatus
    reason : str
    """

    q_command: np.ndarray
    q_deflected: np.ndarray
    target: np.ndarray
    residual_m: np.ndarray
    residual_rad: np.ndarray
    status: CompensationStatus
    reason: str
    failed_rows: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))


def _at_temperature(model: ArmModel, temperature: np.ndarray | None) -> list[tuple[np.ndarray, ArmModel]]:
    """Row groups that share a temperature, each with the model evaluated at it (thermal)."""
    if temperature is None or "thermal" not in model.active_effects:
        return [(np.arange(0), model)] if temperature is None else [(np.arange(len(temperature)), model)]
    temp = np.asarray(temperature, dtype=float)
    out = []
    for t in np.unique(temp):
        out.append((np.flatnonzero(temp == t), replace(model, temperature_ref=float(t))))
    return out


def compensate(model: ArmModel, q_in: np.ndarray, wrench: np.ndarray,
               temperature: np.ndarray | None = None,
               base2target: np.ndarray | None = None) -> CompensationOutcome:
    """Commands that put the real TCP on its targets under ``wrench`` (base frame).

    The targets are the nominal-FK TCP of ``q_in`` (the robot file's chain: what the
    user commanded), or the poses ``base2target`` (N, 4, 4) when given.  The engine is the
    product's one exact compensation (:func:`problems.compensation.exact`) on the
    identified arm model; the equilibrium reached from the commands is solved
    independently and its TCP compared with the target.
    """
    q_in = np.atleast_2d(np.asarray(q_in, dtype=float))
    n = len(q_in)
    F = np.broadcast_to(np.asarray(wrench, dtype=float), (n, 6)).copy()
    target = _nominal_tcp(model.nominal, q_in) if base2target is None else np.asarray(base2target, float)
    q_c = np.zeros_like(q_in)
    q_eq = np.zeros_like(q_in)
    res = np.zeros(n)
    rres = np.zeros(n)
    groups = _at_temperature(model, temperature)
    if len(groups[0][0]) == 0:
        groups = [(np.arange(n), model)]
    for idx, arm in groups:
        out = exact_compensation(arm, q_in[idx], F[idx], tol_m=COMPENSATION_RESIDUAL_TOL, base2target=target[idx])
        q_c[idx], q_eq[idx] = out.q_command, out.q_deflected
        res[idx], rres[idx] = out.error_norm_m, out.error_rad
    bad_rows = np.flatnonzero(~(np.isfinite(res) & (res <= COMPENSATION_RESIDUAL_TOL)))
    if len(bad_rows):
        worst = int(bad_rows[np.argmax(np.where(np.isfinite(res[bad_rows]), res[bad_rows], np.inf))])
        return CompensationOutcome(q_c, q_eq, target, res, rres, CompensationStatus.FAILED,
                                   f"{len(bad_rows)} row(s) not compensated to {COMPENSATION_RESIDUAL_TOL:g} m "
                                   f"(rows {', '.join(str(int(i)) for i in bad_rows[:10])}"
                                   f"{' ...' if len(bad_rows) > 10 else ''}; worst row {worst}: "
                                   f"{res[worst]:.3g} m): target at the edge of the identified model's reach "
                                   "or near a singularity", failed_rows=bad_rows)
    return CompensationOutcome(q_c, q_eq, target, res, rres, CompensationStatus.OK,
                               f"max model-predicted residual {res.max():.3g} m")


def compensation_check(vr: Any, model: IdentifiedModel, n_poses: int = 40,
                       force_N: float | None = None, seed: int = 99) -> dict[str, Any]:
    """Simulate -> compensate -> re-measure on a virtual robot.

    New poses and loads (not those of the campaign) are drawn; the target is the
    nominal-FK TCP of each command; errors are the virtual robot's true TCP minus the
    target (base frame) before (command as is) and after compensation.
    """
    rng = np.random.default_rng(seed)
    q = vr.sample_poses(n_poses, rng, max_cond=COMPENSATION_CHECK_MAX_COND)
    camp = dict(vr.config.get("campaign", {}))
    mags = np.atleast_1d(camp.get("force_magnitudes_N", [100.0])) if force_N is None else [force_N]
    F = np.zeros((n_poses, 6))
    u = rng.normal(size=(n_poses, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    F[:, :3] = u * rng.choice(np.asarray(mags, dtype=float), n_poses)[:, None]
    F[::4] = 0.0
    temp = np.full(n_poses, model.temperature_ref)
    target = _nominal_tcp(model.nominal, q)
    before = vr.tcp_error(q, F, target, temp)
    out = compensate(model, q, F, temp)
    after = vr.tcp_error(out.q_command, F, target, temp)
    # the same in the measurement frame: the measured point against its nominal target mapped
    # by the identified registration (what a tracker can check; free of the base-frame aliasing
    # of unregistered data)
    b2m = model.base2meas()
    p_t = target[:, :3, :3] @ (np.linalg.solve(model.nominal.flange2tcp, np.append(model.measured_point, 1.0))[:3]) \
        + target[:, :3, 3]
    p_t = p_t @ b2m[:3, :3].T + b2m[:3, 3]
    t0 = np.full(n_poses, model.time_ref[0])   # drift is zero at the campaign's first row
    before_m = vr.measure(q, F, t0, temp) - p_t
    after_m = vr.measure(out.q_command, F, t0, temp) - p_t

    def rms3(e: np.ndarray) -> float:
        return float(np.sqrt(np.mean(np.sum(e ** 2, axis=1))))
    rb, ra, rbm, ram = rms3(before), rms3(after), rms3(before_m), rms3(after_m)
    return {"n_poses": n_poses, "rms_before_mm": rb * 1e3, "rms_after_mm": ra * 1e3,
            "max_before_mm": float(np.linalg.norm(before, axis=1).max() * 1e3),
            "max_after_mm": float(np.linalg.norm(after, axis=1).max() * 1e3),
            "fraction_left": ra / rb if rb > 0 else 0.0,
            "meas_frame_rms_before_mm": rbm * 1e3, "meas_frame_rms_after_mm": ram * 1e3,
            "meas_frame_fraction_left": ram / rbm if rbm > 0 else 0.0,
            "status": out.status.value, "reason": out.reason,
            "metric": ("RMS of the 3-D TCP position error in the true base frame of the virtual robot; "
                       "meas_frame_*: the measured point in the measurement frame against its nominal target "
                       "mapped by the identified registration")}


def validate_on(model: IdentifiedModel, m: Measurements) -> dict[str, Any]:
    """Held-out validation on a separate measurement file (a given split).

    Returns per-axis RMS (mm) of ``predict(model) - measured`` and, for reference,
    of the nominal robot with the identified registration and measured point.
    """
    if m.p is None:
        raise DataError(f"{m.source}: the validation file has no measured positions (x, y, z)")
    r = predict(model, m) - m.p
    nominal = IdentifiedModel(nominal=model.nominal, theta=make_layout(model.nominal).nominal.copy(), R0=model.R0,
                              tau_scale=model.tau_scale, gravity_on=False, beams=model.beams, knots=model.knots,
                              time_ref=model.time_ref, temperature_ref=model.temperature_ref)
    for g in ("reg.w", "reg.t", "tool.p"):
        nominal.theta[GROUP_SLICES[g]] = model.theta[GROUP_SLICES[g]]
    r0 = predict(nominal, m) - m.p
    return {"file": m.source, "n_rows": m.n, "rms_mm": _rms(r) * 1e3, "rms_nominal_mm": _rms(r0) * 1e3,
            "max_mm": float(np.linalg.norm(r, axis=1).max() * 1e3)}
