"""The feed law: a joint path timed so that the TCP runs at the programmed feed where the joint
limits allow it, never above it.

The feed becomes one more limit of the existing timing methods. Along the waypoints the
**programmed time** ``tau`` grows by ``|p_k - p_{k-1}| / F_k`` over a cutting move of feed
``F_k`` (m/s) and by 0 over a rapid; ``tau`` is appended to the joint path as a pseudo-joint whose
velocity limit is 1 (``d tau / dt <= 1``: the TCP covers the programmed path no faster than the
program says), and whose acceleration and jerk limits are left loose
(:data:`FEED_PSEUDO_ACCEL`, :data:`FEED_PSEUDO_JERK`). Any registered method times the augmented
path; its samples are verified against every limit as usual, the feed included, so a feed
exceeded on a sample makes the trajectory's status not ``ok``. Rapids are time-optimal under the
joint limits. Where the joint limits force the path slower than the feed, ``d tau / dt < 1``:
:class:`FeedLaw` names those waypoints (and so the program lines) and how much slower.

The pseudo-joint is spline-interpolated through the waypoints like the joints: between
waypoints the TCP speed matches ``F d tau/dt`` to the path's discretisation (chords of a curve
within the path tolerance); ``tests/test_feed.py`` checks the TCP speed from forward kinematics.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from models.errors import InputError
from problems.timing import JointLimits, Trajectory, time_parametrize

__all__ = ["FEED_PSEUDO_ACCEL", "FEED_PSEUDO_JERK", "FEED_SLOW_TOL", "FeedLaw", "feed_time_law", "programmed_time"]

#: Acceleration limit of the programmed-time pseudo-joint (1/s): loose, so that only the joints'
#: limits shape the accelerations (the feed is a speed bound).
FEED_PSEUDO_ACCEL = 1e3
#: Jerk limit of the programmed-time pseudo-joint (1/s^2), loose likewise.
FEED_PSEUDO_JERK = 1e6
#: A waypoint counts as slowed when its peak ``d tau / dt`` is below ``1 - FEED_SLOW_TOL``: 5 %, above
#: the uniform slow-down (a few %) that ``jerk_optimal`` applies to its whole law when its fine
#: check finds a discretisation excess (x1.0245 on the demo's line at 3 m/min).
FEED_SLOW_TOL = 0.05


def programmed_time(points_m: np.ndarray, feed_m_s: np.ndarray) -> np.ndarray:
    """The programmed time at each waypoint (s): ``sum |p_k - p_{k-1}| / F_k`` over cutting moves.

    Parameters
    ----------
    points_m : np.ndarray
        Shape ``(N, 3)``, m: the TCP's waypoints (any frame).
    feed_m_s : np.ndarray
        Shape ``(N,)``, m/s: the feed of the move ending at each waypoint; NaN for a rapid (and
        for waypoint 0, which ends no move).

    Raises
    ------
    InputError
        Wrong shapes, or a cutting feed that is not > 0.
    """
    P = np.asarray(points_m, dtype=float)
    F = np.asarray(feed_m_s, dtype=float)
    if P.ndim != 2 or P.shape[1] != 3 or F.shape != (len(P),):
        raise InputError(f"feed law: points must be (N, 3) and feeds (N,), got {P.shape} and {F.shape}")
    cut = ~np.isnan(F[1:])
    bad = np.flatnonzero(cut & ~(F[1:] > 0.0))
    if bad.size:
        k = int(bad[0]) + 1
        raise InputError(f"feed law: the feed of the move ending at waypoint {k} is {float(F[k])!r} m/s; expected > 0")
    step = np.linalg.norm(np.diff(P, axis=0), axis=1)
    return np.r_[0.0, np.cumsum(np.where(cut, step / np.where(cut, F[1:], 1.0), 0.0))]


@dataclass(frozen=True)
class FeedLaw:
    """A joint trajectory timed at the programmed feed.

    Attributes
    ----------
    trajectory : Trajectory
        The joints' trajectory (rad; the pseudo-joint removed); its ``limit_ratio`` are the
        joints'. Its status covers the feed too (``feed_ratio``).
    feed_ratio : float
        Peak ``d tau / dt`` over the samples: the largest TCP speed over the programmed feed
        (``<= 1`` within the timing tolerance when the feed is held).
    programmed_time_s : float
        The program's time at its feeds over the cutting moves (length / F summed), s.
    slowed : dict of int -> float
        Waypoint -> the fraction of the feed reached at most on the move ending there, for the
        cutting moves the joint limits slow by more than :data:`FEED_SLOW_TOL`.
    """

    trajectory: Trajectory
    feed_ratio: float
    programmed_time_s: float
    slowed: dict[int, float]


def feed_time_law(
    q: np.ndarray,
    points_m: np.ndarray,
    feed_m_s: np.ndarray,
    limits: JointLimits,
    dt: float,
    method: str = "jerk_optimal",
    **options: object,
) -> FeedLaw:
    """Time a joint path so the TCP runs at its programmed feed (see the module docstring).

    Parameters
    ----------
    q : np.ndarray
        Shape ``(N, n)``, rad: the joint waypoints (the commands whose TCP traces ``points_m``).
    points_m : np.ndarray
        Shape ``(N, 3)``, m: the TCP's waypoints.
    feed_m_s : np.ndarray
        Shape ``(N,)``, m/s: the feed of the move ending at each waypoint; NaN for rapids.
    limits : JointLimits
        The joints' limits (SI).
    dt : float
        Controller period, s.
    method : str
        A registered timing method; a jerk-limited one (the default) for a controller.
    **options
        The method's options.

    Returns
    -------
    FeedLaw
    """
    Q = np.asarray(q, dtype=float)
    tau = programmed_time(points_m, feed_m_s)
    if Q.ndim != 2 or len(Q) != len(tau) or Q.shape[1] != limits.n_joints:
        raise InputError(
            f"feed law: q must be (N, {limits.n_joints}) with N = {len(tau)} waypoints, got shape {Q.shape}"
        )
    n = Q.shape[1]
    aug = JointLimits(
        np.r_[limits.velocity, 1.0], np.r_[limits.acceleration, FEED_PSEUDO_ACCEL], np.r_[limits.jerk, FEED_PSEUDO_JERK]
    )
    tr = time_parametrize(np.c_[Q, tau], aug, method, dt, **options)
    rate = tr.qd[:, n] if tr.qd.size else np.empty(0)
    joints = replace(  # the joints' columns and ratios, without the pseudo-joint
        tr,
        q=tr.q[:, :n],
        qd=tr.qd[:, :n],
        qdd=tr.qdd[:, :n],
        qddd=tr.qddd[:, :n],
        limit_ratio={k: v[:n] for k, v in tr.limit_ratio.items()},
        first_pass_limit_ratio={k: v[:n] for k, v in tr.first_pass_limit_ratio.items()},
    )
    return FeedLaw(
        trajectory=joints,
        feed_ratio=float(np.max(np.abs(rate))) if rate.size else float("nan"),
        programmed_time_s=float(tau[-1]),
        slowed=_slowed(tr.q[:, n] if tr.q.size else np.empty(0), rate, tau, np.asarray(feed_m_s, float)),
    )


def _slowed(tau_t: np.ndarray, rate: np.ndarray, tau: np.ndarray, feed: np.ndarray) -> dict[int, float]:
    """Waypoint -> peak ``d tau / dt`` on the cutting move ending there, where it stays below
    ``1 - FEED_SLOW_TOL`` (samples assigned to moves by their programmed time)."""
    if not rate.size:
        return {}
    move = np.clip(np.searchsorted(tau, tau_t, side="right"), 1, len(tau) - 1)  # the move a sample is on
    peak = np.zeros(len(tau))
    np.maximum.at(peak, move, np.abs(rate))
    cutting = ~np.isnan(feed) & (np.r_[0.0, np.diff(tau)] > 0.0)
    cutting[0] = False
    seen = np.zeros(len(tau), dtype=bool)
    seen[np.unique(move)] = True
    return {int(k): float(peak[k]) for k in np.flatnonzero(cutting & seen & (peak < 1.0 - FEED_SLOW_TOL))}
