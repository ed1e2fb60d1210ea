"""``method="toppra"``: time-optimal under joint velocity and acceleration limits.

TOPP-RA (``toppra.algorithm.TOPPRA`` with ``JointVelocityConstraint`` and
``JointAccelerationConstraint``, interpolation discretisation, ``seidel``
solver) times the geometric path of :mod:`problems.timing.path` on a grid in
``s`` that always contains the waypoint knots. TOPP-RA returns ``sd`` (1/s)
at the gridpoints, i.e. a law with constant path acceleration between
gridpoints (piecewise-quadratic ``s(t)``, acceleration jumps). Two ways to
turn that into a C2 time law are offered (option ``time_law``):

* ``"smoothed"`` (default): the constant-acceleration law filtered by a
  causal moving average of width ``smoothing_s`` (default
  ``TOPPRA_SMOOTHING_S``), evaluated exactly from the piecewise polynomial
  and its antiderivative. It stays within the range of the unfiltered path
  velocity/acceleration over the window, is monotone, ends with zero velocity
  *and* acceleration, has finite jerk (about the acceleration jump divided by
  the window) and lasts ``smoothing_s`` longer than the raw law.
* ``"spline"``: cubic spline through the ``(t_i, s_i)`` pairs with zero end
  velocity (the scalar analogue of toppra's own ``ParametrizeSpline``
  output). It rings between gridpoints: about 10-15 % acceleration
  overshoot, whatever the grid density, and large jerk.

Either way, TOPP-RA only enforces the constraints at the gridpoints, so the
result is checked on a fine time grid (:mod:`problems.timing.verification`).
While a velocity or acceleration ratio exceeds 1 (+ ``LIMIT_RATIO_TOL``),
TOPP-RA is re-run, at most ``max_iterations`` runs in all:

1. first (smoothed law only, at most ``refinements`` times, while the
   overshoot exceeds ``TOPPRA_REFINE_MIN_EXCESS``) with the grid intervals
   that produced the violation split in ``TOPPRA_REFINE_FACTOR``
   (discretisation error shrinks with the grid);
2. then with each offending joint's limit divided by
   ``r (1 + max(SHRINK_MARGIN_FLOOR, shrink_margin (r - 1)))`` (``r`` its
   measured peak ratio).

If the last run still exceeds, the status is ``LIMIT_EXCEEDED``. The
correction costs a little optimality: in a randomised sweep (6 joints, 5-80
waypoints, straight, smooth and random-walk paths) the durations were a
median 0.6 % and at most 2 % above a 5000-gridpoint reference. TOPP-RA does
not limit jerk: the jerk ratio is reported but the status depends only on
velocity and acceleration.

Options: ``gridpoints`` (int >= 2, default ``max(TOPPRA_MIN_GRIDPOINTS,
TOPPRA_GRIDPOINTS_PER_WAYPOINT * N)``; the waypoint knots are always added),
``max_iterations`` (int >= 1, total TOPP-RA runs, default
``TOPPRA_MAX_ITERATIONS``), ``shrink_margin`` (float in ``[0,
SHRINK_MARGIN_MAX]``, default ``TOPPRA_SHRINK_MARGIN``), ``time_law``
(``"smoothed"`` or ``"spline"``, default ``TOPPRA_TIME_LAW``),
``smoothing_s`` (float in (0, 1] s, default ``TOPPRA_SMOOTHING_S``),
``refinements`` (int >= 0, local grid refinement rounds, default
``TOPPRA_MAX_REFINEMENTS`` for the smoothed law and 0 for the spline law).

toppra's logger is raised to ``ERROR`` for the duration of each run (not
thread-safe with respect to other code changing that logger's level
concurrently). Importing this module registers the method.
"""

from __future__ import annotations

import contextlib
import logging
import math
from dataclasses import dataclass, replace
from typing import Any
from collections.abc import Iterator, Mapping

import numpy as np

