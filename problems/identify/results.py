"""Result objects and statuses of the identification and of its applications.

Everything is SI (m, rad, N, N*m); reports convert at their edge.  The
``*_m`` fields are lengths in metres; ``*_mm`` properties are the report's
millimetres.
"""

from __future__ import annotations

import enum
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from models.arm import ArmModel
from models.effects import PARAM_NAMES
from models.errors import InputError
from models.status import Status

from ..compensation import CompensationStatus
from ..measurements import Measurements
from .identifiability import Known, aliases_registration, structural_held

#: Progress callback of :func:`problems.identify.identify`: ``progress(message, done, total)``.
Progress = Callable[[str, int, int], None]


class IdentifyStatus(Status):
    """Outcome of an identification (``.value`` is the ``report.json`` string)."""

    OK = "ok"  # the model explains the data (noise floor or no structure left)
    UNEXPLAINED = "unexplained"  # structure remains that no library effect explains
    NOT_CONVERGED = "not_converged"
    IMPLAUSIBLE = "implausible_geometry"  # DH corrections too large for the declared robot: wrong robot file?
    #: the identified model predicts held-out poses worse than the nominal one (over-fitted: too few poses)
    DOES_NOT_GENERALISE = "does_not_generalise"


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
    cross-validated residual variance above the noise floor that the effect explains, never
    negative: 0 when the candidate does not lower the cross-validated residual (a candidate
    that raises it explains none; by how much it raises it is its CV RMS against the step's).
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
        ``max(0, 1 - CV RSS / RSS)`` of the residual: the share of its variance a cross-validated
        fit explains, 0 when the fit predicts held-out rows no better than their mean (no structure).
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
    #: What the user must be told (printed as warnings): repeated rows dropped, campaigns' registrations far apart.
    warnings: list[str] = field(default_factory=list)
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


# ----------------------------------------------------------------------------------
# Held parameters in a few groups: what each means and what to do
# ----------------------------------------------------------------------------------

#: The groups of held parameters (``HeldGroup.kind``), in the order they are reported.
HELD_KINDS = ("setup_alias", "redundant", "undetermined")
#: The longest ``HeldSummary.message`` (characters): one terminal line, the names in the report.
HELD_MESSAGE_MAX_CHARS = 300
#: A joint index in a parameter name (``dd[3]``, ``hardening.b[4].knot5``): 1-based.
_JOINT_IN_NAME = re.compile(r"\[(\d+)\]")


@dataclass(frozen=True)
class HeldGroup:
    """Held parameters that share a cause (:data:`HELD_KINDS`).

    * ``setup_alias`` -- cannot be told apart from the registration or the measured point
      (unregistered data): the model is exact in the measurement frame only;
    * ``redundant`` -- aliased in the model's parametrisation whatever the data (the
      parameters they alias with carry their effect): nothing to do;
    * ``undetermined`` -- these data do not determine them: ``joints`` are those to exercise.
    """

    kind: str
    names: list[str]
    meaning: str
    action: str
    joints: list[int] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": self.kind,
            "count": len(self.names),
            "names": list(self.names),
            "meaning": self.meaning,
            "action": self.action,
            "joints": list(self.joints),
        }


@dataclass(frozen=True)
class HeldSummary:
    """The held parameters of an identification in groups (:class:`HeldGroup`) and one line
    (``message``, at most :data:`HELD_MESSAGE_MAX_CHARS`) that says what they mean and what to do;
    the full list, with each parameter's reason, is ``identifiability['held']``."""

    groups: list[HeldGroup]

    @property
    def count(self) -> int:
        return sum(len(g.names) for g in self.groups)

    @property
    def message(self) -> str:
        """One line: how many, and per group what it means and what to do ("" when none held)."""
        if not self.groups:
            return ""
        words = {
            "setup_alias": "alias with the registration/measured point (exact in the measurement frame; registered "
            "data identify them)",
            "redundant": "redundant in the model (nothing to do)",
            "undetermined": "undetermined ({action})",
        }
        parts = [f"{len(g.names)} " + words[g.kind].format(action=g.action) for g in self.groups]
        return f"{self.count} parameters held at nominal (report.json 'held_parameters'): " + "; ".join(parts)

    def to_dict(self) -> dict[str, Any]:
        return {"count": self.count, "message": self.message, "groups": [g.to_dict() for g in self.groups]}


