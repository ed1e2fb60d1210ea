"""Which poses to measure: optimal experiment design of a measurement campaign for a region.

:func:`design_campaign` chooses ``n`` rows of a pool of joint configurations (optionally loaded)
whose measurement would most reduce the predicted uncertainty of an identified model where it
is used, linearised at the model's parameters:

* **Parameters.**  The model's free parameters (:attr:`models.arm.ArmModel.covariance_names`),
  their Jacobian ``J = dp/dtheta`` at any pose by
  :func:`problems.identify.uncertainty.parameter_jacobian` (measurement frame).  The new campaign
  is measured in its own frame (``new_registration=True``): its registration columns
  (``reg.t``, ``reg.w``) are a separate block of the parameter vector, as are those of every
  earlier campaign but the last (which is the model's own registration).  Parameters are
  scaled so that their pool columns have unit RMS (nothing below depends on the scaling).
* **Prior.**  Earlier data (``earlier``) give the information ``sum J^T J / s^2`` (``s`` the
  row's ``sigma`` when the file has one, else :attr:`~models.arm.ArmModel.residual_sigma_m`);
  without earlier data the design is from scratch: only a tiny ridge
  (:data:`DESIGN_PRIOR_POSES`) keeps the information invertible.
* **Noise.**  Each new row adds ``J_i^T J_i / s^2``, ``s = residual_sigma_m`` per axis.
* **Criterion.**  ``"task"`` (default): minimise the mean over the evaluation poses of
  ``trace(J_e P J_e^T)`` (``P`` the posterior covariance): the mean predicted variance of the
  position, parameters' part.  ``"d"``: maximise ``log det`` of the information (D-optimal).
* **Greedy selection** with rank-3 Sherman-Morrison-Woodbury updates, vectorised over the pool:
  with ``A_i = J_i P``, ``S_i = s^2 I + A_i J_i^T`` the gain of row ``i`` is
  ``trace(S_i^-1 A_i M A_i^T)`` (``M = mean_e J_e^T J_e``) for ``task`` and
  ``log det(S_i / s^2)`` for ``d``; then a Fedorov exchange pass (:data:`EXCHANGE_PASSES`): each
  chosen row is swapped for the pool row that gains most once it is removed, while that helps.
* **Model-robust selection** (DuMouchel & Jones 1994).  What the model lacks is not in its
  parameters, and a design optimal for them alone piles its poses where those parameters act most,
  wherever that is.  The selection therefore also counts *potential terms*: an unmodelled angular
  error of each joint over the evaluation poses' range of that joint (hat functions on
  :data:`DESIGN_POTENTIAL_KNOTS` knots, zero outside the range), acting through the joint's
  ``dp/ddtheta_j``, each with the prior standard deviation :data:`DESIGN_POTENTIAL_SIGMA_RAD`
  (earlier data inform them too).  Only rows within the region's joint ranges pin them down, so
  the design measures where the region is.  The sigmas reported are the model's own (its
  parameters' posterior after the chosen rows).  Off by default (``potential_knots=0``: the
  model's parameters alone); an option of the library, not of the command line.
* **Evaluation poses.**  ``eval_q`` (and ``eval_wrench``), or the pool itself.  ``eval_frame``
  ``"measurement"``: the new campaign's measurement frame (its registration counts);
  ``"base"``: the base frame (the registration does not act, :func:`~.uncertainty.to_base_frame`).
* **Guards.**  Pool rows outside the robot's joint limits, or whose nominal 6x6 Jacobian has a
  condition number above :data:`DESIGN_MAX_JACOBIAN_COND`, are set aside and counted.
* **Unidentifiable parameters.**  A pivoted Gram-Schmidt on the column-normalised stacked
  Jacobian of the usable pool (:func:`problems.identify.identifiability.select_identifiable`,
  tolerance :data:`DESIGN_IDENT_REL_TOL`) names the parameters no pool pose can identify, and
  whether the earlier data determine them.
* **Travel order.**  The chosen rows are ordered by nearest neighbour then 2-opt on the time
  metric ``max_j |dq_j| / v_max_j`` (the robot's joint velocity limits).

The predicted sigma reported per evaluation pose is the RMS over the three axes of the
parameters' part, ``sqrt(trace(J_e P J_e^T) / 3)``, m: before the campaign (the earlier data's
information, or the model's own covariance when no earlier data are given; the new campaign's
registration is left out, it exists only once measured), after it, and after ``n`` random
usable pool rows (mean over ``random_trials`` subsets: the baseline).

:func:`task_region` (:mod:`.design_region`) turns a planning problem into evaluation poses and a
pool around its path.
The library prints nothing.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from models import effects as fx
from models.arm import ArmModel
from models.errors import InputError
from models.status import Status

from ..measurements import Measurements
from ..virtual.campaign import SIM_MAX_JACOBIAN_COND
from .design_region import TASK_MARGIN_RAD, TASK_MAX_EVAL_POSES, TASK_POOL_POSES, TaskRegion, task_region
from .identifiability import IDENT_REL_TOL, select_identifiable
from .travel import travel_order
from .uncertainty import outside_joints, parameter_jacobian, to_base_frame

#: Design criteria: ``task`` (mean predicted variance over the evaluation poses), ``d`` (log det).
DESIGN_CRITERIA = ("task", "d")
#: Frames the evaluation poses' positions are taken in.
EVAL_FRAMES = ("measurement", "base")
#: A pool row whose nominal 6x6 Jacobian has a larger condition number is set aside (near a
#: singularity); the virtual robot's campaigns use the same bound.
DESIGN_MAX_JACOBIAN_COND = SIM_MAX_JACOBIAN_COND
#: Prior information per (scaled) parameter without earlier data, in poses' worth: a ridge
#: that keeps the information invertible and acts on nothing the pool can identify.
DESIGN_PRIOR_POSES = 1e-6
#: Potential terms of the model-robust design (DuMouchel & Jones 1994): an unmodelled angular
#: error of each joint over the evaluation poses' range of that joint, as hat functions on this
#: many evenly spaced knots (zero outside the range), that the campaign should also pin down.
#: 0 (the default): the model's own parameters alone -- on the virtual benchmark
#: (benchmarks/bench_design.py) 6 knots did not beat the model's own criterion.
DESIGN_POTENTIAL_KNOTS = 0
#: Prior standard deviation of each potential term, rad (a gear's periodic error).
DESIGN_POTENTIAL_SIGMA_RAD = 1e-4
#: Relative tolerance of the unidentifiability test (the identification's own).
DESIGN_IDENT_REL_TOL = IDENT_REL_TOL
#: Fedorov exchange passes after the greedy selection (each costs about ``n`` greedy steps).
EXCHANGE_PASSES = 2
#: An exchange is made only when it gains more than this fraction of the criterion's value.
EXCHANGE_REL_GAIN = 1e-9
#: Random subsets of the baseline (``design_campaign(random_trials=...)``).
RANDOM_TRIALS = 20
#: Rows named per guard (the first ones, by file line).
GUARD_LINES_NAMED = 5


class DesignStatus(Status):
    """Outcome of a campaign design (``.value`` is the ``report.json`` string)."""

    OK = "ok"
    #: chosen, but some parameters no pool row identifies and the earlier data do not determine
    UNIDENTIFIABLE = "unidentifiable_parameters"

    @property
    def usable(self) -> bool:
        return True


@dataclass
class SetAside:
    """Pool rows set aside by a guard: how many, and the file lines of the first ones."""

    reason: str
    count: int
    lines: list[int]

    def to_dict(self) -> dict[str, Any]:
        return {"reason": self.reason, "count": self.count, "lines": list(self.lines)}


@dataclass
class Unidentifiable:
    """A parameter no usable pool row can identify (not excited, or a combination of others)."""

    name: str
    reason: str
    determined_by_earlier: bool

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "reason": self.reason, "determined_by_earlier": self.determined_by_earlier}


@dataclass
class CampaignDesign:
    """A designed measurement campaign.

    Attributes
    ----------
    status : DesignStatus
    reason : str
        One sentence on the status.
    chosen : ndarray of int, shape (n,)
        Pool row indices (0-based), in travel order.
    criterion : str
        ``"task"`` or ``"d"``.
    eval_frame : str
        Frame of the evaluation poses' positions (``"measurement"`` or ``"base"``).
    sigma_before_m, sigma_after_m, sigma_random_m : ndarray, shape (N_e,)
        Per evaluation pose: the RMS over the three axes of the parameters' part of the predicted
        sigma, m, before the campaign, after it, and after ``n`` random usable pool rows (mean
        over the random subsets).
    variance_before_m2, variance_after_m2, variance_random_m2 : float
        The task criterion: mean over the evaluation poses of ``trace(J_e P J_e^T)``, m^2 (the
        random one: mean over the subsets).
    logdet_gain_after, logdet_gain_random : float
        The D criterion: ``log det`` of the information after minus before (dimensionless; the
        random one: mean over the subsets).
    unidentifiable : list of Unidentifiable
    guards : dict of str to SetAside
        ``"outside_limits"`` and ``"near_singularity"``.
    travel_s : float
        Estimated travel time of the ordered visit at the joint velocity limits, s (sum over
        moves of ``max_j |dq_j| / v_max_j``; no acceleration).
    n_pool, n_usable, n_eval : int
        Pool rows, rows left after the guards, evaluation poses.
    random_trials : int
    notes : list of str
        What the design assumed (e.g. the source of the "before" sigma).
    """

    status: DesignStatus
    reason: str
    chosen: np.ndarray
    criterion: str
    eval_frame: str
    sigma_before_m: np.ndarray
    sigma_after_m: np.ndarray
    sigma_random_m: np.ndarray
    variance_before_m2: float
    variance_after_m2: float
    variance_random_m2: float
    logdet_gain_after: float
    logdet_gain_random: float
    unidentifiable: list[Unidentifiable]
    guards: dict[str, SetAside]
    travel_s: float
    n_pool: int
    n_usable: int
    n_eval: int
    random_trials: int
    notes: list[str] = field(default_factory=list)

    @staticmethod
    def region_sigma_m(sigma: np.ndarray) -> float:
        """One figure for the region: the RMS over the evaluation poses of a per-pose sigma, m."""
        return float(np.sqrt(np.mean(np.asarray(sigma) ** 2)))

    def to_dict(self) -> dict[str, Any]:
        """Everything, JSON-ready (SI units)."""
        return {
            "status": self.status.value,
            "reason": self.reason,
            "criterion": self.criterion,
            "eval_frame": self.eval_frame,
            "chosen": [int(i) for i in self.chosen],
            "n_pool": self.n_pool,
            "n_usable": self.n_usable,
            "n_eval": self.n_eval,
            "random_trials": self.random_trials,
            "region_sigma_before_m": self.region_sigma_m(self.sigma_before_m),
            "region_sigma_after_m": self.region_sigma_m(self.sigma_after_m),
            "region_sigma_random_m": self.region_sigma_m(self.sigma_random_m),
            "sigma_before_m": self.sigma_before_m.tolist(),
            "sigma_after_m": self.sigma_after_m.tolist(),
            "sigma_random_m": self.sigma_random_m.tolist(),
            "variance_before_m2": self.variance_before_m2,
            "variance_after_m2": self.variance_after_m2,
            "variance_random_m2": self.variance_random_m2,
            "logdet_gain_after": self.logdet_gain_after,
            "logdet_gain_random": self.logdet_gain_random,
            "unidentifiable": [u.to_dict() for u in self.unidentifiable],
            "guards": {k: g.to_dict() for k, g in self.guards.items()},
            "travel_s": self.travel_s,
            "notes": list(self.notes),
        }


# ------------------------------------------------------------------------------ parameters
@dataclass
class _Layout:
    """The design's parameter vector: the model's free parameters, then the new campaign's
    registration block, then one registration block per earlier campaign but the last."""

    names: list[str]
    k: int
    reg_idx: np.ndarray  # positions of the registration columns within the first k
    new_reg: np.ndarray | None  # columns of the new campaign's registration block (or None: shared)
    earlier_reg: list[np.ndarray | None]  # per earlier file: its own block (None: the model's)

    @property
    def size(self) -> int:
        return len(self.names)


def _layout(names: list[str], n_earlier: int, new_registration: bool) -> _Layout:
    k = len(names)
    reg = np.array([i for i, n in enumerate(names) if n in fx.REGISTRATION_NAMES], dtype=int)
    out = list(names)
    new_reg = None
    if new_registration and len(reg):
        new_reg = np.arange(len(out), len(out) + len(reg))
        out += [f"{names[i]} (new campaign)" for i in reg]
    earlier_reg: list[np.ndarray | None] = []
    for e in range(n_earlier):
        if e == n_earlier - 1 or not len(reg):
            earlier_reg.append(None)
        else:
            earlier_reg.append(np.arange(len(out), len(out) + len(reg)))
            out += [f"{names[i]} (earlier campaign {e + 1})" for i in reg]
    return _Layout(out, k, reg, new_reg, earlier_reg)


def _place(J: np.ndarray, lay: _Layout, reg_block: np.ndarray | None) -> np.ndarray:
    """A Jacobian over the model's k free parameters (N, 3, k) in the design's layout, its
    registration columns moved into ``reg_block`` (None: kept in place)."""
    out = np.zeros(J.shape[:2] + (lay.size,))
    out[:, :, : lay.k] = J
    if reg_block is not None and len(lay.reg_idx):
        out[:, :, reg_block] = J[:, :, lay.reg_idx]
        out[:, :, lay.reg_idx] = 0.0
    return out


def _model_for_earlier(model: ArmModel, e: int, n_earlier: int) -> ArmModel:
    """The model with earlier campaign ``e``'s registration when the model's campaigns match the
    earlier files one for one (a several-campaign fit), else the model itself."""
    if len(model.campaigns) == n_earlier and n_earlier > 1:
        return model.for_campaign(model.campaigns[e].name)
    return model


def _check_model(model: ArmModel) -> float:
    """The model's residual sigma (m); InputError when it carries no covariance."""
    where = model.source or f"model of robot '{model.name}'"
    if model.covariance is None or not model.covariance_names:
        raise InputError(
            f"{where}: has no parameter covariance (a nominal robot, or a model file written before format 2); "
            "re-identify it with this version of compplan (compplan identify) to design a campaign"
        )
    s = model.residual_sigma_m if model.residual_sigma_m else model.noise_sigma_m
    if not s or not np.isfinite(s) or s <= 0:
        raise InputError(f"{where}: has no residual sigma; re-identify it with this version of compplan")
    return float(s)


