"""Which poses to measure: optimal experiment design of a measurement campaign for a region.

:func:`design_campaign` chooses ``n`` rows of a pool of joint configurations (optionally loaded)
whose measurement would most reduce the predicted uncertainty of an identified model where it
is used, linearised at the model's parameters:

* **Parameters.**  The model's free parameters (:attr:`models.arm.ArmModel.covariance_names`),
  their Jacobian ``J = dp/dtheta`` at any pose by
  :func:`problems.identify.uncertainty.parameter_jacobian` (measurement frame).  The new campaign
  is measured in its own frame (``new_registration=True``): its registration columns
  (``reg.t``, ``reg.w``) are a separate block of the parameter vector, as are those of every
  earlier campaign but the one whose registration is the model's own (its reference campaign when
  the model's campaigns are the earlier files, else the last).  Parameters are
  scaled so that their pool columns have unit RMS (nothing below depends on the scaling).
* **Prior.**  Earlier data (``earlier``) give the information ``sum J^T J / s^2`` (``s`` the
  row's ``sigma`` when the file has one, else :attr:`~models.arm.ArmModel.residual_sigma_m`);
  without earlier data the design is from scratch, and the prior is what the user has without
  identification, the *nominal model*: each parameter but the set-up's (registration, measured
  point) known to its typical magnitude (``ParamGroup.scale``: prior information ``1/scale^2``); a
  tiny ridge (:data:`DESIGN_PRIOR_POSES`) keeps the set-up's columns invertible.
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
  :data:`~.design_jacobians.DESIGN_TRANSFER_KNOTS` knots, zero outside the range), acting through
  the joint's ``dp/ddtheta_j``, each with a prior standard deviation: inside the model's identified
  ranges :data:`DESIGN_POTENTIAL_SIGMA_RAD`, beyond them the model's calibrated sigma growth there
  (``sigma_growth_rad_per_rad`` times the knot's distance beyond the range,
  :mod:`.sigma_calibration`; earlier data inform them too).  Only rows within the region's joint
  ranges pin them down, so the design measures where the region is, most where the model knows least.
  The sigmas reported are the model's own (its parameters' linearised posterior after the chosen rows,
  without the calibration of :mod:`.sigma_calibration`).  On
  when the evaluation poses lie beyond the model's identified ranges and its sigma grows there
  (:func:`~.design_jacobians.auto_knots`), off otherwise (the model's parameters alone);
  ``potential_knots`` sets it in the library.
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
information, or the nominal model's when no earlier data are given; the set-up's parameters are
left out, the new campaign's exist only once measured), after it, and after ``n`` random
usable pool rows (mean over ``random_trials`` subsets: the baseline).

* **Loads** (:mod:`.design_loads`).  The parameters that act through the region's load (joint
  stiffness: the load changes their sensitivity) and their share of the region's variance; when
  they dominate it after the campaign and the pool has no loaded row, the status is
  ``needs_loads`` (no campaign from that pool can determine them).

:func:`task_region` (:mod:`.design_region`) turns a planning problem into evaluation poses and a
pool around its path.
The library prints nothing.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from models import effects as fx
from models.arm import ArmModel
from models.errors import InputError

from ..measurements import Measurements
from ..virtual.campaign import SIM_MAX_JACOBIAN_COND
from .design_greedy import inv_spd, select_greedy, sigma_rms
from .design_jacobians import (
    DESIGN_POTENTIAL_SIGMA_RAD,
    auto_knots,
    DesignLayout,
    column_scale,
    design_layout,
    earlier_rows,
    own_campaign,
    eval_jacobian,
    place_columns,
    selection_problem,
)
from .design_loads import LoadCheck, load_parameters, load_share
from .design_result import CampaignDesign, DesignStatus, SetAside, Unidentifiable
from .identifiability import IDENT_REL_TOL, select_identifiable
from .travel import travel_order
from .uncertainty import outside_joints, parameter_jacobian

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
#: Relative tolerance of the unidentifiability test (the identification's own).
DESIGN_IDENT_REL_TOL = IDENT_REL_TOL
#: The set-up's parameters (registration, measured point): no nominal prior, known by no one before
#: a campaign measures them.
SETUP_NAMES = frozenset(
    fx.PARAM_NAMES[i]
    for g in ("reg.t", "reg.w", "tool.p", "tool.r")
    for i in range(*fx.GROUP_SLICES[g].indices(fx.N_PARAMS))
)
#: Random subsets of the baseline (``design_campaign(random_trials=...)``).
RANDOM_TRIALS = 20
#: Rows named per guard (the first ones, by file line).
GUARD_LINES_NAMED = 5


# ------------------------------------------------------------------------------ parameters
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


# ------------------------------------------------------------------------------ the design
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
    potential_knots: int | None = None,
) -> CampaignDesign:
    """Choose ``n`` pool rows to measure (module docstring: the method).

    Parameters
    ----------
    model : ArmModel
        An identified model with its parameter covariance (format 2).
    pool : Measurements
        Candidate rows: ``q`` (N, 6), rad, and ``wrench`` (N, 6), base frame, N and N*m (no positions).
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
    potential_knots : int, optional
        Potential terms' knots per joint (0: none; default: :func:`.design_jacobians.auto_knots`).

    Returns
    -------
    CampaignDesign

    Raises
    ------
    InputError
        A model without covariance, an unknown criterion or frame, ``n`` out of range.
    """
    s, uidx, guards = _checked_request(model, pool, n, criterion, eval_frame)
    names = list(model.covariance_names)
    lay = design_layout(names, len(earlier), new_registration, own_campaign(model, len(earlier)))
    notes: list[str] = []
    mats = _design_matrices(
        model, pool, uidx, names, lay, s, (eval_q, eval_wrench, eval_frame), earlier, potential_knots, notes
    )
    sel, _P = select_greedy(inv_spd(mats.I0), mats.Jca, int(n), s * s, criterion, mats.M)
    spread = _uncertainty_fields(model, mats, lay, sel, s, eval_frame, earlier, uidx, n, random_trials, seed, notes)
    unident = _pool_unidentifiable(mats, names, lay, s)
    order, travel_s = travel_order(pool.q[uidx[sel]], model.nominal.v_max)
    loads = _load_check(model, pool, uidx, sel, mats, names, lay, (eval_q, eval_wrench, eval_frame), s)
    status, reason = _status(unident, int(n), len(uidx), criterion, loads, spread["sigma_after_m"], notes)
    return CampaignDesign(
        status=status,
        reason=reason,
        chosen=uidx[sel[order]],
        criterion=criterion,
        eval_frame=eval_frame,
        unidentifiable=unident,
        guards=guards,
        travel_s=travel_s,
        n_pool=pool.n,
        n_usable=len(uidx),
        n_eval=len(mats.Jev),
        notes=notes,
        loads=loads,
        **spread,
    )


def _load_check(
    model: ArmModel,
    pool: Measurements,
    uidx: np.ndarray,
    sel: np.ndarray,
    mats: _DesignMatrices,
    names: list[str],
    lay: DesignLayout,
    evaluation: tuple[np.ndarray | None, np.ndarray | None, str],
    s: float,
) -> LoadCheck:
    """The parameters that act through the region's load, their share of its variance before and
    after the chosen rows, and the pool's and the chosen rows' loaded poses."""
    eval_q, eval_wrench, eval_frame = evaluation
    eq, ew = (pool.q[uidx], pool.wrench[uidx]) if eval_q is None else (eval_q, eval_wrench)
    mask_k = load_parameters(model, eq, ew, names, eval_frame)
    mask = np.zeros(lay.size, dtype=bool)
    mask[: lay.k] = mask_k
    loaded_rows = np.any(np.asarray(pool.wrench, dtype=float)[uidx] != 0, axis=1)
    P_after = _OwnPosterior(mats.I0p, mats.Jc, s * s)(sel)
    return LoadCheck(
        parameters=[names[k] for k in np.flatnonzero(mask_k)],
        share_before=load_share(mats.Jev, mats.P0p, mask),
        share_after=load_share(mats.Jev, P_after, mask),
        pool_loaded=int(loaded_rows.sum()),
        chosen_loaded=int(loaded_rows[sel].sum()),
    )


@dataclass(frozen=True)
class _DesignMatrices:
    """The design's matrices (parameters scaled by ``scale``).

    ``Jp``: pool Jacobian, model's parameters; ``Jc``/``Jev``: the new campaign's pool rows and the
    evaluation poses, design layout; ``Je_rows``/``w_rows``: earlier campaigns' rows and weights;
    ``I0p``/``P0p``: the model's own prior information and its inverse; ``Mp``: evaluation moment;
    ``Jca``/``I0``/``M``: the same for the selection (with the potential terms when asked for).
    """

    Jp: np.ndarray
    Jc: np.ndarray
    Je_rows: list[np.ndarray]
    w_rows: list[np.ndarray]
    Jev: np.ndarray
    scale: np.ndarray
    I0p: np.ndarray
    P0p: np.ndarray
    Mp: np.ndarray
    Jca: np.ndarray
    I0: np.ndarray
    M: np.ndarray


def _design_matrices(
    model: ArmModel,
    pool: Measurements,
    uidx: np.ndarray,
    names: list[str],
    lay: DesignLayout,
    s: float,
    evaluation: tuple[np.ndarray | None, np.ndarray | None, str],
    earlier: Sequence[Measurements],
    potential_knots: int | None,
    notes: list[str],
) -> _DesignMatrices:
    """Jacobians and information matrices of the design (``evaluation``: eval_q, eval_wrench, eval_frame)."""
    eval_q, eval_wrench, eval_frame = evaluation
    s2 = s * s
    # pool Jacobian (usable rows), the new campaign's layout
    _p, Jp = parameter_jacobian(model, pool.q[uidx], pool.wrench[uidx], names)
    Jc = place_columns(Jp, lay, lay.new_reg)
    Je_rows, w_rows = earlier_rows(model, earlier, names, lay, s)
    eq, ew = _evaluation_poses(model, pool, uidx, eval_q, eval_wrench, notes)
    Jev = eval_jacobian(model, eq, ew, names, lay, eval_frame)
    potential_knots = auto_knots(model, eq, potential_knots)

    scale = column_scale([Jc] + Je_rows)
    Jc = Jc / scale
    Jev = Jev / scale
    # the model's own information (what the reported sigmas use)
    n_prim = lay.size
    I0p = _prior_information(n_prim, s2, Je_rows, w_rows, scale)
    if not earlier:
        I0p += np.diag(nominal_prior_information(model, names, lay, scale))
    P0p = inv_spd(I0p)
    Mp = np.einsum("nik,nil->kl", Jev, Jev) / len(Jev)
    # the selection's information: with the potential terms when asked for
    Jca, Jeva, I0 = selection_problem(
        model, pool.subset(uidx), Jc, Jev, eq, ew, eval_frame, earlier, Je_rows, w_rows, scale, I0p, potential_knots
    )
    if Jca.shape[2] > n_prim:
        notes.append(
            "selection: model-robust, with an unmodelled angular error of each joint over the region's range "
            f"({int(potential_knots)} knots, prior {DESIGN_POTENTIAL_SIGMA_RAD:g} rad, beyond the identified ranges "
            f"the model's sigma growth {model.sigma_growth_rad_per_rad * 1e3:.3g} mrad/rad times the distance) as "
            "potential terms; the sigmas reported are the model's own"
        )
    M = np.einsum("nik,nil->kl", Jeva, Jeva) / len(Jeva)
    return _DesignMatrices(Jp, Jc, Je_rows, w_rows, Jev, scale, I0p, P0p, Mp, Jca, I0, M)


def _pool_unidentifiable(mats: _DesignMatrices, names: list[str], lay: DesignLayout, s: float) -> list[Unidentifiable]:
    """Unidentifiable parameters over the usable pool (the model's k parameters, pool frame)."""
    return _unidentifiable(mats.Jp, names, [x[:, :, : lay.k] for x in mats.Je_rows], mats.w_rows, s)


def _uncertainty_fields(
    model: ArmModel,
    mats: _DesignMatrices,
    lay: DesignLayout,
    sel: np.ndarray,
    s: float,
    eval_frame: str,
    earlier: Sequence[Measurements],
    uidx: np.ndarray,
    n: int,
    random_trials: int,
    seed: int,
    notes: list[str],
) -> dict[str, Any]:
    """The design's sigmas, variances and log-det gains before, after and for random subsets (fields of
    :class:`CampaignDesign`)."""
    posterior = _OwnPosterior(mats.I0p, mats.Jc, s * s)
    logdet_gain = posterior.logdet_gain
    P = posterior(sel)
    sig_before = _sigma_before(model, mats.Jev, lay, mats.scale, mats.P0p if earlier else None, notes)
    if lay.new_reg is not None and eval_frame == "measurement":
        notes.append(
            "before: in the model's measurement frame; after: in the new campaign's, its registration's "
            "uncertainty included"
        )
    sig_after = sigma_rms(mats.Jev, P)
    trials = max(1, int(random_trials))
    sig_rand, var_rand, ld_rand = _random_baseline(
        posterior, logdet_gain, mats.Jev, mats.Mp, len(uidx), int(n), trials, seed
    )
    return {
        "sigma_before_m": sig_before,
        "sigma_after_m": sig_after,
        "sigma_random_m": sig_rand,
        "variance_before_m2": float(np.mean(3.0 * sig_before**2)),
        "variance_after_m2": float(np.trace(mats.Mp @ P)),
        "variance_random_m2": var_rand,
        "logdet_gain_after": logdet_gain(P),
        "logdet_gain_random": ld_rand,
        "random_trials": trials,
    }


def _checked_request(
    model: ArmModel, pool: Measurements, n: Any, criterion: str, eval_frame: str
) -> tuple[float, np.ndarray, dict[str, SetAside]]:
    """The model's residual sigma (m), the usable pool rows (indices) and the guards' rows set aside;
    InputError for an unknown criterion or frame, a model without covariance or ``n`` out of range."""
    if criterion not in DESIGN_CRITERIA:
        raise InputError(f"criterion {criterion!r}: expected one of {', '.join(DESIGN_CRITERIA)}")
    if eval_frame not in EVAL_FRAMES:
        raise InputError(f"eval_frame {eval_frame!r}: expected one of {', '.join(EVAL_FRAMES)}")
    s = _check_model(model)
    usable, guards = pool_guards(model, pool)
    uidx = np.flatnonzero(usable)
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 1 <= n <= len(uidx):
        raise InputError(
            f"n = {n!r}: expected an integer from 1 to {len(uidx)}, the usable rows of the pool {pool.source} "
            f"({pool.n} rows, {pool.n - len(uidx)} set aside by the guards)"
        )
    return s, uidx, guards


class _OwnPosterior:
    """The model's own posterior covariance after rows of the pool (scaled parameters), and the
    log-det gain of a posterior over the prior information ``I0p``."""

    def __init__(self, I0p: np.ndarray, Jc: np.ndarray, s2: float) -> None:
        self.I0p, self.Jc, self.s2 = I0p, Jc, s2
        _sign, self.ld0 = np.linalg.slogdet(I0p)

    def __call__(self, rows: np.ndarray) -> np.ndarray:
        """The posterior covariance after ``rows`` of the pool (scaled)."""
        return inv_spd(self.I0p + np.einsum("nik,nil->kl", self.Jc[rows], self.Jc[rows]) / self.s2)

    def logdet_gain(self, Pc: np.ndarray) -> float:
        """``log det`` of the information of posterior ``Pc`` minus that of the prior."""
        _sg, ldp = np.linalg.slogdet(Pc)
        return float(-ldp - self.ld0)


def _evaluation_poses(
    model: ArmModel,
    pool: Measurements,
    uidx: np.ndarray,
    eval_q: np.ndarray | None,
    eval_wrench: np.ndarray | None,
    notes: list[str],
) -> tuple[np.ndarray, np.ndarray | None]:
    """The evaluation poses (N_e, 6), rad, and their base-frame wrenches (the usable pool rows by
    default); a note when some lie outside the joint ranges the model was identified on."""
    if eval_q is None:
        eq, ew = pool.q[uidx], pool.wrench[uidx]
    else:
        eq = np.atleast_2d(np.asarray(eval_q, dtype=float))
        ew = None if eval_wrench is None else np.asarray(eval_wrench, dtype=float)
    out_eval = int(outside_joints(model, eq).any(axis=1).sum())
    if out_eval:
        notes.append(
            f"{out_eval} of the {len(eq)} evaluation poses lie outside the joint ranges the model was identified "
            "on: its sigma there is a linearised extrapolation and can be optimistic (a joint error map is held "
            "at its end value beyond its range; docs/identification.md, section 10)"
        )
    return eq, ew


def _prior_information(
    n_prim: int, s2: float, Je_rows: list[np.ndarray], w_rows: list[np.ndarray], scale: np.ndarray
) -> np.ndarray:
    """The model's own prior information (scaled parameters): the ridge :data:`DESIGN_PRIOR_POSES`
    and the earlier campaigns' rows."""
    I0p = np.eye(n_prim) * (DESIGN_PRIOR_POSES / s2)
    for Jx, w in zip(Je_rows, w_rows):
        Jw = (Jx / scale) * w[:, None, None]
        I0p += np.einsum("nik,nil->kl", Jw, Jw)
    return I0p


def nominal_prior_information(model: ArmModel, names: list[str], lay: DesignLayout, scale: np.ndarray) -> np.ndarray:
    """The nominal model's information on the design's (scaled) parameters, the diagonal (lay.size,):
    ``1/(typical magnitude * scale)^2`` for the model's parameters, 0 for the set-up's (registration,
    measured point) and the registration blocks of other campaigns."""
    typical = fx.make_layout(model.nominal).scale
    info = np.zeros(lay.size)
    for k, name in enumerate(names):
        if name not in SETUP_NAMES:
            info[k] = 1.0 / (typical[fx.PARAM_NAMES.index(name)] * scale[k]) ** 2
    return info


def _sigma_before(
    model: ArmModel, Jev: np.ndarray, lay: DesignLayout, scale: np.ndarray, P0: np.ndarray | None, notes: list[str]
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
        return sigma_rms(Jb, P0)
    names = lay.names[: lay.k]
    setup = np.array([n in SETUP_NAMES for n in names], dtype=bool)
    Jn = Jb[:, :, : lay.k].copy()
    Jn[:, :, setup] = 0.0
    info = nominal_prior_information(model, names, lay, scale)[: lay.k]
    notes.append(
        "before: the nominal model, what you have without identification (each parameter known to its typical "
        "magnitude; the set-up's registration and measured point left out); no earlier data given: a design "
        "from scratch, the campaign alone identifies the model (the model's own covariance is not counted)"
    )
    return sigma_rms(Jn, np.diag(np.where(info > 0, 1.0 / np.where(info > 0, info, 1.0), 0.0)))


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
        sig_rand += sigma_rms(Jev, Pr) / trials
        var_rand += float(np.trace(Mp @ Pr)) / trials
        ld_rand += logdet_gain(Pr) / trials
    return sig_rand, var_rand, ld_rand


def _status(
    unident: list[Unidentifiable],
    n: int,
    n_usable: int,
    criterion: str,
    loads: LoadCheck,
    sigma_after_m: np.ndarray,
    notes: list[str],
) -> tuple[DesignStatus, str]:
    """``needs_loads`` when the region's sigma after the campaign is dominated by parameters that act
    through the load and the pool has no loaded row, else ``unidentifiable_parameters`` when some
    parameter is determined by no data, else ``ok``; the loads' note added to ``notes`` otherwise."""
    if loads.needs_loads:
        return DesignStatus.NEEDS_LOADS, loads.reason(CampaignDesign.region_sigma_m(sigma_after_m) * 1e3)
    if (note := loads.note(n)) is not None:
        notes.append(note)
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
