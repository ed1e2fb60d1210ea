"""A cutting stretch's joint path fitted within the path tolerance: smoothed where there is room,
held to the programmed path where there is not, checked between the waypoints.

The timing methods follow the natural cubic spline through a stretch's rows
(:class:`problems.timing.path.SplinePath`). :func:`fit_stretch` makes the rows whose spline keeps
the TCP within the tolerance of the programmed path *between* the waypoints too, not only at them:

1. the joint waypoints are smoothed within :data:`FIT_SMOOTH_SHARE` of the tolerance
   (:func:`problems.toolpath.smoothing.smooth_stretch`);
2. the spline through the rows is evaluated at :data:`FIT_POINTS_PER_INTERVAL` points inside every
   interval and each point's TCP (forward kinematics) measured against the interval's programmed
   chord (the straight move between the two waypoints' TCP);
3. where an interval leaves :data:`FIT_CHECK_SHARE` of the tolerance, its two waypoints are pinned
   (weight :data:`FIT_PIN_WEIGHT` in the smoothing) and the stretch smoothed again; an interval
   that leaves it with both ends pinned gets a row at its middle (joints, programmed time and
   length interpolated linearly: on a move a fraction of a millimetre long, the joint-space line's
   TCP is on the chord to well under a micrometre), which holds the spline to the chord.

At most :data:`FIT_ROUNDS` rounds; the result's deviation is measured and returned, so a stretch
that still leaves the tolerance is reported, not hidden (``problems.toolpath.feed``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from problems.toolpath.smoothing import smooth_stretch_lam

__all__ = ["FIT_CHECK_SHARE", "fit_stretch", "segment_distance"]

#: Share of the path tolerance the smoothing may move a waypoint (TCP and tool axis).
FIT_SMOOTH_SHARE: float = 0.5
#: Share of the tolerance an interval's checked points must stay within (the rest is the room of
#: the sampled trajectory between the checked points).
FIT_CHECK_SHARE: float = 0.9
#: Points checked inside each interval of the spline, and inside an interval whose points come
#: above FIT_REFINE_AT of the limit (the spline can bend between the coarse points beside a
#: very short interval).
FIT_POINTS_PER_INTERVAL: int = 7
FIT_POINTS_REFINED: int = 63
FIT_REFINE_AT: float = 0.5
#: Weight of a pinned waypoint in the smoothing (the others weigh 1).
FIT_PIN_WEIGHT: float = 1e8
#: Rounds of pinning and splitting.
FIT_ROUNDS: int = 12


def segment_distance(x: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance (m) of points ``x`` (M, 3) from the segments ``a``-``b`` (M, 3 each)."""
    ab = b - a
    L2 = np.einsum("ij,ij->i", ab, ab)
    t = np.clip(np.einsum("ij,ij->i", x - a, ab) / np.where(L2 > 0.0, L2, 1.0), 0.0, 1.0)
    return np.linalg.norm(x - (a + t[:, None] * ab), axis=1)


