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

At program scale (:func:`feed_time_law` with ``stop``): the path is cut at its stops (and at every
change between rapid and cut or of the feed) into stretches timed rest to rest and joined, dwells
held; the pseudo-joint enters scaled by :data:`FEED_TIME_SCALE` so that it leads the spline's
parameter; a second pseudo-joint, the distance along the path, gives the move each sample runs;
a cutting stretch the method runs slowly is re-timed by :data:`FEED_RETRY_METHOD`, and one it fails
on is timed by :data:`FEED_FALLBACK_METHOD` (``docs/gcode.md``, "The feed law at program scale").
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from models.errors import InputError
from problems.timing import JointLimits, TimingStatus, Trajectory
from problems.toolpath.stretch_pool import map_stretches
from problems.toolpath.feed_stretch import (
    FEED_FALLBACK_METHOD,
    FEED_RETRY_METHOD,
    FEED_RETRY_RATIO,
    LENGTH_SCALE,
    StretchGeometry,
    time_stretch_checked,
)

__all__ = [
    "FEED_SLOW_TOL",
    "feed_time_law",
    "programmed_time",
]

#: Acceleration limit of the programmed-time pseudo-joint (1/s): loose, so that only the joints'
#: limits shape the accelerations (the feed is a speed bound).
FEED_PSEUDO_ACCEL = 1e3
#: Jerk limit of the programmed-time pseudo-joint (1/s^2), loose likewise.
FEED_PSEUDO_JERK = 1e6
#: The programmed-time pseudo-joint enters the path as ``FEED_TIME_SCALE * tau`` (with its limits
#: scaled alike): on a cutting stretch it then dominates the spline's chord-length parameter, so the
#: path parameter is the programmed time (``d tau / ds`` constant) and a method's bound on the path
#: speed is the feed everywhere, not only where the joints move least (Ruckig's global bounds held a
#: wavy raster's rows to 74 % of F before).
FEED_TIME_SCALE = 100.0
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
    sample_move : np.ndarray
        Shape ``(M,)``, int: for each sample, the waypoint ending the move it runs (1..N-1).
    n_stretches : int
        Number of stretches between stops timed on their own.
    n_substituted : int
        Stretches the method failed on and :data:`FEED_FALLBACK_METHOD` timed (the trajectory's
        reason names the first and why).
    path_deviation_m : float
        Largest distance (m) of a sample's TCP (forward kinematics of the commands) from the
        programmed path as the commands trace it; NaN when not measured (no ``tcp_position``).
    tolerance_m : float
        The path tolerance the samples were held to, m (NaN when not measured).
    cruise, bound_joint, bound_kind : np.ndarray
        Shape ``(N,)`` each: per waypoint, the fastest the joints let the move ending there cruise,
        over its feed (inf where not measured: rapids, unfitted runs), the joint (0-based) and the
        kind of limit (index into ``problems.timing.lookahead.BOUND_KINDS``) that set it.
    n_fitted : int
        Cutting stretches fitted within the tolerance before timing (smoothed where there is room).
    n_rows_added : int
        Rows the fits added at the middle of intervals that left the tolerance with both ends pinned.
    """

    trajectory: Trajectory
    feed_ratio: float
    programmed_time_s: float
    slowed: dict[int, float]
    sample_move: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    n_stretches: int = 1
    n_substituted: int = 0
    path_deviation_m: float = float("nan")
    tolerance_m: float = float("nan")
    n_fitted: int = 0
    n_rows_added: int = 0
    cruise: np.ndarray = field(default_factory=lambda: np.zeros(0))
    bound_joint: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    bound_kind: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))

    def slowed_by_limit(self, line: np.ndarray) -> dict[int, tuple[float, int, str]]:
        """Program line -> (the smallest fraction of F reached, the joint (1-based), the derivative)
        of the slowed lines a joint limit holds down: their cruising bound (:attr:`cruise`) is below
        ``1 - FEED_SLOW_TOL`` of F. The other slowed lines are slowed only by what surrounds them (the
        accelerations out of and into a stop, or the approach to a part held down)."""
        from problems.timing.lookahead import BOUND_KINDS

        out: dict[int, tuple[float, int, str]] = {}
        if not self.cruise.size:
            return out
        for k, frac in self.slowed.items():
            if not self.cruise[k] < 1.0 - FEED_SLOW_TOL:
                continue
            L = int(line[k])
            if L not in out or frac < out[L][0]:
                out[L] = (frac, int(self.bound_joint[k]) + 1, BOUND_KINDS[int(self.bound_kind[k])])
        return out

    def slowed_lines(self, line: np.ndarray) -> dict[int, float]:
        """Program line -> the smallest fraction of the feed reached on its slowed moves
        (``line``: the program line of each waypoint, shape ``(N,)``)."""
        worst: dict[int, float] = {}
        for k, frac in self.slowed.items():
            L = int(line[k])
            worst[L] = min(frac, worst.get(L, 1.0))
        return worst


#: Limits of the path-length pseudo-joint: unbounded in practice.
_INDEX_LIMIT = 1e12


def feed_time_law(
    q: np.ndarray,
    points_m: np.ndarray,
    feed_m_s: np.ndarray,
    limits: JointLimits,
    dt: float,
    method: str = "jerk_optimal",
    stop: np.ndarray | None = None,
    dwell_s: np.ndarray | None = None,
    progress: Callable[[str, int, int], None] | None = None,
    tcp_frame: Callable[[np.ndarray], np.ndarray] | None = None,
    tolerance_m: float | None = None,
    path_slack_m: np.ndarray | None = None,
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
    stop : np.ndarray, optional
        Shape ``(N,)``, bool: the arm is at rest at these waypoints (the first and last always, and
        every change between a rapid and a cutting move or of the feed: the stretch between two
        stops is then all rapid or all cut at one feed, so its path parameter is the joints' travel
        or the programmed time, and a smooth time law cannot carry one move's speed into the next
        move's lower feed).
        Each stretch between stops is timed on its own, rest to rest, and the pieces joined.
    dwell_s : np.ndarray, optional
        Shape ``(N,)``, s: time held at rest at a stop.
    progress : callable, optional
        ``progress(stage, done, total)``, called after each stretch (stage ``"timing <method>"``).
    tcp_frame : callable, optional
        ``tcp_frame(q (M, n)) -> (M, 4, 4)``: the TCP frame (base frame, m) by forward kinematics of
        the commands. With
        ``tolerance_m``, every cutting stretch's waypoints are smoothed within
        :data:`SMOOTH_SHARE` of the tolerance (:mod:`problems.toolpath.smoothing`) and every sample's
        distance from the programmed path (the polyline through the waypoints' TCP) is measured
        (:attr:`FeedLaw.path_deviation_m`); a stretch whose samples leave the tolerance is timed
        again with half the smoothing, at last unsmoothed.
    tolerance_m : float, optional
        The path tolerance, m (the program's ``G64 P`` or its default).
    path_slack_m : np.ndarray, optional
        Shape ``(N,)``, m: how far the chord ending at each waypoint may lie from the programmed path
        (an arc's chords: their sagitta bound, ``problems.toolpath.waypoints.ARC_SAGITTA_SHARE`` of
        the tolerance); a sample's distance from the path is its distance from the chord plus this.
    **options
        The method's options.

    Returns
    -------
    FeedLaw
    """
    Q = np.asarray(q, dtype=float)
    tau = programmed_time(points_m, feed_m_s)
    n_way = len(tau)
    if Q.ndim != 2 or len(Q) != n_way or Q.shape[1] != limits.n_joints:
        raise InputError(f"feed law: q must be (N, {limits.n_joints}) with N = {n_way} waypoints, got shape {Q.shape}")
    st, dw = _stops(n_way, stop, dwell_s, np.asarray(feed_m_s, dtype=float))
    n = Q.shape[1]
    length = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(np.asarray(points_m, float), axis=0), axis=1))]
    cols = np.c_[Q, FEED_TIME_SCALE * tau, length * LENGTH_SCALE]
    bounds = np.flatnonzero(st)
    geo = _geometry(Q, length, tcp_frame, tolerance_m, path_slack_m)
    with _one_blas_thread():
        run = _time_stretches(cols, tau, bounds, _augmented_limits(limits), method, dt, progress, options, geo)
    joined = _with_reason(
        _join(run.pieces, dw[bounds], dt, n + 2, method), run.pieces, run.failed, run.retimed, run.substituted, method
    )
    return _feed_law(joined, n, tau, length, np.asarray(feed_m_s, float), run, geo)