from models.errors import InputError
from problems.timing.path import SplinePath
from problems.timing.registry import (
    LIMIT_RATIO_TOL,
    TimingMethod,
    check_integer_options,
    check_shrink_margin,
    register_method,
)
from problems.timing.toppra_import import import_toppra
from problems.timing.toppra_law import ToppraLaw
from problems.timing.trajectory import JointLimits, TimingStatus, Trajectory, empty_trajectory
from problems.timing.verification import (
    check_times,
    exceeded_limits,
    finish_trajectory,
    format_ratios,
    limit_ratios,
    moves_backwards,
)

__all__ = [
    "quiet_toppra",
]

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

#: Option names accepted by ``method="toppra"``.
TOPPRA_OPTIONS: tuple[str, ...] = (
    "gridpoints",
    "max_iterations",
    "shrink_margin",
    "time_law",
    "smoothing_s",
    "refinements",
)

#: Limits that decide the status (jerk is reported only).
_CHECKED: tuple[str, ...] = ("velocity", "acceleration")


# --------------------------------------------------------------------------- #
# Building blocks
# --------------------------------------------------------------------------- #


@contextlib.contextmanager
def quiet_toppra() -> Iterator[None]:
    """Raise the ``toppra`` logger to ERROR for the duration of the block."""
    logger = logging.getLogger("toppra")
    old = logger.level
    logger.setLevel(logging.ERROR)
    try:
        yield
    finally:
        logger.setLevel(old)


def toppra_grid(knots: np.ndarray, gridpoints: int) -> np.ndarray:
    """Gridpoints in [0, 1] containing every knot, about ``gridpoints`` in all.

    Parameters
    ----------
    knots : np.ndarray
        Shape ``(N,)``, path parameter of the waypoints, from 0 to 1.
    gridpoints : int
        Target number of gridpoints.

    Returns
    -------
    np.ndarray
        Shape ``(K,)``, increasing, ``grid[0] = 0`` and ``grid[-1] = 1``.
    """
    parts = []
    for k in range(knots.shape[0] - 1):
        m = max(1, int(round((knots[k + 1] - knots[k]) * (gridpoints - 1))))
        parts.append(np.linspace(knots[k], knots[k + 1], m + 1)[:-1])
    parts.append(np.array([1.0]))
    grid = np.concatenate(parts)
    grid[0] = 0.0
    return grid


def refine_grid(grid: np.ndarray, tgrid: np.ndarray, t_bad: np.ndarray, lag: float) -> np.ndarray:
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


def toppra_once(
    tp_path: Any, grid: np.ndarray, vlim: np.ndarray, alim: np.ndarray
) -> tuple[np.ndarray | None, str, bool]:
    """One TOPP-RA run.

    Parameters
    ----------
    tp_path : toppra.SplineInterpolator
        The geometric path in toppra's form.
    grid : np.ndarray
        Shape ``(K,)``, gridpoints in s.
    vlim, alim : np.ndarray
        Shape ``(n,)``: velocity (rad/s) and acceleration (rad/s^2) limits.

    Returns
    -------
    sd : np.ndarray or None
        Shape ``(K,)``, 1/s, path velocity at the gridpoints (``>= 0``), or
        None if the run failed.
    message : str
        Why it failed (empty on success), quoting toppra's return code.
    infeasible : bool
        True if toppra reported the instance uncontrollable.
    """
    toppra = import_toppra()  # on demand (with toppra.algorithm and toppra.constraint)

    constraints = [
        toppra.constraint.JointVelocityConstraint(vlim),
        toppra.constraint.JointAccelerationConstraint(
            alim, discretization_scheme=toppra.constraint.DiscretizationType.Interpolation
        ),
    ]
    try:
        with quiet_toppra():
            inst = toppra.algorithm.TOPPRA(constraints, tp_path, gridpoints=grid, solver_wrapper="seidel")
            _, sd, _ = inst.compute_parameterization(0.0, 0.0)
        code = inst.problem_data.return_code
    except Exception as exc:
        return None, f"toppra raised {type(exc).__name__}: {exc}", False
    if sd is None or code != toppra.algorithm.ParameterizationReturnCode.Ok:
        infeasible = code == toppra.algorithm.ParameterizationReturnCode.FailUncontrollable
        return None, f"toppra returned no parametrisation ({code})", infeasible
    sd = np.asarray(sd, dtype=float)
    if not np.all(np.isfinite(sd)):
        return None, "toppra returned non-finite path velocities", False
    return np.maximum(sd, 0.0), "", False


