"""Time parametrisation of a joint-space path (TOPP-RA or Ruckig).

The input is a geometric path given as joint waypoints ``q_path`` (shape
``(N, n)``, rad). Both methods time the *same* geometric path:

Geometric path (shared by both methods)
    A cubic spline ``P(s)`` through the waypoints over the path parameter
    ``s`` in ``[0, 1]``, with ``s`` proportional to the cumulative joint-space
    chord length (Euclidean norm of the waypoint differences, rad) and
    *natural* end conditions (``P''(0) = P''(1) = 0``). The spline is C2, it
    passes through every waypoint in order (waypoint ``k`` sits at the knot
    ``s_k``), and waypoints that lie on a straight line give an exactly
    straight path. Natural (rather than clamped zero-derivative) end
    conditions are used because ``P'(s) = 0`` would make the path singular
    for the timing (no velocity bound from the joint limits) at the ends;
    rest at the ends comes from the time law (``ds/dt = 0``), not from the
    path.

    Consecutive waypoints that are *exactly* identical are dropped (they add
    no geometry); if that leaves a single waypoint the path has zero length
    and :func:`time_parametrize` returns status ``INFEASIBLE``. Distinct but
    nearly identical neighbours are kept unless their chord is too small to
    give strictly increasing knots, which raises ``ValueError``.

Every trajectory is ``q(t) = P(s(t))`` with a monotone scalar time law
``s(t)`` from ``s = 0`` at rest to ``s = 1`` at rest, so it follows the path
exactly. The joint derivatives are obtained analytically by the chain rule::

    qd   = P'(s) sd
    qdd  = P''(s) sd^2 + P'(s) sdd
    qddd = P'''(s) sd^3 + 3 P''(s) sd sdd + P'(s) sddd

``method="toppra"``
    Time-optimal under joint velocity and acceleration limits
    (``toppra.algorithm.TOPPRA`` with ``JointVelocityConstraint`` and
    ``JointAccelerationConstraint``, interpolation discretisation, ``seidel``
    solver) on a grid that always contains the waypoint knots. TOPP-RA returns
    ``sd`` at the gridpoints, i.e. a law with constant path acceleration
    between gridpoints (piecewise-quadratic ``s(t)``, acceleration jumps).
    Two ways to turn that into a C2 time law are offered (option
    ``time_law``):

    * ``"smoothed"`` (default): the constant-acceleration law filtered by a
      causal moving average of width ``smoothing_s`` (default
      ``TOPPRA_SMOOTHING_S``), evaluated exactly from the piecewise
      polynomial and its antiderivative. It stays within the range of the
      unfiltered path velocity/acceleration over the window, is monotone,
      ends with zero velocity *and* acceleration, has finite jerk (about the
      acceleration jump divided by the window) and lasts ``smoothing_s``
      longer than the raw law.
    * ``"spline"``: cubic spline through the ``(t_i, s_i)`` pairs with zero
      end velocity (the scalar analogue of toppra's own ``ParametrizeSpline``
      output). It rings between gridpoints: about 10-15 % acceleration
      overshoot, whatever the grid density, and large jerk.

    Either way, TOPP-RA only enforces the constraints at the gridpoints, so
    the result is checked on a fine time grid. While a velocity or
    acceleration ratio exceeds 1 (+ ``LIMIT_RATIO_TOL``), TOPP-RA is re-run,
    at most ``max_iterations`` runs in all:

    1. first (smoothed law only, at most ``refinements`` times, while the
       overshoot exceeds ``TOPPRA_REFINE_MIN_EXCESS``) with the grid
       intervals that produced the violation split in
       ``TOPPRA_REFINE_FACTOR`` (discretisation error shrinks with the grid);
    2. then with each offending joint's limit divided by
       ``r (1 + max(SHRINK_MARGIN_FLOOR, shrink_margin (r - 1)))`` (``r`` its
       measured peak ratio).

    If the last run still exceeds, the status is ``LIMIT_EXCEEDED``. The
    correction costs a little optimality: in a randomised sweep (6 joints,
    5-80 waypoints, straight, smooth and random-walk paths) the durations
    were a median 0.6 % and at most 2 % above a 5000-gridpoint reference.
    TOPP-RA does not limit jerk: the jerk ratio is reported but the status
    depends only on velocity and acceleration.

``method="ruckig"``
    Jerk-limited. Ruckig (community version) has no intermediate waypoints,
    so Ruckig plans the 1-DOF path parameter ``s`` rest-to-rest from 0 to 1
    under global bounds ``sd <= sd_max``, ``|sdd| <= sdd_max``,
    ``|sddd| <= sddd_max``. With ``A1, A2, A3`` the *exact* maxima over
    ``s`` of ``|P'|, |P''|, |P'''|`` per joint (computed from the spline
    coefficients: ``P'''`` is piecewise constant, ``P''`` piecewise linear,
    ``P'`` piecewise quadratic), the triangle inequality on the chain rule
    above gives sufficient conditions, per joint ``j``::

        A1_j sd_max                                          <= v_j
        A2_j sd_max^2 + A1_j sdd_max                         <= a_j
        A3_j sd_max^3 + 3 A2_j sd_max sdd_max + A1_j sddd_max <= jerk_j

    A small search over how the acceleration and jerk budgets are split
    between the terms picks the admissible bound set with the shortest Ruckig
    duration. The sampled trajectory is then verified; if a ratio still
    exceeds 1 (numerical edge cases only) the bounds are time-scaled by the
    measured ratio and Ruckig is re-run (bounded iterations). This global
    scheme is conservative on strongly curved paths (the slowest part of the
    path sets the pace everywhere); a segment-wise scheme is not implemented.
    Status ``OK`` requires all three ratios to be within tolerance.

Sampling and checks
    Samples are at ``t_k = k dt`` from 0; the last sample is the first
    multiple of ``dt`` at or after the end of the motion and holds the final
    waypoint at rest (zero velocity, acceleration and jerk), so
    ``duration_s = t[-1]`` is a multiple of ``dt``. ``limit_ratio`` is the
    peak ``|value| / limit`` per joint over the returned samples *and* a check
    grid ``VERIFY_OVERSAMPLE`` times finer than ``dt`` (plus, for TOPP-RA,
    the breakpoints of the time law, where its acceleration has kinks), so it
    also bounds what a finer controller would see, up to the variation
    between check points. Ruckig's ``at_time`` gives position, velocity and
    acceleration of ``s``; the jerk of ``s`` and the fine check grid are
    evaluated from Ruckig's jerk profile (``Trajectory.profiles``), which is
    cross-checked against ``at_time`` on every sample.

The module prints nothing; toppra's logger is raised to ``ERROR`` for the
duration of the call (not thread-safe with respect to other code changing
that logger's level concurrently).
"""

from __future__ import annotations

import contextlib
import enum
import logging
import math
import os
import tempfile
from dataclasses import dataclass, field
from typing import Any, Iterator, Mapping

import numpy as np
import ruckig
import toppra
import toppra.algorithm
import toppra.constraint
from scipy.interpolate import CubicSpline, PPoly

