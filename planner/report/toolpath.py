"""Program paths in the report: the program's own view of a run, its table, and the reduction of
long series for drawing.

A run whose problem is a CAM program (G-code or CL data; ``summary.json`` key ``program``) has a
:class:`ProgramView` in ``Run.program``: the waypoints in the program (workpiece) frame, their
program line, rapid flag and programmed feed, and the program line of every sample of each
trajectory timed by the feed law.  It is built from the plan in memory (:func:`program_from_plan`)
or from the run folder's ``path.csv`` and the ``line`` column of ``trajectory*.csv``
(:func:`program_from_folder`); both give the same view: the points are the base-frame targets of
``path.csv`` taken back into the program frame by the workpiece placement the summary records, and
the feeds are ``path.csv``'s (mm/min) in m/s.

The report's program figures (:mod:`planner.report.toolpath_plot`: the toolpath coloured by the TCP
error, the feed along the program) draw from this view; :func:`program_tables` shows the summary's
``program`` keys (nothing recomputed).  :func:`merge_segments` and :func:`bin_extrema` reduce
10^5 waypoints and 10^6 samples to what a figure can show, keeping every peak.  SI units inside;
the module prints nothing and does not import matplotlib.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any
from collections.abc import Mapping

import numpy as np

from models.errors import InputError
from models.transforms import rpy_to_matrix
from problems.toolpath.feed import FEED_SLOW_TOL

from planner.numbers import format_number
from planner.report.run import method_name
from planner.report.tables import Cell, Table, value_cell

if TYPE_CHECKING:
    from planner.plan import PlanResult
    from planner.report.run import Run

__all__ = [
    "CORNER_DEG",
    "FEED_BINS",
    "MAX_DRAWN_SEGMENTS",
    "PROGRAM_KEY",
    "SLOWED_SHOWN",
    "ProgramView",
    "bin_extrema",
    "line_feed_m_s",
    "sample_feed_m_s",
    "merge_segments",
    "program_from_folder",
    "program_from_plan",
    "program_tables",
    "slowed_lines_worst_first",
    "tcp_speed_m_s",
    "to_program_frame",
]

#: The ``summary.json`` key of a program path (:func:`planner.plan_summary.program_summary`).
PROGRAM_KEY = "program"
#: Most segments drawn per panel of the toolpath figure; a longer program is merged into chords
#: (:func:`merge_segments`): a PDF of 10^5 coloured segments took 9 s to write, of 2 x 10^4 about 2 s.
MAX_DRAWN_SEGMENTS = 20_000
#: A waypoint where the path turns by more than this (deg) in the drawing plane is a corner, kept
#: when the toolpath is merged for drawing (:func:`merge_segments`).
CORNER_DEG = 30.0
#: Bins of the feed figure's time axis (about one per pixel column): a longer trajectory is drawn
#: as the minimum and maximum of each bin (:func:`bin_extrema`).
FEED_BINS = 1500
#: Slowed program lines listed in the program table (worst first).
SLOWED_SHOWN = 10
#: Samples per forward-kinematics batch in :func:`tcp_speed_m_s` (bounds the (M, 4, 4) temporary).
_FK_CHUNK = 1 << 16
#: ``path.csv``'s program columns (:data:`planner.plan.PROGRAM_PATH_COLUMNS`) and its position columns.
_PATH_POSITION = ("x", "y", "z")
_PATH_PROGRAM = ("feed_mm_min", "line", "rapid")
#: m/s -> mm/min.
MM_MIN_PER_M_S = 6e4


@dataclass
class ProgramView:
    """The program of a run, as the report draws it (SI units).

    Attributes
    ----------
    points_m : np.ndarray
        Shape ``(N, 3)``, m, program (workpiece) frame: the TCP waypoints.
    line : np.ndarray
        Shape ``(N,)``, int: the program line of the move ending at each waypoint.
    rapid : np.ndarray
        Shape ``(N,)``, bool: that move is a rapid.
    feed_m_s : np.ndarray
        Shape ``(N,)``, m/s: its programmed feed; NaN for rapids and waypoint 0.
    sample_line : dict of method -> np.ndarray
        Shape ``(M,)``, int: the program line of the move each sample of the method's trajectory
        runs (the ``line`` column of its ``trajectory*.csv``); a method without one is left out.
    """

    points_m: np.ndarray
    line: np.ndarray
    rapid: np.ndarray
    feed_m_s: np.ndarray
    sample_line: dict[str, np.ndarray] = field(default_factory=dict)
    sample_waypoint: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def n(self) -> int:
        """Number of waypoints N."""
        return len(self.points_m)


# ------------------------------------------------------------------------------------ the view
def to_program_frame(points_base_m: np.ndarray, workpiece: Mapping[str, Any]) -> np.ndarray:
    """Base-frame points (N, 3), m, in the program frame of ``workpiece``.

    Parameters
    ----------
    points_base_m : np.ndarray
        Shape ``(N, 3)``, m, base frame.
    workpiece : mapping
        ``xyz_m`` (3,) and ``rpy_rad`` (3,): the program frame in the base frame, ``p_B = R p_P + t``
        with ``R = Rz(yaw) Ry(pitch) Rx(roll)`` (``summary.json`` ``program.workpiece``).

    Raises
    ------
    InputError
        ``workpiece`` lacks 3 finite numbers for ``xyz_m`` or ``rpy_rad``.
    """
    try:
        t = np.asarray(workpiece["xyz_m"], float).reshape(3)
        rpy = np.asarray(workpiece["rpy_rad"], float).reshape(3)
    except (KeyError, TypeError, ValueError):
        raise InputError(
            "summary.json: program.workpiece.xyz_m / rpy_rad missing or not 3 numbers each (m, rad)"
        ) from None
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(rpy))):
        raise InputError("summary.json: program.workpiece.xyz_m / rpy_rad are not finite")
    R = rpy_to_matrix(rpy)
    return (np.asarray(points_base_m, float) - t) @ R  # R^T (p - t), row by row


def _view(summary: Mapping[str, Any], base_m: np.ndarray, feed_mm_min: np.ndarray, line, rapid) -> ProgramView:
    """The view from ``path.csv``'s columns (the same arrays from a plan or a folder)."""
    prog = summary[PROGRAM_KEY]
    return ProgramView(
        points_m=to_program_frame(base_m, prog.get("workpiece") or {}),
        line=np.asarray(line).astype(int),
        rapid=np.asarray(rapid).astype(bool),
        feed_m_s=np.asarray(feed_mm_min, float) / MM_MIN_PER_M_S,
    )


