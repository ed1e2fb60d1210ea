"""What a G-code program is once read: moves, events and recorded words, and its points.

SI, program frame: positions in m in the program's own X, Y, Z; feeds in m/s. Made by
:func:`problems.toolpath.gcode.parse_gcode`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from models.errors import InputError

from .arcs import ArcGeometry, Plane, arc_points

__all__ = [
    "Direction",
    "Event",
    "EventKind",
    "Move",
    "MoveKind",
    "Program",
    "RecordedWord",
    "discretise",
    "discretise_moves",
]


class MoveKind(Enum):
    """What a move is: a rapid (G0), a straight feed move (G1) or an arc (G2/G3)."""

    RAPID = "rapid"
    LINEAR = "linear"
    ARC = "arc"


class Direction(Enum):
    """Turning sense of an arc, seen from the positive end of its plane's normal."""

    CW = "cw"
    CCW = "ccw"


class EventKind(Enum):
    """Something between moves: a dwell (a stop), a path-control mode change, a stop or the end."""

    DWELL = "dwell"  # value: seconds
    EXACT_STOP = "exact_stop"  # G61 / G61.1: stop at every corner from here on
    BLENDING = "blending"  # G64: blend corners; value: P tolerance (m) or None
    PROGRAM_STOP = "program_stop"  # M0 / M1 / M60
    PROGRAM_END = "program_end"  # M2 / M30: lines after it are not read


@dataclass(frozen=True, slots=True)
class Move:
    """One programmed move, in the program frame.

    Attributes
    ----------
    kind : MoveKind
        Rapid, linear or arc.
    start, end : tuple of float
        (x, y, z), m: where the move starts and ends.
    feed_m_s : float or None
        Programmed feed (G94: the tool tip's speed along the path), m/s; None for a rapid.
    line : int
        1-based line of the file the move comes from.
    text : str
        That line as written (without the newline).
    centre : tuple of float or None
        Arcs: the centre (x, y, z), m; its normal coordinate is the start's.
    plane : Plane or None
        Arcs: G17 XY, G18 ZX or G19 YZ.
    direction : Direction or None
        Arcs: G2 clockwise, G3 counter-clockwise.
    turns : int
        Arcs: P, the number of turns started (1 unless P was given); 0 for straight moves.
    sweep_rad : float
        Arcs: signed swept angle, rad (positive counter-clockwise; ±2π for one full circle).
    radius_m : float
        Arcs: radius at the start, m (the end's may differ within the spiral tolerance).
    helical_m : float
        Arcs: travel along the plane's normal, m (0 for a plane arc).
    cycle : str or None
        ``"G81"``, ``"G82"`` or ``"G83"`` when the move is part of an expanded drilling cycle.
    """

    kind: MoveKind
    start: tuple[float, float, float]
    end: tuple[float, float, float]
    feed_m_s: float | None
    line: int
    text: str
    centre: tuple[float, float, float] | None = None
    plane: Plane | None = None
    direction: Direction | None = None
    turns: int = 0
    sweep_rad: float = 0.0
    radius_m: float = 0.0
    helical_m: float = 0.0
    cycle: str | None = None

    @property
    def length_m(self) -> float:
        """Length of the move along its path, m (an arc's: its helix, the plane's radius taken as the
        mean of the start's and the end's)."""
        if self.kind is not MoveKind.ARC:
            return math.dist(self.start, self.end)
        g = self.arc()
        return math.hypot(0.5 * (g.r0 + g.r1) * abs(self.sweep_rad), self.helical_m)

    def arc(self) -> ArcGeometry:
        """The arc in its plane's coordinates (arcs only)."""
        if self.kind is not MoveKind.ARC or self.plane is None or self.centre is None:
            raise ValueError("not an arc")
        ia, ib, _ = self.plane.axes
        c = (self.centre[ia], self.centre[ib])
        r1 = math.hypot(self.end[ia] - c[0], self.end[ib] - c[1])
        t0 = math.atan2(self.start[ib] - c[1], self.start[ia] - c[0])
        return ArcGeometry(c, self.radius_m, r1, t0, self.sweep_rad)


@dataclass(frozen=True, slots=True)
class Event:
    """A dwell, path-control change, stop or end, placed between moves.

    Attributes
    ----------
    kind : EventKind
        What it is.
    line : int
        1-based line.
    text : str
        The line as written.
    after_move : int
        Number of moves before it (it happens after ``moves[after_move - 1]``).
    value : float or None
        Dwell: seconds; blending: the G64 P tolerance in m (None without P); else None.
    """

    kind: EventKind
    line: int
    text: str
    after_move: int
    value: float | None = None


@dataclass(frozen=True, slots=True)
class RecordedWord:
    """An M, S, T, H or D word, recorded but not acted on.

    Attributes
    ----------
    word : str
        As written, upper-case (``"M3"``, ``"S12000"``, ``"T4"``, ``"H4"``).
    value : float
        The number (S: rev/min; others: the code or number).
    line : int
        1-based line.
    after_move : int
        Number of moves before it.
    """

    word: str
    value: float
    line: int
    after_move: int