__all__ = [
    "LIMIT_RATIO_TOL",
    "JointLimits",
    "Trajectory",
    "TimingStatus",
    "VALID_METHODS",
    "time_parametrize",
]

# --------------------------------------------------------------------------- #
# Named constants (tolerances and defaults)
# --------------------------------------------------------------------------- #

#: Valid values of ``method``.
VALID_METHODS: tuple[str, ...] = ("toppra", "ruckig")

#: A limit ratio ``peak |value| / limit`` counts as within the limit when it
#: is ``<= 1 + LIMIT_RATIO_TOL``.
LIMIT_RATIO_TOL: float = 1e-9

#: Largest accepted controller period (s).
DT_MAX_S: float = 0.1

#: The check grid used for ``limit_ratio`` is this many times finer than dt.
VERIFY_OVERSAMPLE: int = 4

#: TOPP-RA default number of gridpoints: max(MIN, PER_WAYPOINT * N).
TOPPRA_MIN_GRIDPOINTS: int = 200
TOPPRA_GRIDPOINTS_PER_WAYPOINT: int = 10

#: TOPP-RA time law: "smoothed" (default) or "spline", and the width of the
#: moving-average window (s) of the smoothed law.
TOPPRA_TIME_LAWS: tuple[str, ...] = ("smoothed", "spline")
TOPPRA_TIME_LAW: str = "smoothed"
TOPPRA_SMOOTHING_S: float = 0.01

#: TOPP-RA local grid refinement (before any limit shrinking): number of
#: refinement rounds (smoothed time law only; the spline law's overshoot does
#: not shrink with the grid), subdivision factor, and grid size cap.
TOPPRA_MAX_REFINEMENTS: int = 2
TOPPRA_REFINE_FACTOR: int = 4
TOPPRA_MAX_GRIDPOINTS: int = 20000
#: Refine only while the worst velocity/acceleration ratio exceeds 1 by more
#: than this; smaller overshoots go straight to limit shrinking.
TOPPRA_REFINE_MIN_EXCESS: float = 0.01

#: TOPP-RA limit-shrinking loop: total number of TOPP-RA runs, and the
#: divisor applied to a limit exceeded with peak ratio r > 1 is
#: r * (1 + max(SHRINK_MARGIN_FLOOR, shrink_margin * (r - 1))).
TOPPRA_MAX_ITERATIONS: int = 6
TOPPRA_SHRINK_MARGIN: float = 1.0
SHRINK_MARGIN_FLOOR: float = 1e-6
SHRINK_MARGIN_MAX: float = 10.0

#: Ruckig verification loop: total number of Ruckig runs and extra margin.
RUCKIG_MAX_ITERATIONS: int = 4
RUCKIG_SHRINK_MARGIN: float = 1e-3

#: Fractions scanned when splitting the acceleration/jerk budgets between the
#: terms of the chain rule (Ruckig global bound set).
RUCKIG_BUDGET_FRACTIONS: np.ndarray = np.linspace(0.05, 1.0, 20)

#: Largest allowed backwards motion of the time law, relative to max sd.
MONOTONE_TOL: float = 1e-9

#: Agreement required between Ruckig ``at_time`` and the profile evaluation
#: used for jerk and for the fine check grid (absolute, in units of s, s/t...,
#: relative to the respective bound).
RUCKIG_CONSISTENCY_TOL: float = 1e-7

_LIMIT_KEYS: tuple[str, ...] = ("velocity", "acceleration", "jerk")


# --------------------------------------------------------------------------- #
# Public data types
# --------------------------------------------------------------------------- #


class TimingStatus(enum.Enum):
    """Outcome of :func:`time_parametrize`."""

    OK = "ok"
    LIMIT_EXCEEDED = "limit_exceeded"
    INFEASIBLE = "infeasible"
    FAILED = "failed"


@dataclass(frozen=True)
class JointLimits:
    """Symmetric per-joint kinematic limits (SI units).

    Parameters
    ----------
    velocity : np.ndarray
        Shape ``(n,)``, rad/s, finite and > 0.
    acceleration : np.ndarray
        Shape ``(n,)``, rad/s^2, finite and > 0.
    jerk : np.ndarray
        Shape ``(n,)``, rad/s^3, finite and > 0.

    Raises
    ------
    ValueError
        If an array is not 1-D, is empty, the shapes differ, or a value is not
        finite or not > 0. The message names the quantity, the joint (1-based)
        and the value.

    Notes
    -----
    The arrays are stored as read-only float copies.
    """

    velocity: np.ndarray
    acceleration: np.ndarray
    jerk: np.ndarray

    def __post_init__(self) -> None:
        shape: tuple[int, ...] | None = None
        for name in _LIMIT_KEYS:
            raw = getattr(self, name)
            try:
                arr = np.array(raw, dtype=float)
            except (TypeError, ValueError) as exc:
                raise ValueError(
                    f"JointLimits.{name} must be a numeric array, got {raw!r}"
                ) from exc
            if arr.ndim != 1 or arr.size == 0:
                raise ValueError(
                    f"JointLimits.{name} must be a non-empty 1-D array (n,), "
                    f"got shape {arr.shape}"
                )
            if shape is None:
                shape = arr.shape
            elif arr.shape != shape:
                raise ValueError(
                    f"JointLimits.{name} has shape {arr.shape} but "
                    f"JointLimits.velocity has shape {shape}; all limits need "
                    "one value per joint"
                )
            bad = np.flatnonzero(~(np.isfinite(arr) & (arr > 0.0)))
            if bad.size:
                j = int(bad[0])
                raise ValueError(
                    f"JointLimits.{name}: joint {j + 1} has value {float(arr[j])!r}; "
                    "limits must be finite and > 0"
                )
            arr.flags.writeable = False
            object.__setattr__(self, name, arr)

    @property
    def n_joints(self) -> int:
        """Number of joints ``n``."""
        return int(self.velocity.shape[0])

    def as_dict(self) -> dict[str, np.ndarray]:
        """Limits keyed like :attr:`Trajectory.limit_ratio`."""
        return {k: getattr(self, k) for k in _LIMIT_KEYS}


