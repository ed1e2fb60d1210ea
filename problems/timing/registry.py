"""Registry of the timing methods, their tolerances and the controller-period bounds.

A method is a :class:`TimingMethod`: a name, a runner that times a
:class:`~problems.timing.path.SplinePath` under :class:`JointLimits`, the
names of its keyword options with their validator, and the limits its
``OK`` status depends on. Each backend module (``toppra_method``,
``ruckig_method``, ``jerk_optimal``) builds one and passes it to
:func:`register_method` when it is imported; :mod:`problems.timing` imports
every module of the package and of the folders named by
``$COMPPLAN_TIMING_PATH`` (:func:`models.plugins.import_plugins`), so adding
a method means adding one module that registers itself, in the package or in
such a folder. :func:`time_parametrize` validates the common inputs and
dispatches by name through the registry.

The registry also owns the tolerances shared by all methods
(:data:`LIMIT_RATIO_TOL`, :data:`MONOTONE_TOL`, :data:`SHRINK_MARGIN_MAX`)
and the bounds of the controller period (:data:`DT_MAX_S`,
:data:`DT_DEFAULT_S`).

A method's record is the one place for everything the rest of the product says about it:
its display name and one-line description (reports, summaries), the limits its ``OK``
status checks (``summary.json`` ``limits_enforced``, exports), its largest controller period,
whether a problem runs it by default (:func:`default_methods`), whether and with which
preference the controller may run its trajectory (:func:`controller_methods`), and the
sentences the summary quotes. A problem file validates ``[timing]`` against the registry.
Every check of the sampled trajectory and the status and reason it earns are made by one
function, :func:`problems.timing.verification.finish_trajectory`, which every backend calls.
A reason never repeats the status (callers show ``f"{status.value}: {reason}"``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any
from collections.abc import Callable, Iterable, Mapping

import numpy as np

from models.errors import InputError
from problems.timing.path import SplinePath, validate_path
from problems.timing.trajectory import LIMIT_KEYS, JointLimits, TimingStatus, Trajectory, empty_trajectory

__all__ = [
    "DT_DEFAULT_S",
    "DT_MAX_S",
    "LIMIT_RATIO_TOL",
    "MAX_TRAJECTORY_SAMPLES",
    "MONOTONE_TOL",
    "SHRINK_MARGIN_MAX",
    "TimingMethod",
    "available_methods",
    "check_integer_options",
    "check_sample_count",
    "check_shrink_margin",
    "controller_methods",
    "default_methods",
    "display_name",
    "get_method",
    "register_method",
    "time_parametrize",
    "unregister_method",
    "validate_options",
]

# --------------------------------------------------------------------------- #
# Tolerances and dt bounds (shared by every method)
# --------------------------------------------------------------------------- #

#: A limit ratio ``peak |value| / limit`` counts as within the limit when it
#: is ``<= 1 + LIMIT_RATIO_TOL``.
LIMIT_RATIO_TOL: float = 1e-9

#: Largest accepted controller period (s).
DT_MAX_S: float = 0.1

#: Default controller period of :func:`time_parametrize` (s).
DT_DEFAULT_S: float = 0.008

#: Largest allowed backwards motion of the time law, relative to max sd.
MONOTONE_TOL: float = 1e-9

#: Upper bound of the ``shrink_margin`` option of every method (-).
SHRINK_MARGIN_MAX: float = 10.0

#: Largest number of samples (at the controller period ``dt``) of a trajectory. Longer
#: motions are refused before anything is sampled: 10^6 samples are 2.2 h at dt = 8 ms or
#: 33 min at 2 ms, and a CSV of about 0.5 GB; a limit given in the wrong unit (a velocity
#: limit of 1e-9 rad/s) would otherwise ask for terabytes.
MAX_TRAJECTORY_SAMPLES: int = 1_000_000


class TimeLawTooLong(Exception):
    """A method's time law is longer than the sample cap allows (raised by :func:`check_times`).

    The duration's lower bound passed the cap before the method ran (so the limits are not
    off by a unit): the method slowed the path to a near stop. :func:`time_parametrize` turns it
    into a ``FAILED`` trajectory whose reason says where the path is hard.

    Attributes
    ----------
    duration_s : float
        The time law's duration, s.
    """

    def __init__(self, duration_s: float) -> None:
        super().__init__(f"time law of {duration_s:.4g} s")
        self.duration_s = duration_s


# --------------------------------------------------------------------------- #
# Method records
# --------------------------------------------------------------------------- #

#: ``run(path, limits, dt, options) -> Trajectory``: times ``path`` (rad)
#: under ``limits`` (SI) with samples every ``dt`` s; ``options`` are already
#: validated. Expected outcomes are returned as statuses, never raised.
MethodRunner = Callable[[SplinePath, JointLimits, float, Mapping[str, Any]], Trajectory]

#: ``validate(options) -> options``: checks and normalises the values of the
#: method's keyword options (names are already known to be valid); raises
#: :class:`~models.errors.InputError` naming the option, its value and what is expected.
OptionValidator = Callable[[dict[str, Any]], dict[str, Any]]

#: ``controller_rank`` of a method whose trajectory the controller never runs.
CONTROLLER_RANK_NEVER: None = None


@dataclass(frozen=True)
class TimingMethod:
    """A registered time-parametrisation method: everything the product says about it.

    Attributes
    ----------
    name : str
        The ``method`` argument of :func:`time_parametrize` and the name a problem file's
        ``[timing] methods`` uses.
    run : MethodRunner
        The backend.
    options : tuple of str
        Names of the keyword options the method accepts (also the keys of the problem
        file's ``[timing.<name>]`` table).
    validate_options : OptionValidator
        Value check of those options.
    checked_limits : tuple of str
        Keys of :data:`~problems.timing.trajectory.LIMIT_KEYS` that decide the
        ``OK`` status (the other ratios are reported only): the limits it enforces.
    description : str
        One line for listings.
    underuse_cause : str
        Why a trajectory of this method can stay under half of every limit (quoted by
        :func:`problems.timing.limit_use.limit_use` when it does).
    display_name : str
        The name reports and figures show (``"TOPP-RA"``); ``name`` if empty.
    controller_rank : int or None
        Preference for the trajectory the controller runs (``trajectory.csv``): among the
        methods a problem runs, the one of lowest rank is the controller's; None
        (:data:`CONTROLLER_RANK_NEVER`): never the controller's.
    default : bool
        Run when a problem names no methods (:func:`default_methods`).
    program_default : bool
        Run when a problem whose path is a CAM program names no methods
        (:func:`program_default_methods`): a program is timed stretch by stretch between its stops,
        often 10^3 of them, so the default there is a method that is fast per stretch.
    dt_max_s : float
        Largest controller period the method accepts (s), at most :data:`DT_MAX_S`.
    duration_note : str
        What the duration of its trajectory is when the controller runs it (the summary
        headline's ``duration_note``, followed by `` (trajectory.csv)``); default
        ``"<display_name>: the trajectory the controller runs"``.
    time_optimal_reference : bool
        The method is a time-optimal reference: when it runs beside the controller's method,
        the headline gives its duration (``duration_time_optimal_s``, with
        ``duration_time_optimal_method``) as the bound the controller's trajectory is
        compared with.
    """

    name: str
    run: MethodRunner
    options: tuple[str, ...]
    validate_options: OptionValidator
    checked_limits: tuple[str, ...]
    description: str = ""
    underuse_cause: str = ""
    display_name: str = ""
    controller_rank: int | None = CONTROLLER_RANK_NEVER
    default: bool = False
    program_default: bool = False
    dt_max_s: float = DT_MAX_S
    duration_note: str = ""
    time_optimal_reference: bool = False

    def __post_init__(self) -> None:
        if not self.display_name:
            object.__setattr__(self, "display_name", self.name)
        if not self.duration_note:
            object.__setattr__(self, "duration_note", f"{self.display_name}: the trajectory the controller runs")

    @property
    def enforces_jerk(self) -> bool:
        """Whether the jerk limit decides its status (a jerk-limited trajectory)."""
        return "jerk" in self.checked_limits


_METHODS: dict[str, TimingMethod] = {}


def register_method(method: TimingMethod, *, replace: bool = False) -> TimingMethod:
    """Add ``method`` to the registry (in registration order) and return it.

    Raises
    ------
    InputError
        If the name is empty, a checked limit is unknown, ``dt_max_s`` is not in
        ``(0, DT_MAX_S]``, the controller rank is not an int (or None), or the name is
        already registered and ``replace`` is false.
    """
    if not isinstance(method.name, str) or not method.name:
        raise InputError(f"a timing method needs a non-empty name, got {method.name!r}")
    if not method.checked_limits:
        raise InputError(
            f"timing method {method.name!r}: checked_limits is empty; name the limits that decide its "
            f"status, from {list(LIMIT_KEYS)}"
        )
    unknown = [k for k in method.checked_limits if k not in LIMIT_KEYS]
    if unknown:
        raise InputError(
            f"timing method {method.name!r}: unknown checked limit(s) {unknown}; valid: {list(LIMIT_KEYS)}"
        )
    if not (0.0 < method.dt_max_s <= DT_MAX_S):
        raise InputError(
            f"timing method {method.name!r}: dt_max_s = {method.dt_max_s!r} s must be in (0, {DT_MAX_S}] s"
        )
    rank = method.controller_rank
    if rank is not None and (isinstance(rank, bool) or not isinstance(rank, int)):
        raise InputError(f"timing method {method.name!r}: controller_rank must be an int or None, got {rank!r}")
    if method.name in _METHODS and not replace:
        raise InputError(f"timing method {method.name!r} is already registered")
    _METHODS[method.name] = method
    return method


def unregister_method(name: str) -> None:
    """Remove a method (no error if it is not registered)."""
    _METHODS.pop(name, None)


def available_methods() -> tuple[str, ...]:
    """Names of the registered methods, in registration order."""
    return tuple(_METHODS)


def default_methods() -> tuple[str, ...]:
    """The methods a problem runs when it names none (registered with ``default=True``), in
    registration order."""
    return tuple(m.name for m in _METHODS.values() if m.default)


def program_default_methods() -> tuple[str, ...]:
    """The methods a problem with a CAM program path runs when it names none (registered with
    ``program_default=True``), in registration order."""
    return tuple(m.name for m in _METHODS.values() if m.program_default)


def controller_methods(names: Iterable[str] | None = None) -> tuple[str, ...]:
    """The methods whose trajectory the controller may run, most preferred first.

    Parameters
    ----------
    names : iterable of str, optional
        Restrict to these (e.g. a problem's methods); unregistered names are left out.
        Default: every registered method.

    Returns
    -------
    tuple of str
        By ``controller_rank`` (ties in registration order); methods without a rank are
        left out.
    """
    chosen = set(_METHODS) if names is None else set(names)
    ranked = [
        (m.controller_rank, i, m.name)
        for i, m in enumerate(_METHODS.values())
        if m.name in chosen and m.controller_rank is not None
    ]
    return tuple(name for _, _, name in sorted(ranked))


def display_name(name: str) -> str:
    """The display name of method ``name`` (``name`` itself if it is not registered)."""
    m = _METHODS.get(name)
    return m.display_name if m is not None else name


def get_method(name: str) -> TimingMethod:
    """The registered method called ``name``.

    Raises
    ------
    InputError
        If no method has that name; the message names it and lists the
        registered ones.
    """
    if not isinstance(name, str) or name not in _METHODS:
        raise InputError(f"unknown method {name!r}; valid methods: {list(available_methods())}")
    return _METHODS[name]


# --------------------------------------------------------------------------- #
# Input checks
# --------------------------------------------------------------------------- #


def validate_dt(dt: float, dt_max: float = DT_MAX_S, method: str = "") -> float:
    """Controller period as float (s).

    Parameters
    ----------
    dt : float
        The controller period, s.
    dt_max : float
        Its largest accepted value, s (a method's ``dt_max_s``).
    method : str
        The timing method, for the message.

    Raises
    ------
    InputError
        Not a number, not finite, ``<= 0`` or ``> dt_max``.
    """
    who = f" of timing method {method!r}" if method and dt_max < DT_MAX_S else ""
    try:
        value = float(dt)
    except (TypeError, ValueError) as exc:
        raise InputError(f"dt must be a number (s), got {dt!r}") from exc
    if not math.isfinite(value) or value <= 0.0 or value > dt_max:
        raise InputError(f"dt must be finite, > 0 and <= {dt_max} s{who}, got {dt!r}")
    return value


def check_sample_count(duration_s: float, dt: float, method: str = "", lower_bound: bool = False) -> int:
    """Number of samples of a motion of ``duration_s`` s at ``dt`` s, checked against the cap.

    Parameters
    ----------
    duration_s : float
        Duration of the motion, s (or a lower bound of it, ``lower_bound=True``).
    dt : float
        Controller period, s.
    method : str
        The timing method, for the message.
    lower_bound : bool
        Whether ``duration_s`` is a lower bound (the message says "at least").

    Returns
    -------
    int
        ``ceil(duration_s / dt) + 1``.

    Raises
    ------
    InputError
        More than :data:`MAX_TRAJECTORY_SAMPLES` samples (or a non-finite duration): the
        message gives the number of samples, the duration, ``dt`` and the cap.
    """
    n = duration_s / dt + 1.0 if math.isfinite(duration_s) else math.inf
    if n > MAX_TRAJECTORY_SAMPLES:
        least = "at least " if lower_bound else ""
        who = f"timing ({method})" if method else "timing"
        count = f"{n:.4g}" if math.isfinite(n) else "infinitely many"
        raise InputError(
            f"{who}: the trajectory would need {least}{count} samples ({least}{duration_s:.4g} s at "
            f"dt = {dt:g} s), more than the cap of {MAX_TRAJECTORY_SAMPLES} samples "
            "(MAX_TRAJECTORY_SAMPLES); the joint limits are probably in the wrong unit (velocity in "
            "rad/s, acceleration in rad/s^2, jerk in rad/s^3): raise them, or raise dt"
        )
    return int(math.ceil(duration_s / dt)) + 1


def _duration_lower_bound(q: np.ndarray, limits: JointLimits, checked: tuple[str, ...]) -> float:
    """A duration (s) no rest-to-rest motion along the waypoints ``q`` (N, n) can beat.

    The spline passes through every waypoint, so joint ``j`` travels at least the total
    variation ``D_j`` of its waypoints: at most ``v_j`` it takes ``D_j / v_j``, and from rest to
    rest at most ``a_j`` at least ``2 sqrt(D_j / a_j)`` (and, jerk-limited, ``(32 D_j / j_j)^(1/3)``).
    """
    travel = np.sum(np.abs(np.diff(q, axis=0)), axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        bounds = [travel / limits.velocity, 2.0 * np.sqrt(travel / limits.acceleration)]
        if "jerk" in checked:
            bounds.append(np.cbrt(32.0 * travel / limits.jerk))
    t = np.nan_to_num(np.max(np.vstack(bounds), axis=0), nan=0.0, posinf=math.inf)
    return float(np.max(t)) if t.size else 0.0


def check_integer_options(out: dict[str, Any], bounds: Iterable[tuple[str, int]]) -> None:
    """Check (in the given order) that each present option is an int ``>= lo``.

    Parameters
    ----------
    out : dict
        Options; the checked values are replaced by plain ``int``.
    bounds : iterable of (str, int)
        ``(name, lo)`` pairs.
    """
    for key, lo in bounds:
        if key in out:
            val = out[key]
            if isinstance(val, bool) or not isinstance(val, (int, np.integer)) or val < lo:
                raise InputError(f"option {key} must be an integer >= {lo}, got {val!r}")
            out[key] = int(val)


def check_shrink_margin(out: dict[str, Any]) -> None:
    """Check ``shrink_margin`` (if present) is in ``[0, SHRINK_MARGIN_MAX]``; make it float."""
    if "shrink_margin" in out:
        val = out["shrink_margin"]
        try:
            fval = float(val)
        except (TypeError, ValueError):
            fval = math.nan
        if not (0.0 <= fval <= SHRINK_MARGIN_MAX):
            raise InputError(f"option shrink_margin must be in [0, {SHRINK_MARGIN_MAX}], got {val!r}")
        out["shrink_margin"] = fval


def validate_options(method: TimingMethod, options: Mapping[str, Any]) -> dict[str, Any]:
    """Reject unknown option names, then check the values (the method's validator).

    Raises
    ------
    InputError
        An unknown option name (the message lists the valid ones) or a bad value.
    """
    allowed = method.options
    unknown = sorted(set(options) - set(allowed))
    if unknown:
        raise InputError(f"unknown option(s) {unknown} for method {method.name!r}; valid options: {list(allowed)}")
    return method.validate_options(dict(options))


# --------------------------------------------------------------------------- #
# Entry point
# --------------------------------------------------------------------------- #


def _zero_length_trajectory(method: str, q: np.ndarray, n_input: int, dt: float) -> Trajectory:
    """``INFEASIBLE`` result for a path whose waypoints are all identical.

    One sample at ``t = 0`` holding ``q[0]`` (shape ``(n,)``, rad) at rest.
    """
    n = q.shape[1]
    zeros = np.zeros((1, n))
    return Trajectory(
        method=method,
        status=TimingStatus.INFEASIBLE,
        reason=(
            f"path has zero length (all {n_input} waypoints are "
            "identical); nothing to time-parametrise, the single sample holds "
            "the start configuration at rest"
        ),
        t=np.zeros(1),
        q=q[:1].copy(),
        qd=zeros,
        qdd=zeros.copy(),
        qddd=zeros.copy(),
        duration_s=0.0,
        limit_ratio={k: np.zeros(n) for k in LIMIT_KEYS},
        dt=dt,
    )


def _too_long_trajectory(method: str, q: np.ndarray, dt: float, duration_s: float, bound_s: float) -> Trajectory:
    """``FAILED`` result (no samples) of a method whose time law is longer than the sample cap
    allows while the path's lower bound ``bound_s`` is not: the reason names the largest joint
    step between waypoints against the median one (a sharp corner is the usual cause)."""
    steps = np.max(np.abs(np.diff(q, axis=0)), axis=1)
    k = int(np.argmax(steps))
    median = float(np.median(steps))
    ratio = f", {steps[k] / median:.3g}x the median step" if median > 0 else ""
    return empty_trajectory(
        method,
        TimingStatus.FAILED,
        (
            f"the time law slows the path to a near stop ({duration_s:.4g} s, more than the cap of "
            f"{MAX_TRAJECTORY_SAMPLES} samples at dt = {dt:g} s, while no motion along these waypoints needs "
            f"more than {bound_s:.4g} s at these limits): a sharp corner is the usual cause; the largest joint "
            f"step is {steps[k]:.4g} rad between waypoints {k} and {k + 1}{ratio}: blend the corners or space "
            "the waypoints evenly"
        ),
        q.shape[1],
        dt,
    )


def time_parametrize(
    q_path: np.ndarray,
    limits: JointLimits,
    method: str = "toppra",
    dt: float = DT_DEFAULT_S,
    **options: Any,
) -> Trajectory:
    """Time-parametrise a joint-space path, rest to rest.

    Parameters
    ----------
    q_path : np.ndarray
        Shape ``(N, n)``, rad (joint space). Waypoints of the geometric path,
        ``N >= 2``, ``n`` equal to ``limits.n_joints``. Consecutive exact
        duplicates are dropped. The trajectory follows the natural cubic
        chord-length spline through the waypoints (:mod:`.path`).
    limits : JointLimits
        Per-joint velocity (rad/s), acceleration (rad/s^2), jerk (rad/s^3).
    method : str
        A registered method (:func:`available_methods`), e.g. ``"toppra"``
        (time-optimal, velocity and acceleration limits), ``"jerk_optimal"``
        (time-optimal, jerk limited too) or ``"ruckig"`` (jerk-limited).
    dt : float
        Controller period (s), ``0 < dt <=`` the method's ``dt_max_s``
        (:data:`DT_MAX_S` for the built-in ones).
    **options
        Method options (the method's ``options``). ``toppra``
        (:mod:`.toppra_method`): ``gridpoints``, ``max_iterations``,
        ``shrink_margin``, ``time_law``, ``smoothing_s``, ``refinements``.
        ``ruckig`` (:mod:`.ruckig_method`): ``max_iterations``,
        ``shrink_margin``. ``jerk_optimal`` (:mod:`.jerk_optimal`):
        ``gridpoints``, ``max_iterations``.

    Returns
    -------
    Trajectory
        Always returned for expected outcomes: ``OK``; ``LIMIT_EXCEEDED``
        (samples present, limits not met after the allowed iterations);
        ``INFEASIBLE`` (zero-length path: one sample at the start at rest,
        ``duration_s = 0``; or TOPP-RA reports the instance uncontrollable);
        ``FAILED`` (the library failed; empty samples, NaN duration, the
        solver's code in ``solver_code`` where it gave one; or the method's time law
        slows the path to a near stop, longer than the sample cap although the path's
        lower bound is not: the reason names the largest joint step between waypoints).

    Raises
    ------
    InputError
        (a subclass of ``ValueError``) Unknown ``method`` (the message names it
        and lists the registered ones); ``limits`` not a :class:`JointLimits`;
        an unknown option name or a bad option value; malformed ``q_path``
        (shape, joint count, non-finite value: the message names the waypoint
        row and joint); bad ``dt``.
    """
    spec = get_method(method)
    if not isinstance(limits, JointLimits):
        raise InputError(
            f"limits must be a JointLimits (velocity, acceleration, jerk per joint), got {type(limits).__name__}"
        )
    opts = validate_options(spec, options)
    dt = validate_dt(dt, spec.dt_max_s, spec.name)
    q, n_input = validate_path(q_path, limits.n_joints)
    if q.shape[0] < 2:
        return _zero_length_trajectory(spec.name, q, n_input, dt)
    # refuse a motion longer than the sample cap before any method runs or samples
    bound = _duration_lower_bound(q, limits, spec.checked_limits)
    check_sample_count(bound, dt, spec.name, lower_bound=True)
    try:
        return spec.run(SplinePath(q), limits, dt, opts)
    except TimeLawTooLong as exc:
        return _too_long_trajectory(spec.name, q, dt, exc.duration_s, bound)
