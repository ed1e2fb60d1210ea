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
:mod:`~problems.identify.selection_scores`
    Scores, cross-validation, BIC, F-test, noise floor.
:mod:`~problems.identify.selection`
    The forward and backward steps.
:mod:`~problems.identify.diagnostics`
    Regressions of the residual on explanatory variables.
:mod:`~problems.identify.engine`
    :func:`identify`, in named steps (step 1 in :mod:`~problems.identify.fit_setup`, the result in
    :mod:`~problems.identify.outcome`).
:mod:`~problems.identify.campaigns`
    :func:`identify_campaigns`: one model from several campaigns, one registration each (the merged
    table in :mod:`~problems.identify.campaign_merge`, the joint problem in
    :mod:`~problems.identify.campaign_joint`).
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
        alias_effect_m,
        check_command_limits,
        compensate,
        compensate_targets,
        compensation_check,
        predict,
        unobservable_in_base,
        validate_on,
    )
    from .campaign_merge import merge_campaigns
    from .campaigns import identify_campaigns
    from .engine import identify
    from .evaluation import evaluator
    from .results import (
        DataError,
        Diagnostic,
        IdentificationResult,
        IdentifyStatus,
        ParameterStatus,
        TargetsError,
        TargetsFrame,
    )
    from .selection_scores import CV_FOLDS

#: Each re-exported name -> its submodule, imported on first use (the engine imports SciPy's statistics:
#: a plan that reads one name of the package must not pay for it).
_LAZY = {
    **dict.fromkeys(
        (
            "alias_effect_m",
            "check_command_limits",
            "compensate",
            "compensate_targets",
            "compensation_check",
            "predict",
            "unobservable_in_base",
            "validate_on",
        ),
        "apply",
    ),
    "merge_campaigns": "campaign_merge",
    "identify_campaigns": "campaigns",
    "identify": "engine",
    "evaluator": "evaluation",
    **dict.fromkeys(
        (
            "DataError",
            "Diagnostic",
            "IdentificationResult",
            "IdentifyStatus",
            "ParameterStatus",
            "TargetsError",
            "TargetsFrame",
        ),
        "results",
    ),
    "CV_FOLDS": "selection_scores",
}

__getattr__, __dir__ = lazy_exports(__name__, globals(), _LAZY)

__all__ = [
    # results and statuses
    "DataError",
    "Diagnostic",
    "IdentificationResult",
    "IdentifyStatus",
    "ParameterStatus",
    "TargetsError",
    "TargetsFrame",
    # evaluation and selection
    "evaluator",
    "CV_FOLDS",
    # the engine and several campaigns
    "identify",
    "identify_campaigns",
    "merge_campaigns",
    # applying a model
    "alias_effect_m",
    "check_command_limits",
    "compensate",
    "compensate_targets",
    "compensation_check",
    "predict",
    "unobservable_in_base",
    "validate_on",
]