def _interval_deviation(
    rows: np.ndarray,
    n: int,
    tcp_frame: Callable[[np.ndarray], np.ndarray],
    chord: np.ndarray,
    chord_limit: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Per interval of the spline through ``rows`` (m, n + 2), the largest distance (m) of its
    checked points' TCP from the interval's chord (``chord``: the rows' programmed TCP, (m, 3)),
    and the length (m) of the TCP's polyline through the interval's ends and checked points. With
    ``chord_limit`` (m), an interval whose points come above :data:`FIT_REFINE_AT` of it is checked
    again at :data:`FIT_POINTS_REFINED` points."""
    from problems.timing.path import SplinePath

    path = SplinePath(rows)
    k = path.knots
    f = np.arange(1, FIT_POINTS_PER_INTERVAL + 1) / (FIT_POINTS_PER_INTERVAL + 1)
    s = (k[:-1, None] + np.diff(k)[:, None] * f[None, :]).ravel()
    pos = tcp_frame(path.spline(s)[:, :n])[:, :3, 3]
    i = np.repeat(np.arange(len(k) - 1), len(f))
    d = segment_distance(pos, chord[i], chord[i + 1])
    ends = tcp_frame(rows[:, :n])[:, :3, 3]
    pts = np.concatenate([ends[:-1, None], pos.reshape(len(k) - 1, len(f), 3), ends[1:, None]], axis=1)
    length = np.linalg.norm(np.diff(pts, axis=1), axis=2).sum(axis=1)
    dev = d.reshape(len(k) - 1, len(f)).max(axis=1)
    # where the coarse points come near the tolerance, the spline is checked again more finely
    close = np.flatnonzero(dev > FIT_REFINE_AT * chord_limit) if chord_limit is not None else np.zeros(0, int)
    if close.size:
        g = np.arange(1, FIT_POINTS_REFINED + 1) / (FIT_POINTS_REFINED + 1)
        s2 = (k[close, None] + np.diff(k)[close, None] * g[None, :]).ravel()
        pos2 = tcp_frame(path.spline(s2)[:, :n])[:, :3, 3]
        i2 = np.repeat(close, len(g))
        d2 = segment_distance(pos2, chord[i2], chord[i2 + 1]).reshape(len(close), len(g)).max(axis=1)
        dev[close] = np.maximum(dev[close], d2)
    return dev, length


class _FitState:
    """The rows of a fit and what goes with each: the joints to smooth (``q0``), their programmed
    TCP (``chord``), time, weight, slack and, for the original rows, their index (``kept``)."""

    def __init__(
        self, rows: np.ndarray, n: int, tcp_frame: Callable[[np.ndarray], np.ndarray], tau: np.ndarray, slack_m: Any
    ):
        self.rows = rows
        self.q0 = rows[:, :n].copy()
        self.chord = tcp_frame(self.q0)[:, :3, 3]
        self.tau = tau
        self.weight = np.ones(len(rows))
        self.kept = np.arange(len(rows))
        self.slack = np.zeros(len(rows)) if slack_m is None else np.asarray(slack_m, dtype=float).copy()

    def pin_or_split(self, bad: np.ndarray) -> None:
        """Pin the ends of the ``bad`` intervals; split those whose ends were pinned already."""
        ends = np.zeros(len(self.rows), dtype=bool)
        ends[:-1] |= bad
        ends[1:] |= bad
        pinned = self.weight >= FIT_PIN_WEIGHT
        split = bad & pinned[:-1] & pinned[1:]
        self.weight[ends] = FIT_PIN_WEIGHT
        if not split.any():
            return
        at = np.flatnonzero(split)

        def mid(a: np.ndarray) -> np.ndarray:
            return np.insert(a, at + 1, 0.5 * (a[at] + a[at + 1]), axis=0)

        self.rows, self.q0, self.chord, self.tau = mid(self.rows), mid(self.q0), mid(self.chord), mid(self.tau)
        self.weight = np.insert(self.weight, at + 1, FIT_PIN_WEIGHT)
        self.slack = np.insert(self.slack, at + 1, self.slack[at + 1])
        self.kept = self.kept + np.searchsorted(at, self.kept, side="left")  # rows inserted before each kept row


def fit_stretch(
    rows: np.ndarray,
    n: int,
    tau: np.ndarray,
    tcp_frame: Callable[[np.ndarray], np.ndarray],
    tolerance_m: float,
    slack_m: np.ndarray | None = None,
    time_column: int | None = None,
) -> tuple[np.ndarray, float, np.ndarray]:
    """The stretch's rows fitted within the tolerance (see the module docstring).

    Parameters
    ----------
    rows : np.ndarray
        Shape ``(m, n + k)``: the joints (rad, first ``n`` columns) and the pseudo-joints the
        timing follows (interpolated linearly where a row is added).
    n : int
        Number of joints.
    tau : np.ndarray
        Shape ``(m,)``, s: programmed time of each row, strictly increasing.
    tcp_frame : callable
        ``tcp_frame(q (M, n)) -> (M, 4, 4)``: the TCP frame by forward kinematics.
    tolerance_m : float
        The path tolerance, m.
    slack_m : np.ndarray, optional
        Shape ``(m,)``, m: how far the chord of the move ending at each row may lie from the
        programmed path (an arc's chords: their sagitta bound); the interval's limit is that much
        tighter (default 0).
    time_column : int, optional
        The column of the (scaled) programmed time: its step over each interval is scaled by the
        fitted TCP path's length there over the chord's, so that a bound on its rate bounds the
        TCP's speed along the fitted path (the smoothing moves waypoints along the path too).

    Returns
    -------
    rows : np.ndarray
        Shape ``(m', n + k)``, ``m' >= m``: the fitted rows (the original rows' order kept).
    deviation_m : float
        The largest distance of a checked point from its chord plus the chord's slack, m.
    kept : np.ndarray
        Shape ``(m,)``, int: the index in ``rows`` of each original row.
    """
    st = _FitState(rows, n, tcp_frame, np.asarray(tau, dtype=float), slack_m)
    dev = np.zeros(0)
    fitted, fitted_kept, fitted_slack = rows, st.kept, st.slack
    limit = FIT_CHECK_SHARE * tolerance_m
    hint = None
    for _ in range(FIT_ROUNDS):
        fitted = st.rows.copy()
        fitted[:, :n], hint = smooth_stretch_lam(
            st.tau, st.q0, tcp_frame, FIT_SMOOTH_SHARE * tolerance_m, st.weight, hint
        )
        if time_column is not None:
            # the programmed time over each interval scaled by the TCP's path length there over the
            # chord's (the smoothing moves waypoints along the path too): a bound on its rate is then
            # a bound on the TCP's speed; the spline's parameter follows it, so the check comes after
            _, run = _interval_deviation(fitted, n, tcp_frame, st.chord)
            ratio = run / np.maximum(np.linalg.norm(np.diff(st.chord, axis=0), axis=1), 1e-300)
            step = np.diff(fitted[:, time_column]) * ratio
            fitted[:, time_column] = fitted[0, time_column] + np.r_[0.0, np.cumsum(step)]
        dev, _ = _interval_deviation(fitted, n, tcp_frame, st.chord, limit)
        fitted_kept, fitted_slack = st.kept.copy(), st.slack.copy()
        bad = dev + st.slack[1:] > limit
        if not bad.any():
            break
        st.pin_or_split(bad)
    return fitted, float((dev + fitted_slack[1:]).max()) if dev.size else 0.0, fitted_kept