def program_from_plan(res: PlanResult, summary: Mapping[str, Any]) -> ProgramView | None:
    """The program view of a plan in memory (None for a path that is not a program).

    ``summary``: the plan's ``summary.json`` content.  Gives the arrays that
    :func:`planner.plan.write_outputs` writes into ``path.csv`` and the ``line`` column of
    ``trajectory*.csv``, so the view equals :func:`program_from_folder`'s of the written folder.
    """
    prog = getattr(res.problem, "program", None)
    if prog is None or not isinstance(summary.get(PROGRAM_KEY), Mapping):
        return None
    w = prog.waypoints
    view = _view(summary, res.positions, w.feed_m_s * MM_MIN_PER_M_S, w.line, w.rapid)
    link = res.dynamic is not None and getattr(res.dynamic, "link", None) is not None
    for m, fl in res.feed.items():
        tr = res.trajectories.get(m)
        if tr is None or (m == res.controller and link):  # a motor-side command: no line column
            continue
        if len(fl.sample_move) == len(tr.t):
            view.sample_line[m] = np.asarray(w.line)[fl.sample_move].astype(int)
            view.sample_waypoint[m] = np.asarray(fl.sample_move).astype(int)
    return view


def program_from_folder(run: Run) -> ProgramView | None:
    """The program view of a run read from its folder (None for a path that is not a program).

    Reads ``path.csv``'s program columns and takes the ``line`` column of each trajectory read into
    ``run.trajectories`` (removing it there, as in the view of a plan).  A missing or malformed
    ``path.csv`` leaves the view None with the reason in ``run.absent["program"]``.
    """
    from planner.report.run import _read_csv  # the report's one CSV reader

    lines = {m: tr.pop("line", None) for m, tr in run.trajectories.items()}
    waypoints = {m: tr.pop("waypoint", None) for m, tr in run.trajectories.items()}
    if not isinstance(run.summary.get(PROGRAM_KEY), Mapping):
        return None
    path = Path(run.folder) / "path.csv"
    if not path.is_file():
        run.absent[PROGRAM_KEY] = "program path: path.csv absent in this run (the toolpath and feed are not drawn)"
        return None
    cols = _read_csv(path)
    missing = [c for c in _PATH_POSITION + _PATH_PROGRAM if c not in cols]
    if missing:
        run.absent[PROGRAM_KEY] = (
            f"program path: {path.name} has no column(s) {', '.join(missing)} (written before programs were "
            "planned?): the toolpath and feed are not drawn"
        )
        return None
    base = np.column_stack([cols[c] for c in _PATH_POSITION])
    view = _view(run.summary, base, cols["feed_mm_min"], cols["line"], cols["rapid"])
    view.sample_line = {m: np.asarray(v).astype(int) for m, v in lines.items() if v is not None}
    view.sample_waypoint = {m: np.asarray(v).astype(int) for m, v in waypoints.items() if v is not None}
    return view