def _geometry(
    Q: np.ndarray,
    length: np.ndarray,
    tcp_frame: Callable[[np.ndarray], np.ndarray] | None,
    tolerance_m: float | None,
    path_slack_m: np.ndarray | None,
) -> StretchGeometry | None:
    """What fitting and checking the stretches need (None without forward kinematics or tolerance)."""
    if tcp_frame is None or tolerance_m is None or not tolerance_m > 0.0:
        return None
    slack = np.zeros(len(Q)) if path_slack_m is None else np.asarray(path_slack_m, dtype=float)
    return StretchGeometry(tcp_frame, tcp_frame(Q)[:, :3, 3], length, float(tolerance_m), slack)


def _one_blas_thread() -> Any:
    """A context holding BLAS to one thread: the stretches' small banded solves (the fit) run
    10-100x slower when OpenBLAS spreads them over busy cores."""
    import scipy.linalg  # noqa: F401  (loaded first, so that threadpool_limits finds its BLAS)
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1, user_api="blas")


def _augmented_limits(limits: JointLimits) -> JointLimits:
    """The joints' limits followed by those of the two pseudo-joints: the programmed time (scaled by
    :data:`FEED_TIME_SCALE`) and the path length (unbounded)."""
    return JointLimits(
        np.r_[limits.velocity, FEED_TIME_SCALE, _INDEX_LIMIT],
        np.r_[limits.acceleration, FEED_TIME_SCALE * FEED_PSEUDO_ACCEL, _INDEX_LIMIT],
        np.r_[limits.jerk, FEED_TIME_SCALE * FEED_PSEUDO_JERK, _INDEX_LIMIT],
    )