# ------------------------------------------------------------------------------ guards
def _nominal_cond(model: ArmModel, q: np.ndarray) -> np.ndarray:
    """Condition number of the nominal 6x6 Jacobian (with the model's tool) at ``q`` (N, 6)."""
    from models.symbolic import KinematicModel

    n = len(q)
    if n == 0:
        return np.zeros(0)
    fk = KinematicModel(model.nominal).kinetostatics
    _p, _R, J, _C = fk.map(n, "thread", 2)(q.T)
    J = np.asarray(J).reshape(6, n, 6).transpose(1, 0, 2)
    with np.errstate(all="ignore"):
        c = np.linalg.cond(J)
    return np.where(np.isfinite(c), c, np.inf)


def pool_guards(model: ArmModel, pool: Measurements) -> tuple[np.ndarray, dict[str, SetAside]]:
    """The usable pool rows (boolean mask, (N,)) and the rows set aside: outside the robot's
    joint limits, or near a singularity (nominal Jacobian condition number above
    :data:`DESIGN_MAX_JACOBIAN_COND`)."""
    q = np.asarray(pool.q, dtype=float)
    lo, hi = model.nominal.q_min, model.nominal.q_max
    outside = np.any((q < lo) | (q > hi), axis=1)
    cond = np.full(len(q), np.inf)
    cond[~outside] = _nominal_cond(model, q[~outside])
    singular = ~outside & (cond > DESIGN_MAX_JACOBIAN_COND)
    lines = np.asarray(pool.line, dtype=int)

    def named(mask: np.ndarray, reason: str) -> SetAside:
        return SetAside(reason, int(mask.sum()), [int(v) for v in lines[mask][:GUARD_LINES_NAMED]])

    guards = {
        "outside_limits": named(outside, "outside the robot's joint limits"),
        "near_singularity": named(
            singular, f"near a singularity (nominal Jacobian condition number > {DESIGN_MAX_JACOBIAN_COND:g})"
        ),
    }
    return ~outside & ~singular, guards


