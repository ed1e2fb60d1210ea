"""Sampling a time law on the controller grid and checking the joint limits.

Samples are at ``t_k = k dt`` from 0 (s); the last sample is the first
multiple of ``dt`` at or after the end of the motion and holds the final
waypoint at rest (zero velocity, acceleration and jerk), so ``duration_s =
t[-1]`` is a multiple of ``dt``. ``limit_ratio`` is the peak ``|value| /
limit`` per joint (joint space, dimensionless) over the returned samples
*and* a check grid ``VERIFY_OVERSAMPLE`` times finer than ``dt`` (plus any
extra times a method adds, e.g. the breakpoints of the TOPP-RA time law where
its acceleration has kinks), so it also bounds what a finer controller would
see, up to the variation between check points. A ratio counts as within its
limit when it is ``<= 1 + LIMIT_RATIO_TOL``; only the limits a method
checks decide its ``OK`` status.

:func:`finish_trajectory` is the end of every method: it samples the method's time law at
``dt``, verifies every limit, and decides the status (``OK``, ``LIMIT_EXCEEDED``, or ``FAILED``
when the law moves backwards) and its reason, from the limits the method's registry record
says it checks. A reason never repeats the status.

The limits checked are the joint velocity (rad/s), acceleration (rad/s^2)
and jerk (rad/s^3) of :class:`~problems.timing.trajectory.JointLimits`; the
position follows the geometric path exactly (first and last samples are the
first and last waypoints) and has no limit of its own here.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping

import numpy as np

from problems.timing.path import SplinePath
from problems.timing.registry import (
    LIMIT_RATIO_TOL,
    MONOTONE_TOL,
    MAX_TRAJECTORY_SAMPLES,
    TimeLawTooLong,
    display_name,
    get_method,
)
from problems.timing.trajectory import LIMIT_KEYS, JointLimits, TimingStatus, Trajectory

__all__ = [
    "VERIFY_OVERSAMPLE",
    "check_times",
    "exceeded_limits",
    "finish_trajectory",
    "format_ratios",
    "limit_ratios",
    "moves_backwards",
    "sampled_ratios",
    "time_scale_factor",
]

#: The check grid used for ``limit_ratio`` is this many times finer than dt.
VERIFY_OVERSAMPLE: int = 4

#: ``law(t) -> (s, sd, sdd, sddd)``: a scalar time law evaluated at times
#: ``t`` (shape ``(M,)``, s); each output shape ``(M,)`` in -, 1/s, 1/s^2,
#: 1/s^3.
TimeLaw = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]


def sample_times(duration: float, dt: float) -> np.ndarray:
    """Uniform times ``k dt`` (s) up to the first multiple of dt >= ``duration``.

    Returns
    -------
    np.ndarray
        Shape ``(M,)``, s, at least two samples.
    """
    k_end = max(1, int(math.ceil(duration / dt)))
    if k_end * dt < duration:
        k_end += 1
    return np.arange(k_end + 1, dtype=float) * dt


def check_times(duration: float, dt: float, extra: np.ndarray | None = None) -> np.ndarray:
    """Times (s) of the fine check grid strictly inside ``[0, duration)``.

    Parameters
    ----------
    duration : float
        End of the motion (s).
    dt : float
        Controller period (s); the grid step is ``dt / VERIFY_OVERSAMPLE``.
    extra : np.ndarray, optional
        Shape ``(E,)``, s, additional times; those in ``[0, duration)`` are
        appended (unsorted).

    Raises
    ------
    TimeLawTooLong
        The motion needs more than ``MAX_TRAJECTORY_SAMPLES`` samples at ``dt``, or its
        duration is not finite (checked here, before anything is sampled).
    """
    if not math.isfinite(duration) or duration / dt + 1.0 > MAX_TRAJECTORY_SAMPLES:
        raise TimeLawTooLong(duration)
    fine = np.arange(0.0, duration, dt / VERIFY_OVERSAMPLE)
    if extra is not None:
        fine = np.concatenate((fine, extra[(extra >= 0.0) & (extra < duration)]))
    return fine


def limit_ratios(qd: np.ndarray, qdd: np.ndarray, qddd: np.ndarray, limits: JointLimits) -> dict[str, np.ndarray]:
    """Peak ``|value| / limit`` per joint.

    Parameters
    ----------
    qd, qdd, qddd : np.ndarray
        Shape ``(M, n)``: rad/s, rad/s^2, rad/s^3.
    limits : JointLimits
        The limits (SI).

    Returns
    -------
    dict[str, np.ndarray]
        Keys :data:`LIMIT_KEYS`, each shape ``(n,)``, dimensionless (zeros if
        ``M = 0``).
    """
    out = {}
    for key, arr in zip(LIMIT_KEYS, (qd, qdd, qddd)):
        lim = getattr(limits, key)
        out[key] = np.abs(arr).max(axis=0) / lim if arr.shape[0] else np.zeros_like(lim)
    return out


def time_scale_factor(ratio: Mapping[str, np.ndarray]) -> float:
    """``k = max(r_v, sqrt(r_a), cbrt(r_j))`` of the peak ratios: slowing a law uniformly in time by
    ``k`` divides every velocity by ``k``, acceleration by ``k^2`` and jerk by ``k^3`` on the same
    path, which brings each peak ratio to at most 1 (<= 1 when they all are)."""
    return max(
        float(np.max(ratio["velocity"])),
        math.sqrt(float(np.max(ratio["acceleration"]))),
        math.cbrt(float(np.max(ratio["jerk"]))),
    )


def sampled_ratios(
    path: SplinePath, law: TimeLaw, duration: float, limits: JointLimits, dt: float
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """The peak ratios of ``law`` on the fine check grid (:func:`check_times`), and its path velocity
    there (1/s, for :func:`finish_trajectory`'s ``check_sd``)."""
    s, sd, sdd, sddd = law(check_times(duration, dt))
    _, qd, qdd, qddd = path.evaluate(s, sd, sdd, sddd)
    return limit_ratios(qd, qdd, qddd, limits), sd


def max_ratios(*dicts: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Element-wise maximum of several ratio dicts (each value shape ``(n,)``)."""
    return {k: np.maximum.reduce([d[k] for d in dicts]) for k in LIMIT_KEYS}


def exceeded_limits(ratio: Mapping[str, np.ndarray], keys: tuple[str, ...]) -> list[str]:
    """The ``keys`` whose peak ratio is above ``1 + LIMIT_RATIO_TOL``, in order."""
    return [k for k in keys if float(np.max(ratio[k])) > 1.0 + LIMIT_RATIO_TOL]


def format_ratios(ratio: Mapping[str, np.ndarray]) -> str:
    """``"peak ratios velocity 0.9876 (joint 2), ..."`` for a reason text."""
    parts = []
    for k in LIMIT_KEYS:
        r = ratio[k]
        j = int(np.argmax(r))
        parts.append(f"{k} {float(r[j]):.4f} (joint {j + 1})")
    return "peak ratios " + ", ".join(parts)


def moves_backwards(sd: np.ndarray, sd_scale: float) -> float | None:
    """Most negative path velocity (1/s) if the law moves backwards, else None.

    Backwards means ``min(sd) < -MONOTONE_TOL * max(1, sd_scale)``; ``sd``
    has shape ``(M,)``, 1/s, and ``sd_scale`` is the law's peak ``sd`` (1/s).
    """
    backwards = float(sd.min(initial=0.0))
    if backwards < -MONOTONE_TOL * max(1.0, sd_scale):
        return backwards
    return None


def sample_path(
    path: SplinePath,
    t: np.ndarray,
    duration: float,
    law_s: np.ndarray,
    law_sd: np.ndarray,
    law_sdd: np.ndarray,
    law_sddd: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Map a time law (values given for ``t < duration``) to joint samples.

    Parameters
    ----------
    path : SplinePath
        The geometric path.
    t : np.ndarray
        Shape ``(M,)``, s, sample times.
    duration : float
        End of the motion (s).
    law_s, law_sd, law_sdd, law_sddd : np.ndarray
        Shape ``(K,)`` with ``K`` the number of ``t < duration``: the law and
        its derivatives (-, 1/s, 1/s^2, 1/s^3) at those times.

    Returns
    -------
    q, qd, qdd, qddd : np.ndarray
        Shape ``(M, n)``: rad, rad/s, rad/s^2, rad/s^3. Samples at ``t >=
        duration`` hold the last waypoint at rest; the first sample is the
        first waypoint exactly.
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


def _limit_words(keys: tuple[str, ...]) -> str:
    """``"velocity, acceleration and jerk"`` for the keys given."""
    return keys[0] if len(keys) == 1 else ", ".join(keys[:-1]) + " and " + keys[-1]


def _verdict(
    method: str, ratio: Mapping[str, np.ndarray], backwards: float | None, runs: str
) -> tuple[TimingStatus, str]:
    """The status of a sampled law and the reason's head (see :func:`finish_trajectory`).

    Parameters
    ----------
    method : str
        The registered method (its checked limits decide).
    ratio : Mapping
        Peak ratios over the samples and the check grid, each shape ``(n,)``.
    backwards : float or None
        The most negative path velocity, 1/s, if the law moves backwards (:func:`moves_backwards`).
    runs : str
        Appended to the limit-exceeded reason.
    """
    checked = get_method(method).checked_limits
    bad = exceeded_limits(ratio, checked)
    if backwards is not None:
        what = f"the {display_name(method)} time law moves backwards along the path (min ds/dt = {backwards:.3g} 1/s)"
        return TimingStatus.FAILED, what
    if bad:
        return TimingStatus.LIMIT_EXCEEDED, f"{' and '.join(bad)} ratio above 1{runs}"
    return TimingStatus.OK, f"{_limit_words(checked)} within limits"


def finish_trajectory(
    method: str,
    path: SplinePath,
    limits: JointLimits,
    dt: float,
    law: TimeLaw,
    duration: float,
    check_ratio: Mapping[str, np.ndarray],
    summary: str,
    *,
    check_sd: np.ndarray,
    sd_scale: float,
    iterations: int,
    first: Mapping[str, np.ndarray] | None = None,
    runs: str = "",
) -> Trajectory:
    """Sample a method's time law at ``dt``, verify it and decide its status and reason.

    The one end of every method: the limits checked are those of the method's registry
    record (:attr:`~problems.timing.registry.TimingMethod.checked_limits`).

    Parameters
    ----------
    method : str
        The registered method that made the law.
    path : SplinePath
        The geometric path (rad).
    limits : JointLimits
        The limits (SI).
    dt : float
        Controller period, s.
    law : TimeLaw
        ``law(t) -> (s, sd, sdd, sddd)`` for ``t < duration`` (s).
    duration : float
        End of the motion, s.
    check_ratio : Mapping
        Peak ratios on the fine check grid (:func:`check_times`), each shape ``(n,)``.
    summary : str
        What the method did (solver, runs, motion, ratios): the reason's tail.
    check_sd : np.ndarray
        Shape ``(C,)``, 1/s, the law's path velocity on the check grid (monotonicity).
    sd_scale : float
        The law's peak path velocity, 1/s (scale of :func:`moves_backwards`).
    iterations : int
        Runs of the method's verification loop.
    first : Mapping, optional
        First-pass ratios (the final ones if empty or None).
    runs : str
        Appended to the limit-exceeded reason, e.g. ``" after 6 run(s) (max_iterations=6)"``.

    Returns
    -------
    Trajectory
        ``FAILED`` if the law moves backwards along the path; else ``OK`` if every checked
        ratio (the maximum of ``check_ratio`` and the ratio over the samples) is
        ``<= 1 + LIMIT_RATIO_TOL``, otherwise ``LIMIT_EXCEEDED``. The reason says which
        (without repeating the status), then ``summary``.
    """
    t = sample_times(duration, dt)
    tm = t[t < duration]
    q, qd, qdd, qddd = sample_path(path, t, duration, *law(tm))
    ratio = max_ratios(limit_ratios(qd, qdd, qddd, limits), check_ratio)
    status, what = _verdict(method, ratio, moves_backwards(check_sd, sd_scale), runs)
    return Trajectory(
        method=method,
        status=status,
        reason=f"{what}; {summary}",
        t=t,
        q=q,
        qd=qd,
        qdd=qdd,
        qddd=qddd,
        duration_s=float(t[-1]),
        limit_ratio=ratio,
        dt=dt,
        iterations=iterations,
        first_pass_limit_ratio=dict(first) if first else dict(ratio),
    )