@dataclass
class _Stretches:
    """The stretches between stops, each timed (:func:`_time_stretches`).

    Attributes
    ----------
    pieces : list of Trajectory
        One per stretch, rest to rest from t = 0, on the augmented path.
    failed : tuple or None
        ``(first waypoint, last waypoint, trajectory)`` of the first stretch not ``OK``.
    retimed : int
        Stretches re-timed by :data:`FEED_RETRY_METHOD`.
    substituted : list of (int, int, str)
        Stretches timed by :data:`FEED_FALLBACK_METHOD`: first and last waypoint, the method's reason.
    """

    pieces: list[Trajectory] = field(default_factory=list)
    failed: tuple[int, int, Trajectory] | None = None
    retimed: int = 0
    substituted: list[tuple[int, int, str]] = field(default_factory=list)
    deviation_m: float = float("nan")
    n_fitted: int = 0
    n_rows_added: int = 0
    cruise: np.ndarray = field(default_factory=lambda: np.zeros(0))
    bound_joint: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    bound_kind: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))


def _time_stretches(
    cols: np.ndarray,
    tau: np.ndarray,
    bounds: np.ndarray,
    aug: JointLimits,
    method: str,
    dt: float,
    progress: Callable[[str, int, int], None] | None,
    options: dict,
    geo: StretchGeometry | None = None,
) -> _Stretches:
    """Each stretch of the augmented path ``cols`` (N, n + 2) between consecutive stops ``bounds``
    timed on its own (:func:`~problems.toolpath.feed_stretch.time_stretch_checked`), its programmed time
    counted from the stretch's start;
    with ``geo``, a cutting stretch smoothed first and its samples checked against the path."""
    run = _Stretches()
    N = len(cols)
    run.cruise, run.bound_joint, run.bound_kind = np.full(N, np.inf), np.full(N, -1), np.full(N, -1)
    stage = f"timing {method}"
    worst = 0.0
    jobs = [(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:])]
    shared = (cols, tau, aug, method, dt, options, geo)
    for i, ((a, b), (tr, how, dev, added, cruise)) in enumerate(zip(jobs, map_stretches(_one_stretch, shared, jobs))):
        if progress is not None:
            progress(stage, i, len(jobs))
        if tau[b] > tau[a]:  # a cutting stretch: rapids in the air are not held to the path tolerance
            worst = max(worst, dev)
        if cruise is not None:
            run.cruise[a + 1 : b + 1], run.bound_joint[a + 1 : b + 1], run.bound_kind[a + 1 : b + 1] = cruise
        run.n_fitted += int(geo is not None and tau[b] > tau[a])
        run.n_rows_added += added
        run.retimed += how == "retimed"
        if how.startswith("substituted"):
            run.substituted.append((a, b, how.split(":", 1)[1]))
        run.pieces.append(tr)
        if run.failed is None and tr.status is not TimingStatus.OK:
            run.failed = (a, b, tr)
    if progress is not None:
        progress(stage, len(bounds) - 1, len(bounds) - 1)
    run.deviation_m = worst if geo is not None else float("nan")
    return run