@dataclass
class Trajectory:
    """A sampled, time-parametrised joint trajectory.

    Attributes
    ----------
    method : str
        ``"toppra"`` or ``"ruckig"``.
    status : TimingStatus
        ``OK`` only if every checked ratio is ``<= 1 + LIMIT_RATIO_TOL``
        (velocity and acceleration for TOPP-RA; all three for Ruckig).
    reason : str
        Human-readable explanation, always non-empty (also for ``OK``).
    t : np.ndarray
        Shape ``(M,)``, s. Uniform at ``dt`` from ``t[0] = 0``; ``t[-1]`` is
        the end time (a multiple of ``dt``) where the arm is at rest.
    q, qd, qdd, qddd : np.ndarray
        Shape ``(M, n)``: rad, rad/s, rad/s^2, rad/s^3, evaluated from the
        analytic trajectory (not finite differences).
    duration_s : float
        ``t[-1]`` (s). ``0.0`` for a zero-length path, NaN when no trajectory
        could be computed (then ``M = 0``).
    limit_ratio : dict[str, np.ndarray]
        Keys ``"velocity"``, ``"acceleration"``, ``"jerk"``; each shape
        ``(n,)``, dimensionless: peak ``|value| / limit`` over the samples and
        the finer check grid (see module docstring). NaN if unavailable.
    dt : float
        Controller period (s).
    iterations : int
        Number of TOPP-RA / Ruckig runs of the limit-verification loop
        (0 if none ran).
    first_pass_limit_ratio : dict[str, np.ndarray]
        Ratios of the first run, before any grid refinement or limit
        shrinking, on the check grid (same keys and shapes; empty if no run
        produced a trajectory). ``first_pass_limit_ratio["acceleration"]``
        above 1 shows the raw TOPP-RA overshoot that was corrected.
    """

    method: str
    status: TimingStatus
    reason: str
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    qddd: np.ndarray
    duration_s: float
    limit_ratio: dict[str, np.ndarray]
    dt: float
    iterations: int = 0
    first_pass_limit_ratio: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        """``True`` if :attr:`status` is ``OK``."""
        return self.status is TimingStatus.OK

    def to_csv(self, path: str | os.PathLike[str]) -> None:
        """Write the samples as CSV, atomically.

        Columns: ``t, q1..qn, qd1..qdn, qdd1..qddn`` (s, rad, rad/s,
        rad/s^2), one header line, one row per sample, values in ``%.17g``
        (round-trip exact). The data are written to a temporary file in the
        destination directory and moved into place with :func:`os.replace`,
        so ``path`` is either fully written or left untouched.

        Parameters
        ----------
        path : str or os.PathLike
            Destination file.

        Raises
        ------
        ValueError
            If the sample arrays have inconsistent shapes.
        OSError
            If the file cannot be written (nothing is left behind).
        """
        t = np.asarray(self.t)
        m = t.shape[0] if t.ndim == 1 else -1
        blocks = [np.asarray(self.q), np.asarray(self.qd), np.asarray(self.qdd)]
        if m < 0 or any(b.ndim != 2 or b.shape[0] != m for b in blocks):
            raise ValueError(
                "inconsistent trajectory arrays: t "
                f"{t.shape}, q {blocks[0].shape}, qd {blocks[1].shape}, "
                f"qdd {blocks[2].shape}"
            )
        n = blocks[0].shape[1]
        if any(b.shape[1] != n for b in blocks):
            raise ValueError("q, qd and qdd must have the same number of joints")
        header = ",".join(
            ["t"]
            + [f"q{j}" for j in range(1, n + 1)]
            + [f"qd{j}" for j in range(1, n + 1)]
            + [f"qdd{j}" for j in range(1, n + 1)]
        )
        data = np.column_stack([t] + blocks) if m else np.empty((0, 1 + 3 * n))

        dest = os.fspath(path)
        directory = os.path.dirname(os.path.abspath(dest))
        fd, tmp = tempfile.mkstemp(
            dir=directory, prefix="." + os.path.basename(dest) + ".", suffix=".tmp"
        )
        try:
            with os.fdopen(fd, "w", newline="") as fh:
                fh.write(header + "\n")
                np.savetxt(fh, data, fmt="%.17g", delimiter=",")
                fh.flush()
                os.fsync(fh.fileno())
            os.replace(tmp, dest)
        except BaseException:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
            raise


# --------------------------------------------------------------------------- #
# Geometric path
# --------------------------------------------------------------------------- #


class _SplinePath:
    """Natural cubic spline ``P(s)``, ``s`` in [0, 1] by chord length.

    Parameters
    ----------
    q_path : np.ndarray
        Shape ``(N, n)``, rad, ``N >= 2``, no consecutive exact duplicates.
    """

    def __init__(self, q_path: np.ndarray) -> None:
        chord = np.linalg.norm(np.diff(q_path, axis=0), axis=1)
        total = float(chord.sum())
        s = np.concatenate(([0.0], np.cumsum(chord))) / total
        s[-1] = 1.0
        steps = np.diff(s)
        if np.any(steps <= 0.0):
            k = int(np.flatnonzero(steps <= 0.0)[0])
            raise ValueError(
                f"waypoints {k} and {k + 1} are distinct but too close "
                f"(joint-space distance {chord[k]:.3g} rad on a path of length "
                f"{total:.3g} rad) to give increasing path parameters; remove one"
            )
        self.q_path = q_path
        self.knots = s  # (N,)
        self.length = total  # rad (joint-space chord length)
        self.spline = CubicSpline(s, q_path, bc_type="natural")
        self._d1 = self.spline.derivative(1)
        self._d2 = self.spline.derivative(2)
        self._d3 = self.spline.derivative(3)
        self.abs_max = self._exact_abs_maxima()  # (A1, A2, A3), each (n,)

    def _exact_abs_maxima(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Exact ``max_s |P'|, |P''|, |P'''|`` per joint, each shape (n,)."""
        c = self.spline.c  # (4, N-1, n): c0 h^3 + c1 h^2 + c2 h + c3
        h = np.diff(self.knots)[:, None]  # (N-1, 1)
        c0, c1, c2 = c[0], c[1], c[2]
        a3 = np.abs(6.0 * c0).max(axis=0)
        a2 = np.maximum(np.abs(2.0 * c1), np.abs(6.0 * c0 * h + 2.0 * c1)).max(axis=0)
        d1_end = 3.0 * c0 * h**2 + 2.0 * c1 * h + c2
        a1 = np.maximum(np.abs(c2), np.abs(d1_end))
        with np.errstate(divide="ignore", invalid="ignore"):
            h_star = np.where(c0 != 0.0, -c1 / (3.0 * c0), -1.0)
            inner = (h_star > 0.0) & (h_star < h)
            v_star = np.where(inner, c2 - c1**2 / (3.0 * np.where(c0 != 0, c0, 1.0)), 0.0)
        a1 = np.maximum(a1, np.abs(v_star)).max(axis=0)
        return a1, a2, a3

    def evaluate(
        self, s: np.ndarray, sd: np.ndarray, sdd: np.ndarray, sddd: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Joint trajectory from a time law by the chain rule.

        Parameters
        ----------
        s, sd, sdd, sddd : np.ndarray
            Shape ``(M,)``: path parameter (-) and its first three time
            derivatives (1/s, 1/s^2, 1/s^3).

        Returns
        -------
        q, qd, qdd, qddd : np.ndarray
            Shape ``(M, n)``: rad, rad/s, rad/s^2, rad/s^3.
        """
        s = np.clip(s, 0.0, 1.0)
        p0 = self.spline(s)
        p1 = self._d1(s)
        p2 = self._d2(s)
        p3 = self._d3(s)
        sd_ = sd[:, None]
        sdd_ = sdd[:, None]
        qd = p1 * sd_
        qdd = p2 * sd_**2 + p1 * sdd_
        qddd = p3 * sd_**3 + 3.0 * p2 * (sd_ * sdd_) + p1 * sddd[:, None]
        return p0, qd, qdd, qddd


# --------------------------------------------------------------------------- #
# Helpers
# --------------------------------------------------------------------------- #


@contextlib.contextmanager
def _quiet_toppra() -> Iterator[None]:
    """Raise the ``toppra`` logger to ERROR for the duration of the block."""
    logger = logging.getLogger("toppra")
    old = logger.level
    logger.setLevel(logging.ERROR)
    try:
        yield
    finally:
        logger.setLevel(old)


def _validate_dt(dt: float) -> float:
    try:
        value = float(dt)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"dt must be a number (s), got {dt!r}") from exc
    if not math.isfinite(value) or value <= 0.0 or value > DT_MAX_S:
        raise ValueError(f"dt must be finite, > 0 and <= {DT_MAX_S} s, got {dt!r}")
    return value


