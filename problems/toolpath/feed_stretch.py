"""One stretch of a program between two stops, timed: fitted within the path tolerance first when
it is a cutting stretch (:mod:`problems.toolpath.stretch_fit`), its samples measured against the
programmed path, its moves' cruising bounds (what holds the feed down) found, re-timed or timed by
another method where the first one is slow or fails (``docs/gcode.md``, "The feed law")."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from problems.timing import JointLimits, TimingStatus, Trajectory, time_parametrize

__all__ = [
    "FEED_FALLBACK_METHOD",
    "LENGTH_SCALE",
    "StretchGeometry",
    "time_stretch_checked",
]

#: The path-length pseudo-joint is the TCP's distance along the waypoints (m) times this: small
#: enough not to change the spline's chord-length parameter, and read back to tell the move each
#: sample runs (the length is smooth along the path where the waypoint index is not).
LENGTH_SCALE = 1e-6
#: A cutting stretch that the method runs above this many times its programmed time is re-timed by
#: :data:`FEED_RETRY_METHOD` and the shorter law kept: Ruckig's one bound set per stretch is held
#: down by the stretch's most demanding point (the largest third derivative of the joint path: on a
#: posture optimised at every waypoint, its small waviness), the jerk-limited NLP is not.
FEED_RETRY_RATIO = 1.1
#: Stretches shorter than this (waypoints) are not re-timed: they are mostly the accelerations at
#: their stops, which no method shortens.
FEED_RETRY_MIN_WAYPOINTS = 8
#: The method (and its options) stretches are re-timed by: jerk-limited, time-optimal on its grid
#: (its default grid, up to 480 gridpoints: 0.1-0.3 s a stretch; its smallest, 160, is faster but
#: held the shipped milling_pocket's cutting time at 1.22x length/F instead of 1.10x).
FEED_RETRY_METHOD = "jerk_optimal"
#: The methods whose stretches may be re-timed: those with one bound set per stretch (Ruckig's);
#: the look-ahead's bounds are local already, so re-timing it gains nothing.
FEED_RETRY_FROM: tuple[str, ...] = ("ruckig",)
FEED_RETRY_OPTIONS: dict[str, object] = {}
#: A stretch the method fails on (TOPP-RA's "not controllable" on a short stretch between two
#: corners of the shipped milling program) is timed by this method instead when it checks every
#: limit the method does; the trajectory's reason and the plan's warnings say so.
FEED_FALLBACK_METHOD = "ruckig"


@dataclass(frozen=True)
class StretchGeometry:
    """What smoothing and the path check need: the TCP frame by forward kinematics, the waypoints' TCP by it
    (the programmed path as the commands trace it, (N, 3) m), the distance along the targets (N,) m
    and the tolerance, m."""

    tcp_frame: Callable[[np.ndarray], np.ndarray]
    tcp_m: np.ndarray
    length_m: np.ndarray
    tolerance_m: float
    slack_m: np.ndarray

    def deviation(self, q: np.ndarray, along_m: np.ndarray) -> float:
        """Largest distance (m) of the samples' TCP from the polyline, each sample measured against
        the move it runs (from its distance along the path) and its two neighbours."""
        from problems.toolpath.stretch_fit import segment_distance

        if not len(q):
            return 0.0
        P = self.tcp_m
        n = len(P)
        move = np.clip(np.searchsorted(self.length_m, along_m, side="left"), 1, n - 1)
        pos = self.tcp_frame(q)[:, :3, 3]
        d = np.min(
            [
                segment_distance(pos, P[np.clip(move + o - 1, 0, n - 1)], P[np.clip(move + o, 0, n - 1)])
                + self.slack_m[np.clip(move + o, 0, n - 1)]
                for o in (-1, 0, 1)
            ],
            axis=0,
        )
        return float(np.max(d))


def time_stretch_checked(
    seg: np.ndarray,
    tau: np.ndarray,
    aug: JointLimits,
    method: str,
    dt: float,
    programmed_s: float,
    options: dict,
    geo: StretchGeometry | None,
    first: int = 0,
) -> tuple[Trajectory, str, float, int, tuple[np.ndarray, ...] | None]:
    """One stretch timed (:func:`_time_stretch`), a cutting stretch first fitted within the tolerance
    (:func:`problems.toolpath.stretch_fit.fit_stretch`), and its samples' largest distance from the
    path measured (m; 0 without ``geo``). Returns the trajectory, how it was timed, the distance,
    the rows the fit added and, for a fitted stretch, its moves' cruising bounds (:func:`_cruise_bounds`)."""
    n = seg.shape[1] - 2
    if geo is None or programmed_s <= 0.0:
        tr, how = _time_stretch(seg, aug, method, dt, programmed_s, options)
        dev = geo.deviation(tr.q[:, :n], tr.q[:, n + 1] / LENGTH_SCALE) if geo is not None and tr.q.size else 0.0
        return tr, how, dev, 0, None
    from problems.toolpath.stretch_fit import fit_stretch

    fitted, _, kept = fit_stretch(
        seg, n, tau, geo.tcp_frame, geo.tolerance_m, geo.slack_m[first : first + len(seg)], time_column=n
    )
    tr, how = _time_stretch(fitted, aug, method, dt, programmed_s, options)
    dev = geo.deviation(tr.q[:, :n], tr.q[:, n + 1] / LENGTH_SCALE) if tr.q.size else 0.0
    return tr, how, dev, len(fitted) - len(seg), _cruise_bounds(fitted, kept, n, _checked_only(aug, method))


