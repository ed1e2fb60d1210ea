"""Program paths in the report: the reduction of long series for drawing and the feed along them.

A run whose problem is a CAM program (G-code or CL data; ``summary.json`` key ``program``) has a
:class:`~planner.record.ProgramRecord` in ``RunRecord.program`` (the waypoints in the workpiece
frame the run records, their program line, rapid flag and programmed feed, and the program line of
every sample of each trajectory timed by the feed law).  The report's program figures
(:mod:`planner.report.toolpath_plot`: the toolpath coloured by the TCP error, the feed along the
program) draw from it with these helpers; :mod:`planner.report.program_tables` shows the summary's
``program`` keys (nothing recomputed).  The slowed lines of a feed entry are read here for both:
all of them (``slowed_lines``), those a joint limit holds down (``slowed_by_limit``), in words
(:func:`slowed_line_text`), and the path deviation against the tolerance (:func:`deviation_words`).
:func:`merge_segments` and :func:`bin_extrema` reduce 10^5 waypoints and 10^6 samples to what a
figure can show, keeping every peak.  SI units inside; the module prints nothing and does not
import matplotlib.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from planner.numbers import format_number
from planner.record.columns import MM_MIN_PER_M_S, PROGRAM_KEY
from planner.record.record import ProgramRecord

__all__ = [
    "FEED_BINS",
    "MAX_DRAWN_SEGMENTS",
    "MM_MIN_PER_M_S",
    "PROGRAM_KEY",
    "bin_extrema",
    "line_feed_m_s",
    "sample_feed_m_s",
    "merge_segments",
    "rapid_move_count",
    "DEVIATION_SLACK",
    "SLOWED_KINDS",
    "deviation_words",
    "slowed_by_limit_worst_first",
    "slowed_line_text",
    "slowed_lines_worst_first",
    "tcp_speed_m_s",
    "view_axes",
]

#: Most segments drawn per panel of the toolpath figure; a longer program is merged into chords
#: (:func:`merge_segments`): a PDF of 10^5 coloured segments took 9 s to write, of 2 x 10^4 about 2 s.
MAX_DRAWN_SEGMENTS = 20_000
#: A waypoint where the path turns by more than this (deg) in the drawing plane is a corner, kept
#: when the toolpath is merged for drawing (:func:`merge_segments`).
CORNER_DEG = 30.0
#: Bins of the feed figure's time axis (about one per pixel column): a longer trajectory is drawn
#: as the minimum and maximum of each bin (:func:`bin_extrema`).
FEED_BINS = 1500
#: Relative slack of a path deviation over the path tolerance still counted within it (the plan's
#: own warning, ``planner/plan.py``, uses the same 1e-6).
DEVIATION_SLACK = 1e-6
#: The kinds of slowed lines the report tells apart: held down by a joint limit (``slowed_by_limit``),
#: slowed only by their neighbours, a stop or a held line (the other ``slowed_lines``), and, for a summary written
#: before the split (no ``slowed_by_limit``), slowed for either reason.
SLOWED_KINDS = ("limit", "stops", "slowed")
#: Samples per forward-kinematics batch in :func:`tcp_speed_m_s` (bounds the (M, 4, 4) temporary).
_FK_CHUNK = 1 << 16


def sample_feed_m_s(view: ProgramRecord, waypoints: np.ndarray) -> np.ndarray:
    """The programmed feed of the move each sample runs (m/s), from the waypoint that move ends at;
    NaN on a rapid (also inside a canned cycle, whose line holds rapids and feeds)."""
    k = np.asarray(waypoints).astype(int)
    return np.where(view.rapid[k], np.nan, view.feed_m_s[k])


def rapid_move_count(view: ProgramRecord) -> int:
    """The number of rapid moves (G0, and a canned cycle's rapids) of a program: the runs of
    consecutive rapid waypoints of one program line, not the waypoints a rapid is split into."""
    r, line = np.asarray(view.rapid[1:], bool), np.asarray(view.line[1:])
    starts = r & ~np.r_[False, r[:-1] & (line[1:] == line[:-1])]
    return int(np.count_nonzero(starts))


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


def line_feed_m_s(view: ProgramRecord, lines: np.ndarray) -> np.ndarray:
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


# ------------------------------------------------------------------------------ slowed lines
def slowed_lines_worst_first(entry: Mapping[str, Any]) -> list[tuple[int, float]]:
    """``(line, fraction of F)`` of a feed entry's ``slowed_lines``, slowest first (then by line)."""
    rows = []
    for item in entry.get("slowed_lines") or []:
        try:
            rows.append((int(item[0]), float(item[1])))
        except (TypeError, ValueError, IndexError):
            continue
    return sorted(rows, key=lambda lf: (lf[1], lf[0]))


def slowed_by_limit_worst_first(entry: Mapping[str, Any]) -> list[tuple[int, float, int, str]] | None:
    """``(line, fraction of F, joint (1-based), derivative)`` of a feed entry's ``slowed_by_limit``
    (the slowed lines a joint limit holds down), slowest first (then by line); ``None`` for an entry
    without the key (a summary written before the slowed lines were split by cause)."""
    items = entry.get("slowed_by_limit")
    if not isinstance(items, list):
        return None
    rows = []
    for item in items:
        try:
            rows.append((int(item[0]), float(item[1]), int(item[2]), str(item[3])))
        except (TypeError, ValueError, IndexError):
            continue
    return sorted(rows, key=lambda r: (r[1], r[0]))


def slowed_line_text(line: int, fraction: float, joint: int | None = None, derivative: str = "") -> str:
    """A slowed line in words: ``"line 445: 52.4 %"``, with the limit that holds it down
    ``"line 445: 52.4 % (J4 jerk)"``."""
    text = f"line {line}: {format_number(100.0 * fraction, 3)} %"
    return text + (f" (J{joint} {derivative})" if joint is not None else "")


def deviation_words(deviation_mm: Any, tolerance_mm: Any) -> str:
    """The largest path deviation of a trajectory's samples against the path tolerance, in words:
    ``"✓ within: 0.0184 mm ≤ 0.02 mm"``, ``"✗ OUTSIDE: 0.03 mm > 0.02 mm (×1.5)"``, or why it is not
    compared (not measured, no tolerance)."""
    if not isinstance(deviation_mm, (int, float)) or not math.isfinite(deviation_mm):
        return "not measured"
    d = f"{format_number(float(deviation_mm), 3)} mm"
    if not isinstance(tolerance_mm, (int, float)) or not tolerance_mm > 0:
        return f"{d} (no path tolerance to compare with)"
    tol = float(tolerance_mm)
    if deviation_mm <= tol * (1.0 + DEVIATION_SLACK):
        return f"✓ within: {d} ≤ {format_number(tol, 3)} mm"
    return f"✗ OUTSIDE: {d} > {format_number(tol, 3)} mm (×{format_number(float(deviation_mm) / tol, 3)})"