def shrink_factor(ratio: np.ndarray, margin: float) -> np.ndarray:
    """Divisor for a limit whose measured peak ratio is ``ratio`` (> 1).

    ``ratio * (1 + m)`` with ``m = max(SHRINK_MARGIN_FLOOR, margin * (ratio -
    1))``: the extra margin is proportional to the overshoot, so a limit that
    was exceeded by a rounding-level amount is only shrunk by that amount.
    Shapes as ``ratio`` (``(n,)``), dimensionless.
    """
    return ratio * (1.0 + np.maximum(SHRINK_MARGIN_FLOOR, margin * (ratio - 1.0)))


# --------------------------------------------------------------------------- #
# Options
# --------------------------------------------------------------------------- #


def _validate_toppra_options(out: dict[str, Any]) -> dict[str, Any]:
    """Check the values of the TOPP-RA options (see module docstring)."""
    check_integer_options(out, (("gridpoints", 2), ("max_iterations", 1), ("refinements", 0)))
    check_shrink_margin(out)
    if "time_law" in out and out["time_law"] not in TOPPRA_TIME_LAWS:
        raise InputError(f"option time_law must be one of {list(TOPPRA_TIME_LAWS)}, got {out['time_law']!r}")
    if "smoothing_s" in out:
        val = out["smoothing_s"]
        try:
            fval = float(val)
        except (TypeError, ValueError):
            fval = math.nan
        if not (0.0 < fval <= 1.0):
            raise InputError(f"option smoothing_s must be in (0, 1] s, got {val!r}")
        out["smoothing_s"] = fval
    return out


@dataclass(frozen=True)
class ToppraSettings:
    """Validated TOPP-RA options with their defaults filled in.

    Attributes
    ----------
    gridpoints : int
        Target grid size (the knots are added).
    max_iterations : int
        Total number of TOPP-RA runs allowed.
    shrink_margin : float
        Extra limit-shrinking margin per unit of overshoot (-).
    time_law : str
        ``"smoothed"`` or ``"spline"``.
    smoothing_s : float
        Moving-average width (s) of the smoothed law.
    refinements : int
        Local grid refinement rounds allowed.
    """

    gridpoints: int
    max_iterations: int
    shrink_margin: float
    time_law: str
    smoothing_s: float
    refinements: int

    @classmethod
    def from_options(cls, opts: Mapping[str, Any], n_waypoints: int) -> ToppraSettings:
        """Fill the defaults for a path of ``n_waypoints`` waypoints."""
        kind = opts.get("time_law", TOPPRA_TIME_LAW)
        return cls(
            gridpoints=opts.get(
                "gridpoints",
                max(TOPPRA_MIN_GRIDPOINTS, TOPPRA_GRIDPOINTS_PER_WAYPOINT * n_waypoints),
            ),
            max_iterations=opts.get("max_iterations", TOPPRA_MAX_ITERATIONS),
            shrink_margin=opts.get("shrink_margin", TOPPRA_SHRINK_MARGIN),
            time_law=kind,
            smoothing_s=opts.get("smoothing_s", TOPPRA_SMOOTHING_S),
            refinements=opts.get("refinements", TOPPRA_MAX_REFINEMENTS if kind == "smoothed" else 0),
        )

    def law_description(self) -> str:
        """How the time law is built, for the reason text."""
        if self.time_law == "smoothed":
            return f"constant-acceleration law smoothed over {self.smoothing_s:g} s"
        return "cubic-spline time law through the gridpoint times"


# --------------------------------------------------------------------------- #
# The verification loop
# --------------------------------------------------------------------------- #


@dataclass
class _Checked:
    """One TOPP-RA run sampled on the check grid.

    ``tc`` shape ``(C,)`` s; ``csd`` shape ``(C,)`` 1/s; ``cqd``, ``cqdd``
    shape ``(C, n)`` rad/s, rad/s^2; ``ratio`` values shape ``(n,)``.
    """

    law: ToppraLaw
    tc: np.ndarray
    csd: np.ndarray
    cqd: np.ndarray
    cqdd: np.ndarray
    ratio: dict[str, np.ndarray]