#: A limit the method does not check, in :func:`_checked_only` (JointLimits takes finite values only).
_UNCHECKED = 1e30


def _checked_only(limits: JointLimits, method: str) -> JointLimits:
    """``limits`` with those the method does not check made practically infinite (TOPP-RA's jerk)."""
    from problems.timing import get_method

    checked = get_method(method).checked_limits
    return JointLimits(
        *(
            getattr(limits, k) if k in checked else np.full(limits.n_joints, _UNCHECKED)
            for k in ("velocity", "acceleration", "jerk")
        )
    )


def _cruise_bounds(rows: np.ndarray, kept: np.ndarray, n: int, aug: JointLimits) -> tuple[np.ndarray, ...]:
    """Per move of a cutting stretch (between kept rows ``j - 1`` and ``j``): the fastest the joints
    let it cruise over its feed (the smallest over its knots and interval middles,
    :func:`problems.timing.lookahead.local_bounds`), the joint (0-based) and the kind of limit
    (index into ``BOUND_KINDS``) that set it. Shapes ``(m - 1,)``."""
    from problems.timing.lookahead import local_bounds
    from problems.timing.path import SplinePath

    path = SplinePath(rows)
    k = path.knots
    s = np.sort(np.r_[k, 0.5 * (k[:-1] + k[1:])])  # knot, middle, knot, ...
    lb = local_bounds(path, aug, s, joints=n)
    feed_speed = aug.velocity[n] / np.maximum(np.abs(path.spline.derivative(1)(s)[:, n]), 1e-300)
    ratio = lb.speed / feed_speed
    # per interval i: points 2i, 2i + 1, 2i + 2
    tri = np.stack([ratio[0:-1:2], ratio[1::2], ratio[2::2]], axis=1)
    arg = np.argmin(tri, axis=1)
    idx = 2 * np.arange(len(tri)) + arg
    per_interval = tri[np.arange(len(tri)), arg]
    starts = kept[:-1]
    moves = np.minimum.reduceat(per_interval, starts)
    # the point of the smallest ratio of each move
    where = np.array([starts[j] + int(np.argmin(per_interval[starts[j] : kept[j + 1]])) for j in range(len(starts))])
    return moves, lb.joint[idx[where]], lb.kind[idx[where]]


def _time_stretch(
    seg: np.ndarray, aug: JointLimits, method: str, dt: float, programmed_s: float, options: dict
) -> tuple[Trajectory, str]:
    """One stretch timed by ``method``; re-timed by :data:`FEED_RETRY_METHOD` where that is shorter
    (``"retimed"``), or by :data:`FEED_FALLBACK_METHOD` where ``method`` fails
    (``"substituted:<its reason>"``); else ``""``."""
    tr = time_parametrize(seg, aug, method, dt, **options)
    if _retry(method, tr, len(seg), programmed_s):
        again = time_parametrize(seg, aug, FEED_RETRY_METHOD, dt, **FEED_RETRY_OPTIONS)
        if again.status is TimingStatus.OK and again.duration_s < tr.duration_s:
            return replace(again, method=method), "retimed"
    if tr.status is not TimingStatus.OK and _covers(FEED_FALLBACK_METHOD, method):
        again = time_parametrize(seg, aug, FEED_FALLBACK_METHOD, dt)
        if again.status is TimingStatus.OK:
            return replace(again, method=method), f"substituted:{tr.status.value}: {tr.reason}"
    return tr, ""


def _covers(other: str, method: str) -> bool:
    """Whether registered method ``other`` (not ``method``) checks every limit ``method`` checks."""
    from problems.timing import available_methods, get_method

    if other == method or other not in available_methods():
        return False
    return set(get_method(method).checked_limits) <= set(get_method(other).checked_limits)


def _retry(method: str, tr: Trajectory, n_way: int, programmed_s: float) -> bool:
    """Whether a stretch timed by ``method`` is re-timed by :data:`FEED_RETRY_METHOD`: a cutting stretch of
    at least :data:`FEED_RETRY_MIN_WAYPOINTS` waypoints that ``method`` ran above
    :data:`FEED_RETRY_RATIO` times its programmed time, when the retry method checks every limit
    ``method`` does."""
    if method not in FEED_RETRY_FROM or tr.status is not TimingStatus.OK or programmed_s <= 0.0:
        return False
    if n_way < FEED_RETRY_MIN_WAYPOINTS or tr.duration_s <= FEED_RETRY_RATIO * programmed_s:
        return False
    return _covers(FEED_RETRY_METHOD, method)
