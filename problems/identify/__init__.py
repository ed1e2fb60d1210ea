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

Modules
-------
:mod:`~problems.identify.results`
    Result dataclasses and statuses (:class:`IdentificationResult`,
    :class:`ParameterStatus`, :class:`CompensationOutcome`, :class:`TargetsFrame`, errors).
:mod:`~problems.identify.evaluation`
    :class:`Evaluator` (the model graph over rows), rows, time reference, the problem data.
:mod:`~problems.identify.lsq`
    Levenberg-Marquardt, residual/Jacobian helpers, one complete model fit.
:mod:`~problems.identify.identifiability`
    :func:`select_identifiable`, the priority order, structural holds.
:mod:`~problems.identify.outliers`
    The robust exclusion of rows.
:mod:`~problems.identify.selection`
    Scores, cross-validation, BIC, F-test, noise floor, the forward and backward steps.
:mod:`~problems.identify.diagnostics`
    Regressions of the residual on explanatory variables.
:mod:`~problems.identify.engine`
    :func:`identify`, in named steps.
:mod:`~problems.identify.campaigns`
    :func:`identify_campaigns`: one model from several campaigns, one registration each.
:mod:`~problems.identify.apply`
    :func:`predict`, :func:`compensate`, :func:`compensate_targets`,
    :func:`compensation_check`, :func:`validate_on`.