def _validate_path(q_path: Any, n: int) -> tuple[np.ndarray, int]:
    """Check ``q_path``; return it without consecutive exact duplicates.

    Returns
    -------
    q : np.ndarray
        Shape ``(N', n)``, rad, a copy with consecutive duplicates removed.
    n_input : int
        Number of waypoints given (``N``).
    """
    try:
        q = np.array(q_path, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"q_path must be a numeric (N, n) array: {exc}") from exc
    if q.ndim != 2:
        raise ValueError(f"q_path must have shape (N, n) with N >= 2, got shape {q.shape}")
    if q.shape[0] < 2:
        raise ValueError(f"q_path needs at least 2 waypoints, got {q.shape[0]}")
    if q.shape[1] != n:
        raise ValueError(
            f"q_path has {q.shape[1]} joints (shape {q.shape}) but the limits "
            f"have {n}"
        )
    bad = np.argwhere(~np.isfinite(q))
    if bad.size:
        row, col = (int(x) for x in bad[0])
        raise ValueError(
            f"q_path[{row}, {col}] (waypoint row {row}, joint {col + 1}) is "
            f"{float(q[row, col])!r}; all waypoint values must be finite"
        )
    keep = np.concatenate(([True], np.any(np.diff(q, axis=0) != 0.0, axis=1)))
    return q[keep], int(q.shape[0])


def _sample_times(duration: float, dt: float) -> np.ndarray:
    """Uniform times ``k dt`` up to the first multiple of dt >= duration."""
    k_end = max(1, int(math.ceil(duration / dt)))
    if k_end * dt < duration:
        k_end += 1
    return np.arange(k_end + 1, dtype=float) * dt


def _check_times(duration: float, dt: float, extra: np.ndarray | None = None) -> np.ndarray:
    """Times of the fine check grid strictly inside ``[0, duration)``."""
    fine = np.arange(0.0, duration, dt / VERIFY_OVERSAMPLE)
    if extra is not None:
        fine = np.concatenate((fine, extra[(extra >= 0.0) & (extra < duration)]))
    return fine


def _ratios(
    qd: np.ndarray, qdd: np.ndarray, qddd: np.ndarray, limits: JointLimits
) -> dict[str, np.ndarray]:
    """Peak ``|value| / limit`` per joint, each shape (n,)."""
    out = {}
    for key, arr in zip(_LIMIT_KEYS, (qd, qdd, qddd)):
        lim = getattr(limits, key)
        out[key] = np.abs(arr).max(axis=0) / lim if arr.shape[0] else np.zeros_like(lim)
    return out