class _ToppraLoop:
    """TOPP-RA runs with grid refinement and limit shrinking until the check passes."""

    def __init__(self, path: SplinePath, limits: JointLimits, dt: float, cfg: ToppraSettings) -> None:
        toppra = import_toppra()  # on demand

        self.path, self.limits, self.dt, self.cfg = path, limits, dt, cfg
        self.n_way = path.knots.shape[0]
        self.grid = toppra_grid(path.knots, cfg.gridpoints)
        self.n_grid0 = self.grid.size
        self.n_refined = 0
        self.n_shrunk = 0
        self.tp_path = toppra.SplineInterpolator(path.knots, path.q_path, bc_type="natural")
        self.vlim = limits.velocity.astype(float).copy()
        self.alim = limits.acceleration.astype(float).copy()
        self.first: dict[str, np.ndarray] = {}
        #: (checked run, its summary, peak sd, iteration) of the last limit-exceeding run.
        self.last: tuple[_Checked, str, float, int] | None = None

    def run(self) -> Trajectory:
        """Iterate until a run passes the check or the runs are used up."""
        for it in range(1, self.cfg.max_iterations + 1):
            done = self._iteration(it)
            if done is not None:
                return done
        raise AssertionError("the last TOPP-RA run always returns")  # pragma: no cover

    def _finish(self, chk: _Checked, summary: str, sd_max: float, it: int) -> Trajectory:
        """The trajectory of run ``it`` (status and reason by :func:`finish_trajectory`)."""
        return finish_trajectory(
            "toppra",
            self.path,
            self.limits,
            self.dt,
            chk.law,
            chk.law.duration,
            chk.ratio,
            summary,
            check_sd=chk.csd,
            sd_scale=sd_max,
            iterations=it,
            first=self.first,
            runs=f" after {it} run(s) (max_iterations={self.cfg.max_iterations})",
        )

    def _solver_failed(self, it: int, msg: str, infeasible: bool) -> Trajectory:
        """Result when run ``it`` gave no parametrisation."""
        reason = f"TOPP-RA run {it} on {self.grid.size} gridpoints failed: {msg}"
        if self.last is not None:  # return the previous (limit-exceeding) run
            tr = self._finish(*self.last)
            return replace(tr, reason=f"{tr.reason}; then {reason}")
        status = TimingStatus.INFEASIBLE if infeasible else TimingStatus.FAILED
        return empty_trajectory("toppra", status, reason, self.limits.n_joints, self.dt, it)

    def _check(self, sd: np.ndarray) -> _Checked:
        """Build the time law from ``sd`` (shape ``(K,)``, 1/s) and check it."""
        law = ToppraLaw(self.grid, sd, self.cfg.time_law, self.cfg.smoothing_s)
        tc = check_times(law.duration, self.dt, law.breaks)
        cs, csd, csdd, csddd = law(tc)
        _, cqd, cqdd, cqddd = self.path.evaluate(cs, csd, csdd, csddd)
        ratio = limit_ratios(cqd, cqdd, cqddd, self.limits)
        return _Checked(law, tc, csd, cqd, cqdd, ratio)

    def _summary(self, it: int, duration: float, ratio: dict[str, np.ndarray]) -> str:
        first = self.first
        return (
            f"TOPP-RA (seidel, {self.grid.size} gridpoints incl. all {self.n_way} waypoint "
            f"knots, {self.cfg.law_description()}), {it} run(s) ({self.n_refined} local grid "
            f"refinement(s) from {self.n_grid0} gridpoints, {self.n_shrunk} limit "
            f"shrink(s)); motion {duration:.4f} s; {format_ratios(ratio)}; "
            f"first-pass ratios velocity {float(first['velocity'].max()):.4f}, "
            f"acceleration {float(first['acceleration'].max()):.4f}; jerk is not "
            "limited by TOPP-RA (its ratio is reported only; status depends on "
            "velocity and acceleration)"
        )

    def _iteration(self, it: int) -> Trajectory | None:
        """Run ``it``; a final result, or None after adapting grid or limits."""
        sd, msg, infeasible = toppra_once(self.tp_path, self.grid, self.vlim, self.alim)
        if sd is None:
            return self._solver_failed(it, msg, infeasible)
        vmean = 0.5 * (sd[1:] + sd[:-1])
        if np.any(vmean <= 0.0):
            i = int(np.flatnonzero(vmean <= 0.0)[0])
            return empty_trajectory(
                "toppra",
                TimingStatus.FAILED,
                f"TOPP-RA path velocity is zero on grid interval {i} "
                f"(s in [{self.grid[i]:.6g}, {self.grid[i + 1]:.6g}]); cannot build a time law",
                self.limits.n_joints,
                self.dt,
                it,
            )
        chk = self._check(sd)
        if not self.first:
            self.first = chk.ratio
        summary = self._summary(it, chk.law.duration, chk.ratio)
        sd_max = float(sd.max())
        if (
            it == self.cfg.max_iterations
            or not exceeded_limits(chk.ratio, _CHECKED)
            or moves_backwards(chk.csd, sd_max) is not None
        ):
            return self._finish(chk, summary, sd_max, it)
        self.last = (chk, summary, sd_max, it)
        self._adapt(it, chk)
        return None

    def _adapt(self, it: int, chk: _Checked) -> None:
        """Refine the grid where the check failed, else shrink the offending limits."""
        ratio = chk.ratio
        excess = max(float(ratio[k].max()) for k in _CHECKED) - 1.0
        if (
            self.n_refined < self.cfg.refinements
            and excess > TOPPRA_REFINE_MIN_EXCESS
            and it + 1 < self.cfg.max_iterations
            and self.grid.size < TOPPRA_MAX_GRIDPOINTS
        ):
            # Discretisation error: TOPP-RA only enforces the constraints at
            # the gridpoints. Refine the grid where the check found a
            # violation, keeping the limits.
            lim = self.limits
            over = (np.abs(chk.cqd) > lim.velocity * (1.0 + LIMIT_RATIO_TOL)).any(axis=1)
            over |= (np.abs(chk.cqdd) > lim.acceleration * (1.0 + LIMIT_RATIO_TOL)).any(axis=1)
            self.grid = refine_grid(self.grid, chk.law.tgrid, chk.tc[over], chk.law.lag)
            self.n_refined += 1
            return
        # Shrink the offending joints' limits by their measured ratio; the
        # others keep their limit (no 0/0).
        self.n_shrunk += 1
        margin = self.cfg.shrink_margin
        rv = ratio["velocity"]
        ra = ratio["acceleration"]
        over_v = rv > 1.0 + LIMIT_RATIO_TOL
        over_a = ra > 1.0 + LIMIT_RATIO_TOL
        self.vlim = self.vlim / np.where(over_v, shrink_factor(np.where(over_v, rv, 2.0), margin), 1.0)
        self.alim = self.alim / np.where(over_a, shrink_factor(np.where(over_a, ra, 2.0), margin), 1.0)


