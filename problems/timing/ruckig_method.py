"""``method="ruckig"``: jerk-limited timing of the geometric path.

Ruckig (community version) has no intermediate waypoints, so Ruckig plans
the 1-DOF path parameter ``s`` (of :mod:`problems.timing.path`) rest-to-rest
from 0 to 1 under global bounds ``sd <= sd_max``, ``|sdd| <= sdd_max``,
``|sddd| <= sddd_max`` (1/s, 1/s^2, 1/s^3). With ``A1, A2, A3`` the *exact*
maxima over ``s`` of ``|P'|, |P''|, |P'''|`` per joint (computed from the
spline coefficients: ``P'''`` is piecewise constant, ``P''`` piecewise
linear, ``P'`` piecewise quadratic), the triangle inequality on the chain
rule gives sufficient conditions, per joint ``j``::

    A1_j sd_max                                          <= v_j
    A2_j sd_max^2 + A1_j sdd_max                         <= a_j
    A3_j sd_max^3 + 3 A2_j sd_max sdd_max + A1_j sddd_max <= jerk_j

A small search over how the acceleration and jerk budgets are split between
the terms picks the admissible bound set with the shortest Ruckig duration.
The sampled trajectory is then verified (:mod:`problems.timing.verification`);
if a ratio still exceeds 1 (numerical edge cases only) the bounds are
time-scaled by the measured ratio and Ruckig is re-run (bounded iterations).
This global scheme is conservative on strongly curved paths (the slowest part
of the path sets the pace everywhere); a segment-wise scheme is not
implemented. Status ``OK`` requires all three ratios to be within tolerance.

Ruckig's ``at_time`` gives position, velocity and acceleration of ``s``; the
jerk of ``s`` and the fine check grid are evaluated from Ruckig's jerk profile
(``Trajectory.profiles``), which is cross-checked against ``at_time`` on
every sample.

When a Ruckig calculation fails, its own code is kept: ``solver_code`` of the
returned :class:`~problems.timing.trajectory.Trajectory` holds
``"ruckig.Result.<name>"`` (or ``"ruckig.RuckigError"`` when the binding
raised instead of returning a code) and the reason quotes it.

Options: ``max_iterations`` (int >= 1, default ``RUCKIG_MAX_ITERATIONS``),
``shrink_margin`` (float in ``[0, SHRINK_MARGIN_MAX]``, the bound set is
time-scaled by ``k (1 + shrink_margin)``, default ``RUCKIG_SHRINK_MARGIN``).
Importing this module registers the method.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any
from collections.abc import Mapping

import numpy as np
import ruckig

from problems.timing.path import SplinePath
from problems.timing.registry import (
    TimingMethod,
    check_integer_options,
    check_shrink_margin,
    register_method,
)
from problems.timing.trajectory import LIMIT_KEYS, JointLimits, TimingStatus, Trajectory, empty_trajectory
from problems.timing.verification import (
    check_times,
    exceeded_limits,
    finish_trajectory,
    format_ratios,
    limit_ratios,
    moves_backwards,
    time_scale_factor,
)

__all__ = [
    "RuckigLaw",
    "ruckig_bound_set",
]

#: Ruckig verification loop: total number of Ruckig runs and extra margin.
RUCKIG_MAX_ITERATIONS: int = 4
RUCKIG_SHRINK_MARGIN: float = 1e-3

#: Fractions scanned when splitting the acceleration/jerk budgets between the
#: terms of the chain rule (Ruckig global bound set).
RUCKIG_BUDGET_FRACTIONS: np.ndarray = np.linspace(0.05, 1.0, 20)

#: Agreement required between Ruckig ``at_time`` and the profile evaluation
#: used for jerk and for the fine check grid (absolute, in units of s, s/t...,
#: relative to the respective bound).
RUCKIG_CONSISTENCY_TOL: float = 1e-7

#: Option names accepted by ``method="ruckig"``.
RUCKIG_OPTIONS: tuple[str, ...] = ("max_iterations", "shrink_margin")

_SUCCESS = (ruckig.Result.Working, ruckig.Result.Finished)


# --------------------------------------------------------------------------- #
# The 1-DOF Ruckig law
# --------------------------------------------------------------------------- #


@dataclass(frozen=True)
class RuckigAttempt:
    """Outcome of one Ruckig calculation.

    Attributes
    ----------
    duration : float or None
        Motion duration (s), None if the calculation failed.
    solver_code : str
        ``"ruckig.Result.<name>"`` as returned by ``Ruckig.calculate``, or
        ``"ruckig.<ExceptionName>"`` if it raised.
    message : str
        First line of the exception text (empty unless it raised).
    """

    duration: float | None
    solver_code: str
    message: str = ""

    @property
    def ok(self) -> bool:
        """``True`` if Ruckig returned ``Working`` or ``Finished``."""
        return self.duration is not None

    def describe(self) -> str:
        """``"returned ruckig.Result.X"`` or ``"raised ruckig.RuckigError: ..."``."""
        if self.message:
            return f"raised {self.solver_code}: {self.message}"
        return f"returned {self.solver_code}"


def _result_code(result: Any) -> str:
    """``"ruckig.Result.<name>"`` for a ``ruckig.Result`` value."""
    name = getattr(result, "name", None) or str(result).rsplit(".", 1)[-1]
    return f"ruckig.Result.{name}"


class RuckigLaw:
    """Rest-to-rest 1-DOF Ruckig time law ``s(t)`` from 0 to 1.

    Attributes
    ----------
    traj : ruckig.Trajectory
        The last successfully calculated law.
    failures : dict[str, int]
        Number of failed calculations per solver code, since creation.
    last_failure : RuckigAttempt or None
        The most recent failed calculation.
    """

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
        self.failures: dict[str, int] = {}
        self.last_failure: RuckigAttempt | None = None

    def solve(self, sd_max: float, sdd_max: float, sddd_max: float) -> RuckigAttempt:
        """Plan with bounds 1/s, 1/s^2, 1/s^3; the duration or the solver's code."""
        self._inp.max_velocity = [sd_max]
        self._inp.max_acceleration = [sdd_max]
        self._inp.max_jerk = [sddd_max]
        try:
            result = self._otg.calculate(self._inp, self.traj)
        except Exception as exc:
            lines = [ln.strip() for ln in str(exc).splitlines() if ln.strip()]
            code = f"{type(exc).__module__}.{type(exc).__name__}"
            attempt = RuckigAttempt(None, code, lines[0] if lines else type(exc).__name__)
        else:
            if result in _SUCCESS:
                return RuckigAttempt(float(self.traj.duration), _result_code(result))
            attempt = RuckigAttempt(None, _result_code(result))
        self.failures[attempt.solver_code] = self.failures.get(attempt.solver_code, 0) + 1
        self.last_failure = attempt
        return attempt

    def profile_eval(self, t: np.ndarray) -> tuple[np.ndarray, ...]:
        """Evaluate the last law from its jerk profile.

        Parameters
        ----------
        t : np.ndarray
            Shape ``(M,)``, s.

        Returns
        -------
        s, sd, sdd, sddd : np.ndarray
            Shape ``(M,)``: -, 1/s, 1/s^2, 1/s^3.

        Raises
        ------
        RuntimeError
            If the profile has a brake/accel pre-phase (not expected from rest).
        """
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


