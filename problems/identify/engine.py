"""The identification: from measured data to an :class:`~models.arm.ArmModel` that explains it.

:func:`identify` runs the named steps of ``docs/identification.md``:

1. :func:`_setup` -- rows, weights, folds, torque scales; the initial registration
   (Kabsch on the nominal model) and the "before" fit (registration and measured
   point only);
2. :func:`_declared_model` -- joint stiffness (+ registration, measured point and the
   effects included without a test); too few data raise :class:`DataError`;
3. :func:`_saturated` -- every testable library effect at once: can the library
   explain the data, and which rows are outliers against the most flexible model;
4. forward selection and backward pass (:mod:`problems.identify.selection`);
5. :func:`_final_fit` -- every row re-tested against the final model;
6. :func:`_result` -- covariance, identified model, parameter table, diagnostics and
   the verdict (ok / unexplained structure / not converged).

Everything is SI; the library never prints -- progress goes to an optional
callback ``progress(message, done, total)``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from models import effects as fx
from models.effects import (
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
from models.effects.joint_error_map import MAP_COMPONENTS, MAP_CONST_KEYS
from models.errors import InputError
from models.plausibility import IMPLAUSIBLE_LENGTH_ERROR_M, implausible_geometry
from models.robot import Robot

from ..measurements import Measurements
from .diagnostics import UNEXPLAINED_MIN_FRACTION, UNEXPLAINED_RMS_RATIO, diagnose, structure_left
from .evaluation import (
    evaluator_for,
    gravity_problem,
    FitProblem,
    torque_scale,
    make_rows,
    row_weights,
    time_reference,
    with_orientation_rows,
)
from .identifiability import Known, priority_order, structural_held
from .lsq import (
    evaluate,
    ModelFit,
    fit_model,
    jacobian,
    levenberg_marquardt,
    rms,
    weighted_jacobian,
    weighted_residual,
    kabsch,
)
from .map_candidate import MAP_CHANNEL_GROUPS, MAP_SEARCH_COMPONENTS
from .map_summary import ErrorMapSummary, summarise_maps
from .nominal_check import check_nominal_fit, target_note
from .orientation import balance_orientation, measured_frame_start, orientation_gain
from .outliers import outlier_mask
from .results import (
    DataError,
    Diagnostic,
    IdentificationResult,
    IdentifiedModel,
    IdentifyStatus,
    ParameterEstimate,
    ParameterStatus,
    Progress,
)
from .selection import (
    CV_FOLDS,
    assign_folds,
    candidate_applicable,
    linear_scores,
    SelectionRun,
    Score,
    score_p,
    SelectionState,
    backward_pass,
    forward_selection,
    noise_floor,
)

#: LM iterations of the saturated (all effects) fit: a diagnostic, not an estimate.
SATURATED_MAX_ITER = 8
#: Parameter groups of the registration and the measured point (and frame).
REGISTRATION_GROUPS = ("reg.t", "reg.w", "tool.p", "tool.r")
#: Parts of the set-up that can be declared known (``identify(known=...)``).
KNOWN_PARTS = ("registration", "measured_point")


@dataclass
class _Setup:
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


def _effect_lists(candidates: Sequence[str] | None, include: Sequence[str]) -> tuple[list[str], list[str], bool]:
    """Candidates, included effects (``outliers`` taken out) and whether the fit is robust."""
    cand = list(LIBRARY if candidates is None else candidates)
    for e in list(cand) + list(include):
        if e not in LIBRARY:
            raise InputError(f"unknown effect '{e}'; library: {', '.join(LIBRARY)}")
    robust = "outliers" in cand or "outliers" in include
    inc = [e for e in include if e != "outliers"]
    cand = [e for e in cand if e != "outliers" and e not in inc]
    return cand, inc, robust


def _known_parts(registered: bool, known: Sequence[str], map_components: Sequence[str]) -> Known:
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


def _setup(robot: Robot, m: Measurements, registered: Known, folds: int, n_cand: int, tick: Progress) -> _Setup:
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
        if n_poses < 3:
            raise DataError(
                f"{m.source}: {n_poses} distinct pose(s); the registration of the measurement "
                "frame and the measured point need at least 3 poses (many more for a useful fit); "
                "or declare the data registered"
            )
        pred0, _q = ev.measure(rows, theta, const)
        R0, t0 = kabsch(pred0[is_pos], m.p)
        theta[GROUP_SLICES["reg.t"]] = t0
        const = set_const(const, "registration.R0", R0)
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
    all_rows = np.ones(mx.n, dtype=bool)
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
    return _Setup(
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


#: An identification whose cross-validated (held-out) RMS after exceeds this multiple of the nominal
#: model's is refused as a model to use: status ``does_not_generalise`` (it fits noise, not the arm).
#: A 20 % margin: at the noise floor the two differ by chance by a few per cent.
CV_WORSE_RATIO = 1.2
#: Parameters named in a "cannot identify" error (one line a person reads); the rest are counted.
HELD_NAMED_MAX = 6
#: Characters of a parameter's reason quoted in that error.
HELD_REASON_CHARS = 80


def _held_list(bad: Sequence[int], held: Mapping[int, str], effect: Mapping[int, str] | None = None) -> str:
    """The parameters of a "cannot identify" error on one short line: the names grouped by their
    reason (each reason once, shortened), at most :data:`HELD_NAMED_MAX` names, the rest counted."""
    groups: dict[str, list[str]] = {}
    for i in bad[:HELD_NAMED_MAX]:
        reason = str(held[i])
        reason = reason if len(reason) <= HELD_REASON_CHARS else reason[: HELD_REASON_CHARS - 1].rstrip() + "…"
        name = PARAM_NAMES[i] + (f" [{effect[i]}]" if effect else "")
        groups.setdefault(reason, []).append(name)
    text = "; ".join(f"{', '.join(names)} ({reason})" for reason, names in groups.items())
    return text + (f" and {len(bad) - HELD_NAMED_MAX} more" if len(bad) > HELD_NAMED_MAX else "")


def _declared_model(
    s: _Setup, include: Sequence[str], registered: bool, robust: bool, structural: set[int], notes: list[str]
) -> tuple[FitProblem, ModelFit]:
    """Step 2: fit the declared model and the included effects; raise :class:`DataError`
    when the registration, the measured point or an included effect cannot be identified
    (and the cause is not structural)."""
    m, layout = s.prob.m, s.prob.layout
    prob = gravity_problem(s.prob, True) if "gravity" in include else s.prob
    fit = fit_model(prob, s.theta, include, registered, np.ones(m.n, dtype=bool), robust=robust)
    reg_idx = set(priority_order(layout, [], registered)) - set(layout.indices(("stiffness.s",)))
    bad = [i for i in fit.held if i in reg_idx and i not in structural]
    if bad:
        rms_b = rms(s.fit_b.residual(s.prob))
        wrong_robot = (
            f"; the nominal model of robot '{s.prob.layout.robot.name}' misses the data by "
            f"{rms_b * 1e3:.0f} mm RMS after the registration: is --robot the arm that was measured?"
            if rms_b > IMPLAUSIBLE_LENGTH_ERROR_M
            else ""
        )
        raise DataError(
            f"{m.source}: too few or too similar poses ({s.n_poses} distinct): cannot identify "
            + _held_list(bad, fit.held)
            + "; measure more poses spread over the workspace (and tool orientations), or declare "
            "known parts of the set-up (--known measured-point / registration, or --registered)" + wrong_robot
        )
    inc_idx = {int(i): e for e in include for i in layout.effect_indices(e)}
    bad = [i for i in fit.held if i in inc_idx and i not in structural]
    if bad:
        raise DataError(
            f"{m.source}: the data ({m.n} rows, {s.n_poses} poses) cannot identify "
            + _held_list(bad, fit.held, inc_idx)
            + "; add poses/loads that excite them or do not include the effect"
        )
    if all(i in fit.held for i in layout.indices(("stiffness.s",))):
        notes.append(
            "joint stiffness is held at the robot file's values: the applied wrench does not excite it"
            if not m.load_varies()
            else "joint stiffness cannot be identified from these data"
        )
    return prob, fit


def _saturated(
    robot: Robot,
    prob: FitProblem,
    fit: ModelFit,
    include: Sequence[str],
    sat_effects: list[str],
    registered: bool,
    robust: bool,
) -> tuple[bool, dict[str, Any], np.ndarray, ModelFit]:
    """Step 3: the saturated model, every testable library effect at once.

    Its residual tells whether the library can explain the data at all (then no
    attribution can be a partial fit of something else), and its robust fit finds the
    outliers against the most flexible model available.

    Returns
    -------
    clean : bool
        The saturated model leaves no structure.
    info : dict
        ``identifiability.saturated_model`` of the report.
    mask_sel : ndarray of bool, shape (N,)
        Rows of the selection.
    fit : ModelFit
        The declared model, refitted on ``mask_sel`` when rows were excluded.
    """
    layout = prob.layout
    info: dict[str, Any] = {"effects": sat_effects}
    mask_sel = fit.inliers.copy()
    if len(sat_effects) <= len(include):
        return False, info, mask_sel, fit
    prob_s = gravity_problem(prob, True) if "gravity" in sat_effects else prob
    th_s = fit.theta.copy()
    if "gravity" in sat_effects and "gravity" not in include:
        gi = layout.effect_indices("gravity")
        th_s[gi] = layout.nominal[gi]
    fit_s = fit_model(
        prob_s,
        th_s,
        sat_effects,
        registered,
        np.ones(prob.m.n, dtype=bool),
        robust=robust,
        max_iter=SATURATED_MAX_ITER,
        passes=1,
        rounds=2,
    )
    left = structure_left(diagnose(prob_s, fit_s, robot))
    clean = left is None or left.explained_fraction < UNEXPLAINED_MIN_FRACTION
    if robust and not clean and (~fit_s.inliers).any():
        # structure outside the library: only gross errors count as outliers
        fit_s.inliers = outlier_mask(prob_s, fit_s.pred, gross_only=True)
    sc_s, _fr = score_p(prob_s, layout, fit_s, sat_effects, registered)
    info.update(
        {
            "cv_rms_mm": sc_s.cv_rms_m * 1e3,
            "clean": clean,
            "structure": None if left is None else left.variable,
            "n_excluded": int((~fit_s.inliers).sum()),
        }
    )
    if robust:
        mask_sel = fit_s.inliers.copy()
        if (~mask_sel).any():
            fit = fit_model(prob, fit.theta, include, registered, mask_sel, robust=robust)
    return clean, info, mask_sel, fit


def _final_fit(run: SelectionRun, st: SelectionState) -> None:
    """Step 5: every row is tested against the final model (robust fit), or the final
    model is refitted on all rows."""
    prob, fit = st.prob, st.fit
    if run.robust:
        # a residual with structure the library lacks is not a Gaussian bulk: gross errors only
        structured = structure_left(diagnose(prob, fit, run.robot)) is not None
        final_mask = outlier_mask(prob, fit.pred, gross_only=structured)
        if not np.array_equal(final_mask, fit.inliers):
            fit = fit_model(prob, fit.theta, st.active, run.registered, final_mask, robust=False)
            fit.inliers = final_mask
    else:
        fit = fit_model(prob, fit.theta, st.active, run.registered, np.ones(prob.m.n, dtype=bool), robust=False)
    if run.robust and (~fit.inliers).any():
        st.effects_added.append("outliers")
    st.fit = fit


def identify(
    robot: Robot,
    data: Measurements,
    registered: bool = False,
    candidates: Sequence[str] | None = None,
    include: Sequence[str] = (),
    folds: int = CV_FOLDS,
    progress: Progress | None = None,
    max_steps: int = 12,
    known: Sequence[str] = (),
    map_components: Sequence[str] = MAP_SEARCH_COMPONENTS,
) -> IdentificationResult:
    """Identify the declared model and select effects from the library.

    Parameters
    ----------
    robot : Robot
        Nominal description (DH, stiffness, tool, masses).
    data : Measurements
        With positions ``p`` (measurement frame, m).
    registered : bool
        True when the measurement frame is the base frame and the measured point is
        the robot file's TCP; otherwise both are identified (unless ``known``).
    known : sequence of str
        Parts of the set-up declared known and held, ``"registration"`` (measurement frame =
        base frame) and/or ``"measured_point"`` (measured point, and frame with orientation
        data, = the robot file's TCP); both together are ``registered``.
    map_components : sequence of str
        Components of the joint error maps the search proposes (``theta``, ``d``, ``a``, ``alpha``,
        ``beta``; default the angular error only, see ``docs/identification.md`` section 4a).
    candidates : sequence of str, optional
        Library effects the selection may add (default: all, ``outliers`` included).
    include : sequence of str
        Effects added without a test (their parameters must be identifiable from
        the data; otherwise :class:`DataError` names them).
    folds : int
        K of the K-fold cross-validation.
    progress : callable, optional
        ``progress(message, done, total)``.
    max_steps : int
        Most forward steps.

    Returns
    -------
    IdentificationResult

    Raises
    ------
    DataError
        Too few rows/poses for the declared model or an included effect (names the
        unidentifiable parameters), no measured positions, or measured points that do not
        fit the robot (in another unit than declared, or from another arm:
        :mod:`problems.identify.nominal_check`).
    InputError
        An unknown effect name.
    """

    def tick(msg: str, k: int, total: int) -> None:
        if progress is not None:
            progress(msg, k, total)

    m = data
    if m.p is None:
        raise DataError(f"{m.source}: no measured positions (columns x, y, z) to identify from")
    cand, inc, robust = _effect_lists(candidates, include)
    registered = _known_parts(registered, known, map_components)
    notes: list[str] = []
    if robot.identified is not None:
        notes.append(
            "the robot file carries an [identified] table; identification starts from its "
            "ordinary fields and ignores that table"
        )
    s = _setup(robot, m, registered, folds, len(cand), tick)
    # do the data fit this robot at all (units, the wrong arm)?  DataError when nothing can fit
    nominal = check_nominal_fit(robot, s.prob, s.fit_b, s.theta, registered, "geometric" in cand + inc)
    notes += nominal.notes()
    target = target_note(robot, m)
    if target is not None:
        notes.append(target)
    structural = structural_held(robot, list(inc) + cand, registered)  # structural vs too few data
    tick("declared model", 1, s.total_steps)
    try:
        prob, fit = _declared_model(s, inc, registered, robust, structural, notes)
    except DataError:
        if nominal.plausible:
            raise
        raise DataError(nominal.refusal()) from None  # undetermined against the miss: the wrong robot
    if m.rotation is not None and getattr(m, "sigma_rot", None) is None:
        prob, fit = balance_orientation(prob, fit, inc, registered, robust, notes)
    sigma_noise, noise_src = noise_floor(m)
    sigma_w = None if sigma_noise is None else (1.0 if m.sigma is not None else sigma_noise)
    applicable: dict[str, str] = {}
    for e in cand:
        ok, why = candidate_applicable(e, m)
        if not ok:
            applicable[e] = why
    tick("saturated library model", 2, s.total_steps)
    sat_effects = list(inc) + [e for e in cand if e not in applicable]
    if "geometric" in sat_effects and "joint_offset" in sat_effects:
        sat_effects.remove("joint_offset")
    sat_clean, sat_info, mask_sel, fit = _saturated(robot, prob, fit, inc, sat_effects, registered, robust)
    score_b = linear_scores(prob, s.fit_b.J, s.fit_b.pred, fit.inliers, np.asarray(s.order_b, dtype=int))
    run = SelectionRun(
        robot=robot,
        layout=prob.layout,
        registered=registered,
        robust=robust,
        include=list(inc),
        cand=cand,
        applicable=applicable,
        sigma_noise=sigma_noise,
        sigma_w=sigma_w,
        sat_clean=sat_clean,
        mask_sel=mask_sel,
        max_steps=max_steps,
        tick=tick,
        total_steps=s.total_steps,
        map_components=tuple(map_components),
    )
    st = SelectionState(prob=prob, fit=fit, active=list(inc))
    forward_selection(run, st)
    backward_pass(run, st)
    tick("final fit and diagnostics", s.total_steps, s.total_steps)
    _final_fit(run, st)
    return _result(run, st, s, score_b, sat_info, noise_src, notes)


# ----------------------------------------------------------------------------------
# Step 6: the result
# ----------------------------------------------------------------------------------


def _covariance(
    prob: FitProblem, fit: ModelFit, free: Sequence[int], full: list[np.ndarray] | None = None
) -> tuple[np.ndarray, float]:
    """Standard deviations (N_PARAMS,), SI (NaN where not free), from ``s^2 (J^T J)^-1``,
    and the condition number of the column-normalised Jacobian; the whole covariance
    (N_PARAMS, N_PARAMS), SI, zero where not free, is appended to ``full`` when given."""
    r_w = weighted_residual(prob, fit.pred, fit.inliers)
    n_res, k_f = r_w.size, len(free)
    s2 = float(r_w @ r_w) / max(n_res - k_f, 1)
    Js = weighted_jacobian(prob, fit.J, fit.inliers, np.asarray(free, dtype=int))
    std = np.full(N_PARAMS, np.nan)
    cond = float("nan")
    if k_f:
        G = Js.T @ Js
        try:
            cov = np.linalg.inv(G) * s2
            std[free] = np.sqrt(np.maximum(np.diag(cov), 0.0)) * prob.layout.scale[free]
            if full is not None:
                C = np.zeros((N_PARAMS, N_PARAMS))
                sc = prob.layout.scale[free]
                C[np.ix_(free, free)] = cov * np.outer(sc, sc)
                full.append(C)
        except np.linalg.LinAlgError:
            pass
        Jn = Js / np.maximum(np.linalg.norm(Js, axis=0), 1e-300)
        sv = np.linalg.svd(Jn, compute_uv=False)
        cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")
    return std, cond


def _effect_of(i: int) -> str:
    """Effect (or declared group) of parameter index ``i``."""
    for g, e, _names, _u in fx.PARAMETER_GROUPS:
        s = GROUP_SLICES[g]
        if s.start <= i < s.stop:
            return e
    return "?"


def _parameter_table(
    layout: ModelLayout, fit: ModelFit, order: Sequence[int], std: np.ndarray, active: Sequence[str], registered: bool
) -> list[ParameterEstimate]:
    """Every parameter of the model (priority order), with value, std, unit and status."""
    out = []
    order_set = set(order)
    for i in order:
        name = PARAM_NAMES[i]
        if i in fit.held:
            out.append(
                ParameterEstimate(
                    name, _effect_of(i), float(fit.theta[i]), None, layout.units[i], ParameterStatus.HELD, fit.held[i]
                )
            )
        else:
            out.append(
                ParameterEstimate(
                    name,
                    _effect_of(i),
                    float(fit.theta[i]),
                    float(std[i]) if np.isfinite(std[i]) else None,
                    layout.units[i],
                    ParameterStatus.FREE,
                )
            )
    known = Known.of(registered)
    if known.registration or known.measured_point:
        for i in layout.indices(REGISTRATION_GROUPS):
            if i not in order_set:
                out.insert(
                    0,
                    ParameterEstimate(
                        PARAM_NAMES[i],
                        _effect_of(i),
                        float(fit.theta[i]),
                        None,
                        layout.units[i],
                        ParameterStatus.HELD,
                        "data declared registered" if known else f"declared known ({known.describe()})",
                    ),
                )
    return out


def _build_model(
    run: SelectionRun,
    st: SelectionState,
    s: _Setup,
    std: np.ndarray,
    free: Sequence[int],
    order: Sequence[int],
    sigma_noise: float | None,
) -> IdentifiedModel:
    """The identified :class:`~models.arm.ArmModel`."""
    fit, robot = st.fit, run.robot
    rows = st.prob.rows[fit.inliers]
    te, tg, _q = st.prob.ev.call("torques", rows[:, 0:6], rows[:, 6:12], rows[:, 13:14], fit.theta, st.prob.const)
    torque_range = np.max(np.abs(np.asarray(te).T + np.asarray(tg).T), axis=0)
    return IdentifiedModel(
        nominal=robot,
        theta=fit.theta.copy(),
        R0=s.R0,
        tau_scale=s.tau_s,
        gravity_on=bool(get_const(st.prob.const, "gravity.on")[0] > 0.5),
        beams=fx.beam_frames(robot),
        knots=get_const(st.prob.const, "hardening.knots").reshape(6, fx.N_KNOTS).copy(),
        time_ref=s.t_ref,
        temperature_ref=s.temp_ref,
        effects=list(st.active),
        registered=bool(run.registered),
        std={PARAM_NAMES[i]: float(std[i]) for i in free},
        noise_sigma_m=sigma_noise,
        held={PARAM_NAMES[i]: r for i, r in fit.held.items() if i in order},
        tcp_correction_m=(
            fit.theta[GROUP_SLICES["tool.p"]] - robot.tcp2flange[:3, 3] if bool(run.registered) else np.zeros(3)
        ),
        torque_range_Nm=torque_range,
        effect_const=(
            {k: get_const(st.prob.const, k).copy() for k in MAP_CONST_KEYS} if "joint_error_map" in st.active else {}
        ),
    )


def _verdict(
    diags: Sequence[Diagnostic], score_f: Score, sigma_noise: float | None, stop_reason: str, converged: bool
) -> tuple[IdentifyStatus, str, dict[str, Any]]:
    """Status, reason and the ``unexplained`` record of the final residual."""
    top = structure_left(diags)
    above_floor = sigma_noise is not None and score_f.cv_rms_m > UNEXPLAINED_RMS_RATIO * sigma_noise
    # strong: any significant diagnostic (the unspecific per-pose one too) explains the threshold
    strong = any(d.significant and d.explained_fraction >= UNEXPLAINED_MIN_FRACTION for d in diags)
    if strong or above_floor or top is not None:
        if top is None:
            top = diags[0]
        weak = not (strong or above_floor)
        unexplained = {
            "present": True,
            "diagnostic": f"residual vs {top.variable}",
            "variable": top.variable,
            "explained_fraction": top.explained_fraction,
            "p_value": top.p_value,
            "description": top.description,
            "weak": weak,
            "rms_over_noise": (score_f.cv_rms_m / sigma_noise) if sigma_noise else None,
            "message": (
                f"{'weak ' if weak else ''}structure remains that no library effect explains: the residual "
                f"depends on {top.variable} (cross-validated regression explains "
                f"{100 * top.explained_fraction:.0f} % of its variance, p = {top.p_value:.2g})"
                + (f"; held-out RMS is {score_f.cv_rms_m / sigma_noise:.2f} x the noise floor" if sigma_noise else "")
            ),
        }
        status = IdentifyStatus.OK if weak else IdentifyStatus.UNEXPLAINED
        reason = stop_reason + "; " + unexplained["message"] if weak else unexplained["message"]
    else:
        unexplained = {
            "present": False,
            "diagnostic": None,
            "variable": None,
            "weak": False,
            "explained_fraction": (diags[0].explained_fraction if diags else None),
            "message": (
                "no diagnostic shows structure the model leaves unexplained (cross-validated "
                "nonparametric fits of the residual on each joint angle, per axis and through "
                "each joint, and on time, load, temperature, position and pose)"
            ),
        }
        status = IdentifyStatus.OK
        reason = stop_reason
    if not converged:
        status = IdentifyStatus.NOT_CONVERGED
        reason = "the final least-squares fit did not converge"
    return status, reason, unexplained


def _result(
    run: SelectionRun,
    st: SelectionState,
    s: _Setup,
    score_b: Score,
    sat_info: dict[str, Any],
    noise_src: str,
    notes: list[str],
) -> IdentificationResult:
    """Step 6: covariance, model, parameter table, diagnostics and verdict."""
    prob, fit, m = st.prob, st.fit, st.prob.m
    score_f, free_f = run.score(prob, fit, st.active)
    order_f = priority_order(prob.layout, st.active, run.registered)
    cov: list[np.ndarray] = []
    std, cond = _covariance(prob, fit, free_f, cov)
    R_un = fit.residual(prob)
    model = _build_model(run, st, s, std, free_f, order_f, run.sigma_noise)
    if cov:
        free_idx = np.asarray(free_f, dtype=int)
        model.covariance = cov[0][np.ix_(free_idx, free_idx)].copy()
        model.covariance_names = [PARAM_NAMES[i] for i in free_idx]
    r_in = R_un[fit.inliers & prob.pos]
    if r_in.size:
        model.residual_sigma_m = float(np.sqrt(np.sum(r_in**2) / max(r_in.size - len(free_f), 1)))
    q_used = prob.m.q[fit.inliers]
    model.joint_range_rad = np.column_stack([q_used.min(axis=0), q_used.max(axis=0)]) if len(q_used) else None
    params = _parameter_table(prob.layout, fit, order_f, std, st.active, run.registered)
    diags = diagnose(prob, fit, run.robot)  # diagnostics on the final residual (inliers)
    status, reason, unexplained = _verdict(diags, score_f, run.sigma_noise, st.stop_reason, fit.converged)
    implausible = implausible_geometry(run.robot, fit.theta, [i for i in fit.held])
    if implausible is not None and status is not IdentifyStatus.NOT_CONVERGED:
        status, reason = IdentifyStatus.IMPLAUSIBLE, implausible
    elif status is not IdentifyStatus.NOT_CONVERGED and score_f.cv_rms_m > CV_WORSE_RATIO * score_b.cv_rms_m:
        status = IdentifyStatus.DOES_NOT_GENERALISE
        reason = (
            f"the identified model predicts held-out poses worse than the nominal one (cross-validated RMS "
            f"{score_b.cv_rms_m * 1e3:.4g} -> {score_f.cv_rms_m * 1e3:.4g} mm per axis): {s.n_poses} poses are "
            f"too few for {len(free_f)} free parameters; do not use this model, measure more poses spread "
            "over the workspace"
        )
    pos = prob.pos
    R_un_all = R_un
    R_un = R_un_all[pos]
    excluded = [
        {
            "row": int(i),
            "line": int(m.line[i]),
            "residual_mm": float(np.linalg.norm(R_un_all[i]) * 1e3),
            "residual_xyz_mm": (R_un_all[i] * 1e3).tolist(),
            "kind": "position" if pos[i] else "orientation",
        }
        for i in np.flatnonzero(~fit.inliers)
    ]
    ident = {
        "rank": len(free_f),
        "condition_number": cond,
        "n_rows": int(pos.sum()),
        "n_inliers": int(fit.inliers[pos].sum()),
        "n_poses": int(s.n_poses),
        "saturated_model": sat_info,
        "held": [
            {"name": PARAM_NAMES[i], "effect": _effect_of(i), "reason": r} for i, r in fit.held.items() if i in order_f
        ],
        "known": Known.of(run.registered).describe(),
    }
    res_b_all = s.fit_b.residual(prob)
    res_b = res_b_all[pos]
    inl = fit.inliers[pos]
    orient: dict[str, Any] | None = None
    if (~pos).any():
        rot = ~pos & fit.inliers
        orient = {
            "rms_before_rad": rms(res_b_all[~pos][fit.inliers[~pos]]),
            "rms_after_rad": rms(R_un_all[rot]),
            "n_rows": int((~pos).sum()),
            "identifiable_thanks_to_orientation": orientation_gain(prob, fit, order_f),
        }
        ident["orientation"] = orient
    return IdentificationResult(
        status=status,
        reason=reason,
        model=model,
        effects_added=st.effects_added,
        history=st.history,
        parameters=params,
        rms_before_m=rms(res_b[inl]),
        rms_after_m=rms(R_un[inl]),
        cv_rms_before_m=score_b.cv_rms_m,
        cv_rms_after_m=score_f.cv_rms_m,
        noise_sigma_m=run.sigma_noise,
        noise_source=noise_src,
        excluded=excluded,
        unexplained=unexplained,
        diagnostics=diags,
        identifiability=ident,
        residual_before=res_b,
        residual_after=R_un,
        inliers=inl,
        data=m.subset(pos),
        notes=notes,
        error_maps=_error_maps(st, cov[0] if cov else None),
        orientation=orient,
    )


def _error_maps(st: SelectionState, cov: np.ndarray | None) -> list[ErrorMapSummary]:
    """Summaries of the identified joint error maps (empty without ``joint_error_map``)."""
    if "joint_error_map" not in st.active:
        return []
    prob, fit = st.prob, st.fit
    mask = fit.inliers
    n = int(mask.sum())
    J3 = fit.J[np.repeat(mask, 3)]
    lever = np.zeros((n, 6, len(MAP_CHANNEL_GROUPS)))
    for k, group in enumerate(MAP_CHANNEL_GROUPS):
        for j in range(6):
            lever[:, j, k] = np.linalg.norm(J3[:, GROUP_SLICES[group].start + j].reshape(n, 3), axis=1)
    return summarise_maps(
        fit.theta,
        cov,
        get_const(prob.const, "error_map.freq"),
        get_const(prob.const, "error_map.range"),
        lever,
        prob.m.q[mask],
    )