def run_toppra(path: SplinePath, limits: JointLimits, dt: float, opts: Mapping[str, Any]) -> Trajectory:
    """Time ``path`` with TOPP-RA (the registered runner of ``"toppra"``).

    Parameters
    ----------
    path : SplinePath
        The geometric path (rad, joint space).
    limits : JointLimits
        Velocity (rad/s) and acceleration (rad/s^2) are enforced; jerk is
        reported only.
    dt : float
        Controller period (s).
    opts : Mapping
        Validated options (see module docstring).

    Returns
    -------
    Trajectory
        ``method = "toppra"``; never raises for solver failures.
    """
    cfg = ToppraSettings.from_options(opts, path.knots.shape[0])
    return _ToppraLoop(path, limits, dt, cfg).run()


#: The registry record of ``method="toppra"``.
TOPPRA_METHOD: TimingMethod = register_method(
    TimingMethod(
        name="toppra",
        run=run_toppra,
        options=TOPPRA_OPTIONS,
        validate_options=_validate_toppra_options,
        checked_limits=_CHECKED,
        description="time-optimal under joint velocity and acceleration limits (TOPP-RA)",
        display_name="TOPP-RA",
        controller_rank=30,
        default=True,
        duration_note="TOPP-RA, time-optimal, jerk not limited",
        time_optimal_reference=True,
    )
)