def sample_feed_m_s(view: ProgramView, waypoints: np.ndarray) -> np.ndarray:
    """The programmed feed of the move each sample runs (m/s), from the waypoint that move ends at;
    NaN on a rapid (also inside a canned cycle, whose line holds rapids and feeds)."""
    k = np.asarray(waypoints).astype(int)
    return np.where(view.rapid[k], np.nan, view.feed_m_s[k])


# ---------------------------------------------------------------------------------- the feed
def tcp_speed_m_s(tcp_position, t_s: np.ndarray, q: np.ndarray) -> np.ndarray:
    """TCP speed between consecutive samples, from forward kinematics of the sampled joints.

    Parameters
    ----------
    tcp_position : callable
        ``tcp_position(q)`` -> ``(K, 4, 4)`` base->TCP transforms of ``(K, 6)`` joint vectors
        (``KinematicModel.tcp``).
    t_s : np.ndarray
        Shape ``(M,)``, s: sample times, increasing.
    q : np.ndarray
        Shape ``(M, 6)``, rad: the sampled joints.

    Returns
    -------
    np.ndarray
        Shape ``(M,)``, m/s: ``|p_i - p_{i-1}| / (t_i - t_{i-1})`` for sample ``i >= 1`` (the speed of
        the interval ending at the sample, so that it carries the sample's program line); 0 at
        sample 0.  The check of ``tests/test_feed.py``.
    """
    t = np.asarray(t_s, float)
    Q = np.asarray(q, float)
    M = len(t)
    if M < 2:
        return np.zeros(M)
    P = np.empty((M, 3))
    for a in range(0, M, _FK_CHUNK):
        P[a : a + _FK_CHUNK] = tcp_position(Q[a : a + _FK_CHUNK])[:, :3, 3]
    dt = np.diff(t)
    step = np.linalg.norm(np.diff(P, axis=0), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        v = np.where(dt > 0, step / np.where(dt > 0, dt, 1.0), 0.0)
    return np.r_[0.0, v]


def line_feed_m_s(view: ProgramView, lines: np.ndarray) -> np.ndarray:
    """The programmed feed of program lines ``lines`` (m/s): the largest feed of the cutting moves
    of each line (a canned cycle's line holds rapids and one feed), NaN for a line of rapids only
    or a line not in the program."""
    L = np.asarray(lines).astype(int)
    known = np.unique(view.line)
    F = np.full(len(known), np.nan)
    cut = ~view.rapid & np.isfinite(view.feed_m_s)
    np.fmax.at(F, np.searchsorted(known, view.line[cut]), view.feed_m_s[cut])
    i = np.clip(np.searchsorted(known, L), 0, max(len(known) - 1, 0))
    out = np.full(len(L), np.nan)
    ok = (known.size > 0) & (known[i] == L) if known.size else np.zeros(len(L), bool)
    out[ok] = F[i[ok]]
    return out


def bin_extrema(values: np.ndarray, n_bins: int = FEED_BINS) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Split a series into ``n_bins`` runs of consecutive samples; min and max of each (NaN ignored).

    Parameters
    ----------
    values : np.ndarray
        Shape ``(M,)``.
    n_bins : int
        Bins wanted; a series of at most ``n_bins`` samples is returned as is (one sample a bin).

    Returns
    -------
    starts : np.ndarray
        Shape ``(B,)``, int: the first sample of each bin.
    lo, hi : np.ndarray
        Shape ``(B,)``: the smallest and largest finite value of each bin (NaN for a bin without one).
    """
    v = np.asarray(values, float)
    M = len(v)
    if M <= n_bins:
        return np.arange(M), v.copy(), v.copy()
    starts = np.unique(np.linspace(0, M, n_bins, endpoint=False).astype(int))
    hi = np.fmax.reduceat(np.where(np.isfinite(v), v, -np.inf), starts)
    lo = np.fmin.reduceat(np.where(np.isfinite(v), v, np.inf), starts)
    hi[~np.isfinite(hi)] = np.nan
    lo[~np.isfinite(lo)] = np.nan
    return starts, lo, hi


# ---------------------------------------------------------------------------------- the path
def merge_segments(
    points: np.ndarray, values: np.ndarray, rapid: np.ndarray, max_segments: int = MAX_DRAWN_SEGMENTS
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """The moves of a path as drawable segments, merged into chords when there are too many.

    Segment ``k`` joins waypoints ``k - 1`` and ``k`` (the move ending at ``k``), its value the larger
    of its two ends'.  With more than ``max_segments`` segments, the drawing plane is divided into
    square cells of side ``tolerance`` and a waypoint is kept where the path enters another cell,
    where the move changes kind (cutting or rapid) and, while they are fewer than half
    ``max_segments``, at the corners (a turn of more than :data:`CORNER_DEG` in the drawing plane);
    the kept waypoints are joined by chords, so every dropped waypoint lies in the cell of the
    chord's start: within ``sqrt(2) * tolerance`` of the chord.  The tolerance is doubled from
    1/4000 of the drawing's extent until the count fits; a chord carries the largest value of the
    moves it replaces (no peak is lost).

    Parameters
    ----------
    points : np.ndarray
        Shape ``(N, 2)``: the waypoints in the drawing plane (any length unit).
    values : np.ndarray
        Shape ``(N,)`` or ``(N, K)``: the value(s) at each waypoint (NaN allowed).
    rapid : np.ndarray
        Shape ``(N,)``, bool: the move ending at the waypoint is a rapid.
    max_segments : int
        Most segments returned (unless the changes of kind alone are more).

    Returns
    -------
    segments : np.ndarray
        Shape ``(S, 2, 2)``: start and end of each segment.
    seg_values : np.ndarray
        Shape ``(S,)`` or ``(S, K)``.
    seg_rapid : np.ndarray
        Shape ``(S,)``, bool.
    tolerance : float
        The cell size used (in ``points``' unit); 0 when nothing was merged.
    """
    P = np.asarray(points, float)
    v = np.asarray(values, float)
    r = np.asarray(rapid, bool)
    N = len(P)
    if N < 2:
        return np.zeros((0, 2, 2)), np.zeros((0,) + v.shape[1:]), np.zeros(0, bool), 0.0
    seg_v = np.fmax(v[:-1], v[1:])  # segment j joins waypoints j and j + 1
    seg_r = r[1:]
    if N - 1 <= max_segments:
        return np.stack([P[:-1], P[1:]], axis=1), seg_v, seg_r, 0.0
    fixed = np.zeros(N, bool)
    fixed[[0, -1]] = True
    fixed[1:-1] = seg_r[1:] != seg_r[:-1]  # a change of kind at the waypoint
    d = np.diff(P, axis=0)
    length = np.linalg.norm(d, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        turn = np.einsum("ij,ij->i", d[:-1], d[1:]) / (length[:-1] * length[1:])
    corner = np.r_[False, turn < math.cos(math.radians(CORNER_DEG)), False]  # NaN (a zero move): no corner
    if np.count_nonzero(fixed | corner) <= max_segments // 2:  # the corners are kept while they are few
        fixed |= corner
    extent = float(np.max(np.ptp(P, axis=0))) or 1.0
    tol = extent / 4000.0
    while True:
        cell = np.floor((P - P.min(axis=0)) / tol)
        keep = fixed.copy()
        keep[1:] |= np.any(cell[1:] != cell[:-1], axis=1)  # entering another cell
        kept = np.flatnonzero(keep)
        if len(kept) - 1 <= max_segments or tol > extent:
            break
        tol *= 2.0
    starts = kept[:-1]
    vals = np.fmax.reduceat(np.where(np.isnan(seg_v), -np.inf, seg_v), starts)
    vals[~np.isfinite(vals)] = np.nan
    return np.stack([P[starts], P[kept[1:]]], axis=1), vals, seg_r[starts], tol


def view_axes(points_m: np.ndarray, rapid: np.ndarray) -> tuple[int, int, int]:
    """The two program axes to draw and the one looked along: the plane normal to the axis along
    which the cutting moves extend least (Z on a tie: the top view of a 3-axis program)."""
    P = np.asarray(points_m, float)
    r = np.asarray(rapid, bool)
    cut = np.zeros(len(P), bool)
    cut[1:] = ~r[1:]  # the end of each cutting move ...
    cut[:-1] |= ~r[1:]  # ... and its start
    span = np.ptp(P[cut] if cut.any() else P, axis=0) if len(P) else np.zeros(3)
    normal = 2 if span[2] <= span.min() * (1.0 + 1e-9) + 1e-12 else int(np.argmin(span))
    a, b = (i for i in range(3) if i != normal)
    return a, b, normal


# ----------------------------------------------------------------------------------- the table
def slowed_lines_worst_first(entry: Mapping[str, Any]) -> list[tuple[int, float]]:
    """``(line, fraction of F)`` of a feed entry's ``slowed_lines``, slowest first (then by line)."""
    rows = []
    for item in entry.get("slowed_lines") or []:
        try:
            rows.append((int(item[0]), float(item[1])))
        except (TypeError, ValueError, IndexError):
            continue
    return sorted(rows, key=lambda lf: (lf[1], lf[0]))


def _slowed_text(entry: Mapping[str, Any]) -> str:
    rows = slowed_lines_worst_first(entry)
    if not rows:
        return "none"
    shown = ", ".join(f"line {L}: {format_number(100.0 * f, 3)} %" for L, f in rows[:SLOWED_SHOWN])
    more = len(rows) - SLOWED_SHOWN
    return f"{len(rows)}: {shown}" + (f" and {more} more" if more > 0 else "")


def _ratio_cell(entry: Mapping[str, Any]) -> Cell:
    prog, dur = entry.get("programmed_time_s"), entry.get("duration_s")
    if isinstance(prog, (int, float)) and isinstance(dur, (int, float)) and prog > 0 and math.isfinite(dur):
        return Cell(format_number(float(dur) / float(prog)), css="num")
    return Cell("n/a")


def program_tables(summary: Mapping[str, Any]) -> list[Table]:
    """The program's tables (file, waypoints, stops, path tolerance; programmed against achieved
    time and the slowed program lines per timing method), from ``summary.json``'s ``program``
    keys; none for a path that is not a program."""
    p = summary.get(PROGRAM_KEY)
    if not isinstance(p, Mapping):
        return []
    k = PROGRAM_KEY
    rows = [
        [Cell("program file"), value_cell(summary, f"{k}.file")],
        [Cell("kind"), value_cell(summary, f"{k}.kind")],
        [Cell("waypoints"), value_cell(summary, f"{k}.n_waypoints")],
        [Cell("program lines with moves"), value_cell(summary, f"{k}.n_lines")],
        [Cell("stops (arm at rest)"), value_cell(summary, f"{k}.n_stops")],
        [Cell("dwell [s]"), value_cell(summary, f"{k}.dwell_s")],
        [Cell("path tolerance [mm]"), value_cell(summary, f"{k}.path_tolerance_mm")],
        [Cell("path tolerance from"), value_cell(summary, f"{k}.path_tolerance_source")],
        [Cell("cutting length [m]"), value_cell(summary, f"{k}.cutting_length_m")],
    ]
    note = "The program read as the path (summary.json 'program')."
    if p.get("units_note"):
        note += f" {p['units_note']}"
    tables = [Table("Program", ["quantity", "value"], rows, note, anchor="program")]
    feed = p.get("feed") if isinstance(p.get("feed"), Mapping) else {}
    ctrl = summary.get("controller_trajectory")
    cutting = any(isinstance(e, Mapping) and "cutting_time_s" in e for e in feed.values())  # (newer summaries)
    frows = []
    for m, entry in feed.items():
        if not isinstance(entry, Mapping):
            continue
        name = method_name(summary, m) + (" (controller)" if m == ctrl else "")
        frows.append(
            [
                Cell(name),
                value_cell(summary, f"{k}.feed.{m}.programmed_time_s"),
                value_cell(summary, f"{k}.feed.{m}.duration_s"),
                _ratio_cell(entry),
            ]
            + (
                [
                    value_cell(summary, f"{k}.feed.{m}.cutting_time_s"),
                    value_cell(summary, f"{k}.feed.{m}.cutting_time_over_programmed"),
                ]
                if cutting
                else []
            )
            + [
                value_cell(summary, f"{k}.feed.{m}.peak_feed_ratio"),
                value_cell(summary, f"{k}.feed.{m}.n_stretches"),
                Cell(_slowed_text(entry)),
            ]
        )
    if frows:
        tables.append(
            Table(
                "Program: feed",
                [
                    "method",
                    "programmed time [s]",
                    "achieved duration [s]",
                    "achieved / programmed [×]",
                ]
                + (["time on cutting moves [s]", "cutting time / programmed [×]"] if cutting else [])
                + [
                    "peak TCP speed / F",
                    "stretches between stops",
                    f"slowed program lines (count: slowest {SLOWED_SHOWN}, % of F)",
                ],
                frows,
                "Programmed time: length / F summed over the cutting moves (rapids count 0). Achieved: the "
                "trajectory's duration, rapids and stops included"
                + (
                    "; time on cutting moves: its samples on cutting moves, their accelerations and stops included"
                    if cutting
                    else ""
                )
                + ". Slowed lines: program lines with a move whose "
                f"peak TCP speed stays below {format_number(100.0 * (1.0 - FEED_SLOW_TOL))} % of F (the value: that "
                "peak on the line's slowest move), slowest first; the full list is "
                "summary.json program.feed.<method>.slowed_lines.",
                anchor="program-feed",
            )
        )
    return tables