def _min_ratio(num: np.ndarray, den: np.ndarray) -> float:
    """``min(num / den)`` over ``den > 0`` (inf if none)."""
    mask = den > 0.0
    return float(np.min(num[mask] / den[mask])) if np.any(mask) else math.inf


def ruckig_bound_set(
    path: SplinePath, limits: JointLimits, law: RuckigLaw
) -> tuple[tuple[float, float, float] | None, str]:
    """Admissible global ``(sd_max, sdd_max, sddd_max)`` with the shortest duration.

    Parameters
    ----------
    path : SplinePath
        Provides ``abs_max = (A1, A2, A3)``, each shape ``(n,)``.
    limits : JointLimits
        Joint limits (SI).
    law : RuckigLaw
        Used to compute each candidate's duration; its ``failures`` record
        the solver codes of failed candidates.

    Returns
    -------
    bounds : tuple of float or None
        1/s, 1/s^2, 1/s^3; None if no candidate is admissible.
    message : str
        Why there is none (empty otherwise), with Ruckig's codes if it failed.
    """
    a1, a2, a3 = path.abs_max
    v, a, jk = limits.velocity, limits.acceleration, limits.jerk
    sd_cap = min(
        _min_ratio(v, a1),
        _min_ratio(np.sqrt(a), np.sqrt(a2)),
        _min_ratio(np.cbrt(jk), np.cbrt(a3)),
    )
    if not math.isfinite(sd_cap) or sd_cap <= 0.0:
        return None, f"no admissible path-velocity bound (sd cap {sd_cap!r})"
    best: tuple[float, tuple[float, float, float]] | None = None
    for f1 in RUCKIG_BUDGET_FRACTIONS:
        sd = float(f1) * sd_cap
        sdd_cap = min(_min_ratio(a - a2 * sd**2, a1), _min_ratio(jk - a3 * sd**3, 3.0 * a2 * sd))
        if not sdd_cap > 0.0:
            continue
        for f2 in RUCKIG_BUDGET_FRACTIONS:
            sdd = float(f2) * sdd_cap
            sddd = _min_ratio(jk - a3 * sd**3 - 3.0 * a2 * sd * sdd, a1)
            if not (sddd > 0.0 and math.isfinite(sddd) and math.isfinite(sdd)):
                continue
            attempt = law.solve(sd, sdd, sddd)
            if attempt.duration is not None and (best is None or attempt.duration < best[0]):
                best = (attempt.duration, (sd, sdd, sddd))
    if best is None:
        msg = "no admissible global bound set for the path parameter"
        if law.failures:
            codes = ", ".join(f"{c} x{k}" for c, k in law.failures.items())
            msg += f" (Ruckig failed on every candidate: {codes})"
        return None, msg
    return best[1], ""


