"""Result objects and statuses of the identification and of its applications.

Everything is SI (m, rad, N, N*m); reports convert at their edge.  The
``*_m`` fields are lengths in metres; ``*_mm`` properties are the report's
millimetres.
"""

from __future__ import annotations

import enum
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from models.arm import ArmModel
from models.errors import InputError
from models.status import Status

from ..compensation import CompensationStatus
from ..measurements import Measurements

#: Progress callback of :func:`problems.identify.identify`: ``progress(message, done, total)``.
Progress = Callable[[str, int, int], None]


class IdentifyStatus(Status):
    """Outcome of an identification (``.value`` is the ``report.json`` string)."""

    OK = "ok"  # the model explains the data (noise floor or no structure left)
    UNEXPLAINED = "unexplained"  # structure remains that no library effect explains
    NOT_CONVERGED = "not_converged"
    IMPLAUSIBLE = "implausible_geometry"  # DH corrections too large for the declared robot: wrong robot file?


class ParameterStatus(Status):
    """Status of one model parameter after identification.

    ``.value`` (and ``str``/f-strings of the member) is the string of ``report.json``
    (``"free"``, ``"held"``, ``"inactive"``).
    """

    FREE = "free"  # identified
    HELD = "held"  # kept at its value (see the reason)
    INACTIVE = "inactive"  # its effect was not added


class TargetsFrame(enum.Enum):
    """Where the targets of ``compensate`` come from (``.value`` is the CLI word).

    * ``NOMINAL`` -- the nominal-FK TCP pose of the input's commands ``q1..q6``;
    * ``BASE`` -- TCP positions ``x, y, z`` in the robot base frame (orientation of the
      nominal FK of the row's commands);
    * ``MEASUREMENT`` -- positions of the *measured point* in the measurement frame.
    """

    NOMINAL = "nominal"
    BASE = "base"
    MEASUREMENT = "measurement"


class DataError(InputError):
    """The data cannot support the identification asked (message names what is missing)."""


class TargetsError(InputError):
    """The targets of ``compensate`` are missing or inconsistent (message names the file,
    column, row and value)."""


@dataclass
class ParameterEstimate:
    """One model parameter after identification (SI units).

    Attributes
    ----------
    name : str
        Parameter name (``models.effects.PARAM_NAMES``).
    effect : str
        Effect (or declared group) the parameter belongs to.
    value : float
        Value, SI unit ``unit``.
    std : float or None
        Standard deviation, same unit (None when not identified).
    unit : str
    status : ParameterStatus
        ``FREE`` (identified), ``HELD`` (kept at ``value``, see ``reason``) or
        ``INACTIVE`` (its effect was not added); ``status.value`` is the report string.
    reason : str
    """

    name: str
    effect: str
    value: float
    std: float | None
    unit: str
    status: ParameterStatus
    reason: str = ""


@dataclass
class CandidateScore:
    """Score of one candidate effect at one step of the selection.

    RMS values are per axis, m (weighted fits report the unweighted RMS); ``bic`` and
    ``delta_bic`` are dimensionless; ``explained_share`` is the fraction of the
    cross-validated residual variance above the noise floor that the effect explains.
    """

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
    detail: str = ""


@dataclass
class SelectionStep:
    """One step of the forward (or backward) selection (RMS per axis, m)."""

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
    x : ndarray, shape (N,) or None
        The variable (per inlier row), for plots, in its own unit.
    description : str
    y : ndarray, shape (N,) or None
        Per-row quantity to plot against ``x`` (None: the residual components).
    y_label : str
    """

    variable: str
    explained_fraction: float
    p_value: float
    significant: bool
    x: np.ndarray | None = None
    description: str = ""
    y: np.ndarray | None = None
    y_label: str = ""


#: An identified model is an :class:`models.arm.ArmModel` (the one model of the arm).
IdentifiedModel = ArmModel


@dataclass
class IdentificationResult:
    """Everything ``compplan identify`` reports.

    RMS values are per axis (``sqrt(mean(r_ij^2))`` over rows and x, y, z), m;
    residuals are ``predicted - measured`` in the measurement frame, (N, 3), m.
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
    #: Identified joint error maps (``problems.identify.map_summary.ErrorMapSummary``), empty without any.
    error_maps: list[Any] = field(default_factory=list)
    #: With orientation data: ``rms_before_rad``, ``rms_after_rad`` (per axis, inlier orientation rows),
    #: ``n_rows`` and ``identifiable_thanks_to_orientation`` (parameter names); None without.
    orientation: dict[str, Any] | None = None

    @property
    def rms_before_mm(self) -> float:
        """Per-axis RMS before identification, mm."""
        return self.rms_before_m * 1e3

    @property
    def rms_after_mm(self) -> float:
        """Per-axis RMS after identification, mm."""
        return self.rms_after_m * 1e3


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
        Target poses, base frame (target-frame coordinates -> base-frame coordinates):
        of the TCP, or of the measured point for measurement-frame targets.
    residual_m, residual_rad : ndarray, shape (N,)
        Model-predicted position (m) and orientation (rad) error after compensation.
    status : CompensationStatus
        ``OK``; ``WARNING`` when every row is compensated but part of the model cannot
        be (see ``reason``); ``FAILED`` when rows are not compensated (``failed_rows``).
    reason : str
    failed_rows : ndarray of int
        Row indices not compensated to the tolerance.
    targets_frame : TargetsFrame
        Where the targets came from.
    warnings : list of str
        Caveats that hold whatever the status (e.g. parameters that cannot be
        compensated in the base frame), one line each.
    """

    q_command: np.ndarray
    q_deflected: np.ndarray
    target: np.ndarray
    residual_m: np.ndarray
    residual_rad: np.ndarray
    status: CompensationStatus
    reason: str
    failed_rows: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    targets_frame: TargetsFrame = TargetsFrame.NOMINAL
    warnings: list[str] = field(default_factory=list)