def _one_stretch(shared: tuple, job: tuple[int, int]) -> tuple[Trajectory, str, float, int, Any]:
    """Stretch ``job`` = (first, last waypoint) of the augmented path timed
    (:func:`~problems.toolpath.feed_stretch.time_stretch_checked`), its programmed time counted from
    its start and given back on its samples (a module-level function: the workers of
    :func:`~problems.toolpath.stretch_pool.map_stretches` call it)."""
    cols, tau, aug, method, dt, options, geo = shared
    a, b = job
    n = cols.shape[1] - 2
    seg = cols[a : b + 1].copy()
    seg[:, n] -= FEED_TIME_SCALE * tau[a]
    tr, how, dev, added, cruise = time_stretch_checked(
        seg, tau[a : b + 1], aug, method, dt, tau[b] - tau[a], options, geo, a
    )
    if tr.q.size:
        tr = replace(tr, q=tr.q.copy())
        tr.q[:, n] += FEED_TIME_SCALE * tau[a]
    return tr, how, dev, added, cruise


def _feed_law(
    joined: Trajectory,
    n: int,
    tau: np.ndarray,
    length: np.ndarray,
    feed: np.ndarray,
    run: _Stretches,
    geo: StretchGeometry | None = None,
) -> FeedLaw:
    """The :class:`FeedLaw` of the joined augmented trajectory: the feed rate read from the
    programmed-time pseudo-joint, the move of each sample from the path-length one, the joints alone."""
    rate = joined.qd[:, n] / FEED_TIME_SCALE if joined.qd.size else np.empty(0)
    along = joined.q[:, n + 1] / LENGTH_SCALE if joined.q.size else np.empty(0)
    joints = _joints_only(joined, n)
    n_way = len(tau)
    move = np.clip(np.searchsorted(length, along, side="left"), 1, n_way - 1) if along.size else np.zeros(0, dtype=int)
    return FeedLaw(
        trajectory=joints,
        feed_ratio=float(np.max(np.abs(rate))) if rate.size else float("nan"),
        programmed_time_s=float(tau[-1]),
        slowed=_slowed(move, rate, tau, feed),
        sample_move=move,
        n_stretches=len(run.pieces),
        n_substituted=len(run.substituted),
        path_deviation_m=run.deviation_m,
        tolerance_m=geo.tolerance_m if geo is not None else float("nan"),
        n_fitted=run.n_fitted,
        n_rows_added=run.n_rows_added,
        cruise=run.cruise,
        bound_joint=run.bound_joint,
        bound_kind=run.bound_kind,
    )