# --------------------------------------------------------------------------- #
# The verification loop
# --------------------------------------------------------------------------- #


class _RuckigLoop:
    """Ruckig runs with uniform time scaling of the bounds until the check passes."""

    def __init__(
        self,
        path: SplinePath,
        limits: JointLimits,
        dt: float,
        opts: Mapping[str, Any],
        law: RuckigLaw,
        bounds: tuple[float, float, float],
    ) -> None:
        self.path, self.limits, self.dt, self.law = path, limits, dt, law
        self.max_iter: int = opts.get("max_iterations", RUCKIG_MAX_ITERATIONS)
        self.margin: float = opts.get("shrink_margin", RUCKIG_SHRINK_MARGIN)
        self.sd_max, self.sdd_max, self.sddd_max = bounds
        self.first: dict[str, np.ndarray] = {}
        self.ratio: dict[str, np.ndarray] = {}
        self.duration = math.nan

    def _failed(self, reason: str, it: int, solver_code: str = "") -> Trajectory:
        return empty_trajectory(
            "ruckig",
            TimingStatus.FAILED,
            reason,
            self.limits.n_joints,
            self.dt,
            it,
            solver_code,
        )

    def sampled_law(self, tm: np.ndarray) -> tuple[np.ndarray, ...]:
        """s, sd, sdd from ``at_time``; sddd from the jerk profile (``tm`` in s)."""
        law = self.law
        states = np.array([law.traj.at_time(float(x))[:3] for x in tm], dtype=float)
        states = states.reshape(tm.size, 3)
        ps, vs, accs, js = law.profile_eval(tm)
        scale = np.array([1.0, self.sd_max, self.sdd_max])
        gap = np.abs(states - np.column_stack((ps, vs, accs))) / scale
        if gap.size and float(gap.max()) > RUCKIG_CONSISTENCY_TOL:
            raise RuntimeError(f"Ruckig profile evaluation differs from at_time by {float(gap.max()):.3g}")
        return states[:, 0], states[:, 1], states[:, 2], js

    def run(self) -> Trajectory:
        """Iterate until a run passes the check or the runs are used up; sample it at dt."""
        for it in range(1, self.max_iter + 1):
            step = self._iteration(it)
            if isinstance(step, Trajectory):
                return step
            csd, summary = step
            if (
                it == self.max_iter
                or not exceeded_limits(self.ratio, LIMIT_KEYS)
                or moves_backwards(csd, self.sd_max) is not None
            ):
                try:
                    return finish_trajectory(
                        "ruckig",
                        self.path,
                        self.limits,
                        self.dt,
                        self.sampled_law,
                        self.duration,
                        self.ratio,
                        summary,
                        check_sd=csd,
                        sd_scale=self.sd_max,
                        iterations=it,
                        first=self.first,
                        runs=f" after {it} run(s) (max_iterations={self.max_iter})",
                    )
                except RuntimeError as exc:
                    return self._failed(f"Ruckig sampling failed: {exc}", it)
            self._rescale()
        raise AssertionError("the last Ruckig run always returns")  # pragma: no cover

    def _iteration(self, it: int) -> Trajectory | tuple[np.ndarray, str]:
        """Run ``it``: a failed result, or the path velocity on the check grid (1/s) and the
        summary of the run (its ratios are in :attr:`ratio`)."""
        sd_max, sdd_max, sddd_max = self.sd_max, self.sdd_max, self.sddd_max
        attempt = self.law.solve(sd_max, sdd_max, sddd_max)
        if attempt.duration is None:
            return self._failed(
                f"Ruckig run {it} failed for bounds sd<={sd_max:.6g}, "
                f"sdd<={sdd_max:.6g}, sddd<={sddd_max:.6g}: {attempt.describe()}",
                it,
                attempt.solver_code,
            )
        self.duration = duration = attempt.duration
        try:
            tc = check_times(duration, self.dt)
            cs, csd, csdd, csddd = self.law.profile_eval(tc)
        except RuntimeError as exc:
            return self._failed(f"Ruckig sampling failed: {exc}", it)
        _, cqd, cqdd, cqddd = self.path.evaluate(cs, csd, csdd, csddd)
        self.ratio = ratio = limit_ratios(cqd, cqdd, cqddd, self.limits)
        if not self.first:
            self.first = ratio
        summary = (
            f"Ruckig on the path parameter with global bounds sd<={sd_max:.6g} 1/s, "
            f"|sdd|<={sdd_max:.6g} 1/s^2, |sddd|<={sddd_max:.6g} 1/s^3, {it} run(s); "
            f"motion {duration:.4f} s; {format_ratios(ratio)}"
        )
        return csd, summary

    def _rescale(self) -> None:
        """Uniform time scaling of the bound set by the measured ratios."""
        ratio = self.ratio
        k = time_scale_factor(ratio) * (1.0 + self.margin)
        self.sd_max, self.sdd_max, self.sddd_max = (
            self.sd_max / k,
            self.sdd_max / k**2,
            self.sddd_max / k**3,
        )