def _max_ratios(*dicts: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    return {k: np.maximum.reduce([d[k] for d in dicts]) for k in _LIMIT_KEYS}


def _exceeds(ratio: Mapping[str, np.ndarray], keys: tuple[str, ...]) -> list[str]:
    return [k for k in keys if float(np.max(ratio[k])) > 1.0 + LIMIT_RATIO_TOL]


def _fmt_ratio(ratio: Mapping[str, np.ndarray]) -> str:
    parts = []
    for k in _LIMIT_KEYS:
        r = ratio[k]
        j = int(np.argmax(r))
        parts.append(f"{k} {float(r[j]):.4f} (joint {j + 1})")
    return "peak ratios " + ", ".join(parts)


def _nan_ratio(n: int) -> dict[str, np.ndarray]:
    return {k: np.full(n, np.nan) for k in _LIMIT_KEYS}


def _empty_trajectory(
    method: str, status: TimingStatus, reason: str, n: int, dt: float, iterations: int = 0
) -> Trajectory:
    empty = np.empty((0, n))
    return Trajectory(
        method=method,
        status=status,
        reason=reason,
        t=np.empty(0),
        q=empty,
        qd=empty.copy(),
        qdd=empty.copy(),
        qddd=empty.copy(),
        duration_s=math.nan,
        limit_ratio=_nan_ratio(n),
        dt=dt,
        iterations=iterations,
    )


def _sampled(
    path: _SplinePath,
    t: np.ndarray,
    duration: float,
    law_s: np.ndarray,
    law_sd: np.ndarray,
    law_sdd: np.ndarray,
    law_sddd: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Map a time law (values given for ``t < duration``) to joint samples.

    Samples at ``t >= duration`` hold the last waypoint at rest.
    """
    n = path.q_path.shape[1]
    m = t.shape[0]
    q = np.empty((m, n))
    qd = np.zeros((m, n))
    qdd = np.zeros((m, n))
    qddd = np.zeros((m, n))
    moving = t < duration
    k = int(np.count_nonzero(moving))
    q[:k], qd[:k], qdd[:k], qddd[:k] = path.evaluate(law_s, law_sd, law_sdd, law_sddd)
    q[k:] = path.q_path[-1]
    q[0] = path.q_path[0]
    return q, qd, qdd, qddd


# --------------------------------------------------------------------------- #
# TOPP-RA
# --------------------------------------------------------------------------- #


def _toppra_grid(knots: np.ndarray, gridpoints: int) -> np.ndarray:
    """Gridpoints in [0, 1] containing every knot, about ``gridpoints`` in all."""
    parts = []
    for k in range(knots.shape[0] - 1):
        m = max(1, int(round((knots[k + 1] - knots[k]) * (gridpoints - 1))))
        parts.append(np.linspace(knots[k], knots[k + 1], m + 1)[:-1])
    parts.append(np.array([1.0]))
    grid = np.concatenate(parts)
    grid[0] = 0.0
    return grid


def _refine_grid(
    grid: np.ndarray, tgrid: np.ndarray, t_bad: np.ndarray, lag: float
) -> np.ndarray:
    """Subdivide the grid intervals that influence the violating times.

    Parameters
    ----------
    grid : np.ndarray
        Shape ``(K,)``, gridpoints in s.
    tgrid : np.ndarray
        Shape ``(K,)``, s, time of each gridpoint in the raw TOPP-RA law.
    t_bad : np.ndarray
        Shape ``(B,)``, s, times where the check found a violation.
    lag : float
        s, the time law at ``t`` depends on the raw law on ``[t - lag, t]``.

    Returns
    -------
    np.ndarray
        Refined gridpoints: every interval overlapping ``[t - lag, t]`` for a
        violating ``t``, and one neighbour on each side, is split into
        ``TOPPRA_REFINE_FACTOR`` equal parts.
    """
    k = grid.size - 1
    lo = np.clip(np.searchsorted(tgrid, t_bad - lag, side="right") - 2, 0, k - 1)
    hi = np.clip(np.searchsorted(tgrid, t_bad, side="right"), 0, k - 1)
    marks = np.zeros(k + 1, dtype=int)
    np.add.at(marks, lo, 1)
    np.add.at(marks, hi + 1, -1)
    chosen = np.flatnonzero(np.cumsum(marks)[:k] > 0)
    frac = np.arange(1, TOPPRA_REFINE_FACTOR) / TOPPRA_REFINE_FACTOR
    extra = grid[chosen, None] + np.diff(grid)[chosen, None] * frac[None, :]
    return np.unique(np.concatenate((grid, extra.ravel())))


def _toppra_once(
    tp_path: Any, grid: np.ndarray, vlim: np.ndarray, alim: np.ndarray
) -> tuple[np.ndarray | None, str, bool]:
    """One TOPP-RA run; returns (sd at gridpoints or None, message, infeasible)."""
    constraints = [
        toppra.constraint.JointVelocityConstraint(vlim),
        toppra.constraint.JointAccelerationConstraint(
            alim, discretization_scheme=toppra.constraint.DiscretizationType.Interpolation
        ),
    ]
    try:
        with _quiet_toppra():
            inst = toppra.algorithm.TOPPRA(
                constraints, tp_path, gridpoints=grid, solver_wrapper="seidel"
            )
            _, sd, _ = inst.compute_parameterization(0.0, 0.0)
        code = inst.problem_data.return_code
    except Exception as exc:  # noqa: BLE001 - library failure becomes FAILED
        return None, f"toppra raised {type(exc).__name__}: {exc}", False
    if sd is None or code != toppra.algorithm.ParameterizationReturnCode.Ok:
        infeasible = code == toppra.algorithm.ParameterizationReturnCode.FailUncontrollable
        return None, f"toppra returned no parametrisation ({code})", infeasible
    sd = np.asarray(sd, dtype=float)
    if not np.all(np.isfinite(sd)):
        return None, "toppra returned non-finite path velocities", False
    return np.maximum(sd, 0.0), "", False


def _shrink_factor(ratio: np.ndarray, margin: float) -> np.ndarray:
    """Divisor for a limit whose measured peak ratio is ``ratio`` (> 1).

    ``ratio * (1 + m)`` with ``m = max(SHRINK_MARGIN_FLOOR, margin * (ratio -
    1))``: the extra margin is proportional to the overshoot, so a limit that
    was exceeded by a rounding-level amount is only shrunk by that amount.
    """
    return ratio * (1.0 + np.maximum(SHRINK_MARGIN_FLOOR, margin * (ratio - 1.0)))


class _ToppraLaw:
    """Scalar time law ``s(t)`` built from TOPP-RA's gridpoint velocities.

    Parameters
    ----------
    grid : np.ndarray
        Shape ``(K,)``, gridpoints in s, from 0 to 1.
    sd : np.ndarray
        Shape ``(K,)``, 1/s, path velocity at the gridpoints (``sd[0] =
        sd[-1] = 0``).
    kind : str
        ``"smoothed"``: the constant-path-acceleration law between gridpoints
        (exact meaning of TOPP-RA's solution), filtered by a causal moving
        average of width ``window`` s. It is C2, ends with zero velocity *and*
        acceleration, has jerk bounded by (acceleration jump) / window and
        stays within the range of the unfiltered velocities and accelerations
        over the window; the motion lasts ``window`` s longer.
        ``"spline"``: cubic spline through the ``(t_i, s_i)`` pairs with zero
        end velocity (toppra's ``ParametrizeSpline`` convention), which rings
        between gridpoints.
    window : float
        Moving-average width (s), > 0, used by ``"smoothed"`` only.
    """

    def __init__(self, grid: np.ndarray, sd: np.ndarray, kind: str, window: float) -> None:
        ds = np.diff(grid)
        vmean = 0.5 * (sd[1:] + sd[:-1])
        self.tgrid = np.concatenate(([0.0], np.cumsum(ds / vmean)))  # (K,) s
        t_end = float(self.tgrid[-1])
        self.kind = kind
        if kind == "spline":
            self._spline = CubicSpline(self.tgrid, grid, bc_type=((1, 0.0), (1, 0.0)))
            self.duration = t_end
            self.breaks = self.tgrid
            self.lag = 0.0
            return
        self.window = float(window)
        self.lag = self.window
        acc = (sd[1:] ** 2 - sd[:-1] ** 2) / (2.0 * ds)  # (K-1,) 1/s^2
        x = np.concatenate(([-self.window], self.tgrid, [t_end + self.window]))
        c = np.zeros((3, x.size - 1))
        c[0, 1:-1] = 0.5 * acc
        c[1, 1:-1] = sd[:-1]
        c[2, 1:-1] = grid[:-1]
        c[2, -1] = 1.0
        self._law = PPoly(c, x)  # raw law, at rest outside [0, t_end]
        self._integral = self._law.antiderivative()
        self.duration = t_end + self.window
        self.breaks = np.concatenate((self.tgrid, self.tgrid + self.window))

    def __call__(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """s, sd, sdd, sddd (-, 1/s, 1/s^2, 1/s^3) at times ``t`` in [0, duration]."""
        if self.kind == "spline":
            sp = self._spline
            return sp(t), sp(t, 1), sp(t, 2), sp(t, 3)
        w = self.window
        lo = t - w
        law = self._law
        s = (self._integral(t) - self._integral(lo)) / w
        sd = (law(t) - law(lo)) / w
        sdd = (law(t, 1) - law(lo, 1)) / w
        sddd = (law(t, 2) - law(lo, 2)) / w
        return s, sd, sdd, sddd


def _build_trajectory(
    method: str,
    path: _SplinePath,
    limits: JointLimits,
    dt: float,
    law: Any,
    duration: float,
    check_ratio: Mapping[str, np.ndarray],
    status: TimingStatus,
    reason: str,
    iterations: int,
    first: dict[str, np.ndarray],
    checked: tuple[str, ...],
) -> Trajectory:
    """Sample ``law`` at dt and assemble the :class:`Trajectory`.

    ``law(t)`` returns ``(s, sd, sdd, sddd)`` for ``t < duration``. The
    reported ratio is the maximum of ``check_ratio`` and the ratio over the
    returned samples; an ``OK`` status is downgraded to ``LIMIT_EXCEEDED`` if
    the samples exceed a ``checked`` limit (so OK can never coexist with a
    ratio above ``1 + LIMIT_RATIO_TOL``).
    """
    t = _sample_times(duration, dt)
    tm = t[t < duration]
    q, qd, qdd, qddd = _sampled(path, t, duration, *law(tm))
    ratio = _max_ratios(_ratios(qd, qdd, qddd, limits), check_ratio)
    bad = _exceeds(ratio, checked)
    if status is TimingStatus.OK and bad:
        status = TimingStatus.LIMIT_EXCEEDED
        reason = f"limit_exceeded: {' and '.join(bad)} ratio above 1 on the samples; {reason}"
    return Trajectory(
        method=method,
        status=status,
        reason=reason,
        t=t,
        q=q,
        qd=qd,
        qdd=qdd,
        qddd=qddd,
        duration_s=float(t[-1]),
        limit_ratio=ratio,
        dt=dt,
        iterations=iterations,
        first_pass_limit_ratio=first if first else dict(ratio),
    )


def _run_toppra(
    path: _SplinePath, limits: JointLimits, dt: float, opts: Mapping[str, Any]
) -> Trajectory:
    n = limits.n_joints
    n_way = path.knots.shape[0]
    gridpoints = opts.get(
        "gridpoints", max(TOPPRA_MIN_GRIDPOINTS, TOPPRA_GRIDPOINTS_PER_WAYPOINT * n_way)
    )
    max_iter = opts.get("max_iterations", TOPPRA_MAX_ITERATIONS)
    margin = opts.get("shrink_margin", TOPPRA_SHRINK_MARGIN)
    kind = opts.get("time_law", TOPPRA_TIME_LAW)
    window = opts.get("smoothing_s", TOPPRA_SMOOTHING_S)
    refinements = opts.get(
        "refinements", TOPPRA_MAX_REFINEMENTS if kind == "smoothed" else 0
    )
    checked = ("velocity", "acceleration")

    grid = _toppra_grid(path.knots, gridpoints)
    n_grid0 = grid.size
    n_refined = 0
    n_shrunk = 0
    tp_path = toppra.SplineInterpolator(path.knots, path.q_path, bc_type="natural")
    vlim = limits.velocity.astype(float).copy()
    alim = limits.acceleration.astype(float).copy()
    first: dict[str, np.ndarray] = {}
    last: tuple[Any, dict[str, np.ndarray], str, int] | None = None
    law_desc = (
        f"constant-acceleration law smoothed over {window:g} s"
        if kind == "smoothed"
        else "cubic-spline time law through the gridpoint times"
    )

    def build(
        law: Any, ratio: dict[str, np.ndarray], status: TimingStatus, reason: str, it: int
    ) -> Trajectory:
        return _build_trajectory(
            "toppra", path, limits, dt, law, law.duration, ratio, status, reason, it, first,
            checked,
        )

    for it in range(1, max_iter + 1):
        sd, msg, infeasible = _toppra_once(tp_path, grid, vlim, alim)
        if sd is None:
            reason = f"TOPP-RA run {it} on {grid.size} gridpoints failed: {msg}"
            if last is not None:  # return the previous (limit-exceeding) run
                law, ratio, prev_reason, prev_it = last
                return build(
                    law, ratio, TimingStatus.LIMIT_EXCEEDED, f"{prev_reason}; then {reason}",
                    prev_it,
                )
            status = TimingStatus.INFEASIBLE if infeasible else TimingStatus.FAILED
            return _empty_trajectory("toppra", status, reason, n, dt, it)
        vmean = 0.5 * (sd[1:] + sd[:-1])
        if np.any(vmean <= 0.0):
            i = int(np.flatnonzero(vmean <= 0.0)[0])
            return _empty_trajectory(
                "toppra",
                TimingStatus.FAILED,
                f"TOPP-RA path velocity is zero on grid interval {i} "
                f"(s in [{grid[i]:.6g}, {grid[i + 1]:.6g}]); cannot build a time law",
                n,
                dt,
                it,
            )
        law = _ToppraLaw(grid, sd, kind, window)
        duration = law.duration
        tc = _check_times(duration, dt, law.breaks)
        cs, csd, csdd, csddd = law(tc)
        _, cqd, cqdd, cqddd = path.evaluate(cs, csd, csdd, csddd)
        ratio = _ratios(cqd, cqdd, cqddd, limits)
        if not first:
            first = ratio
        summary = (
            f"TOPP-RA (seidel, {grid.size} gridpoints incl. all {n_way} waypoint "
            f"knots, {law_desc}), {it} run(s) ({n_refined} local grid "
            f"refinement(s) from {n_grid0} gridpoints, {n_shrunk} limit "
            f"shrink(s)); motion {duration:.4f} s; {_fmt_ratio(ratio)}; "
            f"first-pass ratios velocity {float(first['velocity'].max()):.4f}, "
            f"acceleration {float(first['acceleration'].max()):.4f}; jerk is not "
            "limited by TOPP-RA (its ratio is reported only; status depends on "
            "velocity and acceleration)"
        )
        backwards = float(csd.min(initial=0.0))
        if backwards < -MONOTONE_TOL * max(1.0, float(sd.max())):
            return build(
                law,
                ratio,
                TimingStatus.FAILED,
                f"failed: TOPP-RA time law moves backwards along the path (min "
                f"ds/dt = {backwards:.3g} 1/s); {summary}",
                it,
            )
        bad = _exceeds(ratio, checked)
        if not bad:
            ok_reason = f"ok: velocity and acceleration within limits; {summary}"
            return build(law, ratio, TimingStatus.OK, ok_reason, it)
        last = (
            law,
            ratio,
            f"limit_exceeded: {' and '.join(bad)} ratio above 1 after {it} run(s) "
            f"(max_iterations={max_iter}); {summary}",
            it,
        )
        excess = max(float(ratio[k].max()) for k in checked) - 1.0
        if (
            n_refined < refinements
            and excess > TOPPRA_REFINE_MIN_EXCESS
            and it + 1 < max_iter
            and grid.size < TOPPRA_MAX_GRIDPOINTS
        ):
            # Discretisation error: TOPP-RA only enforces the constraints at
            # the gridpoints. Refine the grid where the check found a
            # violation, keeping the limits.
            over = (np.abs(cqd) > limits.velocity * (1.0 + LIMIT_RATIO_TOL)).any(axis=1)
            over |= (np.abs(cqdd) > limits.acceleration * (1.0 + LIMIT_RATIO_TOL)).any(axis=1)
            grid = _refine_grid(grid, law.tgrid, tc[over], law.lag)
            n_refined += 1
            continue
        # Shrink the offending joints' limits by their measured ratio.
        n_shrunk += 1
        rv = ratio["velocity"]
        ra = ratio["acceleration"]
        over_v = rv > 1.0 + LIMIT_RATIO_TOL
        over_a = ra > 1.0 + LIMIT_RATIO_TOL
        # Only the offending joints are shrunk; the others keep their limit (no 0/0).
        vlim = vlim / np.where(over_v, _shrink_factor(np.where(over_v, rv, 2.0), margin), 1.0)
        alim = alim / np.where(over_a, _shrink_factor(np.where(over_a, ra, 2.0), margin), 1.0)
    assert last is not None
    law, ratio, reason, it = last
    return build(law, ratio, TimingStatus.LIMIT_EXCEEDED, reason, it)


# --------------------------------------------------------------------------- #
# Ruckig
# --------------------------------------------------------------------------- #


class _RuckigLaw:
    """Rest-to-rest 1-DOF Ruckig time law ``s(t)`` from 0 to 1."""

    def __init__(self) -> None:
        self._otg = ruckig.Ruckig(1)
        self._inp = ruckig.InputParameter(1)
        self._inp.current_position = [0.0]
        self._inp.current_velocity = [0.0]
        self._inp.current_acceleration = [0.0]
        self._inp.target_position = [1.0]
        self._inp.target_velocity = [0.0]
        self._inp.target_acceleration = [0.0]
        self.traj = ruckig.Trajectory(1)

    def solve(self, sd_max: float, sdd_max: float, sddd_max: float) -> float | None:
        """Plan with the given bounds; duration (s) or None on failure."""
        self._inp.max_velocity = [sd_max]
        self._inp.max_acceleration = [sdd_max]
        self._inp.max_jerk = [sddd_max]
        try:
            result = self._otg.calculate(self._inp, self.traj)
        except Exception:  # noqa: BLE001 - ruckig input errors become None
            return None
        if result not in (ruckig.Result.Working, ruckig.Result.Finished):
            return None
        return float(self.traj.duration)

    def profile_eval(self, t: np.ndarray) -> tuple[np.ndarray, ...]:
        """Evaluate s, sd, sdd, sddd at times ``t`` (s) from the jerk profile."""
        prof = self.traj.profiles[0][0]
        t0 = float(prof.brake.duration) + float(prof.accel.duration)
        if t0 > 0.0:
            raise RuntimeError("unexpected Ruckig brake/accel pre-phase on a rest start")
        durations = np.asarray(prof.t, dtype=float)
        starts = np.concatenate(([0.0], np.cumsum(durations)))[:-1]
        jerk = np.asarray(prof.j, dtype=float)
        a0 = np.asarray(prof.a, dtype=float)[:-1]
        v0 = np.asarray(prof.v, dtype=float)[:-1]
        p0 = np.asarray(prof.p, dtype=float)[:-1]
        idx = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, durations.size - 1)
        tau = t - starts[idx]
        j = jerk[idx]
        a = a0[idx] + j * tau
        v = v0[idx] + a0[idx] * tau + 0.5 * j * tau**2
        p = p0[idx] + v0[idx] * tau + 0.5 * a0[idx] * tau**2 + j * tau**3 / 6.0
        return p, v, a, j


def _ruckig_bound_set(
    path: _SplinePath, limits: JointLimits, law: _RuckigLaw
) -> tuple[tuple[float, float, float] | None, str]:
    """Admissible global (sd_max, sdd_max, sddd_max) with the shortest duration."""
    a1, a2, a3 = path.abs_max
    v, a, jk = limits.velocity, limits.acceleration, limits.jerk

    def min_ratio(num: np.ndarray, den: np.ndarray) -> float:
        mask = den > 0.0
        return float(np.min(num[mask] / den[mask])) if np.any(mask) else math.inf

    sd_cap = min(
        min_ratio(v, a1),
        min_ratio(np.sqrt(a), np.sqrt(a2)),
        min_ratio(np.cbrt(jk), np.cbrt(a3)),
    )
    if not math.isfinite(sd_cap) or sd_cap <= 0.0:
        return None, f"no admissible path-velocity bound (sd cap {sd_cap!r})"
    best: tuple[float, tuple[float, float, float]] | None = None
    for f1 in RUCKIG_BUDGET_FRACTIONS:
        sd = float(f1) * sd_cap
        sdd_cap = min(min_ratio(a - a2 * sd**2, a1), min_ratio(jk - a3 * sd**3, 3.0 * a2 * sd))
        if not sdd_cap > 0.0:
            continue
        for f2 in RUCKIG_BUDGET_FRACTIONS:
            sdd = float(f2) * sdd_cap
            sddd = min_ratio(jk - a3 * sd**3 - 3.0 * a2 * sd * sdd, a1)
            if not (sddd > 0.0 and math.isfinite(sddd) and math.isfinite(sdd)):
                continue
            dur = law.solve(sd, sdd, sddd)
            if dur is not None and (best is None or dur < best[0]):
                best = (dur, (sd, sdd, sddd))
    if best is None:
        return None, "no admissible global bound set for the path parameter"
    return best[1], ""


def _run_ruckig(
    path: _SplinePath, limits: JointLimits, dt: float, opts: Mapping[str, Any]
) -> Trajectory:
    n = limits.n_joints
    max_iter = opts.get("max_iterations", RUCKIG_MAX_ITERATIONS)
    margin = opts.get("shrink_margin", RUCKIG_SHRINK_MARGIN)
    checked = _LIMIT_KEYS
    law = _RuckigLaw()
    bounds, msg = _ruckig_bound_set(path, limits, law)
    if bounds is None:
        return _empty_trajectory("ruckig", TimingStatus.FAILED, f"Ruckig: {msg}", n, dt)
    sd_max, sdd_max, sddd_max = bounds
    first: dict[str, np.ndarray] = {}
    reason = ""
    ratio: dict[str, np.ndarray] = {}
    duration = math.nan

    def sampled_law(tm: np.ndarray) -> tuple[np.ndarray, ...]:
        """s, sd, sdd from ``at_time``; sddd from the jerk profile."""
        states = np.array([law.traj.at_time(float(x))[:3] for x in tm], dtype=float)
        states = states.reshape(tm.size, 3)
        ps, vs, accs, js = law.profile_eval(tm)
        scale = np.array([1.0, sd_max, sdd_max])
        gap = np.abs(states - np.column_stack((ps, vs, accs))) / scale
        if gap.size and float(gap.max()) > RUCKIG_CONSISTENCY_TOL:
            raise RuntimeError(
                f"Ruckig profile evaluation differs from at_time by {float(gap.max()):.3g}"
            )
        return states[:, 0], states[:, 1], states[:, 2], js

    for it in range(1, max_iter + 1):
        solved = law.solve(sd_max, sdd_max, sddd_max)
        if solved is None:
            return _empty_trajectory(
                "ruckig",
                TimingStatus.FAILED,
                f"Ruckig run {it} failed for bounds sd<={sd_max:.6g}, "
                f"sdd<={sdd_max:.6g}, sddd<={sddd_max:.6g}",
                n,
                dt,
                it,
            )
        duration = solved
        try:
            tc = _check_times(duration, dt)
            cs, csd, csdd, csddd = law.profile_eval(tc)
        except RuntimeError as exc:
            return _empty_trajectory(
                "ruckig", TimingStatus.FAILED, f"Ruckig sampling failed: {exc}", n, dt, it
            )
        _, cqd, cqdd, cqddd = path.evaluate(cs, csd, csdd, csddd)
        ratio = _ratios(cqd, cqdd, cqddd, limits)
        if not first:
            first = ratio
        summary = (
            f"Ruckig on the path parameter with global bounds sd<={sd_max:.6g} 1/s, "
            f"|sdd|<={sdd_max:.6g} 1/s^2, |sddd|<={sddd_max:.6g} 1/s^3, {it} run(s); "
            f"motion {duration:.4f} s; {_fmt_ratio(ratio)}"
        )
        backwards = float(csd.min(initial=0.0))
        if backwards < -MONOTONE_TOL * max(1.0, sd_max):
            status = TimingStatus.FAILED
            reason = (
                f"failed: Ruckig time law moves backwards (min ds/dt {backwards:.3g}); "
                f"{summary}"
            )
            break
        bad = _exceeds(ratio, checked)
        if not bad:
            status = TimingStatus.OK
            reason = f"ok: velocity, acceleration and jerk within limits; {summary}"
            break
        status = TimingStatus.LIMIT_EXCEEDED
        reason = (
            f"limit_exceeded: {' and '.join(bad)} ratio above 1 after {it} run(s) "
            f"(max_iterations={max_iter}); {summary}"
        )
        if it == max_iter:
            break
        # Uniform time scaling of the bound set by the measured ratios.
        k = max(
            float(ratio["velocity"].max()),
            math.sqrt(float(ratio["acceleration"].max())),
            math.cbrt(float(ratio["jerk"].max())),
        ) * (1.0 + margin)
        sd_max, sdd_max, sddd_max = sd_max / k, sdd_max / k**2, sddd_max / k**3
    try:
        return _build_trajectory(
            "ruckig", path, limits, dt, sampled_law, duration, ratio, status, reason, it,
            first, checked,
        )
    except RuntimeError as exc:
        return _empty_trajectory(
            "ruckig", TimingStatus.FAILED, f"Ruckig sampling failed: {exc}", n, dt, it
        )


# --------------------------------------------------------------------------- #
# Entry point
# --------------------------------------------------------------------------- #

_OPTIONS: dict[str, tuple[str, ...]] = {
    "toppra": (
        "gridpoints",
        "max_iterations",
        "shrink_margin",
        "time_law",
        "smoothing_s",
        "refinements",
    ),
    "ruckig": ("max_iterations", "shrink_margin"),
}


def _validate_options(method: str, options: Mapping[str, Any]) -> dict[str, Any]:
    allowed = _OPTIONS[method]
    unknown = sorted(set(options) - set(allowed))
    if unknown:
        raise TypeError(
            f"unknown option(s) {unknown} for method {method!r}; valid options: "
            f"{list(allowed)}"
        )
    out = dict(options)
    for key, lo in (("gridpoints", 2), ("max_iterations", 1), ("refinements", 0)):
        if key in out:
            val = out[key]
            if isinstance(val, bool) or not isinstance(val, (int, np.integer)) or val < lo:
                raise ValueError(f"option {key} must be an integer >= {lo}, got {val!r}")
            out[key] = int(val)
    if "shrink_margin" in out:
        val = out["shrink_margin"]
        try:
            fval = float(val)
        except (TypeError, ValueError):
            fval = math.nan
        if not (0.0 <= fval <= SHRINK_MARGIN_MAX):
            raise ValueError(
                f"option shrink_margin must be in [0, {SHRINK_MARGIN_MAX}], got {val!r}"
            )
        out["shrink_margin"] = fval
    if "time_law" in out and out["time_law"] not in TOPPRA_TIME_LAWS:
        raise ValueError(
            f"option time_law must be one of {list(TOPPRA_TIME_LAWS)}, got {out['time_law']!r}"
        )
    if "smoothing_s" in out:
        val = out["smoothing_s"]
        try:
            fval = float(val)
        except (TypeError, ValueError):
            fval = math.nan
        if not (0.0 < fval <= 1.0):
            raise ValueError(f"option smoothing_s must be in (0, 1] s, got {val!r}")
        out["smoothing_s"] = fval
    return out


def time_parametrize(
    q_path: np.ndarray,
    limits: JointLimits,
    method: str = "toppra",
    dt: float = 0.008,
    **options: Any,
) -> Trajectory:
    """Time-parametrise a joint-space path, rest to rest.

    Parameters
    ----------
    q_path : np.ndarray
        Shape ``(N, n)``, rad. Waypoints of the geometric path, ``N >= 2``,
        ``n`` equal to ``limits.n_joints``. Consecutive exact duplicates are
        dropped. The trajectory follows the natural cubic chord-length spline
        through the waypoints (see module docstring).
    limits : JointLimits
        Per-joint velocity (rad/s), acceleration (rad/s^2), jerk (rad/s^3).
    method : str
        ``"toppra"`` (time-optimal, velocity and acceleration limits) or
        ``"ruckig"`` (jerk-limited).
    dt : float
        Controller period (s), ``0 < dt <= DT_MAX_S``.
    **options
        ``toppra``: ``gridpoints`` (int >= 2, default
        ``max(TOPPRA_MIN_GRIDPOINTS, TOPPRA_GRIDPOINTS_PER_WAYPOINT * N)``;
        the waypoint knots are always added), ``max_iterations`` (int >= 1,
        total TOPP-RA runs, default ``TOPPRA_MAX_ITERATIONS``),
        ``shrink_margin`` (float, default ``TOPPRA_SHRINK_MARGIN``),
        ``time_law`` (``"smoothed"`` or ``"spline"``, default
        ``TOPPRA_TIME_LAW``), ``smoothing_s`` (float in (0, 1] s, default
        ``TOPPRA_SMOOTHING_S``), ``refinements`` (int >= 0, local grid
        refinement rounds, default ``TOPPRA_MAX_REFINEMENTS`` for the smoothed
        law and 0 for the spline law). ``ruckig``: ``max_iterations`` (int >= 1,
        default ``RUCKIG_MAX_ITERATIONS``), ``shrink_margin`` (float, the
        bound set is time-scaled by ``k (1 + shrink_margin)``, default
        ``RUCKIG_SHRINK_MARGIN``). See the module docstring for the methods.

    Returns
    -------
    Trajectory
        Always returned for expected outcomes: ``OK``; ``LIMIT_EXCEEDED``
        (samples present, limits not met after the allowed iterations);
        ``INFEASIBLE`` (zero-length path: one sample at the start at rest,
        ``duration_s = 0``; or TOPP-RA reports the instance uncontrollable);
        ``FAILED`` (the library failed; empty samples, NaN duration).

    Raises
    ------
    ValueError
        Unknown ``method`` (the message lists the valid names), malformed
        ``q_path`` (shape, joint count, non-finite value: the message names
        the waypoint row and joint), bad ``dt``, or bad option values.
    TypeError
        ``limits`` is not a :class:`JointLimits`, or an unknown option name.
    """
    if method not in VALID_METHODS:
        raise ValueError(f"unknown method {method!r}; valid methods: {list(VALID_METHODS)}")
    if not isinstance(limits, JointLimits):
        raise TypeError(f"limits must be a JointLimits, got {type(limits).__name__}")
    opts = _validate_options(method, options)
    dt = _validate_dt(dt)
    n = limits.n_joints
    q, n_input = _validate_path(q_path, n)

    if q.shape[0] < 2:
        zeros = np.zeros((1, n))
        return Trajectory(
            method=method,
            status=TimingStatus.INFEASIBLE,
            reason=(
                f"infeasible: path has zero length (all {n_input} waypoints are "
                "identical); nothing to time-parametrise, the single sample holds "
                "the start configuration at rest"
            ),
            t=np.zeros(1),
            q=q[:1].copy(),
            qd=zeros,
            qdd=zeros.copy(),
            qddd=zeros.copy(),
            duration_s=0.0,
            limit_ratio={k: np.zeros(n) for k in _LIMIT_KEYS},
            dt=dt,
        )
    path = _SplinePath(q)
    if method == "toppra":
        return _run_toppra(path, limits, dt, opts)
    return _run_ruckig(path, limits, dt, opts)