def joints_text(joints: list[int]) -> str:
    """``joint 4``, ``joints 4, 5``, ``joints 1-3, 5`` (runs of three or more joined)."""
    if len(joints) == 1:
        return f"joint {joints[0]}"
    runs: list[list[int]] = []
    for j in joints:
        if runs and j == runs[-1][-1] + 1:
            runs[-1].append(j)
        else:
            runs.append([j])
    words = [f"{r[0]}-{r[-1]}" if len(r) >= 3 else ", ".join(map(str, r)) for r in runs]
    return "joints " + ", ".join(words)


def _undetermined_action(held: list[dict[str, Any]]) -> tuple[str, list[int]]:
    """What to add so that the data determine ``held`` (entries name, reason): the joints of
    the parameters and of those they cannot be told apart from."""
    joints: set[int] = set()
    for h in held:
        joints.update(int(j) for j in _JOINT_IN_NAME.findall(h["name"]))
        _head, _sep, tail = str(h.get("reason", "")).partition("cannot be told apart from ")
        joints.update(int(j) for j in _JOINT_IN_NAME.findall(tail))
    js = sorted(j for j in joints if 1 <= j <= 6)
    if not js:
        return "add poses spread over the workspace and varied loads", []
    return f"add poses and loads exercising {joints_text(js)}", js


def held_summary(res: IdentificationResult) -> HeldSummary:
    """The held parameters of ``res`` in groups (:class:`HeldSummary`).

    ``setup_alias``: those whose reason names the registration or the measured point first
    (:func:`~.identifiability.aliases_registration`, as :func:`~.apply.unobservable_in_base`);
    ``redundant``: the others that a rich synthetic design of the same model holds too
    (:func:`~.identifiability.structural_held`); ``undetermined``: the rest.  Parameters of a
    part of the set-up declared known are not held by the data and are left out.
    """

    held = list(res.identifiability.get("held") or [])
    if not held:
        return HeldSummary([])
    known_words = str(res.identifiability.get("known") or "")
    known = Known("registration" in known_words, "measured point" in known_words)
    structural = structural_held(res.model.nominal, list(res.model.active_effects), known)
    structural_names = {PARAM_NAMES[i] for i in structural}
    by_kind: dict[str, list[dict[str, Any]]] = {k: [] for k in HELD_KINDS}
    for h in held:
        if aliases_registration(str(h.get("reason", ""))):
            by_kind["setup_alias"].append(h)
        elif h["name"] in structural_names:
            by_kind["redundant"].append(h)
        else:
            by_kind["undetermined"].append(h)
    action, joints = _undetermined_action(by_kind["undetermined"])
    text = {
        "setup_alias": (
            "cannot be told apart from the registration or the measured point: held at nominal (zero for DH "
            "errors), their effect is absorbed by the identified registration and measured point, so the model "
            "predicts the measurement frame exactly but not the base frame",
            "none in the measurement frame; for the base frame, calibrate the registration and the tool and "
            "identify with --registered (or --known)",
        ),
        "redundant": (
            "redundant in the model: no data can tell them from the parameters their reasons name, which carry "
            "their effect",
            "none",
        ),
        "undetermined": (
            "not determined by these data: over these poses and loads their effect is too small or too like that "
            "of other parameters",
            action,
        ),
    }
    groups = [
        HeldGroup(k, [h["name"] for h in by_kind[k]], *text[k], joints=joints if k == "undetermined" else [])
        for k in HELD_KINDS
        if by_kind[k]
    ]
    return HeldSummary(groups)