def run_ruckig(path: SplinePath, limits: JointLimits, dt: float, opts: Mapping[str, Any]) -> Trajectory:
    """Time ``path`` with Ruckig (the registered runner of ``"ruckig"``).

    Parameters
    ----------
    path : SplinePath
        The geometric path (rad, joint space).
    limits : JointLimits
        Velocity (rad/s), acceleration (rad/s^2) and jerk (rad/s^3) are all
        enforced.
    dt : float
        Controller period (s).
    opts : Mapping
        Validated options (see module docstring).

    Returns
    -------
    Trajectory
        ``method = "ruckig"``; never raises for solver failures (their code
        is in ``solver_code``).
    """
    law = RuckigLaw()
    bounds, msg = ruckig_bound_set(path, limits, law)
    if bounds is None:
        code = law.last_failure.solver_code if law.last_failure is not None else ""
        return empty_trajectory("ruckig", TimingStatus.FAILED, f"Ruckig: {msg}", limits.n_joints, dt, 0, code)
    return _RuckigLoop(path, limits, dt, opts, law, bounds).run()


def _validate_ruckig_options(out: dict[str, Any]) -> dict[str, Any]:
    """Check the values of the Ruckig options (see module docstring)."""
    check_integer_options(out, (("max_iterations", 1),))
    check_shrink_margin(out)
    return out


#: The registry record of ``method="ruckig"``.
RUCKIG_METHOD: TimingMethod = register_method(
    TimingMethod(
        name="ruckig",
        run=run_ruckig,
        options=RUCKIG_OPTIONS,
        validate_options=_validate_ruckig_options,
        checked_limits=LIMIT_KEYS,
        description="jerk-limited on the path parameter (Ruckig, global bound set)",
        display_name="Ruckig",
        controller_rank=20,
        duration_note="Ruckig, jerk-limited: the trajectory the controller runs",
        underuse_cause=(
            "Ruckig times the path parameter under one bound per derivative for the whole path, set "
            "by the joint and point where the path is most demanding (its largest |dq/ds|, "
            "|d2q/ds2|, |d3q/ds3| at once), so everywhere else and on the other joints the limits "
            "are not reached; method jerk_optimal times the path point by point"
        ),
    )
)