@dataclass(frozen=True)
class Program:
    """A G-code program read into moves.

    Attributes
    ----------
    source : str
        The file name (or the ``name`` given to :func:`parse_gcode`).
    moves : tuple of Move
        The moves in program order; zero-length moves are left out.
    start_m : tuple of float or None
        (x, y, z), m: where the first move starts — the first point where X, Y and Z are all
        known (rapids before it only position the axes they name); None without moves.
    start_line : int
        The line that made ``start_m`` known (0 if none).
    events : tuple of Event
        Dwells, G61/G64 changes, M0/M1/M60 stops, the M2/M30 end.
    words : tuple of RecordedWord
        M, S, T, H, D words.
    units : str
        ``"mm"``, ``"inch"`` or ``"mm and inch"`` (which of G21/G20 the program used).
    units_note : str
        ``"no G20/G21: millimetres"`` when the program gives neither, else empty.
    path_tolerance_m : float or None
        The smallest G64 P tolerance the program gives, m; None when it gives none.
    work_offset : str or None
        The work offset the program selects (``"G54"``...), None if none; it stands for the
        ``[workpiece]`` frame.
    end_line : int
        The M2/M30 line (0 if the program has none).
    """

    source: str
    moves: tuple[Move, ...]
    start_m: tuple[float, float, float] | None
    start_line: int
    events: tuple[Event, ...] = ()
    words: tuple[RecordedWord, ...] = ()
    units: str = "mm"
    units_note: str = ""
    path_tolerance_m: float | None = None
    work_offset: str | None = None
    end_line: int = 0

    @property
    def n_moves(self) -> int:
        """Number of moves."""
        return len(self.moves)


def feed_seconds(program: Program) -> tuple[float, int]:
    """The time the program's feed moves take at their programmed feeds, s (a lower bound of its
    duration: rapids, stops and slow-downs are left out), and the index of the longest of them
    (-1 without feed moves).  From the moves alone, before any point is made of them."""
    times = [m.length_m / m.feed_m_s if m.feed_m_s else 0.0 for m in program.moves]
    if not times or max(times) <= 0.0:
        return 0.0, -1
    return math.fsum(times), max(range(len(times)), key=times.__getitem__)


@dataclass
class _Out:
    points: list[np.ndarray] = field(default_factory=list)
    line: list[np.ndarray] = field(default_factory=list)
    rapid: list[np.ndarray] = field(default_factory=list)
    feed: list[np.ndarray] = field(default_factory=list)
    move: list[np.ndarray] = field(default_factory=list)


def discretise(program: Program, tol_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The program as points (see :func:`discretise_moves`, without the move index)."""
    return discretise_moves(program, tol_m)[:4]


def discretise_moves(
    program: Program, tol_m: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The program as points: every move's end kept exactly, arcs split into chords.

    Parameters
    ----------
    program : Program
        The program.
    tol_m : float
        Largest sagitta of an arc chord (for helices: largest distance of a chord from the helix), m.

    Returns
    -------
    points : np.ndarray
        Shape ``(N, 3)``, m, program frame: ``program.start_m`` then the end of every chord/move.
    line : np.ndarray
        Shape ``(N,)``, int: the 1-based program line of the move ending at each point (point 0:
        the line that made the start known).
    rapid : np.ndarray
        Shape ``(N,)``, bool: the move ending at the point is a rapid (point 0: True).
    feed : np.ndarray
        Shape ``(N,)``, m/s: the programmed feed of the move ending at the point (NaN for rapids
        and point 0).
    move : np.ndarray
        Shape ``(N,)``, int: the index in ``program.moves`` of the move ending at the point (point
        0: -1).
    """
    if not tol_m > 0.0:
        raise InputError(f"the path tolerance for arc chords must be > 0 m, got {tol_m!r}")
    if program.start_m is None or not program.moves:
        return np.zeros((0, 3)), np.zeros(0, dtype=int), np.zeros(0, dtype=bool), np.zeros(0), np.zeros(0, dtype=int)
    moves = program.moves
    n = len(moves)
    ends = np.array([m.end for m in moves], dtype=float)
    lines = np.fromiter((m.line for m in moves), dtype=int, count=n)
    rapid = np.fromiter((m.kind is MoveKind.RAPID for m in moves), dtype=bool, count=n)
    feed = np.fromiter((math.nan if m.feed_m_s is None else m.feed_m_s for m in moves), dtype=float, count=n)
    arcs = [k for k, m in enumerate(moves) if m.kind is MoveKind.ARC]
    index = np.arange(n)
    head = (np.array([program.start_m]), np.array([program.start_line]), np.array([True]), np.array([math.nan]))
    if not arcs:
        return (
            np.vstack([head[0], ends]),
            np.concatenate([head[1], lines]),
            np.concatenate([head[2], rapid]),
            np.concatenate([head[3], feed]),
            np.r_[-1, index],
        )
    out = _Out([head[0]], [head[1]], [head[2]], [head[3]], [np.array([-1])])
    prev = 0
    for k in arcs:
        if k > prev:
            out.points.append(ends[prev:k])
            out.line.append(lines[prev:k])
            out.rapid.append(rapid[prev:k])
            out.feed.append(feed[prev:k])
            out.move.append(index[prev:k])
        m = moves[k]
        pts = arc_points(m.arc(), m.plane, np.asarray(m.start), ends[k], tol_m)
        out.points.append(pts)
        out.line.append(np.full(len(pts), m.line))
        out.rapid.append(np.zeros(len(pts), dtype=bool))
        out.feed.append(np.full(len(pts), feed[k]))
        out.move.append(np.full(len(pts), k))
        prev = k + 1
    if prev < n:
        out.points.append(ends[prev:])
        out.line.append(lines[prev:])
        out.rapid.append(rapid[prev:])
        out.feed.append(feed[prev:])
        out.move.append(index[prev:])
    return (
        np.vstack(out.points),
        np.concatenate(out.line),
        np.concatenate(out.rapid),
        np.concatenate(out.feed),
        np.concatenate(out.move),
    )