Everything here is SI; the library never prints -- progress goes to an optional
callback ``progress(message, done, total)``.
"""

from __future__ import annotations


from typing import TYPE_CHECKING

from models.lazy import lazy_exports

if TYPE_CHECKING:
    from .apply import (
        COMPENSATION_CHECK_MAX_COND,
        COMPENSATION_RESIDUAL_TOL,
        REGISTRATION_ALIAS_MARKERS,
        TARGET_SEED_MAX_M,
        alias_effect_m,
        base_frame_warning,
        compensate,
        check_command_limits,
        compensate_targets,
        compensation_check,
        measured_point_model,
        predict,
        unobservable_in_base,
        validate_on,
    )
    from .campaigns import SHARED_PARTS, campaign_names, identify_campaigns, merge_campaigns
    from .diagnostics import (
        DIAG_ALPHA,
        DIAG_MIN_FRACTION,
        UNEXPLAINED_MIN_FRACTION,
        UNEXPLAINED_RMS_RATIO,
        diagnostic_variables,
        run_diagnostics,
        structure_left,
    )
    from .engine import SATURATED_MAX_ITER, identify
    from .evaluation import Evaluator, evaluator, make_rows, time_reference
    from .identifiability import (
        IDENT_MAX_STD_RATIO,
        IDENT_REL_TOL,
        LAST_AXIS_ROTATION,
        STRUCTURAL_DESIGN_ROWS,
        select_identifiable,
    )
    from .lsq import LM_COST_RTOL, LM_COST_SIGMA_TOL, LM_LAMBDA0, LM_MAX_ITER, LM_STEP_STD_TOL, NORMAL_RIDGE, kabsch
    from .outliers import (
        OUTLIER_FALSE_ALARM,
        OUTLIER_GROSS_SIGMAS,
        OUTLIER_MAX_FRACTION,
        OUTLIER_MAX_ROUNDS,
        OUTLIER_MIN_POSE_ROWS,
        OUTLIER_MIN_SIGMAS,
        OUTLIER_SCALE_QUANTILE,
        OUTLIER_SEPARATION,
        OUTLIER_TAIL_FACTOR,
        OUTLIER_TAIL_QUANTILE,
        OUTLIER_TAIL_SLACK,
    )
    from .results import (
        CandidateScore,
        CompensationOutcome,
        DataError,
        Diagnostic,
        IdentificationResult,
        IdentifiedModel,
        IdentifyStatus,
        ParameterEstimate,
        ParameterStatus,
        Progress,
        SelectionStep,
        TargetsError,
        TargetsFrame,
    )
    from .selection import (
        CV_FOLDS,
        CV_MIN_REL_GAIN,
        CV_SEED,
        F_TEST_ALPHA,
        MIN_EXPLAINED_SHARE,
        NOISE_FLOOR_STOP_RATIO,
        PARSIMONY_REL_TOL,
        REFINE_TOP,
        THERMAL_MIN_RANGE_K,
        backward_pass,
        forward_selection,
        noise_floor,
    )

#: The submodule defining each name re-exported here.  Imported on first use (PEP 562), so that
#: importing one submodule (``problems.identify.uncertainty``, which every plan reads for the
#: predicted sigma of its path) does not import the engine, the selection and the diagnostics, and
#: with them SciPy's statistics: a plan's start-up stays fast.
_LAZY = {
    **dict.fromkeys(
        (
            "COMPENSATION_CHECK_MAX_COND",
            "COMPENSATION_RESIDUAL_TOL",
            "REGISTRATION_ALIAS_MARKERS",
            "TARGET_SEED_MAX_M",
            "alias_effect_m",
            "base_frame_warning",
            "compensate",
            "check_command_limits",
            "compensate_targets",
            "compensation_check",
            "measured_point_model",
            "predict",
            "unobservable_in_base",
            "validate_on",
        ),
        "apply",
    ),
    **dict.fromkeys(("SHARED_PARTS", "campaign_names", "identify_campaigns", "merge_campaigns"), "campaigns"),
    **dict.fromkeys(
        (
            "DIAG_ALPHA",
            "DIAG_MIN_FRACTION",
            "UNEXPLAINED_MIN_FRACTION",
            "UNEXPLAINED_RMS_RATIO",
            "diagnostic_variables",
            "run_diagnostics",
            "structure_left",
        ),
        "diagnostics",
    ),
    **dict.fromkeys(("SATURATED_MAX_ITER", "identify"), "engine"),
    **dict.fromkeys(("Evaluator", "evaluator", "make_rows", "time_reference"), "evaluation"),
    **dict.fromkeys(
        ("IDENT_MAX_STD_RATIO", "IDENT_REL_TOL", "LAST_AXIS_ROTATION", "STRUCTURAL_DESIGN_ROWS", "select_identifiable"),
        "identifiability",
    ),
    **dict.fromkeys(
        ("LM_COST_RTOL", "LM_COST_SIGMA_TOL", "LM_LAMBDA0", "LM_MAX_ITER", "LM_STEP_STD_TOL", "NORMAL_RIDGE", "kabsch"),
        "lsq",
    ),
    **dict.fromkeys(
        (
            "OUTLIER_FALSE_ALARM",
            "OUTLIER_GROSS_SIGMAS",
            "OUTLIER_MAX_FRACTION",
            "OUTLIER_MAX_ROUNDS",
            "OUTLIER_MIN_POSE_ROWS",
            "OUTLIER_MIN_SIGMAS",
            "OUTLIER_SCALE_QUANTILE",
            "OUTLIER_SEPARATION",
            "OUTLIER_TAIL_FACTOR",
            "OUTLIER_TAIL_QUANTILE",
            "OUTLIER_TAIL_SLACK",
        ),
        "outliers",
    ),
    **dict.fromkeys(
        (
            "CandidateScore",
            "CompensationOutcome",
            "DataError",
            "Diagnostic",
            "IdentificationResult",
            "IdentifiedModel",
            "IdentifyStatus",
            "ParameterEstimate",
            "ParameterStatus",
            "Progress",
            "SelectionStep",
            "TargetsError",
            "TargetsFrame",
        ),
        "results",
    ),
    **dict.fromkeys(
        (
            "CV_FOLDS",
            "CV_MIN_REL_GAIN",
            "CV_SEED",
            "F_TEST_ALPHA",
            "MIN_EXPLAINED_SHARE",
            "NOISE_FLOOR_STOP_RATIO",
            "PARSIMONY_REL_TOL",
            "REFINE_TOP",
            "THERMAL_MIN_RANGE_K",
            "backward_pass",
            "forward_selection",
            "noise_floor",
        ),
        "selection",
    ),
}

__getattr__, __dir__ = lazy_exports(__name__, globals(), _LAZY)

__all__ = [
    # results and statuses
    "CandidateScore",
    "CompensationOutcome",
    "DataError",
    "Diagnostic",
    "IdentificationResult",
    "IdentifiedModel",
    "IdentifyStatus",
    "ParameterEstimate",
    "ParameterStatus",
    "Progress",
    "SelectionStep",
    "TargetsError",
    "TargetsFrame",
    # evaluation
    "Evaluator",
    "evaluator",
    "make_rows",
    "time_reference",
    # least squares and identifiability
    "kabsch",
    "select_identifiable",
    "LM_COST_RTOL",
    "LM_COST_SIGMA_TOL",
    "LM_LAMBDA0",
    "LM_MAX_ITER",
    "LM_STEP_STD_TOL",
    "NORMAL_RIDGE",
    "IDENT_MAX_STD_RATIO",
    "IDENT_REL_TOL",
    "LAST_AXIS_ROTATION",
    "STRUCTURAL_DESIGN_ROWS",
    # outliers
    "OUTLIER_FALSE_ALARM",
    "OUTLIER_GROSS_SIGMAS",
    "OUTLIER_MAX_FRACTION",
    "OUTLIER_MAX_ROUNDS",
    "OUTLIER_MIN_POSE_ROWS",
    "OUTLIER_MIN_SIGMAS",
    "OUTLIER_SCALE_QUANTILE",
    "OUTLIER_SEPARATION",
    "OUTLIER_TAIL_FACTOR",
    "OUTLIER_TAIL_QUANTILE",
    "OUTLIER_TAIL_SLACK",
    # selection
    "CV_FOLDS",
    "CV_MIN_REL_GAIN",
    "CV_SEED",
    "F_TEST_ALPHA",
    "MIN_EXPLAINED_SHARE",
    "NOISE_FLOOR_STOP_RATIO",
    "PARSIMONY_REL_TOL",
    "REFINE_TOP",
    "THERMAL_MIN_RANGE_K",
    "backward_pass",
    "forward_selection",
    "noise_floor",
    # diagnostics
    "DIAG_ALPHA",
    "DIAG_MIN_FRACTION",
    "UNEXPLAINED_MIN_FRACTION",
    "UNEXPLAINED_RMS_RATIO",
    "diagnostic_variables",
    "run_diagnostics",
    "structure_left",
    # the engine
    "SATURATED_MAX_ITER",
    "identify",
    # several campaigns
    "SHARED_PARTS",
    "campaign_names",
    "identify_campaigns",
    "merge_campaigns",
    # applying a model
    "COMPENSATION_CHECK_MAX_COND",
    "COMPENSATION_RESIDUAL_TOL",
    "REGISTRATION_ALIAS_MARKERS",
    "TARGET_SEED_MAX_M",
    "alias_effect_m",
    "base_frame_warning",
    "compensate",
    "check_command_limits",
    "compensate_targets",
    "compensation_check",
    "measured_point_model",
    "predict",
    "unobservable_in_base",
    "validate_on",
]