def _stops(
    n_way: int, stop: np.ndarray | None, dwell_s: np.ndarray | None, F: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The stop mask (the given stops, both ends, every change between rapid and cut or of the feed)
    and the dwells, checked (see :func:`feed_time_law`)."""
    st = np.zeros(n_way, dtype=bool) if stop is None else np.asarray(stop, dtype=bool).copy()
    dw = np.zeros(n_way) if dwell_s is None else np.asarray(dwell_s, dtype=float)
    if st.shape != (n_way,) or dw.shape != (n_way,) or np.any(~(dw >= 0.0)):
        raise InputError(f"feed law: stop and dwell_s must be ({n_way},) with dwells >= 0 s")
    st[0] = st[-1] = True
    st[1:-1] |= np.isnan(F[1:-1]) != np.isnan(F[2:])  # a change between rapid and cut: a stop
    st[1:-1] |= np.isfinite(F[1:-1]) & np.isfinite(F[2:]) & (F[1:-1] != F[2:])  # a change of feed: a stop
    return st, dw


def _with_reason(
    joined: Trajectory,
    pieces: list[Trajectory],
    failed: tuple[int, int, Trajectory] | None,
    retimed: int,
    substituted: list[tuple[int, int, str]],
    method: str,
) -> Trajectory:
    """The joined trajectory with the status of its first failed stretch, or a reason that counts the
    stretches, the re-timed ones and those the fallback timed."""
    if failed is not None:
        a, b, tr = failed
        return replace(
            joined,
            status=tr.status,
            reason=f"the stretch from waypoint {a} to {b} (of {len(pieces)} between stops): {tr.reason}",
            solver_code=tr.solver_code,
        )
    if len(pieces) <= 1 and not substituted:
        return joined
    notes = ""
    if retimed:
        notes += (
            f"; {retimed} re-timed by {FEED_RETRY_METHOD} where {method} ran a cutting stretch above "
            f"{FEED_RETRY_RATIO:g}x its programmed time"
        )
    if substituted:
        a, b, why = substituted[0]
        notes += (
            f"; {len(substituted)} timed by {FEED_FALLBACK_METHOD} where {method} failed (the first, waypoints "
            f"{a} to {b}: {why})"
        )
    return replace(joined, reason=f"{len(pieces)} stretches between stops{notes}; the first: {pieces[0].reason}")


def _joints_only(tr: Trajectory, n: int) -> Trajectory:
    """The trajectory's first ``n`` columns and ratios: the joints, without the pseudo-joints."""
    return replace(
        tr,
        q=tr.q[:, :n],
        qd=tr.qd[:, :n],
        qdd=tr.qdd[:, :n],
        qddd=tr.qddd[:, :n],
        limit_ratio={k: v[:n] for k, v in tr.limit_ratio.items()},
        first_pass_limit_ratio={k: v[:n] for k, v in tr.first_pass_limit_ratio.items()},
    )


def _join(pieces: list[Trajectory], dwell: np.ndarray, dt: float, width: int, method: str) -> Trajectory:
    """One trajectory from rest-to-rest pieces (each starting at t = 0), with the dwells held."""
    if len(pieces) == 1 and dwell[0] == 0.0 and dwell[-1] == 0.0:
        return pieces[0]
    t, q, qd, qdd, qddd = [], [], [], [], []
    t_end = 0.0
    last = None

    def hold(at: np.ndarray, seconds: float) -> None:
        nonlocal t_end
        m = int(round(seconds / dt))
        if m <= 0:
            return
        t.append(t_end + dt * np.arange(1, m + 1))
        q.append(np.repeat(at[None, :], m, axis=0))
        z = np.zeros((m, width))
        qd.append(z)
        qdd.append(z)
        qddd.append(z)
        t_end += m * dt

    for i, tr in enumerate(pieces):
        if not tr.q.size:
            continue
        skip = 0 if last is None else 1  # the piece's first sample is the previous one's last
        if last is None:
            t.append(tr.t[:1])
            q.append(tr.q[:1])
            qd.append(tr.qd[:1])
            qdd.append(tr.qdd[:1])
            qddd.append(tr.qddd[:1])
            hold(tr.q[0], float(dwell[0]))
            skip = 1
        t.append(t_end + tr.t[skip:])
        q.append(tr.q[skip:])
        qd.append(tr.qd[skip:])
        qdd.append(tr.qdd[skip:])
        qddd.append(tr.qddd[skip:])
        t_end += float(tr.t[-1])
        last = tr.q[-1]
        hold(last, float(dwell[i + 1]))
    # the keys in the order the pieces name them (a set's order changes between runs: summary.json must not)
    keys = list(dict.fromkeys(k for tr in pieces for k in tr.limit_ratio))
    ratio = {k: np.nanmax(np.vstack([tr.limit_ratio[k] for tr in pieces if k in tr.limit_ratio]), axis=0) for k in keys}
    first = {
        k: np.nanmax(
            np.vstack([tr.first_pass_limit_ratio[k] for tr in pieces if k in tr.first_pass_limit_ratio]), axis=0
        )
        for k in dict.fromkeys(k for tr in pieces for k in tr.first_pass_limit_ratio)
    }
    T = np.concatenate(t) if t else np.zeros(0)
    # uniform at dt from 0: the pieces end at multiples of dt, so the sum is one up to rounding
    T = dt * np.round(T / dt)
    return Trajectory(
        method=method,
        status=TimingStatus.OK,
        reason=pieces[0].reason,
        t=T,
        q=np.vstack(q) if q else np.zeros((0, width)),
        qd=np.vstack(qd) if qd else np.zeros((0, width)),
        qdd=np.vstack(qdd) if qdd else np.zeros((0, width)),
        qddd=np.vstack(qddd) if qddd else np.zeros((0, width)),
        duration_s=float(T[-1]) if T.size else float("nan"),
        limit_ratio=ratio,
        dt=dt,
        iterations=sum(tr.iterations for tr in pieces),
        first_pass_limit_ratio=first,
    )


def _slowed(move: np.ndarray, rate: np.ndarray, tau: np.ndarray, feed: np.ndarray) -> dict[int, float]:
    """Waypoint -> peak ``d tau / dt`` on the cutting move ending there, where it stays below
    ``1 - FEED_SLOW_TOL`` (``move``: the move each sample is on)."""
    if not rate.size:
        return {}
    peak = np.zeros(len(tau))
    np.maximum.at(peak, move, np.abs(rate))
    cutting = ~np.isnan(feed) & (np.r_[0.0, np.diff(tau)] > 0.0)
    cutting[0] = False
    seen = np.zeros(len(tau), dtype=bool)
    seen[np.unique(move)] = True
    return {int(k): float(peak[k]) for k in np.flatnonzero(cutting & seen & (peak < 1.0 - FEED_SLOW_TOL))}
