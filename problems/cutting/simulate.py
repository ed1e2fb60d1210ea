"""Run a 3-axis program through the stock: per move the removed volume, per sample the engagement.

The moves are taken in order; for each feed move the samples' masks are made against the stock as
it is before the move (exact: :mod:`problems.cutting.engagement_zmap`), then the move is cut
(:func:`problems.cutting.removal.cut_segment`).  Masks are handed to a callback in chunks of bounded
size and not kept, so a program of any length runs in bounded memory; each move's mask is written
straight into its chunk (only its engaged slices and front angle bins: the rest of a fresh chunk is
zero and, for a shallow cut, never touched).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from models.cutting.cutter import EndMill
from models.cutting.engagement import ANGLE_BINS, SLICE_HEIGHT_M
from models.errors import InputError

from .engagement_zmap import SampleEngagement, concatenate_engagements, n_slices, segment_engagement
from .removal import cut_segment
from .stock import ZMap

__all__ = ["CHUNK_BYTES", "SimulationResult", "sample_positions", "simulate"]

#: Most mask bytes gathered before a chunk is handed over (64 MB).
CHUNK_BYTES = 64 * 2**20


@dataclass(frozen=True)
class SimulationResult:
    """The stock after a program and what each move removed.

    Attributes
    ----------
    removed_m3 : ndarray, shape (N,)
        Volume removed by the move ending at each waypoint, m^3 (0 at waypoint 0).  Non-zero on a
        rapid: the rapid crashes into the stock.
    holder_hit : ndarray, bool, shape (N,)
        The move would bury the cutter beyond its length (material left above it was cut off too).
    stock_after : ZMap
        The stock once the program has run.
    n_samples : int
        Engagement samples handed to the callback.
    """

    removed_m3: np.ndarray
    holder_hit: np.ndarray
    stock_after: ZMap
    n_samples: int


def sample_positions(length_m: float, samples_per_segment: int | None, sample_spacing_m: float | None) -> np.ndarray:
    """Where a move of length ``length_m`` (m) is sampled, in (0, 1]: ``n`` samples at ``(m + 1)/n``
    (the move's start is the previous move's end, already sampled there); ``n`` fixed or
    ``ceil(length / spacing)``."""
    if sample_spacing_m is not None:
        if not (math.isfinite(sample_spacing_m) and sample_spacing_m > 0.0):
            raise InputError(f"engagement sample spacing must be > 0 m, got {sample_spacing_m!r}")
        n = max(int(math.ceil(length_m / sample_spacing_m - 1e-9)), 1)
    else:
        n = samples_per_segment if samples_per_segment is not None else 1
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            raise InputError(f"engagement samples per segment must be an integer >= 1, got {n!r}")
    return (np.arange(n) + 1.0) / n


def _check(points, rapid, spindle_cw) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    P = np.asarray(points, dtype=float)
    if P.ndim != 2 or P.shape[1] != 3 or P.shape[0] < 1 or not np.all(np.isfinite(P)):
        raise InputError(f"program points must be a finite (N, 3) array in m, got shape {P.shape}")
    n = P.shape[0]
    rp, cw = np.asarray(rapid), np.asarray(spindle_cw)
    if rp.shape != (n,) or rp.dtype != bool:
        raise InputError(f"rapid must be a bool array of shape ({n},), got {rp.dtype} {rp.shape}")
    if cw.shape != (n,) or cw.dtype != bool:
        raise InputError(f"spindle_cw must be a bool array of shape ({n},), got {cw.dtype} {cw.shape}")
    return P, rp, cw


def simulate(
    zmap: ZMap,
    mill: EndMill,
    points: np.ndarray,
    rapid: np.ndarray,
    spindle_cw: np.ndarray,
    *,
    samples_per_segment: int | None = 1,
    sample_spacing_m: float | None = None,
    dz_m: float = SLICE_HEIGHT_M,
    n_angles: int = ANGLE_BINS,
    on_chunk: Callable[[SampleEngagement], None] | None = None,
    chunk_bytes: int = CHUNK_BYTES,
    in_place: bool = False,
) -> SimulationResult:
    """Cut the program's moves from the stock in order, handing the feed moves' engagement to ``on_chunk``.

    Parameters
    ----------
    zmap : ZMap
        The stock before the program, program frame (copied unless ``in_place``).
    mill : EndMill
    points : ndarray, shape (N, 3)
        Tool-tip waypoints, program frame, m; move ``i`` goes from ``points[i-1]`` to ``points[i]``.
    rapid : ndarray, bool, shape (N,)
        Move ending at waypoint ``i`` is a rapid (cut, volume reported, no samples); index 0 unused.
    spindle_cw : ndarray, bool, shape (N,)
        Spindle clockwise (M3) during the move ending at waypoint ``i``, else M4.
    samples_per_segment, sample_spacing_m : int or None, float or None
        Samples of each feed move (the spacing, m, wins when given).
    dz_m, n_angles : float, int
        Mask slice height (m) and angle bins.
    on_chunk : callable or None
        Receives :class:`SampleEngagement` chunks in program order; None: masks are not made.
    chunk_bytes : int
        A chunk is handed over once its masks reach this many bytes.
    in_place : bool
        Cut ``zmap`` itself.
    """
    P, rp, cw = _check(points, rapid, spindle_cw)
    stock = zmap if in_place else zmap.copy()
    n = P.shape[0]
    removed = np.zeros(n)
    holder = np.zeros(n, dtype=bool)
    chunk = _Chunk(on_chunk, n_slices(mill, dz_m), n_angles, chunk_bytes)
    for i in range(1, n):
        p0, p1 = P[i - 1], P[i]
        if on_chunk is not None and not rp[i]:
            t = sample_positions(float(np.linalg.norm(p1 - p0)), samples_per_segment, sample_spacing_m)
            out = chunk.room(t.size)
            chunk.add(segment_engagement(stock, mill, p0, p1, t, bool(cw[i]), dz_m, n_angles, segment_index=i, out=out))
        res = cut_segment(stock, mill, p0, p1)
        removed[i], holder[i] = res.removed_m3, res.holder_hit
    chunk.flush()
    return SimulationResult(removed, holder, stock, chunk.n_samples)


class _Chunk:
    """The samples gathered for the next hand-over: their masks are written straight into one zeroed
    array of at most ``chunk_bytes`` (or one move's samples, if more), handed over when full."""

    def __init__(self, on_chunk, n_slices: int, n_angles: int, chunk_bytes: int) -> None:
        self.on_chunk, self.K, self.J = on_chunk, n_slices, n_angles
        self.capacity = max(int(chunk_bytes) // (n_slices * n_angles), 1)
        self.parts: list[SampleEngagement] = []
        self.buffer: np.ndarray | None = None
        self.used = 0
        self.n_samples = 0

    def room(self, S: int) -> np.ndarray:
        """A zeroed (S, K, J) slot for the next move's masks (the chunk is handed over first if full)."""
        if self.buffer is None or self.used + S > self.buffer.shape[0]:
            self.flush()
            self.buffer = np.zeros((max(self.capacity, S), self.K, self.J), dtype=bool)  # pages zeroed lazily
        return self.buffer[self.used : self.used + S]

    def add(self, e: SampleEngagement) -> None:
        self.parts.append(e)
        self.used += e.n_samples
        self.n_samples += e.n_samples

    def flush(self) -> None:
        if self.parts:
            self.on_chunk(concatenate_engagements(self.parts, self.buffer[: self.used]))
        self.parts, self.buffer, self.used = [], None, 0
