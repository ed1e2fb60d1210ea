"""A program's waypoints: moves split into short steps, corners kept within the path tolerance, and
the points where the arm must be at rest.

The waypoints are what the rest of the product plans: IK and posture at each, compensation at
each, and one timed joint path through them. The joint path between waypoints is a cubic spline
(:mod:`problems.timing.path`), so it rounds a corner of the programmed polyline and bows on a long
straight move. Both effects are kept within the **path tolerance** ``tol`` (the program's ``G64 P``,
or :data:`DEFAULT_PATH_TOLERANCE_M`):

* every move is split into equal steps no longer than :data:`MAX_STEP_M` (arcs are already chords
  within ``tol``, :func:`problems.toolpath.program.discretise`);
* at a programmed corner of deflection ``theta`` (the angle between the two moves' directions), the
  spline's rounding is at most about ``CORNER_DEVIATION_FACTOR * d * theta`` for neighbouring
  waypoints at distance ``d`` (the farther of the two). The corner waypoint is kept exactly; where that bound exceeds
  ``tol`` waypoints are added on both moves at ``a = tol / (CORNER_DEVIATION_FACTOR * theta)`` from
  the corner and at ``2a, 4a, ...`` (a blend within ``tol``);
* where ``a`` would be below :data:`CORNER_MIN_APPROACH_M` (a sharp corner at a small tolerance)
  the corner is an **exact stop**: the arm comes to rest there, as under G61.

The arm is also at rest (a **stop**) at the first and last waypoint, at every change between rapid
and cutting moves and of the feed (the next move runs at its own feed from its first sample), at a
dwell (G4, with its time), at M0/M1/M60, and at every move's end while G61 (exact stop) is in
force. The timed path is one segment per stretch between stops
(:func:`problems.toolpath.feed.feed_time_law`).

The distances between the sampled trajectory and the programmed path are measured after planning
and reported (``docs/gcode.md``, "Path tolerance").
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from models.errors import InputError

from .cl_csv import ClPath
from .program import EventKind, Program, discretise_moves
from .spindle import SpindleTrack, spindle_track

__all__ = [
    "CORNER_MIN_APPROACH_M",
    "DEFAULT_PATH_TOLERANCE_M",
    "MAX_STEP_M",
    "ProgramWaypoints",
    "cl_waypoints",
    "program_waypoints",
]

#: Path tolerance when the program gives no ``G64 P`` (or ``P0``), m: 0.01 mm.
DEFAULT_PATH_TOLERANCE_M = 1e-5
#: Longest step between waypoints on a move, m.
MAX_STEP_M = 2e-3
#: The spline's rounding at a corner of deflection theta with neighbours at distance d is taken as at
#: most ``CORNER_DEVIATION_FACTOR * d * theta`` (a cubic through the corner and its neighbours; the
#: measured rounding is below this, ``tests/test_program_path.py``).
CORNER_DEVIATION_FACTOR = 0.25
#: A corner needing waypoints closer than this to keep its rounding within the tolerance is an exact
#: stop instead, m.
CORNER_MIN_APPROACH_M = 2e-4
#: Directions closer than this (rad) are not a corner.
CORNER_ANGLE_MIN_RAD = 1e-6
#: Arcs are split into chords whose sagitta is at most this share of the path tolerance: the chords
#: then stand for the arc within it, and a trajectory within the rest of the tolerance of them is
#: within the tolerance of the arc (``problems.toolpath.stretch_fit``).
ARC_SAGITTA_SHARE = 0.25


@dataclass(frozen=True)
class ProgramWaypoints:
    """A program's waypoints in the program frame, with what the timing and the outputs need.

    Attributes
    ----------
    points_m : np.ndarray
        Shape ``(N, 3)``, m, program frame: tool-tip waypoints.
    tool_axis : np.ndarray or None
        Shape ``(N, 3)``, program frame, unit vectors from the tip towards the spindle (CL data);
        None: the program's +Z everywhere.
    line : np.ndarray
        Shape ``(N,)``, int: the program line of the move ending at each waypoint.
    rapid : np.ndarray
        Shape ``(N,)``, bool: the move ending at the waypoint is a rapid.
    feed_m_s : np.ndarray
        Shape ``(N,)``, m/s: the programmed feed of that move; NaN for rapids and waypoint 0.
    stop : np.ndarray
        Shape ``(N,)``, bool: the arm is at rest at the waypoint.
    dwell_s : np.ndarray
        Shape ``(N,)``, s: time held at rest at the waypoint (G4).
    corner : np.ndarray
        Shape ``(N,)``, bool: the waypoint is a programmed corner (end of a move followed by a move
        in another direction, or a move's end at a stop).
    wrench : np.ndarray or None
        Shape ``(N, 6)``, N and N·m, TCP frame: the CL file's per-point wrench, or None.
    tolerance_m : float
        The path tolerance used, m.
    tolerance_source : str
        Where it came from (``"G64 P"``, ``"problem file"``, ``"default"``).
    source : str
        The program file.
    arc_chord : np.ndarray or None
        Shape ``(N,)``, bool: the move ending at the waypoint is (part of) an arc's chord, which lies
        within :data:`ARC_SAGITTA_SHARE` of the tolerance from the arc; None: no arcs.
    move : np.ndarray or None
        Shape ``(N,)``, int: the index in the program's moves of the move ending at the waypoint
        (waypoint 0: -1); None for CL data.
    spindle : SpindleTrack or None
        The spindle's speed and turning at every move of the program
        (:func:`problems.toolpath.spindle.spindle_track`); None for CL data.
    """

    points_m: np.ndarray
    tool_axis: np.ndarray | None
    line: np.ndarray
    rapid: np.ndarray
    feed_m_s: np.ndarray
    stop: np.ndarray
    dwell_s: np.ndarray
    corner: np.ndarray
    wrench: np.ndarray | None
    tolerance_m: float
    tolerance_source: str
    source: str
    arc_chord: np.ndarray | None = None
    move: np.ndarray | None = None
    spindle: SpindleTrack | None = None

    @property
    def n(self) -> int:
        """Number of waypoints N."""
        return len(self.points_m)

    def segments(self) -> list[tuple[int, int]]:
        """``(first, last)`` waypoint of each stretch between stops (both included)."""
        idx = np.flatnonzero(self.stop)
        return [(int(a), int(b)) for a, b in zip(idx[:-1], idx[1:]) if b > a]


def _split(P: np.ndarray, max_step: float) -> np.ndarray:
    """How many equal steps each move ``P[k-1] -> P[k]`` is split into (>= 1); shape ``(N-1,)``."""
    step = np.linalg.norm(np.diff(P, axis=0), axis=1)
    return np.maximum(1, np.ceil(step / max_step - 1e-9)).astype(int)


def _deflection(P: np.ndarray) -> np.ndarray:
    """Angle between consecutive moves at each interior waypoint, rad; shape ``(N,)`` (0 at the ends)."""
    d = np.diff(P, axis=0)
    n = np.linalg.norm(d, axis=1)
    u = d / np.where(n > 0, n, 1.0)[:, None]
    cos = np.clip(np.einsum("ij,ij->i", u[:-1], u[1:]), -1.0, 1.0)
    return np.r_[0.0, np.arccos(cos), 0.0]


def corner_waypoints(theta: float, d_in: float, d_out: float, tol: float) -> tuple[np.ndarray, np.ndarray] | None:
    """Distances from a corner at which waypoints are added on the incoming and outgoing moves.

    Returns ``(before, after)`` (m, increasing; empty when the spline's rounding stays within
    ``tol`` without them), or None when the corner must be an exact stop.
    """
    # the longer neighbour drives the rounding (a tiny move beside a corner does not make it small)
    if theta < CORNER_ANGLE_MIN_RAD or CORNER_DEVIATION_FACTOR * max(d_in, d_out) * theta <= tol:
        return np.zeros(0), np.zeros(0)
    a = tol / (CORNER_DEVIATION_FACTOR * theta)
    if a < CORNER_MIN_APPROACH_M:
        return None
    out = []
    for d in (d_in, d_out):
        pts = []
        x = a
        while x < 0.5 * d:
            pts.append(x)
            x *= 2.0
        out.append(np.asarray(pts))
    return out[0], out[1]


def program_waypoints(program: Program, tol_m: float | None = None, tol_source: str = "") -> ProgramWaypoints:
    """The waypoints of a G-code program (see the module docstring).

    Parameters
    ----------
    program : Program
        As read by :func:`problems.toolpath.gcode.read_gcode`.
    tol_m : float, optional
        The path tolerance, m; None: the program's smallest ``G64 P`` (> 0), else
        :data:`DEFAULT_PATH_TOLERANCE_M`.
    tol_source : str
        Where ``tol_m`` came from (recorded).

    Raises
    ------
    InputError
        A program without moves, or a tolerance that is not > 0.
    """
    if tol_m is None:
        p = program.path_tolerance_m
        tol_m, tol_source = (p, "G64 P") if p else (DEFAULT_PATH_TOLERANCE_M, "default")
    if not (tol_m > 0.0 and math.isfinite(tol_m)):
        raise InputError(f"{program.source}: the path tolerance must be > 0 m, got {tol_m!r}")
    P, line, rapid, feed, move = discretise_moves(program, ARC_SAGITTA_SHARE * tol_m)
    if len(P) < 2:
        raise InputError(f"{program.source}: the program has no move with a known start point; nothing to plan")
    stop_m, dwell_m = _stops(program, program.n_moves)
    ends = np.r_[False, move[2:] != move[1:-1], True]  # the point ends its move
    done = np.where(ends, move + 1, 0)  # moves done at the point
    stop = ends & stop_m[done]
    dwell = np.where(ends, dwell_m[done], 0.0)
    dwell[0] = dwell_m[0]
    stop[0] |= dwell_m[0] > 0
    # an arc's chords turn by its sweep over their count; at the arc's ends the chord is that over 2
    # off the tangent, which is not a corner of the program: relieve the deflection by it
    count = np.bincount(move[1:], minlength=program.n_moves)
    sweep = np.fromiter(
        (abs(m.sweep_rad) if m.kind.value == "arc" else 0.0 for m in program.moves), float, program.n_moves
    )
    half = 0.5 * sweep / np.maximum(count, 1)
    relief = np.zeros(len(P))
    k = np.flatnonzero(ends[1:-1]) + 1
    relief[k] = half[move[k]] + half[move[k + 1]]
    is_arc = np.fromiter((m.kind.value == "arc" for m in program.moves), bool, program.n_moves)
    arc = np.r_[False, is_arc[move[1:]]]
    way = _refine(
        P,
        None,
        line,
        rapid,
        feed,
        stop,
        dwell,
        ends,
        None,
        tol_m,
        tol_source,
        program.source,
        relief,
        arc if arc.any() else None,
        move,
    )
    return replace(way, spindle=spindle_track(program))


def cl_waypoints(cl: ClPath, tol_m: float, tol_source: str = "") -> ProgramWaypoints:
    """The waypoints of CL data (:class:`problems.toolpath.cl_csv.ClPath`): every row a corner
    candidate, moves split and corners kept as for a program; no dwells.

    Raises
    ------
    InputError
        Fewer than two rows, a tolerance that is not > 0, or cutting rows without a feed.
    """
    if not (tol_m > 0.0 and math.isfinite(tol_m)):
        raise InputError(f"{cl.source}: the path tolerance must be > 0 m, got {tol_m!r}")
    if cl.n < 2:
        raise InputError(f"{cl.source}: {cl.n} point(s); a toolpath needs at least 2")
    if cl.feed_m_s is None:
        feed = np.full(cl.n, math.nan)
    else:
        feed = np.where(cl.rapid, math.nan, cl.feed_m_s)
    feed[0] = math.nan
    rapid = cl.rapid.copy()
    rapid[0] = True
    if cl.feed_m_s is None and not rapid[1:].all():
        raise InputError(
            f"{cl.source}: no feed column (feed_mm_min or feed_m_s) but line {int(cl.line[1 + np.argmin(rapid[1:])])} "
            "is a cutting move; give the feed of every cutting row"
        )
    n = cl.n
    return _refine(
        cl.points_m,
        cl.tool_axis,
        cl.line,
        rapid,
        feed,
        np.zeros(n, dtype=bool),
        np.zeros(n),
        np.ones(n, dtype=bool),
        cl.wrench,
        tol_m,
        tol_source,
        cl.source,
    )


def _stops(program: Program, n_moves: int) -> tuple[np.ndarray, np.ndarray]:
    """Per count of moves done (0..n_moves): a stop there, and the dwell there (s)."""
    stop = np.zeros(n_moves + 1, dtype=bool)
    dwell = np.zeros(n_moves + 1)
    exact = False
    events = sorted(program.events, key=lambda e: e.after_move)
    ei = 0
    for k in range(n_moves + 1):
        while ei < len(events) and events[ei].after_move <= k:
            e = events[ei]
            if e.kind is EventKind.DWELL:
                stop[k] = True
                dwell[k] += float(e.value or 0.0)
            elif e.kind in (EventKind.PROGRAM_STOP, EventKind.PROGRAM_END):
                stop[k] = True
            elif e.kind is EventKind.EXACT_STOP:
                exact = True
            elif e.kind is EventKind.BLENDING:
                exact = False
            ei += 1
        if exact:
            stop[k] = True
    return stop, dwell


def _refine(
    P: np.ndarray,
    axis: np.ndarray | None,
    line: np.ndarray,
    rapid: np.ndarray,
    feed: np.ndarray,
    stop: np.ndarray,
    dwell: np.ndarray,
    corner: np.ndarray,
    wrench: np.ndarray | None,
    tol: float,
    tol_source: str,
    source: str,
    relief: np.ndarray | None = None,
    arc: np.ndarray | None = None,
    move: np.ndarray | None = None,
) -> ProgramWaypoints:
    """Stops at the ends and at rapid/cut changes, corners blended or stopped, moves split.

    ``corner``: the points that may be corners (move ends); ``relief`` (rad, per point): deflection
    that is not a corner (an arc chord's angle to its tangent at the arc's ends)."""
    n = len(P)
    stop = stop.copy()
    stop[0] = stop[-1] = True
    change = np.r_[False, rapid[1:-1] != rapid[2:], False]  # the move after k is of another kind
    refeed = np.r_[False, np.isfinite(feed[1:-1]) & np.isfinite(feed[2:]) & (feed[1:-1] != feed[2:]), False]
    stop |= change | refeed
    theta = _deflection(P)
    if relief is not None:
        theta = np.maximum(0.0, theta - relief)
    length = np.r_[0.0, np.linalg.norm(np.diff(P, axis=0), axis=1)]
    cand = corner & (theta > CORNER_ANGLE_MIN_RAD)
    corner = cand | stop
    before = [np.zeros(0)] * n
    after = [np.zeros(0)] * n
    for k in np.flatnonzero(cand & ~stop):
        got = corner_waypoints(float(theta[k]), float(length[k]), float(length[k + 1]), tol)
        if got is None:
            stop[k] = True
            corner[k] = True
        else:
            before[k], after[k] = got
    idx, frac = _split_moves(length, before, after)
    end = frac == 1.0  # a programmed point (the others split a move)
    prev = P[np.maximum(idx - 1, 0)]
    points = np.where(end[:, None], P[idx], prev + frac[:, None] * (P[idx] - prev))
    tool = None
    if axis is not None:
        a0 = axis[np.maximum(idx - 1, 0)]
        mid = a0 + frac[:, None] * (axis[idx] - a0)
        tool = np.where(end[:, None], axis[idx], mid / np.linalg.norm(mid, axis=1, keepdims=True))
    return ProgramWaypoints(
        points,
        tool,
        line[idx],
        rapid[idx],
        feed[idx],
        end & stop[idx],
        np.where(end, dwell[idx], 0.0),
        end & corner[idx],
        wrench[idx] if wrench is not None else None,
        float(tol),
        tol_source,
        source,
        arc[idx] if arc is not None else None,
        move[idx] if move is not None else None,
    )


def _split_moves(
    length: np.ndarray, before: list[np.ndarray], after: list[np.ndarray]
) -> tuple[np.ndarray, np.ndarray]:
    """The rows of the split path: for each, the programmed point ``k`` whose move (``k-1 -> k``) it
    lies on and its fraction along that move (1 at the point itself; point 0 first). A move is split
    into equal steps of at most :data:`MAX_STEP_M` and at the corner waypoints ``after[k-1]`` (from
    its start) and ``before[k]`` (from its end), m."""
    idx, frac = [np.zeros(1, dtype=int)], [np.ones(1)]
    for k in range(1, len(length)):
        d = length[k]
        near = np.r_[after[k - 1], d - before[k][::-1]] / d if d > 0 else np.zeros(0)
        m = max(1, int(math.ceil(d / MAX_STEP_M - 1e-9)))
        fr = np.unique(np.r_[np.arange(1, m) / m, near])
        fr = fr[(fr > 1e-12) & (fr < 1 - 1e-12)]
        idx.append(np.full(fr.size + 1, k))
        frac.append(np.r_[fr, 1.0])
    return np.concatenate(idx), np.concatenate(frac)