# ------------------------------------------------------------------------------ gains
def _solve3(S: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``S^-1 B`` for a stack of 3x3 systems."""
    return np.linalg.solve(S, B)


def greedy_gains(
    P: np.ndarray, Jc: np.ndarray, s2: float, criterion: str, M: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gain of adding each candidate row to a posterior covariance ``P``.

    Parameters
    ----------
    P : ndarray, shape (p, p)
        Posterior covariance (design's scaled parameters).
    Jc : ndarray, shape (N, 3, p)
        Candidate rows' Jacobians.
    s2 : float
        Noise variance per axis of a new row.
    criterion : {"task", "d"}
    M : ndarray, shape (p, p)
        ``mean_e J_e^T J_e`` (task criterion).

    Returns
    -------
    gain : ndarray, shape (N,)
        ``task``: reduction of ``trace(M P)``, ``trace(S^-1 A M A^T)``; ``d``: increase of
        ``log det`` of the information, ``log det(S / s2)``.
    A : ndarray, shape (N, 3, p)
        ``J_i P``.
    S : ndarray, shape (N, 3, 3)
        ``s2 I + A_i J_i^T``.
    """
    A = Jc @ P
    S = s2 * np.eye(3) + A @ np.swapaxes(Jc, 1, 2)
    if criterion == "task":
        assert M is not None
        T = (A @ M) @ np.swapaxes(A, 1, 2)
        gain = np.trace(_solve3(S, T), axis1=1, axis2=2)
    else:
        _sign, ld = np.linalg.slogdet(S)
        gain = ld - 3.0 * np.log(s2)
    return gain, A, S


def _add(P: np.ndarray, A: np.ndarray, S: np.ndarray) -> np.ndarray:
    """Posterior after adding a row: ``P - A^T S^-1 A`` (symmetrised)."""
    P = P - A.T @ np.linalg.solve(S, A)
    return 0.5 * (P + P.T)


def _remove(P: np.ndarray, J: np.ndarray, s2: float) -> np.ndarray:
    """Posterior after removing a row of Jacobian ``J`` (3, p): ``P + A^T (s2 I - A J^T)^-1 A``."""
    A = J @ P
    S = s2 * np.eye(3) - A @ J.T
    P = P + A.T @ np.linalg.solve(S, A)
    return 0.5 * (P + P.T)


def _inv_spd(I: np.ndarray) -> np.ndarray:
    """Inverse of a symmetric positive definite matrix (Cholesky), symmetrised."""
    L = np.linalg.cholesky(I)
    Li = np.linalg.solve(L, np.eye(len(I)))
    return Li.T @ Li


def select_greedy(
    P0: np.ndarray,
    Jc: np.ndarray,
    n: int,
    s2: float,
    criterion: str,
    M: np.ndarray | None = None,
    exchange_passes: int = EXCHANGE_PASSES,
) -> tuple[np.ndarray, np.ndarray]:
    """Greedy choice of ``n`` candidate rows (then Fedorov exchange passes).

    Returns the chosen indices into ``Jc`` (in the order chosen; exchanged rows take the place of
    those they replace) and the posterior covariance after them.
    """
    N = len(Jc)
    avail = np.ones(N, dtype=bool)
    chosen: list[int] = []
    P = P0.copy()
    for _ in range(n):
        idx = np.flatnonzero(avail)
        gain, A, S = greedy_gains(P, Jc[idx], s2, criterion, M)
        b = int(np.argmax(gain))
        i = int(idx[b])
        P = _add(P, A[b], S[b])
        chosen.append(i)
        avail[i] = False
    for _ in range(exchange_passes):
        changed = False
        for pos in range(len(chosen)):
            j = chosen[pos]
            Pm = _remove(P, Jc[j], s2)
            idx = np.append(np.flatnonzero(avail), j)
            gain, A, S = greedy_gains(Pm, Jc[idx], s2, criterion, M)
            b = int(np.argmax(gain))
            scale = abs(float(gain[-1])) + 1e-300
            if idx[b] != j and gain[b] - gain[-1] > EXCHANGE_REL_GAIN * scale:
                i = int(idx[b])
                avail[i], avail[j] = False, True
                chosen[pos] = i
                P = _add(Pm, A[b], S[b])
                changed = True
        if not changed:
            break
    return np.array(chosen, dtype=int), P


# ------------------------------------------------------------------------------ the design
def _eval_jacobian(
    model: ArmModel, q: np.ndarray, wrench: np.ndarray | None, names: list[str], lay: _Layout, frame: str
) -> np.ndarray:
    _p, J = parameter_jacobian(model, q, wrench, names)
    if frame == "base":
        return _place(to_base_frame(model, J, names), lay, None)
    return _place(J, lay, lay.new_reg)


def _with_potential(
    J: np.ndarray,
    model: ArmModel,
    q: np.ndarray,
    wrench: np.ndarray | None,
    knots: int,
    tau: float,
    frame: str,
    q_range: np.ndarray,
) -> np.ndarray:
    """``J`` (N, 3, p) with the potential terms' columns appended (N, 3, p + 6 K), scaled by ``tau``:
    joint ``j``'s angular error as hat functions of ``q_j`` on ``K = knots`` evenly spaced knots over
    ``q_range[j]`` (rad, (6, 2): the evaluation poses' range; zero outside it), acting through
    ``dp/ddtheta_j`` (the joint's angle offset; in the base frame rotated as
    :func:`~.uncertainty.to_base_frame`)."""
    if knots <= 0:
        return J
    names = [f"dtheta[{j}]" for j in range(1, 7)]
    _p, Jt = parameter_jacobian(model, q, wrench, names)
    if frame == "base":
        Jt = to_base_frame(model, Jt, names)
    q = np.atleast_2d(np.asarray(q, dtype=float))
    lo, hi = q_range[:, 0], q_range[:, 1]
    width = np.maximum(hi - lo, 1e-9) / max(knots - 1, 1)
    centres = lo[:, None] + width[:, None] * np.arange(knots)  # (6, K)
    u = np.abs(q[:, :, None] - centres[None]) / width[None, :, None]  # (N, 6, K)
    inside = ((q >= lo - 1e-12) & (q <= hi + 1e-12))[:, :, None]
    basis = np.where(inside, np.maximum(1.0 - u, 0.0), 0.0) if knots > 1 else inside.astype(float)
    K = (Jt[:, :, :, None] * basis[:, None, :, :]).reshape(len(q), 3, -1)
    return np.concatenate([J, tau * K], axis=2)


def _sigma_rms(Je: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Per pose: ``sqrt(trace(J_e P J_e^T) / 3)``."""
    v = np.einsum("nik,kl,nil->n", Je, P, Je)
    return np.sqrt(np.maximum(v, 0.0) / 3.0)


def design_campaign(
    model: ArmModel,
    pool: Measurements,
    n: int,
    *,
    eval_q: np.ndarray | None = None,
    eval_wrench: np.ndarray | None = None,
    eval_frame: str = "measurement",
    earlier: Sequence[Measurements] = (),
    criterion: str = "task",
    new_registration: bool = True,
    random_trials: int = RANDOM_TRIALS,
    seed: int = 0,
    potential_knots: int = DESIGN_POTENTIAL_KNOTS,
) -> CampaignDesign:
    """Choose ``n`` pool rows to measure (module docstring: the method).

    Parameters
    ----------
    model : ArmModel
        An identified model with its parameter covariance (format 2).
    pool : Measurements
        Candidate rows: ``q`` (N, 6), rad, and ``wrench`` (N, 6), base frame, N and N*m
        (positions not needed).
    n : int
        Rows to choose, 1 .. usable pool rows.
    eval_q : ndarray, shape (N_e, 6), optional
        Evaluation poses, rad (default: the usable pool rows).
    eval_wrench : ndarray, shape (N_e, 6) or (6,), optional
        Their base-frame TCP wrenches (default zero; the pool's own with the pool).
    eval_frame : {"measurement", "base"}
    earlier : sequence of Measurements
        Campaigns measured so far (their commands, loads and, when given, ``sigma``).
    criterion : {"task", "d"}
    new_registration : bool
        The new campaign is measured in a frame of its own (its registration a separate block).
    random_trials : int
        Random subsets of ``n`` usable pool rows for the baseline (>= 1).
    seed : int
        Seed of the random subsets.
    potential_knots : int
        Knots of the potential terms per joint (:data:`DESIGN_POTENTIAL_KNOTS`; 0: none).

    Returns
    -------
    CampaignDesign

    Raises
    ------
    InputError
        A model without covariance, an unknown criterion or frame, ``n`` out of range.
    """
    if criterion not in DESIGN_CRITERIA:
        raise InputError(f"criterion {criterion!r}: expected one of {', '.join(DESIGN_CRITERIA)}")
    if eval_frame not in EVAL_FRAMES:
        raise InputError(f"eval_frame {eval_frame!r}: expected one of {', '.join(EVAL_FRAMES)}")
    s = _check_model(model)
    s2 = s * s
    usable, guards = pool_guards(model, pool)
    uidx = np.flatnonzero(usable)
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 1 <= n <= len(uidx):
        raise InputError(
            f"n = {n!r}: expected an integer from 1 to {len(uidx)}, the usable rows of the pool {pool.source} "
            f"({pool.n} rows, {pool.n - len(uidx)} set aside by the guards)"
        )
    names = list(model.covariance_names)
    lay = _layout(names, len(earlier), new_registration)
    notes: list[str] = []

    # pool Jacobian (usable rows), the new campaign's layout
    _p, Jp = parameter_jacobian(model, pool.q[uidx], pool.wrench[uidx], names)
    Jc = _place(Jp, lay, lay.new_reg)
    Je_rows, w_rows = _earlier_rows(model, earlier, names, lay, s)
    # evaluation poses
    if eval_q is None:
        eq, ew = pool.q[uidx], pool.wrench[uidx]
    else:
        eq = np.atleast_2d(np.asarray(eval_q, dtype=float))
        ew = None if eval_wrench is None else np.asarray(eval_wrench, dtype=float)
    Jev = _eval_jacobian(model, eq, ew, names, lay, eval_frame)
    out_eval = int(outside_joints(model, eq).any(axis=1).sum())
    if out_eval:
        notes.append(
            f"{out_eval} of the {len(eq)} evaluation poses lie outside the joint ranges the model was identified "
            "on: its sigma there is a linearised extrapolation and can be optimistic (a joint error map is held "
            "at its end value beyond its range; docs/identification.md, section 10)"
        )

    scale = _column_scale([Jc] + Je_rows)
    Jc = Jc / scale
    Jev = Jev / scale
    # the model's own information (what the reported sigmas use)
    n_prim = lay.size
    I0p = np.eye(n_prim) * (DESIGN_PRIOR_POSES / s2)
    for Jx, w in zip(Je_rows, w_rows):
        Jw = (Jx / scale) * w[:, None, None]
        I0p += np.einsum("nik,nil->kl", Jw, Jw)
    P0p = _inv_spd(I0p)
    Mp = np.einsum("nik,nil->kl", Jev, Jev) / len(Jev)
    _sign, ld0 = np.linalg.slogdet(I0p)
    # the selection's information: with the potential terms when asked for
    Jca, Jeva, I0 = _selection_problem(
        model, pool.subset(uidx), Jc, Jev, eq, ew, eval_frame, earlier, Je_rows, w_rows, scale, I0p, potential_knots
    )
    if Jca.shape[2] > n_prim:
        notes.append(
            "selection: model-robust, with an unmodelled angular error of each joint over the region's range "
            f"({int(potential_knots)} knots, prior {DESIGN_POTENTIAL_SIGMA_RAD:g} rad) as potential terms; the "
            "sigmas reported are the model's own"
        )
    M = np.einsum("nik,nil->kl", Jeva, Jeva) / len(Jeva)

    sel, _P = select_greedy(_inv_spd(I0), Jca, int(n), s2, criterion, M)

    def posterior(rows: np.ndarray) -> np.ndarray:
        """The model's own posterior covariance after ``rows`` of the pool (scaled)."""
        return _inv_spd(I0p + np.einsum("nik,nil->kl", Jc[rows], Jc[rows]) / s2)

    def logdet_gain(Pc: np.ndarray) -> float:
        _sg, ldp = np.linalg.slogdet(Pc)
        return float(-ldp - ld0)

    P = posterior(sel)
    sig_before = _sigma_before(model, Jev, lay, scale, P0p if earlier else None, notes)
    if lay.new_reg is not None and eval_frame == "measurement":
        notes.append(
            "before: in the model's measurement frame; after: in the new campaign's, its registration's "
            "uncertainty included"
        )
    sig_after = _sigma_rms(Jev, P)
    trials = max(1, int(random_trials))
    sig_rand, var_rand, ld_rand = _random_baseline(posterior, logdet_gain, Jev, Mp, len(uidx), int(n), trials, seed)

    # unidentifiable parameters over the usable pool (the model's k parameters, pool frame)
    unident = _unidentifiable(Jp, names, [x[:, :, : lay.k] for x in Je_rows], w_rows, s)

    # travel order
    order, travel_s = travel_order(pool.q[uidx[sel]], model.nominal.v_max)
    chosen = uidx[sel[order]]
    status, reason = _status(unident, int(n), len(uidx), criterion)
    return CampaignDesign(
        status=status,
        reason=reason,
        chosen=chosen,
        criterion=criterion,
        eval_frame=eval_frame,
        sigma_before_m=sig_before,
        sigma_after_m=sig_after,
        sigma_random_m=sig_rand,
        variance_before_m2=float(np.mean(3.0 * sig_before**2)),
        variance_after_m2=float(np.trace(Mp @ P)),
        variance_random_m2=var_rand,
        logdet_gain_after=logdet_gain(P),
        logdet_gain_random=ld_rand,
        unidentifiable=unident,
        guards=guards,
        travel_s=travel_s,
        n_pool=pool.n,
        n_usable=len(uidx),
        n_eval=len(Jev),
        random_trials=trials,
        notes=notes,
    )


def _earlier_rows(
    model: ArmModel, earlier: Sequence[Measurements], names: list[str], lay: _Layout, s: float
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """The earlier campaigns' Jacobians placed in the design's layout (each with its own registration
    block but the last), unscaled, and their row weights ``1/sigma`` (the file's, else ``s``)."""
    J_rows: list[np.ndarray] = []
    w_rows: list[np.ndarray] = []
    for e, m in enumerate(earlier):
        me = _model_for_earlier(model, e, len(earlier))
        _pe, Jx = parameter_jacobian(me, m.q, m.wrench, names)
        J_rows.append(_place(Jx, lay, lay.earlier_reg[e]))
        se = np.asarray(m.sigma, dtype=float) if m.sigma is not None else np.full(m.n, s)
        w_rows.append(1.0 / se)
    return J_rows, w_rows


def _column_scale(rows: list[np.ndarray]) -> np.ndarray:
    """Column scales: unit RMS over the rows (N, 3, k) that carry each column (1 for none)."""
    ss = sum(np.einsum("nik,nik->k", R, R) for R in rows)
    cnt = sum(len(R) * 3 * np.any(R != 0, axis=(0, 1)) for R in rows)
    return np.where(ss > 0, np.sqrt(ss / np.maximum(cnt, 1)), 1.0)


def _selection_problem(
    model: ArmModel,
    pool: Measurements,
    Jc: np.ndarray,
    Jev: np.ndarray,
    eq: np.ndarray,
    ew: np.ndarray | None,
    eval_frame: str,
    earlier: Sequence[Measurements],
    Je_rows: list[np.ndarray],
    w_rows: list[np.ndarray],
    scale: np.ndarray,
    I0p: np.ndarray,
    potential_knots: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The selection's pool and evaluation Jacobians and prior information: the model's own (scaled)
    with, when ``potential_knots`` > 0, the potential terms appended (scaled by their prior sigma:
    prior information 1 each, and what the earlier data say of them)."""
    H = max(0, int(potential_knots))
    tau = DESIGN_POTENTIAL_SIGMA_RAD
    n_prim = len(I0p)
    q_range = np.column_stack([eq.min(axis=0), eq.max(axis=0)])
    Jca = _with_potential(Jc, model, pool.q, pool.wrench, H, tau, "measurement", q_range)
    Jeva = _with_potential(Jev, model, eq, ew, H, tau, eval_frame, q_range)
    I0 = np.zeros((Jca.shape[2], Jca.shape[2]))
    I0[:n_prim, :n_prim] = I0p
    if H:
        I0[n_prim:, n_prim:] += np.eye(Jca.shape[2] - n_prim)
        for e, (Jx, w, m) in enumerate(zip(Je_rows, w_rows, earlier)):
            me = _model_for_earlier(model, e, len(earlier))
            K = _with_potential(np.zeros(Jx.shape[:2] + (0,)), me, m.q, m.wrench, H, tau, "measurement", q_range)
            Jw = np.concatenate([Jx / scale, K], axis=2) * w[:, None, None]
            I0[:n_prim, n_prim:] += np.einsum("nik,nil->kl", Jw[:, :, :n_prim], Jw[:, :, n_prim:])
            I0[n_prim:, :n_prim] = I0[:n_prim, n_prim:].T
            I0[n_prim:, n_prim:] += np.einsum("nik,nil->kl", Jw[:, :, n_prim:], Jw[:, :, n_prim:])
    return Jca, Jeva, I0


def _sigma_before(
    model: ArmModel, Jev: np.ndarray, lay: _Layout, scale: np.ndarray, P0: np.ndarray | None, notes: list[str]
) -> np.ndarray:
    """Sigma per evaluation pose before the campaign, in the model's own measurement frame (the new
    campaign's exists only once measured): from the earlier data's posterior ``P0`` (scaled), else from
    the model's own covariance; says which in ``notes``."""
    Jb = Jev.copy()
    if lay.new_reg is not None:
        Jb[:, :, lay.reg_idx] = Jev[:, :, lay.new_reg] * (scale[lay.new_reg] / scale[lay.reg_idx])
        Jb[:, :, lay.new_reg] = 0.0
    if P0 is not None:
        notes.append("before: the information of the earlier data")
        return _sigma_rms(Jb, P0)
    C = np.asarray(model.covariance, dtype=float)
    Cs = C * np.outer(scale[: lay.k], scale[: lay.k])  # covariance of theta * scale
    notes.append("before: the model's own parameter covariance (no earlier data given: a design from scratch)")
    return _sigma_rms(Jb[:, :, : lay.k], Cs)


def _random_baseline(
    posterior: Any, logdet_gain: Any, Jev: np.ndarray, Mp: np.ndarray, n_usable: int, n: int, trials: int, seed: int
) -> tuple[np.ndarray, float, float]:
    """The mean over ``trials`` random subsets of ``n`` usable pool rows: sigma per evaluation pose,
    the task criterion's value and the log-det gain."""
    rng = np.random.default_rng(seed)
    sig_rand = np.zeros(len(Jev))
    var_rand = ld_rand = 0.0
    for _ in range(trials):
        Pr = posterior(rng.choice(n_usable, n, replace=False))
        sig_rand += _sigma_rms(Jev, Pr) / trials
        var_rand += float(np.trace(Mp @ Pr)) / trials
        ld_rand += logdet_gain(Pr) / trials
    return sig_rand, var_rand, ld_rand


def _status(unident: list[Unidentifiable], n: int, n_usable: int, criterion: str) -> tuple[DesignStatus, str]:
    """``unidentifiable_parameters`` when some parameter is determined by no data, else ``ok``."""
    bad = [u for u in unident if not u.determined_by_earlier]
    if bad:
        return DesignStatus.UNIDENTIFIABLE, (
            f"{len(bad)} parameter(s) no pool row can identify and no earlier data determine: "
            + ", ".join(u.name for u in bad)
        )
    return DesignStatus.OK, f"{n} of {n_usable} usable pool rows chosen ({criterion} criterion)"


def _unidentifiable(
    Jp: np.ndarray, names: list[str], earlier: list[np.ndarray], weights: list[np.ndarray], s: float
) -> list[Unidentifiable]:
    """Parameters the usable pool cannot identify (pivoted Gram-Schmidt in the order of
    ``names`` on the column-normalised stacked Jacobian), each with whether the earlier data
    stacked with the pool identify it."""

    def held(J: np.ndarray) -> dict[int, str]:
        A = J.reshape(-1, J.shape[-1])
        nrm = np.linalg.norm(A, axis=0)
        A = A / np.where(nrm > 0, nrm, 1.0)
        _kept, h = select_identifiable(A, list(range(len(names))), 0.0, names)
        return h

    h_pool = held(Jp)
    if not h_pool:
        return []
    h_all = h_pool
    if earlier:
        stacked = [Jp] + [J * (w[:, None, None] * s) for J, w in zip(earlier, weights)]
        h_all = held(np.concatenate(stacked, axis=0))
    return [Unidentifiable(names[i], why.replace("the data", "the pool"), i not in h_all) for i, why in h_pool.items()]


__all__ = [
    "DESIGN_CRITERIA",
    "EVAL_FRAMES",
    "TASK_MARGIN_RAD",
    "TASK_MAX_EVAL_POSES",
    "TASK_POOL_POSES",
    "CampaignDesign",
    "DesignStatus",
    "SetAside",
    "TaskRegion",
    "Unidentifiable",
    "design_campaign",
    "pool_guards",
    "task_region",
    "travel_order",
]
