"""The identification: from measured data to an :class:`~models.arm.ArmModel` that explains it.

:func:`identify` runs the named steps of ``docs/identification.md``:

1. :func:`~.fit_setup.setup_fit` -- rows, weights, folds, torque scales; the initial registration
   (Kabsch on the nominal model) and the "before" fit (registration and measured
   point only);
2. :func:`_declared_model` -- joint stiffness (+ registration, measured point and the
   effects included without a test); too few data raise :class:`DataError`;
3. :func:`_saturated` -- every testable library effect at once: can the library
   explain the data, and which rows are outliers against the most flexible model;
4. forward selection and backward pass (:mod:`problems.identify.selection`);
5. :func:`_final_fit` -- every row re-tested against the final model;
6. :func:`~.outcome.build_result` -- covariance, identified model, parameter table, diagnostics and
   the verdict (ok / unexplained structure / not converged).

:func:`select_model` runs steps 1-5 and returns a :class:`Selection` (its
:meth:`~Selection.result` is step 6), which :func:`~.refit.refit_selection` re-fits to other measured
points of the same rows without selecting again (several campaigns, :mod:`.campaigns`).

Everything is SI; the library never prints -- progress goes to an optional
callback ``progress(message, done, total)``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from models.effects import PARAM_NAMES
from models.plausibility import IMPLAUSIBLE_LENGTH_ERROR_M
from models.robot import Robot

from ..measurements import Measurements
from .diagnostics import UNEXPLAINED_MIN_FRACTION, diagnose, structure_left
from .evaluation import FitProblem, gravity_problem
from .identifiability import Known, priority_order, structural_held
from .lsq import ModelFit, fit_model, rms
from .map_candidate import MAP_SEARCH_COMPONENTS
from .nominal_check import check_nominal_fit, target_note
from .orientation import balance_orientation
from .outliers import outlier_mask
from .results import DataError, IdentificationResult, Progress
from .selection import SelectionRun, SelectionState, backward_pass, forward_selection
from .selection_scores import CV_FOLDS, Score, candidate_applicable, linear_scores, noise_floor, score_p

from .fit_setup import FitSetup, effect_lists, known_parts, setup_fit
from .outcome import build_result

#: LM iterations of the saturated (all effects) fit: a diagnostic, not an estimate.
SATURATED_MAX_ITER = 8


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
    s: FitSetup, include: Sequence[str], registered: bool, robust: bool, structural: set[int], notes: list[str]
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


def _start_notes(robot: Robot) -> list[str]:
    """The notes the identification starts with (a robot file's [identified] table ignored)."""
    if robot.identified is None:
        return []
    return [
        "the robot file carries an [identified] table; identification starts from its "
        "ordinary fields and ignores that table"
    ]


@dataclass
class Selection:
    """An identification before its result (steps 1-5 of :func:`identify`): what a re-fit keeps.

    Attributes
    ----------
    run : SelectionRun
        The selection's fixed inputs (robot, layout, candidates, noise floor, rows of the selection).
    st : SelectionState
        The selected model: its problem (constants: joint error map frequencies, gravity switch,
        knots), its final fit (parameters, held parameters, inlier rows), effects and history.
    s : FitSetup
        Step 1 (registration start ``R0``, torque scales, time and temperature references, the
        "before" fit).
    score_b : Score
        Linearised scores of the "before" fit on the rows ``score_mask``.
    score_mask : ndarray of bool, shape (N,)
        Rows of the "before" score (the declared model's inliers).
    sat_info : dict
        The saturated model's record.
    noise_src : str
        Where the noise floor comes from.
    notes : list of str
    folds : int
        K of the K-fold cross-validation.
    """

    run: SelectionRun
    st: SelectionState
    s: FitSetup
    score_b: Score
    score_mask: np.ndarray
    sat_info: dict[str, Any]
    noise_src: str
    notes: list[str]
    folds: int

    def result(self) -> IdentificationResult:
        """Step 6 (:func:`~.outcome.build_result`): covariance, model, parameter table, diagnostics
        and verdict."""
        return build_result(self.run, self.st, self.s, self.score_b, self.sat_info, self.noise_src, list(self.notes))


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

    return select_model(
        robot, data, registered, candidates, include, folds, progress, max_steps, known, map_components
    ).result()


def select_model(
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
) -> Selection:
    """Steps 1-5 of :func:`identify` (same arguments, same errors): the selected and fitted model,
    whose :meth:`Selection.result` is :func:`identify`'s result (step 6) and which
    :func:`~.refit.refit_selection` re-fits to other measured points of the same rows."""

    def tick(msg: str, k: int, total: int) -> None:
        if progress is not None:
            progress(msg, k, total)

    m = data
    if m.p is None:
        raise DataError(f"{m.source}: no measured positions (columns x, y, z) to identify from")
    cand, inc, robust = effect_lists(candidates, include)
    registered = known_parts(registered, known, map_components)
    notes = _start_notes(robot)
    s = setup_fit(robot, m, registered, folds, len(cand), tick)
    prob, fit = _fit_declared(robot, m, s, inc, cand, registered, robust, notes, tick)
    run, fit, score_b, sat_info, noise_src = _selection_run(
        robot, m, s, prob, fit, inc, cand, registered, robust, max_steps, tick, map_components
    )
    score_mask = fit.inliers.copy()
    st = SelectionState(prob=prob, fit=fit, active=list(inc))
    forward_selection(run, st)
    backward_pass(run, st)
    tick("final fit and diagnostics", s.total_steps, s.total_steps)
    _final_fit(run, st)
    return Selection(run, st, s, score_b, score_mask, sat_info, noise_src, notes, folds)


def _fit_declared(
    robot: Robot,
    m: Measurements,
    s: FitSetup,
    inc: list[str],
    cand: list[str],
    registered: Known,
    robust: bool,
    notes: list[str],
    tick: Progress,
) -> tuple[FitProblem, ModelFit]:
    """The nominal check, step 2 (the declared model, refused as the wrong robot when it cannot be
    identified and the nominal check failed) and the balance of orientation rows; notes appended."""
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
    return prob, fit


def _selection_run(
    robot: Robot,
    m: Measurements,
    s: FitSetup,
    prob: FitProblem,
    fit: ModelFit,
    inc: list[str],
    cand: list[str],
    registered: Known,
    robust: bool,
    max_steps: int,
    tick: Progress,
    map_components: Sequence[str],
) -> tuple[SelectionRun, ModelFit, Score, dict[str, Any], str]:
    """The noise floor, the applicable candidates and step 3 (the saturated model): the
    :class:`~.selection.SelectionRun` of the selection, the declared fit (refitted on the rows of the
    selection), the "before" score, the saturated model's record and the noise floor's source."""
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
    return run, fit, score_b, sat_info, noise_src
